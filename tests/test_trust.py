"""The artist's work is never lost, bad input is refused with a sentence, and what is reported is
what Blender plays (issue 14), with real bpy and the shipped weights."""

import bpy
import numpy as np
import pytest
from mathutils import Quaternion

import blender_rigs
from model_runtime.skeleton import JOINT_INDEX
from trajevae_addon import api, pipeline, rig_state


pytestmark = pytest.mark.usefixtures("scene")


def _hand_curve(scene, rig, name="hand path", joint="RWrist", offset=(0.1, -0.35, 0.25)):
    """A curve from the joint's position at the start frame, moving by ``offset`` (world)."""
    scene.frame_set(scene.frame_start)
    start = blender_rigs.world_joints(rig)[JOINT_INDEX[joint]]
    t = np.linspace(0.0, 1.0, 12)[:, None]
    curve = blender_rigs.curve(scene, name, start + t * offset)
    api.bind_curve(rig, api.map_rig(rig)[joint], curve)
    return curve


def _played_error(scene, rig, joint, curve):
    """Mean world distance of ``joint`` to the curve's per-frame target, frame by frame as played."""
    from model_runtime import generation
    from trajevae_addon import curves
    frames = pipeline.scene_frames(scene)
    points, _ = curves.path(curve, int(frames[0]))
    wanted = generation.curve_samples(points, len(frames) - 1, len(frames) - 1)
    errors = []
    for index, frame in enumerate(frames):
        scene.frame_set(int(frame))
        errors.append(np.linalg.norm(blender_rigs.world_joints(rig)[JOINT_INDEX[joint]] - wanted[index]))
    return float(np.mean(errors))


