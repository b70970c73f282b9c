"""Artist workflow with real bpy: keys as constraints, long shots, cancelling, per-variant feedback."""

import threading

import bpy
import numpy as np
import pytest
from mathutils import Quaternion

import blender_rigs
from model_runtime import generation, shot
from model_runtime.skeleton import JOINT_INDEX
from trajevae_addon import api, inference, pipeline, rig_state


pytestmark = pytest.mark.usefixtures("scene")


def test_keys_constrain_their_joints_on_their_frames_only(scene):
    rig = blender_rigs.mannequin_rig(scene)
    pose = rig.pose.bones
    for bone in ("Hip", "LShoulder", "LElbow", "RHip", "RKnee"):  # a blocking key at frame 1
        pose[bone].keyframe_insert("rotation_quaternion", frame=1)
    pose["Hip"].keyframe_insert("location", frame=1)
    pose["LShoulder"].rotation_quaternion = Quaternion((0, 1, 0), -1.2)  # arm raised sideways
    pose["LElbow"].rotation_quaternion = Quaternion((1, 0, 0), 0.8)
    pose["RHip"].rotation_quaternion = Quaternion((1, 0, 0), 0.5)  # right leg lifted
    pose["RKnee"].rotation_quaternion = Quaternion((1, 0, 0), 0.9)
    pose["Hip"].location = (0.0, 0.05, -0.1)
    for bone in ("Hip", "LShoulder", "LElbow", "RHip", "RKnee"):
        pose[bone].keyframe_insert("rotation_quaternion", frame=40)
    pose["Hip"].keyframe_insert("location", frame=40)
    scene.frame_set(40)
    keyed = blender_rigs.world_joints(rig)
    scene.frame_set(1)
    made = api.generate_variants(rig, n=3, seed=0)
    for action in made:
        api.set_active_variant(rig, action)
        scene.frame_set(40)
        got = blender_rigs.world_joints(rig)
        for joint in ("LWrist", "RFoot", "RKnee", "Hip"):
            error = np.linalg.norm(got[JOINT_INDEX[joint]] - keyed[JOINT_INDEX[joint]])
            assert error < 0.01, (action.name, joint, error)
    at_20 = []
    for action in made:
        api.set_active_variant(rig, action)
        scene.frame_set(20)
        at_20.append(blender_rigs.world_joints(rig)[JOINT_INDEX["LWrist"]])
    assert max(np.linalg.norm(a - b) for a in at_20 for b in at_20) > 0.02  # free between the keys


def test_a_300_frame_shot_has_no_seams_and_curves_are_followed_within_a_centimetre(scene):
    scene.frame_start, scene.frame_end = 1, 300
    scene.render.fps = 24
    rig = blender_rigs.mannequin_rig(scene)
    bones = api.map_rig(rig)
    start = blender_rigs.world_joints(rig)[JOINT_INDEX["RWrist"]]
    t = np.linspace(0.0, 1.0, 40)[:, None]
    path = start + np.column_stack([0.3 * np.sin(2 * np.pi * t[:, 0]), -1.5 * t[:, 0], 0.2 * np.sin(np.pi * t[:, 0])])
    api.bind_curve(rig, bones["RWrist"], blender_rigs.curve(scene, "long path", path))
    job = pipeline.prepare(rig, 3, 0)
    pipeline.infer(job)
    motion = job.result.motion  # (3, 300, 17, 3) world, scene rate
    speed = np.linalg.norm(np.diff(motion, axis=1), axis=-1).mean(axis=-1)  # (3, 299) mean joint step
    jump = np.abs(np.diff(speed, axis=1))  # change of speed from frame to frame
    joins = np.array(generation.window_joins(300, 24, inference.model().frames))  # each cross-fade's first and last frame
    near = np.clip(joins[:, None] - 2 + np.arange(3), 0, jump.shape[1] - 1)  # (joins, 3): the frame either side too
    at_joins = jump[:, near].max(axis=-1).mean()
    print(f"300 frames: speed change at joins {at_joins * 1000:.2f} mm/frame vs {jump.mean() * 1000:.2f} overall "
          f"(95th percentile {np.percentile(jump, 95) * 1000:.2f})")
    assert len(joins) >= 8
    assert at_joins < np.percentile(jump, 95)
    report = pipeline.finish(job, rig)
    print("curve error per variant where reachable (cm):", [round(100 * e, 2) for e in report.curve_error_m],
          "share out of reach:", [round(s, 3) for s in report.out_of_reach])
    assert all(error < 0.01 for error in report.curve_error_m)
    # the body keeps up with a hand walked 1.5 m back on a third of the frames or more (the model before
    # issue 16's kept up on over half; its decoder followed given joints more closely)
    assert np.mean(report.out_of_reach) < 0.67
    assert all(difference > 0.02 for difference in report.difference_m)


