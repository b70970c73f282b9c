"""Steps planned under a ground path of the hips (issue 17): what the model is given to walk on."""

import numpy as np
import pytest

from model_runtime import footsteps, generation, numpy_model, shot, skeleton, weights
from model_runtime.data import dataset
from model_runtime.skeleton import JOINT_INDEX

FPS = 30.0


@pytest.fixture
def standing(all_clips):
    """The first pose (17, 3) of a captured walk (CMU 02_01) facing +x, its hips over the origin,
    the floor at z = 0, both ankles at the lower one's height."""
    clip = next(clip for clip in all_clips if clip.file.endswith("02_01.bvh"))
    pose = dataset.normalise(clip.positions[:1])[0].astype(np.float64)
    across = pose[JOINT_INDEX["LHip"]] - pose[JOINT_INDEX["RHip"]]
    yaw = np.arctan2(across[1], across[0]) - np.pi / 2  # left along +y: facing +x
    turn = np.array([[np.cos(-yaw), -np.sin(-yaw), 0.0], [np.sin(-yaw), np.cos(-yaw), 0.0], [0.0, 0.0, 1.0]])
    pose = pose @ turn.T
    pose[:, :2] -= pose[JOINT_INDEX["Hip"], :2]
    ankles = [JOINT_INDEX["RFoot"], JOINT_INDEX["LFoot"]]
    pose[ankles, 2] = pose[ankles, 2].min()  # both feet flat on the floor
    return pose


def _straight(metres, frames):
    """Hips (1 + frames, 2) along +x, eased from rest to rest as a ground path drawn without times is."""
    share = generation.eased(np.linspace(0.0, 1.0, frames + 1), footsteps.WALK_EASE_S * FPS / frames)
    return np.column_stack([metres * share, np.zeros(frames + 1)])


def test_feet_step_in_turn_stand_still_between_and_stop_beside_the_hips(standing):
    hips = _straight(4.0, 120)
    feet, pitch = footsteps.planned_feet(hips, standing, FPS)
    planted = footsteps.stance(feet)
    lifts = [int(np.sum(np.diff(planted[:, side].astype(int)) == -1)) for side in range(2)]
    print(f"steps per foot {lifts}; stance shares {planted.mean(axis=0).round(2)}; "
          f"highest ankle {feet[..., 2].max():.3f} m, steepest pitch {np.degrees(pitch.max()):.0f} deg")
    assert all(3 <= count <= 4 for count in lifts)  # captured walks: 3-4 steps per foot in 4 m
    toes = feet[..., 2] - feet[0, :, 2].min() - footsteps.FOOT_M * np.sin(pitch)  # over the floor
    assert (toes < 1e-6).any(axis=1).all()  # never both feet in the air: one planted or rolling on its toes
    for side in range(2):
        still = planted[:, side]
        assert np.allclose(np.diff(feet[:, side], axis=0)[still[1:] & still[:-1]], 0.0)
    assert np.all(planted[-1]) and np.abs(feet[-1, :, 0] - hips[-1, 0]).max() < 0.25  # both down by the hips
    assert np.abs(feet[..., 1]).max() < 0.15  # each to its side of a straight path, not across it
    assert feet[..., 2].min() >= standing[[JOINT_INDEX["RFoot"], JOINT_INDEX["LFoot"]], 2].min() - 1e-9


def test_the_heel_rolls_off_with_the_toes_on_the_floor(standing):
    feet, pitch = footsteps.planned_feet(_straight(4.0, 120), standing, FPS)
    heel = feet[..., 2] - feet[0, :, 2].min()
    rolling = (pitch > 0.05) & (heel < 0.03 + footsteps.FOOT_M * np.sin(pitch))  # toes on the floor, heel up
    toes = heel - footsteps.FOOT_M * np.sin(pitch)
    print(f"frames rolling on the toes {rolling.sum()}, toes over the floor there {toes[rolling].max():.4f} m")
    assert rolling.sum() >= 6  # one roll before each lift at least
    lift = footsteps.FOOT_M * np.sin(np.radians(footsteps.HEEL_PITCH_DEG))
    assert np.abs(toes[rolling & (heel <= lift + 1e-9)]).max() < 1e-6 and pitch.max() <= np.radians(footsteps.HEEL_PITCH_DEG) + 1e-9


