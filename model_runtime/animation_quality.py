"""What an animator sees in a shot, as figures: sliding feet, floating or sinking, pops, steps,
lean, knee direction, balance, spread between variants (../shared/notes/quality-measures.md).

Inputs are world positions as Blender plays the rig (metres, Z up): the 17
joints (F, 17, 3) and the toes (F, 2, 3, right then left: each foot bone's
tail), at the scene's ``fps``. Pure numpy, so the same figures serve the
add-on's tests, its benchmark and real capture imported into Blender.
"""

import itertools

import numpy as np

from .filters import runs
from .skeleton import JOINT_INDEX, centre_of_mass, facing, hips_roll

J = JOINT_INDEX
PLANTED_BAND_M = 0.02  # a toe this close to the floor is planted
AIRBORNE_M = 0.03  # both toes higher than this: the body is off the ground
STEP_LIFT_M = 0.04  # a foot lifted this far above the floor ...
STEP_LENGTH_M = 0.15  # ... and landing this far away (horizontally) made a step
HELD_UP_M = 0.05  # a toe this far above the floor ...
HELD_UP_S = 0.6  # ... for this long is a foot held up, not a step (a walk's swing lasts 0.3-0.5 s)
# A foot whose toe is this close to the floor bears weight (captured standing feet rock up to 2.5 cm);
# its sole reaches HEEL_SHARE of the ankle-to-toe length behind the ankle and FOOT_HALF_WIDTH_M to
# either side of that line (and beyond the toe joint, as the toes do).
SUPPORT_BAND_M = 0.05
HEEL_SHARE = 0.35
FOOT_HALF_WIDTH_M = 0.04


def floor_height(toes):
    """The floor under a shot that starts standing: the lower toe at its first frame."""
    return float(toes[0, :, 2].min())


def planted_toe_speed(toes, fps, floor, band=PLANTED_BAND_M):
    """Mean horizontal speed (m/s, central differences) of toes within ``band`` of the floor,
    averaged over the feet that are ever planted; 0 where none is."""
    velocity = np.gradient(toes[..., :2], axis=0) * fps
    speed = np.linalg.norm(velocity, axis=-1)  # (F, 2)
    planted = toes[..., 2] - floor < band
    means = [speed[planted[:, foot], foot].mean() for foot in range(toes.shape[1]) if planted[:, foot].any()]
    return float(np.mean(means)) if means else 0.0


def floating(toes, floor):
    """(highest lower-toe height over the shot (m), share of frames with both toes above
    AIRBORNE_M, deepest sink below the floor (m, positive))."""
    lower = toes[..., 2].min(axis=1) - floor
    airborne = (toes[..., 2] - floor > AIRBORNE_M).all(axis=1)
    return float(lower.max()), float(airborne.mean()), float(max(0.0, -lower.min()))


def held_up(toes, floor, fps):
    """Share of frames (F,) on which a toe has been over HELD_UP_M above the floor for HELD_UP_S or
    longer: a foot left hovering while the body stands (``floating`` sees the lower toe alone)."""
    frames = max(1, round(HELD_UP_S * fps))
    held = np.zeros(len(toes), dtype=bool)
    for up in (toes[..., 2] - floor > HELD_UP_M).T:
        for start, end in runs(up):
            held[start:end + 1] |= end - start + 1 >= frames
    return float(held.mean())


def off_balance(joints, toes, floor):
    """Per frame (F,), how far (m) the body's centre of mass lies horizontally outside the soles of
    both feet where both bear weight (NaN on other frames: a step or a walk falls forward onto
    the next foot): a standing body keeps it over its feet (captured clips of ../shared, standing
    or walking: within 2 cm of the soles on every such frame)."""
    mass = centre_of_mass(joints)[:, :2]
    out = np.full(len(joints), np.nan)
    for frame in np.flatnonzero((toes[..., 2] - floor < SUPPORT_BAND_M).all(axis=1)):
        soles = []
        for side, ankle in enumerate((J["RFoot"], J["LFoot"])):
            heel, toe = joints[frame, ankle, :2], toes[frame, side, :2]
            soles += [heel - HEEL_SHARE * (toe - heel), toe]
        out[frame] = max(_outside(mass[frame], soles) - FOOT_HALF_WIDTH_M, 0.0)
    return out


