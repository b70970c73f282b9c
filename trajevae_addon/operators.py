"""Operators: generate, cycle, keep and discard variants; bind and unbind curves."""

import threading
import traceback

import bpy
from bpy.props import IntProperty

from . import api, pipeline, rig_state, variants


class _ArmatureOperator:
    @classmethod
    def poll(cls, context):
        return rig_state.active_armature(context) is not None


class TRAJEVAE_OT_generate(bpy.types.Operator):
    """Generate N full-body motions over the scene frame range that follow the bound curves and keys.
    The networks run in a worker while the interface stays live; Esc cancels and writes nothing"""

    bl_idname = "trajevae.generate"
    bl_label = "Generate Variants"
    bl_options = {'REGISTER', 'UNDO'}

    _job = None
    _armature_name = ""
    _worker = None
    _writer = None
    _error = None
    _timer = None

    @classmethod
    def poll(cls, context):
        reason = rig_state.unusable_reason(rig_state.active_armature(context))
        if reason:
            cls.poll_message_set(reason[0].upper() + reason[1:])
        return reason is None

    def _start(self, context):
        armature = rig_state.active_armature(context)
        self._armature_name = armature.name  # the artist may select something else meanwhile
        settings = armature.trajevae
        try:
            self._job = pipeline.prepare(armature, settings.variant_count, settings.seed, settings.diversity,
                                         context.scene)
        except pipeline.USER_ERRORS as error:
            self.report({'ERROR'}, str(error))
            return False
        return True

    def _armature(self):
        armature = bpy.data.objects.get(self._armature_name)
        if armature is None:
            raise rig_state.RigError(f"{self._armature_name!r} was deleted or renamed during generation; "
                                     "nothing was written")
        return armature

    def _done(self, report):
        errors = ", ".join(f"{100 * e:.1f}" for e in report.curve_error_m)
        self.report({'INFO'}, f"{len(report.actions)} variants in {sum(report.seconds.values()):.2f} s"
                              + (f"; curve error as played (cm): {errors}" if self._job.request.curves else ""))
        for warning in report.warnings:
            self.report({'WARNING'}, warning)
        return {'FINISHED'}

    def _failed(self, error):
        """Undo whatever was written and say why in one sentence."""
        if self._writer is not None:
            self._writer.rollback()
        if not isinstance(error, pipeline.USER_ERRORS):
            traceback.print_exception(error)  # a fault of the add-on: details for the console
        self.report({'ERROR'}, f"generation failed, nothing was written: {error}")
        return {'CANCELLED'}

    def execute(self, context):  # scripts and headless runs: synchronous
        if not self._start(context):
            return {'CANCELLED'}
        try:
            pipeline.infer(self._job)
            return self._done(pipeline.finish(self._job, self._armature()))
        except Exception as error:
            return self._failed(error)

    def invoke(self, context, event):
        if not self._start(context):
            return {'CANCELLED'}

        def work():
            try:
                pipeline.infer(self._job)
            except pipeline.Cancelled:
                pass
            except Exception as error:  # shown to the artist by modal()
                self._error = error

        self._worker = threading.Thread(target=work, daemon=True)
        self._worker.start()
        window_manager = context.window_manager
        self._timer = window_manager.event_timer_add(0.1, window=context.window)
        window_manager.progress_begin(0.0, 1.0)
        window_manager.modal_handler_add(self)
        return {'RUNNING_MODAL'}

    def modal(self, context, event):
        if event.type == 'ESC':
            self._job.cancel_event.set()
            self._worker.join()
            if self._writer is not None:
                self._writer.rollback()
            self._stop(context)
            self.report({'INFO'}, "generation cancelled; nothing was written")
            return {'CANCELLED'}
        if event.type != 'TIMER':
            return {'PASS_THROUGH'}
        if not self._worker.is_alive():
            try:
                if self._error is not None:
                    raise self._error
                if self._writer is None:
                    self._writer = pipeline.Writer(self._job, self._armature())
                self._writer.step()
            except Exception as error:
                self._stop(context)
                return self._failed(error)
        progress = self._writer.progress if self._writer is not None else self._job.progress
        context.window_manager.progress_update(progress)
        context.workspace.status_text_set(f"TrajeVAE: generating {self._job.count} variants "
                                          f"{100 * progress:.0f}% (Esc to cancel)")
        if self._writer is None or not self._writer.done:
            return {'RUNNING_MODAL'}
        self._stop(context)
        return self._done(self._writer.report)

    def _stop(self, context):
        window_manager = context.window_manager
        window_manager.event_timer_remove(self._timer)
        window_manager.progress_end()
        context.workspace.status_text_set(None)


