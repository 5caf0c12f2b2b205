"""Edits after one bake against Cycles at Blender's DEFAULT light paths, where most of the
light has bounced more than once: does the whole path follow the edit, not just its first
two vertices?

Two rooms (and two third-party scenes), each baked once through the add-on as a user bakes (the default preset, bounces
from the scene's Cycles settings, the default editable-material basis), then edited with
the shader sliders and relit, each edit compared with Cycles rendering the same edited
scene (12 bounces, 2 × 128 spp; the mean of the two is the reference, their difference its
noise):

- the assets' Cornell box, its white walls (floor, ceiling, back wall) an editable
  Principled material (grey 0.6, roughness 0.5);
- a closed room lit only by a sun through a window (`support.rooms`), its walls and ceiling
  an editable Diffuse BSDF (grey 0.7) and its floor an editable Principled (roughness 0.5);
- and, when the shared third-party scenes are beside the repository, McGuire's glossy
  Cornell box (back wall and glossy floor editable) and the bunny on its glossy ground tile
  (ground and bunny editable), each a wall (the ground) recoloured and a floor's roughness
  doubled.

Edits, each alone from the baked values: the walls' colour → 0.9, → 0.05, → (0.7, 0.25,
0.1), and a floor's roughness 0.5 → 0.2 (the Cornell box's floor is part of its white walls).

Measure: relative L2 over 8×8-pixel tile means and the mean ratio Relume / Cycles. The goal
(an edit is as right as the unedited image): its mean ratio within ±`MEAN_SHIFT` of the
unedited image's and its tile error within the unedited one's + `TILE_MARGIN`, plus the
references' noise. Asserted where measured to hold (`GOAL_ASSERTED`); the other edits are
recorded, with how far they miss, and held to the bound they were measured within
(`EDIT_BOUNDS`), so a regression fails. Teeth: every relit edit is closer to Cycles' edited
render than the unedited relight is.

Each edit is also rendered refined (`api.render(refine=REFINE_S)`: the bounces past the
second traced again with the edited materials and the difference added, what the add-on does
in the background once an edit settles) and held to the same goal, and to the relit edit's
tile error plus `REFINE_MARGIN`: the refinement adds its own noise, and must not make an
edit worse than that.

Figures go to stdout (`pytest -s`) and `tail_edit_agreement.json` in pytest's basetemp.
"""

from __future__ import annotations

import pathlib
import time

import bpy
import numpy as np
import pytest
from support import cycles as cy
from support.rooms import window_room
from support.scene_import import import_scene
from support.scenes import principled_material

ROOT = pathlib.Path(__file__).resolve().parent.parent
RES = 64
BLOCK = 8
CYCLES_SPP = 256
MEAN_SHIFT = 0.02
TILE_MARGIN = 0.01
#: Seconds of refinement per refined render (many passes at 64²), and how much worse on
#: tiles than the relit edit a refined one may be (its own noise).
REFINE_S = 2.0
REFINE_MARGIN = 0.005

WALL_EDITS = {
    "walls_to_0.9": (0.9, 0.9, 0.9),
    "walls_to_0.05": (0.05, 0.05, 0.05),
    "walls_to_rust": (0.7, 0.25, 0.1),
}
#: Edits the goal is asserted for (scene, edit): measured to meet it (bpy 5.0.1, 2026-11-29;
#: the third-party scenes 2026-11-30).
GOAL_ASSERTED: set[tuple[str, str]] = {
    ("cornell", "walls_to_0.9"), ("cornell", "walls_to_0.05"), ("cornell", "walls_to_rust"),
    ("cornell", "floor_roughness_0.5_to_0.2"),
    ("window_room", "walls_to_0.9"), ("window_room", "walls_to_0.05"),
    ("window_room", "walls_to_rust"),
    ("cornell_glossy", "walls_to_0.9"), ("cornell_glossy", "walls_to_0.05"),
    ("cornell_glossy", "walls_to_rust"), ("cornell_glossy", "floor_roughness_doubled"),
    ("bunny", "walls_to_0.9"), ("bunny", "walls_to_0.05"), ("bunny", "walls_to_rust"),
    ("bunny", "floor_roughness_doubled"),
}
#: The others, held to (tile error, |mean shift|) above what they measured, so a regression
#: fails. The window room's floor roughness 0.5 → 0.2 turns the sunlit patch into a sharp
#: reflection of a 1° sun (Cycles' image changes by 77 % on tiles): 5.5 % and a mean 3.2 %
#: high with the preview basis' least-squares edits, 2.0 % and 1.4 % low with the edit fit
#: that holds a lobe's energy (2026-11-30), within the goal but by a thin margin; the
#: refinement leaves it where it is (the first two vertices' share, not the tail's).
EDIT_BOUNDS: dict[tuple[str, str], tuple[float, float]] = {
    ("window_room", "floor_roughness_0.5_to_0.2"): (0.07, 0.045),
}

