"""Generated motion as Actions (Blender 5.0 slotted actions, keys set in bulk).

``key_channels`` is plain numpy (the worker thread computes it); ``write``
touches bpy and runs on the main thread.
"""

import bpy
import numpy as np
from bpy_extras import anim_utils

from .runtime import rotations


def slot_name(armature):
    """One slot name shared by every variant of a rig, so swapping actions keeps the slot."""
    return armature.name


def _rotation_channel(mode, matrices):
    """(property, values (F, C)) of rotations (F, 3, 3) in a bone's ``mode``."""
    if mode == 'QUATERNION':
        return "rotation_quaternion", rotations.continuous(rotations.from_matrix(matrices))
    if mode == 'AXIS_ANGLE':
        return "rotation_axis_angle", rotations.to_axis_angle(rotations.continuous(rotations.from_matrix(matrices)))
    return "rotation_euler", rotations.to_euler(matrices, mode)


def key_channels(bases, rotation_modes, root_bone):
    """[(bone, property, values (F, C) float32)] from each bone's matrix_basis (F, 4, 4): rotation
    in the bone's own mode ({bone: mode}) for every bone, location for the root."""
    out = []
    for bone, basis in bases.items():
        rotation = basis[:, :3, :3] / np.linalg.norm(basis[:, :3, :3], axis=1, keepdims=True)
        out.append((bone, *_rotation_channel(rotation_modes[bone], rotation)))
        if bone == root_bone:
            out.append((bone, "location", basis[:, :3, 3]))
    return [(bone, prop, np.asarray(values, dtype=np.float32)) for bone, prop, values in out]


def _curve(channelbag, path, index, group, frames, values):
    fcurve = channelbag.fcurves.new(path, index=index, group_name=group)
    fcurve.keyframe_points.add(len(frames))
    fcurve.keyframe_points.foreach_set("co", np.column_stack([frames, values]).astype(np.float32).ravel())
    fcurve.update()


def write(armature, name, frames, channels, switches):
    """A new Action (fake user set) keyed on ``frames`` (F,) with ``key_channels`` output, and the
    switches {data path: value} held from the first frame."""
    action = bpy.data.actions.new(name)
    try:
        action.use_fake_user = True
        slot = action.slots.new(id_type='OBJECT', name=slot_name(armature))
        channelbag = anim_utils.action_ensure_channelbag_for_slot(action, slot)
        frames = np.asarray(frames, dtype=np.float64)
        for bone, prop, values in channels:
            path = armature.pose.bones[bone].path_from_id(prop)
            for index in range(values.shape[1]):
                _curve(channelbag, path, index, bone, frames, values[:, index])
        for path, value in switches.items():  # e.g. 'pose.bones["thigh_parent.L"]["IK_FK"]'
            _curve(channelbag, path, 0, path.split('"')[1], frames[:1], np.array([value]))
    except BaseException:
        bpy.data.actions.remove(action)
        raise
    return action
