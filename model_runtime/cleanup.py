"""What turns the model's variants into animation an animator keeps, at the scene's frame rate in
the model's frame (metres, Z up, the floor at z = 0 where the rig's toes stood at the start).

``tidy`` runs the steps in order: the body carried along its hips' curve
(``carried_by_hips``) and turned to face along a ground path (``facing_the_path``), the torso
kept from leaning far beyond the start pose (``upright``), the start
eased out of the rig's pose (``ease_out_of_start``), the body put back on the floor (``on_floor``)
with its hips kept from sagging far below their start height (``hips_up``), a foot stepping
under a body that leaves it (``balancing_steps``), carried against its planted feet's slide and
kept within reach of its curves (``without_slide``), planted feet held still with their heading
(``plant_feet``) and the body kept over them (``over_the_feet``; under a ground path, the feet
take the planned steps of ``footsteps``, the body leaning into the walk and the arms swinging
against the legs: ``leaning_into_the_walk``, ``swinging_arms``), eased onto the artist's keys
(``ease_onto_keys``), and every curve and key met exactly (``pin``). Motions are (V, F, 17, 3).
"""

import numpy as np

from . import footsteps
from .filters import runs, smooth, smoothstep, window_max, window_min
from .retarget import steady_across
from .rotations import turned
from .skeleton import (FEET, JOINT_INDEX, JOINT_MASSES, LIMBS, UP_AXIS, UPPER_BODY, centre_of_mass, facing, indices,
                       limb_length, lower_ankle_height, shortest_leg)

J = JOINT_INDEX
# The ground under the body: the lower ankle's height opened (lowest, then highest of the lowest)
# over this many seconds either side, so flights shorter than twice this (jumps) keep their height
# while slow drift up or down is removed.
FLOOR_WINDOW_S = 0.25
# An ankle within this height of where it stood at the start is planted: a foot that moves along
# the floor without lifting is sliding, which an animator never wants. One the model predicts
# planted is held up to MODEL_CONTACT_HEIGHT_M (a planted foot it generated a little above the floor).
CONTACT_HEIGHT_M = 0.04
MODEL_CONTACT_HEIGHT_M = 0.10
# The start of a shot eases out of the rig's pose over this many seconds.
START_EASE_S = 0.25
# Around a key, the model's own motion of the keyed joints is replaced by a smooth bridge over this
# many seconds either side (it jumps onto the key at the last moment).
KEY_BRIDGE_S = 0.25
# Joints no key places (a rig keys the head bone, whose tail is no joint), bridged around the keys of
# the joint that carries them: the model's head jumped 35 cm on the key's frame. (Moving it with the
# neck's layer as well put the keyed head top 13 cm off, against 6-7, and bent the neck off its limits.)
BRIDGED_WITH_KEYED = {"Head": "Neck"}
# Plants shorter than this are not held; a foot that lifts less than STEP_LIFT_M between two plants
# shuffled along the floor and is held through.
MIN_CONTACT_S = 0.1
STEP_LIFT_M = 0.06
# Share of an arm's length the body keeps its pinned hands within (of the generated shoulder)
# while it stops sliding: the rig's own shoulder lands up to a fifth of an arm away, and a Rigify
# arm raised overhead further (at 0.8, a wave's hand missed its curve by 3.1 cm on average, at 0.7
# by 1.7; the mannequin's 0.7 and 0.2). Feet on curves
# are kept within STAND_SHARE of a leg, which is also as far as the hips rise to let a hand reach.
REACH_SHARE = 0.7
REACH_EASE_S = 0.2
# The planted feet's slide that moves the body is smoothed over this long (Gaussian sigma): where a
# foot counts as planted from one frame to the next, the body's correction changed speed in a frame
# (a drawn step leaving the rest pose, seeds 0-3, worst frames 31 / 35 m/s^2 as played on the
# mannequin / Rigify, 30 / 30 smoothed; weights whose feet move more early, 53 / 46 and 36 / 35).
# The feet are held still after it (``plant_feet``).
SLIDE_SMOOTHING_S = 0.05
STAND_SHARE = 0.97
# A standing body keeps its centre of mass over its feet: the model's idle variants stood with it up
# to 28 cm outside them on a Rigify rig (the hips up to 0.44 m off the feet, straight legs slanted
# like a plank), which no captured standing clip of ../shared does. The soles, in feet
# (footsteps.FOOT_M, ankle to toe tip): across the body between the ankles and SOLE_SIDE_SHARE
# beyond, along it from SOLE_BACK_SHARE behind the ankles to SOLE_FRONT_SHARE ahead (about the
# toe joints, as bench-quality measures on the rig; captured bodies lifting a box reach that far,
# and are left as they are). Where both feet are planted and the centre of mass is
# BALANCE_STEP_SHARE of a foot beyond the soles, the foot farther from where it stands under the
# hips steps there (as the start pose stood; a step of BALANCE_STEP_S, STEP_CLEARANCE_M high: at
# STEP_S a Rigify knee took it at 107 m/s^2); what is left the body above the feet takes,
# moving horizontally (the knees half as far) from one standing frame's need to the next,
# smoothed over BALANCE_SMOOTHING_S, in BALANCE_PASSES passes (the smoothing shaves what the
# worst frames need). A foot's centre of mass share (skeleton.SEGMENT_MASSES) is at its ankle.
SOLE_BACK_SHARE = 0.2
SOLE_FRONT_SHARE = 0.7
SOLE_SIDE_SHARE = 0.2
BALANCE_STEP_SHARE = 0.25
BALANCE_STEP_S = 0.5
BALANCE_SMOOTHING_S = 0.25
BALANCE_PASSES = 3
BALANCE_CHECK_FRAMES = 64
BALANCE_LINE_SAMPLES = 9
# A planted foot left this many legs behind its hip (horizontally) steps: it lifts STEP_CLEARANCE_M
# for STEP_S and plants again where the body has taken it, ahead of the hip by the hip's travel
# over the next STEP_S, as a walking foot lands ahead of the body.
STEP_TRIGGER = 0.4
STEP_S = 0.3
STEP_CLEARANCE_M = 0.08
# A step the cleanup lifts rises through its first STEP_LIFT_SHARE before the foot travels and sets
# down through its last: travelling from the start, a foot the body carried off at 1 m/s moved at
# up to 1.8 m/s from one frame to the next within 1 cm of the floor (0.2 of the step left it
# 0.70 m behind its hip, against 0.63).
STEP_LIFT_SHARE = 0.15
# On a ground path the body is turned to face along it, the turn smoothed over this many seconds so
# the pelvis keeps its sway within a stride, and eased in over FACING_EASE_S from the rig's own
# facing; frames where the path moves slower than FACING_MIN_SPEED_M_S face as it did last (or first).
FACING_SMOOTHING_S = 0.25
FACING_EASE_S = 0.5
FACING_MIN_SPEED_M_S = 0.2
# The torso (hips to neck) leans freely up to LEAN_FREE_DEG beyond the start pose's own lean;
# of any lean beyond that, LEAN_KEPT is kept (the model's long shots lean further window by window:
# 40 degrees and more after 10 s of walking or waving, against 7-9 in captured walks). Measured on
# the torso smoothed over LEAN_SMOOTHING_S. Keys and curves come after, so they still bend the body.
LEAN_FREE_DEG = 15.0
LEAN_KEPT = 0.3
LEAN_SMOOTHING_S = 0.25
# Likewise the hips (smoothed as the torso) sink freely to HIPS_FREE_SHARE of their start height
# over the lower ankle; of any sag below that HIPS_KEPT is kept, the legs straightening up to
# STAND_SHARE of their length (chained windows sank a walk's hips to 0.6 of standing in 10 s).
HIPS_FREE_SHARE = 0.85
HIPS_KEPT = 0.3
# Walking arms swing against the legs (``footsteps.Gait.arm_swing``), following how far apart the
# feet are smoothed over ARM_SMOOTHING_S (a rounded swing rather than the feet's plant and swing);
# the forearm swings FOREARM_SHARE further forward, as an elbow bends at the front of a swing.
ARM_SMOOTHING_S = 0.1
FOREARM_SHARE = 0.5