def test_cancelling_mid_run_writes_nothing(scene):
    scene.frame_start, scene.frame_end = 1, 300
    rig = blender_rigs.mannequin_rig(scene)
    actions_before = set(bpy.data.actions)
    job = pipeline.prepare(rig, 5, 0)
    outcome = []

    def work():
        try:
            pipeline.infer(job, on_progress=lambda fraction: job.cancel_event.set())
            outcome.append("finished")
        except pipeline.Cancelled:
            outcome.append("cancelled")

    worker = threading.Thread(target=work)
    worker.start()
    worker.join(timeout=120)
    assert outcome == ["cancelled"] and 0 < job.progress < 0.9
    assert job.result is None
    assert set(bpy.data.actions) == actions_before and not len(rig.trajevae.variants)


def test_a_one_frame_range_or_no_armature_is_a_clear_error(scene):
    scene.frame_end = scene.frame_start
    rig = blender_rigs.mannequin_rig(scene)
    with pytest.raises(rig_state.RigError, match="single frame"):
        pipeline.prepare(rig)
    with pytest.raises(rig_state.RigError, match="select an armature"):
        pipeline.prepare(None)
    bpy.context.view_layer.objects.active = None
    assert not bpy.ops.trajevae.generate.poll()


def _grease_pencil(scene, points, times):
    data = bpy.data.grease_pencils.new("stroke")
    drawing = data.layers.new("Lines").frames.new(1).drawing
    drawing.add_strokes([len(points)])
    drawing.attributes["position"].data.foreach_set("vector", np.asarray(points, np.float32).ravel())
    for point, time in zip(drawing.strokes[0].points, times):
        point.delta_time = time
    obj = bpy.data.objects.new("stroke", data)
    scene.collection.objects.link(obj)
    return obj


def test_grease_pencil_stroke_followed_at_its_drawing_speed(scene):
    scene.frame_end = 61
    rig = blender_rigs.mannequin_rig(scene)
    start = blender_rigs.world_joints(rig)[JOINT_INDEX["RWrist"]]
    points = start + np.linspace(0.0, 1.0, 21)[:, None] * [0.0, -0.4, 0.3]
    times = np.concatenate([np.linspace(0.0, 1.5, 11), np.linspace(1.6, 2.0, 10)])  # slow, then fast
    stroke = _grease_pencil(scene, points, times)
    api.bind_curve(rig, "RWrist", stroke)
    targets = lambda job: job.given.targets["RWrist"]
    timed = targets(pipeline.prepare(rig, 2, 0))
    api.bind_curve(rig, "RWrist", stroke, use_drawing_speed=False)
    even = targets(pipeline.prepare(rig, 2, 0))
    travelled = lambda path: np.linalg.norm(path[30] - start) / np.linalg.norm(points[-1] - start)
    assert abs(travelled(even) - 0.5) < 0.02
    assert abs(travelled(timed) - (1.0 / 2.0 * 2.0 / 1.5) * 0.5) < 0.05  # half the time, a third of the way
    np.testing.assert_allclose(timed[-1], points[-1], atol=1e-6)
    api.bind_curve(rig, "RWrist", stroke)
    report = pipeline.generate_variants(rig, 2)
    print("grease pencil stroke: curve error (cm)", [round(100 * e, 2) for e in report.curve_error_m])
    assert all(error < 0.01 for error in report.curve_error_m)


def test_follow_path_constraint_counts_as_a_binding_and_is_restored(scene):
    rig = blender_rigs.mannequin_rig(scene)
    start = blender_rigs.world_joints(rig)[JOINT_INDEX["LWrist"]]
    path = blender_rigs.curve(scene, "constraint path", start + np.linspace(0, 1, 8)[:, None] * [0.1, -0.3, 0.2])
    constraint = rig.pose.bones["LWrist"].constraints.new('FOLLOW_PATH')
    constraint.target = path
    job = pipeline.prepare(rig, 2, 0)
    assert job.given.mask[:, JOINT_INDEX["LWrist"]].all()
    report = pipeline.finish(pipeline.infer(job) or job, rig)
    assert all(error < 0.01 for error in report.curve_error_m)
    scene.frame_set(10)
    assert constraint.influence == 0.0  # the variant plays without the constraint pulling twice
    api.restore_original(rig)
    scene.frame_set(11)
    assert constraint.influence == 1.0


def test_progress_runs_to_the_end_through_every_stage(scene):
    rig = blender_rigs.mannequin_rig(scene)
    job = pipeline.prepare(rig, 3, 0)
    seen = []
    pipeline.infer(job, on_progress=seen.append)
    writer = pipeline.Writer(job, rig)
    while not writer.done:
        writer.step(seconds=0.0)
        seen.append(writer.progress)
    assert seen == sorted(seen) and seen[0] > 0.0 and seen[-1] == pytest.approx(1.0)
