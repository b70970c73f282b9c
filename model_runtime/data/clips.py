"""One BVH file to a clip of the 17 canonical joints at the model's native rate.

Output convention: metres, Z up, floor at z = 0, ``NATIVE_FPS`` frames per
second. BVH files are read as Y up (the format's convention, and Blender's
importer's): file (x, y, z) becomes (x, -z, y), a rotation, so left stays left.
"""

from dataclasses import dataclass

import numpy as np

from .. import rotations
from ..skeleton import JOINT_INDEX, NUM_JOINTS
from . import bvh, profiles

NATIVE_FPS = 30
# Metres per file unit, by name. "cgspeed" is the CMU ASF unit kept by the
# cgspeed BVH conversions: 1/0.45 inch.
LENGTH_UNITS = {"metre": 1.0, "centimetre": 0.01, "inch": 0.0254, "cgspeed": 0.0254 / 0.45}
TYPICAL_ADULT_HEIGHT_M = 1.7
# A skeleton whose best unit gives a stature outside this range is rescaled to
# the typical height (e.g. the DAZ files of ../mocap, "rescaled to metres" by a
# factor that makes adults 1.2 m tall). Real statures within it are kept: CMU
# subjects read from 1.37 m (105) to 1.95 m.
PLAUSIBLE_HEIGHT_M = (1.3, 2.1)
HIP_HEIGHT_PER_STATURE = 0.53
_Y_UP_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


@dataclass
class Clip:
    """A motion of the canonical skeleton.

    positions: (T, 17, 3) float32 metres, Z up, floor at 0.
    soles: (T, 2) float32 height of the lowest point of the right and left
    foot (ankle and toe joints), for contact checks.
    """

    file: str
    profile: str
    positions: np.ndarray
    soles: np.ndarray
    source_fps: float
    height_m: float
    unit: str
    source_frames: int  # frames of the file used, after any added T-pose or blank frames
    fps: int = NATIVE_FPS

    @property
    def frames(self):
        return self.positions.shape[0]

    @property
    def seconds(self):
        return (self.frames - 1) / self.fps


def load_clip(path, custom=()):
    """Read, map, resample and normalise one BVH file (raises BVHError or MappingError); ``custom``
    profiles (``profiles.read_mapping``) are tried before the built-in ones."""
    motion = bvh.read(path)
    hierarchy = motion.hierarchy
    profile = profiles.detect(hierarchy.names, str(path), custom)
    motion = bvh.Motion(hierarchy, _drop_added_frames(hierarchy, motion.values), motion.frame_time)
    values_used = motion.values.shape[0]

    bones = {joint: hierarchy.index(bone) for joint, bone in profile.resolve(hierarchy.names).items()}
    feet = {side: _descendants(hierarchy, bones[side]) for side in ("RFoot", "LFoot")}
    needed = bvh.ancestors_closure(hierarchy, list(bones.values()) + feet["RFoot"] + feet["LFoot"])
    slot = {joint: k for k, joint in enumerate(needed)}

    quats, translations = bvh.local_transforms(motion, needed)
    source_fps = _snap_rate(1.0 / motion.frame_time)
    quats, translations = resample(quats, translations, source_fps, NATIVE_FPS)
    world_rot, world_pos = bvh.forward_kinematics(
        [slot.get(hierarchy.parents[j], -1) for j in needed], quats, translations)

    canonical = np.zeros((world_pos.shape[0], NUM_JOINTS, 3))
    for joint, bone in bones.items():
        canonical[:, JOINT_INDEX[joint]] = world_pos[:, slot[bone]]
    leg_length = _leg_length(canonical)
    head_bone = bones["Neck"]
    head_direction = hierarchy.offsets[head_bone] / max(np.linalg.norm(hierarchy.offsets[head_bone]), 1e-9)
    _fill_virtual_joints(canonical, world_rot[:, slot[head_bone]], head_direction * leg_length * profiles.HEAD_LENGTH_PER_LEG)

    soles = np.stack([_sole_heights(hierarchy, feet[side], slot, world_rot, world_pos)
                      for side in ("RFoot", "LFoot")], axis=1)
    height_units = _stature(canonical, soles, leg_length)
    unit, scale = _length_unit(height_units)

    positions = canonical @ _Y_UP_TO_Z_UP.T * scale
    soles = soles * scale
    positions, soles = _put_on_floor(positions, soles)
    return Clip(str(path), profile.name, positions.astype(np.float32), soles.astype(np.float32),
                source_fps, float(height_units * scale), unit, int(values_used))


