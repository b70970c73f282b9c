"""Known-joint masks (T, J): which joint positions are given on which frames.

One model serves drawn curves (a joint known on every frame), keyed poses
(some joints on some frames), end-pose control (the whole last frame) and
nothing at all (k = 0). Training mixes these families; evaluation uses the
paper's order of adding trajectories.
"""

import numpy as np

from .skeleton import JOINT_INDEX, NUM_JOINTS

EVALUATION_ORDER = ("RFoot", "LFoot", "RWrist", "LWrist")
BERNOULLI_KEEP = 0.15  # the paper: each joint masked with p = 0.85, for all frames


def trajectory_mask(joint_names, frames):
    """Mask (T, J) with the named joints known on every frame."""
    mask = np.zeros((frames, NUM_JOINTS), dtype=np.float32)
    mask[:, [JOINT_INDEX[name] for name in joint_names]] = 1.0
    return mask


def evaluation_mask(k, frames):
    """The first k joints of ``EVALUATION_ORDER`` as full trajectories (T, J)."""
    return trajectory_mask(EVALUATION_ORDER[:k], frames)


def sample_training_masks(batch, frames, rng):
    """A batch of training masks (B, T, J) drawn from all families."""
    masks = np.zeros((batch, frames, NUM_JOINTS), dtype=np.float32)
    family = rng.choice(5, size=batch, p=[0.35, 0.25, 0.15, 0.15, 0.10])
    for b, kind in enumerate(family):
        mask = masks[b]
        if kind == 0:  # the paper's constant-in-time Bernoulli trajectories
            mask[:, rng.random(NUM_JOINTS) < BERNOULLI_KEEP] = 1.0
        elif kind == 1:  # the evaluation order, sometimes with the root path
            mask[:] = evaluation_mask(rng.integers(0, len(EVALUATION_ORDER) + 1), frames)
            if rng.random() < 0.3:
                mask[:, JOINT_INDEX["Hip"]] = 1.0
        elif kind == 2:  # sparse keys: a few frames, whole or partial poses
            for frame in rng.choice(frames, size=rng.integers(1, 4), replace=False):
                mask[frame] = 1.0 if rng.random() < 0.5 else (rng.random(NUM_JOINTS) < 0.5)
        elif kind == 3:  # end pose, with or without trajectories
            mask[:, rng.random(NUM_JOINTS) < BERNOULLI_KEEP / 2] = 1.0
            mask[-1] = 1.0
        else:  # joints known on part of the window only
            for joint in np.flatnonzero(rng.random(NUM_JOINTS) < 0.25):
                start = rng.integers(0, frames - 1)
                mask[start: rng.integers(start + 1, frames + 1), joint] = 1.0
    return masks
