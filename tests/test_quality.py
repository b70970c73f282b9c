"""Motion an animator keeps (issue 15): planted feet, a floor, eased keys, variants apart. Measured
on the mannequin as Blender plays each variant (``blender_rigs.played``), and the cleanup steps on
their own with synthetic motion."""

import bpy  # noqa: F401  (first: blender_rigs imports Blender's own modules)
import numpy as np
import pytest

import blender_rigs
import shots
from model_runtime import animation_quality, cleanup, filters, footsteps, generation, skeleton
from model_runtime.data import clips
from model_runtime.model import ModelConfig
from model_runtime.skeleton import JOINT_INDEX
from trajevae_addon import api, pipeline
from trajevae_addon import mannequin as mannequin_module

FPS = 30


@pytest.fixture
def mannequin(scene):
    scene.render.fps = FPS
    return blender_rigs.mannequin_rig(scene)


def _played(scene, rig, report):
    """Per variant (joints (F, 17, 3), toes (F, 2, 3)) as played."""
    frames = np.arange(scene.frame_start, scene.frame_end + 1)
    out = []
    for action in report.actions:
        api.set_active_variant(rig, action)
        out.append(blender_rigs.played(rig, frames))
    return out


def test_standing_variants_keep_their_feet_planted_on_the_floor(scene, mannequin):
    """Idle from the rest pose: planted toes still, on the floor, knees over the feet rather than
    knock-kneed (captured motion: knees at most 12 degrees inward; the model's alone: 20-22 through
    whole shots, ``retarget.KNEE_INWARD_DEG``), the body over its feet (captured standing: its
    centre of mass within the soles; before ``cleanup.balancing_steps``, up to 7 cm outside on
    the mannequin and 28 on a Rigify rig), and no seam where model windows meet (on average over
    the variants no faster there than elsewhere, within a fifth: when each window's arms started
    from the rest pose's, they rose at every join, 1.1-1.6x; one variant's step that lands on a join
    is no seam: seeds 0-3, 5 variants, a variant's own ratio reached 1.49 with the weights before
    the facing frame and 1.44 with it, their means 1.09 and 1.10)."""
    scene.frame_end = 150
    shots = _played(scene, mannequin, pipeline.generate_variants(mannequin, 3, 0))
    joins = generation.window_joins(150, FPS, ModelConfig().frames)
    seams = np.array([animation_quality.seam(joints, FPS, joins) for joints, _ in shots])
    print(f"idle: near window joins, accelerations {np.round(seams[:, 0], 2)}x (worst), "
          f"{np.round(seams[:, 1], 2)}x (mean) elsewhere")
    assert seams[:, 1].mean() <= 1.2
    for joints, toes in shots:
        floor = animation_quality.floor_height(toes)
        speed = animation_quality.planted_toe_speed(toes, FPS, floor)
        highest, airborne, sink = animation_quality.floating(toes, floor)
        inward = animation_quality.knee_inward_degrees(joints).max()
        off = np.nanmax(animation_quality.off_balance(joints, toes, floor), initial=0.0)
        print(f"idle: planted toes {speed:.3f} m/s, lower toe up to {100 * highest:.1f} cm, airborne "
              f"{100 * airborne:.0f} %, sink {100 * sink:.1f} cm, knees up to {inward:.0f} degrees inward, "
              f"centre of mass up to {100 * off:.1f} cm outside the soles")
        assert speed <= 0.05 and sink <= 0.01 and airborne <= 0.05 and inward <= 12.0 and off <= 0.03


def test_a_300_frame_shot_with_a_curve_stays_on_the_floor(scene, mannequin):
    scene.frame_end = 300
    curves, _ = shots.wave(mannequin)
    api.bind_curve(mannequin, "RWrist", blender_rigs.curve(scene, "wave", curves["RWrist"]))
    report = pipeline.generate_variants(mannequin, 5, 0)
    for joints, toes in _played(scene, mannequin, report):
        floor = animation_quality.floor_height(toes)
        lower = toes[..., 2].min(axis=1) - floor
        speed = animation_quality.planted_toe_speed(toes, FPS, floor)
        held = animation_quality.held_up(toes, floor, FPS)
        print(f"300 frames: lower toe median {100 * np.median(lower):.1f} cm, last 100 frames median "
              f"{100 * np.median(lower[-100:]):.1f} cm, sink {100 * max(0, -lower.min()):.1f} cm, planted toes "
              f"{speed:.3f} m/s, lean up to {animation_quality.lean_degrees(joints).max():.0f} degrees, a foot "
              f"held up on {100 * held:.0f} % of frames")
        assert lower.min() >= -0.01 and np.median(lower) <= 0.01 and np.median(lower[-100:]) <= 0.01
        # the other foot too: a model trained with the root scored apart (issue 16's f3) left one toe
        # rising to 10 cm over the 10 s, here on 51 % of the second variant's frames (seeds 0-3 of the
        # benchmark's wave: 35 % for the worst of five); the shipped weights on none
        assert speed <= 0.1 and held <= 0.05
    assert all(error < 0.01 for error in report.curve_error_m)


def test_a_hand_curve_within_reach_is_met_on_a_rig_whose_trunk_turns_as_one(scene):
    """Rigify's torso control turns the whole trunk (no chest bone is mapped): the trunk leans from
    the hips toward the hand (``retarget._trunk_to_hands``). Unleaned, the rig kept the hips' turn
    while the model's chest leaned toward the curve, and the 300-frame wave's hand, its arm
    straight, missed the curve: in these three variants by 0.1 / 4.3 / 0.5 cm on average and up to
    12.6 cm; leaned, up to 3.9 cm where the lean stops at MAX_TRUNK_LEAN_TO_HAND; now at most
    0.4 cm, the variants picked among candidates whose hands the rig keeps on the curve
    (``selection.distinct_as_played``)."""
    scene.render.fps = FPS
    scene.frame_end = 300
    rig = blender_rigs.rigify_rig(scene)
    try:
        curves, _ = shots.wave(rig)
        api.bind_curve(rig, api.map_rig(rig)["RWrist"], blender_rigs.curve(scene, "wave", curves["RWrist"]))
        played = np.array([joints for joints, _ in _played(scene, rig, pipeline.generate_variants(rig, 3, 0))])
    finally:
        blender_rigs.disable_rigify()
    on_curve = generation.curve_samples(curves["RWrist"], 299, 299)
    missed = np.linalg.norm(played[:, :, JOINT_INDEX["RWrist"]] - on_curve, axis=-1)  # (V, F)
    print(f"Rigify wave: hand off its curve by {np.round(100 * missed.mean(axis=1), 1)} cm on average, "
          f"{np.round(100 * missed.max(axis=1), 1)} cm at worst")
    assert missed.mean(axis=1).max() < 0.01 and missed.max() < 0.02


