"""Which joints follow which drawn paths: the armature's bindings and its bones' path constraints.

A binding names its bone and also marks it: the pose bone gets a tag (``PoseBone.trajevae_tag``,
a registered property, hidden from the artist's custom properties) that the binding remembers.
Blender carries the tag along when the bone is renamed in pose or edit mode, from Python or the
interface, and through save and reload, whereas the stored name goes stale and the bones' order
is no anchor (edit mode rebuilds it: a duplicated bone is inserted beside its source). A stale
name is resolved through the tag when the bindings are read, and the stored name is updated.
"""

import uuid

from . import rig_state

PATH_CONSTRAINTS = {'FOLLOW_PATH', 'CLAMP_TO'}


def bone_of(armature, binding):
    """The name of the bone the binding means now, or None where that bone is gone (read only,
    for drawing): the bone carrying the binding's tag, the stored name first where several do (a
    duplicated bone copies its tag); the stored name where no bone carries it (a binding from
    before tags, or the bone deleted and made again under its name)."""
    pose = armature.pose.bones
    tagged = [bone.name for bone in pose if bone.trajevae_tag == binding.bone_tag] if binding.bone_tag else []
    if binding.bone in tagged or (not tagged and binding.bone in pose):
        return binding.bone
    return tagged[0] if tagged else None


def refresh(armature):
    """Follow renames: every binding's stored name set to its bone's present name, a new tag for
    a binding without one, and the tag taken off other bones (copies from duplication), so later
    renames stay unambiguous. Writes only what changed."""
    for binding in armature.trajevae.bindings:
        bone = bone_of(armature, binding)
        if bone is None:
            continue
        if binding.bone != bone:
            binding.bone = bone
        if not binding.bone_tag:
            binding.bone_tag = uuid.uuid4().hex
        for pose_bone in armature.pose.bones:
            if (pose_bone.name == bone) != (pose_bone.trajevae_tag == binding.bone_tag):
                pose_bone.trajevae_tag = binding.bone_tag if pose_bone.name == bone else ""


def bind(armature, bone, curve, use_drawing_speed):
    """Bind an existing bone to a path, replacing the row of a binding that already means that
    bone (also one stored under the bone's old name)."""
    refresh(armature)
    bindings = armature.trajevae.bindings
    binding = next((b for b in bindings if b.bone == bone), None) or bindings.add()
    binding.bone, binding.curve, binding.use_drawing_speed = bone, curve, use_drawing_speed
    refresh(armature)


def unbind(armature, bone):
    """Remove the binding of a bone, by its present name or, for a deleted bone, its last one;
    False where there is none."""
    refresh(armature)
    bindings = armature.trajevae.bindings
    index = next((i for i, b in enumerate(bindings) if b.bone == bone), None)
    if index is None:
        return False
    bindings.remove(index)
    return True


def bone_joints(armature, bones):
    """{bone name: joint} of the bones a path can be bound to: those a joint is mapped to, and the
    rig's root, whose path is the hips' (on the floor, a ground path: the body walks along it): the
    bones above the hips, and a parentless bone named root (Rigify's ``root`` is no parent of its
    torso, which hangs from a parent-switch bone)."""
    joints = {bone: joint for joint, bone in bones.items() if bone}
    hips = armature.pose.bones.get(bones.get("Hip") or "")
    for above in (hips.parent_recursive if hips is not None else ()):
        joints.setdefault(above.name, "Hip")
    for bone in armature.pose.bones:
        if bone.parent is None and bone.name.lower() == "root":
            joints.setdefault(bone.name, "Hip")
    return joints


def mapped_bones_sentence(armature, bones):
    """Which bones can be bound: those a joint is mapped to and the root above the hips."""
    names = sorted(bone_joints(armature, bones))
    return f"bind one of the mapped bones ({', '.join(names)}) or map the bone under TrajeVAE > Rig Mapping"


def problem(armature, binding, bones):
    """Why a binding cannot be followed, in a few words for its row in the panel, or None."""
    bone = bone_of(armature, binding)
    if bone is None:
        return "bone deleted"
    if binding.curve is None:
        return "no curve"
    if bone not in bone_joints(armature, bones):
        return "bone not mapped"
    return None


def joint_paths(armature, bones):
    """({joint: (path object, use drawing speed)}, [warning sentence]): the armature's bindings
    (following bone renames), then any Follow Path or Clamp To constraint of a mapped bone (a
    native way to say "this bone follows this path"). A binding without a curve or whose bone
    was deleted is skipped with a warning; one on a bone no joint is mapped to is a RigError."""
    refresh(armature)
    joint_of = bone_joints(armature, bones)
    out, warnings = {}, []
    for binding in armature.trajevae.bindings:
        if binding.curve is None:
            warnings.append(f"the binding of {binding.bone!r} has no curve (deleted?) and was ignored")
            continue
        if binding.bone not in armature.pose.bones:
            warnings.append(f"bone {binding.bone!r}, bound to {binding.curve.name!r}, is no longer in "
                            f"{armature.name!r} (deleted?), so its binding was ignored")
            continue
        joint = joint_of.get(binding.bone)
        if joint is None:
            raise rig_state.RigError(f"bone {binding.bone!r} is bound to {binding.curve.name!r} but TrajeVAE "
                                     f"does not move it; {mapped_bones_sentence(armature, bones)}")
        out[joint] = (binding.curve, binding.use_drawing_speed)
    for joint, bone in bones.items():
        if bone and joint not in out:
            constraint = next(iter(path_constraints(armature, bone)), None)
            if constraint is not None:
                out[joint] = (constraint.target, True)
    return out, warnings


def path_constraints(armature, bone):
    """The bone's active Follow Path / Clamp To constraints that target a curve."""
    return [c for c in armature.pose.bones[bone].constraints
            if c.type in PATH_CONSTRAINTS and not c.mute and c.influence > 0 and c.target is not None
            and c.target.type == 'CURVE']


def muted_path_constraints(armature, bones):
    """{data path: 0.0} turning off the path constraints that served as bindings, so they do not
    pull the generated motion a second time (restored with the artist's action)."""
    return {c.path_from_id("influence"): 0.0 for bone in bones.values() if bone
            for c in path_constraints(armature, bone)}
