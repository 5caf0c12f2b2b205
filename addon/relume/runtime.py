"""Session-wide state of the add-on: the live relight and the running bake.

Held in Python, not in bpy data: a relighter owns GPU buffers and a bake owns a Rust
thread, neither of which belongs in a .blend. One instance per Blender session.
"""

from __future__ import annotations

from .logic.live_state import LiveState
from .logic.settle import Settle
from .logic.throttle import Throttle


class Runtime:
    def __init__(self) -> None:
        self.live = LiveState()
        self.session = None  # logic.bake_session.BakeSession while a bake runs (and after)
        self.throttle = Throttle()
        self.warnings: list = []  # the last export's warnings (ExportWarning)
        self.light_names: list[str] = []  # the last export's lights, in scene order
        self.stale_check_pending = False
        self.relight_timer_registered = False
        #: When the live image is denoised (after the edits settle) and its timer.
        self.settle = Settle()
        self.settle_timer_registered = False
        #: The settled worker's latest (generation, relighter, outcome, error), polled by a
        #: timer, and the worker (denoise, then refinement passes).
        self.settled_result = None
        self.settled_worker = None
        #: The relit pixels in Blender's row order, reused by every write of a top-first
        #: image into the "Relume" image (`api.render`, `api.relight`; the live relight gets
        #: its rows in Blender's order from the relighter and needs no copy).
        self.upload_buffer = None
        self.last_status = ""
        self.estimate: dict | None = None  # the last `api.estimate()`: cost before a bake


RUNTIME = Runtime()