def _outside(point, corners):
    """Distance of a point (2,) from the convex hull of 2-4 corners [(2,)], 0 inside: inside one
    of their triangles, or else the nearest of the segments between them (its edges among them)."""
    def cross(a, b, c):
        return (a[0] - c[0]) * (b[1] - c[1]) - (b[0] - c[0]) * (a[1] - c[1])

    for a, b, c in itertools.combinations(corners, 3):
        signs = (cross(point, a, b), cross(point, b, c), cross(point, c, a))
        if min(signs) >= 0.0 or max(signs) <= 0.0:
            return 0.0
    distances = []
    for a, b in itertools.combinations(corners, 2):
        along = np.clip(np.dot(point - a, b - a) / max(float(np.dot(b - a, b - a)), 1e-12), 0.0, 1.0)
        distances.append(float(np.linalg.norm(point - a - along * (b - a))))
    return min(distances)


def accelerations(joints, fps):
    """Per frame, the largest joint acceleration (F - 2,) in m/s^2 (second differences)."""
    return np.linalg.norm(np.diff(joints, n=2, axis=0), axis=-1).max(axis=1) * fps ** 2


def pops(joints, fps):
    """(worst joint acceleration (m/s^2), worst frame's over the median frame's)."""
    per_frame = accelerations(joints, fps)
    return float(per_frame.max()), float(per_frame.max() / max(np.median(per_frame), 1e-9))


def seam(joints, fps, joins, near=2):
    """(worst, mean): the worst frame's joint acceleration within ``near`` frames of the frame
    indices ``joins`` (where model windows meet) over the worst elsewhere, and the same of their
    means. Above 1, the joins show; in a walk the worst is often a heel strike that happens to
    fall near a join, which the mean ratio tells apart."""
    per_frame = accelerations(joints, fps)  # entry i: frame i + 1
    close = np.zeros(len(per_frame), dtype=bool)
    for frame in joins:
        close[max(frame - 1 - near, 0):max(frame + near, 0)] = True
    if close.all() or not close.any():
        return float("nan"), float("nan")
    return (float(per_frame[close].max() / max(per_frame[~close].max(), 1e-9)),
            float(per_frame[close].mean() / max(per_frame[~close].mean(), 1e-9)))


def steps(toes, floor):
    """Steps per foot (2,): a lift above the floor by STEP_LIFT_M followed by a landing at least
    STEP_LENGTH_M (horizontally) from where the foot left."""
    counts = []
    for foot in range(toes.shape[1]):
        height = toes[:, foot, 2] - floor
        count, lifted_from = 0, None
        for frame in range(len(height)):
            if lifted_from is None and height[frame] > STEP_LIFT_M:
                lifted_from = toes[max(frame - 1, 0), foot, :2]
            elif lifted_from is not None and height[frame] < PLANTED_BAND_M:
                count += np.linalg.norm(toes[frame, foot, :2] - lifted_from) >= STEP_LENGTH_M
                lifted_from = None
        counts.append(int(count))
    return counts


def lean_degrees(joints):
    """Per pose, the angle (...) of Hip -> Thorax from vertical, degrees: (..., 17, 3) -> (...)."""
    up = joints[..., J["Thorax"], :] - joints[..., J["Hip"], :]
    return np.degrees(np.arccos(np.clip(up[..., 2] / np.linalg.norm(up, axis=-1), -1.0, 1.0)))


def roll_degrees(joints):
    """Per frame, how far (F,) the hip line tilts from horizontal, degrees (the pelvis's roll)."""
    return np.abs(np.degrees(hips_roll(joints)))


