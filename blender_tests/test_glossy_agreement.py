"""Smooth and glossy Principled surfaces against Cycles (issue 15): fireflies on smooth metal,
and a glossy scene with the roughness range that covers its materials.

- **No fireflies.** Metal spheres of Principled roughness 0.1, 0.2 (editable) and 0.3 on a
  diffuse floor, under a small bright area light and an HDRI with a sun-like hot spot. The
  brightest pixel in both renderers is the roughness-0.1 sphere's reflection of the 5 cm
  emitter, which covers a few per cent of one pixel: how many of a pixel's samples land in it
  moves that pixel by ±20 % at the final preset's 128 eye samples, in Cycles too (Cycles at 128
  samples, seeds 1–8: 40–90 against 55.5 converged, 2026-11-27). So the pixel is compared at
  equal noise: every relit pixel of Relume's final preset (bake seeds 0–7, as users get it)
  must stay below Cycles' converged brightest pixel (16384 samples) plus three times the
  spread of Cycles' own brightest pixel at 128 samples (seeds 1–8) — an isolated firefly, such
  as the issue's 506 against 2.9, fails it — and the mean over Relume's seeds of that pixel must
  be within three standard errors of the converged value, so a systematically brighter (or
  dimmer) highlight fails too. Multiple importance sampling against the BSDF mixture's
  directions (`core/engine/src/bake/path/mis.rs`) is what keeps fireflies out; at this preset and
  scene light sampling alone also stayed within the bound (the engine's `tests/engine/mis.rs` shows
  the difference at low sample counts), so this test guards the behaviour users see rather
  than telling the two estimators apart.
- **Glossy scene.** A ground at Principled roughness 0.15 and a metallic sphere at 0.25
  (both editable), area light and an HDRI: Relume with the add-on's default roughness range
  (0.1–1, which covers both) against Cycles, one bounce, over 8×8 tiles; the same scene with
  the old ns range [1, 200] (roughness ≥ 0.32, so both materials are baked too rough) is
  recorded beside it. The issue's goal is 5 %. Baked in the Blinn–Phong basis the fitted
  mapping keeps the gap above it (11.2 %: the test asserts that measured bound); baked in the
  basis of Principled lobes (`lobe="principled"`, 2026-11-27: 4.8 %, mean 0.998) the scene
  is held to the goal (docs/fidelity.md).

Figures go to stdout (`pytest -s`) and `glossy_agreement.json` in pytest's basetemp.
"""

from __future__ import annotations

import math
import time

import bpy
import numpy as np
from support import cycles as cy
from support.scenes import add_camera_and_black_world, principled_material

RES = 64
BLOCK = 8
#: Cycles samples of the references (two renders of half as many, seeds 1 and 2): the
#: smooth-metal scene's is converged on its sub-pixel highlight (module docs).
FIREFLY_SPP = 16384
GLOSSY_SPP = 512
#: Samples of the Cycles renders whose brightest pixel's spread is the noise at the final
#: preset's eye-sample count, and how many seeds of those and of Relume's bake.
EQUAL_SPP = 128
NOISE_SEEDS = 8
#: Tile bound of the glossy scene with the covering range: what was measured when the test
#: was written (11.5 %), with room for the Cycles reference's noise; the issue's goal, 5 %,
#: needs the refitted mapping.
GLOSSY_TILE_BOUND = 0.15
#: The issue's goal, which the basis of Principled lobes meets (4.8 % measured).
GLOSSY_GOAL = 0.05

_RESULTS: dict[str, dict] = {}
#: Where `results_file` (conftest.py) writes `_RESULTS`, in pytest's basetemp.
RESULTS_NAME = "glossy_agreement.json"


def sun_sky(width: int = 256, height: int = 128, sun: int = 1, radiance: float = 3000.0) -> dict:
    """An equirectangular sky (top row first): a blue gradient, a dark ground and a sun-like
    hot spot of `sun`² texels (1.4° each) at `radiance`, 40° up."""
    rows = []
    sun_x, sun_y = int(0.62 * width), int(0.5 * height - 40.0 / 180.0 * height)
    for j in range(height):
        z = math.cos(math.pi * (j + 0.5) / height)
        for i in range(width):
            if 0 <= i - sun_x < sun and 0 <= j - sun_y < sun:
                rows.extend([radiance, 0.9 * radiance, 0.75 * radiance])
            elif z >= 0:
                rows.extend([0.15 + 0.1 * (1 - z), 0.25 + 0.1 * (1 - z), 0.5])
            else:
                rows.extend([0.08, 0.07, 0.06])
    return {"width": width, "height": height, "rgb": rows}


