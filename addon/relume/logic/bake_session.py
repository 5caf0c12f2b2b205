"""One bake, from start to a stack on disk, driven by polling from Blender's main thread.

The heavy work runs in a Rust thread (`relume.BakeJob`) that never touches Python or bpy;
the modal operator (UI) or the blocking operator (background mode, scripts) only polls this
object. So the same code path serves the preferences' Bake button, the Image Editor panel,
`bpy.ops.relume.bake()` and the Python API, and cancelling is one call from anywhere.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from .bake_summary import bake_summary


def format_eta(seconds: float | None) -> str:
    if seconds is None or seconds != seconds or seconds < 0:
        return "estimating…"
    seconds = int(round(seconds))
    if seconds < 60:
        return f"{seconds} s"
    return f"{seconds // 60} min {seconds % 60:02d} s"


class BakeSession:
    """Start, poll, cancel and finish one bake.

    `on_stack(path)` is called from `poll()` (so on the caller's thread, Blender's main
    thread in the add-on) each time a complete stack has been written: after every pass of
    a progressive bake, so the image can be relit from it while later passes run.
    """

    def __init__(self, scene, settings, stack_path: str,
                 on_stack: Callable[[str], None] | None = None):
        self.scene = scene
        self.settings = settings
        self.stack_path = stack_path
        self.on_stack = on_stack
        self.job = None
        self.state = "idle"  # idle, running, done, cancelled, failed
        self.message = ""
        self.report: dict | None = None
        self.progress: dict = {}
        self._stacks_seen = 0
        self._cancel_requested_at: float | None = None

    def start(self) -> None:
        import relume

        self.job = relume.BakeJob(self.scene, self.settings, self.stack_path)
        self.state = "running"
        self.message = "starting"

    def cancel(self) -> None:
        """Ask the worker to stop; `poll()` reports 'cancelled' once it has (well under 1 s)."""
        if self.job is not None and self.state == "running":
            self._cancel_requested_at = time.perf_counter()
            self.job.cancel()
            self.message = "cancelling…"

    @property
    def finished(self) -> bool:
        return self.state in ("done", "cancelled", "failed")

    def poll(self) -> str:
        """Update progress, deliver new stacks, and settle the outcome when the job ends."""
        import relume

        if self.job is None or self.finished:
            return self.state
        self.progress = dict(self.job.progress)
        written = int(self.progress.get("stacks_written", 0))
        if written > self._stacks_seen:
            self._stacks_seen = written
            if self.on_stack is not None:
                self.on_stack(self.stack_path)
        if not self.job.done:
            if self._cancel_requested_at is None:
                self.message = self.status_text()
            return self.state
        try:
            self.report = self.job.result()
            self.state = "done"
            self.message = bake_summary(self.report)
        except relume.CancelledError:
            self.state = "cancelled"
            kept = "the previous stack is kept" if self._stacks_seen == 0 else \
                f"the stack of pass {self._stacks_seen} is kept"
            self.message = f"cancelled; {kept}"
        except relume.RelumeError as e:
            self.state = "failed"
            self.message = f"failed: {e}"
        # A stack written between the last poll and the end still has to be delivered.
        written = int(dict(self.job.progress).get("stacks_written", 0))
        if written > self._stacks_seen and self.on_stack is not None:
            self._stacks_seen = written
            self.on_stack(self.stack_path)
        return self.state

    def status_text(self) -> str:
        p = self.progress
        frac = float(p.get("fraction", 0.0))
        passes = int(p.get("pass_count", 1) or 1)
        pass_part = f"pass {int(p.get('pass_index', 0)) + 1}/{passes} · " if passes > 1 else ""
        noise = p.get("noise")
        noise_part = f" · noise {100 * noise:.1f} %" if noise is not None else ""
        return f"Baking {pass_part}{100 * frac:.0f} % · ETA {format_eta(p.get('eta_s'))}{noise_part}"

    def run_blocking(self, poll_interval: float = 0.1,
                     on_progress: Callable[[BakeSession], None] | None = None) -> str:
        """Start (if needed) and poll until the end; for background mode and scripts."""
        if self.job is None:
            self.start()
        while not self.finished:
            self.job.wait(poll_interval)
            self.poll()
            if on_progress is not None:
                on_progress(self)
        return self.state
