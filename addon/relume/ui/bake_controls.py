"""The bake controls (state, progress, Estimate / Bake / Cancel), drawn both in the Image
Editor's Relume tab and in the add-on preferences."""

from __future__ import annotations

from ..logic.estimate_text import estimate_lines
from ..runtime import RUNTIME


def draw_bake_controls(layout, context) -> None:
    """Bake state, progress and the Bake / Cancel buttons (also in the preferences)."""
    live = RUNTIME.live
    session = RUNTIME.session
    box = layout.box()
    if session is not None and not session.finished:
        frac = float(session.progress.get("fraction", 0.0))
        box.progress(factor=frac, type="BAR", text=session.message)
        box.operator("relume.cancel_bake", icon="CANCEL")
        return
    if session is not None and session.message:
        box.label(text=f"Last bake: {session.message}",
                  icon="CHECKMARK" if session.state == "done" else "ERROR")
    if live.stale_reason:
        box.label(text="Stack is stale: the scene changed since the bake", icon="ERROR")
        box.label(text=live.stale_reason[:120])
        box.operator("relume.bake", text="Rebake", icon="FILE_REFRESH")
        return
    if live.stack is None:
        box.label(text=f"No stack: {live.load_error or 'not baked yet'}", icon="INFO")
    else:
        box.label(text=f"Stack: {live.stack.width}×{live.stack.height}, {live.stack.layer_count} layers, "
                       f"{live.stack.bytes / 1e6:.0f} MB", icon="CHECKMARK")
    for line in estimate_lines(RUNTIME.estimate):
        box.label(text=line[:140])
    row = box.row()
    row.operator("relume.estimate", icon="INFO")
    row.operator("relume.bake", icon="RENDER_STILL")
