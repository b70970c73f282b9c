"""Picking distinct, plausible variants from a pool (pure numpy, real motion from the shared data)."""

import numpy as np
import pytest

from model_runtime import animation_quality, joint_angles, metrics, realism, selection
from model_runtime.rotations import turned
from model_runtime.skeleton import JOINT_INDEX, UP_AXIS, UPPER_BODY, facing, indices
from model_runtime.data import dataset


@pytest.fixture(scope="module")
def pool(all_clips, manifest):
    """Twelve real 2-second motions of one person, moved to one starting point as if sampled
    (12, 60, 17, 3), and the initial pose (17, 3); neighbours overlap, so near-duplicates abound."""
    _, validation = dataset.split_by_subject(all_clips, manifest)
    longest = max(validation, key=lambda clip: clip.frames)
    windows = dataset.windows([longest], future=60, stride=5)[:12]
    return windows[:, 1:] - windows[:, :1, :1] + windows[0, 0, 0], windows[0, 0]


def test_typical_first_spread_beats_a_plain_draw_on_the_closest_pair_and_starts_typical(pool):
    candidates, _ = pool
    plain = metrics.diversity(metrics.to_protocol(candidates[:4]))[1]
    chosen = selection.typical_first_spread(candidates, 4)
    picked = metrics.diversity(metrics.to_protocol(candidates[chosen]))[1]
    assert picked > plain
    distances = metrics.pairwise_distances(metrics.to_protocol(candidates))
    assert chosen[0] == np.argmin(distances.mean(axis=1))  # the medoid is always kept
    assert len(set(selection.typical_first_spread(candidates, 12).tolist())) == 12


def test_typical_first_spread_keeps_the_widest_spacing_that_typical_first_picking_allows(pool):
    """Brute force over every spacing: none wider than the chosen one still makes the count."""
    candidates, _ = pool
    distances = metrics.pairwise_distances(metrics.to_protocol(candidates))
    chosen = selection.typical_first_spread(candidates, 5)
    spacing = distances[np.ix_(chosen, chosen)][~np.eye(5, dtype=bool)].min()
    order = np.argsort(distances.mean(axis=1), kind="stable")
    for radius in np.unique(distances[distances > spacing]):
        taken = []
        for index in order:
            if all(distances[index, other] >= radius for other in taken):
                taken.append(index)
        assert len(taken) < 5


def test_a_near_duplicate_and_a_stretched_body_are_not_picked(pool):
    candidates, initial = pool
    duplicate = candidates[0] + 0.001
    stretched = candidates[1].copy()
    stretched[:, 13] += 0.3 * (stretched[:, 13] - stretched[:, 12])  # left forearm 30 % longer
    with_bad = np.concatenate([candidates, duplicate[None], stretched[None]])
    chosen = selection.distinct_plausible(with_bad, initial, 6)
    assert len(with_bad) - 1 not in chosen  # the stretched body is screened out
    assert not {0, len(with_bad) - 2} <= set(chosen.tolist())  # never both copies


def test_a_body_outside_the_joint_limits_is_screened_out(pool):
    """A candidate whose left knee bends backwards on every frame (bone lengths kept) is dropped
    where the joint-angle limits screen the pool, and kept by the same picking without them."""
    candidates, initial = pool
    hip, knee, foot = (JOINT_INDEX[name] for name in ("LHip", "LKnee", "LFoot"))
    backwards = candidates[2].copy()
    along = backwards[:, foot] - backwards[:, hip]
    along /= np.linalg.norm(along, axis=-1, keepdims=True)
    on_line = backwards[:, hip] + ((backwards[:, knee] - backwards[:, hip]) * along).sum(-1, keepdims=True) * along
    backwards[:, knee] = 2.0 * on_line - backwards[:, knee]  # the knee mirrored through the hip-ankle line
    with_bad = np.concatenate([candidates, backwards[None]])
    limits = joint_angles.limit_arrays(joint_angles.read_limits(realism.ANGLE_LIMITS))
    cost = selection.implausibility(with_bad, initial, limits=limits)
    assert cost[-1] > cost[:-1].max()
    assert len(with_bad) - 1 not in selection.most_plausible(with_bad, initial, 9, limits=limits)
    assert len(with_bad) - 1 in selection.most_plausible(with_bad, initial, 9)


def test_a_body_bent_over_that_nothing_asked_for_is_screened_out(pool, monkeypatch):
    """A candidate whose torso, head and arms are turned 30 degrees about the hip joint on every
    frame (a bow; every bone keeps its length, so it is as plausible as itself upright) leans the
    furthest beyond the start pose, and is not picked; without the lean screen it is."""
    candidates, initial = pool
    upright = candidates[3]
    hips = upright[:, JOINT_INDEX["Hip"]]
    side = np.cross(UP_AXIS, facing(upright))  # the hip line's horizontal direction, right to left
    upper = indices(UPPER_BODY)
    bowed = upright.copy()
    bow = np.full(len(side), np.radians(30.0))
    bowed[:, upper] = hips[:, None] + turned(upright[:, upper] - hips[:, None], side, bow)
    with_bad = np.concatenate([candidates, bowed[None]])
    lean = selection.leaning(with_bad, initial)
    assert lean[-1] - lean[3] > 15.0 and lean[-1] == lean.max()
    cost = selection.implausibility(with_bad, initial)
    assert cost[-1] == pytest.approx(cost[3], rel=0.02)
    assert len(with_bad) - 1 not in selection.distinct_plausible(with_bad, initial, 6)
    monkeypatch.setattr(selection, "LEAN_SCREENED_SHARE", 0.0)
    assert len(with_bad) - 1 in selection.distinct_plausible(with_bad, initial, 6)