def test_blocking_keys_are_approached_not_snapped(scene, mannequin):
    _, key_frame = shots.blocking(mannequin)  # rest pose at 1, a crouch with both arms up at 45
    scene.frame_set(key_frame)
    keyed = blender_rigs.world_joints(mannequin)
    scene.frame_set(1)
    floor = blender_rigs.played(mannequin, [1])[1][0][:, 2].min()
    for joints, toes in _played(scene, mannequin, pipeline.generate_variants(mannequin, 5, 0)):
        worst, spike = animation_quality.pops(joints, FPS)
        # every joint but the head, which no key places (the neck bone aims at it)
        missed = np.delete(np.linalg.norm(joints[key_frame - 1] - keyed, axis=-1), JOINT_INDEX["Head"]).max()
        sink = floor - toes[..., 2].min()
        print(f"blocking: worst acceleration {worst:.0f} m/s^2, {spike:.1f}x the median frame's; key missed by "
              f"{100 * missed:.2f} cm; toes {100 * sink:.1f} cm under the floor at most")
        # the keys' layer carried a foot the model lifted before the key 3 cm into the floor (fourth
        # variant; ``cleanup.ease_onto_keys`` keeps keyed ankles above it)
        assert sink < 0.01
        # issue 15's 6x: the worst frames were elbows swinging where their bend direction wrapped
        # around or the arm passed the shoulder line (``retarget._limb``), 9x before; then the fifth
        # variant's elbow spun the long way round to its keyed bend in the 5 frames before the key
        # (7.8x, 73 m/s^2; 4.3x now)
        assert spike <= 6.0 and missed < 0.01


def test_variants_with_one_hand_curve_are_apart_and_on_the_curve(scene, mannequin):
    scene.frame_end = 90
    curves, _ = shots.reach(mannequin)
    api.bind_curve(mannequin, "RWrist", blender_rigs.curve(scene, "reach", curves["RWrist"]))
    report = pipeline.generate_variants(mannequin, 5, 0)
    played = np.array([joints for joints, _ in _played(scene, mannequin, report)])
    spread = animation_quality.spread(played)
    spikes = [animation_quality.pops(joints, FPS)[1] for joints in played]
    missed = np.linalg.norm(played[:, :, JOINT_INDEX["RWrist"]] - generation.curve_samples(curves["RWrist"], 89, 89),
                            axis=-1)
    print(f"one hand curve: 5 variants {spread:.3f} m apart; worst frames {np.round(spikes, 1)}x the median; "
          f"hand off the curve as played by {np.round(100 * missed.max(axis=1), 2)} cm at worst")
    # issue 15 asks for 0.15 m; the contact-aware model's variants spread 0.08 m (0.24 before it),
    # 0.11 picked from the decoded pool, 0.13 picked as played (``selection.widest_apart``), 0.15
    # drawn wider where the curve narrows the prior (``generation.GIVEN_SPREAD``; seeds 0-5: 0.156
    # on average, the least 0.135); a wider pick had a body walking through its hand's path, the
    # hand 2.9 cm off its curve where it passed the shoulder, before candidates that miss were
    # screened out. Kept over their feet (``cleanup.balancing_steps``), bodies step rather than
    # lean away like planks: seeds 0-5 0.152 on average, the least 0.129, this seed 0.153
    assert spread >= 0.14 and missed.max() < 0.01
    # the third variant's body stopped dead where the second window's carried frames end: 12.7x, now
    # 6.1x (``generation.with_momentum``)
    assert max(spikes) <= 7.0


def _still(frames):
    """The mannequin's rest pose held for ``frames`` frames: (1, F, 17, 3), feet on z = ankle height."""
    return np.repeat(mannequin_module.REST_JOINTS[None, None].astype(np.float64), frames, axis=1)


def test_a_body_drifting_off_its_feet_steps_under_itself_and_stays_over_them():
    """The model's idle bodies drifted up to 0.44 m off their feet, straight legs slanted like a
    plank's; captured standing clips keep the centre of mass over the soles on every frame where
    both feet bear weight. The cleanup steps under the body and leans it back over its feet."""
    frames, initial = 120, mannequin_module.REST_JOINTS.astype(np.float64)
    forward = skeleton.facing(initial)
    carried = np.ones(17)  # the body above the feet drifts 0.4 m ahead, the knees half as far
    carried[[JOINT_INDEX["RFoot"], JOINT_INDEX["LFoot"]]] = 0.0
    carried[[JOINT_INDEX["RKnee"], JOINT_INDEX["LKnee"]]] = 0.5
    drift = 0.4 * filters.smoothstep(np.linspace(0.0, 1.0, frames))
    motion = _still(frames) + drift[None, :, None, None] * carried[None, None, :, None] * forward
    standing = initial[JOINT_INDEX["RFoot"], 2]
    out, contacts, _ = cleanup.tidy(motion, FPS, initial, {}, {}, {}, np.zeros((1, frames, 2)))
    joints = out[0]
    feet = joints[:, [JOINT_INDEX["RFoot"], JOINT_INDEX["LFoot"]]]
    toes = feet + 0.6 * footsteps.FOOT_M * forward  # feet turned with the body, which does not turn
    off = animation_quality.off_balance(joints, toes, standing)
    steps = animation_quality.steps(toes, standing)
    print(f"drifting body: {steps} steps, centre of mass up to {100 * np.nanmax(off):.1f} cm outside the soles, "
          f"hips {100 * np.dot(joints[-1, 0] - initial[0], forward):.0f} cm ahead")
    assert sum(steps) >= 1 and np.nanmax(off) <= 0.02 and np.isfinite(off).sum() >= frames // 2
    assert np.dot(joints[-1, 0] - initial[0], forward) >= 0.3  # the body went where the model took it
    speed = np.linalg.norm(np.diff(feet[..., :2], axis=0), axis=-1) * FPS  # (F - 1, 2)
    assert speed[contacts[0, 1:] & contacts[0, :-1]].max() < 1e-6  # planted feet stay put


