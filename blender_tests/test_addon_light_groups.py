"""Light groups in the add-on, on real bpy: bake a two-light box with the lights kept apart,
then check the physics of the live gains — the image is linear in each group's light, a
strength and a tint scale exactly that group's share — through the API, the scene's slider
properties (the live path a user drives), `render()` and a reload of the .blend."""

from __future__ import annotations

import bpy
import numpy as np
import pytest
from support.scenes import save_and_reopen, two_light_box

WHITE = (1.0, 1.0, 1.0)
BLACK = (0.0, 0.0, 0.0)
#: f16 layers summed in f32: sums of the same layers agree far better than this.
REL = 1e-3


def _image():
    img = bpy.data.images["Relume"]
    w, h = img.size
    px = np.empty(w * h * 4, np.float32)
    img.pixels.foreach_get(px)
    return px.reshape(h, w, 4)[..., :3].copy()


def _rel_err(got, expected) -> float:
    """Largest error relative to the expected image's brightest value."""
    return float(np.abs(got - expected).max() / max(float(np.abs(expected).max()), 1e-12))


def _relit(addon, gains: dict) -> np.ndarray:
    """The RGB image with each group's (strength, colour) set through `api.set_light_group`."""
    for name, (strength, color) in gains.items():
        addon.api.set_light_group(name, strength, color)
    rgb = addon.api.relight()[..., :3].copy()
    assert np.array_equal(rgb, _image()), "api.relight() and the Relume image disagree"
    return rgb


def _group_of_light(addon, light: str) -> str:
    """The core's per-light group name ("light <i>", i in the exported scene's light order)."""
    return f"light {addon.api.export().light_names.index(light)}"


@pytest.fixture
def per_light(addon, prefs, blend_dir):
    """The two-light box baked with Per Light grouping: (key group, fill group)."""
    two_light_box(resolution=32)
    prefs.light_groups = "per_light"
    addon.api.bake()
    return _group_of_light(addon, "Key"), _group_of_light(addon, "Fill")


def test_per_light_groups_are_linear_and_gains_scale_their_share(addon, per_light, blend_dir):
    key, fill = per_light
    status = addon.api.status()
    # (a) one group per light; the world is black, so it gets none.
    assert sorted(g["name"] for g in status["light_groups"]) == ["light 0", "light 1"]
    assert {key, fill} == {"light 0", "light 1"}
    both = _relit(addon, {key: (1.0, WHITE), fill: (1.0, WHITE)})
    only_key = _relit(addon, {key: (1.0, WHITE), fill: (0.0, WHITE)})
    only_fill = _relit(addon, {key: (0.0, WHITE), fill: (1.0, WHITE)})
    # Each light alone lights the box, differently (the fill is bluish): a test that
    # cannot pass by accident with one group empty or both the same.
    assert only_key.max() > 0 and only_fill.max() > 0
    assert _rel_err(only_fill, only_key) > 0.1
    # (b) linearity: the image with both lights is the sum of the images of each.
    err_sum = _rel_err(only_key + only_fill, both)
    assert err_sum <= REL, f"linearity: {err_sum:.2e}"
    # (c) a strength on one group and a tint on the other scale exactly their shares.
    tint = np.array([1.0, 0.5, 0.25], np.float32)
    graded = _relit(addon, {key: (2.5, WHITE), fill: (1.0, tuple(tint))})
    err_gain = _rel_err(graded, 2.5 * only_key + tint * only_fill)
    assert err_gain <= REL, f"strength 2.5 and tint: {err_gain:.2e}"
    print(f"\nper-light: linearity {err_sum:.2e}, strength/tint {err_gain:.2e} (relative to max)")
    # status() and render() use the current gains.
    gains = {g["name"]: g for g in addon.api.status()["light_groups"]}
    assert gains[key]["strength"] == 2.5 and gains[fill]["color"] == pytest.approx(tuple(tint))
    import relume

    out = addon.api.render(str(blend_dir / "graded.exr"), denoise="none")
    written = relume.read_exr(out)[::-1, :, :3]  # the file is top row first
    assert _rel_err(written, graded) <= REL


def test_the_scene_slider_relights_through_the_live_path(addon, per_light):
    """(d) What the Relume tab's sliders do: set the scene's light group property; the
    update callback relights the Relume image, equal to a CPU relight of the same stack."""
    import relume

    key, fill = per_light
    before = _image()
    groups = bpy.context.scene.relume_light_groups
    assert sorted(g.name for g in groups) == ["light 0", "light 1"], "synced when the stack loaded"
    groups[key].strength = 0.0
    groups[fill].color = (1.0, 0.5, 0.25)
    after = _image()
    assert _rel_err(after, before) > 0.1, "the slider did not relight"

    ref = relume.Relighter(relume.Stack.load(addon.api.status()["stack_path"]), "cpu")
    for name in ("Ball", "Floor"):
        n = bpy.data.materials[name].node_tree.nodes["Principled BSDF"]
        ref.set_principled(name, tuple(n.inputs["Base Color"].default_value)[:3],
                           n.inputs["Metallic"].default_value, n.inputs["Roughness"].default_value,
                           n.inputs["IOR"].default_value, n.inputs["Specular IOR Level"].default_value)
    ref.set_light_group(key, 0.0)
    ref.set_light_group(fill, 1.0, (1.0, 0.5, 0.25))
    expected = ref.relight(flip_y=True)[..., :3]
    assert _rel_err(after, expected) <= 1e-5


