"""Reading an artist's rig: its mapping (auto-detected, merged with overrides) and its pose at a frame."""

import functools
import json

import numpy as np

from . import rig_mapping
from .runtime import profiles, retarget, skeleton

J = skeleton.JOINT_INDEX


class RigError(ValueError):
    """The rig cannot be used as it is; the message says what to fix."""


def active_armature(context):
    """The active object if it is an armature, else None."""
    obj = context.active_object
    return obj if obj is not None and obj.type == 'ARMATURE' else None


def unusable_reason(armature):
    """A sentence saying why generation cannot write to ``armature``, or None when it can."""
    if armature is None or getattr(armature, "type", None) != 'ARMATURE':
        return "select an armature to generate motion for"
    if armature.override_library is not None:
        return (f"{armature.name!r} is a library override, whose variant list Blender cannot keep across save "
                "and reload; make it local first (Object > Relations > Make Local)")
    if armature.library is not None:
        return (f"{armature.name!r} is linked from {armature.library.filepath!r} and cannot be animated here; "
                "make it local first (Object > Relations > Make Local)")
    animation = armature.animation_data
    if animation is not None and animation.use_tweak_mode:
        return (f"{armature.name!r} is in NLA tweak mode, where a variant cannot be shown; exit it first "
                "(Tab in the NLA editor)")
    gaps = rig_mapping.missing(mapping(armature))
    if gaps:
        return f"{armature.name}: no bone mapped for {', '.join(gaps)}; set them under TrajeVAE > Rig Mapping"
    return None


POSE_CHANNELS = ("location", "rotation_quaternion", "rotation_euler", "rotation_axis_angle", "scale")


def pose_snapshot(armature):
    """{bone: {channel: values}} of every pose bone's transform channels and rotation mode: what
    restoring the artist's rig puts back, exactly (JSON-safe)."""
    return {bone.name: {"rotation_mode": bone.rotation_mode,
                        **{channel: list(getattr(bone, channel)) for channel in POSE_CHANNELS}}
            for bone in armature.pose.bones}


def restore_pose(armature, snapshot):
    """Put back a ``pose_snapshot`` on the bones that still exist."""
    bones = armature.pose.bones
    for name, channels in snapshot.items():
        bone = bones.get(name)
        if bone is None:
            continue
        bone.rotation_mode = channels["rotation_mode"]
        for channel in POSE_CHANNELS:
            setattr(bone, channel, channels[channel])


def detected(armature):
    """(profile name, {joint: bone or None}) from the armature's bone names alone; remembered per
    bone hierarchy, as the panel asks once per binding row on every redraw."""
    profile, bones = _detect(tuple((bone.name, bone.parent.name if bone.parent else None)
                                   for bone in armature.data.bones))
    return profile, dict(bones)


@functools.lru_cache(maxsize=64)
def _detect(hierarchy):
    return rig_mapping.detect(dict(hierarchy))


def mapping(armature):
    """{joint: bone or None}: the detected mapping with the artist's stored overrides on top."""
    _, auto = detected(armature)
    overrides = armature.trajevae.mapping
    bones = armature.data.bones
    return {joint: (getattr(overrides, joint) if getattr(overrides, joint) in bones else auto[joint])
            for joint in skeleton.JOINT_NAMES}


def checked_mapping(armature):
    """The mapping of a rig generation can write to; RigError saying why not otherwise."""
    reason = unusable_reason(armature)
    if reason:
        raise RigError(reason)
    return mapping(armature)


def check_finite(armature, state, frame):
    """RigError naming the bones whose pose at ``frame`` is not a number (NaN or infinite)."""
    broken = sorted(bone for bone in state.matrices if not (np.isfinite(state.matrices[bone]).all()
                                                           and np.isfinite(state.bases[bone]).all()))
    if broken or not np.isfinite(np.array(armature.matrix_world)).all():
        where = f"bone {', '.join(map(repr, broken))}" if broken else "object transform"
        raise RigError(f"{armature.name!r}: the {where} at frame {frame} is not a number (NaN or infinite); "
                       "reset or re-key it before generating")