def resample(quats, translations, source_fps, target_fps):
    """Local rotations (F, J, 4) and translations (F, J, 3) at a new frame rate.

    Rotations are slerped and translations interpolated linearly, so bone
    lengths stay exact. The new frames span the same duration.
    """
    frames = quats.shape[0]
    duration = (frames - 1) / source_fps
    count = int(np.floor(duration * target_fps + 1e-6)) + 1
    position = np.arange(count) * (source_fps / target_fps)
    lower = np.clip(np.floor(position + 1e-6).astype(int), 0, frames - 1)
    upper = np.minimum(lower + 1, frames - 1)
    fraction = np.clip(position - lower, 0.0, 1.0)
    if np.all(fraction < 1e-6):
        return quats[lower], translations[lower]
    out_quats = rotations.slerp(quats[lower], quats[upper], fraction[:, None])
    out_translations = translations[lower] + fraction[:, None, None] * (translations[upper] - translations[lower])
    return out_quats, out_translations


def _length_unit(height_units):
    """(name, metres per file unit): the declared unit that gives an adult height."""
    unit = min(LENGTH_UNITS, key=lambda u: abs(np.log(height_units * LENGTH_UNITS[u] / TYPICAL_ADULT_HEIGHT_M)))
    low, high = PLAUSIBLE_HEIGHT_M
    if low <= height_units * LENGTH_UNITS[unit] <= high:
        return unit, LENGTH_UNITS[unit]
    return "rescaled", TYPICAL_ADULT_HEIGHT_M / height_units


def _snap_rate(fps):
    """A file's rate, snapped to the whole number its rounded frame time stands for (1/0.0333333 -> 30)."""
    return float(round(fps)) if abs(fps - round(fps)) < 1e-3 * fps else fps


def _drop_added_frames(hierarchy, values):
    """Frames (F, C) without a converter's T-pose and any blank leading frames.

    The cgspeed conversions (MotionBuilder and DAZ namings) put a T-pose at frame 0
    in most files, not all: its root rotation is exactly 0, which no captured
    frame has. Some files follow it with frames whose root channels are all 0.
    """
    root = len(hierarchy.channels[0])
    rotation = [k for k, name in enumerate(hierarchy.channels[0]) if name.lower().endswith("rotation")]
    start = 1 if not np.any(values[0, rotation]) else 0
    while start < values.shape[0] - 1 and not np.any(values[start, :root]):
        start += 1
    return values[start:]


def _descendants(hierarchy, joint):
    """A joint and every joint below it."""
    found = [joint]
    for child, parent in enumerate(hierarchy.parents):
        if parent in found:
            found.append(child)
    return found


def _sole_heights(hierarchy, foot_joints, slot, world_rot, world_pos):
    """Per-frame height (file up axis, Y) of a foot's lowest point (F,).

    The points are the ankle and toe joints; a foot without toe joints uses
    its end site instead. (Toe-tip end sites dip below the floor at push-off
    in the CMU skeletons, while the toe joint stays on it.)
    """
    points = [world_pos[:, slot[j], 1] for j in foot_joints]
    for joint in foot_joints if len(foot_joints) == 1 else ():
        end = hierarchy.end_offsets.get(joint)
        if end is not None and np.linalg.norm(end) > 0:
            points.append(world_pos[:, slot[joint], 1] + world_rot[:, slot[joint], 1] @ end)
    return np.min(points, axis=0)


def _leg_length(canonical):
    """Mean hip-knee-ankle length over both legs, from the first frame (bones are rigid)."""
    frame = canonical[0]
    total = 0.0
    for hip, knee, foot in (("RHip", "RKnee", "RFoot"), ("LHip", "LKnee", "LFoot")):
        h, k, f = (frame[JOINT_INDEX[n]] for n in (hip, knee, foot))
        total += np.linalg.norm(k - h) + np.linalg.norm(f - k)
    return total / 2.0


def _fill_virtual_joints(canonical, head_rotation, head_offset):
    """Hip, Spine and Head from the mapped joints, in place. (T, 17, 3)."""
    j = JOINT_INDEX
    canonical[:, j["Hip"]] = 0.5 * (canonical[:, j["LHip"]] + canonical[:, j["RHip"]])
    canonical[:, j["Spine"]] = 0.5 * (canonical[:, j["Hip"]] + canonical[:, j["Thorax"]])
    canonical[:, j["Head"]] = canonical[:, j["Neck"]] + head_rotation @ head_offset


