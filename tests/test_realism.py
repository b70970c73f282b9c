"""Realism measures on real motion capture, and on the same poses broken by hand."""

import numpy as np
import pytest
import torch

from model_runtime import augment, joint_angles, realism
from model_runtime.data import dataset
from model_runtime.skeleton import JOINT_INDEX


@pytest.fixture(scope="module")
def validation_poses(all_clips, manifest):
    """Every 10th frame of the validation subjects (N, 17, 3): poses the limits were not fitted on."""
    _, validation = dataset.split_by_subject(all_clips, manifest)
    return np.concatenate([c.positions for c in validation])[::10].astype(np.float32)


def _cosine(poses, name):
    return realism.joint_angle_cosines(torch.from_numpy(poses)).numpy()[:, realism.ANGLE_NAMES.index(name)]


def test_angle_cosines_by_hand(validation_poses):
    poses = validation_poses[:50].copy()
    shoulder, elbow, wrist = (JOINT_INDEX[n] for n in ("LShoulder", "LElbow", "LWrist"))
    poses[:, wrist] = poses[:, elbow] + (poses[:, elbow] - poses[:, shoulder])  # a straight arm
    np.testing.assert_allclose(_cosine(poses, "left_elbow"), 1.0, atol=1e-5)
    upper = poses[:, elbow] - poses[:, shoulder]
    across = np.cross(upper, [0.0, 0.0, 1.0])
    poses[:, wrist] = poses[:, elbow] + across  # forearm at a right angle to the upper arm
    np.testing.assert_allclose(_cosine(poses, "left_elbow"), 0.0, atol=1e-5)


def test_captured_poses_keep_within_the_angle_limits_and_backward_knees_do_not(validation_poses):
    limits = realism.load_angle_limits()
    assert realism.share_outside_limits(validation_poses, limits) < 0.03
    hip, knee, foot = (JOINT_INDEX[n] for n in ("LHip", "LKnee", "LFoot"))
    bent = validation_poses[_cosine(validation_poses, "left_knee") < 0.8].copy()
    assert len(bent) > 100 and realism.share_outside_limits(bent, limits) < 0.05
    # the knee mirrored through the hip-ankle line: the same bone lengths, the leg bent backwards
    along = bent[:, foot] - bent[:, hip]
    along /= np.linalg.norm(along, axis=-1, keepdims=True)
    on_line = bent[:, hip] + ((bent[:, knee] - bent[:, hip]) * along).sum(-1, keepdims=True) * along
    bent[:, knee] = 2.0 * on_line - bent[:, knee]
    # the signed hinge tells a knee bent backwards from one bent forwards (a bare cosine of the
    # hinge axis caught 0.10 once mocap-extra's breakdance and crawls widened its range)
    assert realism.share_outside_limits(bent, limits) > 0.8


def test_numpy_angles_are_torch_angles(validation_poses):
    """The add-on screens its variants in numpy with the angles training uses in torch."""
    limits = realism.load_angle_limits()
    poses = validation_poses[:500]
    np.testing.assert_allclose(joint_angles.joint_angle_cosines(poses),
                               realism.joint_angle_cosines(torch.from_numpy(poses)).numpy(), atol=1e-6)
    arrays = joint_angles.limit_arrays(joint_angles.read_limits(realism.ANGLE_LIMITS))
    np.testing.assert_allclose(joint_angles.angle_excess(poses, arrays),
                               realism.angle_excess(torch.from_numpy(poses), limits).numpy(), atol=1e-6)


def test_limits_are_open_at_a_cosines_pole_where_captured_poses_come_close(validation_poses):
    """A thigh along the trunk's forward normal (the hip flexed 90 degrees against the trunk, on the
    way into a crouch) is a natural pose, but few poses lie that close to one direction, so the 99.9th
    percentile of the cosine shut out a cone around it. With 1 % of captured poses turned to hold the
    left thigh 3 degrees off that normal, the fitted limit is open, not 0.9986."""
    poses = validation_poses.copy()
    turned = poses[: len(poses) // 100]
    hip, knee = JOINT_INDEX["LHip"], JOINT_INDEX["LKnee"]
    hips = turned[:, hip] - turned[:, JOINT_INDEX["RHip"]]
    spine = turned[:, JOINT_INDEX["Thorax"]] - turned[:, JOINT_INDEX["Hip"]]
    forward = np.cross(hips, spine)
    unit = lambda v: v / np.linalg.norm(v, axis=-1, keepdims=True)
    direction = np.cos(np.radians(3.0)) * unit(forward) + np.sin(np.radians(3.0)) * unit(spine)
    turned[:, knee] = turned[:, hip] + np.linalg.norm(turned[:, knee] - turned[:, hip], axis=-1, keepdims=True) * direction
    name = realism.ANGLE_NAMES.index("left_thigh_forward")
    assert np.percentile(_cosine(poses, "left_thigh_forward"), 99.9) > np.cos(np.radians(realism.POLE_DEG))
    assert realism.fit_angle_limits(poses)["high"][name] == 1.0
    assert realism.fit_angle_limits(validation_poses)["high"][name] < 1.0  # untouched away from the pole


def test_turn_is_the_angle_a_pose_was_turned_by_about_its_hips(validation_poses):
    poses = validation_poses[:40].astype(np.float64)
    angles = np.radians(np.linspace(-170.0, 170.0, len(poses)))
    hips = poses[:, :1]
    turned = hips + augment.rotate_about_z(poses - hips, angles)
    motion = np.stack([poses, turned + [0.7, -0.3, 0.05]], axis=1)  # (N, 2, 17, 3): turned, and moved on
    assert realism.turn(motion, poses) == pytest.approx(np.degrees(np.abs(angles)).mean(), abs=1e-6)
    assert realism.turn(poses[:, None], poses) == pytest.approx(0.0, abs=1e-9)
