"""Generated motion as Actions (Blender 5.0 slotted actions, keys set in bulk), from the channels
of ``retarget.key_channels``; main thread only."""

import bpy
import numpy as np
from bpy_extras import anim_utils


def slot_name(armature):
    """One slot name shared by every variant of a rig, so swapping actions keeps the slot."""
    return armature.name


def _curve(channelbag, path, index, group, frames, values, sampled=False):
    fcurve = channelbag.fcurves.new(path, index=index, group_name=group)
    fcurve.keyframe_points.add(len(frames))
    fcurve.keyframe_points.foreach_set("co", np.column_stack([frames, values]).astype(np.float32).ravel())
    if sampled:
        fcurve.convert_to_samples(int(frames[0]), int(frames[-1]))
    else:
        fcurve.update()


def new(armature, name):
    """(action, channelbag): an empty Action (fake user set) with the rig's slot."""
    action = bpy.data.actions.new(name)
    action.use_fake_user = True
    slot = action.slots.new(id_type='OBJECT', name=slot_name(armature))
    return action, anim_utils.action_ensure_channelbag_for_slot(action, slot)


def add_channels(armature, channelbag, frames, channels, sampled=False):
    """F-curves keyed on ``frames`` (F,) for ``retarget.key_channels`` output, or baked samples (a sixth of
    a key's memory, made into keys by Graph Editor > Channel > Samples to Keys)."""
    frames = np.asarray(frames, dtype=np.float64)
    for bone, prop, values in channels:
        path = armature.pose.bones[bone].path_from_id(prop)
        for index in range(values.shape[1]):
            _curve(channelbag, path, index, bone, frames, values[:, index], sampled)


def add_switches(channelbag, frames, switches):
    """Switches {data path: value} held from the first frame."""
    for path, value in switches.items():  # e.g. 'pose.bones["thigh_parent.L"]["IK_FK"]'
        _curve(channelbag, path, 0, path.split('"')[1], np.asarray(frames[:1], np.float64), np.array([value]))


def write(armature, name, frames, channels, switches):
    """A new Action (fake user set) keyed on ``frames`` (F,) with ``retarget.key_channels`` output, and the
    switches {data path: value} held from the first frame."""
    action, channelbag = new(armature, name)
    try:
        add_channels(armature, channelbag, frames, channels)
        add_switches(channelbag, frames, switches)
    except BaseException:
        bpy.data.actions.remove(action)
        raise
    return action


def fcurves(action):
    """Every F-curve of every slot of an action (none for None)."""
    if action is None:
        return
    for layer in action.layers:
        for strip in layer.strips:
            for bag in strip.channelbags:
                yield from bag.fcurves


def samples_to_keys(action):
    """Turn an action's baked samples into keys, in place."""
    for fcurve in fcurves(action):
        if len(fcurve.sampled_points):
            first, last = fcurve.sampled_points[0].co[0], fcurve.sampled_points[-1].co[0]
            fcurve.convert_to_keyframes(int(first), int(last))
