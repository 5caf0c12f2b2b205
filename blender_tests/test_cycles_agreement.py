"""Relume against Cycles: the same scene, the same one-bounce light transport, the same units.

Every case renders one Blender scene twice with Cycles on the CPU (two seeds, half the
samples each: their mean is the reference and their difference its noise) and bakes it twice
through the add-on with the "final" preset (two seeds: the first is the image compared, the
difference is its noise), then relights it with the scene's materials (diffuse, but for the
recorded glossy case; editable regions through the add-on's Kd/Ks override). Cycles
settings and why: support/cycles.py.

Pass criterion, per case: the relative L2 difference between the Relume image and the Cycles
reference is at most the noise floor of the two — sqrt(σ_cycles² + σ_relume²), both measured
in the same run — plus a stated margin (MARGIN below) for the small known differences of the
two renderers that are not noise. The same is checked on means over 8×8-pixel tiles, whose
noise floor is ~8× lower (0.15–0.5 %), with BLOCK_MARGIN: that is the comparison that would
see a unit, falloff, cone or colour error of a percent. Each check also proves it has teeth:
the same Relume image scaled by 1 + 3·tolerance must fail it.

Resolution is reduced (128² for the Cornell box, 96² for the light cases) to keep the suite's
Cycles time to a few minutes on 2 cores. Figures go to stdout (`pytest -s`) and to
`cycles_agreement.json` in pytest's basetemp.
"""

from __future__ import annotations

import json
import math
import pathlib
import time

import bpy
import numpy as np
import pytest
from support import cycles as cy
from support.scene_import import import_scene, set_world

ROOT = pathlib.Path(__file__).resolve().parent.parent

#: Cycles samples of the reference (two renders of half as many, seeds 1 and 2).
CORNELL_SPP = 1024
LIGHT_SPP = 512
CORNELL_RES = 128
LIGHT_RES = 96
#: Absolute allowance on top of the measured noise floor for what is not noise: f16 storage
#: of the stack (≤ 0.03 %), Relume's point light with a radius being a disk facing the shading
#: point rather than Cycles' sphere (≈ 0.1 % here), the sun's angular-diameter convention
#: (S·2cos²h/(1 + cos h) in Cycles against S, 0.03 % at 2°), bilinear texel centres of the
#: sky, and the uncertainty of the noise-floor estimate itself (two images of ~10⁴ pixels).
MARGIN = 0.004
#: Tile size of the second comparison: means over BLOCK² pixels cut the noise by about BLOCK
#: and keep any low-frequency bias (units, falloff, cone, colour), so that test is the tight one.
BLOCK = 8
#: The tiles' margin: the known systematic differences above are ≤ 0.1 % each; the floor
#: estimate from 144–256 tiles × 3 channels is itself uncertain by ~5–10 % of a 0.15–0.5 % floor.
BLOCK_MARGIN = 0.002

_RESULTS: dict[str, dict] = {}
#: Where `results_file` (conftest.py) writes `_RESULTS`, in pytest's basetemp.
RESULTS_NAME = "cycles_agreement.json"


#: Cycles' two half-sample images per case, for the 2 % goal check.
_CYCLES: dict[str, tuple[np.ndarray, np.ndarray]] = {}


def _relume_image(addon, tmp: pathlib.Path, seed: int, name: str, bounces: int = 1,
                  denoise: bool = False):
    """Bake with the final preset through the add-on and relight the current materials.

    The agreement cases turn the preset's denoiser off: they test the transport, and the
    two-seed noise estimate their floor rests on holds only for an unbiased image. The 2 %
    goal is checked on the preset as users get it (denoised)."""
    import relume

    off = {} if denoise else {"denoise_direct": 0, "denoise_bounce": 0}
    t0 = time.perf_counter()
    report = addon.api.bake(settings=relume.BakeSettings.preset("final", seed=seed, bounces=bounces,
                                                                 **off))
    bake_s = time.perf_counter() - t0
    out = addon.api.render(str(tmp / f"{name}_relume_seed{seed}.exr"), denoise="none")
    image = np.asarray(relume.read_exr(out), dtype=np.float64)[..., :3]
    return image, bake_s, report


def _agreement(r0, r1, c1, c2, margin: float) -> dict:
    """Relative L2 of Relume (seed 0) against the Cycles mean, and the noise floor."""
    reference = 0.5 * (c1 + c2)
    sigma_c = cy.noise_of_mean(c1, c2)
    sigma_r = cy.noise_of_one(r0, r1)
    floor = math.hypot(sigma_c, sigma_r)
    return {"rel_l2": cy.rel_l2(r0, reference), "sigma_cycles": sigma_c, "sigma_relume": sigma_r,
            "noise_floor": floor, "tolerance": floor + margin}


