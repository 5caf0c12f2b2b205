"""Editable Principled spheres against Cycles: each material's brightness at its bake-time
values and after edits, relit from one bake.

    python3 blender_tests/bench_editable_spheres.py [--out out/editable_spheres]
        [--preset preview] [--seeds 0,1,2,3] [--cycles-spp 8192] [--edit-spp 2048]
        [--lights front,side] [--families metal,dielectric] [--reuse-cycles OUT]
        [--fixed-edits roughness_0.1,roughness_0.15]

What a user ticking a glossy material Editable gets by default. Per light placement
(`support.spheres.LIGHTS`) and family — six metals or six dielectrics at roughness 0.1,
0.15, 0.2, 0.3, 0.5, 0.8, every sphere editable — the scene is exported through the add-on
and baked at `--preset` (the add-on's default preset is preview; its settings as they are,
the editable materials in the basis of Principled lobes) with one bounce, once per bake seed;
Cycles renders it with the same one-bounce transport at `--cycles-spp` (two renders of half
as many; their difference gives its noise).

1. **Bake time**: per sphere the mean brightness (RGB summed over the sphere's pure pixels,
   from a material-ID render: `support.cycles.material_ids`) relit at the bake-time values,
   over Cycles', per seed and the mean over the seeds.
2. **Edits**: the roughness-0.3 sphere of the family, from its baked values, to roughness
   0.1, 0.15, 0.5, 0.9, metallic flipped (0 ↔ 1) and another base colour; each relit from
   every seed's stack (`Relighter.set_principled`) and compared with Cycles rendered with the
   same values at `--edit-spp`. The other spheres are unchanged by an edit and are reported
   as the control.

`--fixed-edits` also bakes the scene with each named edit applied and the edited sphere not
editable (evaluated exactly, as a fixed region), per seed: Relume's own image of the edited
material, which splits a relit edit's difference from Cycles into the relight's part and
the bake's.

Prints one line per figure and writes OUT/editable_spheres.json and OUT/editable_spheres.md.
Nothing is asserted: test_principled_fit.py asserts the bake-time goal on its six spheres
at the final preset; this is the wider sweep docs/principled_fit.md reports.
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import sys
import tempfile
import time

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="relume-spheres-user-"))

import bpy  # noqa: E402
import numpy as np  # noqa: E402
from conftest import ROOT, install_addon  # noqa: E402
from support import cycles as cy  # noqa: E402
from support.scenes import clear_scene  # noqa: E402
from support.spheres import build_scene, per_material  # noqa: E402

RES = 96
ROUGHNESS = (0.1, 0.15, 0.2, 0.3, 0.5, 0.8)
FAMILIES = {
    "metal": [(f"Metal r{r}", (0.9, 0.65, 0.35), 1.0, r) for r in ROUGHNESS],
    "dielectric": [(f"Dielectric r{r}", (0.2, 0.35, 0.7), 0.0, r) for r in ROUGHNESS],
}
#: The sphere each family's edits change, and the edits: name → Principled inputs changed.
EDITED = {"metal": "Metal r0.3", "dielectric": "Dielectric r0.3"}
EDITS = {
    "metal": {
        "roughness_0.1": {"Roughness": 0.1}, "roughness_0.15": {"Roughness": 0.15},
        "roughness_0.5": {"Roughness": 0.5}, "roughness_0.9": {"Roughness": 0.9},
        "metallic_0": {"Metallic": 0.0}, "base_colour_blue": {"Base Color": (0.2, 0.35, 0.7, 1.0)},
    },
    "dielectric": {
        "roughness_0.1": {"Roughness": 0.1}, "roughness_0.15": {"Roughness": 0.15},
        "roughness_0.5": {"Roughness": 0.5}, "roughness_0.9": {"Roughness": 0.9},
        "metallic_1": {"Metallic": 1.0}, "base_colour_orange": {"Base Color": (0.9, 0.65, 0.35, 1.0)},
    },
}
INPUTS = ("Base Color", "Metallic", "Roughness", "IOR", "Specular IOR Level")


def _inputs(material: str) -> dict:
    return bpy.data.materials[material].node_tree.nodes["Principled BSDF"].inputs


def _values(material: str) -> dict:
    inputs = _inputs(material)
    return {k: (tuple(inputs[k].default_value) if k == "Base Color" else float(inputs[k].default_value))
            for k in INPUTS}


def _set(material: str, values: dict) -> None:
    inputs = _inputs(material)
    for k, v in values.items():
        inputs[k].default_value = v


def _set_relit(relighter, material: str, values: dict) -> None:
    relighter.set_principled(material, list(values["Base Color"][:3]), metallic=values["Metallic"],
                             roughness=values["Roughness"], ior=values["IOR"],
                             specular_ior_level=values["Specular IOR Level"])


def _ratios(images, ids, names, reference) -> dict[str, list[float]]:
    ref = per_material(reference, ids, names)
    per_seed = [per_material(image, ids, names) for image in images]
    return {n: [m[n] / ref[n] for m in per_seed] for n in ref}


def _noise(c1, c2, ids, names) -> dict[str, float]:
    m1, m2 = per_material(c1, ids, names), per_material(c2, ids, names)
    return {n: abs(m1[n] - m2[n]) / (m1[n] + m2[n]) for n in m1}


def _cycles_pair(scene, folder: pathlib.Path, name: str, samples: int, reuse: pathlib.Path | None):
    """Cycles' two half renders of `name`, or an earlier run's (`--reuse-cycles`)."""
    import relume

    if reuse is not None:
        earlier = reuse / "work" / folder.name
        return tuple(np.asarray(relume.read_exr(str(earlier / f"{name}_c{i}.exr")), dtype=np.float64)[..., :3]
                     for i in (1, 2))
    c1, c2, _ = cy.render_cycles_pair(scene, folder, name, samples, bounces=1)
    return c1, c2


def _relit(relighter) -> np.ndarray:
    """The relit image at the render's size (`support.cycles.at_size_of`)."""
    return cy.at_size_of(np.asarray(relighter.relight(), dtype=np.float64)[..., :3], (RES, RES))