def on_floor(motion, fps, standing):
    """The body moved up or down, smoothly, so the lower ankle stands at ``standing`` (its height
    at the start) wherever the feet touch the ground: no sinking below the floor, no floating
    away over a long shot, flights shorter than 2 FLOOR_WINDOW_S kept."""
    lower = motion[..., indices(FEET), 2].min(-1) - standing  # (V, F)
    half = max(1, int(round(FLOOR_WINDOW_S * fps)))
    opened = window_max(window_min(lower, half), half)  # follows slow drift, drops narrower flights
    ground = _eased_in(np.minimum(smooth(opened, half / 3.0), lower), fps)
    out = motion.copy()
    out[..., 2] -= ground[..., None]
    return out


def _bridge(values, start, end, still_start=False):
    """values (V, F, ...) over frames start..end replaced by a cubic Hermite bridge between its
    positions and velocities at the two ends (none at the start where ``still_start``), in place."""
    velocity = lambda at: 0.5 * (values[:, min(at + 1, values.shape[1] - 1)] - values[:, max(at - 1, 0)])
    span = end - start
    t = ((np.arange(start, end + 1) - start) / span).reshape(1, -1, *([1] * (values.ndim - 2)))
    p0, p1 = values[:, start, None], values[:, end, None]
    m0 = 0.0 if still_start else velocity(start)[:, None]
    m1 = velocity(end)[:, None]
    values[:, start:end + 1] = ((2 * t ** 3 - 3 * t ** 2 + 1) * p0 + (t ** 3 - 2 * t ** 2 + t) * span * m0
                                + (-2 * t ** 3 + 3 * t ** 2) * p1 + (t ** 3 - t ** 2) * span * m1)


def _eased_in(correction, fps):
    """A correction (V, F, ...) scaled from nothing at the first frame (the rig's own pose, which
    stays as the artist left it) to all of it START_EASE_S later."""
    ramp = smoothstep(np.arange(correction.shape[1]) / max(START_EASE_S * fps, 1.0))
    return correction * ramp.reshape(1, -1, *([1] * (correction.ndim - 2)))


def ease_out_of_start(motion, fps):
    """The first START_EASE_S replaced by a bridge from the rig's still pose into the model's
    motion: the model's first frame jumps away from the pose it was given."""
    out = motion.copy()
    end = min(int(round(START_EASE_S * fps)), motion.shape[1] - 1)
    if end > 1:
        _bridge(out, 0, end, still_start=True)
    return out


def ease_onto_keys(motion, keyed, fps, standing=None):
    """Motion brought onto the keys ({frame index: {joint: (3,)}}) as an additive layer would. The
    model jumps onto a key in the last frame or two before it, so each keyed joint's motion is
    first bridged over KEY_BRIDGE_S either side of its keys; then its offset from each key, zero
    at the first frame (the rig's own pose), is eased (smoothstep) from key to key and held after
    the last, so nothing snaps on a key. Joints no key places are bridged with the joint that carries
    them (``BRIDGED_WITH_KEYED``). A keyed ankle is kept above ``standing`` (its height at the
    start; ``pin`` then meets its keys exactly): a key 3 cm below where the model lifted the foot
    carried the foot standing on the floor before and after it 3 cm into it."""
    out = motion.copy()
    frames = np.arange(motion.shape[1])
    half = max(1, int(round(KEY_BRIDGE_S * fps)))
    joints = sorted({joint for keys in keyed.values() for joint in keys})
    for joint in joints:
        bridged_joints = [J[joint]] + [J[child] for child, parent in BRIDGED_WITH_KEYED.items()
                                       if parent == joint and child not in joints]
        for index in sorted(index for index, keys in keyed.items() if joint in keys):
            start, end = max(index - half, 0), min(index + half, len(frames) - 1)
            if end - start > 1:
                bridged = out[:, :, bridged_joints]  # a copy: bridged, then put back
                _bridge(bridged, start, end)
                out[:, :, bridged_joints] = bridged
        times = [0] + sorted(index for index, keys in keyed.items() if joint in keys)
        offsets = [np.zeros((len(motion), 3))] + [keyed[index][joint] - out[:, index, J[joint]]
                                                  for index in times[1:]]
        layer = np.repeat(offsets[-1][:, None], len(frames), axis=1)  # held after the last key
        for (start, before), (end, after) in zip(zip(times, offsets), zip(times[1:], offsets[1:])):
            span = slice(start, end + 1)
            ease = smoothstep((frames[span] - start) / max(end - start, 1))[None, :, None]
            layer[:, span] = before[:, None] + (after - before)[:, None] * ease
        out[:, :, J[joint]] += layer
        if joint in FEET and standing is not None:
            out[:, :, J[joint], 2] = np.maximum(out[:, :, J[joint], 2], standing)
    return out


