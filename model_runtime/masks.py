"""Known-coordinate masks (T, J, 3): which joint coordinates are given on which frames.

One model serves drawn curves (a joint known on every frame), keyed poses
(some joints on some frames), end-pose control (the whole last frame), ground
paths (the hips' horizontal position only: the model chooses their height),
a long shot's later windows (their first frames carried whole) and nothing at
all (k = 0). Training mixes these families; evaluation uses the
paper's order of adding trajectories. A joint mask (T, J) stands for all three
coordinates of each joint (``per_coordinate``).
"""

import numpy as np

from .skeleton import FEET, JOINT_INDEX, LOWER_BODY, NUM_JOINTS, indices

EVALUATION_ORDER = ("RFoot", "LFoot", "RWrist", "LWrist")
ROOT = JOINT_INDEX["Hip"]
BERNOULLI_KEEP = 0.15  # the paper: each joint masked with p = 0.85, for all frames
# Share of training masks whose first 1-CARRIED_FRAMES frames are carried: a later window of a long
# shot, which carries the previous window's last frames (``generation.generate``).
CARRIED_SHARE = 0.15
CARRIED_FRAMES = 20
HORIZONTAL = np.array([1.0, 1.0, 0.0], np.float32)  # the ground plane's coordinates
# Shares of the training mask families (``sample_training_masks``): Bernoulli trajectories, the
# evaluation order's curves, sparse keys, end poses, partial curves, ground paths, waypoints.
FAMILY_SHARES = (0.30, 0.22, 0.13, 0.13, 0.08, 0.10, 0.04)
GAIT_SPREAD_FRAMES = 15  # each side of a frame: a gait cycle takes about 1 s at 30 fps (``body_steps``)


def carried_legs():
    """What a later window of a long shot carries on each carried frame (17, 3): the legs and the
    hips' horizontal position; the upper body and the hips' height start afresh
    (``generation.anchored``)."""
    carry = np.zeros((NUM_JOINTS, 3), np.float32)
    carry[indices(LOWER_BODY)] = 1.0
    carry[ROOT, 2] = 0.0
    return carry


def per_coordinate(mask):
    """A mask (..., J, 3), numpy or torch; a joint mask (..., J) gives each joint's three coordinates."""
    if mask.shape[-1] != NUM_JOINTS:
        return mask
    if isinstance(mask, np.ndarray):
        return np.repeat(mask[..., None], 3, axis=-1)
    return mask[..., None].expand(*mask.shape, 3)


def body_steps(steps, mask, feet_lead=False):
    """The decoder's base step of every joint coordinate (B, T, J, 3), numpy or torch, from the given
    steps (B, T, J, 3) (zero where not given) and the mask (B, T, J, 3): a given joint's own step;
    for the unknown horizontal coordinates, the root's given step (a body given a ground path
    travels with it) and, with ``feet_lead`` (``ModelConfig.feet_lead``), on frames where the
    root's is not given, for every joint but the feet, the steps of the given feet's mean position
    averaged over about a gait cycle (``_spread_over_gait``): a walk's feet alternate between
    planted and swinging at twice the body's speed, and the body moves on between them. A foot
    not given stands where it is unless the network steps it (given the lead too, it glided)."""
    base = steps[..., ROOT, None, :]  # (B, T, 1, 3)
    if feet_lead:
        above_feet = np.ones((NUM_JOINTS, 1), np.float32)
        above_feet[indices(FEET)] = 0.0
        base = base + _feet_lead(steps, mask)[..., None, :] * _like(above_feet, mask)
    return steps + base * _like(HORIZONTAL, mask) * (1.0 - mask)