def bench(addon, light: str, family: str, args, folder: pathlib.Path) -> dict:
    import relume

    clear_scene()
    spheres = FAMILIES[family]
    scene = build_scene(light, spheres, RES, editable_spheres=True)
    ids, names = cy.material_ids(scene, folder / "ids.exr")
    t0 = time.perf_counter()
    c1, c2 = _cycles_pair(scene, folder, "baked", args.cycles_spp, args.reuse_cycles)
    cycles_s = time.perf_counter() - t0
    exported = addon.api.export()
    relighters, bake_s = [], []
    for seed in args.seeds:
        settings = relume.BakeSettings.preset(args.preset, seed=seed, bounces=1)
        stack_path = folder / f"seed{seed}.relume.exr"
        t0 = time.perf_counter()
        report = relume.bake(exported.scene, settings, str(stack_path))
        bake_s.append(time.perf_counter() - t0)
        relighters.append(relume.Relighter(relume.Stack.load(str(stack_path)), device="cpu"))
    editable = set(relighters[0].materials)
    assert all(name in editable for name, *_ in spheres), (sorted(editable), spheres)
    baked = _ratios([_relit(r) for r in relighters], ids, names, 0.5 * (c1 + c2))
    noise = _noise(c1, c2, ids, names)
    out = {"light": light, "family": family, "cycles_spp": args.cycles_spp, "cycles_s": round(cycles_s, 1),
           "bake_s": [round(s, 1) for s in bake_s], "layers": report.get("layers"), "spheres": {}, "edits": {}}
    for name, colour, metallic, roughness in spheres:
        r = baked[name]
        out["spheres"][name] = {"base_color": list(colour), "metallic": metallic, "roughness": roughness,
                                "pixels": int((ids == names.index(name)).sum()), "ratio": float(np.mean(r)),
                                "ratio_per_seed": r, "cycles_noise": noise[name]}
        print(f"[spheres] {light} {name:16s} {np.mean(r):.3f} [{min(r):.3f}–{max(r):.3f}]"
              f"  Cycles noise {noise[name]:.4f}", flush=True)
    target = EDITED[family]
    base = _values(target)
    for edit, change in EDITS[family].items():
        values = {**base, **change}
        _set(target, values)
        c1, c2 = _cycles_pair(scene, folder, edit, args.edit_spp, args.reuse_cycles)
        images = []
        for relighter in relighters:
            _set_relit(relighter, target, values)
            images.append(_relit(relighter))
            _set_relit(relighter, target, base)
        fixed = _fixed_bakes(addon, folder, target, edit, args) if edit in args.fixed_edits else None
        _set(target, base)
        ratios = _ratios(images, ids, names, 0.5 * (c1 + c2))
        noise = _noise(c1, c2, ids, names)
        others = [abs(np.mean(ratios[n]) - 1.0) for n, *_ in spheres if n != target]
        r = ratios[target]
        out["edits"][edit] = {"change": {k: list(v) if isinstance(v, tuple) else v for k, v in change.items()},
                              "ratio": float(np.mean(r)), "ratio_per_seed": r, "cycles_noise": noise[target],
                              "others_max_abs_error": float(max(others))}
        print(f"[spheres] {light} {target} → {edit:18s} {np.mean(r):.3f} [{min(r):.3f}–{max(r):.3f}]"
              f"  Cycles noise {noise[target]:.4f}; other spheres within {max(others):.3f}", flush=True)
        if fixed is not None:
            f = _ratios(fixed, ids, names, 0.5 * (c1 + c2))[target]
            out["edits"][edit]["fixed_ratio"] = float(np.mean(f))
            out["edits"][edit]["fixed_ratio_per_seed"] = f
            print(f"[spheres] {light} {target} → {edit:18s} baked as a fixed material: {np.mean(f):.3f} "
                  f"[{min(f):.3f}–{max(f):.3f}]", flush=True)
    return out


