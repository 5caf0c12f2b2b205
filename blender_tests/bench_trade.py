"""The trade: Relume's first image and its edits against Cycles + OpenImageDenoise.

    python3 blender_tests/bench_trade.py [--scenes bunny.blend,cornell_glossy.blend]
        [--presets draft,preview,final] [--ladder 1,2,4,8,16,32,64] [--reference-spp 512]
        [--sweep-spp 128] [--no-sweep] [--rebake misses|TAG,…] [--out out/trade] [--scene-dir DIR]
        [--reuse-cycles OUT] [--repeats 3]

What a user weighs before pressing Bake: Cycles with OpenImageDenoise (in every Blender)
renders the picture in seconds; Relume bakes once and then shows every edit in milliseconds.
For each scene (a .blend, at its own resolution and Blender's default light paths, its
editable materials ticked as `EDITABLE` says), on this machine, in one run:

1. **Reference**: Cycles at `--reference-spp` (two renders of half as many samples, other
   seeds; the mean is the reference, their difference its noise over 8×8 tiles), unbiased
   (`support.cycles.configure_cycles`: no clamping, no light tree, no adaptive sampling).
2. **Cycles + OIDN ladder**: the same settings with Cycles' own OpenImageDenoise (albedo and
   normal passes, prefilter Accurate, quality High) at each `--ladder` sample count: wall
   time of `bpy.ops.render.render` (scene sync, BVH, path tracing, denoising) and tile error.
3. **Relume at each preset**, through the add-on with its default preferences (editable
   Principled materials in the basis of Principled lobes, bounces from the scene): the bake's
   wall time (export, bake, loading the stack), the shown image (`api.render`: the relit
   image through OIDN with the scene's features) and its time — both `--repeats` times with
   the same seed, the medians used and min and median kept —, the exact relit image, and per
   edit the raw relight's and the denoised relight's time. The Principled basis is built
   beforehand by a small throw-away bake at each preset and kept in the machine's cache (a
   first bake on a new machine pays it once, `basis_warmup_s`). A preset may carry changed
   settings, to try a retune: `--presets preview,preview+spp=8+compression_tolerance=0.005`.
4. **The trade**: Cycles + OIDN's time to the shown image's tile error (log–log between the
   two ladder points around it), Relume's bake over that time, and the number of edits after
   which Relume has paid for its bake (each Cycles render to that error against each denoised
   relight).
5. **Ten edits** (`SWEEPS`, not `--no-sweep`), from the default preset's bake: each edit's
   shown image and exact relit image (and, with `--refine S`, the shown image after S seconds
   of refinement) against Cycles + OIDN at `--sweep-spp` with the same values; the
   tolerance is the unedited shown image's error against its own Cycles + OIDN render plus
   one point. A denoiser artefact that moves with the edit shows as an edit whose
   shown image is further from Cycles than its relit image is.
6. **Re-baked edits** (`--rebake misses` or `--rebake TAG,TAG`): each chosen edit of the
   sweep (`misses`: those outside the tolerance) baked afresh at the same preset with its
   values as the scene's own, its shown and relit images against the same Cycles + OIDN
   render. What a user would get by re-baking after the edit: it tells the edit's own
   error (relit from the one bake) from the preset's error on the edited material.

Errors are relative L2 over 8×8-pixel tile means against the reference, with the
reference's own noise taken out in quadrature (√(e² − n²); both are measured). Prints JSON
to stdout and writes OUT/trade.json, OUT/trade.md and, when matplotlib is installed,
OUT/trade.png (error against time, log–log: Cycles + OIDN's ladder as a line, Relume's
presets as points). Nothing is asserted: this is the figure docs/trade.md shows.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import pathlib
import sys
import tempfile
import time

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="relume-trade-user-"))

import bpy  # noqa: E402
import numpy as np  # noqa: E402
from conftest import ROOT, install_addon  # noqa: E402
from support import cycles as cy  # noqa: E402

BLOCK = 8

#: The materials a user would tick Editable in each scene: the glossy ones they look at.
EDITABLE = {
    "bunny.blend": ["GroundTile", "BunnyTerracotta"],
    "cornell_glossy.blend": ["floor", "backWall"],
    "cornell_glossy_asis.blend": ["floor", "backWall"],
}

#: Ten edits per scene, each from the baked values: name → [(material, input, value), ...].
SWEEPS = {
    "bunny.blend": {
        "ground_rust": [("GroundTile", "Base Color", (0.55, 0.25, 0.12, 1.0))],
        "ground_white": [("GroundTile", "Base Color", (0.8, 0.8, 0.8, 1.0))],
        "ground_roughness_0.3": [("GroundTile", "Roughness", 0.3)],
        "ground_roughness_0.6": [("GroundTile", "Roughness", 0.6)],
        "bunny_blue": [("BunnyTerracotta", "Base Color", (0.2, 0.35, 0.7, 1.0))],
        "bunny_white": [("BunnyTerracotta", "Base Color", (0.9, 0.9, 0.9, 1.0))],
        "bunny_roughness_0.2": [("BunnyTerracotta", "Roughness", 0.2)],
        "bunny_roughness_0.8": [("BunnyTerracotta", "Roughness", 0.8)],
        "bunny_metallic_1": [("BunnyTerracotta", "Metallic", 1.0)],
        "both_recoloured": [("GroundTile", "Base Color", (0.55, 0.25, 0.12, 1.0)),
                            ("BunnyTerracotta", "Base Color", (0.2, 0.35, 0.7, 1.0))],
    },
    "cornell_glossy.blend": {
        "floor_rust": [("floor", "Base Color", (0.55, 0.25, 0.12, 1.0))],
        "floor_dark": [("floor", "Base Color", (0.1, 0.1, 0.1, 1.0))],
        "floor_roughness_0.4": [("floor", "Roughness", 0.4)],
        "floor_roughness_0.7": [("floor", "Roughness", 0.7)],
        "floor_metallic_1": [("floor", "Metallic", 1.0)],
        "back_blue": [("backWall", "Base Color", (0.2, 0.35, 0.7, 1.0))],
        "back_white": [("backWall", "Base Color", (0.9, 0.9, 0.9, 1.0))],
        "back_dark": [("backWall", "Base Color", (0.05, 0.05, 0.05, 1.0))],
        "back_roughness_0.5": [("backWall", "Roughness", 0.5)],
        "both_recoloured": [("floor", "Base Color", (0.55, 0.25, 0.12, 1.0)),
                            ("backWall", "Base Color", (0.2, 0.35, 0.7, 1.0))],
    },
}


def _tiles(image: np.ndarray) -> np.ndarray:
    return cy.block_mean(image, BLOCK)


def _error(image: np.ndarray, reference: np.ndarray, noise: float) -> dict:
    raw = cy.rel_l2(_tiles(cy.at_size_of(image, reference.shape)), _tiles(reference))
    return {"raw": raw, "corrected": math.sqrt(max(raw * raw - noise * noise, 0.0))}


def _configure_denoised(scene, samples: int, seed: int) -> None:
    """Cycles as the agreement tests set it, plus its OpenImageDenoise as a user turns it on."""
    cy.configure_cycles(scene, samples, seed, bounces=None)
    c = scene.cycles
    c.use_denoising = True
    c.denoiser = "OPENIMAGEDENOISE"
    c.denoising_input_passes = "RGB_ALBEDO_NORMAL"
    c.denoising_prefilter = "ACCURATE"
    if hasattr(c, "denoising_quality"):
        c.denoising_quality = "HIGH"
    if hasattr(c, "denoising_use_gpu"):
        c.denoising_use_gpu = False


def _render(scene, path: pathlib.Path) -> tuple[np.ndarray, float]:
    scene.render.filepath = str(path)
    t0 = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    seconds = time.perf_counter() - t0
    return _read(path), seconds


def cycles_denoised(scene, path: pathlib.Path, samples: int, seed: int = 3):
    _configure_denoised(scene, samples, seed)
    return _render(scene, path)


def time_to_error(ladder: list[dict], error: float) -> dict:
    """Cycles + OIDN's time to `error`, log–log between the ladder points around it."""
    points = sorted(ladder, key=lambda p: p["spp"])
    if error >= points[0]["error"]["corrected"]:
        return {"seconds": points[0]["seconds"], "bound": "at_most", "spp": points[0]["spp"]}
    for a, b in zip(points, points[1:], strict=False):
        ea, eb = a["error"]["corrected"], b["error"]["corrected"]
        if ea >= error >= eb and ea > eb > 0:
            f = (math.log(error) - math.log(ea)) / (math.log(eb) - math.log(ea))
            seconds = math.exp(math.log(a["seconds"]) + f * (math.log(b["seconds"]) - math.log(a["seconds"])))
            spp = math.exp(math.log(a["spp"]) + f * (math.log(b["spp"]) - math.log(a["spp"])))
            return {"seconds": seconds, "bound": "interpolated", "spp": spp}
    return {"seconds": points[-1]["seconds"], "bound": "more_than", "spp": points[-1]["spp"]}


