"""Relume's Python API for scripts (`blender -b file.blend --python script.py`, the bpy module).

    import importlib
    relume_addon = importlib.import_module("bl_ext.user_default.relume")
    relume_addon.api.bake()                       # blocking; prints progress
    mat = bpy.data.materials["Floor"]
    mat.node_tree.nodes["Principled BSDF"].inputs["Roughness"].default_value = 0.2
    relume_addon.api.render("/tmp/floor_r02.exr") # relit with the current materials
    relume_addon.api.set_light_group("light 0", 2.5, (1.0, 0.5, 0.25))  # a baked light group

The operators `bpy.ops.relume.bake()`, `bpy.ops.relume.render(filepath=...)` and
`bpy.ops.relume.export_scene(filepath=...)` call these functions.
"""

from __future__ import annotations

import os
import time

import bpy

from .exporter.scene_export import ExportOptions, ExportResult, cycles_bounce_cap, export_scene
from .live import current_gains, current_params, on_stack_loaded, write_image
from .logic.bake_session import BakeSession
from .logic.light_groups import GROUPING_OF_PREF, Gain, unknown_group_message
from .prefs import get_prefs
from .runtime import RUNTIME
from .stack_location import stack_location


class BakeError(RuntimeError):
    """A bake that did not complete (cancelled or failed); the message says which and why."""


class BakeCancelled(BakeError):
    """The bake was cancelled (Esc, the Cancel button, `cancel_bake()`); nothing was lost."""


#: The roughness range an editable material is baked for unless it sets its own: the Principled
#: slider's range down to 0.1 (ns ≈ 20 000; below, lobes narrower than 0.4° need ns > 10⁴·…).
DEFAULT_ROUGHNESS_RANGE = (0.1, 1.0)


def roughness_range(material) -> tuple[float, float]:
    """The roughness range `material`'s basis is baked for: its own when it sets one, else
    `DEFAULT_ROUGHNESS_RANGE`."""
    p = material.relume
    if p.use_roughness_range:
        return (min(p.roughness_min, p.roughness_max), max(p.roughness_min, p.roughness_max))
    return DEFAULT_ROUGHNESS_RANGE


def _ns_range(roughness_min: float, roughness_max: float) -> list[float]:
    import relume

    lo = relume.principled_to_blinn_phong((0.8, 0.8, 0.8), roughness=max(roughness_min, roughness_max))["ns"]
    hi = relume.principled_to_blinn_phong((0.8, 0.8, 0.8), roughness=min(roughness_min, roughness_max))["ns"]
    lo = max(lo, 1e-3)
    return [lo, max(hi, lo * 1.001)]


def export(context=None, scene_file: str | None = None) -> ExportResult:
    """Export the scene; with `scene_file`, also write the core's scene file (CLI, farms)."""
    context = context or bpy.context
    prefs = get_prefs(context)
    _, texture_dir, _ = stack_location(context)
    ns_ranges = {}
    for mat in bpy.data.materials:
        p = getattr(mat, "relume", None)
        if p is not None and p.editable:
            ns_ranges[mat.name] = _ns_range(*roughness_range(mat))
    options = ExportOptions(resolution_scale=float(prefs.resolution_scale), texture_dir=texture_dir,
                            ns_ranges=ns_ranges)
    result = export_scene(context, options)
    RUNTIME.warnings = result.warnings
    RUNTIME.light_names = result.light_names
    if scene_file:
        result.scene.save(scene_file)
    return result


def bake_settings(context=None):
    """`relume.BakeSettings` from the add-on preferences."""
    import relume

    prefs = get_prefs(context)
    if getattr(prefs, "bounces_from_scene", False):
        bounces = cycles_bounce_cap((context or bpy.context).scene)
    else:
        bounces = int(prefs.bounces)
    common = {"bounces": bounces, "passes": int(prefs.passes),
              "light_grouping": GROUPING_OF_PREF[prefs.light_groups]}
    budget = float(getattr(prefs, "memory_budget_mb", 0.0))
    if budget > 0.0:
        common["memory_budget_mb"] = budget
    preset = getattr(relume.BakeSettings, "preset", None)
    if prefs.preset != "custom" and preset is not None:
        return preset(prefs.preset, **common)
    return relume.BakeSettings(spp=int(prefs.spp), light_samples=int(prefs.light_samples),
                               indirect_samples=int(prefs.indirect_samples),
                               basis_tolerance=float(prefs.basis_tolerance), **common)


