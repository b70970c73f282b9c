"""The add-on's preferences (Edit > Preferences > Add-ons > TrajeVAE): the weights folder to generate with."""

import bpy
from bpy.props import StringProperty

from . import inference

# The add-on's module: the extension's package when installed (this package's parent), this
# package when registered from the repository.
ADDON_ID = __package__.rpartition(".")[0] or __package__


def _weights_folder_changed(preferences, _context):
    """Use the folder picked (empty: the bundled weights); one that cannot be used is said in the
    preferences and the panel (``inference.refused``), the weights in use unchanged."""
    try:
        inference.use_weights(bpy.path.abspath(preferences.weights_folder) or None)
    except inference.WeightsError:
        pass


class TRAJEVAE_AP_preferences(bpy.types.AddonPreferences):
    bl_idname = ADDON_ID

    weights_folder: StringProperty(
        name="Weights folder", subtype='DIR_PATH', update=_weights_folder_changed,
        description="A folder written by python -m model_runtime.train --out FOLDER (a model trained or fine-tuned "
                    "on your own motion library); empty for the bundled weights")

    def draw(self, context):
        draw_weights(self.layout)
        self.layout.prop(self, "weights_folder")


def draw_weights(layout):
    """Which weights generate, and why a folder picked was refused."""
    if inference.bundled():
        layout.label(text="Weights: bundled", icon='CHECKMARK')
    else:
        layout.label(text=f"Weights: {inference.in_use()}", icon='FILE_FOLDER')
    if inference.refused():
        layout.label(text=inference.refused(), icon='ERROR')


def get(context):
    """The add-on's preferences, or None where Blender keeps none for it (registered by a script)."""
    addon = context.preferences.addons.get(ADDON_ID)
    return addon.preferences if addon is not None else None


def register():
    bpy.utils.register_class(TRAJEVAE_AP_preferences)
    preferences = get(bpy.context)
    if preferences is not None and preferences.weights_folder:
        _weights_folder_changed(preferences, bpy.context)


def unregister():
    bpy.utils.unregister_class(TRAJEVAE_AP_preferences)
