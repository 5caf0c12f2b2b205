"""The add-on's bpy-free logic (addon/relume/logic), loaded straight from the source tree."""

from __future__ import annotations

import importlib.util
import math
import pathlib
import sys

import pytest

LOGIC = pathlib.Path(__file__).resolve().parent.parent / "addon" / "relume" / "logic"


def _load():
    spec = importlib.util.spec_from_file_location(
        "relume_logic", LOGIC / "__init__.py", submodule_search_locations=[str(LOGIC)])
    pkg = importlib.util.module_from_spec(spec)
    sys.modules["relume_logic"] = pkg
    spec.loader.exec_module(pkg)
    return pkg


_load()
from relume_logic import (  # noqa: E402
    bake_settings_map,  # noqa: F401  (tested in test_bake_settings_map.py)
    camera_map,
    light_groups,
    lights_map,
    material_map,
    oidn_dirs,
    settle,
    stack_paths,
    throttle,
)
from relume_logic.bake_session import format_eta  # noqa: E402
from relume_logic.export_warnings import WarningList  # noqa: E402

IDENTITY = [[1.0, 0, 0, 0], [0, 1.0, 0, 0], [0, 0, 1.0, 0], [0, 0, 0, 1.0]]


def test_throttle_lets_one_through_per_interval_and_keeps_the_last_pending():
    now = [0.0]
    t = throttle.Throttle(0.1, clock=lambda: now[0])
    assert t.request() and not t.pending
    now[0] = 0.05
    assert not t.request() and t.pending
    assert t.remaining() == pytest.approx(0.05)
    now[0] = 0.1
    assert t.request() and not t.pending
    with pytest.raises(ValueError):
        throttle.Throttle(float("nan"))


def test_stack_paths():
    f, temp = stack_paths.stack_folder("/p/shots/a.blend", "", "/tmp")
    assert (f, temp) == ("/p/shots/relume", False)
    assert stack_paths.stack_folder("/p/shots/a.blend", "//cache", "/tmp")[0] == "/p/shots/cache"
    assert stack_paths.stack_folder("/p/shots/a.blend", "/farm/stacks", "/tmp") == ("/farm/stacks", False)
    assert stack_paths.stack_folder("", "", "/tmp") == ("/tmp/relume", True)
    assert stack_paths.stack_file_name("/p/a b.blend", "Scene/1") == "a_b.Scene_1.relume.exr"


def _area(**kw):
    base = dict(name="A", type="AREA", matrix_world=[r[:] for r in IDENTITY], energy=100.0,
                color=(1.0, 1.0, 1.0))
    base.update(kw)
    return lights_map.BlenderLight(**base)


def test_area_light_scale_exposure_normalize_and_spread():
    w = WarningList()
    m = [[2.0, 0, 0, 1], [0, 3.0, 0, 2], [0, 0, 1.0, 3], [0, 0, 0, 1]]
    out = lights_map.map_light(_area(matrix_world=m, shape="RECTANGLE", size=0.5, size_y=0.2,
                                     exposure=1.0, normalize=False, spread=math.radians(60)), w)
    assert out["size_x"] == pytest.approx(1.0) and out["size_y"] == pytest.approx(0.6)
    assert out["power"] == pytest.approx(100.0 * 2.0 * 0.6)  # exposure ×2, normalize off × area
    assert out["position"] == [1, 2, 3]
    assert any("Spread" in str(x) for x in w.items())


def test_zero_power_light_is_left_out_with_a_warning():
    w = WarningList()
    assert lights_map.map_light(_area(energy=0.0), w) is None
    assert "zero power" in str(w.items()[0])


def test_spot_direction_and_elliptic_warning():
    w = WarningList()
    m = [[1.0, 0, 0, 0], [0, 2.0, 0, 0], [0, 0, 1.0, 0], [0, 0, 0, 1]]
    out = lights_map.map_light(lights_map.BlenderLight(
        name="S", type="SPOT", matrix_world=m, energy=10, color=(1, 1, 1), spot_size=1.0), w)
    assert out["direction"] == pytest.approx([0, 0, -1])
    assert any("elliptical" in str(x) for x in w.items())


def test_temperature_tints_colour():
    w = WarningList()
    out = lights_map.map_light(lights_map.BlenderLight(
        name="P", type="POINT", matrix_world=IDENTITY, energy=10, color=(1, 0.5, 1),
        temperature_rgb=(1.0, 0.8, 0.6)), w)
    assert out["color"] == pytest.approx([1.0, 0.4, 0.6])