def _sphere(name, centre, radius, material):
    verts, faces = cy.uv_sphere(centre, radius, segments=48, rings=24)
    return cy.mesh_object(name, verts, faces, material, smooth=True)


def _area_light(power: float, size: float, location, target):
    import mathutils

    data = bpy.data.lights.new("Area", "AREA")
    data.energy = power
    data.shape = "SQUARE"
    data.size = size
    obj = bpy.data.objects.new("Area", data)
    obj.location = location
    d = mathutils.Vector(target) - obj.location
    obj.rotation_euler = (-d).to_track_quat("Z", "Y").to_euler()
    bpy.context.scene.collection.objects.link(obj)


def _base_scene(ground, light_size: float = 0.25) -> bpy.types.Scene:
    scene = bpy.context.scene
    s = 6.0
    cy.mesh_object("Floor", [(-s, -s, 0), (s, -s, 0), (s, s, 0), (-s, s, 0)], [(0, 1, 2, 3)], ground)
    add_camera_and_black_world(scene, RES, 40, (0.0, -3.6, 1.3), (75, 0, 0))
    scene.render.resolution_y = 48
    from support.scene_import import set_world

    set_world({"type": "equirect", "image": sun_sky(), "strength": 1.0})
    _area_light(60.0, light_size, (0.6, -1.2, 2.4), (0.0, 0.0, 0.4))
    bpy.context.view_layer.update()
    return scene