def _fixed_bakes(addon, folder: pathlib.Path, target: str, edit: str, args) -> list[np.ndarray]:
    """The scene as it stands (the edit applied in Blender) baked with `target` not editable,
    once per bake seed, relit at its baked materials: what Relume gives the edited material
    when it is evaluated exactly, to split a relit edit's difference from Cycles into the
    relight's and the bake's."""
    import relume

    material = bpy.data.materials[target]
    material.relume.editable = False
    try:
        exported = addon.api.export()
        images = []
        for seed in args.seeds:
            settings = relume.BakeSettings.preset(args.preset, seed=seed, bounces=1)
            stack_path = folder / f"fixed_{edit}_seed{seed}.relume.exr"
            relume.bake(exported.scene, settings, str(stack_path))
            images.append(_relit(relume.Relighter(relume.Stack.load(str(stack_path)), device="cpu")))
        return images
    finally:
        material.relume.editable = True


def markdown(results: dict) -> str:
    lines = [f"Preset {results['preset']}, one bounce, {RES}², bake seeds {results['seeds']}; Cycles "
             f"{results['cycles_spp']} spp (edits {results['edit_spp']} spp); bpy {results['bpy']}, "
             f"{results['date']}.", "", "Relume / Cycles, mean brightness per sphere, mean over the seeds [range]:", "",
             "| sphere | " + " | ".join(results["lights"]) + " |", "|---|" + "---|" * len(results["lights"])]
    for family in FAMILIES:
        runs = [r for r in results["runs"] if r["family"] == family]
        if not runs:
            continue
        for name, *_ in FAMILIES[family]:
            cells = [f"{r['spheres'][name]['ratio']:.3f} [{min(r['spheres'][name]['ratio_per_seed']):.3f}–"
                     f"{max(r['spheres'][name]['ratio_per_seed']):.3f}]" for r in runs]
            lines.append(f"| {name} | " + " | ".join(cells) + " |")
    lines += ["", "Edits of the roughness-0.3 sphere, relit from the same bakes, against Cycles with the same values:",
              ""]
    for r in results["runs"]:
        for edit, e in r["edits"].items():
            lines.append(f"- {r['light']}, {EDITED[r['family']]} → {edit}: {e['ratio']:.3f} "
                         f"[{min(e['ratio_per_seed']):.3f}–{max(e['ratio_per_seed']):.3f}], other spheres within "
                         f"{e['others_max_abs_error']:.3f}")
    return "\n".join(lines) + "\n"


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default=str(ROOT / "out" / "editable_spheres"))
    ap.add_argument("--preset", default="preview")
    ap.add_argument("--seeds", default="0,1,2,3")
    ap.add_argument("--cycles-spp", type=int, default=8192)
    ap.add_argument("--edit-spp", type=int, default=2048)
    ap.add_argument("--lights", default="front,side")
    ap.add_argument("--families", default="metal,dielectric")
    ap.add_argument("--reuse-cycles", type=pathlib.Path, default=None,
                    help="an earlier run's OUT: its Cycles renders, not rendered again")
    ap.add_argument("--fixed-edits", default="",
                    help="edits (e.g. roughness_0.1,roughness_0.15) also baked with the edited material "
                         "fixed, per seed")
    args = ap.parse_args()
    args.seeds = [int(s) for s in args.seeds.split(",")]
    args.fixed_edits = [e for e in args.fixed_edits.split(",") if e]
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    addon, _ = install_addon()
    runs = []
    for light in args.lights.split(","):
        for family in args.families.split(","):
            folder = out / "work" / f"{light}_{family}"
            folder.mkdir(parents=True, exist_ok=True)
            runs.append(bench(addon, light, family, args, folder))
    results = {"benchmark": "editable_spheres_against_cycles", "bpy": bpy.app.version_string,
               "date": time.strftime("%Y-%m-%d"), "preset": args.preset, "seeds": args.seeds,
               "cycles_spp": args.cycles_spp, "edit_spp": args.edit_spp, "resolution": RES,
               "lights": args.lights.split(","), "runs": runs}
    (out / "editable_spheres.json").write_text(json.dumps(results, indent=1))
    (out / "editable_spheres.md").write_text(markdown(results))
    print(markdown(results))
    return 0


if __name__ == "__main__":
    sys.exit(main())
