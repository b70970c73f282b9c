"""Picking N distinct, plausible variants from a larger pool of the diverse sampler's motions.

Gumbel-softmax weights over M bases often give two samples the same dominant
basis, so a plain draw of N keeps near-duplicates (the minimum pairwise
distance of ../shared/papers/003 barely moves). The sampler therefore draws
``POOL_FACTOR`` x N candidates, drops the third that is least plausible (rigid
bones stretched, feet sliding while on the floor, relative to the rest of the
pool, or straying from the given curves and keys) and picks N of the rest by farthest-point selection, which maximises
the minimum pairwise distance greedily. numpy only, so Blender needs no torch.
"""

import numpy as np

from . import metrics
from .data.clips import NATIVE_FPS
from .skeleton import ankle_speed_on_floor, rigid_bone_lengths

POOL_FACTOR = 3  # candidates drawn per variant asked for
SCREENED_SHARE = 1.0 / 3.0  # least plausible share of the pool dropped before selection


def _relative(values):
    return values / max(float(np.median(values)), 1e-9)


def implausibility(candidates, initial, given=None, known=None):
    """Per candidate (P,): bone-length deviation, foot sliding and, where joints are given, their
    distance from the given positions, each relative to the pool's median.

    candidates (P, T, 17, 3) in metres at the model rate, as decoded (not yet pinned); initial
    (17, 3) holds the rig's bone lengths; given (T, 17, 3) and known (T, 17) as the model's input.
    """
    bones = np.abs(rigid_bone_lengths(candidates) - rigid_bone_lengths(initial)).mean(axis=(1, 2))
    speed, contact = ankle_speed_on_floor(candidates, NATIVE_FPS)  # (P, T-1, 2) each
    sliding = (speed * contact).sum(axis=(1, 2)) / np.maximum(contact.sum(axis=(1, 2)), 1)
    cost = _relative(bones) + _relative(sliding)
    if known is not None and known.any():
        straying = np.linalg.norm(candidates - given, axis=-1)[:, known > 0].mean(axis=1)
        cost += _relative(straying)
    return cost


def farthest_points(candidates, count, first=0):
    """Indices (count,) of candidates (P, T, 17, 3) chosen greedily to maximise the minimum pairwise
    distance, in the DLow protocol (root-relative poses), starting from ``first``."""
    distances = metrics.pairwise_distances(metrics.to_protocol(candidates))
    chosen = [first]
    nearest = distances[first].copy()
    for _ in range(count - 1):
        pick = int(np.argmax(nearest))
        chosen.append(pick)
        nearest = np.minimum(nearest, distances[pick])
    return np.array(chosen)


def distinct_plausible(candidates, initial, count, given=None, known=None):
    """Indices (count,) into candidates (P, T, 17, 3), P >= count: the implausible share dropped,
    then farthest points from the most plausible candidate. Arguments as ``implausibility``."""
    kept = max(count, len(candidates) - int(round(SCREENED_SHARE * len(candidates))))
    order = np.argsort(implausibility(candidates, initial, given, known), kind="stable")[:kept]
    return order[farthest_points(candidates[order], count)]
