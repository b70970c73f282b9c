"""Foot contacts: when a foot is planted, labelled on captured motion for training.

A foot is planted on a frame when its sole (the lowest of its ankle and toe,
``data.clips.Clip.soles``) is within ``CONTACT_HEIGHT_M`` of the floor and its
ankle moves horizontally slower than ``CONTACT_SPEED_M_S``. The model learns
to predict these labels, and training holds planted feet still with them.
"""

import numpy as np

from .skeleton import FEET, indices

CONTACT_HEIGHT_M = 0.04
CONTACT_SPEED_M_S = 0.5  # captured walks: planted ankles under 0.2 m/s, swinging ones 1-5 m/s


def foot_contacts(motion, soles, fps):
    """Planted feet (..., T, 2) bool (right, left) of motion (..., T, 17, 3) with sole heights (..., T, 2)."""
    ankles = motion[..., indices(FEET), :2]
    speed = np.linalg.norm(np.diff(ankles, axis=-3), axis=-1) * fps  # (..., T - 1, 2)
    padded = np.concatenate([speed[..., :1, :], speed, speed[..., -1:, :]], axis=-2)
    frame_speed = 0.5 * (padded[..., :-1, :] + padded[..., 1:, :])  # mean of the steps into and out of a frame
    return (soles < CONTACT_HEIGHT_M) & (frame_speed < CONTACT_SPEED_M_S)
