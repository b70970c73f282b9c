"""Retargeting and rotation conversions in plain numpy, on real motion."""

import numpy as np
import pytest

from model_runtime import cleanup, filters, retarget, rotations
from model_runtime.data import dataset
from model_runtime.skeleton import JOINT_INDEX

# A plain rig of the canonical joints, each bone's head on its joint.
PARENTS = {"RHip": "Hip", "RKnee": "RHip", "RFoot": "RKnee", "LHip": "Hip", "LKnee": "LHip", "LFoot": "LKnee",
           "Spine": "Hip", "Thorax": "Spine", "Neck": "Thorax", "LShoulder": "Spine", "LElbow": "LShoulder",
           "LWrist": "LElbow", "RShoulder": "Spine", "RElbow": "RShoulder", "RWrist": "RElbow"}


def _plain_rig(pose):
    rest = {}
    for joint in ("Hip",) + tuple(PARENTS):
        matrix = np.eye(4)
        matrix[:3, 3] = pose[JOINT_INDEX[joint]]
        rest[joint] = matrix
    bones = {joint: joint for joint in rest}
    return retarget.RigState(bones=bones, matrices=rest, bases={b: np.eye(4) for b in rest},
                             drivers={b: PARENTS.get(b) for b in rest}, joints=pose.copy()), rest


def _rig_with_clavicles(pose):
    """The plain rig with a clavicle from beside the neck base to each upper arm: (rig, rest
    matrices, parents)."""
    parents = dict(PARENTS, RClavicle="Spine", LClavicle="Spine", RShoulder="RClavicle", LShoulder="LClavicle")
    plain, rest = _plain_rig(pose)
    for side in "RL":
        rest[side + "Clavicle"] = np.eye(4)
        rest[side + "Clavicle"][:3, 3] = pose[JOINT_INDEX["Thorax"]] + 0.1 * (
            pose[JOINT_INDEX[side + "Shoulder"]] - pose[JOINT_INDEX["Thorax"]])
    rig = retarget.RigState(bones=plain.bones, matrices=rest, bases={b: np.eye(4) for b in rest},
                            drivers={b: parents.get(b) for b in rest}, joints=pose.copy(),
                            clavicles={f"{side}Clavicle": f"{side}Clavicle" for side in "RL"})
    return rig, rest, parents


def _forward(rest, bases, parents=PARENTS):
    """Pose matrices (F, 4, 4) per bone of the plain rig (or one with other ``parents``)."""
    pose = {}
    while len(pose) < len(rest):
        for bone in rest:
            parent = parents.get(bone)
            if bone in pose or (parent is not None and parent not in pose):
                continue
            pose[bone] = rest[bone] @ bases[bone] if parent is None else (
                pose[parent] @ np.linalg.inv(rest[parent]) @ rest[bone] @ bases[bone])
    return pose


@pytest.fixture(scope="module")
def motion(all_clips):
    window = dataset.windows(all_clips[5:6], future=60, stride=60)[0]
    return window  # (61, 17, 3): bones rigid over time


def test_retarget_puts_hands_and_feet_on_their_targets_with_rig_lengths(motion):
    """Feet, and hands the artist pinned, on their targets (free hands keep their pose against the
    rig's shoulders instead: ``test_a_free_arm_keeps_its_pose_against_the_rigs_shoulder``)."""
    rig, rest = _plain_rig(motion[0])
    targets = motion[1:]
    pinned = np.zeros(targets.shape[:2])
    pinned[:, [JOINT_INDEX["RWrist"], JOINT_INDEX["LWrist"]]] = 1.0
    bases = retarget.bone_bases(rig, retarget.joint_deltas(rig, targets, pinned))
    pose = _forward(rest, bases)
    for end in ("RFoot", "LFoot", "RWrist", "LWrist"):
        error = np.linalg.norm(pose[end][:, :3, 3] - targets[:, JOINT_INDEX[end]], axis=-1)
        assert error.mean() < 0.005, end
    for joint in PARENTS:  # everything else close, bones never stretched
        error = np.linalg.norm(pose[joint][:, :3, 3] - targets[:, JOINT_INDEX[joint]], axis=-1)
        assert error.mean() < 0.06, joint
    achieved = retarget.achieved_joints(rig, retarget.joint_deltas(rig, targets, pinned))
    for joint in PARENTS:
        np.testing.assert_allclose(achieved[:, JOINT_INDEX[joint]], pose[joint][:, :3, 3], atol=1e-6)
    thigh = np.linalg.norm(pose["RKnee"][:, :3, 3] - pose["RHip"][:, :3, 3], axis=-1)
    np.testing.assert_allclose(thigh, np.linalg.norm(motion[0, JOINT_INDEX["RKnee"]] - motion[0, JOINT_INDEX["RHip"]]),
                               rtol=1e-6)


