"""Per material against Cycles: fixed Principled materials, which Relume evaluates as Cycles
does (GGX, Fresnel, multiple scattering and the diffuse base's view-dependent weight:
core/engine/src/bake/path/surface_brdf.rs, since session 30), and the analytic Blinn–Phong
mapping they were rendered with before the fit (core/engine/src/brdf/principled_fit,
docs/principled_fit.md), on a row of Principled spheres — metals at roughness 0.1–0.8,
dielectrics — with the same one-bounce transport on both sides (support/cycles.py says what
"the same" means). The spheres are fixed regions; the floor is the scene's editable region.

Which pixel belongs to which material comes from a material-ID image rendered by Cycles: each
object's material swapped for an Emission of a unique value (black world, box filter), so a
pixel whose every sample saw one material has exactly that value; only those pixels, with
their four neighbours of the same material, are compared (edges, where the two renderers'
pixel samples differ, are left out).

Per material the mean brightness (RGB summed over its pixels) of Relume over Cycles is the
figure, for two placements of one area light (in front, above the camera; to the side).
Relume's figure is the mean over bake seeds 0–3 (each seed's figure is recorded too: a user
gets one); Cycles' reference is converged: 8192 samples per pixel (two renders of 4096).
Fewer do not converge on the smoothest metal: to the side its highlight holds a sliver of
about 1 % of one pixel where the light's corner is seen past the neighbouring sphere (≈ 50
times that pixel's value); Cycles at 2 × 128 samples missed it in both renders (their means
agreed to 0.3 %, yet the sum on that material was 7.7 % under the value at 8192 samples),
and that shortfall was what earlier sessions had recorded as Relume's 11–15 % excess there.
The issue's goal — metals within 5 %, dielectrics within 3 % — is asserted for every
sphere, the smoothest included. Over the metals the exact evaluation must beat the analytic
mapping.

The same spheres made editable and baked in the basis of Principled lobes
(`lobe="principled"`, core/engine/src/brdf/principled_basis), relit at their bake-time
materials, are held to the same goal, the smoothest metal included: each region's bake-time
lobe is a slot of its own there, evaluated as a fixed region's is, so what is left is the
sampling.
Every figure goes to `principled_fit.json` in pytest's basetemp.
"""

from __future__ import annotations

import json
import pathlib
import time

import numpy as np
import pytest
from support import cycles as cy
from support.spheres import LIGHTS, build_scene, per_material

RES = 96
#: Cycles samples (two renders of half as many; their difference is the noise estimate):
#: enough for the smoothest metal's sub-pixel highlight (module docs).
CYCLES_SPP = 8192
#: Bake seeds Relume's figures are averaged over.
SEEDS = (0, 1, 2, 3)
#: Spheres: (name, base colour, metallic, roughness).
SPHERES = (
    ("Metal r0.1", (0.9, 0.65, 0.35), 1.0, 0.1),
    ("Metal r0.3", (0.9, 0.65, 0.35), 1.0, 0.3),
    ("Metal r0.5", (0.8, 0.8, 0.8), 1.0, 0.5),
    ("Metal r0.8", (0.9, 0.65, 0.35), 1.0, 0.8),
    ("Dielectric r0.3", (0.2, 0.35, 0.7), 0.0, 0.3),
    ("Dielectric r0.6", (0.8, 0.8, 0.8), 0.0, 0.6),
)
#: The issue's goals: metals within 5 % of Cycles' mean brightness, dielectrics within 3 %.
GOAL = {"metal": 0.05, "dielectric": 0.03}

_RESULTS: dict[str, dict] = {}
#: Where `results_file` (conftest.py) writes `_RESULTS`, in pytest's basetemp.
RESULTS_NAME = "principled_fit.json"


def relume_image(addon, tmp: pathlib.Path, mode: str, seed: int = 0) -> np.ndarray:
    """Export the scene, bake it (final preset, one bounce, denoiser off, bake seed `seed`) and relight
    with the bake-time materials. `mode`: "exact" as exported (the spheres fixed, evaluated
    as Cycles does); "analytic" with every Principled region replaced by the analytic
    mapping's Blinn–Phong before the bake; "basis" with the spheres editable, baked in the
    basis of Principled lobes (`lobe="principled"`) and relit from it."""
    import relume

    result = addon.api.export()
    scene_dict = json.loads(json.dumps(result.scene_dict))
    for region in scene_dict["regions"]:
        m = region.get("material", {})
        if m.get("model") != "principled":
            continue
        if mode == "analytic":
            bp = relume.principled_to_blinn_phong_analytic(
                m["base_color"], metallic=m.get("metallic", 0.0), roughness=m.get("roughness", 0.5),
                ior=m.get("ior", 1.5), specular_ior_level=m.get("specular_ior_level", 0.5))
            region["material"] = {"model": "blinn_phong", "kd": list(bp["kd"]), "ks": list(bp["ks"]),
                                  "ns": bp["ns"]}
        elif mode == "basis":
            region["editable"] = True
    scene_path = tmp / f"{mode}.scene.json"
    result.scene.save(str(scene_path))
    full = json.loads(scene_path.read_text())
    full["regions"] = scene_dict["regions"]
    scene = relume.Scene.from_json(json.dumps(full), base_dir=str(tmp))
    lobe = "principled" if mode == "basis" else "blinn-phong"
    settings = relume.BakeSettings.preset("final", seed=seed, bounces=1, denoise_direct=0, denoise_bounce=0,
                                          lobe=lobe)
    stack_path = tmp / f"{mode}_seed{seed}.relume.exr"
    relume.bake(scene, settings, str(stack_path))
    relighter = relume.Relighter(relume.Stack.load(str(stack_path)), device="cpu")
    return np.asarray(relighter.relight(), dtype=np.float64)[..., :3]