def _owner_and_name(armature, path):
    """(owner, key, is_item) of a data path like 'pose.bones["b"]["prop"]' or '...constraints["c"].influence'."""
    if path.endswith('"]'):
        owner_path, _, key = path[:-2].rpartition('["')
        return armature.path_resolve(owner_path), key, True
    owner_path, _, key = path.rpartition(".")
    return armature.path_resolve(owner_path), key, False


def current_switches(armature, values):
    """The rig's present values of the switches (data paths) in ``values`` that exist on it."""
    out = {}
    for path in values:
        try:
            out[path] = armature.path_resolve(path)
        except ValueError:  # not on this rig
            continue
    return out


def apply_switches(armature, values):
    """Set switches {data path: value} that exist on the rig."""
    for path in current_switches(armature, values):
        owner, key, is_item = _owner_and_name(armature, path)
        if is_item:
            owner[key] = values[path]
        else:
            setattr(owner, key, values[path])


def switches_to_json(values):
    return json.dumps(values)


def switches_from_json(text):
    return json.loads(text) if text else {}


def _drivers(armature, keyed):
    """Keyed bone -> its nearest keyed ancestor (whose motion carries its parent space) or None. An
    ancestor that copies a keyed bone's transforms whole (Rigify's ORG-shoulder, under its upper
    arms, copies the shoulder control) counts as that bone."""
    out = {}
    for bone in keyed:
        parent, driver = armature.data.bones[bone].parent, None
        while parent is not None and driver is None:
            driver = parent.name if parent.name in keyed else _copied(armature, parent.name, keyed)
            parent = parent.parent
        out[bone] = driver
    return out


def _copied(armature, bone, keyed):
    """The keyed bone whose transforms ``bone`` copies whole (a Copy Transforms constraint of full
    influence on this armature), or None."""
    for constraint in armature.pose.bones[bone].constraints:
        if (constraint.type == 'COPY_TRANSFORMS' and constraint.enabled and constraint.influence == 1.0
                and constraint.target == armature and constraint.subtarget in keyed):
            return constraint.subtarget
    return None


def _snap(matrices, bases, drivers, shown):
    """Keyed bones moved onto the ``shown`` matrices, in place, parents first: a snapped bone's
    children ride along with it, so each gets the basis that puts it where it is shown."""
    moved = {}

    def depth(bone):
        return 0 if drivers[bone] is None else 1 + depth(drivers[bone])

    for bone in sorted(matrices, key=depth):
        parent_space = matrices[bone] @ np.linalg.inv(bases[bone])
        if drivers[bone] in moved:
            parent_space = moved[drivers[bone]] @ parent_space
        new = shown.get(bone, parent_space @ bases[bone])
        moved[bone] = new @ np.linalg.inv(matrices[bone])
        matrices[bone], bases[bone] = new, np.linalg.inv(parent_space) @ new


def clavicles(armature, bones):
    """{"RClavicle" / "LClavicle": bone} (``retarget.CLAVICLES``) of the rig's clavicles, given its
    mapping {joint: bone or None}, that its trunk carries (the hips' or the chest's bone) and that
    carry their upper arm: keyed with the mapped bones."""
    keyed = {joint: bone for joint, bone in bones.items() if bone and joint != "Head"}
    parents = {bone.name: bone.parent.name if bone.parent else None for bone in armature.data.bones}
    found = rig_mapping.clavicles(detected(armature)[0], parents, keyed)
    drivers = _drivers(armature, set(keyed.values()) | set(found.values()))
    trunk = {keyed.get("Hip"), keyed.get("Spine")} - {None}
    return {key: bone for key, bone in found.items() if drivers[bone] in trunk
            and drivers.get(keyed.get(key.replace("Clavicle", "Shoulder"))) == bone}