def arm_swing(joints):
    """How far the wrists swing front to back (m): per arm, the 5th to 95th percentile of the wrist's
    offset from its shoulder along the body's facing over frames (F, 17, 3), the mean of both arms
    (captured walks of ../shared at 0.9-1.9 m/s: 0.1 to 0.7, median 0.37)."""
    forward = facing(joints)
    ranges = [np.ptp(np.percentile(np.sum((joints[:, J[wrist]] - joints[:, J[shoulder]]) * forward, axis=-1),
                                   (5, 95)))
              for wrist, shoulder in (("RWrist", "RShoulder"), ("LWrist", "LShoulder"))]
    return float(np.mean(ranges))


def knee_inward_degrees(joints):
    """Per frame and leg (F, 2), how far each knee points inward of the body's forward direction,
    degrees (0: straight ahead or outward; 90: toward the other leg). Knock-knees and crossed
    shins read high; a straight leg has no direction and reads 0."""
    across = joints[:, J["LHip"]] - joints[:, J["RHip"]]
    across[:, 2] = 0.0
    across /= np.maximum(np.linalg.norm(across, axis=-1, keepdims=True), 1e-9)
    out = []
    for hip, knee, ankle, inward in (("RHip", "RKnee", "RFoot", 1.0), ("LHip", "LKnee", "LFoot", -1.0)):
        axis = joints[:, J[ankle]] - joints[:, J[hip]]
        axis /= np.maximum(np.linalg.norm(axis, axis=-1, keepdims=True), 1e-9)
        bend = joints[:, J[knee]] - joints[:, J[hip]]
        bend -= np.sum(bend * axis, axis=-1, keepdims=True) * axis
        size = np.linalg.norm(bend, axis=-1)
        sideways = inward * np.sum(bend * across, axis=-1) / np.maximum(size, 1e-9)
        angle = np.degrees(np.arcsin(np.clip(sideways, 0.0, 1.0)))
        out.append(np.where(size > 0.01, angle, 0.0))
    return np.stack(out, axis=1)


def mean_joint_distances(variants):
    """Mean joint distances (V, V) (m) between variants (V, F, J, 3), absolute positions as an
    artist compares them."""
    distances = np.zeros((len(variants), len(variants)))
    for index in range(len(variants) - 1):
        distances[index, index + 1:] = np.linalg.norm(variants[index + 1:] - variants[index], axis=-1).mean(axis=(1, 2))
    return distances + distances.T


def spread(variants):
    """Mean over pairs of variants (V, F, J, 3) of their mean joint distance (m); 0 for one."""
    if len(variants) < 2:
        return 0.0
    return float(mean_joint_distances(variants)[np.triu_indices(len(variants), 1)].mean())


def _dense(path, spacing=0.01):
    """A polyline (P, 2) resampled every ``spacing`` metres, with its unit tangents: ((N, 2), (N, 2))."""
    lengths = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=-1))]
    at = np.linspace(0.0, lengths[-1], max(2, int(lengths[-1] / spacing) + 1))
    points = np.column_stack([np.interp(at, lengths, path[:, axis]) for axis in range(2)])
    tangents = np.gradient(points, axis=0)
    return points, tangents / np.maximum(np.linalg.norm(tangents, axis=-1, keepdims=True), 1e-9)


def path_following(joints, path):
    """How a walk follows a ground path (P, 3): (farthest the hips stray from the path horizontally
    (m), per frame the facing's angle from the path's tangent nearest the hips (F,), degrees)."""
    points, tangents = _dense(np.asarray(path)[:, :2])
    hips = joints[:, J["Hip"], :2]
    distances = np.linalg.norm(hips[:, None] - points[None], axis=-1)  # (F, N)
    nearest = distances.argmin(axis=1)
    forward = facing(joints)[:, :2]
    cosine = np.sum(forward * tangents[nearest], axis=-1) / np.maximum(np.linalg.norm(forward, axis=-1), 1e-9)
    return float(distances.min(axis=1).max()), np.degrees(np.arccos(np.clip(cosine, -1.0, 1.0)))


def hip_height_share(joints, floor):
    """The hips' lowest height above the floor over their height at the first frame (standing)."""
    height = joints[:, J["Hip"], 2] - floor
    return float(height.min() / height[0])
