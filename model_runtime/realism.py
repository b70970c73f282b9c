"""Realism measures and losses (GSPS): joint-angle limits from data, rigid bone lengths, foot skating.

Angles are cosines between body-part directions and plane normals, so they
need no rig-specific joint frames. Valid ranges are the 0.1 to 99.9
percentiles over training poses (``fit_angle_limits``), which ignores a few
capture glitches; the shipped ranges live in assets/angle_limits.json.
"""

import json
from pathlib import Path

import numpy as np
import torch

from .skeleton import FEET, FLOOR_CONTACT_M, JOINT_INDEX, indices, rigid_bone_lengths

ANGLE_LIMITS = Path(__file__).resolve().parents[1] / "assets" / "angle_limits.json"
ANGLE_NAMES = (
    "spine_vs_hips", "thorax_twist", "head_vs_neck", "neck_vs_spine",
    "left_thigh_forward", "right_thigh_forward", "left_thigh_sideways", "right_thigh_sideways",
    "left_knee", "right_knee", "left_knee_hinge", "right_knee_hinge",
    "left_upper_arm_forward", "right_upper_arm_forward", "left_elbow", "right_elbow",
)


def _norm(v):
    """Length over the leading axis, with a finite gradient at zero (a straight knee's hinge axis)."""
    return torch.sqrt((v * v).sum(0) + 1e-16)


def _cos(a, b):
    return (a * b).sum(0) / (_norm(a) * _norm(b))


def _hinge(thigh, shin, hips):
    """The knee's signed bend: sin(bend) x cos(hinge axis, hip line), positive bent forwards.

    Scaled by the bend, so a nearly straight knee (whose hinge axis is noise) reads near 0 and
    the fitted range tells a knee bent backwards from one bent forwards (a bare cosine of the
    axis spans -1..1 over straight legs and caught 10 % of backward knees).
    """
    return (torch.cross(thigh, shin, dim=0) * hips).sum(0) / (_norm(thigh) * _norm(shin) * _norm(hips))


def joint_angle_cosines(poses):
    """Cosines of the ``ANGLE_NAMES`` angles for poses (..., 17, 3): (..., 16); the knee hinges
    are signed bends (``_hinge``).

    Coordinates go first, (3, 17, ...), so each joint is one contiguous block and a dot product
    adds three whole arrays (28x faster than reducing a trailing axis of 3 on pools of motions).
    """
    coords = poses.movedim(-1, 0).movedim(-1, 1).contiguous()
    p = {name: coords[:, i] for name, i in JOINT_INDEX.items()}
    spine, hips = p["Thorax"] - p["Hip"], p["LHip"] - p["RHip"]
    forward = torch.cross(hips, spine, dim=0)  # hip plane normal, facing
    shoulders = p["LShoulder"] - p["RShoulder"]
    cosines = [_cos(spine, hips), _cos(shoulders, hips), _cos(p["Head"] - p["Neck"], p["Neck"] - p["Thorax"]),
               _cos(p["Neck"] - p["Thorax"], spine)]
    for side in "LR":
        cosines.append(_cos(p[side + "Knee"] - p[side + "Hip"], forward))
    for side in "LR":
        cosines.append(_cos(p[side + "Knee"] - p[side + "Hip"], hips))
    for side in "LR":
        cosines.append(_cos(p[side + "Foot"] - p[side + "Knee"], p[side + "Knee"] - p[side + "Hip"]))
    for side in "LR":  # a knee bends one way only: its hinge axis stays along the hip line
        thigh, shin = p[side + "Knee"] - p[side + "Hip"], p[side + "Foot"] - p[side + "Knee"]
        cosines.append(_hinge(thigh, shin, hips))
    for side in "LR":
        cosines.append(_cos(p[side + "Elbow"] - p[side + "Shoulder"], forward))
    for side in "LR":
        cosines.append(_cos(p[side + "Wrist"] - p[side + "Elbow"], p[side + "Elbow"] - p[side + "Shoulder"]))
    return torch.stack(cosines, dim=-1)


def fit_angle_limits(poses, low=0.1, high=99.9):
    """{"names", "low", "high"} valid cosine ranges from training poses (N, 17, 3)."""
    cosines = joint_angle_cosines(torch.as_tensor(poses, dtype=torch.float64)).numpy()
    finite = cosines[np.all(np.isfinite(cosines), axis=1)]
    return {"names": list(ANGLE_NAMES), "low": np.percentile(finite, low, axis=0).tolist(),
            "high": np.percentile(finite, high, axis=0).tolist()}


def load_angle_limits(path=ANGLE_LIMITS):
    """(low, high) tensors (16,) of the ranges in a JSON file (the shipped ones unless told)."""
    return angle_limit_tensors(json.loads(Path(path).read_text()))


def angle_limit_tensors(limits):
    """(low, high) tensors (16,) of limits as ``fit_angle_limits`` gives them."""
    assert limits["names"] == list(ANGLE_NAMES), "angle limits were fitted for other angles"
    return torch.tensor(limits["low"]), torch.tensor(limits["high"])


def angle_excess(poses, limits):
    """How far each angle's cosine lies outside its range, 0 inside: (..., 16)."""
    low, high = limits
    cosines = joint_angle_cosines(poses)
    return torch.relu(low.to(cosines) - cosines) + torch.relu(cosines - high.to(cosines))


def angle_limit_loss(poses, limits):
    """GSPS angle loss: squared distance outside the valid ranges, summed over angles (...,)."""
    return (angle_excess(poses, limits) ** 2).sum(-1)


def share_outside_limits(motion, limits, tolerance=1e-3):
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
