"""Everything TrajeVAE stores on an armature object (saved with the .blend): ``Object.trajevae``."""

import bpy
from bpy.props import (BoolProperty, CollectionProperty, FloatProperty, IntProperty, PointerProperty,
                       StringProperty)
from bpy.types import PropertyGroup

from .runtime import skeleton


def _is_path(_, obj):
    return obj.type in {'CURVE', 'GREASEPENCIL'}


def _switch_variant(settings, context):
    """Show the variant the artist clicked in the list."""
    from . import variants
    armature = settings.id_data
    if 0 <= settings.active_variant < len(settings.variants):
        action = settings.variants[settings.active_variant].action
        if action is not None:
            variants.assign(armature, action)


TRAJEVAE_PG_joint_bones = type("TRAJEVAE_PG_joint_bones", (PropertyGroup,), {
    "__doc__": "The artist's bone for each canonical joint; empty means detected automatically.",
    "__annotations__": {joint: StringProperty(name=joint, description=f"Bone keyed for the {joint} joint")
                        for joint in skeleton.JOINT_NAMES},
})


class TRAJEVAE_PG_binding(PropertyGroup):
    """A drawn path that a bone's joint follows over the scene frame range."""

    bone: StringProperty(name="Bone", description="Pose bone that follows the path")
    curve: PointerProperty(name="Path", type=bpy.types.Object, poll=_is_path,
                           description="Curve object or Grease Pencil stroke, followed from its first point")
    use_drawing_speed: BoolProperty(name="Drawing speed", default=True,
                                    description="Follow a stroke at the speed it was drawn (else evenly)")
    bone_tag: StringProperty(description="The tag this binding put on its pose bone, which follows "
                                         "renames (see bindings.py)")

    @classmethod
    def register(cls):
        """The bone side of the tag, registered with the binding that sets it (a registered
        property, unlike a custom one, is not listed among the artist's custom properties)."""
        bpy.types.PoseBone.trajevae_tag = StringProperty(description="TrajeVAE binding tag, kept across renames")

    @classmethod
    def unregister(cls):
        del bpy.types.PoseBone.trajevae_tag


class TRAJEVAE_PG_variant(PropertyGroup):
    action: PointerProperty(name="Action", type=bpy.types.Action)
    curve_error_m: FloatProperty(name="Curve error", unit='LENGTH',
                                 description="Mean distance of the bound joints to their curves")
    difference_m: FloatProperty(name="Difference", unit='LENGTH',
                                description="Mean joint distance to the nearest other variant")


class TRAJEVAE_PG_settings(PropertyGroup):
    mapping: PointerProperty(type=TRAJEVAE_PG_joint_bones)
    bindings: CollectionProperty(type=TRAJEVAE_PG_binding)
    active_binding: IntProperty(name="Active binding")
    variants: CollectionProperty(type=TRAJEVAE_PG_variant)
    active_variant: IntProperty(name="Active variant", update=_switch_variant)
    variant_count: IntProperty(name="Variants", default=5, min=1, max=50,
                               description="How many different motions to generate")
    seed: IntProperty(name="Seed", default=0, min=0, description="Same seed, same variants")
    diversity: FloatProperty(name="Diversity", default=1.0, min=0.0, max=2.0,
                             description="0 gives the most likely motion; higher values spread the variants")
    has_original: BoolProperty(description="The artist's own action is recorded and restorable")
    original_action: PointerProperty(type=bpy.types.Action)
    original_slot: StringProperty(description="Identifier of the original action's slot")
    original_switches: StringProperty(description="JSON of rig switch values before generation")
    original_pose: StringProperty(description="JSON of every pose bone's channels before generation")
    previous_action: PointerProperty(type=bpy.types.Action, name="Previous action",
                                     description="The artist's action before the last Keep (kept with a fake user)")
    last_report: StringProperty(description="What the last generation wants the artist to know, one line each")


CLASSES = (TRAJEVAE_PG_joint_bones, TRAJEVAE_PG_binding, TRAJEVAE_PG_variant, TRAJEVAE_PG_settings)
_register_classes, _unregister_classes = bpy.utils.register_classes_factory(CLASSES)


def register():
    _register_classes()
    bpy.types.Object.trajevae = PointerProperty(type=TRAJEVAE_PG_settings)


def unregister():
    del bpy.types.Object.trajevae
    _unregister_classes()