class TRAJEVAE_OT_step_variant(_ArmatureOperator, bpy.types.Operator):
    """Show the previous or next variant"""

    bl_idname = "trajevae.step_variant"
    bl_label = "Step Variant"
    bl_options = {'REGISTER', 'UNDO'}

    step: IntProperty(default=1)

    def execute(self, context):
        settings = rig_state.active_armature(context).trajevae
        if not len(settings.variants):
            return {'CANCELLED'}
        settings.active_variant = (settings.active_variant + self.step) % len(settings.variants)
        return {'FINISHED'}


class TRAJEVAE_OT_keep_variant(_ArmatureOperator, bpy.types.Operator):
    """Keep the shown variant as the rig's action and delete the other variants"""

    bl_idname = "trajevae.keep_variant"
    bl_label = "Keep"
    bl_options = {'REGISTER', 'UNDO'}

    def execute(self, context):
        armature = rig_state.active_armature(context)
        settings = armature.trajevae
        if not 0 <= settings.active_variant < len(settings.variants):
            self.report({'ERROR'}, "no variant to keep")
            return {'CANCELLED'}
        kept = settings.variants[settings.active_variant].action
        variants.keep(armature, kept)
        previous = settings.previous_action
        self.report({'INFO'}, f"kept {kept.name!r}" + (f"; the previous action {previous.name!r} stays in the file "
                                                        "(fake user)" if previous is not None else ""))
        return {'FINISHED'}


class TRAJEVAE_OT_discard_variants(_ArmatureOperator, bpy.types.Operator):
    """Delete every variant and give the rig back its own action"""

    bl_idname = "trajevae.discard_variants"
    bl_label = "Discard"
    bl_options = {'REGISTER', 'UNDO'}

    def execute(self, context):
        variants.restore_original(rig_state.active_armature(context))
        return {'FINISHED'}


class TRAJEVAE_OT_bind_curve(_ArmatureOperator, bpy.types.Operator):
    """Make the active bone follow the selected curve object or grease pencil stroke"""

    bl_idname = "trajevae.bind_curve"
    bl_label = "Bind Selected Path"
    bl_options = {'REGISTER', 'UNDO'}

    def execute(self, context):
        armature = rig_state.active_armature(context)
        bone = armature.data.bones.active
        curve = next((obj for obj in context.selected_objects if obj.type in {'CURVE', 'GREASEPENCIL'}), None)
        if bone is None or curve is None:
            self.report({'ERROR'}, "select a curve or grease pencil, then the armature with the bone to bind "
                                   "active")
            return {'CANCELLED'}
        try:
            api.bind_curve(armature, bone.name, curve)
        except ValueError as error:
            self.report({'ERROR'}, str(error))
            return {'CANCELLED'}
        return {'FINISHED'}


class TRAJEVAE_OT_walk_along_path(_ArmatureOperator, bpy.types.Operator):
    """Make the rig walk along the selected curve or stroke drawn on the floor: its hips follow the
    path across the floor, the model chooses their height, the steps and the body"""

    bl_idname = "trajevae.walk_along_path"
    bl_label = "Walk Along Selected Path"
    bl_options = {'REGISTER', 'UNDO'}

    def execute(self, context):
        armature = rig_state.active_armature(context)
        curve = next((obj for obj in context.selected_objects if obj.type in {'CURVE', 'GREASEPENCIL'}), None)
        if curve is None:
            self.report({'ERROR'}, "draw a path on the floor (a curve or grease pencil stroke), select it, then the "
                                   "armature")
            return {'CANCELLED'}
        try:
            api.walk_along(armature, curve)
        except ValueError as error:
            self.report({'ERROR'}, str(error))
            return {'CANCELLED'}
        return {'FINISHED'}


class TRAJEVAE_OT_unbind(_ArmatureOperator, bpy.types.Operator):
    """Remove the selected binding"""

    bl_idname = "trajevae.unbind"
    bl_label = "Unbind"
    bl_options = {'REGISTER', 'UNDO'}

    def execute(self, context):
        settings = rig_state.active_armature(context).trajevae
        if 0 <= settings.active_binding < len(settings.bindings):
            settings.bindings.remove(settings.active_binding)
            settings.active_binding = max(0, settings.active_binding - 1)
        return {'FINISHED'}


CLASSES = (TRAJEVAE_OT_generate, TRAJEVAE_OT_step_variant, TRAJEVAE_OT_keep_variant,
           TRAJEVAE_OT_discard_variants, TRAJEVAE_OT_bind_curve, TRAJEVAE_OT_walk_along_path, TRAJEVAE_OT_unbind)
register, unregister = bpy.utils.register_classes_factory(CLASSES)