def test_a_body_turned_on_its_planted_feet_is_kept_over_their_soles():
    """The soles are where the rig's feet point (``plant_feet``'s turns), not where the body faces:
    an idle body turned 35 degrees on its planted feet read as over them while its centre of mass
    stood 12 cm off their soles on the rig. Here a body turned 35 degrees on feet a stride apart
    leans forward and a little to its side, off their soles as the rig measures them (toes along
    the feet) though over soles turned with the body, and is moved onto them."""
    frames, initial = 60, mannequin_module.REST_JOINTS.astype(np.float64)
    forward, feet = skeleton.facing(initial), [JOINT_INDEX["RFoot"], JOINT_INDEX["LFoot"]]
    knees, hip = [JOINT_INDEX["RKnee"], JOINT_INDEX["LKnee"]], initial[JOINT_INDEX["Hip"]]
    turn = np.radians(35.0)
    about_z = np.array([[np.cos(turn), -np.sin(turn), 0.0], [np.sin(turn), np.cos(turn), 0.0], [0.0, 0.0, 1.0]])
    pose = hip + (initial - hip) @ about_z.T
    pose[feet] = initial[feet] + np.array([[0.15], [-0.15]]) * forward  # a stride apart, pointing as they stood
    pose[knees] = 0.5 * (pose[knees] + pose[feet]) + [0.0, 0.0, 0.25]
    carried = np.ones(17)
    carried[feet], carried[knees] = 0.0, 0.5
    body_forward = about_z @ forward
    pose += carried[:, None] * (0.2 * body_forward - 0.05 * np.cross([0.0, 0.0, 1.0], body_forward))
    motion = np.repeat(pose[None, None], frames, axis=1)
    standing, pinned = initial[feet[0], 2], np.zeros((frames, 17))
    kept = cleanup.over_the_feet(motion, FPS, standing, np.ones((1, frames, 2), dtype=bool), pinned, initial,
                                 np.zeros((1, frames, 2)))

    def off(joints):
        return np.nanmax(animation_quality.off_balance(joints, joints[:, feet] + 0.6 * footsteps.FOOT_M * forward,
                                                       standing))

    eased = int(np.ceil(cleanup.START_EASE_S * FPS))  # the first frame stays as the artist left it
    print(f"turned body: centre of mass {100 * off(motion[0]):.1f} cm off the soles, "
          f"{100 * off(kept[0, eased:]):.1f} cm once eased in")
    assert np.abs(cleanup._off_balance(motion)).max() == 0.0  # over soles turned with the body
    assert off(motion[0]) > 0.03 and off(kept[0, eased:]) < 0.01
    np.testing.assert_array_equal(kept[:, :, feet], motion[:, :, feet])


@pytest.mark.parametrize("clip", ["Female1_A07_Crouch.bvh", "Female1_A05_PickUpBox.bvh", "02_01.bvh",
                                  "Female1_B03_Walk1.bvh"])
def test_captured_motion_is_left_as_it_stands(mocap_root, clip):
    """The balance the cleanup keeps is the capture's own: a crouch, a body bending to lift a box
    and two walks of ../shared take no balancing step and no joint moves 2 cm (with the soles
    ending a quarter of a foot short of the toe tips, lifting the box was pulled back 3.4 cm,
    and read as a line between the ankles with a margin, a walk stepped 1 m off its path). With
    the soles turned as the rig turns its feet (``over_the_feet``), a CMU walk's double support
    stands 2.2 cm off them where the pelvis turned 11 degrees from a foot: its body moves 1.9 cm
    (the rig's feet read it 2 cm off as captured: benchmarks/quality.py); the others under 1 cm."""
    path = next(mocap_root.rglob(clip))
    motion = clips.load_clip(path).positions.astype(np.float64)[None]
    initial, frames = motion[0, 0], motion.shape[1]
    standing, pinned, unsure = skeleton.lower_ankle_height(initial), np.zeros((frames, 17)), np.zeros((1, frames, 2))
    stepped, placed = cleanup.balancing_steps(motion, FPS, standing, pinned, initial, unsure)
    _, contacts, turns = cleanup.plant_feet(stepped, FPS, standing, pinned, initial, unsure, placed=placed)
    moved = np.linalg.norm(cleanup.over_the_feet(stepped, FPS, standing, contacts, pinned, initial, turns) - motion,
                           axis=-1).max()
    print(f"{clip}: moved up to {100 * moved:.2f} cm")
    assert not placed.any() and moved < 0.02


def test_on_floor_removes_drift_and_keeps_a_jump():
    motion, standing = _still(150), mannequin_module.REST_JOINTS[JOINT_INDEX["RFoot"], 2]
    motion[..., 2] += np.linspace(0.0, 0.3, 150)[None, :, None]  # the body floats up 30 cm
    jump = np.zeros(150)
    jump[60:73] = 0.2 * np.sin(np.linspace(0.0, np.pi, 13))  # a 0.4 s jump, 20 cm high
    motion[..., 2] += jump[None, :, None]
    lower = cleanup.on_floor(motion, FPS, standing)[0, :, [JOINT_INDEX["RFoot"], JOINT_INDEX["LFoot"]], 2].min(0)
    lower -= standing
    print(f"floor: off the jump up to {100 * np.delete(lower, np.s_[55:78]).max():.2f} cm, jump peak "
          f"{100 * lower[66]:.1f} cm")
    assert np.abs(np.delete(lower, np.s_[55:78])).max() < 0.01 and lower[66] > 0.15 and lower.min() > -1e-9


