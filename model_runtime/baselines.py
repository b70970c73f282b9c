"""Honest, tuned baselines for conditioned motion: what an animator would do without a model.

All work in the window frame (initial root at the ground-plane origin) on
motions (T, 17, 3), and pin the given joints onto their trajectories.
"""

import numpy as np

from . import augment, masks
from .skeleton import facing


def pin(motion, trajectories, mask):
    """Motions (..., T, J, 3) with known coordinates (mask (T, J, 3) or (T, J)) set to their given positions."""
    known = masks.per_coordinate(mask) > 0
    return np.where(known, trajectories, motion)


def pinned_pose(initial, trajectories, mask):
    """The initial pose (17, 3) carried along by the root, given joints pinned: (T, 17, 3).

    The root moves horizontally with the mean displacement of the joints known
    on each frame (and stays where it was on frames with none).
    """
    frames = mask.shape[0]
    shift = np.zeros((frames, 3))
    for t in range(frames):
        known = np.flatnonzero(mask[t])
        if len(known):
            shift[t, :2] = (trajectories[t, known, :2] - initial[known, :2]).mean(axis=0)
        elif t:
            shift[t] = shift[t - 1]
    return pin(initial[None] + shift[:, None], trajectories, mask)


def _yaw(pose):
    """Heading angle (radians) of a pose's facing direction, measured from +Y."""
    forward = facing(pose)
    return np.arctan2(-forward[..., 0], forward[..., 1])


class NearestNeighbour:
    """Motion matching: the training windows closest in initial pose and given trajectories.

    Windows are stored turned to face +Y; queries are turned the same way and
    matched on the squared distance of the initial pose plus the known joints
    over time (one matrix product for a whole batch of queries). The K best
    futures are shifted by the difference of initial poses (so they start from
    the query's pose, as a motion-matching blend would), turned back and
    pinned.
    """

    def __init__(self, windows):
        """windows: (N, 1 + T, 17, 3) training windows in the window frame."""
        self.windows = augment.rotate_about_z(windows, -_yaw(windows[:, 0])).astype(np.float32)
        self.features = self.windows.reshape(len(windows), -1)
        self.squared = self.features ** 2

    def query(self, initial, trajectories, mask, count):
        """The ``count`` best futures (B, count, T, 17, 3) for conditions initial (B, 17, 3),
        trajectories (B, T, 17, 3) sharing one mask (T, 17)."""
        angles = _yaw(initial)
        turned = augment.rotate_about_z(np.concatenate([initial[:, None], trajectories], axis=1), -angles)
        weight = np.concatenate([np.ones((1, mask.shape[1])), mask])  # the initial pose always counts
        weight = np.repeat(weight[..., None], 3, axis=-1).reshape(-1).astype(np.float32)
        query = turned.reshape(len(turned), -1).astype(np.float32)
        cost = (self.squared @ weight)[:, None] - 2.0 * self.features @ (query * weight).T  # (N, B), up to a constant
        best = np.argsort(cost, axis=0)[:count].T  # (B, count)
        futures = self.windows[best, 1:] + (turned[:, None, :1] - self.windows[best, :1])
        futures = augment.rotate_about_z(futures, angles)
        return pin(futures, trajectories[:, None], mask)
