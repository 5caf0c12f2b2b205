"""Operators: thin wrappers over `services` that turn errors into `self.report`."""

from __future__ import annotations

import bpy
from bpy.props import StringProperty

from ..exporter.scene_export import ExportError
from ..logic.bake_summary import bake_summary
from ..logic.estimate_text import estimate_lines
from ..runtime import RUNTIME
from ..services.bake import bake, cancel_bake, start_bake
from ..services.errors import BakeCancelled, BakeError
from ..services.export import estimate, export
from ..services.output import render
from ..services.stack import check_stale, load_stack


def _relume_error_types():
    import relume

    return (relume.RelumeError, ExportError, BakeError, OSError, ValueError)


def _report_warnings(op) -> None:
    for w in RUNTIME.warnings:
        op.report({"WARNING"}, f"Relume: {w}")


class RELUME_OT_bake(bpy.types.Operator):
    """Bake the Relume transfer stack of this scene (Esc cancels)"""

    bl_idname = "relume.bake"
    bl_label = "Bake Relume"
    bl_options = {"REGISTER"}

    _timer = None

    def execute(self, context):
        # Blocking path: background mode, scripts, and `bpy.ops.relume.bake()`.
        try:
            report = bake(context)
        except BakeCancelled as e:
            self.report({"WARNING"}, str(e))
            return {"CANCELLED"}
        except _relume_error_types() as e:
            _report_warnings(self)
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        _report_warnings(self)
        self.report({"INFO"}, f"Relume: {bake_summary(report)}")
        return {"FINISHED"}

    def invoke(self, context, event):
        if bpy.app.background or context.window is None:
            return self.execute(context)
        try:
            start_bake(context)
        except _relume_error_types() as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        _report_warnings(self)
        wm = context.window_manager
        self._timer = wm.event_timer_add(0.1, window=context.window)
        wm.modal_handler_add(self)
        wm.progress_begin(0, 100)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        session = RUNTIME.session
        if session is None:
            return self._finish(context, {"CANCELLED"})
        if event.type == "ESC" and event.value == "PRESS":
            session.cancel()
        if event.type == "TIMER":
            session.poll()
            context.window_manager.progress_update(100.0 * float(session.progress.get("fraction", 0.0)))
            if context.workspace is not None:
                context.workspace.status_text_set(f"Relume: {session.message}  (Esc to cancel)")
            for window in context.window_manager.windows:
                for area in window.screen.areas:
                    area.tag_redraw()
        if session.finished:
            level = {"done": "INFO", "cancelled": "WARNING"}.get(session.state, "ERROR")
            self.report({level}, f"Relume: {session.message}")
            return self._finish(context, {"FINISHED"} if session.state == "done" else {"CANCELLED"})
        return {"PASS_THROUGH"}

    def _finish(self, context, result):
        wm = context.window_manager
        if self._timer is not None:
            wm.event_timer_remove(self._timer)
            self._timer = None
        wm.progress_end()
        if context.workspace is not None:
            context.workspace.status_text_set(None)
        return result


class RELUME_OT_cancel_bake(bpy.types.Operator):
    """Cancel the running Relume bake (the previous stack is kept)"""

    bl_idname = "relume.cancel_bake"
    bl_label = "Cancel Bake"

    def execute(self, context):
        if not cancel_bake():
            self.report({"INFO"}, "Relume: no bake is running")
        return {"FINISHED"}


class RELUME_OT_render(bpy.types.Operator):
    """Write the relit image with the current materials to a file (.exr or .png)"""

    bl_idname = "relume.render"
    bl_label = "Render Relume Image"

    filepath: StringProperty(name="File Path", subtype="FILE_PATH", default="//relume.exr")

    def execute(self, context):
        try:
            path = render(self.filepath, context)
        except _relume_error_types() as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        shown = (RUNTIME.live.last_denoise or {}).get("summary", "none")
        self.report({"INFO"}, f"Relume: wrote {path} (shown image: {shown})")
        return {"FINISHED"}


class RELUME_OT_export_scene(bpy.types.Operator):
    """Write the Relume scene file of this scene (for the relume command line and farms)"""

    bl_idname = "relume.export_scene"
    bl_label = "Export Relume Scene"

    filepath: StringProperty(name="File Path", subtype="FILE_PATH", default="//scene.scene.json")

    def execute(self, context):
        try:
            result = export(context, scene_file=bpy.path.abspath(self.filepath))
        except _relume_error_types() as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        _report_warnings(self)
        self.report({"INFO"}, f"Relume: exported {result.triangle_count} triangles")
        return {"FINISHED"}


class RELUME_OT_reload(bpy.types.Operator):
    """Reload the stack and check that it matches the scene"""

    bl_idname = "relume.reload"
    bl_label = "Reload Stack"

    def execute(self, context):
        load_stack(context)
        if RUNTIME.live.stale_reason:
            self.report({"WARNING"}, f"Relume: stack is stale: {RUNTIME.live.stale_reason}")
        elif RUNTIME.live.load_error:
            self.report({"WARNING"}, f"Relume: {RUNTIME.live.load_error}")
        return {"FINISHED"}


class RELUME_OT_check_stale(bpy.types.Operator):
    """Check whether the scene still matches the baked stack"""

    bl_idname = "relume.check_stale"
    bl_label = "Check Stack"

    def execute(self, context):
        reason = check_stale(context)
        self.report({"WARNING" if reason else "INFO"},
                    f"Relume: {'stale: ' + reason if reason else 'stack matches the scene'}")
        return {"FINISHED"}


class RELUME_OT_estimate(bpy.types.Operator):
    """Forecast the bake's cost (layers, memory, bases per editable material) without baking"""

    bl_idname = "relume.estimate"
    bl_label = "Estimate Bake"
    bl_options = {"REGISTER"}

    def execute(self, context):
        try:
            est = estimate(context)
        except _relume_error_types() as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        for line in estimate_lines(est):
            self.report({"INFO"}, f"Relume: {line}")
        return {"FINISHED"}


CLASSES = (RELUME_OT_bake, RELUME_OT_estimate, RELUME_OT_cancel_bake, RELUME_OT_render, RELUME_OT_export_scene,
           RELUME_OT_reload, RELUME_OT_check_stale)
