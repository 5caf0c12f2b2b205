"""Relighter.refine(): the bounces past the second traced again for the current edit and
added by relight(refined=True) — nothing at the bake-time materials, an edit's correction
that grows more passes across calls and starts anew after another edit, a cancel from
another thread, and a clear error without the scene."""

from __future__ import annotations

import json
import pathlib
import threading

import numpy as np
import pytest
import relume

ROOT = pathlib.Path(__file__).resolve().parents[3]


def _cornell(size: int):
    data = json.loads((ROOT / "assets" / "cornell.scene.json").read_text())
    data["resolution"] = {"width": size, "height": size}
    return relume.Scene.from_json(json.dumps(data), str(ROOT / "assets"))


@pytest.fixture(scope="module")
def baked(tmp_path_factory):
    """The Cornell box at 32², three bounces, 4 spp."""
    tmp = tmp_path_factory.mktemp("refine")
    scene = _cornell(32)
    path = tmp / "cornell.relume.exr"
    relume.bake(scene, relume.BakeSettings(spp=4, light_samples=1, bounces=3, seed=1), str(path))
    return scene, relume.Stack.load(str(path))


def test_the_bake_time_materials_need_no_refinement(baked):
    scene, stack = baked
    r = relume.Relighter(stack, "cpu", scene=scene)
    report = r.refine(seconds=0.0)
    assert report["needed"] is False
    assert r.relight(refined=True).tobytes() == r.relight().tobytes()


def test_an_edit_is_refined_across_calls_and_restarts_after_the_next(baked):
    scene, stack = baked
    r = relume.Relighter(stack, "cpu", scene=scene)
    r.set_material("White walls", kd=0.0, ks=0.9, ns=200.0)  # walls made mirrors
    relit = r.relight()
    first = r.refine(seconds=0.0, max_passes=1)
    assert first["needed"] is True and first["passes"] == 1 and first["bake_samples"] == 4
    assert r.refine(seconds=0.0)["passes"] == 2  # at least one pass, continued
    again = r.refine(seconds=600.0, max_passes=3)
    assert again["passes"] == 3  # continued, not restarted, and stopped at max_passes
    refined = r.relight(refined=True)
    assert np.isfinite(refined).all()
    assert not np.array_equal(refined, relit)
    # Another edit: the old refinement is not added to it, and refining starts from 0.
    r.set_material("White walls", kd=0.5, ks=0.0, ns=1.0)
    assert r.relight(refined=True).tobytes() == r.relight().tobytes()
    assert r.refine(seconds=0.0, max_passes=1)["passes"] == 1


def test_cancel_from_another_thread_keeps_the_passes_done(baked):
    scene, stack = baked
    r = relume.Relighter(stack, "cpu", scene=scene)
    r.set_material("Object", kd=0.1, ks=0.8, ns=300.0)
    r.refine(seconds=0.0, max_passes=1)  # prepares the scene for tracing
    out = {}
    worker = threading.Thread(target=lambda: out.update(r.refine(seconds=600.0)))
    worker.start()
    # A cancel stops the refine() under way; one that comes before it started stops nothing,
    # so keep asking until the worker returns (far sooner than its 600 seconds).
    for _ in range(1200):
        r.cancel_refine()
        worker.join(timeout=0.05)
        if not worker.is_alive():
            break
    assert not worker.is_alive()
    assert out["passes"] >= 1


def test_refine_without_the_scene_says_why(baked):
    _, stack = baked
    r = relume.Relighter(stack, "cpu")
    r.set_material("White walls", kd=0.0, ks=0.9, ns=200.0)
    with pytest.raises(relume.RelumeError, match="without the scene"):
        r.refine(seconds=0.0)
    with pytest.raises(ValueError):
        relume.Relighter(stack, "cpu").refine(seconds=float("nan"))
