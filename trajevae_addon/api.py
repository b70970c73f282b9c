"""Scripting API: the add-on's features for batch scripts and tests (synchronous, no UI).

Example (headless, see README)::

    import bpy, trajevae_addon
    from trajevae_addon import api
    trajevae_addon.register()
    rig = bpy.data.objects["Armature"]
    print(api.map_rig(rig))                      # {"Hip": "hips", "RHip": "thigh.R", ...}
    api.bind_curve(rig, "hand.L", bpy.data.objects["HandPath"])
    variants = api.generate_variants(rig, n=5, seed=0)
    api.set_active_variant(rig, variants[2])
    api.keep_variant(rig, variants[2])           # or api.restore_original(rig)

Joint names are the canonical ones of ``model_runtime.skeleton.JOINT_NAMES``.
"""

from . import pipeline, rig_state, variants


def map_rig(armature):
    """Canonical joint name -> bone name or None (detected, merged with the artist's overrides)."""
    return rig_state.mapping(armature)


def bind_curve(armature, bone_name, curve_object, use_drawing_speed=True):
    """Make the joint carried by ``bone_name`` follow a Curve object or a Grease Pencil object's last
    stroke (at its drawing speed unless told not to); replaces an earlier binding of the bone."""
    if bone_name not in armature.pose.bones:
        raise ValueError(f"{armature.name!r} has no bone {bone_name!r}")
    if curve_object is not None and curve_object.type not in {'CURVE', 'GREASEPENCIL'}:
        raise ValueError(f"{curve_object.name!r} is a {curve_object.type.lower()}, not a curve or grease pencil")
    bindings = armature.trajevae.bindings
    existing = next((b for b in bindings if b.bone == bone_name), None)
    binding = existing or bindings.add()
    binding.bone, binding.curve, binding.use_drawing_speed = bone_name, curve_object, use_drawing_speed


def unbind(armature, bone_name):
    bindings = armature.trajevae.bindings
    index = next((i for i, b in enumerate(bindings) if b.bone == bone_name), None)
    if index is not None:
        bindings.remove(index)


def generate_variants(armature, n=5, seed=0, diversity=1.0):
    """n new Actions over the scene frame range, listed on the armature; the first is assigned."""
    return pipeline.generate_variants(armature, n, seed, diversity).actions


def set_active_variant(armature, action):
    variants.set_active(armature, action)


def keep_variant(armature, action):
    variants.keep(armature, action)


def restore_original(armature):
    variants.restore_original(armature)