def _contacts(ankle, fps, standing, free, predicted):
    """Planted frames (F,) of one ankle (F, 3): low, or a little higher where the model predicts it
    planted (``predicted`` (F,) in [0, 1]), on frames where it is ``free`` (F,) of keys and curves;
    gaps of a frame or two and shuffles closed, plants under MIN_CONTACT_S dropped."""
    height = ankle[:, 2] - standing
    planted = ((height < CONTACT_HEIGHT_M) | ((predicted > 0.5) & (height < MODEL_CONTACT_HEIGHT_M))) & free
    for start, end in runs(~planted):
        between = 0 < start and end < len(planted) - 1 and free[start:end + 1].all()
        if between and (end - start < 2 or height[start:end + 1].max() < STEP_LIFT_M):
            planted[start:end + 1] = True
    for start, end in runs(planted):
        if (end - start + 1) / fps < MIN_CONTACT_S:
            planted[start:end + 1] = False
    return planted


def heading(motion, initial):
    """The pelvis's turn about Z since the first frame (V, F), radians, continuous: of the hips'
    left-right direction steadied as the retarget steadies it (``retarget.steady_across``) from
    the pose ``initial`` (17, 3), so the feet turn with the pelvis the rig gets."""
    across = np.stack([steady_across(initial, variant)[0] for variant in motion])
    angle = np.unwrap(np.arctan2(across[..., 1], across[..., 0]), axis=-1)
    return angle - angle[..., :1]


def _contact_flags(motion, fps, standing, pinned, predicted, placed=None):
    """Planted frames (V, F, 2) of the right and left ankles (see ``_contacts``), as balancing
    steps place them (``placed``, see ``balancing_steps``)."""
    flags = np.zeros(motion.shape[:2] + (2,), dtype=bool)
    placed = np.zeros(flags.shape, np.int8) if placed is None else placed
    for variant in range(len(motion)):
        for side, foot in enumerate(FEET):
            free = pinned[:, J[foot]] == 0
            flags[variant, :, side] = _contacts(motion[variant, :, J[foot]], fps, standing,
                                                free & (placed[variant, :, side] >= 0), predicted[variant, :, side])
            flags[variant, :, side] |= free & (placed[variant, :, side] > 0)
    return flags


def _off_balance(motion, feet_forward=None):
    """The horizontal move (..., 2) that brings poses' (..., 17, 3) centre of mass onto their soles
    (0 where it is on them): every point of the line between the ankles carries a sole, from
    SOLE_BACK_SHARE of a foot behind to SOLE_FRONT_SHARE ahead and SOLE_SIDE_SHARE to either side,
    the soles together the feet's support. The soles point along ``feet_forward`` (..., 2, 2)
    (right, left; unit, horizontal), turned from one foot's way to the other's along the line;
    without it, the way the body faces. The nearest of them is found over BALANCE_LINE_SAMPLES
    points of the line, then as many around the nearest."""
    if feet_forward is None:
        feet_forward = np.repeat(facing(motion)[..., None, :2], 2, axis=-2)
    ankles = motion[..., indices(FEET), :2]  # (..., 2, 2)
    mass = centre_of_mass(motion)[..., None, :2]
    foot = footsteps.FOOT_M

    def moves(along):
        """The moves (..., K, 2) onto the soles at the points ``along`` (..., K) of the line."""
        relative = mass - (ankles[..., :1, :] + along[..., None] * (ankles[..., 1:, :] - ankles[..., :1, :]))
        forward = feet_forward[..., :1, :] + along[..., None] * (feet_forward[..., 1:, :] - feet_forward[..., :1, :])
        forward = forward / np.maximum(np.linalg.norm(forward, axis=-1, keepdims=True), 1e-9)
        side = np.concatenate([forward[..., 1:], -forward[..., :1]], axis=-1)
        ahead, across = np.sum(relative * forward, axis=-1), np.sum(relative * side, axis=-1)
        onto_ahead = np.clip(ahead, -SOLE_BACK_SHARE * foot, SOLE_FRONT_SHARE * foot) - ahead
        onto_side = np.clip(across, -SOLE_SIDE_SHARE * foot, SOLE_SIDE_SHARE * foot) - across
        return onto_ahead[..., None] * forward + onto_side[..., None] * side

    step = 1.0 / (BALANCE_LINE_SAMPLES - 1)
    along = np.broadcast_to(np.linspace(0.0, 1.0, BALANCE_LINE_SAMPLES), mass.shape[:-2] + (BALANCE_LINE_SAMPLES,))
    nearest = np.take_along_axis(along, np.argmin(np.linalg.norm(moves(along), axis=-1), axis=-1)[..., None], -1)
    along = np.clip(nearest + np.linspace(-step, step, BALANCE_LINE_SAMPLES), 0.0, 1.0)
    candidates = moves(along)
    best = np.argmin(np.linalg.norm(candidates, axis=-1), axis=-1)[..., None, None]
    return np.take_along_axis(candidates, np.repeat(best, 2, axis=-1), -2)[..., 0, :]