def read(armature, bones, depsgraph, shown_by=None):
    """The rig as the retargeter needs it (armature space) and its joints in world space (17, 3).

    Call with the scene at the start frame. ``shown_by`` {keyed bone: bone}
    names bones that show the visible pose when the keyed ones may not (a
    Rigify rig posed in IK): the keyed bone is then read as if snapped onto
    it, with the basis that would put it there.
    """
    evaluated = armature.evaluated_get(depsgraph)
    pose = evaluated.pose.bones
    keyed = {joint: bone for joint, bone in bones.items() if bone and joint != "Head"}
    found = clavicles(armature, bones)
    names = set(keyed.values()) | set(found.values())
    matrices = {bone: np.array(pose[bone].matrix, dtype=np.float64) for bone in names}
    bases = {bone: np.array(pose[bone].matrix_basis, dtype=np.float64) for bone in names}
    drivers = _drivers(armature, names)
    if shown_by:
        _snap(matrices, bases, drivers, {bone: np.array(pose[shown].matrix, dtype=np.float64)
                                         for bone, shown in shown_by.items() if bone in names and shown in pose})
    joints = _joints(matrices, keyed, bones, pose)
    state = retarget.RigState(bones=keyed, matrices=matrices, bases=bases, drivers=drivers, joints=joints,
                              clavicles=found)
    world = np.array(armature.matrix_world, dtype=np.float64)
    return state, joints @ world[:3, :3].T + world[:3, 3]


def _joints(matrices, keyed, bones, pose):
    """Joint positions (17, 3) in armature space from the keyed bones' matrices {bone: (4, 4)}."""
    joints = np.zeros((skeleton.NUM_JOINTS, 3))
    for joint in profiles.MAPPED_JOINTS:
        joints[J[joint]] = matrices[keyed[joint]][:3, 3]
    joints[J["Hip"]] = 0.5 * (joints[J["LHip"]] + joints[J["RHip"]])
    joints[J["Spine"]] = 0.5 * (joints[J["Hip"]] + joints[J["Thorax"]])
    if bones.get("Head"):
        joints[J["Head"]] = np.array(pose[bones["Head"]].head)
    else:
        legs = 0.5 * sum(np.linalg.norm(joints[J[a]] - joints[J[b]]) for a, b in
                         (("RHip", "RKnee"), ("RKnee", "RFoot"), ("LHip", "LKnee"), ("LKnee", "LFoot")))
        head_axis = matrices[keyed["Neck"]][:3, 1]
        joints[J["Head"]] = joints[J["Neck"]] + profiles.HEAD_LENGTH_PER_LEG * legs * head_axis / np.linalg.norm(
            head_axis)
    return joints


def world_joints(armature, bones, depsgraph, shown_by=None):
    """The joints in world space (17, 3) as the rig shows them now (``read``'s second part, read
    from the bones that show each keyed one): what measuring a variant as played needs."""
    pose = armature.evaluated_get(depsgraph).pose.bones
    keyed = {joint: bone for joint, bone in bones.items() if bone and joint != "Head"}
    shown = {bone: (shown_by or {}).get(bone, bone) for bone in keyed.values()}
    matrices = {bone: np.array(pose[shown[bone] if shown[bone] in pose else bone].matrix, dtype=np.float64)
                for bone in keyed.values()}
    world = np.array(armature.matrix_world, dtype=np.float64)
    return _joints(matrices, keyed, bones, pose) @ world[:3, :3].T + world[:3, 3]


def toes(armature, bones, depsgraph, shown_by=None):
    """World positions (2, 3) of the rig's toes now, right then left: the tail of each foot's bone,
    or of the bone that shows it. The lower one is the floor the rig stands on."""
    pose, world = armature.evaluated_get(depsgraph).pose.bones, np.array(armature.matrix_world, dtype=np.float64)
    feet = [(shown_by or {}).get(bones[foot], bones[foot]) for foot in ("RFoot", "LFoot")]
    return np.array([world[:3, :3] @ np.array(pose[foot].tail) + world[:3, 3] for foot in feet])


def to_armature_space(armature, points):
    """World points (..., 3) in the armature's object space."""
    inverse = np.linalg.inv(np.array(armature.matrix_world, dtype=np.float64))
    return points @ inverse[:3, :3].T + inverse[:3, 3]
