"""Training augmentations that keep a motion plausible: turns about Z, left-right mirroring and rest-pose starts."""

import numpy as np

from .skeleton import FEET, JOINT_INDEX, PARENTS, UP_AXIS, facing, indices, mirror_permutation

_MIRROR = mirror_permutation()


def rotate_about_z(motion, angles):
    """Turn motions (B, ..., 3) about the Z axis through the origin by ``angles`` (B,) radians."""
    cos, sin = np.cos(angles), np.sin(angles)
    x, y = motion[..., 0], motion[..., 1]
    shape = (-1,) + (1,) * (motion.ndim - 2)
    out = motion.copy()
    out[..., 0] = cos.reshape(shape) * x - sin.reshape(shape) * y
    out[..., 1] = sin.reshape(shape) * x + cos.reshape(shape) * y
    return out


def mirror(motion):
    """Left-right mirror of motions (..., J, 3): x negated and left and right joints swapped."""
    out = motion[..., _MIRROR, :].copy()
    out[..., 0] *= -1.0
    return out


REST_BLEND_FRAMES = (15, 30)  # frames over which a rest start moves into the captured motion
REST_ARM_DROP_DEG = (0.0, 50.0)  # T pose (0) to A pose


def rest_start(motion, soles, rng):
    """Windows (B, 1 + T, 17, 3) starting from a rest pose of their own skeleton instead of their
    captured first pose, and their sole heights (B, 1 + T, 2) carried along.

    Rigs usually start in their rest pose (T or A), which no capture begins with. The rest pose
    stands upright where the captured one stood, facing the same way, its lower ankle at the
    window's lowest ankle height, the arms dropped by a random angle; over the next 15-30 frames
    every bone turns from its rest direction to its captured one (eased), so bone lengths stay
    exact and the motion reaches the captured frames by itself.
    """
    motion, soles = motion.copy(), soles.copy()
    parents = np.array(PARENTS)
    initial = motion[:, 0]
    forward = facing(initial)
    left = np.cross(UP_AXIS, forward)
    down = np.broadcast_to(-UP_AXIS, left.shape)
    drop = np.radians(rng.uniform(*REST_ARM_DROP_DEG, len(motion)))[:, None]
    arm = np.cos(drop) * left + np.sin(drop) * down
    shoulder = _unit(left + 0.3 * down)
    directions = np.zeros_like(initial)
    for name, direction in (("RHip", -left), ("LHip", left), ("RKnee", down), ("RFoot", down), ("LKnee", down),
                            ("LFoot", down), ("Spine", -down), ("Thorax", -down), ("Neck", -down), ("Head", -down),
                            ("LShoulder", shoulder), ("RShoulder", shoulder * [-1, -1, 1]), ("LElbow", arm),
                            ("LWrist", arm), ("RElbow", arm * [-1, -1, 1]), ("RWrist", arm * [-1, -1, 1])):
        directions[:, JOINT_INDEX[name]] = direction
    feet = indices(FEET)
    root = initial[:, 0].copy()
    root[:, 2] = _standing_hip_height(motion)
    frames = rng.integers(REST_BLEND_FRAMES[0], REST_BLEND_FRAMES[1] + 1)
    weight = np.arange(frames + 1) / frames
    weight = weight * weight * (3.0 - 2.0 * weight)  # smoothstep: 0 at the rest pose, 1 on the captured frame
    for t, w in enumerate(weight[:-1]):
        captured = motion[:, t]
        bones = captured[:, 1:] - captured[:, parents[1:]]
        turned = _unit((1.0 - w) * directions[:, 1:] + w * _unit(bones)) * np.linalg.norm(bones, axis=-1)[..., None]
        pose = np.empty_like(captured)
        pose[:, 0] = (1.0 - w) * root + w * captured[:, 0]
        for joint in range(1, len(parents)):
            pose[:, joint] = pose[:, parents[joint]] + turned[:, joint - 1]
        soles[:, t] += pose[:, feet, 2] - captured[:, feet, 2]
        motion[:, t] = pose
    return motion, soles


def stands_upright(motion):
    """Windows (B, 1 + T, 17, 3) whose first pose stands (hips at least 85 % of their standing height):
    the ones a rest start can lead into (not a crawl or a lying pose)."""
    return motion[:, 0, 0, 2] >= 0.85 * _standing_hip_height(motion)


def still_through_blend(motion, travel_m):
    """Windows (B, 1 + T, 17, 3) whose ankles stay within ``travel_m`` (horizontally) of where they
    stood over the longest rest-start blend: a rest start into a window that moves off at once
    slides its feet while its bones turn (rest-started validation windows: planted-height feet
    0.26 m/s over the first second, the capture's 0.14), and taught prior draws to glide from rest."""
    ankles = motion[:, :REST_BLEND_FRAMES[1] + 1, indices(FEET), :2]
    return np.linalg.norm(ankles - ankles[:, :1], axis=-1).max(axis=(1, 2)) < travel_m


def _standing_hip_height(motion):
    """Hip height (B,) of the windows' skeletons standing with straight legs on their lowest ankle height."""
    initial = motion[:, 0]
    legs = np.mean([np.linalg.norm(initial[:, JOINT_INDEX[a]] - initial[:, JOINT_INDEX[b]], axis=-1)
                    for a, b in (("RHip", "RKnee"), ("RKnee", "RFoot"), ("LHip", "LKnee"), ("LKnee", "LFoot"))],
                   axis=0) * 2.0
    return motion[:, :, indices(FEET), 2].min(axis=(1, 2)) + legs


def _unit(vectors):
    return vectors / np.maximum(np.linalg.norm(vectors, axis=-1, keepdims=True), 1e-9)
