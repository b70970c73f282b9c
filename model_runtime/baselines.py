"""Honest, tuned baselines for conditioned motion: what an animator would do without a model.

All work in the window frame (initial root at the ground-plane origin) on
motions (T, 17, 3), and pin the given joints onto their trajectories.
"""

import numpy as np

from . import augment
from .skeleton import JOINT_INDEX, facing


def pin(motion, trajectories, mask):
    """Motions (..., T, J, 3) with known joints (mask (T, J)) set to their given positions."""
    known = mask[..., None] > 0
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

    Windows are stored turned to face +Y; a query is turned the same way,
    matched on the squared distance of its initial pose plus its known joints
    over time. The K best futures are shifted by the difference of initial
    poses (so they start from the query's pose, as a motion-matching blend
    would), turned back and pinned.
    """

    def __init__(self, windows):
        """windows: (N, 1 + T, 17, 3) training windows in the window frame."""
        self.windows = augment.rotate_about_z(windows, -_yaw(windows[:, 0])).astype(np.float32)
        self.initial = self.windows[:, 0].reshape(len(windows), -1)

    def query(self, initial, trajectories, mask, count):
        """The ``count`` best futures (count, T, 17, 3) for one condition."""
        angle = _yaw(initial)
        turn = lambda m: augment.rotate_about_z(m[None], np.array([-angle]))[0]
        initial_turned, trajectories_turned = turn(initial), turn(trajectories)
        cost = ((self.initial - initial_turned.reshape(-1)) ** 2).sum(axis=1)
        frames, joints = np.nonzero(mask)
        if len(frames):
            given = self.windows[:, 1 + frames, joints]  # (N, known, 3)
            cost = cost + ((given - trajectories_turned[frames, joints]) ** 2).sum(axis=(1, 2))
        best = np.argsort(cost)[:count]
        futures = self.windows[best, 1:] + (initial_turned - self.windows[best, 0])[:, None]
        futures = augment.rotate_about_z(futures, np.full(len(best), angle))
        return pin(futures, trajectories, mask)
