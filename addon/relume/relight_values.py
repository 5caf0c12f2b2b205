"""What the live relight reads from the scene: each editable region's material values and
each light group's gain (bpy side of `logic.region_params` and `logic.live_state`)."""

from __future__ import annotations

import bpy

from .exporter.nodes import read_surface
from .logic.export_warnings import WarningList
from .logic.material_map import map_material
from .logic.region_params import OverrideParams, PrincipledParams, RegionParams
from .runtime import RUNTIME


def region_params(material) -> RegionParams:
    """The current material values of one editable region (see `LiveState.apply`)."""
    props = material.relume
    if props.override:
        return OverrideParams(tuple(props.kd), tuple(props.ks), float(props.ns))
    mapped, _textured = map_material(read_surface(material), WarningList())
    if mapped["model"] == "blinn_phong":
        return OverrideParams(tuple(mapped["kd"]), tuple(mapped["ks"]), float(mapped["ns"]))
    return PrincipledParams(
        base_color=tuple(mapped["base_color"]), metallic=mapped["metallic"],
        roughness=mapped["roughness"], ior=mapped["ior"],
        specular_ior_level=mapped["specular_ior_level"],
        subsurface_weight=mapped.get("subsurface_weight", 0.0),
        subsurface_radius=tuple(mapped.get("subsurface_radius", (1.0, 0.2, 0.1))),
        subsurface_scale=mapped.get("subsurface_scale", 0.05))


def current_params() -> dict[str, RegionParams]:
    """Values of every editable region of the loaded stack, read from the materials."""
    live = RUNTIME.live
    params = {}
    if live.stack is None:
        return params
    for name in live.stack.editable_regions:
        mat = bpy.data.materials.get(name)
        if mat is not None:
            params[name] = region_params(mat)
    return params


def current_gains(scene=None) -> dict:
    """Gain of every light group of the loaded stack that the scene stores, by group name:
    (strength, (r, g, b)). Groups without a stored entry stay at the baked light."""
    live = RUNTIME.live
    scene = scene or bpy.context.scene
    groups = set(live.light_groups)
    stored = getattr(scene, "relume_light_groups", None) or ()
    return {g.name: (float(g.strength), tuple(float(c) for c in g.color))
            for g in stored if g.name in groups}


def sync_light_groups(scene=None) -> None:
    """Give the scene an entry (strength 1, white) for each light group of the loaded stack
    that it has none for. Called when a stack loads, never from a panel's draw (which may not
    write data); existing entries, and their gains, are kept."""
    scene = scene or bpy.context.scene
    stored = getattr(scene, "relume_light_groups", None)
    if stored is None:
        return
    have = {g.name for g in stored}
    for name in RUNTIME.live.light_groups:
        if name not in have:
            stored.add().name = name
