"""Sidebar panels in the 3D View (N panel, "TrajeVAE" tab)."""

import bpy

from . import bindings, inference, preferences, rig_mapping, rig_state
from .runtime import skeleton


class TRAJEVAE_UL_bindings(bpy.types.UIList):
    def draw_item(self, context, layout, data, item, icon, active_data, active_property, index=0, flt_flag=0):
        """The bone (by its present name) and its path; a binding that cannot be followed is drawn in
        red with the reason, and its empty path field lets the artist pick a new one."""
        armature = data.id_data
        problem = bindings.problem(armature, item, rig_state.mapping(armature))
        row = layout.row(align=True)
        row.alert = problem is not None
        bone = bindings.bone_of(armature, item) or item.bone
        row.label(text=f"{bone} ({problem})" if problem else bone, icon='ERROR' if problem else 'BONE_DATA')
        row.prop(item, "curve", text="")
        if item.curve is not None and item.curve.type == 'GREASEPENCIL':
            row.prop(item, "use_drawing_speed", text="", icon='TIME')


class TRAJEVAE_UL_variants(bpy.types.UIList):
    def draw_item(self, context, layout, data, item, icon, active_data, active_property, index=0, flt_flag=0):
        row = layout.row()
        row.label(text=item.action.name if item.action else "(deleted)", icon='ACTION')
        row.label(text=f"curve {100 * item.curve_error_m:.1f} cm  apart {100 * item.difference_m:.0f} cm")


class _SidebarPanel:
    bl_space_type = 'VIEW_3D'
    bl_region_type = 'UI'
    bl_category = "TrajeVAE"


class TRAJEVAE_PT_main(_SidebarPanel, bpy.types.Panel):
    bl_label = "TrajeVAE Motion"

    def draw(self, context):
        layout = self.layout
        armature = rig_state.active_armature(context)
        if armature is None:
            layout.label(text="Select an armature", icon='INFO')
            layout.operator("trajevae.add_mannequin", icon='ARMATURE_DATA')
            return
        settings = armature.trajevae
        profile, _ = rig_state.detected(armature)
        gaps = rig_mapping.missing(rig_state.mapping(armature))
        box = layout.box()
        box.label(text=f"Rig: {armature.name} ({profile})", icon='ARMATURE_DATA')
        if gaps:
            box.label(text=f"Unmapped: {', '.join(gaps)}", icon='ERROR')
            box.label(text="Fix them under Rig Mapping below")
        if not inference.torch_installed():
            box.label(text="Runs on numpy: torch is not needed here", icon='CHECKMARK')
        preferences.draw_weights(box)

        walk = layout.row()
        walk.scale_y = 1.2
        walk.operator("trajevae.walk_along_path", icon='CURVE_PATH')
        layout.label(text="Paths (bone follows curve or stroke)")
        row = layout.row()
        row.template_list("TRAJEVAE_UL_bindings", "", settings, "bindings", settings, "active_binding", rows=2)
        column = row.column(align=True)
        column.operator("trajevae.bind_curve", icon='ADD', text="")
        column.operator("trajevae.unbind", icon='REMOVE', text="")
        bones = rig_state.mapping(armature)
        listed = {bindings.bone_of(armature, b) for b in settings.bindings}
        for bone in bones.values():
            if bone and bone not in listed:
                for constraint in bindings.path_constraints(armature, bone):
                    layout.label(text=f"{bone} follows {constraint.target.name} ({constraint.name})",
                                 icon='CON_FOLLOWPATH')
        if not len(settings.bindings) and not any(bindings.path_constraints(armature, b) for b in bones.values()
                                                  if b):
            layout.label(text="No paths: diverse motions from the current pose", icon='INFO')
            layout.label(text="Or draw a path on the floor, select it and Walk Along Selected Path")

        column = layout.column(align=True)
        column.prop(settings, "variant_count")
        column.prop(settings, "seed")
        column.prop(settings, "diversity", slider=True)
        generate = layout.row()
        generate.scale_y = 1.4
        generate.operator("trajevae.generate", text=f"Generate {settings.variant_count} Variants", icon='PLAY')

        if len(settings.variants):
            layout.label(text="Variants")
            layout.template_list("TRAJEVAE_UL_variants", "", settings, "variants", settings, "active_variant",
                                 rows=3)
            row = layout.row(align=True)
            row.operator("trajevae.step_variant", text="", icon='TRIA_LEFT').step = -1
            row.operator("trajevae.step_variant", text="", icon='TRIA_RIGHT').step = 1
            row.operator("trajevae.keep_variant", icon='CHECKMARK')
            row.operator("trajevae.discard_variants", icon='X')
        for line in filter(None, settings.last_report.split("\n")):
            layout.label(text=line, icon='ERROR')
        if settings.previous_action is not None:
            layout.label(text=f"Previous action: {settings.previous_action.name} (kept in the file)", icon='ACTION')


class TRAJEVAE_PT_mapping(_SidebarPanel, bpy.types.Panel):
    bl_label = "Rig Mapping"
    bl_parent_id = "TRAJEVAE_PT_main"
    bl_options = {'DEFAULT_CLOSED'}

    @classmethod
    def poll(cls, context):
        return rig_state.active_armature(context) is not None

    def draw(self, context):
        armature = rig_state.active_armature(context)
        _, detected = rig_state.detected(armature)
        layout = self.layout
        layout.label(text="Empty fields use the detected bone")
        for joint in skeleton.JOINT_NAMES:
            row = layout.row(align=True)
            row.prop_search(armature.trajevae.mapping, joint, armature.data, "bones", text=joint)
            if not getattr(armature.trajevae.mapping, joint):
                row.label(text=detected[joint] or "-")
        found = rig_state.clavicles(armature, rig_state.mapping(armature))
        layout.label(text="Clavicles, keyed too: " + (", ".join(sorted(found.values())) or "none found"))


CLASSES = (TRAJEVAE_UL_bindings, TRAJEVAE_UL_variants, TRAJEVAE_PT_main, TRAJEVAE_PT_mapping)
register, unregister = bpy.utils.register_classes_factory(CLASSES)
