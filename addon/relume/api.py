"""Relume's Python API for scripts (`blender -b file.blend --python script.py`, the bpy module).

    import importlib
    relume_addon = importlib.import_module("bl_ext.user_default.relume")
    relume_addon.api.bake()                       # blocking; prints progress
    mat = bpy.data.materials["Floor"]
    mat.node_tree.nodes["Principled BSDF"].inputs["Roughness"].default_value = 0.2
    relume_addon.api.render("/tmp/floor_r02.exr") # relit with the current materials
    relume_addon.api.set_light_group("light 0", 2.5, (1.0, 0.5, 0.25))  # a baked light group

Only the façade: the functions live in `services`, which the operators
(`bpy.ops.relume.bake()`, `bpy.ops.relume.render(filepath=...)`,
`bpy.ops.relume.export_scene(filepath=...)`) and the panels call too.
"""

from __future__ import annotations

from .logic.estimate_text import estimate_lines
from .services.bake import bake, cancel_bake, start_bake
from .services.errors import BakeCancelled, BakeError
from .services.export import DEFAULT_ROUGHNESS_RANGE, bake_settings, estimate, export, roughness_range
from .services.light_groups import set_light_group
from .services.output import relight, render
from .services.stack import load_stack
from .services.status import status

__all__ = [
    "DEFAULT_ROUGHNESS_RANGE",
    "BakeCancelled",
    "BakeError",
    "bake",
    "bake_settings",
    "cancel_bake",
    "estimate",
    "estimate_lines",
    "export",
    "load_stack",
    "relight",
    "render",
    "roughness_range",
    "set_light_group",
    "start_bake",
    "status",
]
