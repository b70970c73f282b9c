"""The variant list on an armature: show one, keep one, or discard them all.

Before the first variant is shown, the artist's own action, its slot, the rig
switches and every pose channel are recorded; the artist's action is never
modified or deleted. Discarding puts all of it back exactly; keeping assigns
the variant and leaves the artist's action in the file with a fake user,
named on the armature as its previous action.
"""

import json

import bpy

from . import actions, rig_state


def assign(armature, action):
    """Play a variant ``action`` (one slot) on the armature."""
    animation = armature.animation_data or armature.animation_data_create()
    animation.action = action
    if animation.action_slot is None and len(action.slots):
        animation.action_slot = action.slots[0]


def record_original(armature, switch_values):
    """Remember the artist's action, rig switches and pose once, before any variant is assigned.
    True when this call recorded them (False when they already were)."""
    settings = armature.trajevae
    if settings.has_original:
        return False
    animation = armature.animation_data
    settings.original_action = animation.action if animation else None
    settings.original_slot = animation.action_slot.identifier if animation and animation.action_slot else ""
    settings.original_switches = rig_state.switches_to_json(switch_values)
    settings.original_pose = json.dumps(rig_state.pose_snapshot(armature))
    settings.has_original = True
    return True


def forget_original(armature):
    """Drop the record of the artist's state (it is theirs again, or nothing was shown)."""
    settings = armature.trajevae
    settings.has_original = False
    settings.original_action = None
    settings.original_slot = ""
    settings.original_switches = ""
    settings.original_pose = ""


def add(armature, new_actions, curve_errors, differences):
    """Append generated actions (with their curve error and distance to the nearest other variant,
    metres) to the list and show the first of them."""
    settings = armature.trajevae
    first = len(settings.variants)
    for action, error, difference in zip(new_actions, curve_errors, differences):
        item = settings.variants.add()
        item.action, item.curve_error_m, item.difference_m = action, error, difference
    settings.active_variant = first  # its update callback assigns the action


def listed(armature):
    return [item.action for item in armature.trajevae.variants if item.action is not None]


def set_active(armature, action):
    settings = armature.trajevae
    index = next((i for i, item in enumerate(settings.variants) if item.action == action), None)
    if index is None:
        raise ValueError(f"{getattr(action, 'name', action)!r} is not a variant of {armature.name!r}")
    settings.active_variant = index


def _delete_variants(armature, keep=None):
    for action in listed(armature):
        if action != keep:
            bpy.data.actions.remove(action)
    armature.trajevae.variants.clear()
    armature.trajevae.last_report = ""


def keep(armature, action):
    """Assign ``action`` for good and delete the other variants; the artist's own action stays in
    the file (fake user) as the armature's previous action."""
    set_active(armature, action)
    assign(armature, action)
    actions.samples_to_keys(action)
    settings = armature.trajevae
    original = settings.original_action
    if original is not None:
        original.use_fake_user = True
    settings.previous_action = original
    _delete_variants(armature, keep=action)
    forget_original(armature)


def restore_original(armature):
    """Delete every variant and give the rig back its own action, slot, switches and pose."""
    settings = armature.trajevae
    if not settings.has_original:
        return
    original, slot_identifier = settings.original_action, settings.original_slot
    animation = armature.animation_data
    if animation is not None:
        animation.action = original
        if original is not None and slot_identifier:
            slot = next((s for s in original.slots if s.identifier == slot_identifier), None)
            if slot is not None:
                animation.action_slot = slot
    rig_state.apply_switches(armature, rig_state.switches_from_json(settings.original_switches))
    if settings.original_pose:
        rig_state.restore_pose(armature, json.loads(settings.original_pose))
    _delete_variants(armature)
    forget_original(armature)
    if original is not None:  # its keyed channels show the current frame again
        bpy.context.scene.frame_set(bpy.context.scene.frame_current)