@pytest.mark.parametrize("light_at", sorted(LIGHTS))
def test_fixed_principled_per_material_against_cycles(addon, prefs, blend_dir, results_file, light_at):
    scene = build_scene(light_at, SPHERES, RES)
    ids, names = cy.material_ids(scene, blend_dir / "ids.exr")
    counts = {name: int((ids == k).sum()) for k, name in enumerate(names)}
    for name, *_ in SPHERES:
        assert counts.get(name, 0) >= 20, f"{name}: only {counts.get(name, 0)} pure pixels"
    c1, _ = cy.render_cycles(scene, blend_dir / "c1.exr", CYCLES_SPP // 2, seed=1, bounces=1)
    c2, _ = cy.render_cycles(scene, blend_dir / "c2.exr", CYCLES_SPP // 2, seed=2, bounces=1)
    reference = 0.5 * (c1 + c2)
    exacts = [relume_image(addon, blend_dir, "exact", seed) for seed in SEEDS]
    old = relume_image(addon, blend_dir, "analytic")
    started = time.perf_counter()
    bases = [relume_image(addon, blend_dir, "basis", seed) for seed in SEEDS]
    basis_seconds = (time.perf_counter() - started) / len(SEEDS)
    assert all(e.shape == reference.shape for e in exacts + bases + [old])
    assert all(np.isfinite(e).all() for e in exacts + bases + [old])
    ref_m = per_material(reference, ids, names)
    m1, m2 = per_material(c1, ids, names), per_material(c2, ids, names)
    noise = {n: abs(m1[n] - m2[n]) / (m1[n] + m2[n]) for n in m1}
    old_m = per_material(old, ids, names)

    def ratios(images):
        per_seed = [per_material(image, ids, names) for image in images]
        return {n: [m[n] / ref_m[n] for m in per_seed] for n in ref_m}

    exact_r, basis_r = ratios(exacts), ratios(bases)
    figures = {}
    for name, colour, metallic, roughness in SPHERES:
        figures[name] = {
            "metallic": metallic, "roughness": roughness, "base_color": list(colour),
            "pixels": counts[name],
            "ratio_exact": float(np.mean(exact_r[name])),
            "ratio_exact_per_seed": exact_r[name],
            "ratio_analytic": old_m[name] / ref_m[name],
            "ratio_editable_principled_basis": float(np.mean(basis_r[name])),
            "ratio_editable_principled_basis_per_seed": basis_r[name],
            "cycles_noise_of_mean": noise[name],
        }
    for name in ("Floor", "Wall"):
        figures[name] = {"pixels": counts.get(name, 0), "ratio_exact": float(np.mean(exact_r[name])),
                         "ratio_exact_per_seed": exact_r[name], "ratio_analytic": old_m[name] / ref_m[name]}
    _RESULTS[light_at] = figures
    _RESULTS["settings"] = {"resolution": RES, "cycles_spp": CYCLES_SPP, "bounces": 1,
                            "relume_preset": "final, denoiser off", "relume_seeds": list(SEEDS)}
    print(f"\n[principled fit] light {light_at}: Relume/Cycles per material, mean over bake seeds "
          f"{list(SEEDS)} [range] (exact | analytic, seed 0 | editable in the Principled basis, "
          f"bake + relight {basis_seconds:.0f} s a seed):")
    for name, f in figures.items():
        line = (f"  {name:16s} {f['ratio_exact']:.3f} [{min(f['ratio_exact_per_seed']):.3f}–"
                f"{max(f['ratio_exact_per_seed']):.3f}] | {f['ratio_analytic']:.3f}")
        if "ratio_editable_principled_basis" in f:
            per_seed = f["ratio_editable_principled_basis_per_seed"]
            line += (f" | {f['ratio_editable_principled_basis']:.3f} [{min(per_seed):.3f}–"
                     f"{max(per_seed):.3f}]  Cycles noise {f['cycles_noise_of_mean']:.4f}")
        print(line + f"  ({f['pixels']} px)")
    for name, _colour, metallic, _r in SPHERES:
        f = figures[name]
        f["goal"] = GOAL["metal" if metallic else "dielectric"]
        f["meets_goal"] = abs(f["ratio_exact"] - 1.0) <= f["goal"]
        f["basis_meets_goal"] = abs(f["ratio_editable_principled_basis"] - 1.0) <= f["goal"]
        assert abs(f["ratio_exact"] - 1.0) <= f["goal"], (name, f)
        assert abs(f["ratio_editable_principled_basis"] - 1.0) <= f["goal"], \
            (name, f)
    # Metals: the exact evaluation is closer to Cycles than the analytic mapping, on average over them.
    metals = [figures[n] for n, _c, m, _r in SPHERES if m > 0.0]
    exact_err = sum(abs(f["ratio_exact"] - 1.0) for f in metals) / len(metals)
    old_err = sum(abs(f["ratio_analytic"] - 1.0) for f in metals) / len(metals)
    _RESULTS[light_at + "_metal_mean_abs_error"] = {"exact": exact_err, "analytic": old_err}
    assert exact_err < old_err, (exact_err, old_err)
    # Diffuse surfaces must agree (the mapping does not touch them): the comparison's teeth.
    for name in ("Floor", "Wall"):
        assert abs(figures[name]["ratio_exact"] - 1.0) <= 0.03, (name, figures[name])
