"""Picking N distinct, plausible variants from a larger pool of candidate motions.

Gumbel-softmax weights over M bases often give two samples the same dominant
basis, so a plain draw of N keeps near-duplicates (the minimum pairwise
distance of ../shared/papers/003 barely moves). "Generate N variants" therefore
decodes a pool: ``POOL_FACTOR`` x N draws of the diverse sampler, which spread
far, and ``PRIOR_POOL_FACTOR`` x N draws of the plain prior, which stay near the
likely motion. The pool comes through the completion stage, with its known
joints as decoded. It drops the ``SCREENED_SHARE`` that is least plausible
(rigid bones stretched relative to the rest of the pool, straying from the
given curves and keys, joints bent outside the limits fitted on the training
data) and, where no joint is given, the ``LEAN_SCREENED_SHARE`` bent over furthest
beyond the start pose (the sampler's draws lean as a set), and keeps N of the rest
by ``typical_first_spread``: the
widest spacing at which candidates taken from the most typical outwards still
make N. On the validation subjects (k = 0, shipped weights, K = 10 and 50)
that keeps the sampler's spread (minimum pairwise distance 2.3x plain
sampling's) while best-of-K error stays about 4 % above plain sampling's (it was
7-8 % above with sampler draws only and farthest points from the medoid); more
than four variants in five still come from the sampler. Screening half the
pool instead of a quarter, or foot sliding as well, cost a fifth of the
distance; screening none left bones 1.36x as stretched as plain sampling's.

A shot does this twice. Its first window keeps ``played_pool`` candidates this
way; each is carried through the whole shot and the cleanup, and the N variants
are then picked from them as they will play (``distinct_as_played``): the
cleanup takes out the glide that made up half of the decoded candidates'
distance (feet held planted), so variants spread in the decoded pool came out
close, and a body that ends out of its hand curve's reach is only visible then.
numpy only, so Blender needs no torch.
"""

import numpy as np

from . import joint_angles, metrics
from .animation_quality import lean_degrees, mean_joint_distances
from .masks import per_coordinate
from .skeleton import JOINT_INDEX, LIMBS, limb_length, rigid_bone_lengths

POOL_FACTOR = 5  # diverse sampler draws per variant asked for
PRIOR_POOL_FACTOR = 5  # plain prior draws per variant added to the diverse sampler's pool
SCREENED_SHARE = 0.25  # least plausible share of the pool dropped before selection
# ... and then, where no joint is given, the share of the pool bent over furthest beyond the start pose
# (``leaning``): the diverse sampler spreads its draws partly into a forward bend that nothing asked
# for. Where curves are given they hold the body, and the screen only narrowed the variants (a reach's
# 0.151 / 0.184 m apart on the mannequin / Rigify came to 0.128 / 0.168); see "Leaning variants" in README.md
LEAN_SCREENED_SHARE = 0.1
GIVEN_POOL_FACTOR = 2  # prior draws per variant where joints are given (``most_plausible``)
ANGLE_WEIGHT = 2.0  # cost of one joint angle outside its limits on every frame (a pool-median stretch costs 1)
PLAYED_POOL = 15  # candidates a shot carries to the end, at the least, to pick its variants from as played
PLAYED_POOL_FACTOR = 1.5  # ... and per variant asked for
# ... and, for a few variants, PLAYED_POOL_PER_VARIANT per variant as long as candidates and variants together
# come to no more than PLAYED_WORK: each candidate costs about as much as writing and measuring a variant
# on the rig (36 and 27 ms of a 120-frame shot on Rigify), so 10 variants keep 20 candidates and end about
# a second after the click, and the panel's 5 keep 25. One hand curve, seeds 0-5, mannequin / Rigify,
# before the rig's clavicles turned (retarget.CLAVICLES): 25 candidates put a 10 s wave's variants
# 0.159 / 0.162 m apart (0.139 / 0.161 from 15), its hand's worst frame 0.1 / 0.2 cm off (0.4 / 0.9),
# and a reach's 0.151 / 0.203 (0.151 / 0.185).
PLAYED_POOL_PER_VARIANT = 5
PLAYED_WORK = 30
# ... but no more candidate-frames beyond the variants' own than this: 50 variants of 10,000 frames
# carrying 25 more took 108 s instead of 37 and peaked at 1.89 GB instead of 1.3 (target 2)
PLAYED_EXTRA_FRAMES = 6000
SPACING_KEPT = 0.75  # share of typical-first picking's closest pair that the variants picked as played keep
MISS_TOLERANCE = 0.01  # a hand this far off its curve or key on the rig (in arm lengths) misses it
# ... and so does one its curve or key brings closer to the shoulder than an elbow folded to this
# cosine between the arm's bones (about 45 degrees inside): of a reach drawn away from the body, the
# candidate whose body walked into its hand's path folded the arm past that and its elbow whipped
# round (80 m/s^2, 9x the median frame, on Rigify)
SCREENED_FOLD_COS = -0.7
MISS_WEIGHT = 100.0  # cost of a hand missing its curve or key on the rig by an arm's length on the worst frame
# A later window's continuation keeps each given hand within this share of its arm's length from the
# continuation's own shoulder (``continuations_apart``): the rig leans and reaches only so far.
CONTINUATION_REACH_SHARE = 0.97
# ... and measures how far the continuations lie apart on every CONTINUATION_FRAME_STRIDE-th frame: a
# motion moves little in a tenth of a second, and on every frame the distances took 146 ms (52 now) of
# a 1.2 s shot of 10 variants carrying 25 candidates
CONTINUATION_FRAME_STRIDE = 3