def test_retarget_of_the_initial_pose_changes_nothing(motion):
    """The rig's own pose with its hips where the artist put them (a shot's first frame) retargets to
    itself; unfixed, the pelvis would come down to bend straight legs to ``retarget.LEG_REACH``."""
    rig, rest = _plain_rig(motion[0])
    pinned = np.zeros((3, 17))
    pinned[:, JOINT_INDEX["Hip"]] = 1.0
    bases = retarget.bone_bases(rig, retarget.joint_deltas(rig, np.repeat(motion[:1], 3, axis=0), pinned))
    for bone, basis in bases.items():
        np.testing.assert_allclose(basis, np.broadcast_to(np.eye(4), basis.shape), atol=1e-5, err_msg=bone)


def test_a_rigs_clavicles_put_its_shoulders_where_the_generated_ones_are(motion):
    """A shrug: the generated right arm turned 15 degrees up about its clavicle's head. A rig whose
    clavicles stay put leaves its shoulder, and so the held hand's reach, where the chest carries it."""
    J = JOINT_INDEX
    rig, rest, parents = _rig_with_clavicles(motion[0])
    plain, _ = _plain_rig(motion[0])
    targets = motion[1:].copy()
    head = targets[:, J["Thorax"]] + 0.1 * (targets[:, J["RShoulder"]] - targets[:, J["Thorax"]])  # (F, 3)
    forward = np.cross(targets[:, J["LShoulder"]] - targets[:, J["RShoulder"]], [0.0, 0.0, 1.0])
    forward /= np.linalg.norm(forward, axis=-1, keepdims=True)
    angle = np.radians(15.0)  # about the forward axis, the right arm's side rises
    for joint in ("RShoulder", "RElbow", "RWrist"):
        offset = targets[:, J[joint]] - head
        along = np.sum(offset * forward, axis=-1, keepdims=True) * forward
        targets[:, J[joint]] = head + along + np.cos(angle) * (offset - along) + np.sin(angle) * np.cross(offset, forward)
    pinned = np.zeros(targets.shape[:2])
    pinned[:, J["RWrist"]] = 1.0
    pose = _forward(rest, retarget.bone_bases(rig, retarget.joint_deltas(rig, targets, pinned)), parents)
    unturned = retarget.achieved_joints(plain, retarget.joint_deltas(plain, targets, pinned))
    error = np.linalg.norm(pose["RShoulder"][:, :3, 3] - targets[:, J["RShoulder"]], axis=-1)
    fixed = np.linalg.norm(unturned[:, J["RShoulder"]] - targets[:, J["RShoulder"]], axis=-1)
    print(f"shrugged shoulder {100 * error.mean():.2f} cm from the generated one on average "
          f"({100 * fixed.mean():.2f} with the clavicle unturned)")
    assert error.mean() < 0.01 and fixed.mean() > 0.03
    assert np.linalg.norm(pose["RWrist"][:, :3, 3] - targets[:, J["RWrist"]], axis=-1).mean() < 0.005
    first = retarget.bone_bases(rig, retarget.joint_deltas(rig, np.repeat(motion[:1], 3, axis=0),
                                                           np.ones((3, 17)) * (np.arange(17) == J["Hip"])))
    for bone, basis in first.items():  # the rig's own pose retargets to itself, clavicles too
        np.testing.assert_allclose(basis, np.broadcast_to(np.eye(4), basis.shape), atol=1e-5, err_msg=bone)


