"""Any-length generation with the numpy model: world space in, world space out.

The model works on 2-second windows at 30 fps (``clips.NATIVE_FPS``) in its
window frame: metres, Z up, floor at z = 0, initial root at the ground-plane
origin, adult proportions. ``Placement`` maps a scene's units and floor into
that frame and back; ``generate`` chains windows: each window after the first
starts ``overlap`` frames before the previous one ends, sees those frames as
known (see below), and the two are cross-faded over the overlap, so there is
no seam; where its carried frames end, a few frames are smoothed
(``smooth_across``). Every frame keeps the initial pose's proportions above
the hips (``with_proportions``) and a rigid pelvis whose roll stays near the
initial pose's (``with_rigid_pelvis``). A later window carries the legs and the hips'
horizontal position only: its upper body and hip height start afresh from the
initial pose's (``anchored``), so what one window bends or sinks the next does
not continue (carried whole, a 10 s walk's torso folded to 0.4 of its length and
its hips sank to 0.8 of their height).
"""

from dataclasses import dataclass

import numpy as np

from . import selection
from .data.clips import NATIVE_FPS
from .augment import rotate_about_z
from .filters import smooth, smoothstep
from .masks import carried_legs, per_coordinate
from .retarget import steady_across
from .skeleton import (FEET, JOINT_INDEX, JOINT_NAMES, LIMBS, PARENTS, UPPER_BODY, elevation, facing,
                       hips_roll, indices, lower_ankle_height, turned)

# Hip-knee-ankle length of the training subjects (metres, 201 clips: 0.796 to
# 0.880, median 0.808): rigs whose legs fall outside are scaled to the median.
TRAINED_LEG_LENGTH_M = (0.79, 0.89)
TYPICAL_LEG_LENGTH_M = 0.81

# Model frames shared by consecutive windows (at 30 fps); 10 left the joins at the motion's own 95th
# percentile of speed change, 15 well inside it.
WINDOW_OVERLAP = 15
# Where a later window's carried frames end, the body (hips and above) keeps its horizontal speed
# and eases into the window's own over MOMENTUM_FRAMES model frames: the model stopped a carried
# drift dead there (a reach's body, moving 1 m/s sideways, stopped in one frame: 83 m/s^2 on the
# elbow as played); 6 and 10 frames carried it on far enough to bend legs past their limits.
MOMENTUM_FRAMES = 4
# Where a later window's carried frames end, its decoder lets the carried legs go: every joint's
# speed changes in a frame there. Within SEAM_FRAMES model frames of that frame the motion is
# eased toward itself smoothed over SEAM_SIGMA frames, so the change spreads over a few frames.
SEAM_FRAMES = 6
SEAM_SIGMA = 2.0
# The hips' roll (the line between the hip joints tilting about the body's forward axis) is kept
# as generated up to PELVIS_ROLL_FREE_DEG beyond the initial pose's and eased toward
# PELVIS_ROLL_MOST_DEG beyond it: the model rolled the pelvis 12-24 degrees in a wave and a long
# walk (median 11), and a rig whose trunk turns as one bone (Rigify's torso) leaned sideways with
# it; captured walks and reaches of ../shared roll at most 3-10 degrees.
PELVIS_ROLL_FREE_DEG = 5.0
PELVIS_ROLL_MOST_DEG = 10.0
# Where joints are given, the first window draws its latents this much wider than the prior's spread
# (times the artist's diversity): a curve narrows what the prior allows, and 5 variants of a hand
# reach, picked as played, lay 0.126 m apart on the mannequin (seeds 0-5, weights before the facing
# frame; 0.156 at 1.25 with selection.SCREENED_FOLD_COS). The facing-frame weights are surer of a
# curve's body: seeds 0-3, mannequin / Rigify, a reach's variants 0.132 / 0.163 m apart at 1.25,
# 0.152 / 0.166 at 1.4, a 10 s wave's 0.131 / 0.170 and 0.147 / 0.165, blocking keys' 0.056 / 0.064
# and 0.060 / 0.071, worst frames at most 7.7x the median (at 1.5, wider still under curves where
# the spread grew with the share of frames given, the keys' variants lay 0.047 m apart).
GIVEN_SPREAD = 1.4
# A later window that holds given joints (a curve, keys) shared by the motions (candidates the
# variants are picked from as played, not walks along their own paths) draws CONTINUATION_DRAWS
# continuations of each motion, CONTINUATION_SPREAD x the prior's spread, and keeps the one farthest
# from the other motions' that keeps the hands within reach (``selection.continuations_apart``).
# Measured before cleanup.balancing_steps: one draw at the prior's spread, a 10 s wave's 5 variants
# lay 0.098 / 0.110 m apart (mannequin / Rigify, seeds 0-5)
# and its hand's worst frame was 1.0 / 0.8 cm off the curve; 4 draws: 0.109 / 0.130 m and 0.8 / 0.6
# cm (one draw 1.5x wider: 0.108 / 0.119 m, 1.1 / 1.2 cm; 8 draws: 0.118 / 0.127 m, 1.2 / 0.9 cm;
# 2x wider: 0.123 / 0.134 m, 0.9 / 1.4 cm). Only while the extra draws come to no more than
# CONTINUATION_EXTRA_FRAMES candidate-frames: 50 variants of 10,000 frames took 170 s instead of 77.
CONTINUATION_DRAWS = 4
CONTINUATION_SPREAD = 1.5
CONTINUATION_EXTRA_FRAMES = 15000
# The joints a later window's start raises to the initial hip height and a carried speed moves: the
# pelvis and everything above it, the legs below the hip joints staying where they are.
PELVIS_AND_ABOVE = indices(UPPER_BODY + ("Hip", "RHip", "LHip"))