def test_variants_are_picked_as_played_and_never_one_that_misses_its_hand_curve(pool):
    """Among cleaned-up candidates, one a metre from the others would be the widest pick by its
    distance as played; where its hand would miss its curve on the rig, it is never picked."""
    candidates, initial = pool
    away = candidates[3] + np.array([1.0, 0.0, 0.0])  # the same motion a metre to the side
    with_far = np.concatenate([candidates, away[None]])
    far = len(with_far) - 1
    distances = animation_quality.mean_joint_distances(with_far)
    assert np.isclose(distances[0, 1], animation_quality.spread(with_far[:2]))
    assert far in selection.typical_first_spread(with_far, 5, distances)
    assert far in selection.distinct_as_played(with_far, initial, 5, np.zeros(len(with_far)))
    missed = np.zeros(len(with_far))
    missed[far] = 0.1  # a tenth of the arm short on its worst frame
    assert far not in selection.distinct_as_played(with_far, initial, 5, missed)


def test_the_widest_pick_keeps_the_medoid_and_typical_first_spacing_and_spreads_wider(pool):
    """``widest_apart`` against ``typical_first_spread`` on the same distances as played, with one
    candidate standing half a metre off: the same first pick (the medoid), a closest pair no
    closer than SPACING_KEPT of typical-first's, and the outlying one taken, so a larger mean
    distance."""
    candidates, _ = pool
    with_off = np.concatenate([candidates, (candidates[3] + np.array([0.5, 0.0, 0.0]))[None]])
    distances = animation_quality.mean_joint_distances(with_off)
    typical = selection.typical_first_spread(None, 5, distances)
    widest = selection.widest_apart(distances, 5)
    pairs = lambda chosen: distances[np.ix_(chosen, chosen)][~np.eye(5, dtype=bool)]
    assert widest[0] == typical[0] == np.argmin(distances.mean(axis=1))
    assert len(set(widest.tolist())) == 5 and len(with_off) - 1 in widest
    assert pairs(widest).min() >= selection.SPACING_KEPT * pairs(typical).min()
    assert pairs(widest).mean() > pairs(typical).mean()


def test_a_continuation_keeps_its_hand_within_reach_and_stays_apart_from_the_others(pool):
    """Three motions, three continuations each (one captured motion stepped aside by up to 0.15 m),
    the right hand held 0.2 m under the captured shoulder: a draw stepped a metre aside is never
    kept though it lies farthest from the others; the last motion keeps the draw farthest from the
    others' picks; where no draw reaches, the nearest to reaching is kept."""
    candidates, initial = pool
    shoulder, wrist = JOINT_INDEX["RShoulder"], JOINT_INDEX["RWrist"]
    aside = np.array([[[0.0, 0.0], [1.0, 0.0], [0.1, 0.0]],
                      [[0.0, 0.05], [0.0, 0.15], [-0.1, 0.0]],
                      [[0.05, 0.05], [0.0, -0.12], [0.12, 0.1]]])  # (3 motions, 3 draws, 2) m
    steps = np.concatenate([aside, np.zeros((3, 3, 1))], axis=-1)[:, :, None, None]
    draws = candidates[0] + steps  # (3, 3, 60, 17, 3)
    given = np.zeros((3, 60, 17, 3))
    known = np.zeros((3, 60, 17, 3))
    given[:, :, wrist] = candidates[0, :, shoulder] - np.array([0.0, 0.0, 0.2])
    known[:, :, wrist] = 1.0
    pick = selection.continuations_apart(draws, initial, given, known, new_from=10)
    assert pick[0] != 1
    others = [draws[other, pick[other], 10:] for other in (0, 1)]  # the last motion chose against their picks
    apart = [sum(np.linalg.norm(draw[10:] - other, axis=-1).mean() for other in others) for draw in draws[2]]
    assert pick[2] == np.argmax(apart)
    beyond = draws.copy()
    beyond[0] += np.array([2.0, 3.0, 1.5])[:, None, None, None] * np.array([1.0, 0.0, 0.0])  # none in reach
    assert selection.continuations_apart(beyond, initial, given, known, new_from=10)[0] == 2


def test_bones_are_scored_as_the_rig_plays_them_with_the_given_joints_pinned(pool):
    """Two candidates miss a given right-foot path by the same 3 cm: one whole body that reaches for
    it short (pinned, its shin stretches 3 cm), one whose body stands 3 cm further along with only its
    decoded foot left behind (pinned, every bone keeps its length). The rig pins the foot, so the
    second is the plausible one, though as decoded its own shin is the stretched one."""
    candidates, initial = pool
    motion = candidates[4]
    knee, foot = JOINT_INDEX["RKnee"], JOINT_INDEX["RFoot"]
    shin = motion[:, foot] - motion[:, knee]
    step = 0.03 * shin / np.linalg.norm(shin, axis=-1, keepdims=True)  # (T, 3)
    given, known = np.zeros_like(motion), np.zeros(motion.shape[:2])
    given[:, foot], known[:, foot] = motion[:, foot] + step, 1.0
    short = motion.copy()
    along = motion + step[:, None]
    along[:, foot] = motion[:, foot]
    with_both = np.concatenate([candidates, short[None], along[None]])
    cost = selection.implausibility(with_both, initial, given, known)
    assert cost[-1] < cost[-2]