def test_a_clavicle_turns_no_further_than_captured_shoulders_do(motion):
    rig, rest, parents = _rig_with_clavicles(motion[0])
    targets = np.repeat(motion[:1], 5, axis=0)
    targets[:, JOINT_INDEX["RShoulder"], 2] += np.linspace(0.0, 0.3, 5)  # up to 30 cm above where it was
    bases = retarget.bone_bases(rig, retarget.joint_deltas(rig, targets))
    turned = np.degrees(np.arccos(np.clip((np.trace(bases["RClavicle"][:, :3, :3], axis1=1, axis2=2) - 1) / 2, -1, 1)))
    print(f"clavicle turned {np.round(turned, 1)} degrees")
    assert np.all(np.diff(turned) > 0.0) and turned.max() < retarget.MAX_CLAVICLE_DEG


def test_a_pelvis_lowered_for_a_foot_out_of_reach_rises_again_eased(motion):
    """A foot 15 cm below what the legs reach for 8 frames, then within reach: the pelvis drops to
    let it reach and comes back up over frames. Its direction, smoothed over fewer frames than its
    size, was nothing 4 frames on and the last 7 cm went in one frame (a wave's hips, 38 m/s^2)."""
    rig, _ = _plain_rig(motion[0])
    targets = np.repeat(motion[:1], 24, axis=0)
    targets[:, [JOINT_INDEX["Hip"], JOINT_INDEX["RHip"], JOINT_INDEX["LHip"]], 2] -= 0.05  # knees bent
    targets[:8, JOINT_INDEX["RFoot"], 2] -= 0.15
    hips = retarget._apply(retarget.joint_deltas(rig, targets)["Hip"], rig.joints[JOINT_INDEX["Hip"]])
    drop = hips[:, 2] - hips[-1, 2]
    print(f"pelvis drop (cm) {np.round(100 * drop, 1)}")
    assert drop.min() < -0.08 and np.abs(np.diff(drop)).max() < 0.45 * -drop.min()


def test_unreachable_targets_stretch_nothing(motion):
    rig, rest = _plain_rig(motion[0])
    targets = motion[1:].copy()
    targets[:, JOINT_INDEX["LWrist"]] += [0.0, 0.0, 1.0]  # a metre above reach
    pose = _forward(rest, retarget.bone_bases(rig, retarget.joint_deltas(rig, targets)))
    forearm = np.linalg.norm(pose["LWrist"][:, :3, 3] - pose["LElbow"][:, :3, 3], axis=-1)
    np.testing.assert_allclose(forearm, np.linalg.norm(motion[0, JOINT_INDEX["LWrist"]] - motion[0, JOINT_INDEX["LElbow"]]),
                               rtol=1e-6)


@pytest.mark.parametrize("order", ["XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX"])
def test_euler_and_quaternion_conversions_round_trip(order):
    rng = np.random.default_rng(1)
    quats = rng.standard_normal((50, 4))
    quats /= np.linalg.norm(quats, axis=-1, keepdims=True)
    matrices = rotations.to_matrix(quats)
    back = rotations.to_matrix(rotations.from_matrix(matrices))
    np.testing.assert_allclose(back, matrices, atol=1e-9)
    angles = rotations.to_euler(matrices, order)
    # Blender's "XYZ" (X first) is Rz @ Ry @ Rx, which rotations.euler calls "ZYX"; angles are (x, y, z)
    reversed_order = order[::-1]
    rebuilt = rotations.to_matrix(rotations.euler(np.degrees(angles[:, ["XYZ".index(a) for a in reversed_order]]),
                                                  reversed_order))
    np.testing.assert_allclose(rebuilt, matrices, atol=1e-9)
    axis_angle = rotations.to_axis_angle(rotations.from_matrix(matrices))
    half = axis_angle[:, :1] / 2
    np.testing.assert_allclose(rotations.to_matrix(np.concatenate([np.cos(half), np.sin(half) * axis_angle[:, 1:]], -1)),
                               matrices, atol=1e-9)