_RESULTS: dict[str, dict] = {}
#: Where `results_file` (conftest.py) writes `_RESULTS`, in pytest's basetemp.
RESULTS_NAME = "tail_edit_agreement.json"


def _colour_input(mat):
    nodes = mat.node_tree.nodes
    node = nodes.get("Principled BSDF") or nodes.get("Diffuse BSDF")
    return node.inputs["Base Color" if "Base Color" in node.inputs else "Color"]


def _set_colour(mat, rgb) -> None:
    _colour_input(mat).default_value = (*rgb, 1.0)


def _set_roughness(mat, value: float) -> None:
    mat.node_tree.nodes["Principled BSDF"].inputs["Roughness"].default_value = value


def _relit(addon, folder: pathlib.Path, name: str, refine: float = 0.0) -> np.ndarray:
    import relume

    bpy.context.view_layer.update()
    out = addon.api.render(str(folder / f"{name}_relume.exr"), denoise="none", refine=refine)
    return np.asarray(relume.read_exr(out), dtype=np.float64)[..., :3]


def _compare(image: np.ndarray, c1: np.ndarray, c2: np.ndarray) -> dict:
    ref = 0.5 * (c1 + c2)
    return {
        "tiles": cy.rel_l2(cy.block_mean(image, BLOCK), cy.block_mean(ref, BLOCK)),
        "mean_ratio": float(image.sum() / ref.sum()),
        "cycles_tile_noise": cy.noise_of_mean(cy.block_mean(c1, BLOCK), cy.block_mean(c2, BLOCK)),
    }