def test_camera_mapping():
    w = WarningList()
    cam = camera_map.BlenderCamera(name="C", type="PERSP",
                                   matrix_world=[[2, 0, 0, 1], [0, 2, 0, 2], [0, 0, 2, 3], [0, 0, 0, 1]],
                                   use_dof=True)
    out = camera_map.map_camera(cam, w)
    assert out["matrix_world"][0][:3] == pytest.approx([1, 0, 0])
    assert out["matrix_world"][2][3] == 3
    assert any("depth of field" in str(x) for x in w.items())
    with pytest.raises(camera_map.CameraError, match="panoramic"):
        camera_map.map_camera(camera_map.BlenderCamera(name="C", type="PANO", matrix_world=IDENTITY), w)
    mirrored = [[-1.0, 0, 0, 0], [0, 1.0, 0, 0], [0, 0, 1.0, 0], [0, 0, 0, 1]]
    with pytest.raises(camera_map.CameraError, match="mirrored"):
        camera_map.map_camera(camera_map.BlenderCamera(name="C", type="PERSP", matrix_world=mirrored), w)


def test_material_mapping_rules():
    SN = material_map.SurfaceNodes
    w = WarningList()
    diffuse, tex = material_map.map_material(SN("D", material_map.DIFFUSE, values={"Color": (0.2, 0.3, 0.4, 1)}), w)
    assert diffuse == {"model": "blinn_phong", "kd": [0.2, 0.3, 0.4], "ks": [0, 0, 0], "ns": 1.0}
    assert not tex and len(w) == 0  # exact, not a fallback
    # A Diffuse colour above 1 (Blender allows it) is clamped with a warning: the core refuses
    # Kd > 1 in a scene as in a materials file.
    bright, _ = material_map.map_material(SN("B", material_map.DIFFUSE, values={"Color": (2.0, 0.3, 0.4, 1)}), w)
    assert bright["kd"] == [1.0, 0.3, 0.4] and len(w) == 1
    w = WarningList()

    w = WarningList()
    mat, tex = material_map.map_material(SN(
        "P", material_map.PRINCIPLED,
        values={"Base Color": (0.5, 0.5, 0.5, 1), "Roughness": 0.3, "Metallic": 0.2, "Alpha": 0.5},
        links={"Base Color": material_map.IMAGE_TEXTURE, "Roughness": "ShaderNodeTexNoise"},
        base_color_image=object()), w)
    assert tex and mat["base_color"] == [1.0, 1.0, 1.0]
    text = " | ".join(str(x) for x in w.items())
    assert "Roughness linked to ShaderNodeTexNoise" in text
    assert "Alpha 0.5" in text and "metallic with a Base Color texture" in text

    # An Emission shader reflects nothing (its light is exported as an emissive light).
    w = WarningList()
    black, _ = material_map.map_material(SN("E", material_map.EMISSION), w)
    assert black == {"model": "blinn_phong", "kd": [0.0, 0.0, 0.0], "ks": [0.0, 0.0, 0.0], "ns": 1.0}
    # A shader the exporter cannot map falls back with a warning naming it.
    w = WarningList()
    fallback, _ = material_map.map_material(SN("T", "ShaderNodeBsdfToon"), w)
    assert fallback == material_map.FALLBACK_PRINCIPLED
    assert "ShaderNodeBsdfToon" in str(w.items()[0])


def test_eta_format():
    assert format_eta(None) == "estimating…"
    assert format_eta(5.4) == "5 s"
    assert format_eta(125) == "2 min 05 s"


def test_scene_light_groups_from_blender_light_groups():
    # Lights 0 and 2 in "Key", light 1 in none, light 3 in a group named like the core's
    # default group (the same thing as none), the world in "Sky"; groups sorted by name.
    groups = light_groups.scene_light_groups(["Key", "", "Key", "default", "Rim"], "Sky")
    assert groups == [
        {"name": "Key", "lights": [0, 2], "world": False},
        {"name": "Rim", "lights": [4], "world": False},
        {"name": "Sky", "lights": [], "world": True},
    ]
    # The world in a group with lights; no world at all; nothing grouped → no key to write.
    assert light_groups.scene_light_groups(["A"], "A") == [{"name": "A", "lights": [0], "world": True}]
    assert light_groups.scene_light_groups(["A"], None) == [{"name": "A", "lights": [0], "world": False}]
    assert light_groups.scene_light_groups(["", "default"], "") == []