def test_quaternions_are_made_continuous():
    quats = rotations.axis_angle("Z", np.linspace(0, 6.0, 40))
    flipped = np.where(np.arange(40)[:, None] % 3 == 0, -quats, quats)
    smooth = rotations.continuous(flipped)
    assert np.all(np.sum(smooth[1:] * smooth[:-1], axis=-1) > 0)


def test_the_chest_leans_so_a_pinned_hand_beyond_reach_gets_there(motion):
    rig, rest = _plain_rig(motion[0])
    targets = motion[1:].copy()
    shoulder, wrist = JOINT_INDEX["LShoulder"], JOINT_INDEX["LWrist"]
    away = targets[:, wrist] - targets[:, shoulder]
    targets[:, wrist] += 0.12 * away / np.linalg.norm(away, axis=-1, keepdims=True)  # 12 cm past the hand
    pinned = np.zeros(targets.shape[:2])
    pinned[:, wrist] = 1.0
    errors = {}
    for name, mask in (("free", None), ("pinned", pinned)):
        pose = _forward(rest, retarget.bone_bases(rig, retarget.joint_deltas(rig, targets, mask)))
        errors[name] = np.linalg.norm(pose["LWrist"][:, :3, 3] - targets[:, wrist], axis=-1).mean()
    assert errors["free"] > 0.02 and errors["pinned"] < 0.005, errors


def test_the_trunk_alone_tells_how_far_a_pinned_hand_misses_as_the_whole_retarget_does(motion):
    """``hands_missed`` (the shot's screen of its candidates) against where the whole retarget
    puts the hand, for a hand 40 cm past its reach (which the chest's lean cannot make up) and
    for one pulled onto its shoulder (tighter than the elbow folds)."""
    rig, rest = _plain_rig(motion[0])
    shoulder, wrist = JOINT_INDEX["LShoulder"], JOINT_INDEX["LWrist"]
    pinned = np.zeros((len(motion) - 1, len(JOINT_INDEX)))
    pinned[:, wrist] = 1.0
    far, near = motion[1:].copy(), motion[1:].copy()
    away = far[:, wrist] - far[:, shoulder]
    far[:, wrist] += 0.4 * away / np.linalg.norm(away, axis=-1, keepdims=True)
    near[:, wrist] = near[:, shoulder] + 0.01 * away / np.linalg.norm(away, axis=-1, keepdims=True)
    for targets in (far, near):
        pose = _forward(rest, retarget.bone_bases(rig, retarget.joint_deltas(rig, targets, pinned)))
        whole = np.linalg.norm(pose["LWrist"][:, :3, 3] - targets[:, wrist], axis=-1)
        assert whole.min() > 0.01
        np.testing.assert_allclose(retarget.hands_missed(rig, targets, pinned)[:, 1], whole, atol=1e-4)


def test_a_hand_held_within_a_screened_fold_counts_as_missed_only_by_that_fold(motion):
    """A hand pinned where its elbow must fold to cosine -0.8 between the bones: within the
    retarget's reach (it folds to -0.92), but short of the fold the shot screens candidates with
    (``selection.SCREENED_FOLD_COS``), by about as much as the two folds' reaches differ (2.9 cm;
    the rig's rigid trunk puts the shoulder a few millimetres from the motion's)."""
    rig, _ = _plain_rig(motion[0])
    shoulder, wrist = JOINT_INDEX["LShoulder"], JOINT_INDEX["LWrist"]
    pinned = np.zeros((len(motion) - 1, len(JOINT_INDEX)))
    pinned[:, wrist] = 1.0
    upper, lower = (np.linalg.norm(motion[0, JOINT_INDEX[b]] - motion[0, JOINT_INDEX[a]])
                    for a, b in (("LShoulder", "LElbow"), ("LElbow", "LWrist")))
    reach = lambda cos: np.sqrt(upper ** 2 + lower ** 2 + 2.0 * upper * lower * cos)
    targets = motion[1:].copy()
    away = targets[:, wrist] - targets[:, shoulder]
    targets[:, wrist] = targets[:, shoulder] + reach(-0.8) * away / np.linalg.norm(away, axis=-1, keepdims=True)
    assert retarget.hands_missed(rig, targets, pinned)[:, 1].max() < 1e-3
    screened = retarget.hands_missed(rig, targets, pinned, tightest_fold_cos=-0.7)[:, 1]
    np.testing.assert_allclose(screened, reach(-0.7) - reach(-0.8), atol=0.01)


