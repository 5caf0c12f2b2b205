"""Translucent materials through the add-on: Principled subsurface inputs exported (scene
format 2), baked into subsurface layers, and relit live when a subsurface slider moves."""

from __future__ import annotations

import bpy
import numpy as np
from support.scenes import box_scene


def _image():
    img = bpy.data.images["Relume"]
    w, h = img.size
    px = np.empty(w * h * 4, np.float32)
    img.pixels.foreach_get(px)
    return px.reshape(h, w, 4)


def _make_ball_translucent(scale=0.1):
    node = bpy.data.materials["Ball"].node_tree.nodes["Principled BSDF"]
    node.inputs["Subsurface Weight"].default_value = 1.0
    node.inputs["Subsurface Radius"].default_value = (1.0, 0.3, 0.15)
    node.inputs["Subsurface Scale"].default_value = scale
    return node


def test_subsurface_inputs_are_exported_and_fixed_ones_warn(addon, prefs, blend_dir):
    box_scene(resolution=16)
    _make_ball_translucent()
    walls = bpy.data.materials["Walls"].node_tree.nodes["Principled BSDF"]
    walls.inputs["Subsurface Weight"].default_value = 0.5  # Walls is not editable
    bpy.context.view_layer.update()
    result = addon.api.export()
    assert result.scene_dict["version"] >= 2  # 3 when a visible lamp is in the scene
    ball = next(r for r in result.scene_dict["regions"] if r["name"] == "Ball")["material"]
    assert ball["subsurface_weight"] == 1.0
    assert np.allclose(ball["subsurface_radius"], [1.0, 0.3, 0.15])
    assert abs(ball["subsurface_scale"] - 0.1) < 1e-6
    walls_region = next(r for r in result.scene_dict["regions"] if r["name"] == "Walls")
    assert "subsurface_weight" not in walls_region["material"]
    text = [str(w) for w in result.warnings]
    assert any("Material 'Walls'" in t and "subsurface" in t and "Editable" in t for t in text), text


def test_subsurface_slider_relights_the_image(addon, prefs, blend_dir):
    import relume

    box_scene(resolution=24)
    node = _make_ball_translucent(scale=0.1)
    bpy.context.view_layer.update()
    addon.api.bake()
    status = addon.api.status()
    assert status["loaded"] and status["stale"] is None, status
    stack = relume.Stack.load(status["stack_path"])
    ball_info = next(r for r in stack.header["regions"] if r["name"] == "Ball")
    assert ball_info.get("subsurface"), ball_info  # the bake made Ball's subsurface layers
    before = _image().copy()

    node.inputs["Subsurface Scale"].default_value = 0.02  # a shorter mean free path
    bpy.context.view_layer.update()
    after = _image()
    assert np.isfinite(after).all()
    assert np.abs(after - before).max() > 1e-5, "the subsurface slider did not relight"

    # The image is the stack relit on the CPU with the same Principled + subsurface values.
    ref = relume.Relighter(stack, "cpu")
    for name in ("Ball", "Floor"):
        n = bpy.data.materials[name].node_tree.nodes["Principled BSDF"]
        ref.set_principled(
            name, tuple(n.inputs["Base Color"].default_value)[:3], n.inputs["Metallic"].default_value,
            n.inputs["Roughness"].default_value, n.inputs["IOR"].default_value,
            n.inputs["Specular IOR Level"].default_value,
            subsurface_weight=n.inputs["Subsurface Weight"].default_value,
            subsurface_radius=tuple(n.inputs["Subsurface Radius"].default_value),
            subsurface_scale=n.inputs["Subsurface Scale"].default_value)
    expected = ref.relight(flip_y=True)
    assert np.abs(after - expected).max() <= 1e-5 * max(1.0, float(expected.max()))

    # Weight 0 turns the subsurface term off: a visibly different image again.
    node.inputs["Subsurface Weight"].default_value = 0.0
    bpy.context.view_layer.update()
    opaque = _image()
    assert np.abs(opaque - after).max() > 1e-5