def _sweep(addon, prefs, folder: pathlib.Path, scene_name: str, edits: dict) -> dict:
    """Bake once as a user does, then relight each edit (a function that applies it, and
    one that undoes it) and render it with Cycles."""
    # The scene's light paths at Blender's defaults, as a user's scene has them (the bake
    # takes its bounce cap from them; an earlier test may have left other values).
    cy.configure_cycles(bpy.context.scene, CYCLES_SPP // 2, seed=1, bounces=None)
    prefs.preset = "preview"
    prefs.bounces_from_scene = True
    prefs.material_lobes = "principled"
    t0 = time.perf_counter()
    report = addon.api.bake(settings=addon.api.bake_settings(bpy.context))
    bake_s = time.perf_counter() - t0
    scene = bpy.context.scene
    figures: dict = {"bake_s": bake_s, "bounces_baked": report.get("bounces"), "edits": {}}
    states = {"unedited": (lambda: None, lambda: None), **edits}
    images = {}
    for name, (apply, undo) in states.items():
        apply()
        image = _relit(addon, folder, f"{scene_name}_{name}")
        refined = _relit(addon, folder, f"{scene_name}_{name}_refined", refine=REFINE_S)
        refine_report = addon.api.status()["refine"]
        c1, c2, cycles_s = cy.render_cycles_pair(scene, folder, f"{scene_name}_{name}", CYCLES_SPP,
                                                 bounces=None)
        undo()
        images[name] = (image, 0.5 * (c1 + c2))
        r = _compare(refined, c1, c2)
        figures["edits"][name] = {**_compare(image, c1, c2), "cycles_s": cycles_s,
                                  "refined_tiles": r["tiles"], "refined_mean_ratio": r["mean_ratio"],
                                  "refine_passes": refine_report["passes"],
                                  "refine_needed": refine_report["needed"]}
    base = figures["edits"]["unedited"]
    for name, f in figures["edits"].items():
        if name == "unedited":
            continue
        image, ref = images[name]
        f["mean_shift"] = f["mean_ratio"] - base["mean_ratio"]
        f["tiles_over_unedited"] = f["tiles"] - base["tiles"]
        f["unedited_relight_vs_edited_cycles"] = cy.rel_l2(cy.block_mean(images["unedited"][0], BLOCK),
                                                          cy.block_mean(ref, BLOCK))
        noise = float(np.hypot(f["cycles_tile_noise"], base["cycles_tile_noise"]))
        f["goal_met"] = bool(abs(f["mean_shift"]) <= MEAN_SHIFT
                             and f["tiles"] <= base["tiles"] + TILE_MARGIN + noise)
        f["refined_mean_shift"] = f["refined_mean_ratio"] - base["mean_ratio"]
        f["refined_goal_met"] = bool(abs(f["refined_mean_shift"]) <= MEAN_SHIFT
                                     and f["refined_tiles"] <= base["tiles"] + TILE_MARGIN + noise)
    _RESULTS[scene_name] = figures
    for name, f in figures["edits"].items():
        print(f"[tail edits] {scene_name} {name}: " + ", ".join(
            f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in f.items()))
    return figures


def _check(scene_name: str, figures: dict) -> None:
    for name, f in figures["edits"].items():
        if name == "unedited":
            continue
        key = (scene_name, name)
        # Teeth: the relit edit moved towards Cycles' edited render.
        assert f["tiles"] < f["unedited_relight_vs_edited_cycles"], (key, f)
        # The refinement traced this edit (every one changes a material of a bake with a
        # tail) and kept it at least as close to Cycles, up to its own noise.
        assert f["refine_needed"] and f["refine_passes"] >= 1, (key, f)
        assert f["refined_tiles"] <= f["tiles"] + REFINE_MARGIN, (key, f)
        if key in GOAL_ASSERTED:
            assert f["goal_met"], (key, f)
            assert f["refined_goal_met"], (key, f)
        elif key in EDIT_BOUNDS:
            tiles, shift = EDIT_BOUNDS[key]
            assert f["tiles"] <= tiles and abs(f["mean_shift"]) <= shift, (key, f)


def _cornell_edits(walls) -> dict:
    edits = {name: (lambda rgb=rgb: _set_colour(walls, rgb), lambda: _set_colour(walls, (0.6, 0.6, 0.6)))
             for name, rgb in WALL_EDITS.items()}
    edits["floor_roughness_0.5_to_0.2"] = (lambda: _set_roughness(walls, 0.2),
                                            lambda: _set_roughness(walls, 0.5))
    return edits


def test_cornell_box_walls_edited_after_one_bake(addon, prefs, blend_dir, results_file):
    import_scene(ROOT / "assets" / "cornell.scene.json", resolution=(RES, RES), diffuse_only=True)
    for mat in bpy.data.materials:  # only the walls are editable here
        mat.relume.editable = False
        mat.relume.override = False
    walls = principled_material("Cornell walls", (0.6, 0.6, 0.6), roughness=0.5, editable=True)
    old = bpy.data.materials["White walls"]
    for obj in bpy.data.objects:
        if obj.type == "MESH":
            for slot in obj.material_slots:
                if slot.material == old:
                    slot.material = walls
    figures = _sweep(addon, prefs, blend_dir, "cornell", _cornell_edits(walls))
    _check("cornell", figures)


def test_window_room_walls_and_floor_edited_after_one_bake(addon, prefs, blend_dir, results_file):
    walls = cy.diffuse_material("Room", (0.7, 0.7, 0.7))
    walls.relume.editable = True
    floor = principled_material("RoomFloor", (0.5, 0.45, 0.4), roughness=0.5, editable=True)
    window_room(RES, walls=walls, floor=floor)
    edits = {name: (lambda rgb=rgb: _set_colour(walls, rgb), lambda: _set_colour(walls, (0.7, 0.7, 0.7)))
             for name, rgb in WALL_EDITS.items()}
    edits["floor_roughness_0.5_to_0.2"] = (lambda: _set_roughness(floor, 0.2),
                                            lambda: _set_roughness(floor, 0.5))
    figures = _sweep(addon, prefs, blend_dir, "window_room", edits)
    _check("window_room", figures)


def _third_party(name: str, tmp_path: pathlib.Path) -> None:
    """Open a shared third-party scene (skipped with a message when the folder is absent),
    saved into `tmp_path` (the stacks go beside it), at the test's resolution."""
    path = ROOT.parent / "shared" / "scenes" / name
    if not path.exists():
        pytest.skip(f"{path} is absent: the third-party scenes live in ../shared/scenes/ beside the "
                    "repository (not part of it)")
    bpy.ops.wm.open_mainfile(filepath=str(path))
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / name))
    scene = bpy.context.scene
    aspect = scene.render.resolution_y / scene.render.resolution_x
    scene.render.resolution_x = RES
    scene.render.resolution_y = max(BLOCK, int(round(RES * aspect / BLOCK)) * BLOCK)
    scene.render.resolution_percentage = 100


