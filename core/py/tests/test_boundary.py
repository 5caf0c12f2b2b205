"""The Python boundary: specific exceptions, panics caught, the GIL released, stubs complete."""

from __future__ import annotations

import ast
import json
import pathlib
import threading
import time

import numpy as np
import pytest
import relume

ROOT = pathlib.Path(__file__).resolve().parents[3]
STUBS = pathlib.Path(__file__).resolve().parents[1] / "python" / "relume" / "_core.pyi"


def test_panic_on_the_calling_thread_is_an_internal_error():
    with pytest.raises(relume.InternalError, match="debug panic"):
        relume._debug_panic()
    # The process lives on and the module still works.
    assert relume.principled_to_blinn_phong((0.5, 0.5, 0.5))["ns"] > 0


def test_panic_in_a_worker_thread_is_an_internal_error():
    with pytest.raises(relume.InternalError, match="worker thread"):
        relume._debug_panic(in_thread=True)


def test_error_classes_form_one_hierarchy():
    for name in ("SceneError", "StackError", "StaleStackError", "TruncatedStackError",
                 "ForeignStackError", "StackVersionError", "CancelledError", "MaterialsError",
                 "BasisError", "DeviceError", "RelumeIOError", "InternalError"):
        assert issubclass(getattr(relume, name), relume.RelumeError), name
    assert issubclass(relume.StaleStackError, relume.StackError)
    assert issubclass(relume.RelumeIOError, OSError)


def test_bad_scenes_name_what_is_wrong(tmp_path):
    with pytest.raises(relume.RelumeIOError):
        relume.Scene.load(str(tmp_path / "missing.scene.json"))
    with pytest.raises(relume.SceneError):
        relume.Scene.from_json("{not json")
    scene = relume.Scene.from_json(json.dumps({
        "format": "relume-scene", "version": 1, "meshes": [],
        "regions": [{"name": "A", "editable": True, "material": {"model": "blinn_phong",
                     "kd": [0.5, 0.5, 0.5], "ks": [0, 0, 0], "ns": 1}}],
        "camera": json.loads((ROOT / "assets" / "cornell.scene.json").read_text())["camera"],
        "resolution": {"width": 8, "height": 8}}))
    pos = np.array([[0, 0, 0], [1, 0, 0], [np.nan, 1, 0]], np.float32)
    scene.add_mesh("Bad", pos, np.array([[0, 1, 2]]))
    with pytest.raises(relume.SceneError, match="Bad"):
        scene.validate()
    with pytest.raises(relume.SceneError, match="positions"):
        scene.add_mesh("Shape", np.zeros((3, 2), np.float32), np.array([[0, 1, 2]]))