def compare(addon, tmp: pathlib.Path, name: str, spp: int, bounces: int = 1,
            extra: dict | None = None, check: bool = True) -> dict:
    """Render the current scene with Cycles (2 × spp/2) and Relume (final, 2 seeds); assert
    agreement within the noise floor plus MARGIN, per pixel and over BLOCK² tiles; return and
    record the figures."""
    scene = bpy.context.scene
    c1, t1 = cy.render_cycles(scene, tmp / f"{name}_cycles_1.exr", spp // 2, seed=1, bounces=bounces)
    c2, t2 = cy.render_cycles(scene, tmp / f"{name}_cycles_2.exr", spp // 2, seed=2, bounces=bounces)
    r0, b0, report = _relume_image(addon, tmp, 0, name, bounces)
    r1, b1, _ = _relume_image(addon, tmp, 1, name, bounces)
    _CYCLES[name] = (c1, c2)
    reference = 0.5 * (c1 + c2)
    assert reference.shape == r0.shape, (reference.shape, r0.shape)
    assert np.isfinite(reference).all() and np.isfinite(r0).all() and np.isfinite(r1).all()
    assert reference.max() > 0 and r0.max() > 0
    pixel = _agreement(r0, r1, c1, c2, MARGIN)
    blocks = _agreement(*(cy.block_mean(x, BLOCK) for x in (r0, r1, c1, c2)), BLOCK_MARGIN)
    figures = {
        "resolution": list(reference.shape[:2]),
        "bounces": bounces,
        "cycles_spp": spp,
        "relume_preset": "final, denoiser off",
        **pixel,
        "rel_l2_mean_of_two_relume_seeds": cy.rel_l2(0.5 * (r0 + r1), reference),
        **{f"block{BLOCK}_{k}": v for k, v in blocks.items()},
        "mean_ratio_relume_over_cycles": float(r0.sum() / reference.sum()),
        "cycles_s": t1 + t2,
        "relume_bake_s": b0,
        "relume_layers": report.get("layers"),
        **(extra or {}),
    }
    _RESULTS[name] = figures
    print(f"\n[cycles agreement] {name}: " + ", ".join(
        f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in figures.items()))
    if not check:
        return figures
    for what, f, (a, ref) in (("per pixel", pixel, (r0, reference)),
                              (f"over {BLOCK}x{BLOCK} tiles", blocks,
                               (cy.block_mean(r0, BLOCK), cy.block_mean(reference, BLOCK)))):
        assert f["rel_l2"] <= f["tolerance"], (
            f"{name}: Relume differs from Cycles {what} by {f['rel_l2']:.3%} (rel. L2), beyond the "
            f"noise floor {f['noise_floor']:.3%} + margin {f['tolerance'] - f['noise_floor']:.1%}; mean ratio "
            f"{figures['mean_ratio_relume_over_cycles']:.4f}")
        # Teeth: a brightness error of 3 × the tolerance must not pass.
        assert cy.rel_l2(a * (1.0 + 3.0 * f["tolerance"]), ref) > f["tolerance"]
    return figures


@pytest.mark.parametrize("bounces", [0, 1])
def test_cornell_diffuse_agrees_with_cycles(addon, prefs, blend_dir, results_file, bounces):
    """Direct light only (Cycles max bounces 0, Relume bounces 0) and direct + one bounce
    (1 and 1): both must agree, which pins down what "one bounce" means on each side."""
    import_scene(ROOT / "assets" / "cornell.scene.json", resolution=(CORNELL_RES, CORNELL_RES),
                 diffuse_only=True)
    compare(addon, blend_dir, f"cornell_diffuse_b{bounces}", CORNELL_SPP, bounces=bounces)


def test_cornell_final_preset_is_within_2_percent_of_cycles(addon, prefs, blend_dir, results_file):
    """The issue's goal: the final preset as users get it (QMC sampling, denoised bounce
    layers) against the 1024-spp Cycles image of the diffuse Cornell box, direct + one bounce:
    relative L2 ≤ 2 % per pixel. The difference includes Cycles' own noise (printed), the
    denoiser's bias and Relume's remaining noise; nothing is taken out of it."""
    name = "cornell_diffuse_b1"
    if name not in _CYCLES:
        pytest.skip("needs test_cornell_diffuse_agrees_with_cycles[1] first")
    import_scene(ROOT / "assets" / "cornell.scene.json", resolution=(CORNELL_RES, CORNELL_RES),
                 diffuse_only=True)
    c1, c2 = _CYCLES[name]
    reference = 0.5 * (c1 + c2)
    r, bake_s, _ = _relume_image(addon, blend_dir, 0, name + "_denoised", 1, denoise=True)
    figures = {"rel_l2": cy.rel_l2(r, reference), "sigma_cycles": cy.noise_of_mean(c1, c2),
               "relume_bake_s": bake_s, "cycles_spp": CORNELL_SPP, "relume_preset": "final"}
    _RESULTS["cornell_final_preset_goal"] = figures
    print(f"\n[cycles agreement] final preset (denoised) against Cycles 1024 spp: {figures}")
    assert np.isfinite(r).all() and r.min() >= 0.0
    assert figures["rel_l2"] <= 0.02, figures


@pytest.mark.parametrize("kind", ["point", "spot", "sun", "area"])
def test_light_agrees_with_cycles(addon, prefs, blend_dir, results_file, kind):
    cy.open_scene(LIGHT_RES)
    cy.add_light(kind)
    compare(addon, blend_dir, f"light_{kind}", LIGHT_SPP)


#: Bounds of the HDRI cases, tighter than the shared margins: issue 15 reported an HDRI-lit
#: diffuse scene 1.8 % brighter than Cycles; measured since, every HDRI case (these two, the
#: bunny's forest HDRI with diffuse materials) is within 0.1 % of Cycles' mean and these two
#: are at their tile noise floor (docs/fidelity.md, "HDRI brightness against Cycles").
HDRI_MEAN_BOUND = 0.002
HDRI_BLOCK_MARGIN = 0.001


@pytest.mark.parametrize("sky", ["blob", "sun_disc"])
def test_hdri_world_agrees_with_cycles(addon, prefs, blend_dir, results_file, sky):
    """The 64×32 sky with a broad 12° blob, and the assets' 128×64 sky with a small, very
    bright sun disc (4°, radiance 2000: a texel and a half across, where the lookup's
    filtering, the map's resolution and the sampling pdf all matter)."""
    cy.open_scene(LIGHT_RES)
    if sky == "blob":
        world = {"type": "equirect", "image": cy.sky_image(), "strength": 1.0}
    else:
        world = json.loads((ROOT / "assets" / "hdri.scene.json").read_text())["world"]
    set_world(world)
    f = compare(addon, blend_dir, f"world_hdri_{sky}", LIGHT_SPP)
    assert abs(f["mean_ratio_relume_over_cycles"] - 1.0) <= HDRI_MEAN_BOUND, f
    assert f[f"block{BLOCK}_rel_l2"] <= f[f"block{BLOCK}_noise_floor"] + HDRI_BLOCK_MARGIN, f


def test_glossy_model_difference_is_recorded(addon, prefs, blend_dir, results_file):
    """Principled BSDFs in both renderers: Cycles renders GGX (multiscatter) with Fresnel,
    Relume the closest Blinn–Phong of the core's mapping (α = r², ns = 2/α² − 2; metallic →
    Ks from the base colour, dielectric → F0 from the IOR; principled.rs). The difference is
    model mismatch, recorded as a figure, not a failure; the test checks finiteness and a
    loose sanity bound (rel. L2 ≤ 50 %, mean within ±25 %) that only a broken mapping —
    a lobe in the wrong place, a unit error — would miss."""
    from support.scenes import principled_material

    cy.open_scene(LIGHT_RES)
    cy.add_light("area")
    ball = principled_material("Gold", (0.9, 0.6, 0.3), roughness=0.35, metallic=1.0, editable=True)
    floor = principled_material("Satin", (0.5, 0.5, 0.5), roughness=0.3)
    bpy.data.objects["Sphere"].data.materials[0] = ball
    bpy.data.objects["Floor"].data.materials[0] = floor
    bpy.context.view_layer.update()
    import relume

    mapping = {name: relume.principled_to_blinn_phong(col, metallic=m, roughness=r)
               for name, col, m, r in (("Gold", (0.9, 0.6, 0.3), 1.0, 0.35),
                                       ("Satin", (0.5, 0.5, 0.5), 0.0, 0.3))}
    f = compare(addon, blend_dir, "glossy_principled", LIGHT_SPP, check=False,
                extra={"mapping": {k: {kk: (list(vv) if isinstance(vv, (list, tuple)) else vv)
                                       for kk, vv in v.items()} for k, v in mapping.items()}})
    assert math.isfinite(f["rel_l2"]) and math.isfinite(f["block8_rel_l2"])
    assert f["rel_l2"] <= 0.5, f
    assert 0.75 <= f["mean_ratio_relume_over_cycles"] <= 1.25, f
