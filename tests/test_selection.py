"""Picking distinct, plausible variants from a pool (pure numpy, real motion from the shared data)."""

import numpy as np
import pytest

from model_runtime import metrics, selection
from model_runtime.data import dataset


@pytest.fixture(scope="module")
def pool(all_clips, manifest):
    """Twelve real 2-second motions of one person, moved to one starting point as if sampled
    (12, 60, 17, 3), and the initial pose (17, 3); neighbours overlap, so near-duplicates abound."""
    _, validation = dataset.split_by_subject(all_clips, manifest)
    longest = max(validation, key=lambda clip: clip.frames)
    windows = dataset.windows([longest], future=60, stride=5)[:12]
    return windows[:, 1:] - windows[:, :1, :1] + windows[0, 0, 0], windows[0, 0]


def test_farthest_points_beat_a_plain_draw_on_the_closest_pair(pool):
    candidates, _ = pool
    plain = metrics.diversity(metrics.to_protocol(candidates[:4]))[1]
    picked = metrics.diversity(metrics.to_protocol(candidates[selection.farthest_points(candidates, 4)]))[1]
    assert picked > plain
    assert len(set(selection.farthest_points(candidates, 12).tolist())) == 12


def test_a_near_duplicate_and_a_stretched_body_are_not_picked(pool):
    candidates, initial = pool
    duplicate = candidates[0] + 0.001
    stretched = candidates[1].copy()
    stretched[:, 13] += 0.3 * (stretched[:, 13] - stretched[:, 12])  # left forearm 30 % longer
    with_bad = np.concatenate([candidates, duplicate[None], stretched[None]])
    chosen = selection.distinct_plausible(with_bad, initial, 6)
    assert len(with_bad) - 1 not in chosen  # the stretched body is screened out
    assert not {0, len(with_bad) - 2} <= set(chosen.tolist())  # never both copies