def _relative(values):
    return values / max(float(np.median(values)), 1e-9)


def implausibility(candidates, initial, given=None, known=None, limits=None):
    """Per candidate (P,): bone-length deviation and, where joints are given, their distance from the
    given positions, each relative to the pool's median; with ``limits`` (low, high) (16,), the
    share of frames each joint angle spends outside them, summed over angles (``ANGLE_WEIGHT``).

    candidates (P, T, 17, 3) in metres at the model rate, as decoded (not yet pinned); initial
    (17, 3) holds the rig's bone lengths; given (T, 17, 3) and known (T, 17, 3) or (T, 17) as the
    model's input (a joint's distance over its known coordinates). Bones and angles are those of
    the body as the rig plays it, its given joints pinned: scored as decoded, the screened draws of
    the weights before kept 2.1 % of their frames off the limits at k = 1 (validation subjects,
    K = 50), pinned 2.0 %, for the same best-of-50 error. Weighing the angles more screened further
    (at 4, 1.7 % with the shipped weights, against 1.8 % at 2), but as played the rig's joints
    whipped round faster: on the mannequin a 10 s wave's worst joint 41 m/s^2 on average over seeds
    0-5 against 34 at 2, a reach's 30 over seeds 0-9 against 27 (the weights before, at 6: 36, up
    to 63). The angles' shares are absolute, not relative: a pool that keeps within the limits has
    a median of zero.
    """
    known = per_coordinate(known) if known is not None and known.any() else None
    played = candidates if known is None else np.where(known > 0, given, candidates)
    cost = _relative(np.abs(rigid_bone_lengths(played) - rigid_bone_lengths(initial)).mean(axis=(1, 2)))
    if known is not None:
        distance = np.sqrt((np.square(candidates - given) * known).sum(-1))
        cost += _relative(distance[:, known.any(-1)].mean(axis=1))
    if limits is not None:
        outside = joint_angles.angle_excess(played, limits) > joint_angles.OFF_LIMIT_TOLERANCE  # (P, T, 16)
        cost += ANGLE_WEIGHT * outside.mean(axis=1).sum(axis=-1)
    return cost


