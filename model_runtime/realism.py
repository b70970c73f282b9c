"""Realism measures and losses (GSPS): joint-angle limits from data, rigid bone lengths, foot skating.

Angles are ``joint_angles``'s cosines. Valid ranges are the 0.1 to 99.9
percentiles over training poses (``fit_angle_limits``), which ignores a few
capture glitches, open at a pole (``POLE_DEG``); the shipped ranges live in
assets/angle_limits.json.
"""

from pathlib import Path

import numpy as np
import torch

from . import joint_angles
from .joint_angles import ANGLE_NAMES, joint_angle_cosines
from .skeleton import FEET, FLOOR_CONTACT_M, indices, rigid_bone_lengths

ANGLE_LIMITS = Path(__file__).resolve().parents[1] / "assets" / "angle_limits.json"
# A cosine's percentile within this many degrees of +-1 is no limit: few poses lie that close to a
# direction (the solid angle shrinks to nothing at the pole), so the percentile there shut out a
# 3-4 degree cone of natural poses: a crouch's thigh passing along the trunk's forward normal (hip
# flexed 90 degrees against the trunk) counted as off the limits on 5 frames before the key.
POLE_DEG = 5.0


def fit_angle_limits(poses, low=0.1, high=99.9):
    """{"names", "low", "high"} valid cosine ranges from training poses (N, 17, 3), open where a
    percentile lies within POLE_DEG of a pole."""
    cosines = joint_angle_cosines(torch.as_tensor(poses, dtype=torch.float64)).numpy()
    finite = cosines[np.all(np.isfinite(cosines), axis=1)]
    pole = np.cos(np.radians(POLE_DEG))
    lows, highs = np.percentile(finite, low, axis=0), np.percentile(finite, high, axis=0)
    return {"names": list(ANGLE_NAMES), "low": np.where(lows < -pole, -1.0, lows).tolist(),
            "high": np.where(highs > pole, 1.0, highs).tolist()}


def load_angle_limits(path=ANGLE_LIMITS):
    """(low, high) tensors (16,) of the ranges in a JSON file (the shipped ones unless told)."""
    return angle_limit_tensors(joint_angles.read_limits(path))


def angle_limit_tensors(limits):
    """(low, high) tensors (16,) of limits as ``fit_angle_limits`` gives them."""
    assert limits["names"] == list(ANGLE_NAMES), "angle limits were fitted for other angles"
    return torch.tensor(limits["low"]), torch.tensor(limits["high"])


def angle_excess(poses, limits):
    """``joint_angles.angle_excess`` of poses (..., 17, 3) with the limits (tensors) on their device and dtype."""
    return joint_angles.angle_excess(poses, tuple(bound.to(poses) for bound in limits))


def angle_limit_loss(poses, limits):
    """GSPS angle loss: squared distance outside the valid ranges, summed over angles (...,)."""
    return (angle_excess(poses, limits) ** 2).sum(-1)


def share_outside_limits(motion, limits, tolerance=joint_angles.OFF_LIMIT_TOLERANCE):
    """Share of frames (motion (..., T, 17, 3)) with any angle outside its range."""
    excess = angle_excess(torch.as_tensor(motion, dtype=torch.float32), limits)  # a float64 copy cost 2x
    return float((excess.amax(-1) > tolerance).double().mean())


def bone_length_deviation(motion, initial):
    """Mean absolute deviation (m) of rigid bone lengths in motion (..., T, 17, 3) from initial (..., 17, 3)."""
    lengths, rest = (rigid_bone_lengths(np.asarray(a)).astype(np.float64) for a in (motion, initial))
    return float(np.abs(lengths - rest[..., None, :]).mean())  # lengths, not poses, in float64: 10x less copying


def planted_skating_loss(motion, initial, planted, fps):
    """Squared horizontal speed ((m/s)^2) of planted feet, summed over frames and feet: (B, ...) for
    motions (B, ..., T, 17, 3) after initial poses (B, 17, 3), ``planted`` (B, ..., T, 2) weights in
    [0, 1] (right, left; labels, or the model's own contact predictions)."""
    feet = indices(FEET)
    start = initial[:, feet].reshape(len(initial), *(1,) * (motion.ndim - 3), 2, 3).expand(*motion.shape[:-3], 1, 2, 3)
    ankles = torch.cat([start, motion[..., feet, :]], dim=-3)
    speed = (torch.diff(ankles[..., :2], dim=-3) ** 2).sum(-1) * fps ** 2
    return (planted * speed).flatten(-2).sum(-1)


def floor_loss(motion, floor):
    """Squared depth of ankles below ``floor`` (B, ..., 1, 2) (per foot), summed over frames and feet:
    (B, ...) for motions (B, ..., T, 17, 3)."""
    return (torch.relu(floor - motion[..., indices(FEET), 2]) ** 2).flatten(-2).sum(-1)


def foot_skating(motion, fps, contact_m=FLOOR_CONTACT_M):
    """Mean horizontal ankle speed (m/s) over the frames of motion (..., T, 17, 3) where an ankle is
    within ``contact_m`` of its lowest height in the motion (ankles sit above the sole, so the floor
    is the motion's own lowest ankle height)."""
    feet = np.asarray(np.asarray(motion)[..., indices(FEET), :], np.float64)  # (..., T, 2, 3): ankles only
    speed = np.linalg.norm(np.diff(feet[..., :2], axis=-3), axis=-1) * fps
    contact = feet[..., 1:, :, 2] < feet[..., 2].min(axis=-2, keepdims=True) + contact_m
    return float(speed[contact].mean()) if contact.any() else 0.0


def turn(motion, initial):
    """Mean absolute turn about Z (degrees) from initial poses (..., 17, 3) to the last frames of
    motion (..., T, 17, 3): the yaw that best fits the hips-relative horizontal pose of the one onto
    the other over all joints (least squares). Captured windows of 2 s turn 28 degrees on average."""
    before = np.asarray(initial, np.float64)[..., :2]
    after = np.asarray(motion, np.float64)[..., -1, :, :2]
    before, after = before - before[..., :1, :], after - after[..., :1, :]
    cross = (before[..., 0] * after[..., 1] - before[..., 1] * after[..., 0]).sum(-1)
    dot = (before * after).sum((-1, -2))
    return float(np.degrees(np.abs(np.arctan2(cross, dot))).mean())
