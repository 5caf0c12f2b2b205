"""Relume on scenes nobody on the project made (issue 15): `../shared/scenes/` beside the
repository (see its README: McGuire's CornellBox-Glossy mapped to Principled, the same as
Blender's OBJ importer makes it with its emissive quad, the Stanford bunny on a glossy tile
under an HDRI). Skipped with a message when the folder is absent (it is not part of the
repository).

Each scene: export (every warning must be one this test explains), bake with the final
preset at a small resolution, relight, compare with a Cycles render made here at the file's
own light paths (one bounce), over 8×8 tiles. The figures are printed and recorded. These
scenes' materials are fixed, so Relume evaluates their Principled BSDFs as Cycles does
(core/engine/src/bake/path/surface_brdf.rs): the two opaque scenes must agree within 3 % on tiles
and 2 % on the mean (measured 1.1–1.4 % and 0.997–1.003, 2026-11-27); the `_asis` variant,
whose sphere has a transmission Relume renders opaque, within its measured gap (6.4 %,
mean 1.025) plus a margin. Its emissive quad must light the box and be seen: its pixels
show the emission's radiance as Cycles shows it.
"""

from __future__ import annotations

import pathlib
import time

import bpy
import numpy as np
import pytest
from support import cycles as cy

ROOT = pathlib.Path(__file__).resolve().parent.parent
SCENES = ROOT.parent / "shared" / "scenes"
RES = 64
CYCLES_SPP = 256
BLOCK = 8

#: Export warnings these scenes give and why they are expected (substring → reason).
EXPLAINED = {
    "Specular Tint": "OBJ importer materials tint the specular; Relume's mapping is untinted",
    "Transmission Weight": "the OBJ importer turns the .mtl's transparency into transmission; Relume "
                           "renders the sphere opaque (part of the measured gap)",
}

#: Per scene: (largest 8×8-tile relative L2, largest |mean ratio − 1|) asserted.
BOUNDS = {
    "cornell_glossy.blend": (0.03, 0.02),
    "cornell_glossy_asis.blend": (0.09, 0.05),
    "bunny.blend": (0.03, 0.02),
}

_RESULTS: dict[str, dict] = {}
#: Where `results_file` (conftest.py) writes `_RESULTS`, in pytest's basetemp.
RESULTS_NAME = "third_party_scenes.json"


def _open(name: str) -> None:
    path = SCENES / name
    if not path.exists():
        pytest.skip(f"{path} is absent: the third-party scenes live in ../shared/scenes/ beside the "
                    "repository (not part of it)")
    bpy.ops.wm.open_mainfile(filepath=str(path))
    scene = bpy.context.scene
    aspect = scene.render.resolution_y / scene.render.resolution_x
    scene.render.resolution_x = RES
    scene.render.resolution_y = max(BLOCK, int(round(RES * aspect / BLOCK)) * BLOCK)
    scene.render.resolution_percentage = 100