def test_a_sliding_body_is_held_by_its_planted_feet():
    motion, initial = _still(90), mannequin_module.REST_JOINTS.astype(np.float64)
    motion[..., 1] += np.arange(90)[None, :, None] * 0.5 / FPS  # feet and all glide at 0.5 m/s
    standing, pinned = initial[JOINT_INDEX["RFoot"], 2], np.zeros((90, 17))
    unsure = np.zeros((1, 90, 2))  # the model's contacts: none, the height decides
    held = cleanup.without_slide(motion, FPS, standing, pinned, initial, {}, unsure)
    held, contacts, turns = cleanup.plant_feet(held, FPS, standing, pinned, initial, unsure)
    feet = held[0][:, [JOINT_INDEX["RFoot"], JOINT_INDEX["LFoot"]]]
    speed = np.linalg.norm(np.diff(feet[..., :2], axis=0), axis=-1).max() * FPS
    assert contacts.all() and speed < 1e-6 and np.abs(turns).max() < 1e-9


def test_a_body_held_against_its_feet_changes_speed_over_frames_where_they_start_and_stop_sliding():
    """A still body whose planted feet glide at 0.5 m/s for half a second: the body is moved back
    by their glide, 0.25 m in all, and where the glide starts and stops its speed changes over
    frames (SLIDE_SMOOTHING_S), not in one (15 m/s^2 on the hips)."""
    motion, initial = _still(90), mannequin_module.REST_JOINTS.astype(np.float64)
    feet = [JOINT_INDEX["RFoot"], JOINT_INDEX["LFoot"]]
    motion[:, :, feet, 1] += np.clip(np.arange(90) - 30, 0, 15)[None, :, None] * 0.5 / FPS
    standing, pinned = initial[JOINT_INDEX["RFoot"], 2], np.zeros((90, 17))
    held = cleanup.without_slide(motion, FPS, standing, pinned, initial, {}, np.zeros((1, 90, 2)))
    hips = held[0, :, JOINT_INDEX["Hip"], 1]
    assert hips[-1] - hips[0] == pytest.approx(-0.25, abs=0.001)
    assert np.abs(np.diff(hips, 2)).max() * FPS * FPS < 7.5


def test_a_foot_the_model_says_is_planted_is_held_on_the_floor_though_generated_above_it():
    motion, initial = _still(60), mannequin_module.REST_JOINTS.astype(np.float64)
    right = JOINT_INDEX["RFoot"]
    standing, pinned = initial[right, 2], np.zeros((60, 17))
    motion[0, :, right, 2] += 0.07  # floating 7 cm up
    motion[0, :, right, 0] += np.arange(60) * 0.2 / FPS  # and drifting sideways at 0.2 m/s
    said = np.zeros((1, 60, 2))
    said[0, :, 0] = 1.0
    for predicted, held in ((np.zeros((1, 60, 2)), False), (said, True)):
        out, contacts, _ = cleanup.plant_feet(motion, FPS, standing, pinned, initial, predicted)
        foot = out[0, :, right]
        assert contacts[0, :, 0].all() == held
        if held:
            np.testing.assert_allclose(foot[:, 2], standing, atol=1e-9)
            assert np.linalg.norm(np.diff(foot[:, :2], axis=0), axis=-1).max() < 1e-9


def test_a_key_is_eased_into_and_met_exactly():
    motion = _still(60)
    key = motion[0, 40, JOINT_INDEX["LWrist"]] + [0.0, -0.2, 0.3]
    motion[0, 38:43, JOINT_INDEX["LWrist"]] = key  # the model jumps onto the key at the last moment
    eased = cleanup.ease_onto_keys(motion, {40: {"LWrist": key}}, FPS)[0, :, JOINT_INDEX["LWrist"]]
    acceleration = np.linalg.norm(np.diff(eased, n=2, axis=0), axis=-1) * FPS ** 2
    print(f"eased key: worst acceleration {acceleration.max():.2f} m/s^2")
    np.testing.assert_allclose(eased[40], key)
    assert acceleration.max() < 3.0


def test_a_body_that_does_not_turn_with_its_ground_path_is_turned_to_face_along_it():
    frames, fps = 90, 30.0
    rest = mannequin_module.REST_JOINTS.astype(np.float64)
    forward = skeleton.facing(rest[None])[0]
    side = np.cross(forward, [0.0, 0.0, 1.0])
    angle = np.linspace(0.0, np.pi / 2, frames)[:, None]  # a quarter circle of radius 2.5 m from the rest facing
    path = rest[JOINT_INDEX["Hip"]] + 2.5 * (np.sin(angle) * forward + (1.0 - np.cos(angle)) * side)
    sideways = _still(frames)[0] - rest[JOINT_INDEX["Hip"]] + path[:, None]  # facing as at rest throughout
    turned = cleanup.facing_the_path(sideways[None], rest, path, fps)[0]
    facing = skeleton.facing(turned)[:, :2]
    tangent = np.gradient(path[:, :2], axis=0)
    cosine = (facing * tangent).sum(-1) / np.linalg.norm(facing, axis=-1) / np.linalg.norm(tangent, axis=-1)
    start_cosine = (skeleton.facing(rest[None])[0, :2] * tangent[0]).sum() / np.linalg.norm(tangent[0])
    eased = int(cleanup.FACING_EASE_S * fps)
    np.testing.assert_allclose(turned[0], sideways[0])  # the start pose as the artist left it
    assert start_cosine > 0.99 and np.degrees(np.arccos(np.clip(cosine[eased:], -1, 1))).max() < 3.0
    np.testing.assert_allclose(turned[:, JOINT_INDEX["Hip"]], path)  # turned about the hips
    np.testing.assert_allclose(np.linalg.norm(turned - turned[:, :1], axis=-1),
                               np.linalg.norm(sideways - sideways[:, :1], axis=-1), atol=1e-9)  # rigidly