def played_pool(count, frames):
    """How many candidates a shot of ``count`` variants over ``frames`` frames carries to the end
    (``distinct_as_played``); ``count`` where a long shot has no room for more."""
    wanted = max(PLAYED_POOL, int(np.ceil(PLAYED_POOL_FACTOR * count)),
                 min(PLAYED_POOL_PER_VARIANT * count, PLAYED_WORK - count))
    return count + max(0, min(wanted - count, PLAYED_EXTRA_FRAMES // max(frames, 1)))


def distinct_as_played(motion, initial, count, missed, limits=None):
    """Indices (count,) into cleaned-up candidates (P, F, 17, 3), P >= count, at the scene's rate:
    those whose hands stay on their curves and keys on the rig (``missed`` (P,): the worst miss,
    in arm lengths; any that miss by more than MISS_TOLERANCE only where too few others remain)
    and that are otherwise plausible (``implausibility``), the least plausible SCREENED_SHARE
    dropped, then ``widest_apart`` by their distances as played. One hand curve, seeds
    0-5, mannequin / Rigify, with the first window drawn ``generation.GIVEN_SPREAD`` wider: the
    hand's worst frame off a 10 s wave's curve 1.0 / 0.8 cm (3.2 / 2.3 picked from the decoded
    pool at the prior's spread, 0.5 / 0.6 as played), 5 variants of a reach 0.156 / 0.180 m apart
    (0.126 / 0.162 at the prior's spread; about 0.11 / 0.14 picked from the decoded pool)."""
    cost = implausibility(motion, initial, limits=limits) + MISS_WEIGHT * missed
    reaching = missed <= MISS_TOLERANCE
    kept = max(count, min(len(motion) - int(round(SCREENED_SHARE * len(motion))), int(reaching.sum())))
    order = np.lexsort((cost, ~reaching))[:kept]  # those that reach first, each group by its cost
    return order[widest_apart(mean_joint_distances(motion[order]), count)]


def continuations_apart(draws, initial, given, known, new_from=0):
    """Index (B,) of one continuation per motion among its draws (B, D, W, 17, 3), model frame: of
    the draws that keep every given hand within CONTINUATION_REACH_SHARE of its arm from their own
    shoulder on the frames from ``new_from`` on (where none does, the nearest to it), the one whose
    frames from ``new_from`` on lie farthest in sum from the other motions' picks, over two rounds
    from the nearest to reach. A long shot continues each candidate window by window; its variants
    are picked at the end among candidates that stayed apart and on their curves.

    initial (17, 3) holds the arm lengths; given and known (B, W, 17, 3) as the model's input."""
    count = len(draws)
    fresh = draws[:, :, new_from:]  # (B, D, N, 17, 3)
    sparse = fresh[:, :, ::CONTINUATION_FRAME_STRIDE].astype(np.float32)  # for the distances
    excess = np.zeros(draws.shape[:2])
    for arm in LIMBS[2:]:
        shoulder, wrist = arm[0], arm[-1]
        held = known[:, new_from:, JOINT_INDEX[wrist]].max(axis=-1) > 0  # (B, N)
        distance = np.linalg.norm(given[:, None, new_from:, JOINT_INDEX[wrist]] - fresh[..., JOINT_INDEX[shoulder], :],
                                  axis=-1)  # (B, D, N)
        beyond = np.maximum(distance - CONTINUATION_REACH_SHARE * limb_length(initial, arm), 0.0)
        excess = np.maximum(excess, (beyond * held[:, None]).max(axis=-1, initial=0.0))
    allowed = excess <= excess.min(axis=1, keepdims=True)
    pick = np.argmin(excess, axis=1)
    for _ in range(2):
        for motion in range(count):
            others = np.arange(count) != motion
            apart = np.linalg.norm(sparse[motion][:, None] - sparse[others, pick[others]][None], axis=-1)
            total = apart.mean(axis=(2, 3)).sum(axis=1)  # (D,): summed over the other motions' picks
            pick[motion] = int(np.argmax(np.where(allowed[motion], total, -np.inf)))
    return pick


def widest_apart(distances, count):
    """Indices (count,) into P candidates by their distances (P, P), P >= count: the most typical
    (the medoid) first, then each next the one farthest in sum from those taken, among those no
    closer to any of them than SPACING_KEPT of the closest pair ``typical_first_spread`` keeps
    (its own picks where that runs out). Typical-first picking took the typical candidates, which
    lie closer together than the pool does: a reach's 5 variants 0.113 m apart as played where
    its 15 candidates lay 0.127 m apart; over seeds 0-5 (mannequin / Rigify) about 0.117 / 0.154 m
    -> 0.126 / 0.162, idle 0.23 / 0.29 -> 0.24 / 0.31 (keeping the whole spacing: 0.120 / 0.155)."""
    typical = typical_first_spread(None, count, distances)
    closest = distances[np.ix_(typical, typical)][~np.eye(count, dtype=bool)].min() if count > 1 else 0.0
    spacing = SPACING_KEPT * closest
    chosen = [int(typical[0])]
    while len(chosen) < count:
        allowed = (distances[:, chosen] >= spacing).all(axis=1)
        allowed[chosen] = False
        if not allowed.any():
            return typical
        chosen.append(int(np.argmax(np.where(allowed, distances[:, chosen].sum(axis=1), -np.inf))))
    return np.array(chosen)


def typical_first_spread(candidates, count, distances=None):
    """Indices (count,) of candidates (P, T, 17, 3), P >= count, as far apart as typical-first
    greedy picking allows, in the DLow protocol (root-relative poses), or by ``distances`` (P, P)
    where given (``candidates`` then unused).

    Candidates are visited from the most typical (least mean distance to the others) outwards and
    taken unless closer than r to one already taken; r is the widest of the pool's pairwise
    distances at which that still takes ``count``, found by bisection (wider spacings take fewer
    candidates, all but always; tests/test_selection.py checks it by brute force). Every pair is
    then at least r apart, as with farthest-point picking, but the variants are the typical ones
    that allow it rather than the pool's outliers, so one of them stays near the likely motion.
    """
    if distances is None:
        distances = metrics.pairwise_distances(metrics.to_protocol(candidates))
    order = np.argsort(distances.mean(axis=1), kind="stable")

    def taken(radius):
        blocked, chosen = np.zeros(len(order), dtype=bool), []
        for index in order:
            if not blocked[index]:
                chosen.append(index)
                if len(chosen) == count:
                    break
                blocked |= distances[index] < radius
        return chosen

    radii = np.unique(distances[np.triu_indices(len(distances), 1)])
    low, high, best = 0, len(radii) - 1, taken(0.0)  # taken(radii[low]) always makes count
    while low < high:
        middle = (low + high + 1) // 2
        chosen = taken(radii[middle])
        if len(chosen) == count:
            low, best = middle, chosen
        else:
            high = middle - 1
    return np.array(best)


def most_plausible(candidates, initial, count, given=None, known=None, limits=None):
    """Indices (count,) of the ``count`` least implausible candidates (P, T, 17, 3), best first.

    Where joints are given, the prior's samples are drawn ``GIVEN_POOL_FACTOR`` x over and screened
    so, keeping the variants whose bodies follow the curves by themselves: on the validation
    subjects with 1-4 curves, best-of-50 FDE 4-7 mm lower (k = 3: 0.582 -> 0.575 m, measured before
    the completion stage), spread 7-9 % lower. Arguments as ``implausibility``.
    """
    return np.argsort(implausibility(candidates, initial, given, known, limits), kind="stable")[:count]


def leaning(candidates, initial):
    """Per candidate (P,): the mean over its frames of how far (degrees) the hips-to-thorax line of
    candidates (P, T, 17, 3) leans from vertical beyond that of the initial pose (17, 3)."""
    return np.maximum(lean_degrees(candidates) - lean_degrees(initial), 0.0).mean(axis=1)


def distinct_plausible(candidates, initial, count, given=None, known=None, limits=None):
    """Indices (count,) into candidates (P, T, 17, 3), P >= count: the implausible share dropped,
    then, where no joint is given, the share bent over furthest (``LEAN_SCREENED_SHARE``), then
    ``typical_first_spread``. Arguments as ``implausibility``."""
    kept = max(count, len(candidates) - int(round(SCREENED_SHARE * len(candidates))))
    order = most_plausible(candidates, initial, kept, given, known, limits)
    if known is None or not known.any():
        upright = max(count, kept - int(round(LEAN_SCREENED_SHARE * len(candidates))))
        order = order[np.sort(np.argsort(leaning(candidates[order], initial), kind="stable")[:upright])]
    return order[typical_first_spread(candidates[order], count)]
