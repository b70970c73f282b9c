"""The Blender extension with real bpy, the shipped weights and rigs built in Blender."""

import bpy
import numpy as np
import pytest

import blender_rigs
import trajevae_addon
from trajevae_addon import api, pipeline, rig_mapping, rig_state

HAND_AND_FOOT = {"LWrist": (0.0, -0.35, 0.25), "RWrist": (0.15, -0.3, 0.1), "LFoot": (0.0, -0.3, 0.0),
                 "RFoot": (0.0, -0.6, 0.0)}


pytestmark = pytest.mark.usefixtures("scene")


def _joint_world(rig, joint, bones=None):
    bones = bones or api.map_rig(rig)
    state, world = rig_state.read(rig, bones, bpy.context.evaluated_depsgraph_get())
    from model_runtime.skeleton import JOINT_INDEX
    return world[JOINT_INDEX[joint]]


def _bind(scene, rig, joints, scale=1.0):
    """Curves from each joint's start position, moving by the given world offsets (scaled)."""
    bones = api.map_rig(rig)
    scene.frame_set(scene.frame_start)
    for joint in joints:
        start = _joint_world(rig, joint, bones)
        offset = np.array(HAND_AND_FOOT[joint]) * scale
        path = start + np.linspace(0.0, 1.0, 12)[:, None] * offset + np.sin(np.linspace(0, np.pi, 12))[:, None] * [
            0.0, 0.0, 0.05 * scale]
        api.bind_curve(rig, bones[joint], blender_rigs.curve(scene, f"path {joint}", path))
    return bones


def _curve_errors(scene, rig, read_bones):
    """Mean distance (world units) of each bound joint to its curve, evaluated on the rig per frame."""
    from trajevae_addon import curves
    from model_runtime import generation
    frames = pipeline.scene_frames(scene)
    joint_of = {bone: joint for joint, bone in api.map_rig(rig).items()}
    expected = {}
    for binding in rig.trajevae.bindings:
        points = curves.polyline(binding.curve)
        expected[binding.bone] = generation.curve_samples(points, len(frames) - 1, len(frames) - 1)
    errors = {bone: [] for bone in expected}
    world = np.array(rig.matrix_world)
    for index, frame in enumerate(frames):
        scene.frame_set(int(frame))
        for bone, path in expected.items():
            head = rig.pose.bones[read_bones.get(joint_of[bone], bone)].head
            position = world[:3, :3] @ np.array(head) + world[:3, 3]
            errors[bone].append(np.linalg.norm(position - path[index]))
    return {bone: float(np.mean(e)) for bone, e in errors.items()}


def _keys(action):
    """Every channel's keys of an action, for exact comparison."""
    out = {}
    for layer in action.layers:
        for strip in layer.strips:
            for bag in strip.channelbags:
                for fcurve in bag.fcurves:
                    co = np.empty(len(fcurve.keyframe_points) * 2)
                    fcurve.keyframe_points.foreach_get("co", co)
                    out[(fcurve.data_path, fcurve.array_index)] = co
    return out


def _check_variants(rig, made, count):
    assert len(made) == count and all(action.use_fake_user for action in made)
    assert [item.action for item in rig.trajevae.variants][-count:] == made
    motions = [np.concatenate([keys for path, keys in sorted(_keys(action).items()) if "rotation" in path[0]])
               for action in made]
    for a in range(count):
        for b in range(a + 1, count):
            assert np.abs(motions[a] - motions[b]).max() > 0.05  # clearly different keys


def test_mannequin_follows_0_1_2_4_curves_and_leaves_the_original_action_alone(scene):
    scene = scene
    rig = blender_rigs.mannequin_rig(scene)
    rig.pose.bones["Spine"].rotation_quaternion = (0.99, 0.1, 0.0, 0.0)
    rig.pose.bones["Spine"].keyframe_insert("rotation_quaternion", frame=1)
    rig.pose.bones["LElbow"].keyframe_insert("rotation_quaternion", frame=30)
    original = rig.animation_data.action
    before = _keys(original)
    for joints in ((), ("LWrist",), ("LWrist", "RFoot"), ("LWrist", "RWrist", "LFoot", "RFoot")):
        rig.trajevae.bindings.clear()
        _bind(scene, rig, joints)
        made = api.generate_variants(rig, n=3, seed=len(joints))
        _check_variants(rig, made, 3)
        errors = _curve_errors(scene, rig, {})
        print(f"mannequin, {len(joints)} curves: mean curve error (m) {errors}")
        assert all(error < 0.05 for error in errors.values())
    assert rig.animation_data.action == made[0]
    api.restore_original(rig)
    assert rig.animation_data.action == original and len(rig.trajevae.variants) == 0
    assert not any(action.name.startswith(f"{rig.name} variant") for action in bpy.data.actions)
    after = _keys(original)
    assert before.keys() == after.keys() and all(np.array_equal(before[k], after[k]) for k in before)


