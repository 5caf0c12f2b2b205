"""The add-on's state as a dict, for scripts (what the panel shows)."""

from __future__ import annotations

import bpy

from ..relight_values import current_gains
from ..runtime import RUNTIME


def status(context=None) -> dict:
    """What the panel shows, for scripts: stack, staleness, device, bake state, warnings,
    and the light groups with their gains."""
    live = RUNTIME.live
    session = RUNTIME.session
    return {
        "stack_path": live.stack_path,
        "loaded": live.stack is not None,
        "stale": live.stale_reason,
        "load_error": live.load_error,
        "device": live.device_text,
        "bake_state": session.state if session else "idle",
        "bake_message": session.message if session else "",
        "last_latency_ms": live.last_latency_ms,
        # What the last image shown went through: {"asked", "ran", "note", "summary", …}.
        "denoise": live.last_denoise,
        "refine": live.last_refine,
        "relight_error": live.relight_error,
        # Editable materials outside their baked roughness range (relit at the range's edge).
        "range_warnings": live.range_warnings,
        # The last estimate (`estimate()`): layers, memory, bases per editable region.
        "estimate": RUNTIME.estimate,
        "warnings": [str(w) for w in RUNTIME.warnings],
        "light_groups": _light_group_status(context),
    }


def _light_group_status(context=None) -> list[dict]:
    """Each light group of the loaded stack with the gain the next relight uses."""
    scene = (context or bpy.context).scene
    gains = current_gains(scene)
    out = []
    for name in RUNTIME.live.light_groups:
        strength, color = gains.get(name, (1.0, (1.0, 1.0, 1.0)))
        out.append({"name": name, "strength": strength, "color": color})
    return out
