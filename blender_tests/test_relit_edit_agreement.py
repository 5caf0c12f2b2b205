"""Relit edits against Cycles (issue 15): an edit of a glossy editable material, relit from
one bake, must stay as close to a Cycles render of the edited scene as the unedited relight
is to Cycles' render of the unedited scene.

The scene is `support.scenes.box_scene` (a box open to the camera, an area light under the
ceiling) at 64×48 px, with its sphere "Ball" a glossy Principled dielectric (roughness 0.25)
and the only editable material, driven by its shader sliders as a user drives it. It is
baked once through the add-on as a user bakes (the final preset, the add-on's default
roughness range), then for each edit — roughness 0.25 → 0.6, base colour blue → orange,
metallic 0 → 1, each from the baked values — relit with `api.render` and compared with a
Cycles render of the same scene with the same edit, at the same bounces: one bounce on both
sides, and Blender's default light paths (the add-on takes the bounce cap from the scene;
bounces after the first are traced with the bake-time materials, and an edit reaches them
through the first bounce's keyed vertices and, for its diffuse and glossy energy, through the
tail-edit layers — its lobe shape stays the bake-time one there: an approximation this test
measures); and one bounce with the sphere baked in the basis of Principled lobes
(`lobe="principled"`), where no Blinn–Phong mapping stands between the material and Cycles.

Measure: relative L2 over 8×8-pixel tile means and the mean ratio Relume / Cycles, Cycles'
reference the mean of two half renders (their difference is its tile noise). The issue's
goal: each edit within the tolerance the unedited pair meets — the baseline's tile error
(the mapping's and the bake's, which an edit carries along) with `EDIT_MARGIN` to spare,
plus the references' noise. Beside the Cycles comparison each edit is also baked afresh
with the edited material: the relit-vs-rebaked tile error is what relighting adds (basis
projection; at the default bounces also the tail's approximation), apart from the Principled →
Blinn–Phong mapping both images share.

Asserted: the goal where it holds (`GOAL_ASSERTED`; the other cases are recorded with the
reason they miss it); relit-vs-rebaked within `RELIGHT_BOUND` for every edit; and that the
test can tell — each relit edit is closer to Cycles' edited render than the unedited relight
is, by more than the reference's noise.

Figures go to stdout (`pytest -s`) and `relit_edit_agreement.json` in pytest's basetemp.
"""

from __future__ import annotations

import time

import bpy
import numpy as np
import pytest
from support import cycles as cy
from support.scenes import box_scene

RES_X, RES_Y = 64, 48
BLOCK = 8
#: Cycles samples of each reference (two renders of half as many, seeds 1 and 2).
CYCLES_SPP = 256
#: The editable glossy material as baked, and the edits, each applied alone from it.
BAKED = {"Base Color": (0.2, 0.3, 0.8, 1.0), "Roughness": 0.25, "Metallic": 0.0}
EDITS = {
    "roughness_0.25_to_0.6": {"Roughness": 0.6},
    "base_colour_blue_to_orange": {"Base Color": (0.8, 0.45, 0.15, 1.0)},
    "metallic_0_to_1": {"Metallic": 1.0},
}
#: The tolerance an edit must stay within: the baseline's own tile error (the mapping's and
#: the bake's, which every edit carries along) with `EDIT_MARGIN` of it to spare, plus
#: `NOISE_ALLOWANCE` times the two Cycles references' tile noise (combined in quadrature).
EDIT_MARGIN = 0.25
NOISE_ALLOWANCE = 3.0
#: Where the issue's goal (an edit within the baseline's tolerance) is asserted. The other
#: cases are measured and recorded, with what keeps them out: a metallic edit is as far from
#: Cycles as a fresh bake of the metal (the Principled → Blinn–Phong mapping of a smooth
#: metal), which the relit-vs-rebaked figure shows. At Blender's default bounces the base
#: colour edit also changes light that meets the sphere at the third vertex or later, which
#: the tail-edit layers carry (2026-11-28: 1.93 % against a tolerance of 4.70 %).
GOAL_ASSERTED = {("one", "roughness_0.25_to_0.6"), ("one", "base_colour_blue_to_orange"),
                 ("default", "roughness_0.25_to_0.6"), ("default", "base_colour_blue_to_orange"),
                 # In the basis of Principled lobes every edit, the metallic one included
                 # (2026-11-27: baseline 0.68 %, edits 0.52 / 0.74 / 1.92 %).
                 ("one_principled", "roughness_0.25_to_0.6"),
                 ("one_principled", "base_colour_blue_to_orange"),
                 ("one_principled", "metallic_0_to_1")}