def _balancing_steps(motion, both, free, initial, turns, fps, standing):
    """One variant's motion (F, 17, 3) with a foot stepping under the hips wherever, both feet
    planted (``both`` (F,)) and free of the artist's curves and keys (``free`` (F, 2)), the centre
    of mass is BALANCE_STEP_SHARE of a foot beyond the soles, and where the steps place the feet
    (F, 2) (``balancing_steps``); ``turns`` (F,): the pelvis's turn since the pose ``initial``
    (17, 3), whose feet stand under its hips; ``standing``: the floor's ankle height."""
    out, placed = motion.copy(), np.zeros((len(motion), 2), dtype=np.int8)
    swing = max(2, int(round(BALANCE_STEP_S * fps)))
    stance = initial[indices(FEET), :2] - initial[J["Hip"], :2]  # (2, 2)
    may_step = both & free.all(axis=1)
    may_step[len(out) - swing:] = False  # a step the shot's end would cut short is not taken
    off = np.zeros(len(out))  # how far out of balance, known up to frame ``known``
    frame = known = 0
    while frame < len(out):
        if frame >= known:  # a stretch at a time: a step moves the foot on every later frame
            known = frame + BALANCE_CHECK_FRAMES
            off[frame:known] = np.linalg.norm(_off_balance(out[frame:known]), axis=-1)
        due = np.flatnonzero(may_step[frame:known] & (off[frame:known] >= BALANCE_STEP_SHARE * footsteps.FOOT_M))
        if not len(due):
            frame = known
            continue
        frame += due[0]
        land = frame + swing
        cos, sin = np.cos(turns[land]), np.sin(turns[land])
        under = out[land, J["Hip"], :2] + stance @ np.array([[cos, sin], [-sin, cos]])  # (2, 2)
        moves = under - out[frame, indices(FEET), :2]
        side = int(np.argmax(np.linalg.norm(moves, axis=-1)))
        phase = np.linspace(0.0, 1.0, swing + 1)
        travel = smoothstep(_travel(phase))
        for joint, share in ((J[FEET[side]], 1.0), (J[LIMBS[side][1]], 0.5)):
            out[frame:land + 1, joint, :2] += share * travel[:, None] * moves[side]
            out[land + 1:, joint, :2] += share * moves[side]
            out[frame:land + 1, joint, 2] += share * _arc(phase)
        rises = np.flatnonzero(out[land:, J[FEET[side]], 2] - standing >= STEP_LIFT_M)
        placed[land:land + (rises[0] if len(rises) else len(out)), side] = 1
        placed[frame + 1:land, side] = -1
        frame = known = land + 1
    return out, placed


def balancing_steps(motion, fps, standing, pinned, initial, predicted, steps=True):
    """(motion, placed): motion (V, F, 17, 3) with a foot stepping under the hips where, both feet
    planted, the centre of mass is BALANCE_STEP_SHARE of a foot beyond their soles (see
    SOLE_FRONT_SHARE); never feet the artist pinned on the frame (``pinned`` (F, 17)), nor
    without ``steps`` (feet the artist keyed). ``predicted`` (V, F, 2): the model's planted feet
    in [0, 1]; ``initial`` (17, 3): the rig's balanced start. ``placed`` (V, F, 2) int8: -1 while
    a step carries the foot (low frames too), 1 where it stands where a step put it, until its
    own motion lifts it STEP_LIFT_M (a foot the model left hovering 4.3 cm up, just above
    CONTACT_HEIGHT_M, after a step slid on the floor for a second), 0 where the motion decides."""
    free = (pinned[:, indices(FEET)] == 0) & steps
    both = _contact_flags(motion, fps, standing, pinned, predicted).all(axis=-1)  # (V, F)
    stepped = [_balancing_steps(variant, flags, free, initial, turn, fps, standing)
               for variant, flags, turn in zip(motion, both, heading(motion, initial))]
    return np.stack([variant for variant, _ in stepped]), np.stack([placed for _, placed in stepped])


def over_the_feet(motion, fps, standing, contacts, pinned, initial, foot_turns):
    """Motion (V, F, 17, 3) whose body above the feet moves horizontally, the knees half as far,
    to keep its centre of mass over the soles (see SOLE_FRONT_SHARE) where both feet are down
    (planted, ``contacts`` (V, F, 2), or within CONTACT_HEIGHT_M of ``standing``, as a step
    lands), from one such frame's need to the next; the feet stay, and so do frames whose hips the
    artist pinned (``pinned`` (F, 17)). The soles point the way the pose ``initial`` (17, 3) faces,
    turned by ``foot_turns`` (V, F, 2) (``plant_feet``'s, as the rig's feet turn): a body turned
    35 degrees on its planted feet read as over them, and its centre of mass stood 12 cm off their
    soles on the rig."""
    low = motion[..., indices(FEET), 2] - standing < CONTACT_HEIGHT_M
    both = (contacts | low).all(axis=-1)
    share = np.ones(motion.shape[2])  # how far each joint moves with the body
    share[indices(FEET)], share[[J["RKnee"], J["LKnee"]]] = 0.0, 0.5
    moved = JOINT_MASSES @ share  # the share of its move the centre of mass makes
    frames = np.arange(motion.shape[1])
    feet_forward = turned(np.broadcast_to(facing(initial), foot_turns.shape + (1, 3)), UP_AXIS, foot_turns)[..., 0, :2]
    for _ in range(BALANCE_PASSES):
        need = _off_balance(motion, feet_forward)  # (V, F, 2)
        move = np.zeros_like(need)
        for variant in np.flatnonzero(both.any(axis=1)):
            standing_frames = np.flatnonzero(both[variant])
            for axis in range(2):
                move[variant, :, axis] = np.interp(frames, standing_frames, need[variant, standing_frames, axis])
        move *= (1.0 - pinned[:, J["Hip"]])[None, :, None] / moved
        move = _eased_in(np.swapaxes(smooth(np.swapaxes(move, 1, 2), BALANCE_SMOOTHING_S * fps), 1, 2), fps)
        motion = motion.copy()
        motion[..., :2] += share[None, None, :, None] * move[:, :, None]
    return motion


