"""What training sees beside the capture itself: foot contact labels and rest-pose starts, on real clips."""

from pathlib import Path

import numpy as np
import pytest

from model_runtime import augment, skeleton
from model_runtime.contacts import foot_contacts
from model_runtime.data import clips, dataset
from model_runtime.train import WindowSampler


@pytest.fixture(scope="module")
def walks(manifest, all_clips):
    return [clip for clip in all_clips if manifest[Path(clip.file).resolve()]["description"].strip('"') == "walk"
            and clip.seconds > 3]


def test_walks_plant_each_foot_in_turn_and_planted_feet_stay_still(walks):
    assert len(walks) >= 5
    for clip in walks:
        planted = foot_contacts(clip.positions, clip.soles, clips.NATIVE_FPS)
        assert 0.45 < planted.mean() < 0.9, clip.file  # stance is about 60 % of a walking gait cycle
        assert (planted.sum(axis=1) == 1).mean() > 0.2, clip.file  # one foot down while the other swings
        starts = np.flatnonzero(np.diff(planted[:, 0].astype(int)) == 1)
        assert len(starts) >= clip.seconds / 2, clip.file  # a right step at least every 2 s
        ankles = clip.positions[:, skeleton.indices(skeleton.FEET), :2]
        speed = np.linalg.norm(np.gradient(ankles, axis=0), axis=-1) * clips.NATIVE_FPS
        assert np.median(speed[planted]) < 0.15 and np.median(speed[~planted]) > 1.0, clip.file


def test_rest_starts_leave_an_upright_rest_pose_into_the_capture(all_clips):
    sampler = WindowSampler(all_clips[:40], 60)
    rng = np.random.default_rng(0)
    motion, soles = sampler.sample(64, rng)
    upright = augment.stands_upright(motion)
    assert upright.mean() > 0.5
    motion, soles = motion[upright], soles[upright]
    started, moved = augment.rest_start(motion, soles, rng)
    j = skeleton.JOINT_INDEX
    rest = started[:, 0]
    # every bone keeps its length on every frame
    np.testing.assert_allclose(skeleton.bone_lengths(started), skeleton.bone_lengths(motion), atol=1e-5)
    # upright: head over hips, straight legs, arms out to the sides between T (level) and A (50 degrees down)
    np.testing.assert_allclose(rest[:, j["Head"], :2], rest[:, j["Hip"], :2], atol=1e-5)
    np.testing.assert_allclose(rest[:, j["RFoot"], :2], rest[:, j["RHip"], :2], atol=1e-5)
    arm = rest[:, j["LWrist"]] - rest[:, j["LShoulder"]]
    drop = np.degrees(np.arcsin(-arm[:, 2] / np.linalg.norm(arm, axis=-1)))
    assert drop.min() >= -1e-3 and drop.max() <= 50.0 + 1e-3
    # standing where the capture stood, facing its way, the lower ankle on the window's lowest ankle height
    np.testing.assert_allclose(rest[:, 0, :2], motion[:, 0, 0, :2], atol=1e-6)
    facing = np.sum(skeleton.facing(rest) * skeleton.facing(motion[:, 0]), axis=-1)
    assert facing.min() > 0.999
    feet = skeleton.indices(skeleton.FEET)
    np.testing.assert_allclose(rest[:, feet, 2].min(axis=1), motion[:, :, feet, 2].min(axis=(1, 2)), atol=3e-3)
    # the capture is reached within 30 frames, its later frames untouched, soles carried with the ankles
    np.testing.assert_array_equal(started[:, 31:], motion[:, 31:])
    changed = np.abs(started - motion).max(axis=(2, 3)) > 0
    assert changed[:, 0].all() and not changed[:, 30:].any()
    np.testing.assert_allclose(moved - soles, started[..., feet, 2] - motion[..., feet, 2], atol=1e-5)
    # eased in: no joint faster than 6 m/s (a fast punch) on the way
    assert np.linalg.norm(np.diff(started[:, :31], axis=1), axis=-1).max() < 0.2


def test_rest_starts_into_windows_still_through_the_blend_slide_their_feet_less(walks, all_clips):
    """A rest start into a walk turns its legs while the body walks off: its low feet slide. The windows
    ``still_through_blend`` keeps have feet that stay put over the blend, so rest-started they slide
    less than half as fast as the walks do."""
    rng = np.random.default_rng(0)
    walking = WindowSampler(walks, 60).sample(64, rng)
    mixed = WindowSampler(all_clips[:40], 60).sample(256, rng)
    feet = skeleton.indices(skeleton.FEET)

    def blend_speed(windows):
        started, _ = augment.rest_start(*windows, np.random.default_rng(1))
        ankles = started[:, :31, feet, :2]
        return np.linalg.norm(np.diff(ankles, axis=1), axis=-1).mean() * clips.NATIVE_FPS

    assert not augment.still_through_blend(walking[0], 0.1).any()
    still = augment.still_through_blend(mixed[0], 0.1) & augment.stands_upright(mixed[0])
    assert 10 <= still.sum() < len(still)
    ankles = mixed[0][still][:, :31, feet, :2]
    assert np.linalg.norm(ankles - ankles[:, :1], axis=-1).max() < 0.1
    walking_speed, still_speed = blend_speed(walking), blend_speed(tuple(part[still] for part in mixed))
    assert still_speed < 0.5 * walking_speed
