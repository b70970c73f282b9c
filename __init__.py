"""Blender extension entry point: the add-on lives in ``trajevae_addon``; its API is ``.trajevae_addon.api``."""

from . import trajevae_addon


def register():
    trajevae_addon.register()


def unregister():
    trajevae_addon.unregister()
