"""Footsteps: when and where feet plant and swing, for paths drawn without them.

Two uses. ``Stepping`` times a foot path drawn on the floor without drawing
times (the foot plants and swings along it). ``planned_feet`` plans both feet
under a ground path of the hips (each variant in its own ``Gait``: timing, arm
swing, lean; the hips ``swayed`` over the feet), rolling heel to toe: given only the hips'
path, the model's feet glide along it at the hips' speed (ankles lifted 2-4 cm,
planted ankles at 0.8 m/s); given feet that step, it completes the walking or
running body around them. Stride lengths and
timing are those of captured walks and runs: a stride (one foot's travel from
plant to plant) of about STRIDE_M + STRIDE_PER_SPEED_S * speed, each foot in the
air for SWING_SHARE of it at a walk and RUN_SWING_SHARE at a run (both feet
off the ground between steps), the feet half a stride apart.
"""

from dataclasses import dataclass

import numpy as np

from .filters import runs, smooth, smoothstep
from .skeleton import FEET, JOINT_INDEX, shortest_leg

J = JOINT_INDEX

# A foot's travel per stride at a speed v (m/s): about STRIDE_M + STRIDE_PER_SPEED_S * v
# (1.4 m at a 1.4 m/s walk, 1 m at a stroll).
STRIDE_M, STRIDE_PER_SPEED_S = 0.6, 0.55
SWING_SHARE = 0.4  # of each stride, the foot in the air (a walk: 40 %, with double support)
FOOT_LIFT_M = 0.1  # the ankle's lift at mid-swing, heel off to toe clearance
# Running: from WALK_TOP_M_S to RUN_FROM_M_S the gait turns from a walk into a run, each foot in the air
# for RUN_SWING_SHARE of a stride (stance 35 %: a flight between steps), its ankle lifted RUN_LIFT_M.
WALK_TOP_M_S, RUN_FROM_M_S = 2.0, 2.6
RUN_SWING_SHARE = 0.65
RUN_LIFT_M = 0.25

# Planned feet: the hips walk while faster than WALKING_M_S (their speed smoothed over SPEED_SMOOTHING_S);
# slower, the feet still step at MIN_CADENCE strides a second until both stand beside the hips. The
# first foot lifts START_DELAY of a stride after the hips set off; steps shorter than SHORTEST_STEP_M are
# not taken; each foot stands HALF_WIDTH_M (at least, at most) to its side of the hips' path.
WALKING_M_S = 0.1
SPEED_SMOOTHING_S = 0.25
MIN_CADENCE = 0.9  # 0.6 left the trailing foot 0.7 m behind the setting-off hips
START_DELAY = 0.15
SHORTEST_STEP_M = 0.05
HALF_WIDTH_M = (0.05, 0.10)
RESTS = (0.45, 0.95)  # shares of a stride where both feet are down (the left foot swings from 0.5)
FULL_LIFT_STEP_M = 0.4  # shorter steps lift the foot in proportion
FARTHEST_LANDING = 0.4  # legs (hip to ankle) from the hips, horizontally, to a landing as it lands
UNDER_HIPS = 0.45  # share of its stance at which a planted foot is under the hips
# The last HEEL_OFF of a stance rolls onto the toes, the foot pitched HEEL_PITCH_DEG by lift-off (an adult's
# 0.2 m foot: its heel 12 cm up; as a height, a Rigify foot, its toes the ball of the foot, stood on end).
HEEL_OFF, HEEL_PITCH_DEG = 0.5, 37.0
FOOT_M = 0.2  # ankle to toe tip over the ground, an adult's (a rig's own where it has toes)
STRIDE_SPREAD = (0.9, 1.1)  # stride scales of a walk's variants
DELAY_SPREAD = (0.05, 0.25)  # their first lifts, in strides after the hips set off
# Drawn without times, a ground path is walked from rest to rest, speeding up over WALK_EASE_S and
# slowing over as long (over 0.5 s the hips ran ahead of the first steps and the legs' reach dropped
# them to 0.8 of their height); a walk's variants set off and arrive over EASE_SPREAD, so they are
# not in step along the path.
WALK_EASE_S = 0.8
EASE_SPREAD = (0.6, 1.0)
# From WALKING_FULL_M_S the walk's lean and sway are full; slower, less, and none standing.
WALKING_FULL_M_S = 1.0
# The arms swing against the legs (cleanup.swinging_arms) by ARM_SWING_DEG per leg length the feet are
# apart along the body's facing: at a 1.1 m/s walk the wrist swings about 0.35 m front to back,
# the median of 38 captured walks of ../shared (0.1 to 0.7 m, more the faster). The model's own arms
# hang nearly still (0.08-0.15 m). A walk's variants swing theirs over ARM_SWING_SPREAD.
ARM_SWING_DEG = 24.0
ARM_SWING_SPREAD = (12.0, 40.0)
# Walking, the torso leans LEAN_DEG forward of the start pose's (cleanup.leaning_into_the_walk); a walk's
# variants lean over LEAN_SPREAD. Between people of ../shared walking the same path (statures
# scaled alike), the neck and head lie 9 cm apart, the wrists 14 cm: posture differs.
LEAN_DEG = 3.0
LEAN_SPREAD = (-2.0, 8.0)
# Walking, the hips sway SWAY_SHARE of the way toward the foot bearing the body (one moving slower
# than BEARING_SPEED_M_S: an ankle rolling onto its toes still bears it), at most SWAY_M, smoothed
# over SWAY_SMOOTHING_S: a walker's pelvis shifts 2-3 cm over each stance foot, not along a rail.
SWAY_SHARE, SWAY_M = 0.4, 0.03
SWAY_SMOOTHING_S = 0.1
BEARING_SPEED_M_S = 0.5