def test_a_free_hand_carried_past_its_reach_straightens_the_arm_gently(motion):
    """A hand moving out along its arm from 0.94 to 1.03 of the arm's length in 3 frames: solved
    exactly (as a pinned hand is) the elbow snaps onto the straight arm; a free hand's reach is
    smoothed over frames first (FREE_REACH_SMOOTHING), its elbow accelerating at a fraction of that."""
    rig, _ = _plain_rig(motion[0])
    start = motion[0]
    shoulder, elbow, wrist = (JOINT_INDEX[name] for name in ("LShoulder", "LElbow", "LWrist"))
    arm = np.linalg.norm(start[elbow] - start[shoulder]) + np.linalg.norm(start[wrist] - start[elbow])
    way = (start[wrist] - start[shoulder]) / np.linalg.norm(start[wrist] - start[shoulder])
    share = np.concatenate([np.full(10, 0.94), np.linspace(0.94, 1.03, 4)[1:], np.full(10, 1.03)])
    targets = np.repeat(start[None], len(share), axis=0)
    targets[:, wrist] = start[shoulder] + share[:, None] * arm * way
    targets[:, elbow] = start[shoulder] + 0.5 * share[:, None] * arm * way + 0.05 * np.cross(way, [0.0, 0.0, 1.0])
    accelerations = {}
    for name, held in (("pinned", 1.0), ("free", 0.0)):
        pinned = np.zeros(targets.shape[:2])
        pinned[:, wrist] = held
        placed = retarget.achieved_joints(rig, retarget.joint_deltas(rig, targets, pinned))[:, elbow]
        accelerations[name] = np.linalg.norm(np.diff(placed, 2, axis=0), axis=-1).max()
    assert accelerations["free"] < 0.5 * accelerations["pinned"], accelerations


def test_a_lean_toward_a_hand_at_the_arms_full_reach_changes_gently_instead_of_flickering(motion):
    """A pinned hand hovering about the arm's full reach from the chest (1 % beyond, then 1 % short,
    frame by frame) needs a lean that jumps by about 10 degrees between those frames; the chest's
    lean changes by LEAN_DEG_PER_FRAME at most, still as far as each frame needs."""
    rig, rest = _plain_rig(motion[0])
    pose = motion[0]
    spine, shoulder, wrist = (JOINT_INDEX[name] for name in ("Spine", "LShoulder", "LWrist"))
    arm = pose[shoulder] - pose[spine]
    reach = retarget.limb_length(pose, ("LShoulder", "LElbow", "LWrist"))
    side = np.cross(arm, [0.0, 0.0, 1.0])
    away = np.cos(np.radians(20.0)) * arm / np.linalg.norm(arm) + np.sin(np.radians(20.0)) * side / np.linalg.norm(side)
    frames = 30
    distance = (np.linalg.norm(arm) + reach) * np.where(np.arange(frames) % 2 == 0, 1.01, 0.99)
    targets = np.repeat(pose[None], frames, axis=0)
    targets[:, wrist] = pose[spine] + distance[:, None] * away
    pinned = np.zeros(targets.shape[:2])
    pinned[:, wrist] = 1.0
    chest = _forward(rest, retarget.bone_bases(rig, retarget.joint_deltas(rig, targets, pinned)))["Spine"][:, :3, :3]
    turns = [np.degrees(np.arccos(np.clip((np.trace(a.T @ b) - 1.0) / 2.0, -1.0, 1.0))) for a, b in zip(chest, chest[1:])]
    leans = [np.degrees(np.arccos(np.clip((np.trace(c) - 1.0) / 2.0, -1.0, 1.0))) for c in chest]
    assert max(turns) < retarget.LEAN_DEG_PER_FRAME + 0.05, turns
    assert min(leans[5:-5]) > 15.0, leans  # as far as the frames beyond reach need (about 20 degrees)


