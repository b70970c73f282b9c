"""A path drawn on the floor and bound to the rig's root or hips: the hips' horizontal path (issue 17)."""

import numpy as np
import pytest

import blender_rigs
from model_runtime import shot
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
    path = job.given.targets["Hip"]
    speed = np.linalg.norm(np.diff(path[:, :2], axis=0), axis=-1) * 30
    print(f"ground path: speed at the start {speed[0]:.3f}, cruising {speed[60]:.2f}, at the end {speed[-1]:.3f} m/s")
    assert speed[0] < 0.1 * speed[60] and speed[-1] < 0.1 * speed[60]  # the walk starts and stops eased
    assert abs(speed[40:80].mean() - 4.0 / (4.0 - shot.GROUND_EASE_S)) < 0.05  # 4 m in 4 s, half a second easing each end
    np.testing.assert_allclose(path[-1], floor_path[-1], atol=1e-9)


def test_a_hip_curve_at_hip_height_gives_all_three_coordinates(scene, rigify):
    hips = blender_rigs.world_joints(rigify)[HIP]
    raised = hips + np.linspace(0.0, 1.0, 10)[:, None] * [0.0, -0.5, 0.1]
    api.bind_curve(rigify, "torso", blender_rigs.curve(scene, "sway", raised))
    job = pipeline.prepare(rigify, 2, 0)
    np.testing.assert_array_equal(job.given.axes["Hip"], [True, True, True])
    assert job.given.mask[:, HIP].all()