def without_slide(motion, fps, standing, pinned, initial, targets, predicted, stance=None, placed=None):
    """The whole body moved against the slide of its planted feet: while a foot is planted, its
    horizontal drift is the body's, smoothed over SLIDE_SMOOTHING_S and taken out (where the hips
    are not pinned), as far as the hands and feet on curves ({joint: (F, 3)}) stay within reach of
    the body. What brings them back within reach is eased over REACH_EASE_S; its upward part raises
    the body above its feet (the legs straighten, up to STAND_SHARE of their length) rather than lifting
    the feet off the floor. ``predicted`` (V, F, 2): the model's planted feet in [0, 1]; ``stance``
    (V, F, 2) bool: the feet's planned plants, which replace those found in the motion; ``placed``:
    where balancing steps place the feet (``balancing_steps``)."""
    planted = _contact_flags(motion, fps, standing, pinned, predicted, placed) if stance is None else stance
    velocity = np.diff(motion[..., indices(FEET), :2], axis=1)  # (V, F - 1, 2, 2)
    both = planted[:, 1:] & planted[:, :-1]
    slide = (velocity * both[..., None]).sum(-2) / np.maximum(both.sum(-1), 1)[..., None]  # (V, F - 1, 2)
    slide = np.swapaxes(smooth(np.swapaxes(slide, 1, 2), SLIDE_SMOOTHING_S * fps), 1, 2)
    slide *= (1.0 - pinned[1:, J["Hip"]])[None, :, None]
    shift = np.zeros(motion.shape[:2] + (3,))
    shift[:, 1:, :2] = -np.cumsum(slide, axis=1)
    back = np.zeros_like(shift)
    for limb in LIMBS:
        if limb[-1] not in targets:
            continue
        share = STAND_SHARE if limb[-1] in FEET else REACH_SHARE
        gap = targets[limb[-1]] - motion[:, :, J[limb[0]]] - shift - back
        distance = np.linalg.norm(gap, axis=-1)
        back += gap * np.clip(1.0 - share * limb_length(initial, limb) / np.maximum(distance, 1e-9), 0.0,
                              None)[..., None]
    legs = shortest_leg(initial)
    room = motion[..., indices(FEET), 2].min(-1) + STAND_SHARE * legs - motion[..., J["Hip"], 2]
    back[..., 2] = np.minimum(back[..., 2], np.maximum(room, 0.0))  # (V, F): how far the hips can still rise
    back = np.swapaxes(smooth(np.swapaxes(back, 1, 2), REACH_EASE_S * fps), 1, 2)
    move = _eased_in(shift + back, fps)
    out = motion + move[:, :, None]
    out[:, :, indices(FEET), 2] -= move[:, :, None, 2]  # the feet stay on the floor
    return out


def _layer(frames, plants, inside, base, lifted=()):
    """An additive correction (F, ...) to ``base`` (F, ...), the foot's own course, that is
    ``inside(start, end)`` (its values over the plant) within each plant (start, end), a run of
    planted frames, and eases (smoothstep) from one plant's last value to the next one's first in
    between; where the cleanup lifts the foot (the plants' indices ``lifted``, ``_lifted_steps``)
    the foot itself eases from where it stood to where it lands, only while off the floor
    (``_travel``), whatever its own course does meanwhile. 0 at the first frame, the last plant's
    last value held after it."""
    values = inside(0, 0)[:1] * 0.0
    layer = np.repeat(values, len(frames), axis=0)
    before_frame, before_value = 0, values[0]
    for index, (start, end) in enumerate(plants):
        inner = inside(start, end)
        if start > before_frame:
            span = slice(before_frame, start + 1)
            phase = (frames[span] - before_frame) / (start - before_frame)
            shape = (-1, *([1] * (inner.ndim - 1)))
            if index in lifted:
                stood, lands = before_value + base[before_frame], inner[0] + base[start]
                layer[span] = stood + (lands - stood) * smoothstep(_travel(phase)).reshape(shape) - base[span]
            else:
                layer[span] = before_value + (inner[0] - before_value) * smoothstep(phase).reshape(shape)
        layer[start:end + 1] = inner
        before_frame, before_value = end, inner[-1]
    layer[before_frame:] = before_value
    return layer


def _steps_when_left_behind(planted, ankles, hips, legs, fps):
    """Planted frames (F, 2) of the ankles (F, 2, 3) with steps cut in wherever a foot's hip (F, 2, 3)
    has moved more than STEP_TRIGGER legs (``legs`` (2,)) away from where the foot was planted (the
    body carried off by a curve or a ground path while the model's feet glide): the foot lifts for
    STEP_S and lands ahead of where it was generated by the hip's travel over the next STEP_S. A
    foot never starts such a step unless both stay planted through it otherwise (the other foot,
    and this one where it would lift by itself), the one left farther behind goes first, so feet
    carried off together step in turn instead of hopping; it stands for STEP_S after it lands
    before it steps, and takes no step the shot's end would cut short (stepping again as it
    landed, or into or out of a balancing step, a foot slid on the floor at 0.2-0.5 m/s for a
    second). The foot lands no farther from the hip than STAND_SHARE of the leg reaches (the
    model's own foot, far behind, set it down 1.25 legs from a wave's hip, where the rig's knee
    snapped straight at 79 m/s^2). Also returns each frame's landing offset (F, 2, 2): nonzero
    where such a step lands."""
    planted, ahead = planted.copy(), np.zeros(planted.shape + (2,))
    swing = max(2, int(round(STEP_S * fps)))
    since = [0 if planted[0, side] else None for side in range(2)]  # the frame each foot was planted on
    for frame in range(len(planted)):
        for side in range(2):
            if not planted[frame, side]:
                since[side] = None
            elif since[side] is None:
                since[side] = frame
        behind = [0.0 if since[side] is None else np.linalg.norm(
            hips[frame, side, :2] - ankles[since[side], side, :2] - ahead[since[side], side]) / legs[side]
            for side in range(2)]
        side = int(np.argmax(behind))
        landing = frame + swing
        down = planted[frame:landing].all(axis=0)  # (2,): neither foot lifts meanwhile, nor is in a step
        settled = since[side] is not None and frame - since[side] >= swing  # a foot that lands stands a while
        if behind[side] > STEP_TRIGGER and down.all() and settled and landing < len(planted):
            planted[frame:landing, side] = False
            since[side] = None
            later = min(landing + swing, len(planted) - 1)
            spot = ankles[landing, side, :2] + hips[later, side, :2] - hips[landing, side, :2]
            from_hip = spot - hips[later, side, :2]
            drop = hips[later, side, 2] - ankles[landing, side, 2]
            room = np.sqrt(max((STAND_SHARE * legs[side]) ** 2 - drop ** 2, 0.0))  # how far the leg reaches
            spot = hips[later, side, :2] + from_hip * min(1.0, room / max(np.linalg.norm(from_hip), 1e-9))
            ahead[landing, side] = spot - ankles[landing, side, :2]
    return planted, ahead