@pytest.fixture
def rigify(scene):
    yield blender_rigs.rigify_rig(scene)
    blender_rigs.disable_rigify()


def test_generated_rigify_rig_is_keyed_on_its_fk_controls(scene, rigify):
    scene, rig = scene, rigify
    assert api.map_rig(rig)["LWrist"] == "hand_fk.L"
    rig.pose.bones["foot_ik.L"].location = (0.0, 0.1, 0.25)  # the artist poses the left leg in IK
    bpy.context.view_layer.update()
    shown_foot = np.array(rig.pose.bones["ORG-foot.L"].head)
    bones, depsgraph, shown = api.map_rig(rig), bpy.context.evaluated_depsgraph_get(), rig_mapping.shown_by("rigify")
    np.testing.assert_allclose(rig_state.world_joints(rig, bones, depsgraph, shown),
                               rig_state.read(rig, bones, depsgraph, shown)[1], atol=1e-6)  # measured as read
    _bind(scene, rig, ("LWrist", "RWrist"))
    made = api.generate_variants(rig, n=2, seed=1)
    scene.frame_set(scene.frame_start)
    assert np.linalg.norm(np.array(rig.pose.bones["ORG-foot.L"].head) - shown_foot) < 0.03  # starts as shown (IK may stretch)
    _check_variants(rig, made, 2)
    keyed = {path for path, _ in _keys(made[0])}
    bones = {path.split('"')[1] for path in keyed}
    assert not any(bone.startswith(("DEF-", "MCH-", "ORG-")) for bone in bones)
    assert 'pose.bones["thigh_parent.L"]["IK_FK"]' in keyed
    # the shoulder controls turn the clavicles, and the FK arms hang from them (through ORG-shoulder)
    assert {"shoulder.L", "shoulder.R"} <= bones
    state, _ = rig_state.read(rig, api.map_rig(rig), bpy.context.evaluated_depsgraph_get())
    assert state.clavicles == rig_state.clavicles(rig, rig_state.mapping(rig)) == {
        "LClavicle": "shoulder.L", "RClavicle": "shoulder.R"}  # as the Rig Mapping panel lists them
    assert state.drivers["upper_arm_fk.L"] == "shoulder.L" and state.drivers["shoulder.L"] == "torso"
    # measured on the visible skeleton (ORG bones follow FK once the switches are keyed)
    read = {"LWrist": "ORG-hand.L", "RWrist": "ORG-hand.R"}
    errors = _curve_errors(scene, rig, read)
    print(f"rigify, 2 curves: mean curve error (m) {errors}")
    assert all(error < 0.05 for error in errors.values())


def test_mixamo_centimetre_rig_turned_and_moved_with_mixed_rotation_modes(scene):
    scene = scene
    rig = blender_rigs.mixamo_rig(scene)
    assert api.map_rig(rig)["Spine"] == "mixamorig:Spine"
    _bind(scene, rig, ("LWrist", "RFoot"))
    made = api.generate_variants(rig, n=2, seed=2)
    _check_variants(rig, made, 2)
    paths = {path for path, _ in _keys(made[0])}
    assert 'pose.bones["mixamorig:LeftArm"].rotation_axis_angle' in paths
    assert any(path.startswith('pose.bones["mixamorig:LeftShoulder"].rotation') for path in paths)  # its clavicle
    assert 'pose.bones["mixamorig:RightUpLeg"].rotation_euler' in paths
    errors = _curve_errors(scene, rig, {})
    print(f"mixamo (cm, turned), 2 curves: mean curve error (m) {errors}")
    assert all(error < 0.05 for error in errors.values())


