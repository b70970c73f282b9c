"""Joint positions to bone rotations on an artist's rig, vectorised over frames (no bpy).

Everything happens in the rig's armature space and relative to the rig's
initial pose (the evaluated pose at the start frame), so rest-pose axes, bone
rolls and units do not matter. Each mapped bone gets a rigid world "delta"
(F, 4, 4) that carries its initial matrix to the new one:

- Hip (the root): pelvis frame (hips across exactly, torso up) and translation of the
  pelvis centre, moved where a leg could not reach its foot.
- Spine: chest frame (shoulders across, torso up), about the bone's head.
- Thorax and Neck (the neck and head bones): along the generated segment to
  the next joint, or at it where the artist fixed it (aimed at generated
  points from the rig's own neck base, the head tilted against the neck
  beyond the fitted limits on 27 % of idle frames; 2 % along them).
- Legs and arms: a two-bone solve from the (carried) hip or shoulder to the
  generated ankle or wrist, bending towards the generated knee or elbow, with
  the rig's own bone lengths (never stretched), the upper bone twisted so the
  limb bends about its initial hinge. Feet keep their initial orientation
  turned with the pelvis heading; hands follow the forearm.

A bone's parent space is assumed to move with its nearest mapped ancestor
(``drivers``): exact when the bones between them keep their initial pose.
"""

from dataclasses import dataclass, field
import math

import numpy as np

from . import rotations
from .filters import rate_limited_from_above, runs, smooth, smoothstep, window_max
from .skeleton import JOINT_INDEX, LIMBS, limb_length

J = JOINT_INDEX
# Share of a limb's length it is stretched to at most: a limb held straight keeps a hint of bend, so
# the solve still knows which way it bends (a keyed straight arm's elbow is met within 4 mm).
REACH_MARGIN = 0.9999
# Generated hips or shoulders narrower than this share of the rig's are not trusted for direction;
# directions are smoothed over this many frames (sigma).
ACROSS_TRUST = 0.6
ACROSS_SMOOTHING = 1.5
# The most (degrees) the chest turns toward each pinned hand beyond reach.
MAX_LEAN_TO_HAND = 30.0
# Where no chest bone is mapped (Rigify's torso control turns the trunk as one), the most the trunk
# leans from the hips instead: at 30 the lean jerked a Rigify wave's body (9x the median frame).
MAX_TRUNK_LEAN_TO_HAND = 15.0
# How fast (degrees per frame) a lean toward a hand may come and go where the lean a frame needs
# changes faster: where a hand hovers at the arm's full reach the least lean that reaches it is
# steep in the hand's distance (arccos), so a wave's chest leaned 11.6, 1.8, then 11.7 degrees
# on consecutive frames (124 m/s^2 on the free elbow) and dropped 7-10 degrees in a frame where the
# hand came back within reach. Every frame still leans as far as it needs, a key's frame no further.
LEAN_DEG_PER_FRAME = 1.0
# How far (degrees) the way a knee or elbow points may turn about its limb in one frame: where the
# hand passes close to the shoulder that way is steep in the limb's direction (see _turning_at_most).
MAX_POLE_DEG_PER_FRAME = 10.0
# How far (degrees) a knee or elbow may point away from the way its hinge bends it, and the bend (in
# upper-limb lengths) at which the generated direction counts half.
MAX_BEND_TURN = {"leg": 30.0, "arm": 90.0}
# ... and the turn taken from the generated bend is smoothed over this many frames (Gaussian sigma):
# where the generated elbow swings past its hinge's side the turn rises and falls within a few frames
# (a Rigify elbow before a key: 57 m/s^2 clipped hard, 37 eased into the limit, 9 smoothed as well).
BEND_SMOOTHING = 2.0
# A knee turns at most this far (degrees) inward, toward the other leg: the model's knees pointed
# up to 22 degrees inward through whole idle shots (knock-kneed; captured motion: 0-12).
KNEE_INWARD_DEG = 8.0
# An upper arm points at most this far back (cosine with the body's forward): the joint-angle limits
# fitted on capture reach -0.92 / -0.94. Where a body turned from its hand's curve puts the hand behind
# and above the shoulder, an elbow bent the way the generated one hangs (down) points the upper arm
# straight back at shoulder height (a Rigify reach at -0.93 to -0.99 on a third of its frames); the
# elbow is turned about the limb, the least way, until the upper arm keeps this.
UPPER_ARM_BACK_COS = -0.9
POLE_PRIOR = 0.2
KEYED_BEND_TRUST = 0.05  # a keyed middle joint this far (upper-limb lengths) off its limb's line sets the bend,
KEYED_BEND_SURE = 0.25  # ... bent the way its hinge bends it; this far, whichever way (see _limb)
# Frames trusted less than this (a keyed limb all but straight, or the key's weight all but gone)
# part the stretches a keyed bend is turned to on its own; each such frame takes it the short way round.
KEYED_SPLIT = 0.02
# No knee or elbow folds tighter than captured ones do: the cosine between the upper and lower
# bones' directions stays above this (the fitted angle limits: -0.93 to -0.94).
TIGHTEST_FOLD_COS = -0.92
# A free hand's (no curve or key holds it) distance from its shoulder is smoothed over this many
# frames (Gaussian sigma) before the arm is solved for it: near the arm's full reach the elbow's
# offset from the straight line changes ever faster with that distance, and a free hand carried
# from 0.94 to 1.03 of the arm's reach in 3 frames snapped the elbow 7 cm onto the straight arm
# (Rigify, blocking keys after the key: 49 m/s^2, 8.8x the median frame, where the generated
# elbow moved at 5 m/s^2). An arm held straight, or steadily bent, is solved as before. Where a
# key's weight eases out the smoothing comes in as the square of the hand's freedom: in
# proportion, a keyed straight arm's elbow took 6.2x the median frame's acceleration on the key
# frame (5.1x unsmoothed, 5.5x now).
FREE_REACH_SMOOTHING = 2.0
# Near a limb's full length its middle joint's offset from the straight line goes as the square root of
# the end's shortfall, so an end that comes to the full length and back (a keyed straight arm) took
# its elbow in and out again with a corner: 30 m/s^2, 7x the median frame, on the key frame of a
# mannequin's arms-up key. Where a curve or key holds the hand, its shortfall s is taken as
# s (1 - exp(-s / c)), c = STRAIGHTENING_SHARE x the arm's length, as a soft solve would: the same
# at the full length and far from it, the elbow leaving the line smoothly, and the hand at most c / e
# beyond its target between (1.5 mm on the mannequin). Free hands have their reach smoothed instead
# (FREE_REACH_SMOOTHING), and legs are solved as asked: standing legs hold their knees within this
# range, where the ease stirred them (idle shots' worst frames 6.7x -> 8.4x the median, seeds 0-5).
STRAIGHTENING_SHARE = 0.008
REQUIRED_JOINTS = ("Hip",) + tuple(joint for limb in LIMBS for joint in limb) + ("Thorax", "Neck")
# A rig's clavicle (the bone between the chest and an upper arm, keyed as "RClavicle" / "LClavicle"
# where it has one) turns so its shoulder follows the generated one, up to MAX_CLAVICLE_DEG from its
# start relative to the chest (eased as tanh; captured shoulders turn against the chest from where
# they start by 3 degrees on the median frame, 10 on the 90th percentile, 30 on the 99th). Left as
# it started, the mannequin's shoulder stayed 5-9 cm inside the generated one wherever a wave's hand
# was raised: 8 of 25 candidates kept the hand on its curve for 10 s, 18 now (seeds 0-5).
CLAVICLES = {"RShoulder": "RClavicle", "LShoulder": "LClavicle"}
MAX_CLAVICLE_DEG = 30.0


