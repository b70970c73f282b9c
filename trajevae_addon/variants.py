"""The variant list on an armature: show one, keep one, or discard them all.

The artist's own action is recorded before the first variant is shown and is
never modified; discarding reassigns it (with its slot) and the rig switches
generation changed.
"""

import bpy

from . import rig_state


def assign(armature, action):
    """Play a variant ``action`` (one slot) on the armature."""
    animation = armature.animation_data or armature.animation_data_create()
    animation.action = action
    if animation.action_slot is None and len(action.slots):
        animation.action_slot = action.slots[0]


def record_original(armature, switch_values):
    """Remember the artist's action and rig switches once, before any variant is assigned."""
    settings = armature.trajevae
    if settings.has_original:
        return
    animation = armature.animation_data
    settings.original_action = animation.action if animation else None
    settings.original_slot = animation.action_slot.identifier if animation and animation.action_slot else ""
    settings.original_switches = rig_state.switches_to_json(switch_values)
    settings.has_original = True


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
        raise ValueError(f"{action.name!r} is not a variant of {armature.name!r}")
    settings.active_variant = index


def _forget(armature, keep=None):
    settings = armature.trajevae
    for action in listed(armature):
        if action != keep:
            bpy.data.actions.remove(action)
    settings.variants.clear()
    settings.has_original = False
    settings.original_action = None
    settings.original_slot = ""
    settings.original_switches = ""


def keep(armature, action):
    """Assign ``action`` for good and delete the other variants."""
    set_active(armature, action)
    assign(armature, action)
    _forget(armature, keep=action)


def restore_original(armature):
    """Delete every variant and give the rig back its own action and switches."""
    settings = armature.trajevae
    if not settings.has_original:
        return
    original, slot_identifier = settings.original_action, settings.original_slot
    rig_state.apply_switches(armature, rig_state.switches_from_json(settings.original_switches))
    animation = armature.animation_data
    if animation is not None:
        animation.action = original
        if original is not None and slot_identifier:
            slot = next((s for s in original.slots if s.identifier == slot_identifier), None)
            if slot is not None:
                animation.action_slot = slot
    _forget(armature)