def leg_length(pose):
    """Mean hip-knee-ankle length of both legs of a pose (17, 3)."""
    j = JOINT_INDEX
    return 0.5 * sum(np.linalg.norm(pose[j[k]] - pose[j[h]]) + np.linalg.norm(pose[j[f]] - pose[j[k]])
                     for h, k, f in (("RHip", "RKnee", "RFoot"), ("LHip", "LKnee", "LFoot")))


@dataclass(frozen=True)
class Placement:
    """World <-> model frame: model = (world - origin) * scale."""

    origin: np.ndarray  # (3,): initial root over the floor
    scale: float

    @classmethod
    def for_pose(cls, initial, floor_z, metres_per_unit=1.0):
        """Placement of an initial pose (17, 3) in world units standing on z = ``floor_z``."""
        legs = leg_length(initial) * metres_per_unit
        low, high = TRAINED_LEG_LENGTH_M
        metres = metres_per_unit if low <= legs <= high else metres_per_unit * TYPICAL_LEG_LENGTH_M / legs
        root = initial[JOINT_INDEX["Hip"]]
        return cls(np.array([root[0], root[1], floor_z], dtype=np.float64), float(metres))

    def to_model(self, points):
        return ((points - self.origin) * self.scale).astype(np.float32)

    def to_world(self, points):
        return points / self.scale + self.origin


def model_frames(scene_frames, fps):
    """Model frames after the initial one that cover ``scene_frames`` frames at ``fps``."""
    return int(np.ceil((scene_frames - 1) * NATIVE_FPS / fps - 1e-6))


def to_scene_rate(motion, scene_frames, fps):
    """Motion (..., 1 + T, J, 3) at the model rate, linearly resampled to (..., scene_frames, J, 3)."""
    times = np.arange(scene_frames) * NATIVE_FPS / fps
    below = np.minimum(np.floor(times).astype(int), motion.shape[-3] - 1)
    above = np.minimum(below + 1, motion.shape[-3] - 1)
    weight = (times - below)[:, None, None]
    return motion[..., below, :, :] * (1.0 - weight) + motion[..., above, :, :] * weight