def _bearing(planted, heights, free):
    """Planted frames (F, 2), in place: where neither foot is planted but the lower free one is within
    MODEL_CONTACT_HEIGHT_M of the floor (``heights`` (F, 2) over it, ``free`` (F, 2)), that one is,
    as one foot bears the body short of a jump (a wave's late step left the other foot hovering
    3.5 cm up for 7 frames, both feet off the floor)."""
    heights = np.where(free, heights, np.inf)
    lower = np.argmin(heights, axis=1)
    rows = np.flatnonzero(~planted.any(axis=1) & (heights[np.arange(len(heights)), lower] < MODEL_CONTACT_HEIGHT_M))
    planted[rows, lower[rows]] = True


def _travel(phase):
    """A step's horizontal progress (...) in [0, 1] at its ``phase`` (...): none while the foot rises
    through the first STEP_LIFT_SHARE of the step or sets down through the last."""
    return np.clip((phase - STEP_LIFT_SHARE) / (1.0 - 2.0 * STEP_LIFT_SHARE), 0.0, 1.0)


def _lifted_steps(plants, height):
    """Indices of the plants [(start, end)] whose step in from the plant before the cleanup lifts:
    the foot (its own ``height`` (F,) over where it stands) does not lift by STEP_LIFT_M."""
    return {index for index, ((_, before), (after, _)) in enumerate(zip(plants, plants[1:]), start=1)
            if after - before > 1 and height[before:after + 1].max() < STEP_LIFT_M}


def _arc(phase):
    """A stepping foot's added height (...) at its step's ``phase`` (...) in [0, 1]: STEP_CLEARANCE_M
    at the middle, sin^2, so it leaves and meets the floor at rest (a half sine lifted the foot off
    at full speed, and a Rigify knee over a wave's late step took it at 53 m/s^2 and landed at 77)."""
    return STEP_CLEARANCE_M * np.sin(np.pi * phase) ** 2


def _lift(frames, plants, lifted):
    """A foot's added height (F,): an ``_arc`` over each step into the plants ``lifted``
    (``_lifted_steps``)."""
    lift = np.zeros(len(frames))
    for index in lifted:
        before, after = plants[index - 1][1], plants[index][0]
        lift[before:after + 1] = _arc((frames[before:after + 1] - before) / (after - before))
    return lift


def plant_feet(motion, fps, standing, pinned, initial, predicted, stance=None, placed=None):
    """(motion, contacts (V, F, 2), foot turns (V, F, 2)), right foot first: each planted ankle
    held where it landed, on the floor, with its foot's turn about Z as it landed. The hold is an
    additive layer on the foot, eased from plant to plant through the step between, so no pop
    appears where a plant starts or ends. A foot in the air never goes below where it stands: a
    step the shot's end cuts off has no plant to land on, and the model's foot sank 1 cm under the
    floor in a wave's last frames. ``pinned`` (F, 17): joints the artist fixed on each
    frame, which are never planted; ``initial`` (17, 3) gives the legs' lengths; ``predicted``
    (V, F, 2) the model's planted feet in [0, 1]; ``stance`` (V, F, 2) bool: planned plants, taken
    as they are (no steps cut in); ``placed``: where balancing steps place the feet
    (``balancing_steps``)."""
    out = motion.copy()
    pelvis = heading(motion, initial)
    turns = np.repeat(pelvis[..., None], 2, axis=-1)
    contacts = (_contact_flags(motion, fps, standing, pinned, predicted, placed) if stance is None
                else stance.copy())
    frames = np.arange(motion.shape[1])
    legs = [limb_length(initial, leg) for leg in LIMBS[:2]]
    feet, free = indices(FEET), pinned[:, indices(FEET)] == 0
    for variant in range(len(motion)):
        hips = motion[variant][:, [J[leg[0]] for leg in LIMBS[:2]]]
        ahead = np.zeros(contacts.shape[1:] + (2,))
        if stance is None:
            contacts[variant], ahead = _steps_when_left_behind(contacts[variant], motion[variant][:, feet], hips, legs,
                                                               fps)
            _bearing(contacts[variant], motion[variant][:, feet, 2] - standing,
                     free if placed is None else free & (placed[variant] >= 0))
        for side, foot in enumerate(FEET):
            ankle, turn = motion[variant, :, J[foot]], pelvis[variant]
            plants = runs(contacts[variant, :, side])
            held = lambda start, end: (np.array([*(ankle[start, :2] + ahead[start, side]), standing])
                                       - ankle[start:end + 1])
            lifted = _lifted_steps(plants, ankle[:, 2] - standing)
            out[variant, :, J[foot]] += _layer(frames, plants, held, ankle, lifted)
            out[variant, :, J[foot], 2] += _lift(frames, plants, lifted)
            height = out[variant, :, J[foot], 2]
            out[variant, :, J[foot], 2] = np.where(free[:, side], np.maximum(height, standing), height)
            turns[variant, :, side] += _layer(frames, plants, lambda start, end: turn[start] - turn[start:end + 1],
                                              turn, lifted)
    return out, contacts, turns