def _read(path: pathlib.Path) -> np.ndarray:
    import relume

    return np.asarray(relume.read_exr(str(path)), dtype=np.float64)[..., :3]


def _write(path: pathlib.Path, rgb: np.ndarray) -> None:
    import relume

    if path.exists():
        return
    alpha = np.ones(rgb.shape[:2] + (1,))
    relume.write_exr(str(path), np.ascontiguousarray(np.concatenate([rgb, alpha], axis=2), dtype=np.float32))


def _previous_cycles(folder: pathlib.Path | None, name: str) -> dict | None:
    if folder is None:
        return None
    for scene in json.loads((folder / "trade.json").read_text())["scenes"]:
        if scene["scene"] == name:
            return scene
    raise SystemExit(f"{folder / 'trade.json'} has no {name}")


def _open(scene_dir: pathlib.Path, name: str):
    bpy.ops.wm.open_mainfile(filepath=str(scene_dir / name))
    scene = bpy.context.scene
    scene.render.resolution_percentage = 100
    for axis in ("resolution_x", "resolution_y"):  # whole 8×8 tiles
        setattr(scene.render, axis, max(BLOCK, getattr(scene.render, axis) // BLOCK * BLOCK))
    return scene


def _set(edits) -> list:
    """Apply (material, input, value) edits; returns what undoes them."""
    undo = []
    for mat, inp, value in edits:
        socket = bpy.data.materials[mat].node_tree.nodes["Principled BSDF"].inputs[inp]
        old = tuple(socket.default_value) if hasattr(socket.default_value, "__len__") else socket.default_value
        undo.append((mat, inp, old))
        socket.default_value = value
    bpy.context.view_layer.update()
    return undo


def _relume_images(addon, folder: pathlib.Path, tag: str) -> dict:
    """The shown (OIDN, `high`) and exact relit images with the current materials, timed."""
    live = addon.runtime.RUNTIME.live
    t0 = time.perf_counter()
    shown = addon.api.render(str(folder / f"{tag}_shown.exr"), denoise="oidn")
    shown_s = time.perf_counter() - t0
    report = dict(live.last_denoise or {})
    relit = addon.api.render(str(folder / f"{tag}_relit.exr"), denoise="none")
    return {"shown": _read(shown), "relit": _read(relit), "shown_s": shown_s,
            "relight_ms": live.relighter.last_ms, "denoise": report}


def _edit_times(addon, edits: dict, repeats: int = 3) -> dict:
    """Per edit: the raw relight (what a slider shows) and the settled image (OIDN
    `balanced`, as the add-on shows it when the slider stops), each min over the edits."""
    live = addon.runtime.RUNTIME.live
    raw, settled = [], []
    for _ in range(repeats):
        for changes in edits.values():
            undo = _set(changes)
            t0 = time.perf_counter()
            addon.api.relight(denoise="none")
            raw.append((time.perf_counter() - t0) * 1e3)
            t0 = time.perf_counter()
            live.denoised(quality="balanced")
            settled.append((time.perf_counter() - t0) * 1e3)
            _set(undo)
    return {"raw_ms": {"min": min(raw), "median": float(np.median(raw))},
            "settled_ms": {"min": min(settled), "median": float(np.median(settled))}}


def _variant(text: str) -> tuple[str, dict]:
    """"preview+spp=8+adaptive_threshold=0.05" → ("preview", {"spp": 8, ...}): a preset with
    some of its settings changed, for trying a retune."""
    preset, *changes = text.split("+")
    overrides = {}
    for change in changes:
        key, _, value = change.partition("=")
        try:
            overrides[key] = int(value)
        except ValueError:
            try:
                overrides[key] = float(value)
            except ValueError:
                overrides[key] = value
    return preset, overrides


def _bake(addon, prefs, variant: str) -> tuple[dict, float]:
    import relume

    preset, overrides = _variant(variant)
    prefs.preset = preset
    t0 = time.perf_counter()
    settings = addon.api.bake_settings(bpy.context)
    if overrides:
        settings = relume.BakeSettings(**{**settings.to_dict(), **overrides})
    report = addon.api.bake(settings=settings)
    return report, time.perf_counter() - t0


def _warm_basis(addon, prefs, scene, preset: str) -> float:
    """A throw-away bake at a tiny resolution: builds the preset's Principled basis into the
    machine's cache (a user pays this once per machine), so the timed bake does not."""
    saved = scene.render.resolution_percentage
    scene.render.resolution_percentage = 10
    try:
        _, seconds = _bake(addon, prefs, preset)
    finally:
        scene.render.resolution_percentage = saved
    addon.runtime.RUNTIME.live.unload()
    return seconds


def bench_scene(addon, prefs, scene_dir: pathlib.Path, name: str, args, folder: pathlib.Path) -> dict:
    scene = _open(scene_dir, name)
    bpy.ops.wm.save_as_mainfile(filepath=str(folder / "scene.blend"))  # stacks go beside it
    for mat in EDITABLE.get(name, []):
        bpy.data.materials[mat].relume.editable = True
    # Blender's default light paths, which the bake takes its bounce cap from (the files
    # are saved with one bounce).
    cy.configure_cycles(scene, args.reference_spp, seed=1, bounces=None)
    out: dict = {"scene": name, "resolution": [scene.render.resolution_x, scene.render.resolution_y],
                 "editable": EDITABLE.get(name, [])}

    previous = _previous_cycles(args.reuse_cycles, name)
    if previous is None:
        c1, c2, ref_s = cy.render_cycles_pair(scene, folder, "reference", args.reference_spp, bounces=None)
    else:  # an earlier run's Cycles side, to try Relume's settings without re-rendering it
        c1, c2 = (_read(args.reuse_cycles / "work" / folder.name / f"reference_c{i}.exr") for i in (1, 2))
        ref_s = previous["reference"]["seconds"]
        out["cycles_from"] = str(args.reuse_cycles)
    for i, image in ((1, c1), (2, c2)):  # kept for a later --reuse-cycles
        _write(folder / f"reference_c{i}.exr", image)
    reference = 0.5 * (c1 + c2)
    noise = cy.noise_of_mean(_tiles(c1), _tiles(c2))
    out["reference"] = {"spp": args.reference_spp if previous is None else previous["reference"]["spp"],
                        "seconds": ref_s, "tile_noise": noise}
    print(f"[trade] {name}: reference {ref_s:.1f} s, tile noise {noise:.4f}", file=sys.stderr)

    ladder = [] if previous is None else previous["cycles_oidn"]
    for spp in args.ladder if previous is None else []:
        image, seconds = cycles_denoised(scene, folder / f"cycles_oidn_{spp}.exr", spp)
        ladder.append({"spp": spp, "seconds": seconds, "error": _error(image, reference, noise)})
        print(f"[trade] {name}: Cycles + OIDN {spp} spp {seconds:.2f} s "
              f"{ladder[-1]['error']['corrected']:.4f}", file=sys.stderr)
    out["cycles_oidn"] = ladder

    presets = {}
    for preset in args.presets:
        warm = _warm_basis(addon, prefs, scene, preset)
        # The VM is shared and noisy: bake (same seed, the same stack each time) and make the
        # shown image `--repeats` times, and take the medians; min and median are kept.
        runs = []
        for _ in range(max(1, args.repeats)):
            report, bake_s = _bake(addon, prefs, preset)
            images = _relume_images(addon, folder, preset)
            runs.append((bake_s, images["shown_s"], report))
        bake_times = [r[0] for r in runs]
        shown_times = [r[1] for r in runs]
        middle = sorted(range(len(runs)), key=lambda i: bake_times[i])[len(runs) // 2]
        bake_s, report = bake_times[middle], runs[middle][2]
        images["shown_s"] = float(np.median(shown_times))
        shown = _error(images["shown"], reference, noise)
        relit = _error(images["relit"], reference, noise)
        edits = _edit_times(addon, dict(list(SWEEPS.get(name, {}).items())[:3])) if SWEEPS.get(name) else None
        first_image_s = bake_s + images["shown_s"]
        cycles = time_to_error(ladder, shown["corrected"])
        row = {
            "bake_s": bake_s, "basis_warmup_s": warm, "layers": report.get("layers"),
            "repeats": {"bake_s": bake_times, "shown_s": shown_times,
                        "first_image_s": {"min": min(bake_times) + min(shown_times),
                                          "median": bake_s + images["shown_s"]}},
            "bake_phases_s": {k: (report.get("report") or {}).get(f"{k}_seconds")
                              for k in ("setup", "trace", "assembly", "denoise")},
            "bounces": report.get("bounces"), "shown_s": images["shown_s"],
            "first_image_s": first_image_s, "shown_error": shown, "relit_error": relit,
            "denoise": {k: images["denoise"].get(k) for k in ("ran", "device", "quality", "ms", "note")},
            "edit": edits, "cycles_oidn_to_same_error": cycles,
            "first_image_over_cycles_oidn": first_image_s / cycles["seconds"],
        }
        if edits is not None and cycles["seconds"] > edits["settled_ms"]["median"] / 1e3:
            per_edit_saving = cycles["seconds"] - edits["settled_ms"]["median"] / 1e3
            row["edits_to_pay_for_bake"] = math.ceil(max(first_image_s - cycles["seconds"], 0.0) / per_edit_saving)
        presets[preset] = row
        print(f"[trade] {name}: {preset} bake {bake_s:.1f} s, shown {shown['corrected']:.4f} "
              f"(relit {relit['corrected']:.4f}), Cycles + OIDN {cycles['seconds']:.2f} s "
              f"({cycles['bound']}), ratio {row['first_image_over_cycles_oidn']:.2f}", file=sys.stderr)
        if preset == args.sweep_preset and not args.no_sweep and name in SWEEPS:
            out["sweep"] = sweep(addon, scene, name, folder, args.sweep_spp, args.refine)
            if args.rebake:
                rebake(addon, prefs, preset, name, folder, out["sweep"], args.rebake)
        addon.runtime.RUNTIME.live.unload()
    out["relume"] = presets
    return out


def sweep(addon, scene, name: str, folder: pathlib.Path, spp: int, refine: float = 0.0) -> dict:
    """The ten edits against Cycles + OIDN at `spp` with the same values (seed 3); with
    `refine` > 0 also the shown image after that many seconds of refinement."""
    rows = {}
    for tag, changes in {"unedited": [], **SWEEPS[name]}.items():
        undo = _set(changes)
        images = _relume_images(addon, folder, f"sweep_{tag}")
        refined = None
        if refine > 0.0:
            refined = _read(addon.api.render(str(folder / f"sweep_{tag}_refined.exr"), denoise="oidn",
                                             refine=refine))
            refine_report = dict(addon.api.status()["refine"] or {})
        target, seconds = cycles_denoised(scene, folder / f"sweep_{tag}_cycles.exr", spp)
        _set(undo)
        for kind in ("shown", "relit"):
            images[kind] = cy.at_size_of(images[kind], target.shape)
        rows[tag] = {
            "shown": cy.rel_l2(_tiles(images["shown"]), _tiles(target)),
            "relit": cy.rel_l2(_tiles(images["relit"]), _tiles(target)),
            "mean_ratio": float(images["shown"].sum() / target.sum()),
            "cycles_s": seconds,
        }
        if refined is not None:
            refined = cy.at_size_of(refined, target.shape)
            rows[tag]["refined"] = cy.rel_l2(_tiles(refined), _tiles(target))
            rows[tag]["refined_mean_ratio"] = float(refined.sum() / target.sum())
            rows[tag]["refine_passes"] = refine_report.get("passes")
        print(f"[trade] {name} sweep {tag}: shown {rows[tag]['shown']:.4f}, relit "
              f"{rows[tag]['relit']:.4f}, mean {rows[tag]['mean_ratio']:.4f}"
              + (f", refined {rows[tag]['refined']:.4f} (mean {rows[tag]['refined_mean_ratio']:.4f}, "
                 f"{rows[tag]['refine_passes']} passes)" if refined is not None else ""), file=sys.stderr)
    tolerance = rows["unedited"]["shown"] + 0.01
    for row in rows.values():
        row["within_tolerance"] = bool(row["shown"] <= tolerance)
        row["denoiser_no_worse"] = bool(row["shown"] <= row["relit"] + 0.002)
    return {"cycles_oidn_spp": spp, "tolerance": tolerance, "edits": rows}


def rebake(addon, prefs, variant: str, name: str, folder: pathlib.Path, result: dict, which: str) -> None:
    """Bakes each chosen edit of `result` (the sweep's; `which` is "misses" or tags) afresh
    with its values as the scene's own and adds its shown and relit errors against the
    sweep's Cycles + OIDN render of the same values to its row (`rebaked_shown`,
    `rebaked_relit`, `rebaked_mean_ratio`)."""
    edits = {"unedited": [], **SWEEPS[name]}
    rows = result["edits"]
    if which == "misses":
        tags = [tag for tag, row in rows.items() if not row["within_tolerance"]]
    else:
        tags = which.split(",")
        unknown = [tag for tag in tags if tag not in edits]
        if unknown:
            raise SystemExit(f"--rebake: no edit named {', '.join(unknown)} in {name}'s sweep")
    for tag in tags:
        undo = _set(edits[tag])
        try:
            _bake(addon, prefs, variant)
            images = _relume_images(addon, folder, f"rebake_{tag}")
        finally:
            _set(undo)
            addon.runtime.RUNTIME.live.unload()
        target = _read(folder / f"sweep_{tag}_cycles.exr")
        for kind in ("shown", "relit"):
            image = cy.at_size_of(images[kind], target.shape)
            rows[tag][f"rebaked_{kind}"] = cy.rel_l2(_tiles(image), _tiles(target))
            if kind == "shown":
                rows[tag]["rebaked_mean_ratio"] = float(image.sum() / target.sum())
        print(f"[trade] {name} re-baked {tag}: shown {rows[tag]['rebaked_shown']:.4f}, relit "
              f"{rows[tag]['rebaked_relit']:.4f} (relit from the one bake: shown "
              f"{rows[tag]['shown']:.4f})", file=sys.stderr)


def markdown(results: dict) -> str:
    lines = ["| scene | preset | bake | shown error (relit) | Cycles + OIDN to that error | "
             "bake ÷ Cycles + OIDN | edit raw / settled | edits to pay |", "|---|---|---|---|---|---|---|---|"]
    for s in results["scenes"]:
        for preset, r in s["relume"].items():
            c = r["cycles_oidn_to_same_error"]
            bound = {"at_most": "≤ ", "more_than": "> ", "interpolated": ""}[c["bound"]]
            edit = r.get("edit") or {}
            lines.append(
                f"| {s['scene']} | {preset} | {r['first_image_s']:.1f} s | "
                f"{100 * r['shown_error']['corrected']:.2f} % ({100 * r['relit_error']['corrected']:.2f} %) | "
                f"{bound}{c['seconds']:.2f} s ({bound}{c['spp']:.0f} spp) | "
                f"{r['first_image_over_cycles_oidn']:.1f}× | "
                + (f"{edit['raw_ms']['min']:.0f} ms / {edit['settled_ms']['median'] / 1e3:.2f} s | "
                   if edit else "— | ")
                + f"{r.get('edits_to_pay_for_bake', '—')} |")
    lines += ["", "| scene | Cycles + OIDN spp | time | tile error |", "|---|---|---|---|"]
    for s in results["scenes"]:
        for p in s["cycles_oidn"]:
            lines.append(f"| {s['scene']} | {p['spp']} | {p['seconds']:.2f} s | "
                         f"{100 * p['error']['corrected']:.2f} % |")
    for s in results["scenes"]:
        if "sweep" not in s:
            continue
        sw = s["sweep"]
        lines += ["", f"{s['scene']}: ten edits against Cycles + OIDN at {sw['cycles_oidn_spp']} spp "
                  f"(tolerance {100 * sw['tolerance']:.2f} %)", "",
                  "| edit | shown | relit | mean ratio | within |", "|---|---|---|---|---|"]
        for tag, r in sw["edits"].items():
            lines.append(f"| {tag} | {100 * r['shown']:.2f} % | {100 * r['relit']:.2f} % | "
                         f"{r['mean_ratio']:.3f} | {'yes' if r['within_tolerance'] else 'no'} |")
        rebaked = {tag: r for tag, r in sw["edits"].items() if "rebaked_shown" in r}
        if rebaked:
            lines += ["", "| edit | relit from the one bake: shown | baked afresh: shown (relit) | "
                      "mean ratio |", "|---|---|---|---|"]
            for tag, r in rebaked.items():
                lines.append(f"| {tag} | {100 * r['shown']:.2f} % | {100 * r['rebaked_shown']:.2f} % "
                             f"({100 * r['rebaked_relit']:.2f} %) | {r['rebaked_mean_ratio']:.3f} |")
    return "\n".join(lines) + "\n"


def chart(results: dict, path: pathlib.Path) -> bool:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("[trade] matplotlib is not installed: no chart (pip install matplotlib)", file=sys.stderr)
        return False
    fig, ax = plt.subplots(figsize=(6.4, 4.2), dpi=120)
    for i, s in enumerate(results["scenes"]):
        colour = f"C{i}"
        lad = s["cycles_oidn"]
        ax.plot([p["seconds"] for p in lad], [100 * p["error"]["corrected"] for p in lad], "-o",
                color=colour, ms=3, label=f"{s['scene']}: Cycles + OIDN")
        for preset, r in s["relume"].items():
            ax.plot(r["first_image_s"], 100 * r["shown_error"]["corrected"], "s", color=colour, ms=7)
            ax.annotate(preset, (r["first_image_s"], 100 * r["shown_error"]["corrected"]),
                        textcoords="offset points", xytext=(5, 4), fontsize=8)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("seconds to the first image (this machine)")
    ax.set_ylabel("tile error against Cycles (%)")
    ax.set_title("Relume's first image (squares) against Cycles + OIDN")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path)
    return True


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--scenes", default="bunny.blend,cornell_glossy.blend")
    ap.add_argument("--scene-dir", default=str(ROOT.parent / "shared" / "scenes"))
    ap.add_argument("--presets", default="draft,preview,final")
    ap.add_argument("--ladder", default="1,2,4,8,16,32,64")
    ap.add_argument("--reference-spp", type=int, default=512)
    ap.add_argument("--sweep-spp", type=int, default=128)
    ap.add_argument("--sweep-preset", default="preview")
    ap.add_argument("--no-sweep", action="store_true")
    ap.add_argument("--repeats", type=int, default=3,
                    help="bakes (and shown images) per preset, timed; the medians are used")
    ap.add_argument("--refine", type=float, default=0.0,
                    help="seconds of refinement for a third image of each edit (api.render(refine=…))")
    ap.add_argument("--rebake", default="",
                    help="'misses' or edit names: bake those sweep edits afresh and compare them too")
    ap.add_argument("--out", default=str(ROOT / "out" / "trade"))
    ap.add_argument("--reuse-cycles", type=pathlib.Path, default=None,
                    help="an earlier run's OUT: its reference and Cycles + OIDN ladder, not re-rendered")
    args = ap.parse_args()
    args.presets = args.presets.split(",")
    args.ladder = [int(v) for v in args.ladder.split(",")]
    scene_dir = pathlib.Path(args.scene_dir)
    if not scene_dir.is_dir():
        print(f"{scene_dir} is absent: pass --scene-dir with the .blend files", file=sys.stderr)
        return 2
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    addon, prefs = install_addon()
    prefs.bounces_from_scene = True
    work = out / "work"
    scenes = []
    for name in args.scenes.split(","):
        folder = work / name.replace(".blend", "")
        folder.mkdir(parents=True, exist_ok=True)
        scenes.append(bench_scene(addon, prefs, scene_dir, name, args, folder))
    results = {
        "benchmark": "trade_against_cycles_oidn", "bpy": bpy.app.version_string,
        "cpu_count": os.cpu_count(), "threads": 2, "date": time.strftime("%Y-%m-%d"),
        "scenes": scenes,
    }
    (out / "trade.json").write_text(json.dumps(results, indent=1))
    (out / "trade.md").write_text(markdown(results))
    chart(results, out / "trade.png")
    print(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
