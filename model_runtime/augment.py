"""Training augmentations that keep a motion plausible: turns about Z and left-right mirroring."""

import numpy as np

from .skeleton import mirror_permutation

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
