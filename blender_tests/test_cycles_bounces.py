"""Relume against Cycles at Blender's DEFAULT light paths (Max Bounces 12, Diffuse 4,
Glossy 4): every bounce, not just the first.

Relume bakes the first bounce exactly (layers keyed by region and basis) and the later ones
with the bake-time materials, folded into the one-bounce layers, beside tail-edit layers that
carry albedo edits to them (core/engine/src/bake/path/integrator.rs, tail_edits.rs). The
add-on bakes with the scene's Cycles light paths
(`cycles_light_paths`: Max Bounces, no more than Diffuse + Glossy, 8 at the defaults, with
each path's diffuse and glossy bounces counted against their own limits of 4) and the final
preset bakes as many as the scene needs up to that (its 0.5 % light budget, measured by a
pre-pass). Relit at the bake-time materials, the
image must then look like the user's Cycles render:

- the assets' Cornell box (diffuse version), lit by its area light;
- a closed room lit only by a sun through a window opening (built here with bpy), where one
  bounce holds about two thirds of the light;
- the same Cornell box with its white walls a rough metal (fixed), where paths alternate
  glossy and diffuse bounces: Cycles counts each kind against its own limit, and so must
  Relume (a total cap of 4, what the add-on baked before, must come out darker).

Pass: relative L2 over 8×8-pixel tile means ≤ 3 % and mean ratio Relume/Cycles in
0.98–1.02 (one bounce gave 0.66–0.78). Small renders (64², Cycles 2 × 128 spp) keep the
file at about a minute on 2 cores; the Cycles noise on tiles is printed with the figures.
"""

from __future__ import annotations

import pathlib
import time

import bpy
import numpy as np
from support import cycles as cy
from support.rooms import window_room
from support.scene_import import import_scene

ROOT = pathlib.Path(__file__).resolve().parent.parent
RES = 64
CYCLES_SPP = 256
BLOCK = 8
TILE_TOLERANCE = 0.03
MEAN_RATIO = (0.98, 1.02)

_RESULTS: dict[str, dict] = {}
#: Where `results_file` (conftest.py) writes `_RESULTS`, in pytest's basetemp.
RESULTS_NAME = "cycles_bounces.json"


def _relume(addon, prefs, tmp: pathlib.Path, name: str, preset: str = "final",
            bounces_from_scene: bool = True, bounces: int = 1):
    """Bake through the add-on as a user would (preferences: the preset, bounces from the
    scene's Cycles settings) and relight the current materials."""
    import relume

    prefs.preset = preset
    prefs.bounces_from_scene = bounces_from_scene
    prefs.bounces = bounces
    settings = addon.api.bake_settings(bpy.context)
    t0 = time.perf_counter()
    report = addon.api.bake(settings=settings)
    seconds = time.perf_counter() - t0
    out = addon.api.render(str(tmp / f"{name}_relume.exr"), denoise="none")
    image = np.asarray(relume.read_exr(out), dtype=np.float64)[..., :3]
    return image, seconds, report, settings