def test_every_frame_keeps_the_initial_poses_proportions_above_the_hips():
    initial = mannequin_module.REST_JOINTS.astype(np.float64)
    rng = np.random.default_rng(0)
    stretched = initial + rng.normal(scale=0.05, size=(4, 17, 3))  # four poses, every segment off
    kept = generation.with_proportions(stretched, initial)
    for joint, parent in enumerate(skeleton.PARENTS):
        if parent < 0:
            continue
        if skeleton.JOINT_NAMES[joint] not in skeleton.UPPER_BODY:  # legs as generated
            np.testing.assert_array_equal(kept[:, joint], stretched[:, joint])
            continue
        np.testing.assert_allclose(np.linalg.norm(kept[:, joint] - kept[:, parent], axis=-1),
                                   np.linalg.norm(initial[joint] - initial[parent]), rtol=1e-9)
        direction = lambda poses: (poses[:, joint] - poses[:, parent]) / np.linalg.norm(
            poses[:, joint] - poses[:, parent], axis=-1, keepdims=True)
        np.testing.assert_allclose(direction(kept), direction(stretched), atol=1e-9)
    np.testing.assert_array_equal(kept[:, 0], stretched[:, 0])


def test_hips_rolling_further_and_further_are_levelled_without_a_kink():
    """A pelvis the model rolls a little more each window (a wave's reached 24 degrees) tilted a
    Rigify trunk sideways with it; captured motion of ../shared rolls at most 3-10 degrees."""
    initial = mannequin_module.REST_JOINTS.astype(np.float64)
    right, left = JOINT_INDEX["RHip"], JOINT_INDEX["LHip"]
    middle, half = 0.5 * (initial[left] + initial[right]), 0.5 * (initial[left] - initial[right])
    degrees = np.linspace(0.0, 40.0, 300)
    rolled = np.repeat(initial[None, None], len(degrees), axis=1)  # (1, F, 17, 3)
    lift = np.abs(half[0]) * np.tan(np.radians(degrees))  # the left hip rising over the right about their middle
    rolled[0, :, left] = middle + half + lift[:, None] * [0.0, 0.0, 1.0]
    rolled[0, :, right] = middle - half - lift[:, None] * [0.0, 0.0, 1.0]
    level = generation.with_rigid_pelvis(rolled, initial)[0]
    roll = np.degrees(skeleton.hips_roll(level))
    print(f"hips rolled to 40 degrees: {roll[-1]:.1f} after")
    assert roll.max() < generation.PELVIS_ROLL_MOST_DEG
    mild = degrees < generation.PELVIS_ROLL_FREE_DEG - 0.5
    np.testing.assert_allclose(roll[mild], degrees[mild], atol=0.05)  # within the free roll: as generated
    np.testing.assert_allclose(np.linalg.norm(level[:, left] - level[:, right], axis=-1),
                               np.linalg.norm(initial[left] - initial[right]), rtol=1e-9)  # a rigid pelvis
    np.testing.assert_allclose(level[:, [left, right]].mean(axis=1), rolled[0][:, [left, right]].mean(axis=1),
                               atol=1e-9)
    others = [joint for joint in range(17) if joint not in (left, right)]
    np.testing.assert_array_equal(level[:, others], rolled[0][:, others])
    assert (np.diff(roll[5:-5]) > 0).all() and np.abs(np.diff(roll[5:-5], 2)).max() < 0.01  # rising, no kink


def test_hips_the_model_brings_together_keep_the_pelvis_width_and_facing():
    """The out/rb7000 weights brought a run's hip joints within 5 cm of each other, crossing for a
    frame, and the facing they define flipped 209 degrees: the body spun round for a frame. Here
    the hips close to 4 cm and swap sides for 3 frames; the shoulders keep the body's facing."""
    initial = mannequin_module.REST_JOINTS.astype(np.float64)
    right, left = JOINT_INDEX["RHip"], JOINT_INDEX["LHip"]
    motion = np.repeat(initial[None, None], 60, axis=1)  # (1, F, 17, 3)
    middle, half = 0.5 * (initial[left] + initial[right]), 0.5 * (initial[left] - initial[right])
    width = np.ones(60)
    width[20:40] = 0.2
    width[29:32] = -0.2  # crossed
    motion[0, :, left] = middle + width[:, None] * half
    motion[0, :, right] = middle - width[:, None] * half
    kept = generation.with_rigid_pelvis(motion, initial)[0]
    forward = skeleton.facing(kept)
    turn = np.degrees(np.arccos(np.clip(np.sum(forward * skeleton.facing(initial), axis=-1), -1.0, 1.0)))
    print(f"hips closed and crossed: facing at most {turn.max():.1f} degrees off, width "
          f"{np.linalg.norm(kept[:, left] - kept[:, right], axis=-1).min():.3f} m")
    assert turn.max() < 1.0
    np.testing.assert_allclose(np.linalg.norm(kept[:, left] - kept[:, right], axis=-1),
                               np.linalg.norm(initial[left] - initial[right]), rtol=1e-9)


def test_hip_joints_drifting_off_the_root_are_put_back_where_they_lie_from_it_turned_with_the_pelvis():
    """Window by window a 10 s wave's hip joints rose 0.25 m above the root about their own middle;
    they stay where they lie from the root in the start pose, turned with the pelvis."""
    initial = mannequin_module.REST_JOINTS.astype(np.float64)
    initial[[JOINT_INDEX["RHip"], JOINT_INDEX["LHip"]], 2] -= 0.06  # hip joints a little under the root
    turned = initial - initial[JOINT_INDEX["Hip"]]
    turned[:, :2] = turned[:, [1, 0]] * [-1.0, 1.0]  # the whole body turned 90 degrees about Z
    drifted = np.repeat(turned[None, None], 30, axis=1)
    hips = [JOINT_INDEX["RHip"], JOINT_INDEX["LHip"]]
    drifted[0, :, hips, 2] += np.linspace(0.0, 0.25, 30)[None, :]
    kept = generation.with_rigid_pelvis(drifted, initial)[0]
    np.testing.assert_allclose(kept[:, hips], np.repeat(turned[None, hips], 30, axis=0), atol=1e-6)


