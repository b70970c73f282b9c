"""Writing generated motion as a new Action (Blender 5.0 slotted actions, keys set in bulk)."""

import bpy
import numpy as np
from bpy_extras import anim_utils

from .runtime import rotations


def slot_name(armature):
    """One slot name shared by every variant of a rig, so swapping actions keeps the slot."""
    return armature.name


def _rotation_channels(pose_bone, matrices):
    """(data path, values (F, C)) of a bone's rotation in its own rotation mode from (F, 3, 3)."""
    mode = pose_bone.rotation_mode
    if mode == 'QUATERNION':
        return "rotation_quaternion", rotations.continuous(rotations.from_matrix(matrices))
    if mode == 'AXIS_ANGLE':
        return "rotation_axis_angle", rotations.to_axis_angle(rotations.continuous(rotations.from_matrix(matrices)))
    return "rotation_euler", rotations.to_euler(matrices, mode)


def _curve(channelbag, path, index, group, frames, values):
    fcurve = channelbag.fcurves.new(path, index=index, group_name=group)
    fcurve.keyframe_points.add(len(frames))
    fcurve.keyframe_points.foreach_set("co", np.column_stack([frames, values]).astype(np.float32).ravel())
    fcurve.update()


def write(armature, name, frames, bases, root_bone, switches):
    """A new Action (fake user set) with keys on ``frames`` (F,) for each bone's matrix_basis (F, 4, 4):
    rotation for every bone, location for the root; switches {data path: value} held."""
    action = bpy.data.actions.new(name)
    action.use_fake_user = True
    slot = action.slots.new(id_type='OBJECT', name=slot_name(armature))
    channelbag = anim_utils.action_ensure_channelbag_for_slot(action, slot)
    frames = np.asarray(frames, dtype=np.float64)
    for bone, basis in bases.items():
        pose_bone = armature.pose.bones[bone]
        rotation = basis[:, :3, :3] / np.linalg.norm(basis[:, :3, :3], axis=1, keepdims=True)
        path, values = _rotation_channels(pose_bone, rotation)
        channels = [(path, values)]
        if bone == root_bone:
            channels.append(("location", basis[:, :3, 3]))
        for prop, channel_values in channels:
            for index in range(channel_values.shape[1]):
                _curve(channelbag, pose_bone.path_from_id(prop), index, bone, frames, channel_values[:, index])
    for path, value in switches.items():  # e.g. 'pose.bones["thigh_parent.L"]["IK_FK"]'
        _curve(channelbag, path, 0, path.split('"')[1], frames[:1], np.array([value]))
    return action