#: What relighting may add to a fresh bake with the edited material (tile rel. L2): at one
#: bounce the basis projection only; at the default bounces also the tail. Bounds on
#: what was measured when the test was written (docs/fidelity.md), with room for the two
#: bakes' noise; an approximation's size, not a goal.
RELIGHT_BOUND = {"one": 0.02, "default": 0.08, "one_principled": 0.02}

_RESULTS: dict[str, dict] = {}
#: Where `results_file` (conftest.py) writes `_RESULTS`, in pytest's basetemp.
RESULTS_NAME = "relit_edit_agreement.json"


def _glossy_box():
    """`box_scene` at 64×48 with "Ball" the only editable material, at the baked values; a
    longer lens (the box's opening fills the frame) and the sphere 1.5 × larger (radius
    0.6 m, about 25 px across) so that its reflections cover several 8×8 tiles."""
    scene = box_scene(resolution=RES_X)
    scene.render.resolution_y = RES_Y
    scene.camera.data.lens = 45.0
    sphere = bpy.data.objects["Sphere"]
    sphere.scale = (1.5, 1.5, 1.5)
    sphere.location.z = 0.6
    bpy.data.materials["Floor"].relume.editable = False
    _set_ball(BAKED)
    bpy.context.view_layer.update()
    return scene


def _set_ball(values: dict) -> None:
    inputs = bpy.data.materials["Ball"].node_tree.nodes["Principled BSDF"].inputs
    for name, value in values.items():
        inputs[name].default_value = value


def _bake(addon, prefs, bounces: str) -> tuple[dict, float]:
    """Bake through the add-on's preferences, as a user does: the final preset, bounces one
    or from the scene's Cycles light paths; "one_principled" is one bounce with the editable
    material in the basis of Principled lobes (`lobe="principled"`, not in the preferences
    yet, so set on the settings the preferences give)."""
    prefs.preset = "final"
    prefs.bounces_from_scene = bounces == "default"
    prefs.bounces = 1
    settings = addon.api.bake_settings(bpy.context)
    if bounces == "one_principled":
        settings.lobe = "principled"
    t0 = time.perf_counter()
    report = addon.api.bake(settings=settings)
    return report, time.perf_counter() - t0


def _relit(addon, folder, name) -> np.ndarray:
    import relume

    out = addon.api.render(str(folder / f"{name}_relume.exr"), denoise="none")
    return np.asarray(relume.read_exr(out), dtype=np.float64)[..., :3]


def _tiles(a: np.ndarray, b: np.ndarray) -> float:
    return cy.rel_l2(cy.block_mean(a, BLOCK), cy.block_mean(b, BLOCK))


def _compare(image, c1, c2) -> dict:
    reference = 0.5 * (c1 + c2)
    assert image.shape == reference.shape and np.isfinite(image).all()
    return {
        "block8_rel_l2": _tiles(image, reference),
        "pixel_rel_l2": cy.rel_l2(image, reference),
        "mean_ratio": float(image.sum() / reference.sum()),
        "cycles_tile_noise": cy.noise_of_mean(cy.block_mean(c1, BLOCK), cy.block_mean(c2, BLOCK)),
    }