def test_armature_imported_from_cmu_bvh(scene, mocap_root):
    scene = scene
    rig = blender_rigs.bvh_rig(mocap_root / "cmu_mb_01-09" / "02" / "02_01.bvh")
    bones = api.map_rig(rig)
    assert not rig_state.rig_mapping.missing(bones)
    scale = np.linalg.norm(_joint_world(rig, "LHip") - _joint_world(rig, "LFoot"))  # file units per leg
    _bind(scene, rig, ("LWrist", "RWrist", "LFoot", "RFoot"), scale=scale / 0.81)
    made = api.generate_variants(rig, n=2, seed=3)
    _check_variants(rig, made, 2)
    errors = _curve_errors(scene, rig, {})
    print(f"bvh import (file units, leg {scale:.2f}), 4 curves: mean curve error in legs {errors}")
    assert all(error / scale * 0.81 < 0.05 for error in errors.values())


def test_variants_survive_save_and_reload_then_keep(scene, tmp_path):
    scene = scene
    rig = blender_rigs.mannequin_rig(scene)
    _bind(scene, rig, ("RWrist",))
    made = api.generate_variants(rig, n=3, seed=4)
    names, rig_name = [action.name for action in made], rig.name
    keys = _keys(made[1])
    path = str(tmp_path / "variants.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    rig = bpy.data.objects[rig_name]
    reloaded = [item.action for item in rig.trajevae.variants]
    assert [action.name for action in reloaded] == names
    assert rig.trajevae.bindings[0].curve.name == "path RWrist"
    api.set_active_variant(rig, reloaded[1])
    assert rig.animation_data.action == reloaded[1]
    assert all(np.array_equal(keys[k], v) for k, v in _keys(reloaded[1]).items())
    api.keep_variant(rig, reloaded[1])
    assert rig.animation_data.action.name == names[1]
    assert [a.name for a in bpy.data.actions] == [names[1]] and len(rig.trajevae.variants) == 0


def test_clear_errors_and_operators(scene):
    scene = scene
    rig = blender_rigs.mannequin_rig(scene)
    scene.frame_end = scene.frame_start
    with pytest.raises(rig_state.RigError, match="single frame"):
        api.generate_variants(rig)
    scene.frame_end = 40
    with pytest.raises(ValueError, match="bind one of the mapped bones"):
        api.bind_curve(rig, "LClavicle", blender_rigs.curve(scene, "c", np.zeros((2, 3)) + [0, 0, 1.4]))
    bpy.context.view_layer.objects.active = rig
    rig.trajevae.variant_count = 2
    assert bpy.ops.trajevae.generate() == {'FINISHED'}
    assert len(rig.trajevae.variants) == 2
    assert bpy.ops.trajevae.step_variant(step=1) == {'FINISHED'}
    assert rig.animation_data.action == rig.trajevae.variants[1].action
    assert bpy.ops.trajevae.discard_variants() == {'FINISHED'}
    assert rig.animation_data.action is None and not bpy.data.actions


def test_register_unregister_register_leaves_nothing_behind(scene):
    trajevae_addon.unregister()
    assert not hasattr(bpy.types.Object, "trajevae")
    assert not [name for name in dir(bpy.types) if name.startswith("TRAJEVAE_")]
    trajevae_addon.register()
    assert hasattr(bpy.types.Object, "trajevae")


def test_child_sized_rig_and_a_stored_mapping_override(scene, tmp_path):
    scene = scene
    rig = blender_rigs.mannequin_rig(scene)
    rig.scale = (0.65, 0.65, 0.65)
    _bind(scene, rig, ("RWrist", "LFoot"), scale=0.65)
    api.generate_variants(rig, n=2, seed=5)
    errors = _curve_errors(scene, rig, {})
    print(f"child-sized mannequin (x0.65), 2 curves: mean curve error (m) {errors}")
    assert all(error < 0.05 * 0.65 for error in errors.values())
    rig.trajevae.mapping.Head = "Neck"  # the artist's pick wins over detection and is saved
    path, name = str(tmp_path / "mapping.blend"), rig.name
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    assert api.map_rig(bpy.data.objects[name])["Head"] == "Neck"
