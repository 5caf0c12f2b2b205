"""Relume: edit materials and see global illumination update live after one bake.

The Rust core (the bundled `relume` wheel) bakes a transfer stack of the scene's light
paths; this add-on exports the scene, runs the bake without freezing Blender, and relights
an Image Editor image named "Relume" whenever an editable material changes.
"""

from __future__ import annotations

from . import api, live, live_image  # noqa: F401  (api: the scripting API)
from .runtime import RUNTIME
from .ui import ops, panels, prefs, props

_CLASSES = prefs.CLASSES + ops.CLASSES + panels.CLASSES


def register() -> None:
    import bpy

    props.register()
    for c in _CLASSES:
        bpy.utils.register_class(c)
    live.register()
    # The relighter's OpenImageDenoise search starts with Blender's own copy.
    live_image.set_oidn_dirs()


def unregister() -> None:
    import bpy

    if RUNTIME.session is not None and not RUNTIME.session.finished:
        RUNTIME.session.cancel()
    live.unregister()
    for c in reversed(_CLASSES):
        bpy.utils.unregister_class(c)
    props.unregister()
    RUNTIME.live.unload()
