"""Loading the scene's stack and checking that it still matches the scene."""

from __future__ import annotations

import os

import bpy

from ..live_image import IMAGE_NAME, on_stack_loaded, relight_now
from ..runtime import RUNTIME
from ..stack_location import stack_location
from ..ui.prefs import get_prefs
from .export import export


def load_stack(context=None) -> bool:
    """Load the scene's stack (if baked) and check it against the current scene."""
    context = context or bpy.context
    path, _, _ = stack_location(context)
    scene = None
    if os.path.exists(path):
        try:
            scene = export(context).scene
        except Exception as e:
            RUNTIME.live.unload()
            RUNTIME.live.load_error = f"the scene cannot be exported: {e}"
            return False
    ok = RUNTIME.live.load(path, scene, get_prefs(context).device)
    if ok:
        on_stack_loaded()
    return ok


def check_stale(context=None) -> str | None:
    """Export the scene and compare its hash with the stack's; returns the stale reason."""
    live = RUNTIME.live
    RUNTIME.stale_check_pending = False
    if live.stack is None:
        return None
    try:
        result = export(context)
    except Exception as e:  # an export that fails cannot match the stack either
        live.stale_reason = f"the scene cannot be exported: {e}"
        return live.stale_reason
    was_stale = live.stale_reason is not None
    live.check(result.scene)
    if live.stale_reason is None:
        # Back from stale (or the image was deleted): the image shows nothing current, so
        # relight every region. Otherwise only what changed, as a slider edit would.
        relight_now(force=was_stale or bpy.data.images.get(IMAGE_NAME) is None)
    return live.stale_reason