def estimate(context=None, settings=None) -> dict:
    """What a bake with the preferences (or `settings`) will cost, without baking (about a
    second): the core's estimate — layers reached, peak and stack bytes, the memory budget —
    and, per editable region, its roughness range and the basis count it needs. Kept in
    `status()["estimate"]` and shown in the panel."""
    import relume

    context = context or bpy.context
    result = export(context)
    est = dict(relume.estimate_bake(result.scene, settings or bake_settings(context)))
    RUNTIME.estimate = est
    return est


def estimate_lines(est: dict | None) -> list[str]:
    """The estimate as the panel shows it, one short line each."""
    if not est:
        return []
    mb = 1e6
    lines = [f"Estimate: {est['layers_reached']} of {est['layers_possible']} layers, "
             f"peak {est['peak_bytes'] / mb:.0f} MB, stack {est['stack_bytes'] / mb:.0f} MB"]
    for r in est.get("editable", []):
        lo, hi = r["roughness_range"]
        lines.append(f"{r['region']}: roughness {lo:.2f}–{hi:.2f} (ns ≤ {r['ns_range'][1]:.0f}) → "
                     f"{r['bases']} bases, {r['slots']} slots")
    return lines


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


def relight(context=None):
    """Relight with the current material values; returns the (h, w, 4) image (bottom row first)."""
    live = RUNTIME.live
    if live.stack is None and not load_stack(context):
        raise BakeError(f"no usable Relume stack: {live.load_error or 'not baked yet'}")
    if live.stale_reason is not None:
        raise BakeError(f"the Relume stack is stale: {live.stale_reason}")
    outcome = live.relight(current_params(), force=True, gains=current_gains())
    write_image(outcome.image)
    return outcome.image


def set_light_group(name: str, strength: float = 1.0, color=(1.0, 1.0, 1.0), context=None) -> None:
    """Set a light group's live strength and colour (a stack baked with light groups).

    Stored on the scene like the Relume tab's sliders — saved with the .blend, re-applied when
    the stack reloads — and relit through the same live path; `render()` uses it. Raises
    `BakeError` when there is no stack, `ValueError` for a group the loaded stack does not
    have (its groups are listed) or a negative or non-finite value.
    """
    context = context or bpy.context
    live = RUNTIME.live
    if live.stack is None and not load_stack(context):
        raise BakeError(f"no usable Relume stack: {live.load_error or 'not baked yet'}")
    groups = live.light_groups
    if name not in groups:
        raise ValueError(unknown_group_message(name, groups))
    gain = Gain(strength, tuple(color)).checked(name)
    stored = context.scene.relume_light_groups
    entry = stored.get(name)
    if entry is None:
        entry = stored.add()
        entry.name = name
    entry.strength = gain.strength  # each assignment relights through the update callback
    entry.color = gain.color


def render(filepath: str, context=None, check_stale: bool = True) -> str:
    """Write the relit image to `filepath` (.exr: linear float; .png: sRGB 8-bit)."""
    import relume

    from .live import check_stale as _check

    if check_stale and RUNTIME.live.stack is not None and _check(context) is not None:
        raise BakeError(f"the Relume stack is stale: {RUNTIME.live.stale_reason}")
    image = relight(context)
    path = bpy.path.abspath(filepath)
    folder = os.path.dirname(path)
    if folder:
        os.makedirs(folder, exist_ok=True)
    top_first = image[::-1]
    if path.lower().endswith(".png"):
        relume.write_png(path, top_first)
    elif path.lower().endswith(".exr"):
        relume.write_exr(path, top_first)
    else:
        raise ValueError(f"unsupported output format '{os.path.splitext(path)[1]}': use .exr or .png")
    return path


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