def _window(model, initial, trajectories, mask, count, rng, diversity, sampler, continuation=False):
    """One window for B conditions in the model frame: motions (B, count, W, 17, 3) and planted
    feet (B, count, W, 2) in [0, 1]; inputs (B, ...).

    Known joints come back as the decoder's fit, not pasted: carried frames are cross-faded into
    the new window, and the retarget pins curves and keys exactly afterwards. A ``continuation``
    (a later window, its first frames carried) is one plain prior sample as decoded: it follows its
    carried frames by itself, and the completion stage, not trained on such windows, stepped
    where they end (16 mm/frame against 4 mm/frame at the joins of a 300-frame shot).
    """
    shift = initial[:, :1].copy()  # (B, 1, 3): root over the floor
    shift[..., 2] = 0.0
    motion, planted = model.sample(initial - shift, (trajectories - shift[:, None]) * mask, mask, count, rng,
                                   scale=diversity, sampler=sampler, keep_given=False,
                                   screen_given=not continuation, decoded_only=continuation)
    return motion + shift[:, None, None], planted


def with_momentum(motion, done, hips_free):
    """Motion (B, F, 17, 3) whose frames after ``done`` carry on the horizontal speed the hips had
    at ``done``, the body above them moving with them, easing into their own over MOMENTUM_FRAMES
    (the speed's change fading as 1 - smoothstep); only where ``hips_free`` (B,) (a ground path
    gives the hips their speed)."""
    out = motion.copy()
    hips = JOINT_INDEX["Hip"]
    jump = (motion[:, done, hips] - motion[:, done - 1, hips]) - (motion[:, done + 1, hips] - motion[:, done, hips])
    change = jump * np.array([1.0, 1.0, 0.0]) * hips_free[:, None]  # (B, 3)
    share = np.minimum(np.arange(1, motion.shape[1] - done) / MOMENTUM_FRAMES, 1.0)
    travelled = MOMENTUM_FRAMES * (share - share ** 3 + share ** 4 / 2)  # the integral of 1 - smoothstep
    out[:, done + 1:, PELVIS_AND_ABOVE] += travelled[None, :, None, None] * change[:, None, None]
    return out


def on_the_floor(motion, known, carried, frames, standing):
    """A later window's motions (B, W, 17, 3) moved up or down as one so that the lower ankle's
    lowest over the window's own frames (``carried`` to ``frames``) stands at ``standing``, where
    no foot's height is given there (``known`` (B, W, 17, 3)): each continuation rose 2-3 cm on its
    carried legs, and a 10 s wave's decoded ankles ended 0.25 m off the floor."""
    feet = indices(FEET)
    lowest = motion[:, carried:frames, feet, 2].min(axis=(1, 2))  # (B,)
    free = known[:, carried:frames, feet, 2].max(axis=(1, 2)) == 0.0
    out = motion.copy()
    out[..., 2] += np.where(free, standing - lowest, 0.0)[:, None, None]
    return out


def smooth_across(motion, at):
    """Ease motion (B, F, 17, 3), in place, within SEAM_FRAMES of frame ``at`` toward itself
    smoothed over SEAM_SIGMA frames (fully at ``at``, not at all SEAM_FRAMES away): a kink there
    spreads over a few frames; a joint that is still or moves steadily stays as it is. Only the
    frames around ``at`` are read, so a long shot's windows cost no more."""
    low, high = max(at - SEAM_FRAMES, 0), min(at + SEAM_FRAMES + 1, motion.shape[1])
    reach = int(np.ceil(3 * SEAM_SIGMA))  # the smoothing's own span either side
    first, last = max(low - reach, 0), min(high + reach, motion.shape[1])
    over_frames = np.moveaxis(motion[:, first:last], 1, -1)  # (B, 17, 3, frames)
    smoothed = np.moveaxis(smooth(over_frames, SEAM_SIGMA), -1, 1)[:, low - first:high - first]
    weight = 1.0 - smoothstep(np.abs(np.arange(low, high) - at) / SEAM_FRAMES)
    motion[:, low:high] += weight[None, :, None, None] * (smoothed - motion[:, low:high])