def _check(addon, prefs, tmp: pathlib.Path, name: str, teeth: bool = True) -> dict:
    scene = bpy.context.scene
    c1, t1 = cy.render_cycles(scene, tmp / f"{name}_c1.exr", CYCLES_SPP // 2, seed=1, bounces=None)
    c2, t2 = cy.render_cycles(scene, tmp / f"{name}_c2.exr", CYCLES_SPP // 2, seed=2, bounces=None)
    c = scene.cycles
    cycles_paths = {k: getattr(c, k) for k in ("max_bounces", "diffuse_bounces", "glossy_bounces")}
    reference = 0.5 * (c1 + c2)
    image, bake_s, report, settings = _relume(addon, prefs, tmp, name)
    one, _, _, _ = _relume(addon, prefs, tmp, name + "_one_bounce", bounces_from_scene=False,
                           bounces=1)
    assert image.shape == reference.shape and np.isfinite(image).all()
    tiles = cy.rel_l2(cy.block_mean(image, BLOCK), cy.block_mean(reference, BLOCK))
    tiles_one = cy.rel_l2(cy.block_mean(one, BLOCK), cy.block_mean(reference, BLOCK))
    figures = {
        "resolution": RES,
        "cycles_spp": CYCLES_SPP,
        "cycles_light_paths": cycles_paths,
        "relume_cap": settings.bounces,
        "relume_bounces_baked": report.get("bounces"),
        "bounce_estimate": report.get("bounce_estimate"),
        f"block{BLOCK}_rel_l2": tiles,
        f"block{BLOCK}_cycles_noise": cy.noise_of_mean(cy.block_mean(c1, BLOCK), cy.block_mean(c2, BLOCK)),
        "pixel_rel_l2": cy.rel_l2(image, reference),
        "mean_ratio": float(image.sum() / reference.sum()),
        "one_bounce_mean_ratio": float(one.sum() / reference.sum()),
        f"one_bounce_block{BLOCK}_rel_l2": tiles_one,
        "cycles_s": t1 + t2,
        "relume_bake_s": bake_s,
    }
    _RESULTS[name] = figures
    print(f"\n[cycles bounces] {name}: " + ", ".join(
        f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in figures.items()
        if k != "bounce_estimate"))
    est = figures["bounce_estimate"] or {}
    if est:
        print(f"  pre-pass energy per bounce: {[round(e, 5) for e in est.get('energy', [])]}, "
              f"left out {est.get('left_out', 0):.4%}")
    assert figures["relume_cap"] == cy_cap(scene)
    assert (settings.diffuse_bounces, settings.glossy_bounces) == (c.diffuse_bounces, c.glossy_bounces)
    lo, hi = MEAN_RATIO
    assert lo <= figures["mean_ratio"] <= hi, figures
    assert tiles <= TILE_TOLERANCE, figures
    # Teeth: the one-bounce image (what Relume gave before) fails the same check.
    assert not teeth or not (lo <= figures["one_bounce_mean_ratio"] <= hi), figures
    return figures


def cy_cap(scene) -> int:
    c = scene.cycles
    return min(c.max_bounces, c.diffuse_bounces + c.glossy_bounces)


def test_cornell_box_at_default_bounces(addon, prefs, blend_dir, results_file):
    import_scene(ROOT / "assets" / "cornell.scene.json", resolution=(RES, RES), diffuse_only=True)
    _check(addon, prefs, blend_dir, "cornell_default_bounces")


def test_room_lit_by_a_sun_through_a_window_at_default_bounces(addon, prefs, blend_dir, results_file):
    window_room(RES)
    _check(addon, prefs, blend_dir, "window_room_default_bounces")


def test_glossy_cornell_box_counts_diffuse_and_glossy_bounces_apart(addon, prefs, blend_dir, results_file):
    """The Cornell box with its white walls (floor, ceiling, back) a rough metal: paths that
    alternate them with the coloured walls take up to four diffuse and four glossy bounces in
    Cycles. Relume with the scene's limits must match Cycles' mean; teeth: a total cap of 4
    (what the add-on baked before it passed the Diffuse and Glossy limits) is darker."""
    import relume

    import_scene(ROOT / "assets" / "cornell.scene.json", resolution=(RES, RES), diffuse_only=True)
    walls = bpy.data.materials["White walls"]
    walls.relume.editable = False
    tree = walls.node_tree
    for node in list(tree.nodes):
        if node.type != "OUTPUT_MATERIAL":
            tree.nodes.remove(node)
    bsdf = tree.nodes.new("ShaderNodeBsdfPrincipled")
    bsdf.inputs["Base Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    bsdf.inputs["Metallic"].default_value = 1.0
    bsdf.inputs["Roughness"].default_value = 0.3
    tree.links.new(bsdf.outputs["BSDF"], tree.nodes["Material Output"].inputs["Surface"])
    figures = _check(addon, prefs, blend_dir, "glossy_cornell_default_bounces", teeth=False)
    total4, _, report4, _ = _relume(addon, prefs, blend_dir, "glossy_cornell_total_4",
                                    bounces_from_scene=False, bounces=4)
    c1 = np.asarray(relume.read_exr(str(blend_dir / "glossy_cornell_default_bounces_c1.exr")),
                    dtype=np.float64)[..., :3]
    c2 = np.asarray(relume.read_exr(str(blend_dir / "glossy_cornell_default_bounces_c2.exr")),
                    dtype=np.float64)[..., :3]
    reference = 0.5 * (c1 + c2)
    figures["total_4_mean_ratio"] = float(total4.sum() / reference.sum())
    figures["total_4_bounces_baked"] = report4.get("bounces")
    print(f"  a total cap of 4: mean ratio {figures['total_4_mean_ratio']:.4f} "
          f"({figures['total_4_bounces_baked']} bounces baked)")
    assert figures["total_4_mean_ratio"] < figures["mean_ratio"] - 0.01, figures
