"""Which joints follow which drawn paths: the armature's bindings and its bones' path constraints."""

from . import rig_state

PATH_CONSTRAINTS = {'FOLLOW_PATH', 'CLAMP_TO'}


def joint_paths(armature, bones):
    """({joint: (path object, use drawing speed)}, [warning sentence]): the armature's bindings,
    then any Follow Path or Clamp To constraint of a mapped bone (a native way to say "this bone
    follows this path"); a binding without a curve is skipped with a warning."""
    joint_of = {bone: joint for joint, bone in bones.items() if bone}
    out, warnings = {}, []
    for binding in armature.trajevae.bindings:
        if binding.curve is None:
            warnings.append(f"the binding of {binding.bone!r} has no curve (deleted?) and was ignored")
            continue
        joint = joint_of.get(binding.bone)
        if joint is None:
            raise rig_state.RigError(f"bone {binding.bone!r} is bound to {binding.curve.name!r} but carries no "
                                     "joint; bind a mapped bone (hand, foot, ...)")
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