@pytest.mark.parametrize("name", ["cornell_glossy.blend", "cornell_glossy_asis.blend", "bunny.blend"])
def test_third_party_scene_agrees_with_cycles(addon, prefs, tmp_path, results_file, name):
    import relume

    _open(name)
    scene = bpy.context.scene
    # Cycles first: it hides lamp objects from the camera (support/cycles.py) and the export
    # then reads the same visibility.
    c1, t1 = cy.render_cycles(scene, tmp_path / "c1.exr", CYCLES_SPP // 2, seed=1, bounces=1)
    c2, t2 = cy.render_cycles(scene, tmp_path / "c2.exr", CYCLES_SPP // 2, seed=2, bounces=1)
    reference = 0.5 * (c1 + c2)
    result = addon.api.export()
    warnings = [str(w) for w in result.warnings]
    unexplained = [w for w in warnings if not any(k in w for k in EXPLAINED)]
    assert not unexplained, unexplained
    t0 = time.perf_counter()
    report = addon.api.bake(settings=relume.BakeSettings.preset("final", seed=0, bounces=1))
    bake_s = time.perf_counter() - t0
    out = addon.api.render(str(tmp_path / "relume.exr"), denoise="none")
    image = np.asarray(relume.read_exr(out), dtype=np.float64)[..., :3]
    assert image.shape == reference.shape and np.isfinite(image).all()
    blocks = cy.block_mean(image, BLOCK)
    ref_blocks = cy.block_mean(reference, BLOCK)
    figures = {
        "resolution": list(reference.shape[:2]),
        "cycles_spp": CYCLES_SPP,
        "cycles_noise_of_mean_tiles": cy.noise_of_mean(cy.block_mean(c1, BLOCK), cy.block_mean(c2, BLOCK)),
        "block8_rel_l2": cy.rel_l2(blocks, ref_blocks),
        "pixel_rel_l2": cy.rel_l2(image, reference),
        "mean_ratio_relume_over_cycles": float(image.sum() / reference.sum()),
        "relume_layers": report.get("layers"),
        "relume_bake_s": bake_s,
        "cycles_s": t1 + t2,
        "warnings": warnings,
        "emissive_lights": [li for li in result.scene_dict["lights"] if li["type"] == "emissive"],
    }
    if name == "cornell_glossy_asis.blend":
        # The emissive quad is exported as a light and is seen: the brightest Cycles pixels
        # (the quad) are bright in Relume too, with the same radiance.
        assert figures["emissive_lights"], "the emissive quad was not exported as a light"
        quad = reference.max(axis=2) >= 0.5 * reference.max()
        figures["emitter_pixels"] = int(quad.sum())
        figures["emitter_ratio_relume_over_cycles"] = float(image[quad].sum() / reference[quad].sum())
    _RESULTS[name] = figures
    print(f"\n[third-party] {name}: " + ", ".join(
        f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in figures.items()))
    assert image.max() > 0
    tiles, mean = BOUNDS[name]
    assert abs(figures["mean_ratio_relume_over_cycles"] - 1.0) <= mean, figures
    assert figures["block8_rel_l2"] <= tiles, figures
    if "emitter_ratio_relume_over_cycles" in figures:
        assert 0.8 <= figures["emitter_ratio_relume_over_cycles"] <= 1.2, figures


def test_default_bake_with_two_editable_materials_is_not_lost(addon, prefs, tmp_path):
    """The bake a user makes first — the default (preview) preset at the file's own
    resolution, Blender's default light paths, two materials ticked Editable — once lost
    everything at the very end on this scene (seed 0): a denoised layer so faint over a tile
    that its f16 scale was subnormal stored NaN, and the writer refused the file. It must
    complete, relight finite, and report no value any stage had to keep finite."""
    import relume

    path = SCENES / "cornell_glossy_asis.blend"
    if not path.exists():
        pytest.skip(f"{path} is absent: the third-party scenes live in ../shared/scenes/ beside "
                    "the repository (not part of it)")
    bpy.ops.wm.open_mainfile(filepath=str(path))
    for name in ("backWall", "floor"):
        bpy.data.materials[name].relume.editable = True
    addon.api.export()
    report = addon.api.bake(settings=relume.BakeSettings.preset("preview", seed=0))
    counts = report["report"]["non_finite"]
    print(f"\n[third-party] cornell_glossy_asis default bake: {report.get('layers')} layers, "
          f"non-finite kept out {counts}")
    image = np.asarray(relume.read_exr(addon.api.render(str(tmp_path / "relume.exr"), denoise="none")))
    assert np.isfinite(image).all() and image[..., :3].max() > 0
    assert sum(counts.values()) == 0, counts


#: Edits of the bunny's editable materials after one bake (material, input, value, and the
#: asserted largest tile error and |ground mean ratio − 1|), each held to the unedited
#: image's error plus the preview's noise. Colour and metallic edits keep the bake-time
#: lobe's shape (measured 2.9 % and 4.0 %, ground within 0.4 %); a roughness edit changes
#: it, as far as the preview's 17-slot basis carries it (measured 2.7 %, the ground's
#: reflection 1.007 of Cycles; 13 slots gave 4.0 % and 0.941).
#: The bake's own noise is most of these bounds at 64 px: the preview bake's tile error
#: between bakes of other seeds is about 2.5 % unedited and 3.4 % with the bunny made metal
#: (four seeds, `relume bake --preset preview --bounces 1 --resolution 64x64`, 2026-11-30),
#: so the metal edit's bound sits above that noise by what the basis may add.
BUNNY_EDITS = {
    "ground_roughness_0.15_to_0.3": ("GroundTile", "Roughness", 0.3, 0.045, 0.03),
    "ground_colour_to_rust": ("GroundTile", "Base Color", (0.55, 0.25, 0.12, 1.0), 0.045, 0.03),
    "bunny_metallic_0_to_1": ("BunnyTerracotta", "Metallic", 1.0, 0.05, 0.03),
}


def test_bunny_with_editable_materials_against_cycles(addon, prefs, tmp_path, results_file):
    """The bunny's ground (Principled, roughness 0.15, reflecting the sky and the bunny) and
    the bunny ticked Editable, baked once as a user bakes first: the default (preview)
    preset, whose editable Principled materials go into the basis of Principled lobes with
    each region's bake-time lobe as a slot of its own, one bounce as the file's light paths.
    The unedited image is the bake-time materials evaluated as Cycles does. (The Blinn–Phong
    basis, `lobe="blinn-phong"`, loses the ground's reflections there: 11.9 % on tiles, the
    ground 0.943 of Cycles, measured 2026-11-28; not re-run here to keep the suite's time.)
    Then edits of the ground and the bunny, relit from that one bake, each against Cycles
    rendered with the same values: the relit image over the whole frame and the ground's
    pixels (the reflection region) alone."""
    import relume

    _open("bunny.blend")
    scene = bpy.context.scene
    ids, names = cy.material_ids(scene, tmp_path / "ids.exr")
    ground = ids == names.index("Ground")
    for m in ("GroundTile", "BunnyTerracotta"):
        bpy.data.materials[m].relume.editable = True

    def compare(image, c1, c2):
        reference = 0.5 * (c1 + c2)
        assert image.shape == reference.shape and np.isfinite(image).all()
        return {
            "block8_rel_l2": cy.rel_l2(cy.block_mean(image, BLOCK), cy.block_mean(reference, BLOCK)),
            "mean_ratio": float(image.sum() / reference.sum()),
            "ground_mean_ratio": float(image[ground].sum() / reference[ground].sum()),
            "cycles_tile_noise": cy.noise_of_mean(cy.block_mean(c1, BLOCK), cy.block_mean(c2, BLOCK)),
        }

    def relit(name):
        out = addon.api.render(str(tmp_path / f"{name}.exr"), denoise="none")
        return np.asarray(relume.read_exr(out), dtype=np.float64)[..., :3]

    c1, _ = cy.render_cycles(scene, tmp_path / "c1.exr", CYCLES_SPP // 2, seed=1, bounces=1)
    c2, _ = cy.render_cycles(scene, tmp_path / "c2.exr", CYCLES_SPP // 2, seed=2, bounces=1)
    addon.api.export()
    figures = {"ground_pixels": int(ground.sum())}
    settings = relume.BakeSettings.preset("preview", seed=0, bounces=1)
    assert settings.lobe == "principled", "the default preset bakes editable Principled materials in their lobes"
    report = addon.api.bake(settings=settings)
    figures["principled"] = {"layers": report.get("layers"), **compare(relit("principled"), c1, c2)}
    edits = {}
    for edit, (material, name, value, _, _) in BUNNY_EDITS.items():
        inputs = bpy.data.materials[material].node_tree.nodes["Principled BSDF"].inputs
        before = inputs[name].default_value
        before = tuple(before) if hasattr(before, "__len__") else before
        inputs[name].default_value = value
        bpy.context.view_layer.update()
        e1, _ = cy.render_cycles(scene, tmp_path / f"{edit}_c1.exr", CYCLES_SPP // 2, seed=1, bounces=1)
        e2, _ = cy.render_cycles(scene, tmp_path / f"{edit}_c2.exr", CYCLES_SPP // 2, seed=2, bounces=1)
        edits[edit] = compare(relit(edit), e1, e2)
        inputs[name].default_value = before
        bpy.context.view_layer.update()
    figures["principled_edits"] = edits
    _RESULTS["bunny_editable"] = figures
    print("\n[third-party] bunny.blend, ground and bunny editable:")
    for lobe in ("principled",):
        f = figures[lobe]
        print(f"  {lobe}: tiles {f['block8_rel_l2']:.2%}, mean {f['mean_ratio']:.3f}, ground mean"
              f" {f['ground_mean_ratio']:.3f}, {f['layers']} layers")
    for edit, f in edits.items():
        print(f"  principled, {edit}: tiles {f['block8_rel_l2']:.2%}, mean {f['mean_ratio']:.3f},"
              f" ground mean {f['ground_mean_ratio']:.3f}, Cycles noise {f['cycles_tile_noise']:.2%}")
    # Measured 2026-11-29 at the preview preset: 2.33 % (ground 0.997). Asserted: the
    # unedited image as the fixed scene's bound; each edit as BUNNY_EDITS says.
    p = figures["principled"]
    assert p["block8_rel_l2"] <= 0.03 and abs(p["ground_mean_ratio"] - 1.0) <= 0.02, figures
    for edit, f in edits.items():
        tiles, ground = BUNNY_EDITS[edit][3:]
        assert f["block8_rel_l2"] <= tiles and abs(f["ground_mean_ratio"] - 1.0) <= ground, (edit, f)