def _cycles_pair(scene, tmp, name, spp):
    c1, t1 = cy.render_cycles(scene, tmp / f"{name}_c1.exr", spp // 2, seed=1, bounces=1)
    c2, t2 = cy.render_cycles(scene, tmp / f"{name}_c2.exr", spp // 2, seed=2, bounces=1)
    return c1, c2, t1 + t2


def _relume(addon, tmp, name, lobe="blinn-phong", seed=0):
    import relume

    t0 = time.perf_counter()
    report = addon.api.bake(settings=relume.BakeSettings.preset("final", seed=seed, bounces=1, lobe=lobe))
    bake_s = time.perf_counter() - t0
    out = addon.api.render(str(tmp / f"{name}_relume.exr"), denoise="none")
    image = np.asarray(relume.read_exr(out), dtype=np.float64)[..., :3]
    return image, bake_s, report


def _record(name, figures):
    _RESULTS[name] = figures
    print(f"\n[glossy agreement] {name}: " + ", ".join(
        f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in figures.items()))


def test_smooth_metal_has_no_fireflies(addon, prefs, blend_dir, results_file):
    ground = cy.diffuse_material("Floor", (0.5, 0.5, 0.5))
    # Small emitters: their reflections in the spheres cover a pixel only in part, so the
    # brightest converged pixel stays far below what a firefly reaches.
    _base_scene(ground, light_size=0.05)
    for x, r in ((-1.0, 0.1), (0.0, 0.2), (1.0, 0.3)):
        metal = principled_material(f"Metal {r}", (0.95, 0.8, 0.6), roughness=r, metallic=1.0,
                                    editable=r == 0.2)
        _sphere(f"Sphere {r}", (x, 0.0, 0.4), 0.4, metal)
    bpy.context.view_layer.update()
    scene = bpy.context.scene
    c1, c2, cycles_s = _cycles_pair(scene, blend_dir, "fireflies", FIREFLY_SPP)
    reference = 0.5 * (c1 + c2)
    peak = np.unravel_index(reference.max(axis=2).argmax(), reference.shape[:2])
    brightest = float(reference.max())
    # Cycles' own brightest pixel at the final preset's sample count, over seeds: its spread is
    # the noise a relit pixel is measured against.
    equal = [cy.render_cycles(scene, blend_dir / f"equal_{seed}.exr", EQUAL_SPP, seed=seed, bounces=1)[0]
             for seed in range(1, NOISE_SEEDS + 1)]
    equal_brightest = [float(e.max()) for e in equal]
    equal_sigma = float(np.std(equal_brightest, ddof=1))
    runs = [_relume(addon, blend_dir, f"fireflies_{seed}", seed=seed) for seed in range(NOISE_SEEDS)]
    images = [image for image, _, _ in runs]
    bake_s = [seconds for _, seconds, _ in runs]
    layers = runs[-1][2].get("layers")
    assert all(i.shape == reference.shape and np.isfinite(i).all() for i in images)
    relume_brightest = [float(i.max()) for i in images]
    at_peak = [float(i[peak].max()) for i in images]
    peak_mean = float(np.mean(at_peak))
    peak_standard_error = float(np.std(at_peak, ddof=1) / math.sqrt(len(at_peak)))
    bound = brightest + 3.0 * equal_sigma
    image = images[0]
    err = ((image - reference) ** 2).sum(axis=2).ravel()
    figures = {
        "resolution": list(reference.shape[:2]),
        "cycles_spp": FIREFLY_SPP,
        "cycles_brightest": brightest,
        "cycles_brightest_noise": float(np.abs(c1 - c2)[peak].max() / 2.0),
        "cycles_equal_spp": EQUAL_SPP,
        "cycles_equal_spp_brightest_per_seed": equal_brightest,
        "cycles_equal_spp_brightest_sigma": equal_sigma,
        "relume_brightest_per_seed": relume_brightest,
        "relume_at_cycles_peak_per_seed": at_peak,
        "relume_at_cycles_peak_mean": peak_mean,
        "relume_at_cycles_peak_standard_error": peak_standard_error,
        "firefly_bound": bound,
        "ratio_of_brightest_seed0": relume_brightest[0] / brightest,
        "ten_worst_pixels_share_of_squared_error_seed0": float(np.sort(err)[-10:].sum() / err.sum()),
        "mean_ratio_relume_over_cycles_seed0": float(image.sum() / reference.sum()),
        "block8_rel_l2_seed0": cy.rel_l2(cy.block_mean(image, BLOCK), cy.block_mean(reference, BLOCK)),
        "relume_bake_s": float(np.median(bake_s)),
        "cycles_s": cycles_s,
        "relume_layers": layers,
    }
    _record("smooth_metal_fireflies", figures)
    assert brightest > 0.0 and equal_sigma > 0.0
    # No firefly: every relit pixel of every seed within the noise of an unbiased render at
    # the same sample count.
    assert max(relume_brightest) <= bound, figures
    # No systematic excess (or shortfall) of the highlight: the seeds' mean at Cycles' peak.
    assert abs(peak_mean - brightest) <= 3.0 * peak_standard_error + figures["cycles_brightest_noise"], figures


def _glossy_scene():
    ground = principled_material("Ground", (0.5, 0.5, 0.5), roughness=0.15, editable=True)
    metal = principled_material("Metal", (0.9, 0.6, 0.3), roughness=0.25, metallic=1.0,
                                editable=True)
    _base_scene(ground)
    _sphere("Sphere", (0.0, 0.0, 0.5), 0.5, metal)
    bpy.context.view_layer.update()
    return bpy.context.scene


def test_glossy_scene_agrees_with_cycles(addon, prefs, blend_dir, results_file):
    scene = _glossy_scene()
    c1, c2, cycles_s = _cycles_pair(scene, blend_dir, "glossy", GLOSSY_SPP)
    reference = 0.5 * (c1 + c2)
    figures = {"cycles_spp": GLOSSY_SPP, "cycles_s": cycles_s,
               "cycles_tile_noise": cy.noise_of_mean(cy.block_mean(c1, BLOCK), cy.block_mean(c2, BLOCK))}
    images = {}
    for label, lobe, old in (("range_0.1-1", "blinn-phong", False), ("principled_basis", "principled", False),
                             ("old_ns_1-200", "blinn-phong", True)):
        if old:
            # ns ∈ [1, 200] under ns = 2/α² − 2, α = r²: roughness (2/(ns + 2))^¼.
            for name in ("Ground", "Metal"):
                m = bpy.data.materials[name]
                m.relume.use_roughness_range = True
                m.relume.roughness_min = (2.0 / 202.0) ** 0.25
                m.relume.roughness_max = (2.0 / 3.0) ** 0.25
        image, bake_s, report = _relume(addon, blend_dir, f"glossy_{label}", lobe)
        assert image.shape == reference.shape and np.isfinite(image).all()
        images[label] = image
        figures[label] = {
            "block8_rel_l2": cy.rel_l2(cy.block_mean(image, BLOCK), cy.block_mean(reference, BLOCK)),
            "pixel_rel_l2": cy.rel_l2(image, reference),
            "mean_ratio_relume_over_cycles": float(image.sum() / reference.sum()),
            "relume_bake_s": bake_s,
            "relume_layers": report.get("layers"),
            "range_warnings": addon.api.status().get("range_warnings"),
        }
    _record("glossy_ground_0.15_metal_0.25", figures)
    covered = figures["range_0.1-1"]["block8_rel_l2"]
    assert covered <= GLOSSY_TILE_BOUND, figures
    assert figures["principled_basis"]["block8_rel_l2"] <= GLOSSY_GOAL, figures
    # Teeth: the same image 3 × the bound brighter fails.
    assert cy.rel_l2(cy.block_mean(images["range_0.1-1"] * (1 + 3 * GLOSSY_TILE_BOUND), BLOCK),
                     cy.block_mean(reference, BLOCK)) > GLOSSY_TILE_BOUND