def test_a_later_window_rising_on_its_carried_legs_is_set_back_on_the_floor_unless_a_foot_is_given():
    initial = mannequin_module.REST_JOINTS.astype(np.float64)
    standing = skeleton.lower_ankle_height(initial)
    window = np.repeat(initial[None, None], 60, axis=1).repeat(2, axis=0)  # (2, W, 17, 3)
    window[..., 2] += np.linspace(0.0, 0.03, 60)[None, :, None]  # rising 3 cm through the window
    known = np.zeros_like(window)
    known[:, :15, skeleton.indices(skeleton.LOWER_BODY)] = 1.0  # the carried legs
    known[1, 15:, JOINT_INDEX["RFoot"]] = 1.0  # a foot's curve in the second
    placed = generation.on_the_floor(window, known, 15, 60, standing)
    lowest = placed[0, 15:, skeleton.indices(skeleton.FEET), 2].min()
    assert lowest == pytest.approx(standing, abs=1e-9)
    shift = placed[0] - window[0]
    np.testing.assert_array_equal(shift[..., :2], 0.0)
    np.testing.assert_allclose(shift[..., 2], shift[0, 0, 2], atol=1e-12)  # up or down as one
    np.testing.assert_array_equal(placed[1], window[1])


def test_a_later_window_carries_on_the_bodys_speed_where_its_carried_frames_end():
    """A body moving 3 cm a frame sideways through the carried frames, then still in the window's
    own: it slows over MOMENTUM_FRAMES instead of stopping in a frame; its legs, and a body whose
    hips follow a ground path, are left as they are."""
    frames, done = 30, 14
    motion = np.repeat(mannequin_module.REST_JOINTS[None, None].astype(np.float64), frames, axis=1).repeat(2, axis=0)
    motion[:, :done + 1, :, 0] += 0.03 * np.arange(done + 1)[None, :, None]
    motion[:, done + 1:, :, 0] += 0.03 * done
    carried_on = generation.with_momentum(motion, done, np.array([True, False]))
    hips, knee = JOINT_INDEX["Hip"], JOINT_INDEX["RKnee"]
    speed = np.diff(carried_on[0, :, hips, 0])
    np.testing.assert_allclose(speed[:done], 0.03)
    assert np.all(np.diff(speed[done - 1:done + generation.MOMENTUM_FRAMES + 1]) <= 1e-12)  # slowing, never faster
    assert np.abs(np.diff(speed)).max() < 0.03 / generation.MOMENTUM_FRAMES * 2.0  # no stop in one frame
    assert speed[done + generation.MOMENTUM_FRAMES:].max() < 1e-12  # then still
    np.testing.assert_array_equal(carried_on[0, :, knee], motion[0, :, knee])
    np.testing.assert_array_equal(carried_on[1], motion[1])


def test_where_a_later_windows_carried_frames_end_a_change_of_speed_spreads_over_frames():
    """Each joint still, then moving 3 cm a frame from the frame where the carried frames end (the
    decoder letting the carried legs go): the change of speed, a kink of 0.03 in one frame, spreads
    over frames to under a third of that; a joint moving steadily, and frames beyond
    SEAM_FRAMES, stay as they were."""
    frames, done = 40, 20
    motion = np.zeros((2, frames, 17, 3), np.float32)
    motion[0, done:, :, 0] = 0.03 * np.arange(frames - done)[:, None]
    motion[1, :, :, 1] = 0.03 * np.arange(frames)[:, None]
    smoothed = motion.copy()
    generation.smooth_across(smoothed, done)
    kink = np.abs(np.diff(motion[0, :, 0, 0], 2)).max()
    assert kink == pytest.approx(0.03)
    assert np.abs(np.diff(smoothed[0, :, 0, 0], 2)).max() < kink / 3.0
    np.testing.assert_allclose(smoothed[1], motion[1], atol=1e-6)
    beyond = np.r_[:done - generation.SEAM_FRAMES, done + generation.SEAM_FRAMES + 1:frames]
    np.testing.assert_array_equal(smoothed[0, beyond], motion[0, beyond])


def test_long_shots_are_windows_that_overlap_and_a_step_at_a_join_shows_as_a_seam():
    schedule = generation.windows(299, 60)  # 300 frames at 30 fps: 299 model frames after the initial one
    assert schedule[0] == (0, 60, 0) and all(carried == generation.WINDOW_OVERLAP for _, _, carried in schedule[1:])
    assert schedule[-1][0] + schedule[-1][1] == 299
    assert all(start + frames - generation.WINDOW_OVERLAP == after for (start, frames, _), (after, _, _)
               in zip(schedule, schedule[1:]))
    joins = generation.window_joins(300, FPS, 60)
    assert joins[:2] == [46, 61] and len(joins) == 2 * (len(schedule) - 1)
    time = np.arange(300) / FPS
    swaying = np.zeros((300, 17, 3))
    swaying[..., 0] = 0.1 * np.sin(2.0 * np.pi * time)[:, None]  # a smooth sway
    assert animation_quality.seam(swaying, FPS, joins)[0] <= 1.0 + 1e-9
    stepped = swaying.copy()
    stepped[joins[3]:, :, 1] += 0.02  # 2 cm where the third window's own frames begin
    assert animation_quality.seam(stepped, FPS, joins)[0] > 3.0


def test_a_step_cut_in_leaves_and_meets_the_floor_at_rest():
    """The arc a foot that does not lift by itself is given between two plants: STEP_CLEARANCE_M
    high, leaving the floor and landing with no jump in its speed (a half sine started it at
    full speed: a 2.5 cm step in the first frame of a 10-frame swing)."""
    frames, plants = np.arange(40), [(0, 10), (20, 39)]
    lift = cleanup._lift(frames, plants, cleanup._lifted_steps(plants, np.zeros(40)))
    assert lift[:11].max() == 0.0 and lift[20:].max() < 1e-12
    assert lift.max() == pytest.approx(cleanup.STEP_CLEARANCE_M)
    smooth_arc = 2.0 * np.pi ** 2 * cleanup.STEP_CLEARANCE_M / 10 ** 2  # the arc's own largest acceleration
    assert np.abs(np.diff(lift, 2)).max() <= 1.01 * smooth_arc


