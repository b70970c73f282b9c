"""Scripting API: the add-on's features for batch scripts and tests (synchronous, no UI).

Example (headless, see README)::

    import bpy, trajevae_addon
    from trajevae_addon import api
    trajevae_addon.register()
    rig = bpy.data.objects["Armature"]
    print(api.map_rig(rig))                      # {"Hip": "hips", "RHip": "thigh.R", ...}
    api.bind_curve(rig, "hand.L", bpy.data.objects["HandPath"])
    api.walk_along(rig, bpy.data.objects["FloorPath"])  # a path on the floor: the rig walks along it
    variants = api.generate_variants(rig, n=5, seed=0)
    api.set_active_variant(rig, variants[2])
    api.keep_variant(rig, variants[2])           # or api.restore_original(rig)
    api.use_weights("/studio/weights")           # a folder from model_runtime.train --out

Joint names are the canonical ones of ``model_runtime.skeleton.JOINT_NAMES``.
"""

import os

import bpy
import numpy as np

from . import bindings, inference, pipeline, preferences, rig_state, variants

PATH_TYPES = {'CURVE', 'GREASEPENCIL'}


def _object(obj, call, role):
    """The object's type; TypeError where ``obj`` is not a Blender object, ValueError where it was deleted."""
    if not isinstance(obj, bpy.types.Object):
        raise TypeError(f"{call} needs {role} object, not {obj!r}")
    try:
        return obj.type
    except ReferenceError:
        raise ValueError(f"{call} was given {role} object that has been deleted") from None


def _armature(obj, call, writes=False):
    """``obj`` if it is an armature object (whose bindings this file can keep, where ``writes``),
    else a sentence. Blender refuses new rows in an override's bindings, and a linked rig's would
    be lost on save; Object > Relations > Make Local turns either into a local rig."""
    kind = _object(obj, call, "an armature")
    if kind != 'ARMATURE':
        raise ValueError(f"{call} needs an armature, and {obj.name!r} is a {kind.lower()}")
    if writes and obj.library is not None:
        raise ValueError(f"{obj.name!r} is linked from {obj.library.filepath!r}, so its bindings would not be "
                         "saved; make it local first (Object > Relations > Make Local)")
    if writes and obj.override_library is not None:
        raise ValueError(f"{obj.name!r} is a library override, whose bindings Blender cannot store; make it "
                         "local first (Object > Relations > Make Local)")
    return obj


def map_rig(armature):
    """Canonical joint name -> bone name or None (detected, merged with the artist's overrides)."""
    return rig_state.mapping(_armature(armature, "map_rig"))


def bind_curve(armature, bone_name, curve_object, use_drawing_speed=True):
    """Make the joint carried by ``bone_name`` follow a Curve object or a Grease Pencil object's last
    stroke (at its drawing speed unless told not to); replaces an earlier binding of the bone,
    also one made before the bone was renamed."""
    _armature(armature, "bind_curve", writes=True)
    if not isinstance(bone_name, str):
        raise TypeError(f"bind_curve needs the bone's name as a string, not {bone_name!r}")
    if bone_name not in armature.pose.bones:
        raise ValueError(f"{armature.name!r} has no bone {bone_name!r}")
    kind = _object(curve_object, "bind_curve", "a curve or grease pencil")
    if kind not in PATH_TYPES:
        raise ValueError(f"{curve_object.name!r} is a {kind.lower()}, not a curve or grease pencil")
    if not isinstance(use_drawing_speed, (bool, np.bool_)):
        raise TypeError(f"use_drawing_speed must be True or False, not {use_drawing_speed!r}")
    bones = rig_state.mapping(armature)
    if bone_name not in bindings.bone_joints(armature, bones):
        raise ValueError(f"TrajeVAE does not move {bone_name!r} (no joint is mapped to it); "
                         f"{bindings.mapped_bones_sentence(armature, bones)}")
    bindings.bind(armature, bone_name, curve_object, bool(use_drawing_speed))


def walk_along(armature, curve_object, use_drawing_speed=True):
    """Make the rig walk along a path drawn on the floor: bind it to the hips' bone as a ground path
    (the hips' horizontal path; the model chooses the height, the steps and the body)."""
    hips = rig_state.mapping(_armature(armature, "walk_along", writes=True))["Hip"]
    if hips is None:
        raise ValueError(f"{armature.name!r} has no bone mapped to the hips; map one under TrajeVAE > Rig Mapping")
    bind_curve(armature, hips, curve_object, use_drawing_speed)


def unbind(armature, bone_name):
    """Remove the binding of ``bone_name`` (its present name, or the last one of a deleted bone)."""
    _armature(armature, "unbind", writes=True)
    if not isinstance(bone_name, str):
        raise TypeError(f"unbind needs the bone's name as a string, not {bone_name!r}")
    if not bindings.unbind(armature, bone_name):
        raise ValueError(f"no path is bound to {bone_name!r} on {armature.name!r}")


def generate_variants(armature, n=5, seed=0, diversity=1.0):
    """n new Actions over the scene frame range, listed on the armature; the first is assigned."""
    return pipeline.generate_variants(armature, n, seed, diversity).actions


def set_active_variant(armature, action):
    variants.set_active(armature, action)


def keep_variant(armature, action):
    variants.keep(armature, action)


def restore_original(armature):
    variants.restore_original(armature)


def use_weights(folder=None):
    """Generate with the weights folder ``folder`` (as ``python -m model_runtime.train --out FOLDER``
    writes it; None: the bundled weights) from now on, kept in the add-on's preferences where Blender
    has them. Returns the folder in use; ValueError (one sentence) where it cannot be used."""
    if folder is not None and not isinstance(folder, (str, os.PathLike)):
        raise TypeError(f"use_weights needs a folder path, not {folder!r}")
    used = inference.use_weights(folder)
    settings = preferences.get(bpy.context)
    if settings is not None:
        settings.weights_folder = "" if inference.bundled() else str(used)
    return str(used)