@dataclass
class RigState:
    """A rig at its initial pose, in armature space.

    bones: canonical joint -> keyed bone name (joints without a bone absent)
    matrices: bone -> (4, 4) initial pose matrix; bases: bone -> (4, 4) initial matrix_basis
    drivers: bone -> the keyed bone whose motion carries its parent space, or None
    joints: (17, 3) initial joint positions
    clavicles: see CLAVICLES
    """

    bones: dict
    matrices: dict
    bases: dict
    drivers: dict
    joints: np.ndarray
    clavicles: dict = field(default_factory=dict)  # "RClavicle" / "LClavicle" -> bone, where the rig has one

    @property
    def keyed(self):
        """{joint or clavicle: bone} of every bone the retarget keys."""
        return {**self.bones, **self.clavicles}


def _unit(v, eps=1e-9):
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), eps)


def frame(primary, secondary):
    """Orthonormal frames (..., 3, 3) as columns (x, y, z): z along ``primary`` (..., 3), x along
    ``secondary`` made orthogonal to it."""
    z = _unit(primary)
    x = _unit(secondary - np.sum(secondary * z, axis=-1, keepdims=True) * z)
    return np.stack([x, np.cross(z, x), z], axis=-1)


def swing(a, b):
    """Smallest rotations (..., 3, 3) taking directions a to b (..., 3)."""
    a, b = _unit(a), _unit(b)
    axis = np.cross(a, b)
    cos = np.sum(a * b, axis=-1)
    opposite = cos < -1.0 + 1e-9
    if np.any(opposite):  # any axis perpendicular to a
        helper = np.where(np.abs(a[..., :1]) < 0.9, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
        axis = np.where(opposite[..., None], _unit(np.cross(a, helper)) * 1e-9, axis)
    k = np.zeros(axis.shape + (3,))
    k[..., 0, 1], k[..., 0, 2], k[..., 1, 2] = -axis[..., 2], axis[..., 1], -axis[..., 0]
    k = k - np.swapaxes(k, -1, -2)
    scale = 1.0 / np.maximum(1.0 + cos, 1e-18)
    rotation = np.eye(3) + k + (k @ k) * scale[..., None, None]
    flip = 2.0 * np.einsum("...i,...j->...ij", _unit(axis), _unit(axis)) - np.eye(3)
    return np.where(opposite[..., None, None], flip, rotation)


def _rigid(rotation, pivot_before, pivot_after):
    """Deltas (F, 4, 4): rotate about pivot_before (3,) and move it to pivot_after (F, 3)."""
    delta = np.zeros(rotation.shape[:-2] + (4, 4))
    delta[..., :3, :3] = rotation
    delta[..., :3, 3] = pivot_after - rotation @ pivot_before
    delta[..., 3, 3] = 1.0
    return delta


def _apply(delta, point):
    """Points (F, 3) of a point (3,), or of each frame's point (F, 3), moved by deltas (F, 4, 4)."""
    return (delta[..., :3, :3] @ point[..., None])[..., 0] + delta[..., :3, 3]


def _twist_to(rotation, axis, reference, wanted, weight):
    """Rotations turned about their bone ``axis`` (F, 3) so ``reference`` (F, 3) meets ``wanted``
    (F, 3) in the plane across the axis, by ``weight`` (F,)."""
    axis = _unit(axis)
    flat = lambda v: _unit(v - np.sum(v * axis, axis=-1, keepdims=True) * axis)
    r, w = flat(reference), flat(wanted)
    angle = np.arctan2(np.sum(np.cross(r, w) * axis, axis=-1), np.sum(r * w, axis=-1)) * weight
    return _axis_angle_matrix(axis, angle) @ rotation


def _bend_weight(upper, lower):
    """0 for a straight limb, 1 past 25 degrees of bend: (F,)."""
    cos = np.sum(_unit(upper) * _unit(lower), axis=-1)
    bend = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
    return np.clip((bend - 5.0) / 20.0, 0.0, 1.0)


def joint_deltas(rig, targets, pinned=None, foot_turns=None, hips_on_path=False, foot_pitches=None):
    """World deltas joint -> (F, 4, 4) for every mapped joint, from targets (F, 17, 3).

    ``pinned`` (F, 17), optional: joints the artist fixed on each frame; a
    pinned pelvis is never moved to let the feet reach, and the chest leans
    toward pinned hands beyond the arms' reach; free hands keep their pose
    against the rig's shoulders (``_free_arm_at_its_shoulder``). ``foot_turns`` (F, 2),
    optional: each foot's turn about Z since the start (right, left; a planted
    foot keeps its own), else the pelvis's. ``hips_on_path``: the hips'
    horizontal position is given (a ground path), so the feet's reach may
    lower the pelvis but not move it off the path. ``foot_pitches`` (F, 2),
    optional: each foot's pitch, toes down (radians), as it rolls onto its toes.
    """
    start, frames = rig.joints, len(targets)
    deltas, targets, pelvis = _trunk(rig, targets, pinned, hips_on_path)
    carried = lambda joint: _carried(rig, deltas, joint, frames)
    for joint, child in (("Thorax", "Neck"), ("Neck", "Head")):
        parent = carried(joint)
        pivot = _apply(parent, start[J[joint]])
        rotation = parent[:, :3, :3]
        fixed = np.zeros(frames, dtype=bool) if pinned is None else pinned[:, J[child]] > 0
        aim = np.where(fixed[:, None], targets[:, J[child]] - pivot, targets[:, J[child]] - targets[:, J[joint]])
        rotation = swing(rotation @ (start[J[child]] - start[J[joint]]), aim) @ rotation
        deltas[joint] = _rigid(rotation, start[J[joint]], pivot)
    heading = np.arctan2(pelvis[:, 1, 0], pelvis[:, 0, 0])  # turn of the pelvis about Z
    turns = {"RFoot": heading, "LFoot": heading} if foot_turns is None else {
        "RFoot": foot_turns[:, 0], "LFoot": foot_turns[:, 1]}
    pitches = {} if foot_pitches is None else {"RFoot": foot_pitches[:, 0], "LFoot": foot_pitches[:, 1]}
    for upper, lower, end in LIMBS:
        if end.endswith("Wrist"):
            targets = _free_arm_at_its_shoulder(targets, _apply(carried(upper), start[J[upper]]), (upper, lower, end),
                                                pinned)
        fixed = np.zeros(frames) if pinned is None else pinned[:, J[lower]]
        free_hand = None if not end.endswith("Wrist") else np.ones(frames) if pinned is None else 1.0 - pinned[:, J[end]]
        deltas.update(_limb(rig, targets, carried(upper), upper, lower, end, turns.get(end), fixed,
                            pitches.get(end), free_hand))
    return deltas


def _carried(rig, deltas, joint, frames):
    """The delta (F, 4, 4) of the keyed bone that carries ``joint``'s (or a clavicle's) bone
    (identity for none)."""
    driver = rig.drivers.get(rig.keyed[joint])
    owner = next((j for j, b in rig.keyed.items() if b == driver), None)
    return deltas[owner] if owner is not None else np.broadcast_to(np.eye(4), (frames, 4, 4))


def _trunk(rig, targets, pinned, hips_on_path):
    """(deltas of the hips and, where mapped, the spine; targets (F, 17, 3) with the free arms
    carried by any lean toward a hand; the pelvis's rotation (F, 3, 3)): the part of
    ``joint_deltas`` that places the shoulders."""
    start = rig.joints
    head = lambda joint: rig.matrices[rig.bones[joint]][:3, 3]
    across = lambda pose, l, r: pose[..., J[l], :] - pose[..., J[r], :]
    up = lambda pose: pose[..., J["Thorax"], :] - pose[..., J["Hip"], :]
    hips, shoulders = steady_across(start, targets, pinned)
    pelvis = frame(hips, up(targets)) @ frame(  # the hips exactly, then the lean
        across(start, "LHip", "RHip"), up(start)).T
    free = np.ones(len(targets)) if pinned is None else 1.0 - pinned[:, J["Hip"]]
    trunk = _rigid(pelvis, start[J["Hip"]], targets[:, J["Hip"]])
    turns = None  # the clavicles' turns, found before any lean toward a hand, which reckons with them
    if "Spine" not in rig.bones and pinned is not None:
        turns = _clavicle_turns(rig, targets, {"Hip": trunk})
        trunk, targets = _trunk_to_hands(rig, targets, trunk, pinned, turns)
    deltas = {"Hip": _reach_feet(rig, targets, trunk, free, hips_on_path)}
    if "Spine" in rig.bones:
        chest = frame(up(targets), shoulders) @ frame(
            up(start), across(start, "LShoulder", "RShoulder")).T
        deltas["Spine"] = _rigid(chest, head("Spine"), _apply(_carried(rig, deltas, "Spine", len(targets)),
                                                             head("Spine")))
        if pinned is not None:
            turns = _clavicle_turns(rig, targets, deltas)
            leaned = _lean_to_hands(rig, targets, deltas["Spine"], head("Spine"), pinned, turns)
            targets = _free_arms_carried(targets, leaned @ _rigid_inverse(deltas["Spine"]), pinned)
            deltas["Spine"] = leaned
    for clavicle, turn in (_clavicle_turns(rig, targets, deltas) if turns is None else turns).items():
        deltas[clavicle] = _carried(rig, deltas, clavicle, len(targets)) @ turn
    return deltas, targets, pelvis


def _clavicle_turns(rig, targets, deltas):
    """{clavicle: (F, 4, 4)} rotations of each of the rig's clavicles about its head, before the bone
    that carries it moves (its delta in ``deltas``), that turn its shoulder toward the generated one
    (targets (F, 17, 3)), MAX_CLAVICLE_DEG at most (see CLAVICLES)."""
    turns = {}
    most = np.radians(MAX_CLAVICLE_DEG)
    for shoulder, clavicle in CLAVICLES.items():
        if clavicle not in rig.clavicles:
            continue
        head = rig.matrices[rig.clavicles[clavicle]][:3, 3]
        carrier = _carried(rig, deltas, clavicle, len(targets))
        wanted = _apply(_rigid_inverse(carrier), targets[:, J[shoulder]]) - head
        initial = np.broadcast_to(rig.joints[J[shoulder]] - head, wanted.shape)
        axis = _unit(np.cross(initial, wanted))
        angle = np.arctan2(np.linalg.norm(np.cross(initial, wanted), axis=-1), np.sum(initial * wanted, axis=-1))
        turns[clavicle] = _rigid(_axis_angle_matrix(axis, most * np.tanh(angle / most)), head, head)
    return turns


def _shoulder_before_lean(rig, shoulder, turns, frames):
    """Where a shoulder (F, 3) lies before the chest moves: turned with its clavicle (``turns`` of
    ``_clavicle_turns``), or as it started."""
    clavicle = CLAVICLES[shoulder]
    if clavicle in turns:
        return _apply(turns[clavicle], rig.joints[J[shoulder]])
    return np.broadcast_to(rig.joints[J[shoulder]], (frames, 3))


def hands_missed(rig, targets, pinned=None, hips_on_path=False, tightest_fold_cos=TIGHTEST_FOLD_COS):
    """How far (F, 2) each hand's target (right, left) lies outside its arm's reach (beyond the
    straight arm, or within the fold at ``tightest_fold_cos``, by default the tightest the retarget
    allows) from where the rig's trunk puts the shoulder, leaned toward it as ``joint_deltas``
    leans it: where the rig will miss a hand's curve, at a fraction of the whole retarget's cost.
    Other arguments as ``joint_deltas``."""
    deltas, _, _ = _trunk(rig, targets, pinned, hips_on_path)
    missed = []
    for shoulder, elbow, wrist in LIMBS[2:]:
        nearest, farthest = _reach_range(*_segments(rig.joints, (shoulder, elbow, wrist)), tightest_fold_cos)
        root = _apply(_carried(rig, deltas, shoulder, len(targets)), rig.joints[J[shoulder]])
        distance = np.linalg.norm(targets[:, J[wrist]] - root, axis=-1)
        missed.append(np.maximum(np.maximum(distance - farthest, nearest - distance), 0.0))
    return np.stack(missed, axis=-1)


def steady_across(start, targets, pinned=None):
    """(hips, shoulders) left-right directions (F, 3) of targets (F, 17, 3). Where generated hips
    (or shoulders) lie closer together than ACROSS_TRUST of the rig's width their direction is
    noise that spun the pelvis by over 100 degrees in a frame, so the other pair's direction takes
    over in proportion, and where both are narrow, the neighbouring frames' (ACROSS_SMOOTHING);
    pairs the artist fixed (``pinned`` (F, 17), keys) keep their own direction."""
    def pair(pose, left, right):
        return pose[..., J[left], :] - pose[..., J[right], :]

    weighted = []
    for left, right in (("LHip", "RHip"), ("LShoulder", "RShoulder")):
        vector = pair(targets, left, right)
        trust = np.clip(np.linalg.norm(vector, axis=-1) / (ACROSS_TRUST * np.linalg.norm(pair(start, left, right))),
                        0.0, 1.0)
        fixed = np.zeros(len(targets)) if pinned is None else np.minimum(pinned[:, J[left]], pinned[:, J[right]])
        weighted.append((_unit(vector), trust[:, None], fixed[:, None]))
    (hips, hip_trust, hips_fixed), (shoulders, shoulder_trust, shoulders_fixed) = weighted
    steady = lambda v: _unit(np.swapaxes(smooth(np.swapaxes(v, 0, 1), ACROSS_SMOOTHING), 0, 1))
    mixed_hips = steady(hip_trust * hips + (1.0 - hip_trust) * shoulder_trust * shoulders)
    mixed_shoulders = steady(shoulder_trust * shoulders + (1.0 - shoulder_trust) * hip_trust * hips)
    return (_unit(hips_fixed * hips + (1.0 - hips_fixed) * mixed_hips),
            _unit(shoulders_fixed * shoulders + (1.0 - shoulders_fixed) * mixed_shoulders))


def _axis_angle_matrix(axis, angle):
    """Rotations (F, 3, 3) by ``angle`` (F,) about unit ``axis`` (F, 3)."""
    k = np.zeros(axis.shape + (3,))
    k[..., 0, 1], k[..., 0, 2], k[..., 1, 2] = -axis[..., 2], axis[..., 1], -axis[..., 0]
    k = k - np.swapaxes(k, -1, -2)
    return np.eye(3) + np.sin(angle)[..., None, None] * k + (1 - np.cos(angle))[..., None, None] * (k @ k)


def _lean_to_hands(rig, targets, chest, pivot, pinned, turns, most=MAX_LEAN_TO_HAND):
    """The chest delta (F, 4, 4) turned about ``pivot`` (3,) (the spine bone's head; the hips' for a
    trunk that turns as one), just enough for a pinned hand beyond the arm's reach to come within it
    (as a body leans to reach), by ``most`` degrees at most: further, a body would step rather
    than fold. The lean comes and goes at LEAN_DEG_PER_FRAME at most, and is none where the chest
    is keyed: rising early for a hand's need a few frames after a key, it turned a keyed chest
    by a degree, its shoulder 6 mm off, and the keyed straight arm bent: the elbow 2.6 cm off its key.
    ``turns``: the clavicles' (``_clavicle_turns``), which the chest carries."""
    start, rate = rig.joints, np.radians(LEAN_DEG_PER_FRAME)
    for shoulder, elbow, wrist in LIMBS[2:]:
        reach = REACH_MARGIN * limb_length(start, (shoulder, elbow, wrist))
        centre = _apply(chest, pivot)
        arm = _apply(chest, _shoulder_before_lean(rig, shoulder, turns, len(targets))) - centre
        goal = targets[:, J[wrist]] - centre
        r, d = np.linalg.norm(arm, axis=-1), np.linalg.norm(goal, axis=-1)
        between = np.arccos(np.clip(np.sum(arm * goal, -1) / np.maximum(r * d, 1e-12), -1.0, 1.0))
        closest = np.arccos(np.clip((r ** 2 + d ** 2 - reach ** 2) / np.maximum(2 * r * d, 1e-12), -1.0, 1.0))
        furthest = np.minimum(between, np.radians(most))
        needed = np.clip(between - closest, 0.0, furthest) * pinned[:, J[wrist]]
        allowed = -rate_limited_from_above(-np.where(pinned[:, J["Thorax"]] > 0, 0.0, furthest), rate)
        turn = np.minimum(rate_limited_from_above(needed, rate), allowed)
        rotation = _axis_angle_matrix(_unit(np.cross(arm, goal)), turn) @ chest[:, :3, :3]
        chest = _rigid(rotation, pivot, centre)
    return chest


def _trunk_to_hands(rig, targets, trunk, pinned, turns):
    """(trunk delta (F, 4, 4), targets (F, 17, 3)) for a rig whose trunk turns as one bone (no
    chest mapped: Rigify's torso control): the trunk leaned about the hips toward a pinned hand
    beyond the arm's reach (``_lean_to_hands``, MAX_TRUNK_LEAN_TO_HAND at most), and the arms
    whose hands no curve or key holds carried with it (``_free_arms_carried``), so they keep their
    pose against the body. Unleaned, the trunk kept the hips' turn while the model's chest leaned
    toward the hand: a Rigify wave's hand missed its curve by up to 11 cm, the arm straight and
    short of it."""
    leaned = _lean_to_hands(rig, targets, trunk, rig.joints[J["Hip"]], pinned, turns, MAX_TRUNK_LEAN_TO_HAND)
    return leaned, _free_arms_carried(targets, leaned @ _rigid_inverse(trunk), pinned)


def _free_arm_at_its_shoulder(targets, shoulder, arm, pinned=None):
    """Targets (F, 17, 3) with an arm's elbow and wrist moved by where the rig's shoulder (F, 3)
    lies from the generated one, on the frames where its hand is free (``pinned`` (F, 17), in
    proportion; joints pinned themselves stay): a free arm keeps its pose against its own shoulder.
    Left where they were generated, a free hand 11 cm from its generated shoulder lay 1-3 cm from
    the rig's, 10 cm away, and its elbow swung over in a frame (562 m/s^2)."""
    targets = targets.copy()
    offset = shoulder - targets[:, J[arm[0]]]
    for joint in map(J.get, arm[1:]):
        targets[:, joint] += (1.0 if pinned is None else _free_share(pinned, arm, joint)) * offset
    return targets


def _free_share(pinned, arm, joint):
    """(F, 1): how free one joint of an arm is on each frame, neither it nor the arm's hand pinned."""
    return ((1.0 - pinned[:, J[arm[-1]]]) * (1.0 - pinned[:, joint]))[:, None]


def _free_arms_carried(targets, lean, pinned):
    """Targets (F, 17, 3) with each arm's shoulder, elbow and wrist moved by ``lean`` (F, 4, 4), a
    lean toward a pinned hand, on the frames where that arm's hand is free (``pinned`` (F, 17)),
    in proportion; joints pinned themselves stay. A free arm left where it was generated while the
    chest leaned 22 degrees found its shoulder 19 cm away, its hand folded onto it, and its elbow
    swung over in a frame (297 m/s^2)."""
    targets = targets.copy()
    for arm in LIMBS[2:]:
        joints = [J[joint] for joint in arm]
        carried = targets[:, joints] @ np.swapaxes(lean[:, :3, :3], 1, 2) + lean[:, None, :3, 3]
        share = np.stack([_free_share(pinned, arm, joint) for joint in joints], axis=1)  # (F, 3, 1)
        targets[:, joints] += share * (carried - targets[:, joints])
    return targets


MAX_PELVIS_DROP = 0.15  # the most the feet's reach may lower the pelvis, in leg lengths
# Where the artist did not fix it, the pelvis comes down so the feet lie within LEG_REACH of a leg's
# length (a walk's leg never straightens to its last 0.5 %: there a millimetre of reach swung the
# knee 3 cm, knees accelerated at 3x a captured walk's, 130 m/s^2 at heel strikes), its drop eased
# over PELVIS_EASE frames either side (dropped frame by frame, the hips dipped 5 cm in 3 frames).
LEG_REACH = 0.995
PELVIS_EASE = 3


def _reach_feet(rig, targets, pelvis, free, hips_on_path=False, rounds=4):
    """The pelvis delta (F, 4, 4) moved toward any foot target beyond LEG_REACH of the rig's leg.

    Generated hips can sit a little too far from the feet for the rig's legs
    (a pinned foot, other proportions); moving the body keeps the feet planted
    instead of leaving them short of the floor. Only on frames where ``free``
    (F,) is 1, and never lower than ``MAX_PELVIS_DROP`` of a leg's length: feet
    planted far apart would pull the pelvis down to the floor between them.
    With ``hips_on_path`` it moves up or down only. The move is eased over
    PELVIS_EASE frames either side of each frame that needs it, never less than it needs.
    """
    start = rig.joints
    moved = pelvis.copy()
    lowest = pelvis[:, 2, 3] - MAX_PELVIS_DROP * limb_length(start, LIMBS[0])
    for _ in range(rounds):
        shift = np.zeros((len(targets), 3))
        for upper, lower, end in LIMBS[:2]:
            reach = LEG_REACH * limb_length(start, (upper, lower, end))
            to_end = targets[:, J[end]] - _apply(moved, start[J[upper]])
            distance = np.linalg.norm(to_end, axis=-1, keepdims=True)
            shift += np.maximum(distance - reach, 0.0) * to_end / np.maximum(distance, 1e-9)
        if hips_on_path:
            shift[:, :2] = 0.0
        moved[:, :3, 3] += shift * free[:, None]
        moved[:, 2, 3] = np.maximum(moved[:, 2, 3], lowest)
    move = moved[:, :3, 3] - pelvis[:, :3, 3]  # (F, 3)
    size = np.maximum(smooth(window_max(np.linalg.norm(move, axis=-1), PELVIS_EASE), PELVIS_EASE / 3.0) * free,
                      np.linalg.norm(move, axis=-1))  # each frame's own move at least, eased in and out
    # its direction smoothed over a wider span than the size's ease reaches (3 frames of window and 3
    # of smoothing): narrower, the direction was nothing 4 frames after the last frame that needed a
    # move, and a 3 cm drop ended in a frame (a wave's hips 38 m/s^2, the knee 67)
    way = _unit(np.swapaxes(smooth(move.T, PELVIS_EASE), 0, 1))
    pelvis = pelvis.copy()
    pelvis[:, :3, 3] += way * size[:, None]
    return pelvis


def _segments(start, limb):
    """The lengths of a limb's (root, middle, end) two segments in the pose ``start`` (17, 3)."""
    return tuple(np.linalg.norm(start[J[b]] - start[J[a]]) for a, b in zip(limb, limb[1:]))


def _reach_range(first, second, tightest_fold_cos=TIGHTEST_FOLD_COS):
    """(nearest, farthest): the distances from a limb's root at which a two-bone solve of segments
    ``first`` and ``second`` puts its end, folded no tighter than ``tightest_fold_cos`` (the cosine
    between the bones' directions)."""
    tightest = np.sqrt(first ** 2 + second ** 2 + 2.0 * first * second * tightest_fold_cos)
    return max(abs(first - second) + 1e-6, tightest), first + second - 1e-6


def _limb(rig, targets, parent, upper, lower, end, heading, fixed, pitch=None, free=None):
    """Deltas of a limb's three joints: a two-bone solve toward the end target; a foot keeps its
    initial orientation pitched toes down by ``pitch`` (F,) (None: not) about its own left-right
    axis, then turned by ``heading`` (F,) about Z (None for a hand). Where ``fixed`` (F,) is 1
    the artist put the middle joint where it is (a key), so its bend is taken as given. ``free``
    (F,) in [0, 1]: how free the end is of curves and keys; its reach is smoothed over frames as
    far as the square of that (FREE_REACH_SMOOTHING)."""
    start = rig.joints
    root = _apply(parent, start[J[upper]])
    first, second = _segments(start, (upper, lower, end))
    to_end = targets[:, J[end]] - root
    nearest, farthest = _reach_range(first, second)
    reach = np.clip(np.linalg.norm(to_end, axis=-1), nearest, farthest)
    if free is not None:
        reach = np.clip(reach + free ** 2 * (smooth(reach, FREE_REACH_SMOOTHING) - reach), nearest, farthest)
        shortfall = farthest - reach  # a held hand's eased toward the straight arm (see STRAIGHTENING_SHARE)
        reach += (1.0 - free) * shortfall * np.exp(-shortfall / (STRAIGHTENING_SHARE * (first + second)))
    along = _unit(to_end)
    initial_upper = start[J[lower]] - start[J[upper]]
    initial_hinge = np.cross(initial_upper, start[J[end]] - start[J[lower]])
    straight = np.linalg.norm(initial_hinge) < 0.05 * first * second
    if straight:
        initial_hinge = _straight_hinge(rig, upper)
    # Bend toward the generated middle joint, turned about the limb at most MAX_BEND_TURN from the
    # way the limb bends about its own hinge (carried by its parent: knees forward), and less as
    # the generated limb straightens (its bend direction becomes noise) or bends backwards (a
    # hinge cannot), so the bend never flips from one side to the other.
    if end.endswith("Foot"):
        own_bend = _unit(np.cross(along, parent[:, :3, :3] @ initial_hinge))
    else:
        reference = parent[:, :3, :3] @ _elbow_reference(rig, upper, lower, end, straight)
        own_bend = _unit(reference - np.sum(reference * along, axis=-1, keepdims=True) * along)
    side = np.cross(along, own_bend)
    # the generated limb's own bend (its middle joint off its root-to-end line), not its middle
    # joint seen from the rig's root: where the rig's shoulder lands 20 cm from the generated one,
    # the generated elbow seen from it pointed anywhere (elbows swung 30 cm in a frame)
    generated_along = _unit(targets[:, J[end]] - targets[:, J[upper]])
    generated = targets[:, J[lower]] - targets[:, J[upper]]
    generated -= np.sum(generated * generated_along, axis=-1, keepdims=True) * generated_along
    bend_x, bend_y = np.sum(generated * own_bend, axis=-1), np.sum(generated * side, axis=-1)
    size = np.hypot(bend_x, bend_y)
    limit = np.radians(MAX_BEND_TURN["leg" if end.endswith("Foot") else "arm"])
    angle = np.arctan2(bend_y, bend_x)
    below = above = np.full(len(targets), limit)  # the turn's range: -below to above
    if end.endswith("Foot"):  # turned toward the other hip is inward
        other = next(leg[0] for leg in LIMBS[:2] if leg[0] != upper)
        inward = np.sum(side * (parent[:, :3, :3] @ (start[J[other]] - start[J[upper]])), axis=-1) > 0.0
        above = np.where(inward, np.radians(KNEE_INWARD_DEG), limit)
        below = np.where(inward, limit, np.radians(KNEE_INWARD_DEG))
    behind = smoothstep((np.pi - np.abs(angle)) / (0.5 * np.pi))  # a bend generated backwards counts less
    own = smooth(_eased_clip(angle, below, above) * behind * size / (size + POLE_PRIOR * first), BEND_SMOOTHING)
    # A keyed bend is turned to from the limb's own the short way round, continuously in time within
    # each stretch of frames the key is trusted on (the two blended as plain angles once spun an
    # elbow through 317 degrees in 5 frames before a key, and one wrapping from +180 to -180 degrees
    # while the key's weight eased out swung an elbow 8 cm in a frame; carried on across a straight
    # frame, after an arms-up key, the turn went the long way round at 60 degrees a frame), each
    # frame outside those stretches the short way round on its own (unwrapped over the whole shot, a
    # knee whose generated bend had gone once round read a full turn from its own where the key's
    # weight had all but gone: a 4-degree blip, 57 m/s^2), and only as far as the keyed limb is bent
    # at all (a straight arm's bend direction is noise that swung the elbow 5 cm in a frame), and
    # where it bends the way its hinge cannot, only as far as it is sure to (an arms-up key held all
    # but straight, 1-2 cm off the line behind the hinge, swung the elbow 80 degrees round and back).
    sure = np.clip(size / (KEYED_BEND_SURE * first), 0.0, 1.0)
    as_keyed = fixed * np.clip(size / (KEYED_BEND_TRUST * first), 0.0, 1.0) * (sure + (1.0 - sure) * behind)
    short_way = np.angle(np.exp(1j * (angle - own)))
    to_keyed = short_way.copy()  # frames the key barely holds: each the short way round
    for first_frame, last_frame in runs(as_keyed > KEYED_SPLIT):  # each stretch the short way round on its own
        span = slice(first_frame, last_frame + 1)
        to_keyed[span] = np.unwrap(short_way[span])
        to_keyed[span] -= 2.0 * np.pi * np.round(np.average(to_keyed[span], weights=as_keyed[span]) / (2.0 * np.pi))
    turn = own + as_keyed * to_keyed
    cos = (first ** 2 + reach ** 2 - second ** 2) / (2.0 * first * reach)
    if not end.endswith("Foot"):
        turn += (1.0 - as_keyed) * _upper_arm_back_turn(turn, own_bend, side, along, cos, _facing(targets))
    pole = _turning_at_most(np.cos(turn)[:, None] * own_bend + np.sin(turn)[:, None] * side, along,
                            np.radians(MAX_POLE_DEG_PER_FRAME), as_keyed > 0.0)
    middle = root + first * (cos[:, None] * along + np.sqrt(np.clip(1.0 - cos ** 2, 0.0, 1.0))[:, None] * pole)
    goal = root + along * reach[:, None]

    rotation = parent[:, :3, :3]
    rotation = swing(rotation @ initial_upper, middle - root) @ rotation
    rotation = _twist_to(rotation, middle - root, rotation @ initial_hinge, np.cross(middle - root, goal - middle),
                         _bend_weight(middle - root, goal - middle))
    upper_delta = _rigid(rotation, start[J[upper]], root)
    lower_rotation = swing(rotation @ (start[J[end]] - start[J[lower]]), goal - middle) @ rotation
    lower_delta = _rigid(lower_rotation, start[J[lower]], middle)
    if end.endswith("Foot"):
        turn = np.zeros((len(targets), 3, 3))
        turn[:, 0, 0], turn[:, 0, 1], turn[:, 1, 0], turn[:, 1, 1], turn[:, 2, 2] = (
            np.cos(heading), -np.sin(heading), np.sin(heading), np.cos(heading), 1.0)
        end_rotation = turn
        if pitch is not None:
            toes = rig.matrices[rig.bones[end]][:3, 1] * np.array([1.0, 1.0, 0.0])  # the foot bone, level
            across = np.broadcast_to(_unit(np.cross([0.0, 0.0, 1.0], toes)), (len(pitch), 3))
            end_rotation = turn @ _axis_angle_matrix(across, pitch)
    else:
        end_rotation = lower_rotation
    return {upper: upper_delta, lower: lower_delta, end: _rigid(end_rotation, start[J[end]], goal)}


def _facing(joints):
    """The body's forward (F, 3) of poses (F, 17, 3): the hip plane's normal, as the joint-angle
    limits measure it."""
    return _unit(np.cross(joints[:, J["LHip"]] - joints[:, J["RHip"]], joints[:, J["Thorax"]] - joints[:, J["Hip"]]))


def _upper_arm_back_turn(turn, bend, side, along, cos, forward, floor=UPPER_ARM_BACK_COS):
    """The least turn (F,) to add about the arm to ``turn`` (F,), the pole's angle from ``bend`` toward
    ``side`` (F, 3), so the upper arm's cosine with ``forward`` (F, 3) is at least ``floor``: the upper
    arm lies at arccos(``cos``) (F,) from the shoulder-to-hand line ``along`` (F, 3), so that cosine is
    a + b cos(turn - best) over the turn, and the allowed turns are those within arccos((floor - a) / b)
    of ``best`` (where none is, ``best`` itself: the upper arm as far forward as the hand allows).
    Each stretch of frames that needs a turn takes it throughout on the side of ``best``'s opposite
    that it enters from (a stretch from the first frame that ends before the last: it leaves by).
    Chosen per frame, a generated elbow crossing straight back moved the turn to the other side in
    a frame (55 degrees, a Rigify reach); chosen where most of the stretch's frames lie, one
    entering from the other side swung 65 degrees in a frame (67 m/s^2 on a mannequin wave's
    elbow, 39 without the turn)."""
    sin = np.sqrt(np.clip(1.0 - cos ** 2, 0.0, 1.0))
    across_x, across_y = np.sum(bend * forward, axis=-1), np.sum(side * forward, axis=-1)
    a = np.clip(cos, -1.0, 1.0) * np.sum(along * forward, axis=-1)
    b = sin * np.hypot(across_x, across_y)
    best = np.arctan2(across_y, across_x)
    allowed = np.arccos(np.clip((floor - a) / np.maximum(b, 1e-9), -1.0, 1.0))
    continuous = np.unwrap(turn - best)
    offset = np.angle(np.exp(1j * continuous))
    for first_frame, last_frame in runs(np.abs(offset) > allowed):
        by = first_frame if first_frame > 0 or last_frame == len(turn) - 1 else last_frame
        offset[first_frame:last_frame + 1] = continuous[first_frame:last_frame + 1] + (offset[by] - continuous[by])
    return np.clip(offset, -allowed, allowed) - offset


def _eased_clip(angle, below, above):
    """``angle`` (F,) kept within -below..above (F,) with no corner: as it is up to half the limit,
    then easing (tanh) toward it. Clipped hard, and counted less linearly beyond 90 degrees
    (``behind``), an elbow the model swung past its hinge's side turned back in a frame (57 m/s^2,
    8x the median frame, a Rigify arm before a key; see BEND_SMOOTHING)."""
    limit = np.where(angle < 0.0, below, above)
    excess = np.maximum(np.abs(angle) - 0.5 * limit, 0.0)
    return np.sign(angle) * (np.minimum(np.abs(angle), 0.5 * limit) + 0.5 * limit * np.tanh(excess / (0.5 * limit)))


def _turning_at_most(poles, along, most, free):
    """Unit poles (F, 3), each perpendicular to its limb's ``along`` (F, 3), turned about the limb
    from the previous frame's by at most ``most`` radians a frame, except on ``free`` (F,) frames
    (a key's bend is met as keyed). Where the hand passes close to the shoulder the way the elbow
    points is steep in the limb's direction, and the generated elbow flips from side to side."""
    out = poles.tolist()  # plain floats: a numpy call per 3-vector cost more than the arithmetic
    limb = along.tolist()
    for index in range(1, len(out)):
        if free[index]:
            continue
        (ax, ay, az), (px, py, pz), (cx, cy, cz) = limb[index], out[index - 1], out[index]
        along_share = px * ax + py * ay + pz * az
        px, py, pz = px - along_share * ax, py - along_share * ay, pz - along_share * az
        length = math.sqrt(px * px + py * py + pz * pz)
        if length < 1e-6:
            continue
        px, py, pz = px / length, py / length, pz / length
        sine = (py * cz - pz * cy) * ax + (pz * cx - px * cz) * ay + (px * cy - py * cx) * az
        angle = math.atan2(sine, px * cx + py * cy + pz * cz)
        if abs(angle) > most:
            cos, sin = math.cos(most), math.copysign(math.sin(most), angle)
            out[index] = [cos * px + sin * (ay * pz - az * py), cos * py + sin * (az * px - ax * pz),
                          cos * pz + sin * (ax * py - ay * px)]
    return np.array(out, dtype=poles.dtype)


def _elbow_reference(rig, upper, lower, end, straight):
    """The way an elbow points when nothing says otherwise (3,), in the rig's start pose: as it
    bends there, or back and out from the shoulder where the arm is ``straight``. An arm rarely
    reaches that way; an elbow bent about its hinge, as a knee is, flipped sides whenever the arm
    passed the shoulder line (every lift from a T pose)."""
    start = rig.joints
    if not straight:
        along = _unit(start[J[end]] - start[J[upper]])
        bend = start[J[lower]] - start[J[upper]]
        return _unit(bend - np.dot(bend, along) * along)
    other = "LShoulder" if upper.startswith("R") else "RShoulder"
    forward = np.cross(start[J["LHip"]] - start[J["RHip"]], start[J["Thorax"]] - start[J["Hip"]])
    return _unit(_unit(start[J[upper]] - start[J[other]]) - _unit(forward))


def _straight_hinge(rig, upper):
    """The hinge a limb straight at the start will bend about: the body's left-right axis, signed
    as cross(upper, lower) of a knee bending forward (to the left) and an elbow folding forward
    (to the right)."""
    start = rig.joints
    if upper.endswith("Hip"):
        return start[J["LHip"]] - start[J["RHip"]]
    return start[J["RShoulder"]] - start[J["LShoulder"]]


def achieved_joints(rig, deltas):
    """Where the retargeted rig puts each mapped joint: (F, 17, 3), NaN for joints without a bone."""
    frames = len(next(iter(deltas.values())))
    out = np.full((frames, len(rig.joints), 3), np.nan)
    for joint, delta in deltas.items():
        if joint in J:  # not a clavicle
            out[:, J[joint]] = _apply(delta, rig.joints[J[joint]])
    return out


def reach_shortfall(rig, achieved, targets, joint):
    """How far (F,) each target of ``joint`` lies beyond its limb's reach from the limb's (achieved)
    root, 0 where the rig can put the joint on it. Joints outside the limbs always reach."""
    for limb in LIMBS:
        if joint in limb[1:]:
            chain = limb[: limb.index(joint) + 1]
            return np.maximum(np.linalg.norm(targets - achieved[:, J[chain[0]]], axis=-1)
                              - REACH_MARGIN * limb_length(rig.joints, chain), 0.0)
    return np.zeros(len(targets))


def _rigid_inverse(delta):
    """Inverses of rigid transforms (..., 4, 4), without a general matrix inverse."""
    inverse = np.zeros_like(delta)
    rotation = np.swapaxes(delta[..., :3, :3], -1, -2)
    inverse[..., :3, :3] = rotation
    inverse[..., :3, 3] = -(rotation @ delta[..., :3, 3, None])[..., 0]
    inverse[..., 3, 3] = 1.0
    return inverse


def bone_bases(rig, deltas):
    """matrix_basis (F, 4, 4) per keyed bone from joint deltas: parent space^-1 @ delta @ initial,
    where the parent space is the driver's delta applied to the initial parent space."""
    bases = {}
    by_bone = {bone: deltas[joint] for joint, bone in rig.keyed.items() if joint in deltas}
    for bone, delta in by_bone.items():
        initial, basis = rig.matrices[bone], rig.bases[bone]
        from_parent_space = basis @ np.linalg.inv(initial)  # inverse of initial @ basis^-1
        driver = rig.drivers.get(bone)
        moved = _rigid_inverse(by_bone[driver]) @ delta if driver in by_bone else delta
        bases[bone] = from_parent_space @ moved @ initial
    return bases


def _rotation_channel(mode, matrices):
    """(property, values (F, C)) of rotations (F, 3, 3) in a bone's rotation ``mode``."""
    if mode == 'QUATERNION':
        return "rotation_quaternion", rotations.continuous(rotations.from_matrix(matrices))
    if mode == 'AXIS_ANGLE':
        return "rotation_axis_angle", rotations.to_axis_angle(rotations.continuous(rotations.from_matrix(matrices)))
    return "rotation_euler", rotations.to_euler(matrices, mode)


def key_channels(bases, rotation_modes, root_bone):
    """[(bone, property, values (F, C) float32)] to key from each bone's matrix_basis (F, 4, 4):
    rotation in the bone's own mode ({bone: Blender rotation mode}) for every bone, location for
    the root."""
    out = []
    for bone, basis in bases.items():
        rotation = basis[:, :3, :3] / np.linalg.norm(basis[:, :3, :3], axis=1, keepdims=True)
        out.append((bone, *_rotation_channel(rotation_modes[bone], rotation)))
        if bone == root_bone:
            out.append((bone, "location", basis[:, :3, 3]))
    return [(bone, prop, np.asarray(values, dtype=np.float32)) for bone, prop, values in out]