def anchored(poses, initial):
    """Poses (B, 17, 3) with the torso, neck and head as in ``initial`` (17, 3), turned about Z with
    each pose's pelvis, the arms hanging from its shoulders as they were, and the hips at the
    initial pose's height: a later window's first pose. (Arms taken from ``initial`` as well went
    back to the start pose's at every window: from an A pose, idle arms rose at each join.)"""
    out = poses.copy()
    upper, root = indices(UPPER_BODY), JOINT_INDEX["Hip"]
    offsets = np.broadcast_to(initial[upper] - initial[root], (len(poses), len(upper), 3))  # (B, U, 3)
    out[:, upper] = poses[:, root, None] + rotate_about_z(offsets, _facing_angle(poses) - _facing_angle(initial))
    for shoulder, elbow, wrist in LIMBS[2:]:
        for joint, parent in ((JOINT_INDEX[elbow], JOINT_INDEX[shoulder]), (JOINT_INDEX[wrist], JOINT_INDEX[elbow])):
            out[:, joint] = out[:, parent] + poses[:, joint] - poses[:, parent]
    out[:, PELVIS_AND_ABOVE, 2] += (initial[root, 2] - poses[:, root, 2])[:, None]
    return out


def _facing_angle(poses):
    """Angles (...) about Z of poses' (..., 17, 3) facing (``skeleton.facing``)."""
    forward = facing(poses)
    return np.arctan2(forward[..., 1], forward[..., 0])


def with_rigid_pelvis(motion, reference):
    """Motions (V, F, 17, 3) with the hip joints as far apart as in ``reference`` (17, 3), about
    their midpoint placed from the root as in ``reference`` (turned with the pelvis), along the
    hips' direction steadied as the retarget steadies it (``retarget.steady_across``: where the
    generated hips lie close together, the shoulders' direction takes over) and rolled no further
    than PELVIS_ROLL_MOST_DEG beyond ``reference``'s, eased (no kink in its speed) from
    PELVIS_ROLL_FREE_DEG on. The hip joints are a rigid offset of the pelvis; the model keeps each
    one's distance from the root but not their angle, and in some takes brought them within 5 cm
    of each other, where the facing they define flipped; about their own midpoint, a 10 s wave's
    hip joints rose 0.25 m above the root, window by window."""
    right, left = JOINT_INDEX["RHip"], JOINT_INDEX["LHip"]
    across = np.stack([steady_across(reference, variant)[0] for variant in motion])  # (V, F, 3) unit
    roll = elevation(across)
    excess = roll - hips_roll(reference)
    free, room = np.radians(PELVIS_ROLL_FREE_DEG), np.radians(PELVIS_ROLL_MOST_DEG - PELVIS_ROLL_FREE_DEG)
    beyond = np.maximum(np.abs(excess) - free, 0.0)
    kept = roll - np.sign(excess) * (beyond - room * np.tanh(beyond / room))  # (V, F)
    ground = across * np.array([1.0, 1.0, 0.0])
    ground /= np.maximum(np.linalg.norm(ground, axis=-1, keepdims=True), 1e-9)
    span = reference[left] - reference[right]
    half = 0.5 * np.linalg.norm(span) * (
        np.cos(kept)[..., None] * ground + np.sin(kept)[..., None] * np.array([0.0, 0.0, 1.0]))
    start = span[:2] / np.linalg.norm(span[:2])
    turns = (ground[..., 0] * start[0] + ground[..., 1] * start[1],  # (cos, sin) (V, F) of the pelvis's turn
             start[0] * ground[..., 1] - start[1] * ground[..., 0])
    offset = 0.5 * (reference[left] + reference[right]) - reference[JOINT_INDEX["Hip"]]
    middle = motion[..., JOINT_INDEX["Hip"], :] + turned(np.broadcast_to(offset, motion.shape[:2] + (3,)), turns)
    out = motion.copy()
    out[..., left, :], out[..., right, :] = middle + half, middle - half
    return out


