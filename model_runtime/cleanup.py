"""What turns the model's variants into animation an animator keeps, at the scene's frame rate in
the model's frame (metres, Z up, floor at z = 0). Motions are (V, F, 17, 3)."""

import numpy as np

from .skeleton import JOINT_INDEX

J = JOINT_INDEX


def pin(motion, targets, keyed):
    """Motion with each curve's joint on its target (F, 3) on every frame ({joint: targets}) and
    each keyed joint on its key ({frame index: {joint: (3,)}}): in place, returned."""
    for index, joints in keyed.items():
        for joint, position in joints.items():
            motion[:, index, J[joint]] = position
    for joint, path in targets.items():
        motion[:, :, J[joint]] = path
    return motion


def tidy(motion, fps, initial, targets, keyed):
    """(motion, contacts (V, F, 2) of the right and left feet): the variants on their curves and
    keys."""
    return pin(motion, targets, keyed), np.zeros(motion.shape[:2] + (2,), dtype=bool)