def _feet_lead(steps, mask):
    """``body_steps``' share from the given feet: (B, T, 3), zero where the root's horizontal
    position is given."""
    feet = indices(FEET)
    given = _numpy(mask)
    before = np.concatenate([np.ones_like(given[:, :1]), given[:, :-1]], axis=1)
    counted = (given[:, :, feet, 0] * before[:, :, feet, 0]).sum(-1, keepdims=True)  # (B, T, 1) feet with a step
    spread = _spread_over_gait(given.shape[1]) / np.maximum(counted, 1.0).transpose(0, 2, 1)  # (B, T, T)
    free = 1.0 - given[:, :, ROOT, :1]  # (B, T, 1)
    return (_like(spread, mask) @ steps[..., feet, :].sum(-2)) * _like(free, mask)


def _spread_over_gait(frames):
    """Weights (T, T) that turn a foot's steps into the steps of its position averaged over the
    frames within GAIT_SPREAD_FRAMES (before the window it stood at the initial pose, after it
    holds its last position): a body moves with its feet's mean position over the gait cycle around
    it, smoothly, and no faster where the window ends mid-stride."""
    times = np.arange(-1, frames)  # -1: the initial pose
    sources = np.clip(times[:, None] + np.arange(-GAIT_SPREAD_FRAMES, GAIT_SPREAD_FRAMES + 1), -1, frames - 1)
    # the mean position at frames -1..T-1 (F + 1, F) from steps 0..T-1: a position sums the steps up to it
    averaged = (sources[:, :, None] >= np.arange(frames)).mean(axis=1, dtype=np.float32)
    return np.diff(averaged, axis=0)


def following_given_feet(motion, trajectories, mask):
    """Decoded motions (B, count, T, J, 3), numpy or torch, moved along the ground, every joint
    together, by their feet's mean horizontal offset from the given feet (trajectories (B, T, J, 3),
    mask (B, T, J, 3) or (B, T, J)) on the frames where a foot is given: a body goes where its given
    feet go. Where the hips' horizontal position is given (a ground path, a walk's planned steps)
    the body already goes with them (``body_steps``) and is not moved.

    Between those frames the move is linear, from none at the initial pose and held after the
    last (``_between_given_frames``). The decoder's own fit of a given foot strays from its path
    (by 7 cm at the median and 28 cm at the 90th percentile of frames of training windows), and
    its body strays with it: with the foot pinned, its hip stood 1.5x the leg's length from it on
    1 % of validation frames, and that knee was straightened past its limits. Moved so before the
    completion stage (and the stage trained on decodes moved so), best-of-50 FDE with the right
    foot given went from 0.764 to 0.738 m, frames off the joint-angle limits from 1.8 % to 1.6 %.
    A foot off the floor moves the body along the ground only: a kick does not lift the hips.
    """
    feet, mask = indices(FEET), per_coordinate(mask)
    hips_given = mask[:, :, ROOT, 0]  # (B, T); x and y go together
    known = mask[:, :, feet, 0] * (1 - hips_given[..., None])  # (B, T, 2)
    count = known.sum(-1)[:, None, :, None]
    offset = ((trajectories[:, None, :, feet] - motion[..., feet, :]) * known[:, None, ..., None]).sum(-2)
    offset = offset / (count + (count == 0))  # (B, count, T, 3)
    weights = _between_given_frames(_numpy(mask[:, :, feet + [ROOT], 0]).max(-1) > 0)[:, None]
    moved = _like(weights, motion) @ offset
    return motion + (moved * _like(HORIZONTAL, motion))[..., None, :]


def _between_given_frames(given):
    """Weights (B, T, T) that spread values known on the ``given`` frames (B, T) to every frame:
    linear between given frames, from zero at the initial pose (the frame before the first) to the
    first given one, and held after the last; all zero where no frame is given."""
    batch, frames = given.shape
    weights = np.zeros((batch, frames, frames), np.float32)
    times = np.arange(frames)
    for row, flags in zip(weights, given):
        anchors = np.concatenate([[-1], np.flatnonzero(flags)])  # -1: the initial pose, where nothing moves
        if len(anchors) == 1:
            continue
        after = np.minimum(np.searchsorted(anchors, times), len(anchors) - 1)  # the first at or after, else the last
        start, end = anchors[after - 1], anchors[after]
        share = np.minimum((times - start) / (end - start), 1.0)
        row[times, end] = share
        real = start >= 0
        row[times[real], start[real]] += 1.0 - share[real]
    return weights