@dataclass(frozen=True)
class Gait:
    """How one take walks: its strides scaled by ``stride`` (longer, a slower cadence), its first
    lift ``delay`` strides after the hips set off, led by the foot farther behind unless
    ``other_foot_first``, its arms swinging ``arm_swing`` degrees per leg the feet are apart, its
    torso leaning ``lean`` degrees forward; a path drawn without times it walks speeding up over
    ``ease_in`` seconds and slowing over ``ease_out``."""

    stride: float = 1.0
    delay: float = START_DELAY
    other_foot_first: bool = False
    arm_swing: float = ARM_SWING_DEG
    lean: float = LEAN_DEG
    ease_in: float = WALK_EASE_S
    ease_out: float = WALK_EASE_S


@dataclass(frozen=True)
class Walks:
    """Each variant's planned walk under a ground path of the hips, frames at one rate: its ankles
    (V, F, 2, 3) and feet's pitches (V, F, 2), right then left (``planned_feet``), its hips' route
    (V, F, 3) before they sway over the feet (``swayed``), and its ``Gait`` [V]."""

    ankles: np.ndarray
    pitches: np.ndarray
    routes: np.ndarray
    gaits: list

    def resampled(self, resample):
        """The same walks on other frames: ``resample`` maps values (V, F, ..., 3) over frames."""
        return Walks(resample(self.ankles), resample(self.pitches[..., None])[..., 0],
                     resample(self.routes[:, :, None])[:, :, 0], self.gaits)


def swing_share(speed):
    """Each foot's share (...) of a stride in the air at hip speeds (...) m/s: a walk's, a run's, or between."""
    return np.interp(speed, (WALK_TOP_M_S, RUN_FROM_M_S), (SWING_SHARE, RUN_SWING_SHARE))


def stride_length(speed):
    """A foot's travel (m) from plant to plant at a walking ``speed`` (m/s), as captured walks take."""
    return STRIDE_M + STRIDE_PER_SPEED_S * speed


