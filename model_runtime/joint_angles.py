"""Joint angles of the 17-joint skeleton as GSPS measures them, on numpy arrays or torch tensors.

Angles are cosines between body-part directions and plane normals, so they need no rig-specific
joint frames. Training's realism terms (torch, ``realism``) and the add-on's screening of its
candidate variants (numpy, ``selection``) use the same code: one definition of a pose outside the
limits fitted on the training data (``realism.fit_angle_limits``; each weights folder ships its own
as angle_limits.json).
"""

import json
from pathlib import Path

import numpy as np

from .skeleton import JOINT_INDEX

OFF_LIMIT_TOLERANCE = 1e-3  # cosine beyond a limit before a frame counts as outside it
ANGLE_NAMES = (
    "spine_vs_hips", "thorax_twist", "head_vs_neck", "neck_vs_spine",
    "left_thigh_forward", "right_thigh_forward", "left_thigh_sideways", "right_thigh_sideways",
    "left_knee", "right_knee", "left_knee_hinge", "right_knee_hinge",
    "left_upper_arm_forward", "right_upper_arm_forward", "left_elbow", "right_elbow",
)


def _norm(v):
    """Length over the leading axis, with a finite gradient at zero (a straight knee's hinge axis)."""
    return ((v * v).sum(0) + 1e-16) ** 0.5


def _cos(a, b):
    return (a * b).sum(0) / (_norm(a) * _norm(b))


def _cross(a, b):
    """Cross products of coordinate-first vectors (3, ...)."""
    return _stack([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]], 0)


def _stack(parts, axis):
    if isinstance(parts[0], np.ndarray):
        return np.stack(parts, axis=axis)
    import torch  # a tensor came in, so torch is loaded already; the add-on passes numpy only

    return torch.stack(parts, dim=axis)


def _coordinates_first(poses):
    """Poses (..., 17, 3) as (3, 17, ...), contiguous: each joint one block, so a dot product adds
    three whole arrays (28x faster than reducing a trailing axis of 3 on pools of motions)."""
    if isinstance(poses, np.ndarray):
        return np.ascontiguousarray(np.moveaxis(np.moveaxis(poses, -1, 0), -1, 1))
    return poses.movedim(-1, 0).movedim(-1, 1).contiguous()


def _hinge(thigh, shin, hips):
    """The knee's signed bend: sin(bend) x cos(hinge axis, hip line), positive bent forwards.

    Scaled by the bend, so a nearly straight knee (whose hinge axis is noise) reads near 0 and
    the fitted range tells a knee bent backwards from one bent forwards (a bare cosine of the
    axis spans -1..1 over straight legs and caught 10 % of backward knees).
    """
    return (_cross(thigh, shin) * hips).sum(0) / (_norm(thigh) * _norm(shin) * _norm(hips))


def joint_angle_cosines(poses):
    """Cosines of the ``ANGLE_NAMES`` angles for poses (..., 17, 3): (..., 16); the knee hinges
    are signed bends (``_hinge``)."""
    coords = _coordinates_first(poses)
    p = {name: coords[:, i] for name, i in JOINT_INDEX.items()}
    spine, hips = p["Thorax"] - p["Hip"], p["LHip"] - p["RHip"]
    forward = _cross(hips, spine)  # hip plane normal, facing
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
    return _stack(cosines, -1)


def angle_excess(poses, limits):
    """How far each angle's cosine lies outside its range (``limits``: (low, high) (16,) of the
    poses' kind, numpy or torch), 0 inside: (..., 16)."""
    low, high = limits
    cosines = joint_angle_cosines(poses)
    return (low - cosines).clip(min=0) + (cosines - high).clip(min=0)


def read_limits(path):
    """{"names", "low", "high"} of an angle_limits.json, checked to be for ``ANGLE_NAMES``."""
    limits = json.loads(Path(path).read_text())
    if limits["names"] != list(ANGLE_NAMES) or not len(limits["low"]) == len(limits["high"]) == len(ANGLE_NAMES):
        raise ValueError(f"{Path(path).name} holds joint-angle limits for other angles")
    return limits


def limit_arrays(limits):
    """(low, high) float32 arrays (16,) of limits as ``read_limits`` gives them."""
    return np.array(limits["low"], np.float32), np.array(limits["high"], np.float32)