def test_foreign_and_truncated_stacks(tmp_path, small_cornell):
    img = tmp_path / "plain.exr"
    relume.write_exr(str(img), np.ones((4, 4, 3), np.float32))
    with pytest.raises(relume.ForeignStackError):
        relume.Stack.load(str(img))
    path = tmp_path / "s.relume.exr"
    relume.bake(small_cornell, relume.BakeSettings(spp=1, light_samples=1), str(path))
    data = path.read_bytes()
    cut = tmp_path / "cut.relume.exr"
    cut.write_bytes(data[: len(data) // 2])
    with pytest.raises(relume.TruncatedStackError):
        relume.Stack.load(str(cut))
    stack = relume.Stack.load(str(path))
    stack.check_scene(small_cornell)
    rel = relume.Relighter(stack, "cpu")
    with pytest.raises(relume.MaterialsError, match="Tall box"):
        rel.set_material("Tall box", 0.5, 0.0, 1.0)  # a fixed region
    with pytest.raises(relume.MaterialsError):
        rel.set_material("Object", 0.8, 0.5, 10.0)  # Kd + Ks > 1


def test_bake_wait_releases_the_gil(tmp_path, small_cornell):
    """A Python thread keeps running while the main thread waits on a bake."""
    ticks = []
    stop = threading.Event()

    def ticker():
        while not stop.is_set():
            ticks.append(time.perf_counter())
            time.sleep(0.005)

    t = threading.Thread(target=ticker)
    t.start()
    try:
        job = relume.BakeJob(small_cornell, relume.BakeSettings(spp=8, light_samples=2),
                             str(tmp_path / "gil.relume.exr"))
        t0 = time.perf_counter()
        job.wait()
        waited = time.perf_counter() - t0
        job.result()
    finally:
        stop.set()
        t.join()
    during = [x for x in ticks if t0 <= x <= t0 + waited]
    # With the GIL held the ticker could not run at all while waiting.
    assert waited < 0.05 or len(during) >= 3, (waited, len(during))


def test_cancel_stops_within_a_second_and_writes_nothing(tmp_path, small_cornell):
    path = tmp_path / "c.relume.exr"
    job = relume.BakeJob(small_cornell, relume.BakeSettings(spp=4096, light_samples=4,
                                                            resolution=(128, 128)), str(path))
    while job.progress["fraction"] <= 0.01 and not job.done:
        time.sleep(0.01)
    t0 = time.perf_counter()
    job.cancel()
    assert job.wait(5.0)
    assert time.perf_counter() - t0 < 1.0
    with pytest.raises(relume.CancelledError):
        job.result()
    assert not path.exists()
    assert [p.name for p in tmp_path.iterdir()] == []  # no temporary file left either


def test_progress_callback_can_cancel(tmp_path, small_cornell):
    calls = []

    def progress(p):
        calls.append(p["fraction"])
        return len(calls) < 2

    with pytest.raises(relume.CancelledError):
        relume.bake(small_cornell, relume.BakeSettings(spp=4096, resolution=(128, 128)),
                    str(tmp_path / "x.relume.exr"), progress)
    assert len(calls) >= 2


def test_presets_are_ordered_and_overridable():
    d, p, f = (relume.BakeSettings.preset(n) for n in ("draft", "preview", "final"))
    assert d.spp < p.spp < f.spp
    assert f.basis_tolerance < p.basis_tolerance < d.basis_tolerance
    assert d.resolution_scale < 1.0 == p.resolution_scale
    o = relume.BakeSettings.preset("preview", bounces=0, spp=3)
    assert (o.bounces, o.spp, o.basis_tolerance) == (0, 3, p.basis_tolerance)
    with pytest.raises(ValueError, match="ultra"):
        relume.BakeSettings.preset("ultra")
    with pytest.raises(ValueError, match="spp"):
        relume.BakeSettings(spp=0)



def test_compression_is_a_setting_judged_by_the_engines_rules():
    assert relume.BakeSettings().compression_step == 0
    f = relume.BakeSettings.preset("final")
    assert f.compression_step > 0 and 0 < f.compression_tolerance < 0.02
    off = relume.BakeSettings.preset("final", compression_step=0)
    assert off.compression_step == 0
    s = relume.BakeSettings(compression_step=8)
    assert (s.compression_step, s.compression_tolerance) == (8, pytest.approx(0.02))
    for field, value in (("compression_step", 17), ("compression_tolerance", 1.5),
                         ("compression_step", -1)):
        with pytest.raises(ValueError, match=field):
            setattr(s, field, value)
    # A refused value leaves the settings as they were.
    assert (s.compression_step, s.compression_tolerance) == (8, pytest.approx(0.02))

def test_bake_settings_keywords_are_the_engines_fields_and_bad_ones_are_named():
    s = relume.BakeSettings(subsurface_theta=0.3, resolution="64x32", light_grouping="scene")
    assert (s.subsurface_theta, s.resolution, s.light_grouping) == (pytest.approx(0.3), [64, 32], "scene")
    assert relume.BakeSettings(**s.to_dict()) == s
    for kwargs, words in (({"spp": 0}, "BakeSettings.spp"), ({"spp": "many"}, "BakeSettings.spp"),
                          ({"sampling": "best"}, "uniform"), ({"seed": float("nan")}, "BakeSettings.seed"),
                          ({"spp_count": 1}, "no such bake setting"),
                          ({"bases": 7, "basis_tolerance": 0.1}, "not both"),
                          ({"passes": 0}, "BakeSettings.passes")):
        with pytest.raises(ValueError, match=words):
            relume.BakeSettings(**kwargs)


def test_stubs_declare_exactly_the_module():
    tree = ast.parse(STUBS.read_text())
    declared = set()
    for node in tree.body:
        if isinstance(node, (ast.ClassDef, ast.FunctionDef)):
            declared.add(node.name)
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            declared.add(node.target.id)
    public = {n for n in dir(relume._core) if not n.startswith("__") or n == "__version__"}
    public -= {"_core"}
    declared -= {"_Path", "_Rgb", "_Device", "_Denoise"}
    assert public == declared, (sorted(public - declared), sorted(declared - public))
    # Methods too: every public method or property of each class is in its stub.
    for node in tree.body:
        if isinstance(node, ast.ClassDef) and not node.name.endswith("Error"):
            cls = getattr(relume._core, node.name)
            stub_members = {n.name for n in node.body if isinstance(n, ast.FunctionDef)} | \
                {n.target.id for n in node.body if isinstance(n, ast.AnnAssign)}
            real = {n for n in dir(cls) if not n.startswith("_")}
            if node.name == "BakeSettings":
                real |= set(relume.BakeSettings().to_dict())
            assert real <= stub_members | {"to_dict"}, (node.name, sorted(real - stub_members))


def _hostile_module():
    import importlib.util

    spec = importlib.util.spec_from_file_location("hostile_stack", ROOT / "scripts" / "hostile_stack.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_a_stack_claiming_huge_pixels_raises_and_the_interpreter_lives(tmp_path, small_cornell):
    path = tmp_path / "s.relume.exr"
    relume.bake(small_cornell, relume.BakeSettings(spp=1, light_samples=1), str(path))
    hostile = tmp_path / "hostile.relume.exr"
    hostile.write_bytes(_hostile_module().with_claimed_size(path.read_bytes(), 16384, 16384))
    with pytest.raises(relume.TruncatedStackError, match="claims 16384×16384 pixels"):
        relume.Stack.load(str(hostile))
    # Still alive, and the good file still loads.
    assert relume.Stack.load(str(path)).layer_count > 0


def test_a_bake_over_budget_is_refused_before_tracing(tmp_path, small_cornell):
    assert issubclass(relume.OutOfMemoryError, MemoryError)
    # At half a MiB the scene's geometry alone is over the budget: refused before its BVH
    # is built; with room for the geometry, the layer probe's forecast refuses the bake.
    settings = relume.BakeSettings(spp=1, light_samples=1, memory_budget_mb=0.5)
    with pytest.raises(relume.OutOfMemoryError, match="this scene's geometry"):
        relume.bake(small_cornell, settings, str(tmp_path / "s.relume.exr"))
    settings = relume.BakeSettings(spp=1, light_samples=1, memory_budget_mb=12.0)
    with pytest.raises(relume.OutOfMemoryError, match="layers reached by a probe"):
        relume.bake(small_cornell, settings, str(tmp_path / "s.relume.exr"))
    assert not (tmp_path / "s.relume.exr").exists()
    with pytest.raises(relume.RelumeError, match="each side must be 1…65536"):
        relume.bake(small_cornell, relume.BakeSettings(resolution=(60000, 60000), resolution_scale=2.0),
                    str(tmp_path / "t.relume.exr"))


def test_python_refuses_materials_in_the_command_lines_words(tmp_path, small_cornell):
    """The same texts as core/cli/tests/cli.rs::the_command_line_refuses_the_materials_python_refuses."""
    path = tmp_path / "s.relume.exr"
    relume.bake(small_cornell, relume.BakeSettings(spp=1, light_samples=1), str(path))
    rel = relume.Relighter(relume.Stack.load(str(path)), "cpu")
    cases = [
        (lambda: rel.set_material("Object", 0.75, 0.5, 10.0),
         'invalid region "Object".kd + ks: Kd + Ks = 1.25 > 1 in channel 0: '
         'the surface would reflect more light than it receives'),
        (lambda: rel.set_material("Object", 0.2, 0.1, 0.0),
         'invalid region "Object".ns: the Blinn–Phong exponent must be finite and > 0, got 0'),
        (lambda: rel.set_material("Object", (-0.1, 0.2, 0.2), 0.1, 5.0),
         'invalid region "Object".kd: channel 0 is negative (-0.1); albedos must be ≥ 0'),
        (lambda: rel.set_principled("Object", (0.5, 0.5, 0.5), roughness=2.0),
         'invalid region "Object".roughness: must be in [0, 1], got 2'),
        (lambda: rel.set_principled("Object", (0.5, 0.5, 0.5), metallic=5.0),
         'invalid region "Object".metallic: must be in [0, 1], got 5'),
        (lambda: rel.set_principled("Object", (0.5, 0.5, 0.5), ior=0.0),
         'invalid region "Object".ior: must be finite and > 0, got 0'),
    ]
    for call, message in cases:
        with pytest.raises(relume.MaterialsError) as info:
            call()
        assert str(info.value) == message


def test_the_estimate_is_available_before_baking(small_cornell):
    est = relume.estimate_bake(small_cornell, relume.BakeSettings(spp=1, light_samples=1))
    assert 0 < est["layers_reached"] <= est["layers_possible"]
    assert est["peak_bytes"] > est["stack_bytes"] > 0
    assert est["width"] == 32 and est["height"] == 32