class Stepping:
    """The timing of a foot path of ``length`` metres drawn on the floor without drawing times,
    covered in ``seconds``: strides as long as people take at that speed, the foot planted for all
    but SWING_SHARE of each stride and swinging between plants with an ease in and out, lifted
    FOOT_LIFT_M at mid-swing. ``phase`` (a share of a stride) delays its swings: the left foot
    swings half a stride after the right."""

    SHORTEST_PATH_M = 1.0  # a foot path shorter than this is not a walk

    def __init__(self, length, seconds, phase=0.0):
        stride = stride_length(length / max(seconds, 1e-9))
        self.strides, self.phase = max(1, round(length / stride)), phase

    def _swing(self, progress):
        """(strides completed (..,), share of the current swing done (..,) in [0, 1])."""
        cycle = np.asarray(progress) * self.strides - self.phase
        whole = np.floor(cycle)
        return whole, np.clip((cycle - whole) / SWING_SHARE, 0.0, 1.0)

    def __call__(self, progress):
        """Share of the way covered at ``progress`` in [0, 1] of the time."""
        whole, swing = self._swing(progress)
        return np.clip((whole + smoothstep(swing)) / self.strides, 0.0, 1.0)

    def lift(self, progress):
        """The foot's lift above its path (m) at ``progress``: a half sine over each swing."""
        _, swing = self._swing(progress)
        return FOOT_LIFT_M * np.sin(np.pi * swing)


def gait_phase(speed, fps, gait):
    """Strides walked by each frame (F,) at hip speeds (F,) m/s: while the hips walk (faster than
    WALKING_M_S) the feet step at the cadence of captured walks (at least MIN_CADENCE), and each
    walk's cadence is stretched a little so that the walk ends with both feet down (``RESTS``)
    on the frame the hips stop: no foot is left mid-air or steps after the body has stopped.
    ``gait`` (a ``Gait``) scales the strides and delays the first lift."""
    cadence = np.maximum(speed / (gait.stride * stride_length(speed)), MIN_CADENCE) / fps
    phase = np.full(len(speed), -gait.delay)
    for start, end in runs(speed > WALKING_M_S):
        now = phase[start - 1] if start else phase[0]
        walked = cadence[start:end + 1].sum()
        rests = np.floor(now) + np.arange(-1, np.ceil(walked) + 2)[:, None] + np.array(RESTS)
        rests = rests.ravel()[rests.ravel() >= now]
        stop = rests[np.argmin(np.abs(rests - (now + walked)))]
        phase[end + 1:] = stop
        phase[start:end + 1] = now + np.cumsum(cadence[start:end + 1]) * (stop - now) / max(walked, 1e-9)
    return phase


def planned_feet(hips, initial, fps, gait=None, foot=FOOT_M):
    """(ankles (F, 2, 3), foot pitches (F, 2) radians, toes down), right then left, stepping under
    the hips' ground path (F, 2) from the pose ``initial`` (17, 3) (its first frame), in a frame
    with the floor at z = 0: each foot lands where the hips will be UNDER_HIPS of the way into
    its stance, to its side of the path, rolls onto its toes before it lifts (``heel_roll``), at most
    FARTHEST_LANDING legs from the hips as it lands (a first step from standing would reach for
    the hips' cruising travel), and lifts FOOT_LIFT_M between plants (less for steps under
    FULL_LIFT_STEP_M). The foot farther behind the direction of travel steps first, unless the
    ``gait`` (a ``Gait``, by default the plain one) leads with the other. ``foot``: the ankle to
    toe length over the ground. None where the hips never walk."""
    frames = len(hips)
    travel = np.gradient(hips, axis=0) * fps
    speed = np.linalg.norm(travel, axis=-1)
    half = max(1, int(round(SPEED_SMOOTHING_S * fps)))
    speed = np.convolve(np.pad(speed, half, mode="edge"), np.ones(2 * half + 1) / (2 * half + 1), "valid")
    moving = np.flatnonzero(speed > WALKING_M_S)
    if not len(moving):
        return None
    forward = travel[moving[np.clip(np.searchsorted(moving, np.arange(frames)), 0, len(moving) - 1)]]
    forward /= np.maximum(np.linalg.norm(forward, axis=-1, keepdims=True), 1e-9)
    left = np.stack([-forward[:, 1], forward[:, 0]], axis=-1)
    gait = gait or Gait()
    phase = gait_phase(speed, fps, gait)
    ankles = initial[[J[foot] for foot in FEET]].astype(np.float64)
    floor_height = ankles[:, 2].min()
    longest = FARTHEST_LANDING * shortest_leg(initial)
    first = int(np.argmin((ankles[:, :2] - hips[0]) @ forward[0])) ^ int(gait.other_foot_first)
    widths = np.clip(np.abs((ankles[:, :2] - hips[0]) @ left[0]), *HALF_WIDTH_M) * np.array([-1.0, 1.0])
    strides = phase[:, None] - np.where(np.arange(2) == first, 0.0, 0.5)  # (F, 2): each foot's own strides
    swung = swing_share(speed)  # (F,)
    lifted = np.interp(speed, (WALK_TOP_M_S, RUN_FROM_M_S), (FOOT_LIFT_M, RUN_LIFT_M))
    swings, progress = _swings(strides, swung)
    feet = np.repeat(ankles[None], frames, axis=0)
    for lift_off, end, side in swings:
        landing = min(end, frames - 1)
        rate = max(phase[landing] - phase[landing - 1], 1e-9)  # strides per frame
        middle = min(landing + int(round((1.0 - swung[landing]) * UNDER_HIPS / rate)), frames - 1)
        target = hips[middle] + widths[side] * left[middle]
        reach = np.linalg.norm(target - hips[landing])
        if reach > longest:
            target = hips[landing] + (target - hips[landing]) * longest / reach
        position, height = feet[lift_off, side, :2], feet[lift_off, side, 2]
        step = np.linalg.norm(target - position)
        if step < SHORTEST_STEP_M:
            continue
        share = progress[lift_off:end, side]
        eased = smoothstep(share)
        feet[lift_off:end, side, :2] = position + (target - position) * eased[:, None]
        feet[lift_off:end, side, 2] = (height + (floor_height - height) * eased
                                       + lifted[lift_off] * min(1.0, step / FULL_LIFT_STEP_M) * np.sin(np.pi * share))
        feet[end:, side] = (*target, floor_height)
    return heel_roll(feet, swings, phase, progress, 1.0 - swung, forward, foot)