def test_light_group_gain_checks_and_messages():
    assert light_groups.Gain(2, [1, 0.5, 0]).checked("g") == light_groups.Gain(2.0, (1.0, 0.5, 0.0))
    for bad in (light_groups.Gain(-1.0), light_groups.Gain(1.0, (1.0, float("nan"), 1.0)),
                light_groups.Gain(float("inf"))):
        with pytest.raises(ValueError, match="light group 'g': strength and color must be finite"):
            bad.checked("g")
    with pytest.raises(ValueError, match="color needs 3 components"):
        light_groups.Gain(1.0, (1.0, 1.0)).checked("g")
    assert light_groups.unknown_group_message("x", ["a", "b"]) == \
        "light group 'x' is not in the loaded stack (its groups: a, b)"
    assert "has no light groups" in light_groups.unknown_group_message("x", [])
    assert light_groups.cost_text(3) == "3 light groups: stack and relight cost ×3"
    assert light_groups.cost_text(1) == "1 light group: stack and relight cost ×1"
    assert light_groups.GROUPING_OF_PREF == {"none": "all", "per_light": "per-light", "scene": "scene"}


def test_light_group_labels_name_the_blender_light():
    names = ["Key", "Fill"]
    assert light_groups.group_label("light 1", names) == "light 1 (Fill)"
    assert light_groups.group_label("light 7", names) == "light 7"  # stack and scene differ
    assert light_groups.group_label("world", names) == "world"
    assert light_groups.group_label("default", names).startswith("default (")
    assert light_groups.group_label("Sky", names) == "Sky"


def test_bake_summary_names_layers_bytes_and_compression_error():
    # The keys are the core's BakeReport fields (bake/report.rs), as relume.BakeJob.result()
    # hands them over under "report".
    from relume_logic.bake_summary import bake_summary

    line = bake_summary({"seconds": 12.34, "report": {
        "layers_possible": 6643, "layers_grey": 3500, "layers_rgb": 60,
        "stored_bytes": 342_800_000, "dense_bytes": 14_764_000_000, "compression_error": 0.00051}})
    assert line == ("baked in 12.3 s · 3560 of 6643 layers · 343 MB (14764 MB as full frames) · "
                    "compression error 0.05 %")
    # A bake without compression or a tiled report (a merge, older bindings) says only what it has.
    assert bake_summary({"seconds": 1.0, "report": {"compression_error": 0.0}}) == "baked in 1.0 s"
    assert bake_summary({}) == "baked in 0.0 s"
    # Values a stage kept out of the stack (bake/non_finite.rs) are said, not hidden.
    kept = bake_summary({"seconds": 1.0, "report": {"non_finite": {
        "path_contributions": 3, "layer_values": 0, "lattice_fits": 1, "stored_values": 0}}})
    assert kept == "baked in 1.0 s · 4 non-finite values kept out (see warnings)"
    clean = {"path_contributions": 0, "layer_values": 0, "lattice_fits": 0, "stored_values": 0}
    assert bake_summary({"seconds": 1.0, "report": {"non_finite": clean}}) == "baked in 1.0 s"


def test_settle_is_due_a_delay_after_the_last_edit_and_each_edit_pushes_it_back():
    now = [0.0]
    s = settle.Settle(delay=0.3, clock=lambda: now[0])
    assert not s.pending and not s.take()
    s.touch()
    now[0] = 0.2
    assert s.pending and not s.take() and abs(s.remaining() - 0.1) < 1e-9
    s.touch()  # another edit at 0.2: due at 0.5, and a denoise of generation 1 is out of date
    assert s.generation == 2
    now[0] = 0.45
    assert not s.take()
    now[0] = 0.5
    assert s.take() and not s.pending and not s.take()
    with pytest.raises(ValueError):
        settle.Settle(delay=float("nan"))


def test_blender_lib_dirs_find_the_folders_holding_oidn(tmp_path):
    # A Linux install: the binary's lib folder.
    install = tmp_path / "blender-5.0"
    (install / "lib").mkdir(parents=True)
    (install / "lib" / "libOpenImageDenoise.so.2").write_bytes(b"")
    # The bpy wheel: bpy/lib, found from the scripts' bpy package four levels below it.
    wheel = tmp_path / "site" / "bpy"
    scripts_bpy = wheel / "5.0" / "scripts" / "modules" / "bpy"
    scripts_bpy.mkdir(parents=True)
    (wheel / "lib").mkdir()
    (wheel / "lib" / "libOpenImageDenoise.so.2").write_bytes(b"")
    (tmp_path / "site" / "lib").mkdir()  # a lib folder without OIDN is passed over
    dirs = oidn_dirs.blender_lib_dirs(str(install / "blender"), str(scripts_bpy / "__init__.py"))
    assert dirs == [str(install / "lib"), str(wheel / "lib")]
    assert oidn_dirs.blender_lib_dirs("", None) == []