def _third_party_edits(wall, floor) -> tuple[dict, float]:
    """`WALL_EDITS` on `wall`'s colour and `floor`'s roughness doubled, each undone after."""
    colour = tuple(_colour_input(wall).default_value)[:3]
    roughness = floor.node_tree.nodes["Principled BSDF"].inputs["Roughness"].default_value
    edits = {name: (lambda rgb=rgb: _set_colour(wall, rgb), lambda: _set_colour(wall, colour))
             for name, rgb in WALL_EDITS.items()}
    edits["floor_roughness_doubled"] = (lambda: _set_roughness(floor, 2.0 * roughness),
                                         lambda: _set_roughness(floor, roughness))
    return edits, roughness


def test_third_party_glossy_box_edited_after_one_bake(addon, prefs, tmp_path, results_file):
    """McGuire's glossy Cornell box from the shared third-party scenes: its back wall and its
    glossy floor ticked Editable, the back wall recoloured and the floor's roughness doubled
    (0.2 in the file → 0.4)."""
    _third_party("cornell_glossy.blend", tmp_path)
    for mat in bpy.data.materials:
        mat.relume.editable = mat.name in ("backWall", "floor")
    edits, roughness = _third_party_edits(bpy.data.materials["backWall"], bpy.data.materials["floor"])
    figures = _sweep(addon, prefs, tmp_path, "cornell_glossy", edits)
    figures["floor_roughness_baked"] = roughness
    _check("cornell_glossy", figures)


def test_third_party_bunny_ground_edited_after_one_bake(addon, prefs, tmp_path, results_file):
    """The shared bunny on its glossy ground tile under a sunny HDRI, outdoors: the ground
    and the bunny ticked Editable, the ground recoloured (the edits `WALL_EDITS` name) and its
    roughness doubled (0.15 in the file → 0.3). Outdoors little light bounces twice, so this
    mostly checks that the edits' first two vertices and the tail agree at once."""
    _third_party("bunny.blend", tmp_path)
    for mat in bpy.data.materials:
        mat.relume.editable = mat.name in ("GroundTile", "BunnyTerracotta")
    ground = bpy.data.materials["GroundTile"]
    edits, roughness = _third_party_edits(ground, ground)
    figures = _sweep(addon, prefs, tmp_path, "bunny", edits)
    figures["ground_roughness_baked"] = roughness
    _check("bunny", figures)