def _numpy(values):
    """numpy or torch ``values`` as a numpy array, to build weights from."""
    return values if isinstance(values, np.ndarray) else values.detach().cpu().numpy()


def _like(array, reference):
    """A numpy ``array`` as the kind (numpy or torch), dtype and device of ``reference``."""
    if isinstance(reference, np.ndarray):
        return array.astype(reference.dtype, copy=False)
    return reference.new_tensor(array)


def trajectory_mask(joint_names, frames):
    """Mask (T, J) with the named joints known on every frame."""
    mask = np.zeros((frames, NUM_JOINTS), dtype=np.float32)
    mask[:, [JOINT_INDEX[name] for name in joint_names]] = 1.0
    return mask


def evaluation_mask(k, frames):
    """The first k joints of ``EVALUATION_ORDER`` as full trajectories (T, J)."""
    return trajectory_mask(EVALUATION_ORDER[:k], frames)


def sample_training_masks(batch, frames, rng, curve_share=FAMILY_SHARES[1], carried_legs_share=0.0):
    """A batch of training masks (B, T, J, 3) drawn from all families, ``CARRIED_SHARE`` of them
    continuing a previous window (whole poses carried, or for ``carried_legs_share`` of them what a
    long shot carries, ``carried_legs``); ``curve_share`` of them the evaluation order's curves (the
    other families keep their proportions)."""
    masks = np.zeros((batch, frames, NUM_JOINTS, 3), dtype=np.float32)
    shares = np.array(FAMILY_SHARES) * (1.0 - curve_share) / (1.0 - FAMILY_SHARES[1])
    shares[1] = curve_share
    family = rng.choice(len(shares), size=batch, p=shares)
    hip = ROOT
    for b, kind in enumerate(family):
        mask = masks[b]
        if kind == 0:  # the paper's constant-in-time Bernoulli trajectories
            mask[:, rng.random(NUM_JOINTS) < BERNOULLI_KEEP] = 1.0
        elif kind == 1:  # the evaluation order, sometimes with the root path
            mask[:] = per_coordinate(evaluation_mask(rng.integers(0, len(EVALUATION_ORDER) + 1), frames))
            if rng.random() < 0.3:
                mask[:, JOINT_INDEX["Hip"]] = 1.0
        elif kind == 2:  # sparse keys: a few frames, whole or partial poses
            for frame in rng.choice(frames, size=rng.integers(1, 4), replace=False):
                mask[frame] = 1.0 if rng.random() < 0.5 else (rng.random(NUM_JOINTS) < 0.5)[:, None]
        elif kind == 3:  # end pose, with or without trajectories
            mask[:, rng.random(NUM_JOINTS) < BERNOULLI_KEEP / 2] = 1.0
            mask[-1] = 1.0
        elif kind == 4:  # joints known on part of the window only
            for joint in np.flatnonzero(rng.random(NUM_JOINTS) < 0.25):
                start = rng.integers(0, frames - 1)
                mask[start: rng.integers(start + 1, frames + 1), joint] = 1.0
        elif kind == 5:  # a ground path: the hips' horizontal position, sometimes with a hand or foot curve
            mask[:, hip, :2] = 1.0
            if rng.random() < 0.3:
                mask[:, JOINT_INDEX[EVALUATION_ORDER[rng.integers(len(EVALUATION_ORDER))]]] = 1.0
        else:  # waypoints: the hips' horizontal position on a few frames
            mask[rng.choice(frames, size=rng.integers(1, 5), replace=False), hip, :2] = 1.0
            mask[-1, hip, :2] = 1.0
        if rng.random() < CARRIED_SHARE:
            carried = rng.integers(1, CARRIED_FRAMES + 1)
            legs_only = carried_legs_share > 0 and rng.random() < carried_legs_share  # no draw at 0: runs repeat
            mask[:carried] = np.maximum(mask[:carried], carried_legs()) if legs_only else 1.0
    return masks
