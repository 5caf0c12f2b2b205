"""Bake → live relight inside Blender: handler, cancel, preferences operator, staleness."""

from __future__ import annotations

import os
import threading
import time

import bpy
import numpy as np
import pytest
from support.scenes import box_scene, save_and_reopen

ROOT = __import__("pathlib").Path(__file__).resolve().parent.parent


def _image():
    img = bpy.data.images["Relume"]
    w, h = img.size
    px = np.empty(w * h * 4, np.float32)
    img.pixels.foreach_get(px)
    return px.reshape(h, w, 4)


def _stack_files(folder):
    return sorted(p for p in os.listdir(folder) if not p.startswith("textures"))


def test_bake_then_relight_through_the_handler(addon, prefs, blend_dir):
    import relume

    box_scene(resolution=32)
    report = addon.api.bake()
    assert report["layers"] > 0
    status = addon.api.status()
    assert status["loaded"] and status["stale"] is None and status["bake_state"] == "done"
    before = _image().copy()
    assert np.isfinite(before).all() and (before[..., :3] >= 0).all() and before[..., :3].max() > 0
    assert np.all(before[..., 3] == 1.0)

    # Roughness through the material → depsgraph handler → new pixels.
    node = bpy.data.materials["Floor"].node_tree.nodes["Principled BSDF"]
    node.inputs["Roughness"].default_value = 0.35
    bpy.context.view_layer.update()
    after = _image()
    assert np.abs(after - before).max() > 1e-4, "the handler did not relight"

    # The image is exactly the stack relit with the mapped values (CPU reference, same stack).
    stack = relume.Stack.load(status["stack_path"])
    ref = relume.Relighter(stack, "cpu")
    for name in ("Ball", "Floor"):
        n = bpy.data.materials[name].node_tree.nodes["Principled BSDF"]
        ref.set_principled(name, tuple(n.inputs["Base Color"].default_value)[:3],
                           n.inputs["Metallic"].default_value, n.inputs["Roughness"].default_value,
                           n.inputs["IOR"].default_value, n.inputs["Specular IOR Level"].default_value)
    expected = ref.relight(flip_y=True)
    assert np.abs(after - expected).max() <= 1e-5 * max(1.0, float(expected.max()))

    # Nothing relevant changed → no relight (the handler does nothing).
    stamp = addon.runtime.RUNTIME.live.last_latency_ms
    addon.runtime.RUNTIME.live.last_latency_ms = None
    bpy.data.objects["Sphere"].select_set(True)
    bpy.context.view_layer.update()
    assert addon.runtime.RUNTIME.live.last_latency_ms is None
    del stamp


def test_override_values_relight(addon, prefs, blend_dir):
    box_scene(resolution=24)
    addon.api.bake()
    before = _image().copy()
    props = bpy.data.materials["Ball"].relume
    props.kd = (0.0, 0.0, 0.0)
    props.ks = (0.0, 0.0, 0.0)
    props.override = True
    bpy.context.view_layer.update()
    after = _image()
    # A black ball: its pixels lose all their light, the rest changes by less.
    assert after[..., :3].sum() < before[..., :3].sum()


def test_cancel_mid_bake_then_rerun_leaves_one_valid_stack(addon, prefs, blend_dir):
    import relume

    box_scene(resolution=64)
    prefs.spp = 1024  # seconds of work: long enough to cancel at 30 %
    folder = blend_dir / "relume"

    t0 = [None]

    def cancel_halfway(session):
        if float(session.progress.get("fraction", 0.0)) >= 0.3 and t0[0] is None:
            t0[0] = time.perf_counter()
            addon.api.cancel_bake()

    with pytest.raises(addon.api.BakeError, match="cancelled"):
        addon.api.bake(progress=cancel_halfway)
    assert time.perf_counter() - t0[0] < 1.0, "cancel took a second or more"
    assert not folder.exists() or _stack_files(folder) == [], "a cancelled first bake left files"

    prefs.spp = 4
    addon.api.bake()
    files = _stack_files(folder)
    assert len(files) == 1 and files[0].endswith(".relume.exr"), files
    stack = relume.Stack.load(str(folder / files[0]))
    stack.check_scene(addon.api.export().scene)

    # Cancelling a rebake keeps the complete stack as it was.
    before = (folder / files[0]).read_bytes()
    prefs.spp = 1024
    t0[0] = None
    with pytest.raises(addon.api.BakeError, match="cancelled"):
        addon.api.bake(progress=cancel_halfway)
    assert _stack_files(folder) == files
    assert (folder / files[0]).read_bytes() == before