def test_a_foot_hovering_while_the_other_steps_bears_the_body():
    """The right foot steps (lifted 10 cm) while the left hovers 6 cm up, not predicted planted: the
    lower of the two bears the body on the floor, so both are never up at once (short of a jump)."""
    motion, initial = _still(60), mannequin_module.REST_JOINTS.astype(np.float64)
    right, left = JOINT_INDEX["RFoot"], JOINT_INDEX["LFoot"]
    standing, pinned = initial[right, 2], np.zeros((60, 17))
    motion[0, 20:40, right, 2] += 0.1 * np.sin(np.linspace(0.0, np.pi, 20))
    motion[0, :, left, 2] += 0.06
    out, contacts, _ = cleanup.plant_feet(motion, FPS, standing, pinned, initial, np.zeros((1, 60, 2)))
    lower = out[0][:, [right, left], 2].min(axis=1) - standing
    print(f"lowest foot up to {100 * lower.max():.2f} cm; left planted on {contacts[0, :, 1].mean():.0%} of frames")
    assert contacts[0].any(axis=1).all() and lower.max() < 0.005


def test_a_foot_left_in_the_air_at_the_shots_end_does_not_sink_under_the_floor():
    """The right foot steps off at frame 45 and, with no plant left before the shot ends, comes
    down 1.5 cm under where it stands: it stops where it stands; a foot the artist's curve takes
    lower stays on its curve."""
    motion, initial = _still(60), mannequin_module.REST_JOINTS.astype(np.float64)
    right = JOINT_INDEX["RFoot"]
    standing, pinned = initial[right, 2], np.zeros((60, 17))
    motion[0, 45:, right, 2] += np.maximum(0.1 * np.sin(np.linspace(0.0, 1.2 * np.pi, 15)), -0.015)
    stance = np.ones((1, 60, 2), dtype=bool)
    stance[0, 45:, 0] = False  # the right foot's step the shot cuts off
    out, _, _ = cleanup.plant_feet(motion, FPS, standing, pinned, initial, np.zeros((1, 60, 2)), stance)
    assert motion[0, -1, right, 2] < standing - 0.01 and out[0, :, right, 2].min() >= standing - 1e-9
    pinned[50:, right] = 1.0
    out, _, _ = cleanup.plant_feet(motion, FPS, standing, pinned, initial, np.zeros((1, 60, 2)), stance)
    assert out[0, -1, right, 2] == pytest.approx(standing - 0.015)


def test_feet_left_behind_step_after_the_body_through_a_long_shot():
    frames, initial = 3000, mannequin_module.REST_JOINTS.astype(np.float64)
    motion = _still(frames)
    motion[..., 1] += np.arange(frames)[None, :, None] * 1.0 / FPS  # carried off at 1 m/s (by a curve, say)
    feet = [JOINT_INDEX["RFoot"], JOINT_INDEX["LFoot"]]
    moved, contacts, _ = cleanup.plant_feet(motion, FPS, initial[feet[0], 2], np.zeros((frames, 17)), initial,
                                            np.zeros((1, frames, 2)))
    behind = np.linalg.norm(moved[0][:, feet, :2] - moved[0][:, [JOINT_INDEX["RHip"], JOINT_INDEX["LHip"]], :2], axis=-1)
    steps = [int((np.diff(contacts[0, :, side].astype(int)) == 1).sum()) for side in range(2)]  # plants after the first
    print(f"carried 100 m: {steps} steps, feet at most {behind.max():.2f} m behind the hips "
          f"({behind[FPS:].max():.2f} after the first second)")
    # captured walks at 1 m/s: a stride per foot every 1.1-1.3 m; mincing steps under the body took 149
    assert 70 < min(steps) <= max(steps) < 130 and behind.max() < 0.7 and behind[FPS:].max() < 0.45
    swinging = ~contacts[0]
    assert not (swinging[:, 0] & swinging[:, 1]).any()  # in turn: never both feet in the air (no hops)
    # a foot moves only off the floor: dragged from the start of each step, 1.8 m/s within 1 cm of it
    low = moved[0][:, feet, 2] - initial[feet[0], 2] < 0.01
    speed = np.linalg.norm(np.diff(moved[0][:, feet, :2], axis=0), axis=-1) * FPS
    assert speed[low[1:] & low[:-1]].max() < 0.01


def test_a_foot_the_model_leaves_far_behind_lands_within_its_legs_reach():
    """Carried off at 1 m/s while the model's left foot falls 0.7 m behind: each step the cleanup
    cuts in sets the foot down where a leg at STAND_SHARE of its length reaches from the hip as the
    step's weight comes onto it (STEP_S after landing; straight under it here, the rest pose
    standing on straight legs). Landed where the model's foot was, it was up to 1.25 legs from a
    wave's hip, out of the rig's reach, and the knee snapped straight."""
    frames, initial = 150, mannequin_module.REST_JOINTS.astype(np.float64)
    forward = skeleton.facing(initial)
    motion = _still(frames) + (np.arange(frames) / FPS)[None, :, None, None] * forward
    lag = 0.7 * np.clip(np.arange(frames) / FPS, 0.0, 1.0)[:, None] * forward
    motion[0, :, JOINT_INDEX["LFoot"]] -= lag
    motion[0, :, JOINT_INDEX["LKnee"]] -= 0.5 * lag
    standing, leg = initial[JOINT_INDEX["RFoot"], 2], skeleton.limb_length(initial, skeleton.LIMBS[1])
    out, contacts, _ = cleanup.plant_feet(motion, FPS, standing, np.zeros((frames, 17)), initial,
                                          np.zeros((1, frames, 2)))
    lands = np.flatnonzero(contacts[0, 1:, 1] & ~contacts[0, :-1, 1]) + 1
    hips = out[0, np.minimum(lands + int(round(cleanup.STEP_S * FPS)), frames - 1), JOINT_INDEX["LHip"]]
    room = np.sqrt(np.maximum((cleanup.STAND_SHARE * leg) ** 2 - (hips[:, 2] - standing) ** 2, 0.0))
    away = np.linalg.norm(out[0, lands, JOINT_INDEX["LFoot"], :2] - hips[:, :2], axis=-1)
    print(f"left foot landings {np.round(away, 3)} m from under the hip, room {np.round(room, 3)}")
    assert len(lands) >= 3 and (away <= room + 1e-6).all()