def facing_the_path(motion, initial, path, fps):
    """Motion (V, F, 17, 3) turned about its hips, frame by frame, to face along a ground path
    (F, 3), or each variant's route (V, F, 3), of the hips: the model walks the path but its body
    drifts off it (30 to 80 degrees on a quarter circle). The turn is smoothed (FACING_SMOOTHING_S)
    and eased in from the start pose (FACING_EASE_S); ``initial`` (17, 3) is the start pose, which
    steadies the hips' direction."""
    frames = np.arange(motion.shape[1])
    routes = np.broadcast_to(path, (len(motion),) + path.shape[-2:])
    turn = np.zeros(motion.shape[:2])
    for variant, route in enumerate(routes):
        travel = np.gradient(route[:, :2], axis=0)
        moving = np.flatnonzero(np.linalg.norm(travel, axis=-1) * fps > FACING_MIN_SPEED_M_S)
        if not len(moving):
            continue
        after = np.minimum(np.searchsorted(moving, frames), len(moving) - 1)
        before = np.maximum(after - 1, 0)
        nearest = np.where(np.abs(frames - moving[before]) <= np.abs(moving[after] - frames), moving[before],
                           moving[after])
        wanted = np.arctan2(travel[nearest, 1], travel[nearest, 0])  # (F,)
        forward = np.cross(steady_across(initial, motion[variant])[0], np.array([0.0, 0.0, 1.0]))
        turn[variant] = np.unwrap(np.angle(np.exp(1j * (wanted - np.arctan2(forward[:, 1], forward[:, 0])))))
    turn = smooth(turn, FACING_SMOOTHING_S * fps) * smoothstep(frames / max(FACING_EASE_S * fps, 1.0))
    cos, sin = np.cos(turn)[..., None], np.sin(turn)[..., None]
    hips = motion[:, :, J["Hip"], None, :2]
    offset = motion[..., :2] - hips
    out = motion.copy()
    out[..., 0] = (hips[..., 0] + cos * offset[..., 0] - sin * offset[..., 1])
    out[..., 1] = (hips[..., 1] + sin * offset[..., 0] + cos * offset[..., 1])
    return out


def _lean(torso):
    """Angles (...) of torso vectors (..., 3) from vertical, radians."""
    return np.arctan2(np.linalg.norm(torso[..., :2], axis=-1), torso[..., 2])


def upright(motion, initial, fps):
    """Motion (V, F, 17, 3) with the body above the hips turned about them toward vertical where
    the torso leans more than LEAN_FREE_DEG beyond the pose ``initial`` (17, 3) (see LEAN_KEPT)."""
    torso = motion[..., J["Neck"], :] - motion[..., J["Hip"], :]  # (V, F, 3)
    steady = np.swapaxes(smooth(np.swapaxes(torso, 1, 2), LEAN_SMOOTHING_S * fps), 1, 2)
    lean = _lean(steady)
    free = _lean(initial[J["Neck"]] - initial[J["Hip"]]) + np.radians(LEAN_FREE_DEG)
    turn = (1.0 - LEAN_KEPT) * np.clip(lean - free, 0.0, None)  # (V, F)
    if not turn.any():
        return motion
    axis = np.cross(steady, [0.0, 0.0, 1.0])  # horizontal: turning about it raises the torso
    axis /= np.maximum(np.linalg.norm(axis, axis=-1, keepdims=True), 1e-9)
    return _upper_body_turned(motion, axis, turn)


def _upper_body_turned(motion, axis, angle):
    """Motion (V, F, 17, 3) with everything above the hips turned about them by ``angle`` (V, F)
    radians about ``axis`` (V, F, 3), unit."""
    out = motion.copy()
    above = indices(UPPER_BODY)
    hips = motion[..., J["Hip"], None, :]
    out[..., above, :] = hips + turned(motion[..., above, :] - hips, axis, angle)
    return out


def leaning_into_the_walk(motion, leans, fps, initial):
    """Motion (V, F, 17, 3) with the body above the hips turned forward or back about them, as far
    as the hips walk (``footsteps.walking_share``), until the torso (hips to thorax, smoothed over
    LEAN_SMOOTHING_S) leans ``leans`` (V,) degrees forward of the start pose ``initial`` (17, 3);
    its sway within a stride is kept. Turned to the gait's lean, not by it: a model whose walking
    torso leans forward of itself (7-10 degrees in some takes) was leaned twice."""
    hips, thorax = J["Hip"], J["Thorax"]
    forward = facing(motion)  # (V, F, 3)
    torso = motion[..., thorax, :] - motion[..., hips, :]
    steady = np.arctan2(smooth(np.sum(torso * forward, axis=-1), LEAN_SMOOTHING_S * fps),
                        smooth(torso[..., 2], LEAN_SMOOTHING_S * fps))  # (V, F) forward of vertical
    start_torso = initial[thorax] - initial[hips]
    start = np.arctan2(np.sum(start_torso * facing(initial)), start_torso[2])
    walking = smooth(footsteps.walking_share(motion[..., hips, :], fps), LEAN_SMOOTHING_S * fps)  # (V, F)
    across = np.cross(forward, [0.0, 0.0, 1.0])  # turning the other way about it leans forward
    return _upper_body_turned(motion, across, -(start + np.radians(leans)[:, None] - steady) * walking)


def swinging_arms(motion, swings, fps, initial, free):
    """Motion (V, F, 17, 3) with each ``free`` arm ((2,) bool, right then left: neither curves nor
    keys on it) swung about its shoulder against the legs, forward as the other foot is ahead,
    ``swings`` (V,) degrees per leg length the feet are apart along the body's facing (eased in
    from the start pose as ``_eased_in``)."""
    forward = facing(motion)  # (V, F, 3)
    feet = motion[..., indices(FEET), :]
    legs = shortest_leg(initial)
    apart = smooth(((feet[..., 1, :] - feet[..., 0, :]) * forward).sum(-1), ARM_SMOOTHING_S * fps) / legs
    across = np.cross(forward, [0.0, 0.0, 1.0])  # turning about it carries a hanging arm forward
    out = motion.copy()
    for (shoulder, elbow, wrist), sign, kept in zip(LIMBS[2:], (1.0, -1.0), free):
        if not kept:
            continue
        angle = _eased_in(sign * np.radians(swings)[:, None] * apart, fps)  # (V, F)
        pivot = motion[..., J[shoulder], None, :]
        out[..., [J[elbow], J[wrist]], :] = pivot + turned(motion[..., [J[elbow], J[wrist]], :] - pivot, across,
                                                           angle)
        hinge = out[..., J[elbow], None, :]
        out[..., J[wrist], :] = (hinge + turned(out[..., J[wrist], None, :] - hinge, across,
                                                FOREARM_SHARE * np.maximum(angle, 0.0)))[..., 0, :]
    return out


