"""TrajeVAE for Blender: curves drawn in the viewport become full-body motion variants.

The Blender layer: properties, operators, panels, reading rigs and curves,
writing Actions. The model and all math live in ``model_runtime`` (no bpy),
imported through ``runtime``.
"""

from . import mannequin, operators, preferences, properties, ui

_MODULES = (preferences, properties, operators, mannequin, ui)


def register():
    for module in _MODULES:
        module.register()


def unregister():
    from . import inference
    for module in reversed(_MODULES):
        module.unregister()
    inference.release()