def test_a_free_arm_keeps_its_pose_against_the_rigs_shoulder(motion):
    """Generated shoulders 10 cm above where the rig's chest puts them (the upper body stretched
    up from the hips): each free hand keeps its place against the rig's shoulder, as generated against its
    own, not its place in the scene (there a hand folded near its shoulder swung the elbow over in a
    frame)."""
    rig, rest = _plain_rig(motion[0])
    targets = motion[1:].copy()
    upper = [JOINT_INDEX[name] for name in ("Spine", "Thorax", "Neck", "Head", "LShoulder", "LElbow", "LWrist",
                                            "RShoulder", "RElbow", "RWrist")]
    targets[:, upper, 2] += 0.10
    pose = _forward(rest, retarget.bone_bases(rig, retarget.joint_deltas(rig, targets, np.zeros(targets.shape[:2]))))
    for side in "LR":
        shoulder, wrist = pose[side + "Shoulder"][:, :3, 3], pose[side + "Wrist"][:, :3, 3]
        generated = targets[:, JOINT_INDEX[side + "Wrist"]] - targets[:, JOINT_INDEX[side + "Shoulder"]]
        assert np.linalg.norm(wrist - shoulder - generated, axis=-1).mean() < 0.01, side
        assert np.linalg.norm(wrist - targets[:, JOINT_INDEX[side + "Wrist"]], axis=-1).mean() > 0.05, side


def _left_arm(pose):
    """The left arm's joint indices, its upper and lower bones' lengths and, at its shoulder, the
    pose's forward and the way perpendicular to it and to the shoulders that points down (3,)."""
    shoulder, elbow, wrist = (JOINT_INDEX[name] for name in ("LShoulder", "LElbow", "LWrist"))
    upper, lower = (np.linalg.norm(pose[b] - pose[a]) for a, b in ((shoulder, elbow), (elbow, wrist)))
    across = pose[shoulder] - pose[JOINT_INDEX["RShoulder"]]
    forward = np.cross([0.0, 0.0, 1.0], across)
    forward /= np.linalg.norm(forward)
    return shoulder, elbow, wrist, upper, lower, forward, np.cross(forward, across / np.linalg.norm(across))


def test_an_elbow_turns_about_its_arm_a_little_each_frame_where_the_model_flips_it(motion):
    """A pinned hand held 0.2 m in front of its shoulder, the arm folded, while the generated elbow
    flips from one side of the arm to the other in a frame (as the model's did where a Rigify
    reach's hand passed 0.17 m from the shoulder: 63 m/s^2 on the elbow): the rig's elbow turns
    over to the new side at MAX_POLE_DEG_PER_FRAME, no faster (35 cm in a frame without), and gets there."""
    rig, rest = _plain_rig(motion[0])
    pose = motion[0]
    shoulder, elbow, wrist, _, _, forward, _ = _left_arm(pose)
    frames, flip = 45, 15
    targets = np.repeat(pose[None], frames, axis=0)
    targets[:, wrist] = pose[shoulder] + 0.2 * forward
    side = np.where(np.arange(frames) < flip, 1.0, -1.0)[:, None] * np.array([0.0, 0.0, 1.0])  # above, then below
    targets[:, elbow] = pose[shoulder] + 0.1 * forward + 0.2 * side
    pinned = np.zeros(targets.shape[:2])
    pinned[:, wrist] = 1.0
    achieved = retarget.achieved_joints(rig, retarget.joint_deltas(rig, targets, pinned))[:, elbow]
    radius = np.linalg.norm(np.cross(achieved[0] - pose[shoulder], forward))  # from the shoulder-hand line
    steps = np.linalg.norm(np.diff(achieved, axis=0), axis=-1)
    most = 2.0 * radius * np.sin(np.radians(retarget.MAX_POLE_DEG_PER_FRAME) / 2.0)
    print(f"elbow {radius:.3f} m off the arm's line; moves up to {100 * steps.max():.1f} cm a frame "
          f"(at most {100 * most:.1f})")
    assert steps.max() <= 1.05 * most
    assert np.dot(achieved[-1] - pose[shoulder], side[-1]) > 0.9 * radius  # on the generated side by the end