def _record(name, figures):
    _RESULTS[name] = figures
    print(f"\n[relit edits] {name}: baseline {figures['baseline']['block8_rel_l2']:.2%} (tiles),"
          f" {figures['layers']} layers, {figures['bounces_baked']} bounce(s) baked")
    for edit, f in figures["edits"].items():
        print(f"  {edit}: relit {f['block8_rel_l2']:.2%} (bound {f['bound']:.2%}, goal"
              f" {'asserted' if f['goal_asserted'] else 'recorded'}: {'met' if f['goal_met'] else 'not met'}),"
              f" mean ratio {f['mean_ratio']:.3f}; rebaked {f['rebaked_block8_rel_l2']:.2%};"
              f" relit vs rebaked {f['relit_vs_rebaked_block8']:.2%}; unedited relight"
              f" {f['unedited_relight_block8_rel_l2']:.2%}; Cycles noise {f['cycles_tile_noise']:.2%}")


@pytest.mark.parametrize("bounces", ["one", "default", "one_principled"])
def test_relit_edits_agree_with_cycles_as_the_baseline_does(addon, prefs, blend_dir, results_file,
                                                             bounces):
    scene = _glossy_box()
    cycles_bounces = None if bounces == "default" else 1
    t0 = time.perf_counter()
    base_c1, base_c2, _ = cy.render_cycles_pair(scene, blend_dir, "baseline", CYCLES_SPP, cycles_bounces)
    cycles_s = time.perf_counter() - t0
    report, bake_s = _bake(addon, prefs, bounces)
    baseline_image = _relit(addon, blend_dir, "baseline")
    baseline = _compare(baseline_image, base_c1, base_c2)
    figures = {"resolution": [RES_X, RES_Y], "cycles_spp": CYCLES_SPP,
               "bounces_baked": report.get("bounces"), "layers": report.get("layers"),
               "bake_s": round(bake_s, 1), "baseline": baseline, "edits": {}}
    relit_images, references = {}, {}
    for name, change in EDITS.items():
        _set_ball({**BAKED, **change})
        t0 = time.perf_counter()
        c1, c2, _ = cy.render_cycles_pair(scene, blend_dir, name, CYCLES_SPP, cycles_bounces)
        cycles_s += time.perf_counter() - t0
        relit_images[name] = _relit(addon, blend_dir, name)
        edit = _compare(relit_images[name], c1, c2)
        reference = references[name] = 0.5 * (c1 + c2)
        edit["cycles_edit_effect_block8"] = _tiles(0.5 * (base_c1 + base_c2), reference)
        edit["unedited_relight_block8_rel_l2"] = _tiles(baseline_image, reference)
        edit["bound"] = (baseline["block8_rel_l2"] * (1.0 + EDIT_MARGIN) + NOISE_ALLOWANCE
                         * float(np.hypot(baseline["cycles_tile_noise"], edit["cycles_tile_noise"])))
        edit["goal_met"] = edit["block8_rel_l2"] <= edit["bound"]
        edit["goal_asserted"] = (bounces, name) in GOAL_ASSERTED
        figures["edits"][name] = edit
    figures["cycles_s"] = round(cycles_s, 1)
    # The same edits baked afresh, each a new bake with the edited material: what relighting
    # adds, apart from the mapping both images share.
    for name, change in EDITS.items():
        _set_ball({**BAKED, **change})
        _bake(addon, prefs, bounces)
        rebaked = _relit(addon, blend_dir, f"{name}_rebaked")
        edit = figures["edits"][name]
        edit["relit_vs_rebaked_block8"] = _tiles(relit_images[name], rebaked)
        edit["relit_vs_rebaked_pixel"] = cy.rel_l2(relit_images[name], rebaked)
        edit["rebaked_block8_rel_l2"] = _tiles(rebaked, references[name])
    _set_ball(BAKED)
    _record(f"box_{bounces}_bounce", figures)
    for name, edit in figures["edits"].items():
        if edit["goal_asserted"]:
            assert edit["goal_met"], (name, figures)
        assert edit["relit_vs_rebaked_block8"] <= RELIGHT_BOUND[bounces], (name, figures)
        # Teeth: the edit moved the relit image towards Cycles' edited render — the unedited
        # relight is farther from it by more than the references' noise.
        noise = NOISE_ALLOWANCE * edit["cycles_tile_noise"]
        assert edit["block8_rel_l2"] + noise < edit["unedited_relight_block8_rel_l2"], (name, figures)