def test_cancel_from_another_thread(addon, prefs, blend_dir):
    box_scene(resolution=64)
    prefs.spp = 4096  # minutes of work: only the cancel can end it within the test
    cancelled_at = []

    def cancel_once_running():
        deadline = time.perf_counter() + 60
        while time.perf_counter() < deadline:
            session = addon.runtime.RUNTIME.session
            if session is not None and session.state == "running":
                time.sleep(0.3)
                cancelled_at.append(time.perf_counter())
                assert addon.api.cancel_bake()
                return
            time.sleep(0.01)

    t = threading.Thread(target=cancel_once_running)
    t.start()
    try:
        with pytest.raises(addon.api.BakeError, match="cancelled"):
            addon.api.bake()
        assert cancelled_at and time.perf_counter() - cancelled_at[0] < 1.5
    finally:
        t.join()
    assert not (blend_dir / "relume").exists() or _stack_files(blend_dir / "relume") == []


def test_preferences_bake_operator(addon, prefs, blend_dir):
    box_scene(resolution=24)
    assert bpy.ops.relume.bake() == {"FINISHED"}
    status = addon.api.status()
    assert status["loaded"] and os.path.exists(status["stack_path"])
    assert status["stack_path"].startswith(str(blend_dir / "relume"))


def test_stale_stack_detected_and_never_used(addon, prefs, blend_dir):
    box_scene(resolution=24)
    addon.api.bake()
    out = blend_dir / "ok.exr"
    addon.api.render(str(out))
    assert out.exists()
    bpy.data.objects["Key"].location.z = 1.5  # moving the light changes the bake
    bpy.context.view_layer.update()
    status = addon.api.status()
    assert status["stale"] is not None
    with pytest.raises(addon.api.BakeError, match="stale"):
        addon.api.render(str(blend_dir / "stale.exr"))
    # An operator that reports an error raises RuntimeError when called from Python.
    with pytest.raises(RuntimeError, match="stale"):
        bpy.ops.relume.render(filepath=str(blend_dir / "stale.exr"))
    assert not (blend_dir / "stale.exr").exists()
    # Toggling editability also changes what the stack holds.
    bpy.data.objects["Key"].location.z = 1.95
    bpy.context.view_layer.update()
    assert addon.api.status()["stale"] is None
    bpy.data.materials["Walls"].relume.editable = True
    bpy.context.view_layer.update()
    assert addon.api.status()["stale"] is not None


def test_stack_reloaded_when_the_file_opens(addon, prefs, blend_dir):
    box_scene(resolution=24)
    addon.api.bake()
    status = save_and_reopen(addon)
    assert status["loaded"] and status["stale"] is None, status
    assert "Relume" in bpy.data.images


def test_cornell_from_the_preferences_button_cancelled_halfway_then_rerun(addon, prefs, blend_dir):
    """The issue's check: the assets Cornell scene baked by the Bake operator (the button in
    the preferences and the Image Editor panel), cancelled halfway, then rerun to completion,
    leaves exactly one valid stack."""
    import relume
    from support.scene_import import import_scene

    import_scene(ROOT / "assets" / "cornell.scene.json", resolution=(128, 128))
    prefs.preset = "preview"
    folder = blend_dir / "relume"
    seen = []

    def cancel_halfway():
        deadline = time.perf_counter() + 120
        while time.perf_counter() < deadline:
            session = addon.runtime.RUNTIME.session
            if session is not None and session.state == "running":
                frac = float(session.progress.get("fraction", 0.0))
                if frac >= 0.5:
                    seen.append((frac, time.perf_counter()))
                    addon.api.cancel_bake()
                    return
            time.sleep(0.005)

    t = threading.Thread(target=cancel_halfway)
    t.start()
    try:
        assert bpy.ops.relume.bake() == {"CANCELLED"}
    finally:
        t.join()
    assert seen and 0.5 <= seen[0][0] < 1.0, seen
    assert time.perf_counter() - seen[0][1] < 1.5
    assert addon.api.status()["bake_state"] == "cancelled"
    assert not folder.exists() or _stack_files(folder) == [], "the cancelled bake left files"

    assert bpy.ops.relume.bake() == {"FINISHED"}
    files = _stack_files(folder)
    assert len(files) == 1 and files[0].endswith(".relume.exr"), files
    stack = relume.Stack.load(str(folder / files[0]))
    stack.check_scene(addon.api.export().scene)
    assert stack.editable_regions == ["Object", "White walls"]
    assert (stack.width, stack.height) == (128, 128)
    image = _image()
    assert np.isfinite(image).all() and image[..., :3].max() > 0


def test_material_lobes_preference_reaches_the_bake_settings(addon, prefs):
    """The preference picks the basis editable Principled materials are baked in, with a
    preset or custom samples alike (the `prefs` fixture restores it)."""
    assert addon.api.bake_settings().lobe == "blinn-phong"
    prefs.material_lobes = "principled"
    assert addon.api.bake_settings().lobe == "principled"
    prefs.preset = "final"
    assert addon.api.bake_settings().lobe == "principled"
