"""The live edit path inside Blender: what one slider step costs, and what still checks.

A shader slider of an editable material must relight once and export nothing (an export is
the stale check's cost, once run on every step: Blender tags the objects and meshes that use
the material for shading along with it). Edits that change what the bake saw — a mesh's
vertices, a fixed material — must still mark the stack stale.
"""

from __future__ import annotations

import bpy
from support.scenes import box_scene


def _count_exports_and_relights(addon, monkeypatch) -> dict:
    counts = {"exports": 0, "relights": 0}
    stack_service = addon.services.stack
    real_export = stack_service.export

    def counting_export(*args, **kwargs):
        counts["exports"] += 1
        return real_export(*args, **kwargs)

    live = addon.runtime.RUNTIME.live
    real_relight = live.relight

    def counting_relight(*args, **kwargs):
        outcome = real_relight(*args, **kwargs)
        counts["relights"] += outcome is not None
        return outcome

    monkeypatch.setattr(stack_service, "export", counting_export)
    monkeypatch.setattr(live, "relight", counting_relight)
    return counts


def test_slider_step_relights_once_and_exports_nothing(addon, prefs, blend_dir, monkeypatch):
    box_scene(resolution=24)
    addon.api.bake()
    counts = _count_exports_and_relights(addon, monkeypatch)
    inputs = bpy.data.materials["Floor"].node_tree.nodes["Principled BSDF"].inputs
    for value in (0.25, 0.45, 0.65):
        inputs["Roughness"].default_value = value
        bpy.context.view_layer.update()
    assert counts == {"exports": 0, "relights": 3}
    assert addon.api.status()["stale"] is None
    upload_ms = addon.runtime.RUNTIME.live.last_upload_ms
    assert upload_ms is not None and upload_ms >= 0.0


def test_geometry_and_fixed_material_edits_still_mark_the_stack_stale(addon, prefs, blend_dir,
                                                                      monkeypatch):
    box_scene(resolution=24)
    addon.api.bake()
    counts = _count_exports_and_relights(addon, monkeypatch)
    mesh = bpy.data.meshes["FloorQuad"]
    mesh.vertices[0].co.z = 0.2
    mesh.update()
    bpy.context.view_layer.update()
    assert counts["exports"] == 1 and addon.api.status()["stale"] is not None
    mesh.vertices[0].co.z = 0.0
    mesh.update()
    bpy.context.view_layer.update()
    assert addon.api.status()["stale"] is None
    assert counts["relights"] == 1, "back from stale, the image is relit"
    walls = bpy.data.materials["Walls"].node_tree.nodes["Principled BSDF"].inputs
    walls["Base Color"].default_value = (0.2, 0.5, 0.2, 1.0)
    bpy.context.view_layer.update()
    assert addon.api.status()["stale"] is not None