def test_an_elbow_turns_to_a_keyed_bend_the_short_way_on_each_side_of_a_straight_arm(motion):
    """Keys ease in and out on the elbow, whose generated bend turns from one side of the arm to the
    other through a frame where the arm is straight and the bend is noise (as the blocking keys'
    arms-up key did: 167 degrees there, then -110). Each stretch of keyed frames is turned to the short way
    round on its own: unwrapped across the straight frame and shifted as one, the bend after the key
    spun the long way round (60 degrees a frame, the elbow at 78 m/s^2)."""
    rig, rest = _plain_rig(motion[0])
    pose = motion[0]
    shoulder, elbow, wrist, upper, lower, forward, down = _left_arm(pose)
    frames, straight = 60, 30
    reach = np.where(np.arange(frames) == straight, 1.0, 0.85) * (upper + lower)
    targets = np.repeat(pose[None], frames, axis=0)
    targets[:, wrist] = pose[shoulder] + reach[:, None] * forward
    # about the arm from ``down``; the rig's own bend direction lies 94 degrees round, so to the
    # retarget these read 63 degrees, then 167 on the straight frame, then -111, as the keys' did
    angle = np.radians(np.where(np.arange(frames) < straight, -31.0, 155.0))
    angle[straight] = np.radians(73.0)
    offset = np.sqrt(np.maximum(upper ** 2 - (reach / 2.0) ** 2, 1e-6))
    offset[straight] = 1e-4  # 0.1 mm off the line
    bend = np.cos(angle)[:, None] * down + np.sin(angle)[:, None] * np.cross(forward, down)
    targets[:, elbow] = pose[shoulder] + 0.5 * reach[:, None] * forward + offset[:, None] * bend
    pinned = np.zeros(targets.shape[:2])
    pinned[:, wrist] = 1.0
    for key, ease in ((8, 8), (straight, 12)):  # an early key, and one on the straight arm
        pinned[:, elbow] = np.maximum(pinned[:, elbow], np.clip(1.0 - np.abs(np.arange(frames) - key) / ease, 0, 1))
    achieved = retarget.achieved_joints(rig, retarget.joint_deltas(rig, targets, pinned))[:, elbow]
    after = np.linalg.norm(np.diff(achieved[straight + 1:], axis=0), axis=-1)
    print(f"elbow after the straight frame: up to {100 * after.max():.1f} cm a frame")
    assert after.max() < 0.03