def test_keep_leaves_the_artists_action_in_the_file(scene, tmp_path):
    rig = blender_rigs.mannequin_rig(scene)
    rig.pose.bones["Spine"].keyframe_insert("rotation_quaternion", frame=1)
    original = rig.animation_data.action
    original.name = "artist take"
    keys = blender_rigs.action_keys(original)
    made = api.generate_variants(rig, n=2, seed=0)
    api.keep_variant(rig, made[1])
    assert rig.animation_data.action == made[1]
    assert original.use_fake_user and rig.trajevae.previous_action == original
    name, path = rig.name, str(tmp_path / "kept.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    kept = bpy.data.actions.get("artist take")
    assert kept is not None and blender_rigs.action_keys(kept) == keys
    assert bpy.data.objects[name].trajevae.previous_action == kept


@pytest.mark.parametrize("through", ["api", "operator"])
def test_discard_puts_back_every_pose_channel_exactly(scene, through):
    rig = blender_rigs.mannequin_rig(scene)
    pose = rig.pose.bones
    pose["Hip"].location = (0.0, 0.0, 0.05)  # hip lifted 5 cm, spine turned: nothing keyed
    pose["Spine"].rotation_quaternion = Quaternion((0.0, 0.0, 1.0), 0.4)
    pose["LElbow"].rotation_mode = 'XZY'
    pose["LElbow"].rotation_euler = (0.3, -0.2, 0.1)
    pose["RElbow"].rotation_mode = 'AXIS_ANGLE'
    pose["RElbow"].rotation_axis_angle = (0.5, 1.0, 0.0, 0.0)
    pose["LKnee"].scale = (1.0, 1.1, 1.0)
    switch = pose["RWrist"].constraints.new('FOLLOW_PATH')  # a path constraint the add-on mutes
    switch.target = _hand_curve(scene, rig)
    rig.trajevae.bindings.clear()
    before = rig_state.pose_snapshot(rig)
    api.generate_variants(rig, n=2, seed=0)
    scene.frame_set(37)
    assert switch.influence == 0.0 and rig_state.pose_snapshot(rig) != before
    if through == "api":
        api.restore_original(rig)
    else:
        bpy.context.view_layer.objects.active = rig
        assert bpy.ops.trajevae.discard_variants() == {'FINISHED'}
    assert rig_state.pose_snapshot(rig) == before
    assert switch.influence == 1.0
    assert rig.animation_data.action is None and not bpy.data.actions


def _artist_state(rig):
    """Everything of the artist's a refused or undone generation must leave byte-identical."""
    animation = rig.animation_data
    return {"actions": {action.name: blender_rigs.action_keys(action) for action in bpy.data.actions},
            "assigned": animation.action.name if animation and animation.action else None,
            "pose": rig_state.pose_snapshot(rig),
            "constraints": {(bone.name, c.name): (c.mute, c.influence) for bone in rig.pose.bones
                            for c in bone.constraints},
            "variants": len(rig.trajevae.variants), "recorded": rig.trajevae.has_original}


def test_non_finite_input_is_refused_before_anything_is_written(scene):
    rig = blender_rigs.mannequin_rig(scene)
    rig.pose.bones["Spine"].keyframe_insert("rotation_quaternion", frame=1)
    before = _artist_state(rig)
    with pytest.raises(pipeline.InputError, match="diversity"):
        api.generate_variants(rig, n=2, diversity=float("nan"))
    rig.pose.bones["Hip"].location = (0.0, float("nan"), 0.0)
    with pytest.raises(rig_state.RigError, match="'Hip'.*not a number"):
        api.generate_variants(rig, n=2)
    before["pose"]["Hip"]["location"][1] = float("nan")
    assert str(_artist_state(rig)) == str(before)  # NaN != NaN: compared as text
    rig.pose.bones["Hip"].location = (0.0, 0.0, 0.0)
    rig.pose.bones["Hip"].keyframe_insert("location", frame=1)
    rig.pose.bones["Hip"].location = (0.0, 0.0, float("nan"))
    rig.pose.bones["Hip"].keyframe_insert("location", frame=30)  # a key that is not a number
    scene.frame_set(1)
    state = _artist_state(rig)
    with pytest.raises(rig_state.RigError, match="'Hip'.*frame 30"):
        api.generate_variants(rig, n=2)
    assert _artist_state(rig) == state


def test_a_failure_while_writing_puts_everything_back(scene):
    rig = blender_rigs.mannequin_rig(scene)
    rig.pose.bones["Spine"].keyframe_insert("rotation_quaternion", frame=1)
    rig.pose.bones["Hip"].location = (0.0, 0.0, 0.05)
    _hand_curve(scene, rig)
    before = _artist_state(rig)
    job = pipeline.prepare(rig, 4, 0)
    pipeline.infer(job)
    writer = pipeline.Writer(job, rig)
    with pytest.raises(KeyError):
        try:
            writer.step(seconds=0.0)  # one variant written
            assert len([a for a in bpy.data.actions if "variant" in a.name]) == 1
            rig.data.bones["LKnee"].name = "knee renamed"  # the artist edits the rig meanwhile
            while not writer.done:
                writer.step(seconds=0.0)
        except BaseException:
            writer.rollback()
            raise
    rig.data.bones["knee renamed"].name = "LKnee"
    assert _artist_state(rig) == before


def test_a_bone_renamed_while_the_worker_runs_is_said_and_nothing_written(scene):
    rig = blender_rigs.mannequin_rig(scene)
    before = _artist_state(rig)
    job = pipeline.prepare(rig, 2, 0)
    pipeline.infer(job)
    rig.data.bones["LElbow"].name = "elbow"
    with pytest.raises(rig_state.RigError, match="'LElbow'.*renamed or deleted"):
        pipeline.finish(job, rig)
    rig.data.bones["elbow"].name = "LElbow"
    assert _artist_state(rig) == before


def test_nla_tweak_mode_is_refused_and_generate_says_why(scene):
    rig = blender_rigs.mannequin_rig(scene)
    rig.pose.bones["Spine"].keyframe_insert("rotation_quaternion", frame=1)
    animation = rig.animation_data
    track = animation.nla_tracks.new()
    track.strips.new("take", 1, animation.action)
    animation.action = None
    track.strips[0].select = True
    animation.use_tweak_mode = True
    assert animation.use_tweak_mode
    before = _artist_state(rig)
    with pytest.raises(rig_state.RigError, match="tweak mode"):
        api.generate_variants(rig, n=2)
    bpy.context.view_layer.objects.active = rig
    with pytest.raises(RuntimeError, match="tweak mode"):  # the greyed-out button's reason
        bpy.ops.trajevae.generate()
    assert _artist_state(rig) == before


def test_linked_rigs_and_library_overrides_are_refused_with_the_way_out(scene, tmp_path):
    rig = blender_rigs.mannequin_rig(scene)
    collection = bpy.data.collections.new("Character")
    scene.collection.children.link(collection)
    for obj in [rig, *rig.children]:
        for owner in list(obj.users_collection):
            owner.objects.unlink(obj)
        collection.objects.link(obj)
    library = str(tmp_path / "character.blend")
    bpy.ops.wm.save_as_mainfile(filepath=library)
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    with bpy.data.libraries.load(library, link=True) as (_, linked):
        linked.collections = ["Character"]
    instance = bpy.data.objects.new("Character", None)
    instance.instance_type, instance.instance_collection = 'COLLECTION', linked.collections[0]
    scene.collection.objects.link(instance)
    rig = next(obj for obj in bpy.data.objects if obj.type == 'ARMATURE')
    with pytest.raises(rig_state.RigError, match="linked from .*Make Local"):
        api.generate_variants(rig, n=2)
    linked.collections[0].override_hierarchy_create(scene, bpy.context.view_layer)
    rig = next(obj for obj in bpy.data.objects if obj.type == 'ARMATURE' and obj.override_library)
    with pytest.raises(rig_state.RigError, match="library override"):
        api.generate_variants(rig, n=2)
    assert not bpy.data.actions


def test_a_rig_carried_by_a_moving_parent_follows_its_curve_in_world_space(scene):
    rig = blender_rigs.mannequin_rig(scene)
    carrier = bpy.data.objects.new("carrier", None)
    scene.collection.objects.link(carrier)
    carrier.keyframe_insert("location", frame=1)
    carrier.keyframe_insert("rotation_euler", frame=1)
    carrier.location, carrier.rotation_euler = (0.8, 0.4, 0.0), (0.0, 0.0, 0.6)
    carrier.keyframe_insert("location", frame=60)
    carrier.keyframe_insert("rotation_euler", frame=60)
    rig.parent = carrier
    curve = _hand_curve(scene, rig)
    report = pipeline.generate_variants(rig, 2, 0)
    for action in report.actions:
        api.set_active_variant(rig, action)
        error = _played_error(scene, rig, "RWrist", curve)
        print(f"moving parent: curve error as played {100 * error:.2f} cm")
        assert error < 0.01
    assert all(error < 0.01 for error in report.curve_error_m)


def test_a_constraint_that_overrides_the_keys_is_named_and_its_error_reported(scene):
    rig = blender_rigs.mannequin_rig(scene)
    goal = bpy.data.objects.new("elbow goal", None)
    scene.collection.objects.link(goal)
    goal.location = (0.5, -0.3, 1.0)
    ik = rig.pose.bones["LElbow"].constraints.new('IK')
    ik.name, ik.target, ik.chain_count = "Arm IK", goal, 2
    curve = _hand_curve(scene, rig, joint="LWrist", offset=(-0.1, -0.35, 0.25))
    report = pipeline.generate_variants(rig, 2, 0)
    api.set_active_variant(rig, report.actions[0])
    played = _played_error(scene, rig, "LWrist", curve)
    print(f"IK on the bound arm: reported {[round(100 * e, 1) for e in report.curve_error_m]} cm, "
          f"played {100 * played:.1f} cm; {report.warnings}")
    assert played > 0.05 and abs(report.curve_error_m[0] - played) < 0.02
    assert any("'Arm IK'" in warning and "misses its curve" in warning for warning in report.warnings)


@pytest.mark.parametrize("case, message", [
    ("far", r"starts 100\.\d+ m from its joint"),
    ("long", r"is \d{4}\.\d m long, \d+ m/s"),
    ("below", r"goes \d\.\d+ m below the feet"),
])
def test_curves_out_of_reach_are_said_per_binding_and_nothing_written(scene, case, message):
    rig = blender_rigs.mannequin_rig(scene)
    start = blender_rigs.world_joints(rig)[JOINT_INDEX["RWrist"]]
    t = np.linspace(0.0, 1.0, 50)[:, None]
    points = {"far": start + [100.0, 0.0, 0.0] + t * [0.2, 0.0, 0.0],
              "long": start + t * [1000.0, 0.0, 0.0],
              "below": start + t * [0.0, -0.3, -2.0]}[case]
    api.bind_curve(rig, "RWrist", blender_rigs.curve(scene, "wild", points))
    before = _artist_state(rig)
    with pytest.raises(pipeline.InputError, match=r"curve 'wild' \(RWrist\) " + message):
        api.generate_variants(rig, n=2)
    assert _artist_state(rig) == before


@pytest.mark.parametrize("arguments", [dict(n=0), dict(n=-1), dict(n=2.5), dict(n=True), dict(n=51),
                                       dict(seed=-1), dict(seed=1.5), dict(diversity=-0.1),
                                       dict(diversity=2.5), dict(diversity=float("inf")), dict(diversity="1")])
def test_arguments_are_checked_with_a_sentence(scene, arguments):
    rig = blender_rigs.mannequin_rig(scene)
    with pytest.raises(pipeline.InputError, match=r"^(the number of variants|the seed|diversity) must be") as caught:
        api.generate_variants(rig, **arguments)
    assert "reshape" not in str(caught.value) and not bpy.data.actions


def test_generate_is_greyed_out_with_a_reason_without_an_armature(scene):
    mesh = bpy.data.objects.new("mesh", bpy.data.meshes.new("mesh"))
    scene.collection.objects.link(mesh)
    bpy.context.view_layer.objects.active = mesh
    assert not bpy.ops.trajevae.generate.poll()
    with pytest.raises(RuntimeError, match="Select an armature"):
        bpy.ops.trajevae.generate()