def heel_roll(feet, swings, phase, within, stance, forward, foot=FOOT_M):
    """(ankles (F, 2, 3), pitches (F, 2)): planted ankles (F, 2, 3) rolled onto the toes over the
    last HEEL_OFF of each stance before a swing (``swings``: (lift-off, landing, side)), the heel
    up by HEEL_PITCH_DEG at lift-off and down again by mid-swing, the foot pitched about its toes
    (``foot`` ahead of the ankle along ``forward`` (F, 2)) so they stay where they stood; ``phase``
    (F,): strides walked (``gait_phase``), ``within`` (F, 2): the share of its swing each foot has
    done (``_swings``), ``stance`` (F,): a stride's share on the ground. A flat foot keeps the
    legs from reaching a walk's plants without lowering the hips (a captured ankle rises 15-20 cm
    at push-off)."""
    heel = np.zeros(feet.shape[:2])
    lift = foot * np.sin(np.radians(HEEL_PITCH_DEG))
    for lift_off, end, side in swings:
        rate = max(phase[lift_off] - phase[max(lift_off - 1, 0)], 1e-9)  # strides per frame
        rolling = max(1, int(round(HEEL_OFF * stance[lift_off] / rate)))
        start = max(0, lift_off - rolling)
        heel[start:lift_off, side] = lift * smoothstep((np.arange(start, lift_off) - start + 1) / rolling)
        share = within[lift_off:end, side]
        heel[lift_off:end, side] = lift * (1.0 - smoothstep(2.0 * share))
    pitch = np.arcsin(np.clip(heel / foot, 0.0, 1.0))
    out = feet.copy()
    out[..., 2] += heel
    out[..., :2] += forward[:, None] * (foot * (1.0 - np.cos(pitch)))[..., None]
    return out, pitch


def _swings(strides, swung):
    """(swings, progress): each foot's swings (lift-off frame, landing frame, side), in time order,
    from its strides (F, 2) (a swing starts with each stride and lasts the share ``swung`` (F,) of
    it at lift-off, so a run slowing to a walk mid-swing does not cut the swing short), and the
    share (F, 2) of its swing each foot has done (0 on the ground)."""
    cycle = np.floor(strides)
    progress = np.zeros(strides.shape)
    swings = []
    for side in range(2):
        starts = np.flatnonzero((strides[:, side] >= 0.0) & (np.diff(cycle[:, side], prepend=-np.inf) != 0))
        for lift_off in starts:
            share = (strides[lift_off:, side] - cycle[lift_off, side]) / swung[lift_off]
            end = lift_off + int(np.argmax(np.append(share >= 1.0, True)))
            if end > lift_off:
                swings.append((lift_off, end, side))
                progress[lift_off:end, side] = share[:end - lift_off]
    return sorted(swings), progress


