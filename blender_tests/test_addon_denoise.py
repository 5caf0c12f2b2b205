"""The shown image in Blender: raw while a slider moves, through OpenImageDenoise (Blender's
own copy, here the bpy wheel's `bpy/lib`) with the scene's albedo and normal features once
the edits settle, and raw everywhere when the preference *Denoise Shown Image* is off; then,
with *Refine After Edits*, refined on the same worker until the next edit.

Headless there is no event loop, so no timer fires: the tests call `show_settled` (the
settled step done at once) and the worker-thread path's start and poll functions as the
timers would.
"""

from __future__ import annotations

import os
import time

import bpy
import numpy as np
from support.scenes import box_scene


def _image():
    img = bpy.data.images["Relume"]
    w, h = img.size
    px = np.empty(w * h * 4, np.float32)
    img.pixels.foreach_get(px)
    return px.reshape(h, w, 4)


def _edit_floor(roughness: float) -> None:
    inputs = bpy.data.materials["Floor"].node_tree.nodes["Principled BSDF"].inputs
    inputs["Roughness"].default_value = roughness
    bpy.context.view_layer.update()


def test_the_settled_image_is_blenders_oidn_and_the_preference_turns_it_off(addon, prefs, blend_dir,
                                                                           tmp_path):
    import relume  # the add-on's wheel, installed by the `addon` fixture

    live = addon.runtime.RUNTIME.live
    box_scene(resolution=32)
    addon.api.bake()
    assert any(os.path.isfile(os.path.join(d, "libOpenImageDenoise.so.2")) for d in live.oidn_dirs), \
        f"Blender's lib folder not among {live.oidn_dirs}"
    saved = prefs.denoise
    try:
        prefs.denoise = True
        _edit_floor(0.3)
        raw = _image()
        # While the slider moves: the raw relit image, exactly the relighter's sum.
        assert np.array_equal(raw, live.relighter.relight(flip_y=True))
        # Settled: the same relight through OIDN with the features.
        assert addon.live_image.show_settled()
        shown = _image()
        status = addon.api.status()["denoise"]
        assert (status["ran"], status["features"], status["note"]) == ("oidn", "albedo+normal", None), status
        assert os.path.dirname(status["library"]) in live.oidn_dirs, status
        assert np.isfinite(shown).all() and not np.array_equal(shown, raw)
        assert status["quality"] == "balanced"  # the live image: OIDN's interactive mode
        assert np.array_equal(shown, live.relighter.relight(flip_y=True, denoise="oidn",
                                                            oidn_dirs=live.oidn_dirs,
                                                            oidn_quality="balanced"))
        # The operator writes the shown image at OIDN's high quality and says so.
        out = tmp_path / "shown.exr"
        assert bpy.ops.relume.render(filepath=str(out)) == {"FINISHED"}
        assert addon.api.status()["denoise"]["quality"] == "high"
        high = live.relighter.relight(flip_y=True, denoise="oidn", oidn_dirs=live.oidn_dirs)
        written = np.asarray(relume.read_exr(str(out)))[::-1]
        assert np.allclose(written[..., :3], high[..., :3], rtol=1e-6, atol=1e-7)

        # Off: nothing is denoised, the render is the exact relit image, and status says so.
        prefs.denoise = False
        _edit_floor(0.5)
        assert not addon.live_image.show_settled()
        raw = _image()
        assert np.array_equal(raw, live.relighter.relight(flip_y=True))
        addon.api.render(str(tmp_path / "raw.exr"))
        assert addon.api.status()["denoise"]["ran"] == "none"
        written = np.asarray(relume.read_exr(str(tmp_path / "raw.exr")))[::-1]
        assert np.allclose(written[..., :3], raw[..., :3], rtol=1e-6, atol=1e-7)
    finally:
        prefs.denoise = saved


def _wait_for_worker(runtime, timeout: float = 60.0) -> None:
    t0 = time.monotonic()
    while runtime.settled_result is None:
        assert time.monotonic() - t0 < timeout, "the denoise worker gave no result"
        time.sleep(0.01)


def test_the_worker_threads_image_is_written_unless_an_edit_came_meanwhile(addon, prefs, blend_dir):
    runtime = addon.runtime.RUNTIME
    live, live_image = runtime.live, addon.live_image
    box_scene(resolution=32)
    addon.api.bake()
    saved = prefs.denoise, prefs.refine
    try:
        prefs.denoise, prefs.refine = True, False
        _edit_floor(0.35)
        raw = _image()
        # Settled, OIDN on the worker thread; the poll (the timer's function) writes it.
        runtime.settle.touch()
        live_image._start_settled_worker()
        _wait_for_worker(runtime)
        assert live_image._poll_settled() is None
        denoised = _image()
        assert live.last_denoise["ran"] == "oidn" and not np.array_equal(denoised, raw)
        # An edit while the worker runs: its image is out of date and not written.
        _edit_floor(0.55)
        raw = _image()
        live_image._start_settled_worker()
        runtime.settle.touch()  # the edit's generation
        _wait_for_worker(runtime)
        live_image._poll_settled()
        assert np.array_equal(_image(), raw)
    finally:
        prefs.denoise, prefs.refine = saved


def test_the_worker_refines_the_settled_edit_until_the_next(addon, prefs, blend_dir):
    runtime = addon.runtime.RUNTIME
    live, live_image = runtime.live, addon.live_image
    box_scene(resolution=32)
    prefs.bounces = 3  # a tail to refine (the fixture's settings bake one bounce)
    addon.api.bake()
    saved = prefs.denoise, prefs.refine
    try:
        prefs.denoise, prefs.refine = False, True
        _edit_floor(0.12)  # a roughness edit: what the tail-edit layers cannot follow
        live_image.relight_now(force=True)
        raw = _image()
        runtime.settle.touch()
        live_image._start_settled_worker()
        runtime.settled_worker.join(timeout=120)
        assert not runtime.settled_worker.is_alive()
        assert live_image._poll_settled() is None
        report = live.last_refine
        assert report["needed"] and report["passes"] >= report["bake_samples"], report
        assert live.refine_status() == f"Refined: {report['passes']} passes"
        refined = _image()
        assert np.isfinite(refined).all() and not np.array_equal(refined, raw)
        # The shown image is the relit one plus the refinement of exactly these values.
        again = live.relighter.relight(flip_y=True, refined=True)
        assert np.array_equal(refined, again)
        # An edit: the worker's refinement is not added to the next values' image.
        _edit_floor(0.7)
        live_image.relight_now(force=True)
        assert np.array_equal(live.relighter.relight(flip_y=True, refined=True), _image())
    finally:
        prefs.denoise, prefs.refine = saved