def test_a_fast_path_is_run_with_flights_between_steps(standing):
    """10 m in 4 s (cruising 3.1 m/s): a run, each foot in the air RUN_SWING_SHARE of a stride, so
    both are up between steps; the same feet at 1.2 m/s never leave the ground together."""
    def flight_share(metres):
        feet, pitch = footsteps.planned_feet(_straight(metres, 120), standing, FPS)
        toes = feet[..., 2] - feet[0, :, 2].min() - footsteps.FOOT_M * np.sin(pitch)
        return float((toes > 0.01).all(axis=1).mean()), feet
    running, feet = flight_share(10.0)
    walking, _ = flight_share(4.0)
    lift = feet[..., 2].max() - feet[0, :, 2].min()
    print(f"both feet up: run {running:.2f}, walk {walking:.2f} of the frames; run ankle lift {lift:.2f} m")
    assert 0.1 < running < 0.35 and walking == 0.0 and lift > 0.2


def test_no_walk_no_steps_and_variants_walk_in_their_own_gaits(standing):
    assert footsteps.planned_feet(np.zeros((60, 2)), standing, FPS) is None
    gaits = footsteps.variant_gaits(5, np.random.default_rng(0))
    assert len(set(gaits)) == 5 and {gait.other_foot_first for gait in gaits} == {False, True}
    hips = _straight(4.0, 120)
    plans = [footsteps.planned_feet(hips, standing, FPS, gait)[0] for gait in gaits]
    apart = [np.linalg.norm(a - b, axis=-1).mean() for i, a in enumerate(plans) for b in plans[i + 1:]]
    print(f"ankles of 5 gaits apart: {min(apart):.3f} to {max(apart):.3f} m, mean {np.mean(apart):.3f}")
    assert min(apart) > 0.02 and np.mean(apart) > 0.1
    assert footsteps.variant_gaits(1, np.random.default_rng(0)) == [footsteps.Gait()]
    assert footsteps.variant_gaits(5, np.random.default_rng(0), diversity=0.0) == [footsteps.Gait()] * 5
    narrow = footsteps.variant_gaits(5, np.random.default_rng(0), diversity=0.5)
    for part in ("stride", "arm_swing", "lean", "ease_in"):  # half as far from the plain gait, in the same order
        plain = getattr(footsteps.Gait(), part)
        np.testing.assert_allclose([getattr(g, part) - plain for g in narrow],
                                   [0.5 * (getattr(g, part) - plain) for g in gaits], atol=1e-12)


def test_the_model_walks_each_variants_own_steps_for_10_s_without_folding(standing):
    """Each variant's planned feet given to the bundled model (numpy, as the add-on runs it) over
    300 frames of chained windows: every frame generated, each body over its own steps, the torso
    keeping its length and the hips their height to the end (later windows carry the legs and
    start the upper body and the hip height afresh: ``generation.anchored``)."""
    network, sampler = numpy_model.load_folder(weights.ASSETS)
    frames, count = 300, 3
    hips = _straight(10.0, frames)
    plans = [footsteps.planned_feet(hips, standing, FPS, gait)[0]
             for gait in footsteps.variant_gaits(count, np.random.default_rng(0))]
    trajectories = np.zeros((count, frames, skeleton.NUM_JOINTS, 3), np.float32)
    mask = np.zeros((frames, skeleton.NUM_JOINTS, 3), np.float32)
    feet = [JOINT_INDEX["RFoot"], JOINT_INDEX["LFoot"]]
    trajectories[:, :, JOINT_INDEX["Hip"], :2], mask[:, JOINT_INDEX["Hip"], :2] = hips[1:], 1.0
    trajectories[:, :, feet], mask[:, feet] = np.stack(plans)[:, 1:], 1.0
    motion, _ = generation.generate(network, standing.astype(np.float32), trajectories, mask, count,
                                    np.random.default_rng(0), 1.0, sampler)
    assert motion.shape == (count, 1 + frames, skeleton.NUM_JOINTS, 3)
    own = np.linalg.norm(motion[:, :, feet] - np.stack(plans), axis=-1).mean(axis=(1, 2))
    torso = np.linalg.norm(motion[:, -60:, JOINT_INDEX["Thorax"]] - motion[:, -60:, JOINT_INDEX["Hip"]], axis=-1)
    standing_torso = np.linalg.norm(standing[JOINT_INDEX["Thorax"]] - standing[JOINT_INDEX["Hip"]])
    height = motion[:, -60:, JOINT_INDEX["Hip"], 2] / standing[JOINT_INDEX["Hip"], 2]
    print(f"feet from their own plans {own.round(3)} m; last 2 s: torso {torso.min() / standing_torso:.2f} of its "
          f"length at the least, hips {height.min():.2f} of their height")
    assert own.max() < 0.3
    assert torso.min() > 0.9 * standing_torso and height.min() > 0.85