def with_proportions(poses, reference):
    """Poses (..., 17, 3) with every segment (joint to parent) above the hips as long as in
    ``reference`` (17, 3), each in its own direction, from the hips out. Each window of a long shot
    starts from the last one's poses, so a body the model stretched a little per window kept
    stretching (a walk's neck reached 3.8x its length in 10 s). The legs are left as generated:
    lengthened, the ankles moved with every frame's small length errors and planted feet slid."""
    out = poses.copy()
    for joint, parent in enumerate(PARENTS):
        if parent < 0 or JOINT_NAMES[joint] not in UPPER_BODY:
            continue
        segment = poses[..., joint, :] - poses[..., parent, :]
        length = np.linalg.norm(segment, axis=-1, keepdims=True)
        out[..., joint, :] = out[..., parent, :] + segment * (
            np.linalg.norm(reference[joint] - reference[parent]) / np.maximum(length, 1e-9))
    return out


def generate(model, initial, trajectories, mask, count, rng, diversity=1.0, sampler=None, overlap=WINDOW_OVERLAP,
             progress=None):
    """``count`` motions (count, 1 + T, 17, 3) in the model frame, initial pose first, and how surely
    each foot is planted on each frame (count, 1 + T, 2) in [0, 1] (the initial frame as the first).

    initial (17, 3); trajectories (T, 17, 3), or each motion's (count, T, 17, 3), and mask
    (T, 17, 3) or (T, 17) of the coordinates given on each frame after the initial one. The first
    window draws ``count`` latents (with the diverse sampler when given; one per motion for
    trajectories of their own; ``GIVEN_SPREAD`` wider where joints are given); later windows
    continue each motion with one prior sample (where shared joints are given, the one kept of
    CONTINUATION_DRAWS), the body keeping its speed where their carried frames end
    (``with_momentum``).
    ``progress(fraction)`` is called after each window (it may raise to stop the work).
    """
    window = model.frames
    total = trajectories.shape[-3]
    mask = per_coordinate(mask)
    motion = np.zeros((count, 1 + total, 17, 3), np.float32)
    motion[:, 0] = initial
    planted = None
    standing = lower_ankle_height(initial)
    carry = carried_legs()
    for start, frames, carried in windows(total, window, overlap):
        done = start + carried  # frames already generated
        given = np.zeros((count, window, 17, 3), np.float32)
        known = np.zeros((count, window, 17, 3), np.float32)
        given[:, :frames] = trajectories[..., start:start + frames, :, :]
        known[:, :frames] = mask[start:start + frames]
        given[:, :carried] = np.where(carry > 0, motion[:, start + 1:done + 1], given[:, :carried])
        known[:, :carried] = np.maximum(known[:, :carried], carry)
        if start == 0:
            spread = diversity * (GIVEN_SPREAD if known.any() else 1.0)
            if trajectories.ndim == 4:
                new, feet = (part[:, 0] for part in _window(model, np.repeat(initial[None], count, axis=0), given,
                                                             known, 1, rng, spread, sampler))
            else:
                new, feet = (part[0] for part in _window(model, initial[None], given[:1], known[:1], count, rng,
                                                          spread, sampler))
            planted = np.zeros((count, 1 + total, feet.shape[-1]), np.float32)
            planted[:, 0] = feet[:, 0]
        else:
            shared = count > 1 and trajectories.ndim == 3 and mask[start:start + frames].any()  # not walks' own paths
            draws = 1 + min(CONTINUATION_DRAWS - 1, CONTINUATION_EXTRA_FRAMES // (count * total)) if shared else 1
            new, feet = _window(model, anchored(motion[:, start], initial), given, known, draws, rng,
                                diversity * (CONTINUATION_SPREAD if draws > 1 else 1.0), None, continuation=True)
            pick = (selection.continuations_apart(new[:, :, :frames], initial, given[:, :frames], known[:, :frames],
                                                  carried) if draws > 1 else np.zeros(count, int))
            new, feet = new[np.arange(count), pick], feet[np.arange(count), pick]
        new = with_rigid_pelvis(new, initial)
        if start > 0:
            new = on_the_floor(new, known, carried, frames, standing)
        fade = smoothstep(np.linspace(0.0, 1.0, carried + 2)[1:-1, None])  # no kink where it starts or ends
        motion[:, start + 1:done + 1] = motion[:, start + 1:done + 1] * (1.0 - fade[..., None]) \
            + new[:, :carried] * fade[..., None]
        planted[:, start + 1:done + 1] = planted[:, start + 1:done + 1] * (1.0 - fade) + feet[:, :carried] * fade
        motion[:, done + 1:start + frames + 1] = new[:, carried:frames]
        motion[:, start + 1:start + frames + 1] = with_proportions(motion[:, start + 1:start + frames + 1], initial)
        if start > 0 and carried < frames:
            hips_free = known[:, carried, JOINT_INDEX["Hip"], :2].max(axis=-1) == 0.0  # no ground path
            motion[:, done - 1:start + frames + 1] = with_momentum(motion[:, done - 1:start + frames + 1], 1, hips_free)
            smooth_across(motion[:, :start + frames + 1], done)
        planted[:, done + 1:start + frames + 1] = feet[:, carried:frames]
        if progress is not None:
            progress((start + frames) / total)
    return motion, planted


def window_joins(scene_frames, fps, window, overlap=WINDOW_OVERLAP):
    """Frame indices of a shot (``scene_frames`` at ``fps``) where a later window's cross-fade
    begins and where it ends (the seams a long shot could show)."""
    total = model_frames(scene_frames, fps)
    model = sorted({edge for start, _, carried in windows(total, window, overlap)[1:]
                    for edge in (start + 1, start + carried + 1)})
    return [int(round(frame * fps / NATIVE_FPS)) for frame in model if frame * fps / NATIVE_FPS < scene_frames]


def windows(total, window, overlap=WINDOW_OVERLAP):
    """The model windows of a ``total``-frame shot: (start, frames, carried) each, its initial
    frame, its frames (up to ``window``) and how many of them the window before generated
    already (cross-faded into this one's)."""
    schedule, start, done = [], 0, 0
    while done < total:
        frames = min(window, total - start)
        schedule.append((start, frames, done - start))
        done = start + frames
        start = done - overlap
    return schedule


def eased(progress, ease, ease_out=None):
    """Share of the way covered (same shape) at ``progress`` in [0, 1] of the time, with constant
    acceleration over the first ``ease`` of it and deceleration over the last ``ease_out`` (by
    default ``ease``): a trapezoid of speed; linear for no ease."""
    ease_in, ease_out = min(ease, 0.5), min(ease if ease_out is None else ease_out, 0.5)
    if ease_in <= 0.0 and ease_out <= 0.0:
        return progress
    top = 1.0 / (1.0 - 0.5 * (ease_in + ease_out))  # the cruising speed, in shares of the way per share of the time
    rest = 1.0 - progress
    return np.where(progress < ease_in, top * progress ** 2 / (2 * max(ease_in, 1e-9)),
                    np.where(rest < ease_out, 1.0 - top * rest ** 2 / (2 * max(ease_out, 1e-9)),
                             top * (progress - ease_in / 2)))


def time_shares(frames, span):
    """Share of the shot's time (1 + frames,) in [0, 1] on each frame: frame m at min(m / span, 1),
    ``span`` (model frames, possibly fractional) being where the scene's last frame falls."""
    return np.clip(np.arange(frames + 1) / max(span, 1e-9), 0.0, 1.0)


def curve_samples(points, frames, span, times=None, timing=None):
    """Positions (1 + frames, 3) along a polyline (P, 3), uniform in arc length, or in drawing
    time when the points' ``times`` (P,) are given.

    Frame m sits at fraction min(m / span, 1) of the time: ``span`` (model
    frames, possibly fractional) is where the scene's last frame falls.
    ``timing`` maps that fraction to the share of the way covered (``eased``: a
    walk starting and stopping; ``footsteps.Stepping``: a foot's plants and swings);
    none: at constant speed.
    """
    if times is not None:
        lengths = np.asarray(times, dtype=np.float64) - times[0]
    else:
        lengths = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
    progress = time_shares(frames, span)
    wanted = (progress if timing is None else timing(progress)) * lengths[-1]
    return np.stack([np.interp(wanted, lengths, points[:, axis]) for axis in range(3)], axis=-1)
