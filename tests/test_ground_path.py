"""A path drawn on the floor and bound to the rig's root or hips: the hips' horizontal path (issue 17)."""

import bpy  # noqa: F401  (first: blender_rigs imports Blender's own modules)
import numpy as np
import pytest

import blender_rigs
from model_runtime import animation_quality as quality
from model_runtime import footsteps, shot
from model_runtime.skeleton import JOINT_INDEX
from trajevae_addon import api, pipeline

HIP = JOINT_INDEX["Hip"]


@pytest.fixture
def rigify(scene):
    scene.frame_start, scene.frame_end = 1, 121
    rig = blender_rigs.rigify_rig(scene)
    yield rig
    blender_rigs.disable_rigify()


def test_a_path_on_the_floor_bound_to_the_root_gives_the_hips_horizontal_path(scene, rigify):
    hips = blender_rigs.world_joints(rigify)[HIP]
    along = np.linspace(0.0, 1.0, 30)[:, None]
    floor_path = np.column_stack([np.full(30, hips[0]), hips[1] - 4.0 * along[:, 0], np.zeros(30)])
    api.bind_curve(rigify, "root", blender_rigs.curve(scene, "walk", floor_path))  # Rigify's root carries no joint
    job = pipeline.prepare(rigify, 2, 0)  # the path lies 0.9 m under the hips: not refused as a jump onto it
    np.testing.assert_array_equal(job.given.axes["Hip"], [True, True, False])
    np.testing.assert_array_equal(job.given.mask[:, HIP].max(axis=0), [1.0, 1.0, 0.0])
    fps = scene.render.fps / scene.render.fps_base
    seconds = 120 / fps
    quickest, slowest = 4.0 / (seconds - np.array(footsteps.EASE_SPREAD))  # 4 m, easing in and out
    for path in job.given.targets["Hip"]:  # each variant walks the path in its own time
        speed = np.linalg.norm(np.diff(path[:, :2], axis=0), axis=-1) * fps
        print(f"ground path: speed at the start {speed[0]:.3f}, cruising {speed[50:70].mean():.2f} "
              f"({quickest:.2f}-{slowest:.2f}), at the end {speed[-1]:.3f} m/s")
        assert speed[0] < 0.1 * speed[60] and speed[-1] < 0.1 * speed[60]  # the walk starts and stops eased
        assert 0.99 * quickest < speed[50:70].mean() < 1.03 * slowest  # the hips sway a little as well
        np.testing.assert_allclose(path[-1], floor_path[-1], atol=1e-9)


def test_a_hip_curve_at_hip_height_gives_all_three_coordinates(scene, rigify):
    hips = blender_rigs.world_joints(rigify)[HIP]
    raised = hips + np.linspace(0.0, 1.0, 10)[:, None] * [0.0, -0.5, 0.1]
    api.bind_curve(rigify, "torso", blender_rigs.curve(scene, "sway", raised))
    job = pipeline.prepare(rigify, 2, 0)
    np.testing.assert_array_equal(job.given.axes["Hip"], [True, True, True])
    assert job.given.mask[:, HIP].all()


def test_feet_drawn_on_the_floor_without_timing_plant_and_swing_in_turn(scene):
    """Two straight 3 m foot paths on the floor (plain curves: no drawing times) would glide at
    constant speed; instead each foot stands still for most of each stride and swings between
    plants, lifted at mid-swing, the left half a stride after the right."""
    scene.frame_start, scene.frame_end = 1, 121
    rig = blender_rigs.mannequin_rig(scene)
    joints = blender_rigs.world_joints(rig)
    forward = np.array([0.0, -1.0, 0.0])
    for foot in ("RFoot", "LFoot"):
        start = joints[JOINT_INDEX[foot]] * [1.0, 1.0, 0.0]  # drawn on the floor under the ankle
        line = start + np.linspace(0.0, 3.0, 20)[:, None] * forward
        api.bind_curve(rig, api.map_rig(rig)[foot], blender_rigs.curve(scene, f"{foot} steps", line))
    job = pipeline.prepare(rig, 2, 0)
    speed, lift = {}, {}
    for foot in ("RFoot", "LFoot"):
        target = job.given.targets[foot]
        speed[foot] = np.linalg.norm(np.diff(target[:, :2], axis=0), axis=-1) * 30
        lift[foot] = target[:, 2] - joints[JOINT_INDEX[foot], 2]
        np.testing.assert_allclose(target[-1, :2], (joints[JOINT_INDEX[foot]] + 3.0 * forward)[:2], atol=1e-6)
    planted = {foot: speed[foot] < 1e-6 for foot in speed}
    print(f"planted share: right {planted['RFoot'].mean():.2f}, left {planted['LFoot'].mean():.2f}; "
          f"top speed {max(s.max() for s in speed.values()):.2f} m/s, lift {max(l.max() for l in lift.values()):.3f} m")
    assert all(0.5 < share.mean() < 0.75 for share in planted.values())  # stance most of each stride
    assert not (~planted["RFoot"] & ~planted["LFoot"]).any()  # never both feet in the air: a walk
    assert all(0.09 < l.max() < 0.11 and l.min() > -1e-9 for l in lift.values())
    assert all(np.isclose(l[np.r_[planted[f], False]], 0.0).all() for f, l in lift.items())  # on the ground when planted


def test_keys_on_the_root_are_waypoints_of_a_walk(scene, rigify):
    """Rigify's root keyed at three frames along the floor (2 m, then 4 m, the middle one 0.5 m to
    the side): the hips walk a smooth path through the keys (their horizontal position on every
    frame, the model choosing their height), on the planned steps, and pass each key on its frame
    as played."""
    hips = blender_rigs.world_joints(rigify)[HIP]
    _, toes = blender_rigs.played(rigify, [1])
    root = rigify.pose.bones["root"]
    for frame, (side, along) in ((1, (0.0, 0.0)), (61, (0.5, 2.0)), (121, (0.0, 4.0))):
        root.location = (side, along, 0.0)  # the root bone's Y points along the floor
        root.keyframe_insert("location", frame=frame)
    scene.frame_set(1)
    job = pipeline.prepare(rigify, 2, 0)
    assert sorted(job.request.keys) == [61, 121]
    np.testing.assert_array_equal(job.given.axes["Hip"], [True, True, False])
    assert job.given.mask[:, HIP, :2].all() and not job.given.mask[:, HIP, 2].any() and job.given.walks is not None
    for frame in (61, 121):
        np.testing.assert_allclose(job.given.targets["Hip"][:, frame - 1, :2],
                                   np.broadcast_to(job.request.keys[frame]["Hip"][:2], (2, 2)), atol=1e-6)
    floor = quality.floor_height(toes)
    for action in api.generate_variants(rigify, 2, 0):
        api.set_active_variant(rigify, action)
        joints, toes = blender_rigs.played(rigify, range(1, 122))
        passed = [float(np.linalg.norm((joints[frame - 1, HIP] - job.request.keys[frame]["Hip"])[:2])) for frame in (61, 121)]
        steps = quality.steps(toes, floor)
        print(f"hips from the keys {np.round(passed, 3)} m; steps {steps}, planted toes "
              f"{quality.planted_toe_speed(toes, scene.render.fps / scene.render.fps_base, floor):.2f} m/s, hips {quality.hip_height_share(joints, floor):.2f}")
        assert max(passed) < 0.01 and min(steps) >= 2 and quality.hip_height_share(joints, floor) > 0.8
    assert np.linalg.norm(job.request.keys[121]["Hip"][:2] - hips[:2]) > 3.9