def stance(feet):
    """Frames (F, 2) bool where planned ankles (F, 2, 3) stand still: moved neither into nor out of."""
    moved = np.linalg.norm(np.diff(feet, axis=0), axis=-1) > 1e-6  # (F - 1, 2)
    still = np.ones(feet.shape[:2], dtype=bool)
    still[1:] &= ~moved
    still[:-1] &= ~moved
    return still


def walking_share(hips, fps):
    """How fully hips (..., F, 2 or 3) walk on each frame (..., F): their horizontal speed over
    WALKING_FULL_M_S, at most 1."""
    speed = np.linalg.norm(np.gradient(hips[..., :2], axis=-2), axis=-1) * fps
    return np.clip(speed / WALKING_FULL_M_S, 0.0, 1.0)


def swayed(path, feet, fps):
    """A ground path of the hips (F, 3) swayed toward the foot bearing the body, of the planned
    ankles (F, 2, 3) (see SWAY_SHARE), as far as the hips walk (``walking_share``)."""
    forward = np.gradient(path[:, :2], axis=0)
    forward /= np.maximum(np.linalg.norm(forward, axis=-1, keepdims=True), 1e-9)
    left = np.stack([-forward[:, 1], forward[:, 0]], axis=-1)
    speed = np.linalg.norm(np.gradient(feet[..., :2], axis=0), axis=-1) * fps  # (F, 2)
    bearing = np.clip(1.0 - speed / BEARING_SPEED_M_S, 0.0, 1.0)
    support = (feet[..., :2] * bearing[..., None]).sum(1) / np.maximum(bearing.sum(1), 1e-9)[:, None]
    across = np.where(bearing.any(1), ((support - path[:, :2]) * left).sum(-1), 0.0)
    across = np.clip(SWAY_SHARE * across, -SWAY_M, SWAY_M) * walking_share(path, fps)
    out = path.copy()
    out[:, :2] += smooth(across, SWAY_SMOOTHING_S * fps)[:, None] * left
    return out


def variant_gaits(count, rng, diversity=1.0):
    """A ``Gait`` for each of ``count`` variants of a walk: strides, first lifts, arm swings, leans
    and eases in and out spread evenly over STRIDE_SPREAD, DELAY_SPREAD, ARM_SWING_SPREAD,
    LEAN_SPREAD and EASE_SPREAD, each in its own random order, every other variant leading with
    the other foot, so the variants differ in timing, arm swing and posture, not only in what the
    model adds above the feet (5 variants of a 4 m walk, as played: 0.03 m apart in one gait, 0.06
    in their own steps, 0.10 in their own gaits, their hips swaying). ``diversity`` (the request's,
    0 to 2) narrows the spreads toward the plain ``Gait`` below 1: at 0 every variant walks alike."""
    share = min(max(diversity, 0.0), 1.0)
    if count == 1 or share == 0.0:
        return [Gait()] * count
    plain = Gait()
    spreads = (STRIDE_SPREAD, DELAY_SPREAD, ARM_SWING_SPREAD, LEAN_SPREAD, EASE_SPREAD, EASE_SPREAD)
    centres = (plain.stride, plain.delay, plain.arm_swing, plain.lean, plain.ease_in, plain.ease_out)
    drawn = np.stack([centre + share * (rng.permutation(np.linspace(*spread, count)) - centre)
                      for spread, centre in zip(spreads, centres)], axis=1)
    return [Gait(float(stride), float(delay), bool(index % 2), *map(float, style))
            for index, (stride, delay, *style) in enumerate(drawn)]


def toes_down(pitches, heels, foot=FOOT_M):
    """Foot pitches (...) no steeper than ankles ``heels`` (...) over their standing height let
    toes ``foot`` ahead of them reach down to: the cleanup's ease out of the start pose holds the
    ankles lower than planned, and a foot pitched as planned put its toes 6 cm through the floor."""
    return np.minimum(pitches, np.arcsin(np.clip(heels / foot, 0.0, 1.0)))