def test_a_torso_leaning_further_and_further_is_drawn_back_toward_the_start_pose():
    frames, initial = 300, mannequin_module.REST_JOINTS.astype(np.float64)
    motion = _still(frames)
    hip = initial[JOINT_INDEX["Hip"]]
    above = skeleton.indices(skeleton.UPPER_BODY)
    for frame, degrees in enumerate(np.linspace(0.0, 60.0, frames)):  # a forward lean growing to 60 degrees
        angle = np.radians(degrees)
        turn = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(angle), -np.sin(angle)], [0.0, np.sin(angle), np.cos(angle)]])
        motion[0, frame, above] = hip + (initial[above] - hip) @ turn.T
    upright = cleanup.upright(motion, initial, FPS)
    lean = np.degrees(cleanup._lean(upright[0, :, JOINT_INDEX["Neck"]] - upright[0, :, JOINT_INDEX["Hip"]]))
    start = np.degrees(cleanup._lean(initial[JOINT_INDEX["Neck"]] - hip))
    print(f"lean grown to 60 degrees: {lean[-1]:.1f} after (start pose {start:.1f})")
    free = start + cleanup.LEAN_FREE_DEG
    assert lean[-1] < free + cleanup.LEAN_KEPT * (60.0 - free) + 2.0 and lean.max() < 35.0
    mild = np.degrees(cleanup._lean(motion[0, :, JOINT_INDEX["Neck"]] - hip)) < free - 2.0  # well within: untouched
    np.testing.assert_allclose(upright[0, mild], motion[0, mild], atol=1e-9)
    lengths = np.linalg.norm(upright[0][:, above] - hip, axis=-1)
    np.testing.assert_allclose(lengths, np.linalg.norm(motion[0][:, above] - hip, axis=-1), atol=1e-9)


def test_a_walk_leans_to_its_gaits_lean_whatever_the_models_own():
    """Two takes walking 1.2 m/s along the mannequin's facing, one generated upright, one leaning
    12 degrees forward of the start pose: both end up leaning the gait's 3 degrees (turned to it, not
    by it: the second leaned 15), the stride's sway of +-2 degrees kept, and still where they stand."""
    frames, initial = 150, mannequin_module.REST_JOINTS.astype(np.float64)
    motion = np.repeat(_still(frames), 2, axis=0)
    forward = skeleton.facing(initial)
    walking = np.arange(frames) >= 60  # still for 2 s, then walking
    motion += (np.cumsum(walking) * 1.2 / FPS)[None, :, None, None] * forward
    hip, above = JOINT_INDEX["Hip"], skeleton.indices(skeleton.UPPER_BODY)
    across = np.cross(forward, [0.0, 0.0, 1.0])
    sway = 2.0 * np.sin(np.arange(frames) * 4.0 * np.pi / FPS)  # two a second, one a step
    for take, own in enumerate((0.0, 12.0)):
        angle = -np.radians(own + sway)
        motion[take] = cleanup._upper_body_turned(motion[take][None], np.broadcast_to(across, (1, frames, 3)),
                                                  angle[None])[0]
    leant = cleanup.leaning_into_the_walk(motion, np.array([3.0, 3.0]), FPS, initial)
    torso = leant[:, :, JOINT_INDEX["Thorax"]] - leant[:, :, hip]
    lean = np.degrees(np.arctan2(np.sum(torso * forward, axis=-1), torso[..., 2]))  # (2, F)
    print(f"walking, lean forward: {lean[:, 90:140].mean(axis=1).round(1)} degrees (sway kept: "
          f"{np.ptp(lean[:, 90:140], axis=1).round(1)})")
    np.testing.assert_allclose(lean[:, 90:140].mean(axis=1), 3.0, atol=0.3)
    assert (np.ptp(lean[:, 90:140], axis=1) > 3.8).all()  # the +-2 degree sway
    np.testing.assert_allclose(leant[:, :30], motion[:, :30], atol=1e-9)  # standing: untouched
    np.testing.assert_allclose(np.linalg.norm(leant[:, :, above] - leant[:, :, hip, None], axis=-1),
                               np.linalg.norm(motion[:, :, above] - motion[:, :, hip, None], axis=-1), atol=1e-9)


def test_hips_sinking_further_and_further_are_raised_over_the_feet():
    frames, initial = 300, mannequin_module.REST_JOINTS.astype(np.float64)
    motion = _still(frames)
    feet = [JOINT_INDEX["RFoot"], JOINT_INDEX["LFoot"]]
    standing = initial[feet, 2].min()
    start = initial[JOINT_INDEX["Hip"], 2] - standing
    sag = np.linspace(0.0, 0.5, frames) * start  # the hips sink to half their height, feet on the floor
    body = [joint for joint in range(17) if joint not in feet]
    motion[0][:, body, 2] -= sag[:, None]
    raised = cleanup.hips_up(motion, initial, FPS, standing)
    share = (raised[0, :, JOINT_INDEX["Hip"], 2] - standing) / start
    print(f"hips sunk to 0.50 of their height: {share[-1]:.2f} after")
    np.testing.assert_allclose(raised[0][:, feet], motion[0][:, feet], atol=1e-12)
    free = cleanup.HIPS_FREE_SHARE
    assert share.min() > free - cleanup.HIPS_KEPT * (free - 0.5) - 0.02
    untouched = sag / start < (1.0 - free) - 0.02
    np.testing.assert_allclose(raised[0, untouched], motion[0, untouched], atol=1e-9)
