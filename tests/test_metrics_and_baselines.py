"""Metrics of the DLow protocol and the baselines, on small hand-made motions and real windows."""

import numpy as np
import pytest

from model_runtime import baselines, masks, metrics
from model_runtime.data import dataset
from model_runtime.dct import dct_matrix


def test_dct_is_orthonormal():
    d = dct_matrix(60)
    np.testing.assert_allclose(d @ d.T, np.eye(60), atol=1e-10)


def test_apd_mpd_ade_fde_by_hand():
    truth = np.zeros((4, 48))
    near = np.full((4, 48), 0.1)
    far = np.full((4, 48), 1.0)
    samples = np.stack([near, far])
    assert metrics.ade_fde(samples, truth) == pytest.approx((np.linalg.norm(near[0]),) * 2)
    distance = np.linalg.norm((far - near).ravel())
    assert metrics.diversity(samples) == pytest.approx((distance, distance))
    apd, mpd = metrics.diversity(np.stack([near, near, far]))
    assert mpd == pytest.approx(0.0, abs=1e-6) and apd == pytest.approx(4 * distance / 6)
    assert metrics.diversity(samples[:1]) == (0.0, 0.0)


def test_multimodal_averages_over_pseudo_truths():
    rng = np.random.default_rng(1)
    samples, truths = rng.normal(size=(6, 10, 48)), rng.normal(size=(3, 10, 48))
    ade, fde = metrics.multimodal_ade_fde(samples, truths)
    by_truth = [metrics.ade_fde(samples, t) for t in truths]
    assert np.isclose(ade, np.mean([a for a, _ in by_truth]))
    assert np.isclose(fde, np.mean([f for _, f in by_truth]))


def test_protocol_is_root_relative():
    motion = np.random.default_rng(2).normal(size=(5, 17, 3))
    shifted = motion + np.array([3.0, -2.0, 1.0])
    np.testing.assert_allclose(metrics.to_protocol(motion), metrics.to_protocol(shifted))
    assert metrics.to_protocol(motion).shape == (5, 48)


def test_training_masks_can_weigh_the_evaluation_orders_curves():
    """``curve_share`` sets the share of the family of curves the evaluation gives (the first k of
    its joints on every frame, sometimes with the ground path) and leaves the rest in proportion."""
    frames, joints = 60, [masks.JOINT_INDEX[name] for name in masks.EVALUATION_ORDER]

    def curves_share(share):
        batch = masks.sample_training_masks(2000, frames, np.random.default_rng(1), curve_share=share)
        body = batch[:, masks.CARRIED_FRAMES:]  # past any carried frames
        given = body.any(axis=(1, 3))  # (B, J)
        in_order = np.array([given[:, joints[:k]].all(axis=1) & ~given[:, joints[k:]].any(axis=1)
                             for k in range(len(joints) + 1)]).any(axis=0)
        others = np.delete(given, joints + [masks.ROOT], axis=1).any(axis=1)
        curves = body[:, :, joints]  # (B, T, 4, 3)
        whole = curves.all(axis=(1, 3)) | ~curves.any(axis=(1, 3))  # (B, 4): each on every frame or on none
        return (in_order & ~others & whole.all(axis=1)).mean()

    alike = curves_share(0.0)  # other families' masks that look the same (nothing given, a ground path alone)
    assert curves_share(1.0) == 1.0
    for share in (masks.FAMILY_SHARES[1], 0.5):
        assert abs(curves_share(share) - (share + (1.0 - share) * alike)) < 0.03


def test_training_masks_cover_every_family():
    rng = np.random.default_rng(0)
    batch = masks.sample_training_masks(400, 60, rng)
    assert batch.shape == (400, 60, 17, 3)
    known_frames = batch.any(axis=(2, 3)).sum(axis=1)
    constant_in_time = np.all(batch == batch[:, :1], axis=(1, 2, 3))
    assert (known_frames == 0).any()  # nothing given
    assert (constant_in_time & (known_frames == 60)).any()  # whole trajectories
    assert (~constant_in_time).sum() > 50  # keys, end poses, partial curves
    assert (batch[:, -1].all(axis=(1, 2)) & ~batch[:, 0].all(axis=(1, 2))).any()  # end pose
    hip = batch[:, :, 0]
    ground = hip[..., :2].all(axis=-1) & (hip[..., 2] == 0)  # the hips' horizontal position only
    assert (ground.all(axis=1)).sum() > 20  # ground paths
    assert (ground.any(axis=1) & ~ground.all(axis=1)).sum() > 5  # waypoints
    whole = batch.all(axis=(2, 3))  # (B, T): whole poses given
    assert (whole[:, 0] & ~whole.all(axis=1)).sum() > 40  # a long shot's later windows: first frames carried
    partial = batch.any(axis=-1) & ~batch.all(axis=-1)
    assert np.array_equal(partial.any(axis=(1, 2)), ground.any(axis=1))  # only the hips go by coordinate


def test_training_masks_can_carry_what_a_long_shots_later_window_carries():
    """At ``carried_legs_share`` 1 the masks that carry a previous window's frames give the legs and
    the hips' horizontal position there (``masks.carried_legs``, as ``generation.generate`` carries
    them), the hips' height left to the model, not whole poses; at 0 (the default) the masks are the
    default's."""
    def batch(share):
        return masks.sample_training_masks(400, 60, np.random.default_rng(0), carried_legs_share=share)

    np.testing.assert_array_equal(batch(0.0), masks.sample_training_masks(400, 60, np.random.default_rng(0)))
    carry = masks.carried_legs()
    assert carry[masks.ROOT].tolist() == [1.0, 1.0, 0.0] and carry.sum() == 6 * 3 + 2
    legs_without_height = lambda masks_: ((masks_[:, 0] >= carry).all(axis=(1, 2))
                                          & (masks_[:, 0, masks.ROOT, 2] == 0)).sum()
    whole_first_pose = lambda masks_: masks_.all(axis=(2, 3))[:, 0].sum()
    legs, whole = batch(1.0), batch(0.0)
    assert legs_without_height(legs) > 30 and legs_without_height(whole) < 5  # about CARRIED_SHARE of 400
    assert whole_first_pose(legs) < whole_first_pose(whole) / 5  # only where a key happens to give one


def test_baselines_pin_given_joints_and_match_their_own_data(all_clips):
    windows = dataset.windows(all_clips[:3], future=60, stride=20)
    mask = masks.evaluation_mask(2, 60)
    window = windows[1]
    trajectories = window[1:] * mask[..., None]
    pinned = baselines.pinned_pose(window[0], trajectories, mask)
    np.testing.assert_allclose(pinned[mask > 0], window[1:][mask > 0])
    neighbours = baselines.NearestNeighbour(windows)
    best = neighbours.query(windows[:, 0], windows[:, 1:] * mask[..., None], mask, count=3)
    assert best.shape == (len(windows), 3, 60, 17, 3)
    np.testing.assert_allclose(best[:, 0], windows[:, 1:], atol=1e-3)  # every window finds itself first