def test_gains_persist_in_the_blend_and_are_reapplied_on_reload(addon, per_light):
    key, _fill = per_light
    unit = _image()
    addon.api.set_light_group(key, 0.25, (1.0, 0.8, 0.6))
    graded = _image()
    assert _rel_err(graded, unit) > 0.1, "the gain did not change the image"
    status = save_and_reopen(addon)
    assert status["loaded"] and status["stale"] is None, status
    assert bpy.context.scene.relume_light_groups[key].strength == 0.25
    assert _rel_err(_image(), graded) <= 1e-6, "the stored gain was not re-applied"


def test_unknown_group_and_bad_values_are_clear_errors(addon, per_light):
    # (e)
    with pytest.raises(ValueError, match=r"light group 'Nope' is not in the loaded stack "
                                         r"\(its groups: light 0, light 1\)"):
        addon.api.set_light_group("Nope", 2.0)
    key, _ = per_light
    with pytest.raises(ValueError, match=r"light group 'light \d': strength and color must be "
                                         r"finite and ≥ 0"):
        addon.api.set_light_group(key, -1.0)
    with pytest.raises(ValueError, match="color needs 3 components"):
        addon.api.set_light_group(key, 1.0, (1.0, 1.0))


def test_preference_change_is_not_stale_and_a_plain_stack_has_no_groups(addon, prefs, per_light):
    prefs.light_groups = "none"
    assert addon.live.check_stale() is None, "the preference alone made the stack stale"
    assert addon.api.bake_settings().light_grouping == "all"
    addon.api.bake()
    assert addon.api.status()["light_groups"] == []
    with pytest.raises(ValueError, match="the loaded stack has no light groups"):
        addon.api.set_light_group("light 0", 2.0)
    # A Blender light group is part of the scene (its file's light_groups, in the hash).
    bpy.data.objects["Key"].lightgroup = "KeyGroup"
    assert addon.live.check_stale() is not None


def test_blender_light_groups_bake_with_scene_grouping(addon, prefs, blend_dir):
    """Blender's light groups (obj.lightgroup, world.lightgroup) → the scene file's
    `light_groups` → a "scene" bake: one group each, plus the core's "default" for the
    light without one."""
    import relume

    scene = two_light_box(resolution=32)
    background = scene.world.node_tree.nodes["Background"]
    background.inputs["Color"].default_value = (0.3, 0.35, 0.5, 1.0)  # the world emits
    bpy.context.view_layer.lightgroups.add(name="KeyGroup")
    bpy.context.view_layer.lightgroups.add(name="Sky")
    bpy.data.objects["Key"].lightgroup = "KeyGroup"
    scene.world.lightgroup = "Sky"
    bpy.context.view_layer.update()

    result = addon.api.export(scene_file=str(blend_dir / "scene.scene.json"))
    key_index = result.light_names.index("Key")
    assert result.scene_dict["light_groups"] == [
        {"name": "KeyGroup", "lights": [key_index], "world": False},
        {"name": "Sky", "lights": [], "world": True},
    ]
    # The core reads the file back with its groups (they are part of the scene hash).
    assert relume.Scene.load(str(blend_dir / "scene.scene.json")).hash() == result.scene.hash()

    prefs.light_groups = "scene"
    addon.api.bake()
    groups = [g["name"] for g in addon.api.status()["light_groups"]]
    assert groups == ["KeyGroup", "Sky", "default"]
    off = {g: (0.0, WHITE) for g in groups}
    singles = [_relit(addon, {**off, g: (1.0, WHITE)}) for g in groups]
    assert all(s.max() > 0 for s in singles), "a group holds no light"
    both = _relit(addon, {g: (1.0, WHITE) for g in groups})
    err_sum = _rel_err(sum(singles), both)
    assert err_sum <= REL, f"linearity: {err_sum:.2e}"
    tint = np.array([1.0, 0.5, 0.25], np.float32)
    graded = _relit(addon, {"KeyGroup": (2.5, WHITE), "Sky": (1.0, WHITE),
                            "default": (1.0, tuple(tint))})
    err_gain = _rel_err(graded, 2.5 * singles[0] + singles[1] + tint * singles[2])
    assert err_gain <= REL, f"strength 2.5 and tint: {err_gain:.2e}"
    print(f"\nscene groups: linearity {err_sum:.2e}, strength/tint {err_gain:.2e} (relative to max)")