def test_a_nearly_straight_keyed_arm_bent_backwards_does_not_swing_the_elbow(motion):
    """A key on an arm held all but straight, its generated elbow 1.5 cm off the arm's line on the
    side its hinge cannot bend to, while the rig's arm, shorter of the hand, bends: that bend's
    direction is noise, so the key's weight, easing in and out over KEY_BRIDGE_S as
    ``cleanup.pinned_joints`` gives it, turns the elbow only as far as the arm bends backwards at all.
    Trusted as bent, the elbow swung 25 cm round the arm and back within the key's 15 frames at 41
    m/s^2 (the blocking keys' arms-up key, after the facing-frame model: 38 m/s^2, 8.5x the median
    frame); now 12 cm at 11 m/s^2, as far as the bend is sure (KEYED_BEND_SURE)."""
    rig, rest = _plain_rig(motion[0])
    pose = motion[0]
    shoulder, elbow, wrist, upper, lower, forward, down = _left_arm(pose)
    frames, key = 40, 20
    targets = np.repeat(pose[None], frames, axis=0)
    targets[:, wrist] = pose[shoulder] + 0.8 * (upper + lower) * forward
    # about the arm from ``down``; the rig's own bend direction lies 94 degrees round: this is behind it
    angle = np.radians(180.0 - 94.0)
    bend = np.cos(angle) * down + np.sin(angle) * np.cross(forward, down)
    targets[:, elbow] = pose[shoulder] + 0.4 * (upper + lower) * forward + 0.015 * bend
    pinned = np.zeros(targets.shape[:2])
    pinned[:, wrist] = 1.0
    pinned[:, elbow] = 1.0 - filters.smoothstep(np.abs(np.arange(frames) - key) / (cleanup.KEY_BRIDGE_S * 30.0))
    achieved = retarget.achieved_joints(rig, retarget.joint_deltas(rig, targets, pinned))[:, elbow]
    acceleration = np.linalg.norm(achieved[2:] - 2 * achieved[1:-1] + achieved[:-2], axis=-1) * 30.0 ** 2
    print(f"elbow of a nearly straight keyed arm: up to {acceleration.max():.1f} m/s^2, "
          f"{100 * np.linalg.norm(achieved - achieved[0], axis=-1).max():.1f} cm from where it started")
    assert acceleration.max() < 15.0


def test_an_upper_arm_never_points_straight_back_for_a_hand_behind_and_above_the_shoulder(motion):
    """A pinned hand carried from in front of its shoulder over to behind and above it, the generated
    elbow hanging down and swinging from one side of the arm to the other (as a Rigify reach's body
    turned from its curve did: the rig's upper arm pointed straight back at shoulder height, its
    cosine with the body's forward -0.93 to -0.99 on a third of the frames): the rig's upper arm
    keeps UPPER_ARM_BACK_COS, and its elbow turns there without a jump."""
    rig, rest = _plain_rig(motion[0])
    pose = motion[0]
    shoulder, elbow, wrist = (JOINT_INDEX[name] for name in ("LShoulder", "LElbow", "LWrist"))
    upper, lower = (np.linalg.norm(pose[b] - pose[a]) for a, b in ((shoulder, elbow), (elbow, wrist)))
    across = (pose[shoulder] - pose[JOINT_INDEX["RShoulder"]]) * np.array([1.0, 1.0, 0.0])
    across /= np.linalg.norm(across)
    forward = retarget._facing(pose[None])[0]
    up = np.cross(across, forward)
    frames = 60
    lift = np.radians(np.linspace(30.0, 150.0, frames))  # from the front, over the top, to behind
    targets = np.repeat(pose[None], frames, axis=0)
    targets[:, wrist] = pose[shoulder] + 0.6 * (upper + lower) * (
        np.cos(lift)[:, None] * forward + np.sin(lift)[:, None] * up)
    swing = np.linspace(0.1, -0.1, frames)[:, None] * across  # hanging, from outside to inside
    targets[:, elbow] = pose[shoulder] + upper * (-0.95 * up + swing)
    pinned = np.zeros(targets.shape[:2])
    pinned[:, wrist] = 1.0
    achieved = retarget.achieved_joints(rig, retarget.joint_deltas(rig, targets, pinned))
    arm = achieved[:, elbow] - achieved[:, shoulder]
    backward = np.sum(arm / np.linalg.norm(arm, axis=-1, keepdims=True) * retarget._facing(achieved), axis=-1)
    steps = np.linalg.norm(np.diff(achieved[:, elbow], axis=0), axis=-1)
    hand_off = np.linalg.norm(achieved[:, wrist] - targets[:, wrist], axis=-1).max()
    print(f"upper arm's least cosine with forward {backward.min():.3f} (floor {retarget.UPPER_ARM_BACK_COS}); "
          f"elbow up to {100 * steps.max():.1f} cm a frame, hand {100 * hand_off:.1f} cm off")
    assert backward.min() >= retarget.UPPER_ARM_BACK_COS - 0.01
    assert steps.max() < 0.04
    assert hand_off < 0.005