def _stature(canonical, soles, leg_length):
    """Standing height in file units, from lengths that do not depend on the pose.

    Mean of two estimates whose biases run opposite ways on mocap skeletons
    (rigs disagree on where the hips and the neck base sit): the skeleton's
    upright chain (sole to ankle, leg, pelvis to neck base, neck, head) and
    the anthropometric rule hip joint height = 0.53 x stature (Drillis and
    Contini). The bending torso is measured at its longest over the clip,
    the ankle's height above the sole at its median.
    """
    j = JOINT_INDEX
    ankle = np.median(canonical[:, [j["RFoot"], j["LFoot"]], 1] - soles)
    torso = np.percentile(np.linalg.norm(canonical[:, j["Thorax"]] - canonical[:, j["Hip"]], axis=-1), 95)
    neck = np.linalg.norm(canonical[0, j["Neck"]] - canonical[0, j["Thorax"]])
    head = np.linalg.norm(canonical[0, j["Head"]] - canonical[0, j["Neck"]])
    chain = ankle + leg_length + torso + neck + head
    anthropometric = (ankle + leg_length) / HIP_HEIGHT_PER_STATURE
    return float(0.5 * (chain + anthropometric))


def _put_on_floor(positions, soles, window=15, max_tilt_deg=3.0, inlier_m=0.05):
    """Level a clip on its floor and put the floor at z = 0. (T, 17, 3), (T, 2) -> same.

    Floor contacts are the lowest sole point of each half-second; a plane
    through them (least squares, refitted without points off by more than
    ``inlier_m``) measures the capture floor's tilt, undone by a rotation
    (bones keep their lengths) when it is under ``max_tilt_deg`` and fits
    most contacts; anything else is terrain or climbing, not tilt. The floor
    height is the 10th percentile of the contacts, which ignores short
    capture glitches below the floor.
    """
    lowest = soles.min(axis=1)
    starts = range(0, max(len(lowest) - window + 1, 1), window)
    frames = np.array([start + int(np.argmin(lowest[start:start + window])) for start in starts])
    feet = positions[:, [JOINT_INDEX["RFoot"], JOINT_INDEX["LFoot"]], :2]
    contacts = np.column_stack([feet[frames, np.argmin(soles[frames], axis=1)], lowest[frames]])
    keep = np.ones(len(contacts), bool)
    slope = np.zeros(2)
    if not len(contacts):
        return positions, soles
    spread = np.ptp(contacts[:, :2], axis=0).max() if len(contacts) else 0.0
    if len(contacts) >= 4 and spread > 1.0:
        for _ in range(3):
            design = np.column_stack([contacts[keep, :2], np.ones(keep.sum())])
            coef = np.linalg.lstsq(design, contacts[keep, 2], rcond=None)[0]
            residual = contacts[:, 2] - np.column_stack([contacts[:, :2], np.ones(len(contacts))]) @ coef
            keep = np.abs(residual) < inlier_m
            if keep.sum() < 4:
                break
        else:
            slope = coef[:2]
    if np.degrees(np.arctan(np.linalg.norm(slope))) >= max_tilt_deg or keep.mean() < 0.6:
        slope = np.zeros(2)
    if np.any(slope):
        normal = np.array([-slope[0], -slope[1], 1.0]) / np.sqrt(1.0 + slope @ slope)
        level = _rotation_between(normal, np.array([0.0, 0.0, 1.0]))
        before = positions[..., 2].copy()
        positions = positions @ level.T
        soles = soles + (positions[:, [JOINT_INDEX["RFoot"], JOINT_INDEX["LFoot"]], 2]
                         - before[:, [JOINT_INDEX["RFoot"], JOINT_INDEX["LFoot"]]])
        contacts[:, 2] = (np.column_stack([contacts[:, :2], contacts[:, 2]]) @ level.T)[:, 2]
    floor = float(np.percentile(contacts[:, 2], 10))
    positions = positions.copy()
    positions[..., 2] -= floor
    return positions, soles - floor


def _rotation_between(a, b):
    """Rotation matrix (3, 3) turning unit vector a onto unit vector b (not opposite)."""
    axis = np.cross(a, b)
    sine, cosine = np.linalg.norm(axis), float(a @ b)
    if sine < 1e-12:
        return np.eye(3)
    k = axis / sine
    cross = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + sine * cross + (1 - cosine) * cross @ cross
