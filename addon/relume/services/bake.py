"""Starting, waiting for and cancelling a bake."""

from __future__ import annotations

import os
import time

import bpy

from ..live_image import on_stack_loaded
from ..logic.bake_session import BakeSession
from ..runtime import RUNTIME
from ..stack_location import stack_location
from ..ui.prefs import get_prefs
from .errors import BakeCancelled, BakeError
from .export import bake_settings, export


def start_bake(context=None, settings=None) -> BakeSession:
    """Export and start a bake in the background; poll the returned session.

    `settings` (a `relume.BakeSettings`) overrides the preferences, for scripts.
    """
    context = context or bpy.context
    if RUNTIME.session is not None and not RUNTIME.session.finished:
        raise BakeError("a Relume bake is already running (Esc or Cancel stops it)")
    result = export(context)
    path, _, _ = stack_location(context)
    os.makedirs(os.path.dirname(path), exist_ok=True)
    device = get_prefs(context).device

    def on_stack(stack_path: str) -> None:
        # Main thread (called from poll): reload and show the newest complete stack.
        if RUNTIME.live.load(stack_path, result.scene, device):
            on_stack_loaded()

    session = BakeSession(result.scene, settings or bake_settings(context), path, on_stack=on_stack)
    session.export = result
    session.start()
    RUNTIME.session = session
    return session


def bake(context=None, progress=None, settings=None) -> dict:
    """Bake and wait (background mode, scripts). Returns the bake report.

    `progress(session)` is called about ten times a second; raise or call
    `cancel_bake()` from it (or from another thread) to stop. Raises `BakeError` when the
    bake is cancelled or fails; the previous stack, if any, is then left as it was.
    """
    session = start_bake(context, settings)
    last_print = [0.0]

    def tick(s: BakeSession) -> None:
        if progress is not None:
            progress(s)
        now = time.perf_counter()
        if now - last_print[0] >= 1.0 and not s.finished:
            last_print[0] = now
            print(f"Relume: {s.message}", flush=True)

    try:
        state = session.run_blocking(on_progress=tick)
    except BaseException:
        session.cancel()
        if session.job is not None:
            session.job.wait(5.0)
        raise
    print(f"Relume: {session.message}", flush=True)
    if state == "cancelled":
        raise BakeCancelled(f"Relume bake {session.message}")
    if state != "done":
        raise BakeError(f"Relume bake {session.message}")
    return session.report


def cancel_bake() -> bool:
    """Cancel the running bake (safe from any thread); False when none runs."""
    session = RUNTIME.session
    if session is None or session.finished:
        return False
    session.cancel()
    return True