def hips_up(motion, initial, fps, standing):
    """Motion (V, F, 17, 3) with the body over the feet raised where the hips (smoothed over
    LEAN_SMOOTHING_S) sag below HIPS_FREE_SHARE of their height in ``initial`` (17, 3) over the
    floor ``standing`` (see HIPS_KEPT); the ankles stay, the knees rise half as far."""
    height = smooth(motion[..., J["Hip"], 2], LEAN_SMOOTHING_S * fps) - standing  # (V, F)
    lift = (1.0 - HIPS_KEPT) * np.clip(HIPS_FREE_SHARE * (initial[J["Hip"], 2] - standing) - height, 0.0, None)
    legs = shortest_leg(initial)
    ankles = motion[..., indices(FEET), :]
    reach = np.sqrt(np.maximum((STAND_SHARE * legs) ** 2 - np.sum(  # the hips' highest over the farther ankle
        (ankles[..., :2] - motion[..., None, J["Hip"], :2]) ** 2, axis=-1), 0.0)) + ankles[..., 2]
    lift = np.minimum(lift, np.maximum(reach.min(-1) - motion[..., J["Hip"], 2], 0.0))
    if not lift.any():
        return motion
    out = motion.copy()
    out[..., 2] += lift[..., None]
    out[..., indices(FEET), 2] -= lift[..., None]
    out[..., [J["RKnee"], J["LKnee"]], 2] -= 0.5 * lift[..., None]
    return out


def pin(motion, targets, axes, keyed):
    """Motion with each curve's joint on its target (F, 3) on every frame ({joint: targets}), on the
    coordinates it follows ({joint: (3,) bool}), and each keyed joint on its key ({frame index:
    {joint: (3,)}}): in place, returned."""
    for index, joints in keyed.items():
        for joint, position in joints.items():
            motion[:, index, J[joint]] = position
    for joint, path in targets.items():
        for axis in np.flatnonzero(axes[joint]):
            motion[:, :, J[joint], axis] = path[..., axis]
    return motion


def carried_by_hips(motion, targets, axes):
    """Motion (V, F, 17, 3) moved whole onto its hips' curve (a path on the ground gives x and y
    only), so the body comes along rather than the hips alone being pinned."""
    if "Hip" not in targets:
        return motion
    shift = (targets["Hip"] - motion[:, :, J["Hip"]]) * axes["Hip"]
    return motion + shift[:, :, None, :]


def pinned_joints(frames, targets, keyed, fps=None):
    """(frames, 17): 1 where the artist fixed a joint on a frame (a curve's joint, a keyed joint).
    With ``fps``, a key's weight also eases out over KEY_BRIDGE_S either side of it, so what the
    retarget does differently for fixed joints comes in without a step."""
    pinned = np.zeros((frames, len(J)))
    for joint in targets:
        pinned[:, J[joint]] = 1.0
    half = max(KEY_BRIDGE_S * fps, 1.0) if fps else 0.5
    near = 1.0 - smoothstep(np.abs(np.arange(frames)[:, None] - np.array(sorted(keyed))[None]) / half)  # (F, keys)
    for column, index in enumerate(sorted(keyed)):
        for joint in keyed[index]:
            pinned[:, J[joint]] = np.maximum(pinned[:, J[joint]], near[:, column])
    return pinned


def tidy(motion, fps, initial, targets, axes, keyed, predicted, walks=None):
    """(motion, contacts (V, F, 2), foot turns (V, F, 2)) of the variants (V, F, 17, 3) at ``fps``
    from the pose ``initial`` (17, 3): on the floor, eased onto the keys, planted feet still (those
    low, or a little higher where the model predicts them planted: ``predicted`` (V, F, 2)),
    every curve ({joint: (F, 3), or each variant's (V, F, 3)}, on its axes {joint: (3,) bool})
    and key ({frame index: {joint: (3,)}}) met exactly; a curve of the hips carries the whole body
    (``carried_by_hips``). Under a ground path, ``walks`` (``footsteps.Walks`` at ``fps``): the body
    faces along each variant's route, its ankles take the planned steps (the model's own feet land
    up to 0.4 m short of them) and it walks in its gait, leaning into the walk and swinging the
    arms free of curves and keys against the legs."""
    standing = lower_ankle_height(initial)
    on_curves = pinned_joints(motion.shape[1], targets, {})  # keys ease in after the feet are planted
    motion = carried_by_hips(motion, targets, axes)
    if "Hip" in targets and not axes["Hip"][2]:  # a ground path: walk facing along it
        motion = facing_the_path(motion, initial, targets["Hip"] if walks is None else walks.routes, fps)
    stance = placed = None
    if walks is not None:
        motion = motion.copy()
        motion[:, :, indices(FEET)] = walks.ankles
        stance = np.stack([footsteps.stance(variant) for variant in walks.ankles])
    motion = upright(motion, initial, fps)
    motion = hips_up(on_floor(ease_out_of_start(motion, fps), fps, standing), initial, fps, standing)
    if walks is None:  # a walk's body falls forward from step to step
        motion, placed = balancing_steps(motion, fps, standing, on_curves, initial, predicted,
                                         steps=not set(FEET) & set().union(*keyed.values()))
    motion = without_slide(motion, fps, standing, on_curves, initial, targets, predicted, stance, placed)
    motion, contacts, turns = plant_feet(motion, fps, standing, on_curves, initial, predicted, stance, placed)
    if walks is None:
        motion = over_the_feet(motion, fps, standing, contacts, on_curves, initial, turns)
    else:
        fixed = set(targets).union(*keyed.values())
        motion = leaning_into_the_walk(motion, np.array([gait.lean for gait in walks.gaits]), fps, initial)
        motion = swinging_arms(motion, np.array([gait.arm_swing for gait in walks.gaits]), fps, initial,
                               [not fixed & set(arm) for arm in LIMBS[2:]])
    return pin(ease_onto_keys(motion, keyed, fps, standing), targets, axes, keyed), contacts, turns
