"""Exporting the scene for the core, the bake settings from the preferences, and the bake's
estimate."""

from __future__ import annotations

import bpy

from ..exporter.scene_export import ExportOptions, ExportResult, cycles_light_paths, export_scene
from ..logic.bake_settings_map import settings_keywords
from ..runtime import RUNTIME
from ..stack_location import stack_location
from ..ui.prefs import get_prefs

#: The roughness range an editable material is baked for unless it sets its own: the Principled
#: slider's range down to 0.1 (the mapping's exponent there is a few times 10⁴; the panel
#: shows the cost before a bake).
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
    kinds = None
    if getattr(prefs, "bounces_from_scene", False):
        bounces, diffuse, glossy = cycles_light_paths((context or bpy.context).scene)
        kinds = (diffuse, glossy)
    else:
        bounces = int(prefs.bounces)
    preset, keywords = settings_keywords(prefs, bounces, kinds)
    if preset is not None:
        return relume.BakeSettings.preset(preset, **keywords)
    return relume.BakeSettings(**keywords)


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
