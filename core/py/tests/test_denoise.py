"""Relighter.relight(denoise=...): "none" and "linear" are the relit image bit for bit;
"oidn" denoises with the scene's albedo and normal features (OpenImageDenoise from the bpy
wheel, as the tests install it) after an edit too; a missing library falls back to the
linear image and says so in `last_denoise`."""

from __future__ import annotations

import importlib.util
import json
import os
import pathlib

import numpy as np
import pytest
import relume

ROOT = pathlib.Path(__file__).resolve().parents[3]


def _oidn_found() -> bool:
    spec = importlib.util.find_spec("bpy")
    if spec is None or not spec.submodule_search_locations:
        return bool(os.environ.get("RELUME_OIDN_LIBRARY"))
    lib = pathlib.Path(list(spec.submodule_search_locations)[0]) / "lib"
    return any(lib.glob("libOpenImageDenoise*")) or bool(os.environ.get("RELUME_OIDN_LIBRARY"))


def _cornell(size: int):
    data = json.loads((ROOT / "assets" / "cornell.scene.json").read_text())
    data["resolution"] = {"width": size, "height": size}
    return relume.Scene.from_json(json.dumps(data), str(ROOT / "assets"))


def _rel_l2(a, b):
    a, b = a[..., :3].astype(np.float64), b[..., :3].astype(np.float64)
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


@pytest.fixture(scope="module")
def baked(tmp_path_factory):
    """A noisy (4 spp) and a converged (96 spp × 4 × 4) bake of the Cornell scene at 64²."""
    tmp = tmp_path_factory.mktemp("denoise")
    scene = _cornell(64)
    noisy, converged = tmp / "noisy.relume.exr", tmp / "converged.relume.exr"
    relume.bake(scene, relume.BakeSettings(spp=4, light_samples=1, seed=1), str(noisy))
    relume.bake(scene, relume.BakeSettings(spp=96, light_samples=4, indirect_samples=4, seed=2),
                str(converged))
    return scene, relume.Stack.load(str(noisy)), relume.Stack.load(str(converged))


def test_none_and_linear_are_the_relit_image_and_report_so(baked):
    scene, stack, _ = baked
    r = relume.Relighter(stack, "cpu", scene=scene)
    assert r.last_denoise is None
    exact = r.relight()
    assert r.last_denoise["ran"] == "none"
    for mode in ("none", "linear"):
        img = r.relight(denoise=mode)
        assert img.tobytes() == exact.tobytes(), mode
        assert (r.last_denoise["asked"], r.last_denoise["ran"], r.last_denoise["note"]) == (mode, mode, None)
    with pytest.raises(ValueError, match="oidn"):
        r.relight(denoise="bilateral")


def test_a_scene_other_than_the_stacks_is_refused(baked):
    _, stack, _ = baked
    with pytest.raises(relume.StaleStackError, match="not the one the stack was baked from"):
        relume.Relighter(stack, "cpu", scene=_cornell(32))


def test_a_missing_library_falls_back_to_the_linear_image_with_the_reason(baked, monkeypatch):
    scene, stack, _ = baked
    monkeypatch.setenv("RELUME_OIDN_LIBRARY", "/nonexistent/libOpenImageDenoise.so.2")
    r = relume.Relighter(stack, "cpu", scene=scene)
    exact = r.relight()
    img = r.relight(denoise="oidn", oidn_dirs=["/nonexistent/blender/lib"])
    d = r.last_denoise
    if d["ran"] == "oidn":
        pytest.skip(f"an OpenImageDenoise is on the system library path: {d['library']}")
    assert img.tobytes() == exact.tobytes()
    assert (d["asked"], d["ran"]) == ("oidn", "linear")
    assert "OpenImageDenoise 2 was not found" in d["note"]
    assert "/nonexistent/libOpenImageDenoise.so.2 (RELUME_OIDN_LIBRARY): no such file" in d["note"]
    assert "/nonexistent/blender/lib/" in d["note"]
    assert d["summary"].startswith("linear (OpenImageDenoise did not run")


@pytest.mark.skipif(not _oidn_found(), reason="no OpenImageDenoise here: pip install bpy (its lib "
                                              "folder has one) or set RELUME_OIDN_LIBRARY")
def test_oidn_with_features_is_closer_to_a_converged_bake_after_an_edit_and_flips_alike(baked):
    scene, stack, converged = baked
    r = relume.Relighter(stack, "cpu", scene=scene)
    ref = relume.Relighter(converged, "cpu")
    for edit in (None, ("Object", (0.8, 0.15, 0.1), 0.0, 0.3), ("White walls", (0.5, 0.6, 0.8), 0.0, 0.8)):
        if edit is not None:
            name, colour, metallic, roughness = edit
            r.set_principled(name, colour, metallic, roughness)
            ref.set_principled(name, colour, metallic, roughness)
        raw = r.relight()
        shown = r.relight(denoise="oidn")
        d = r.last_denoise
        assert (d["ran"], d["features"]) == ("oidn", "albedo+normal"), d
        assert d["note"] is None and d["version"].startswith("2") and d["ms"] > 0
        assert np.isfinite(shown).all()
        assert np.array_equal(shown[..., 3], raw[..., 3])
        reference = ref.relight()
        e_raw, e_oidn = _rel_l2(raw, reference), _rel_l2(shown, reference)
        assert e_oidn < 0.5 * e_raw, (edit, e_raw, e_oidn)
    # Blender's row order: the same image, rows reversed.
    flipped = r.relight(flip_y=True, denoise="oidn")
    assert np.array_equal(flipped, shown[::-1])
