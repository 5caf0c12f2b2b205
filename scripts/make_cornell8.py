"""Writes a Cornell scene with eight materials, `k` of them editable, for the memory and
scale benchmarks (the issue's resolution × editable-materials grid).

It is the assets' Cornell box (assets/cornell.scene.json) with every surface its own
material: floor, ceiling and back wall apart, the red and green walls, the tall box, and the
sphere split into an upper and a lower half (per-triangle regions). The first `k` are
editable, each a different Blinn–Phong material (`--principled`: a different Principled BSDF,
dielectrics and metals from roughness 0.15 to 1, as a scene exported from Blender has); the
resolution is set by `--resolution`.

    python3 scripts/make_cornell8.py --editable 8 --resolution 1024x1024 --out out/cornell8.scene.json
"""

from __future__ import annotations

import argparse
import json
import pathlib

ROOT = pathlib.Path(__file__).resolve().parents[1]

MATERIALS = [  # name, kd, ks, ns
    ("Floor", [0.45, 0.42, 0.38], [0.2, 0.2, 0.2], 40),
    ("Ceiling", [0.7, 0.7, 0.7], [0.0, 0.0, 0.0], 1),
    ("Back wall", [0.5, 0.5, 0.55], [0.1, 0.1, 0.1], 10),
    ("Red wall", [0.6, 0.05, 0.05], [0.05, 0.05, 0.05], 5),
    ("Green wall", [0.05, 0.5, 0.05], [0.05, 0.05, 0.05], 5),
    ("Tall box", [0.4, 0.35, 0.3], [0.3, 0.3, 0.3], 80),
    ("Sphere top", [0.1, 0.2, 0.5], [0.5, 0.5, 0.5], 150),
    ("Sphere bottom", [0.5, 0.3, 0.1], [0.3, 0.3, 0.3], 20),
]

PRINCIPLED = [  # base colour, metallic, roughness: the same surfaces as Principled BSDFs
    ([0.45, 0.42, 0.38], 0.0, 0.4),
    ([0.7, 0.7, 0.7], 0.0, 1.0),
    ([0.5, 0.5, 0.55], 0.0, 0.6),
    ([0.6, 0.05, 0.05], 0.0, 0.8),
    ([0.05, 0.5, 0.05], 0.0, 0.8),
    ([0.9, 0.75, 0.5], 1.0, 0.3),
    ([0.1, 0.2, 0.5], 0.0, 0.15),
    ([0.95, 0.6, 0.3], 1.0, 0.2),
]


def build(editable: int, width: int, height: int, principled: bool = False) -> dict:
    src = json.loads((ROOT / "assets" / "cornell.scene.json").read_text())
    by_name = {m["name"]: m for m in src["meshes"]}
    walls = by_name["White walls"]
    meshes = []
    # The white walls mesh holds floor, ceiling and back as three quads (two triangles each).
    for i, name in enumerate(("Floor", "Ceiling", "Back wall")):
        tris = walls["indices"][2 * i:2 * i + 2]
        used = sorted({v for t in tris for v in t})
        remap = {v: j for j, v in enumerate(used)}
        meshes.append({"name": name, "positions": [walls["positions"][v] for v in used],
                       "indices": [[remap[v] for v in t] for t in tris], "region": i})
    for region, name in ((3, "Red wall"), (4, "Green wall"), (5, "Tall box")):
        m = dict(by_name[name])
        m["name"], m["region"] = name, region
        meshes.append(m)
    sphere = dict(by_name["Object"])
    centre_z = sum(p[2] for p in sphere["positions"]) / len(sphere["positions"])
    sphere["name"], sphere["region"] = "Sphere", 6
    sphere["triangle_regions"] = [
        6 if sum(sphere["positions"][v][2] for v in t) / 3 >= centre_z else 7 for t in sphere["indices"]]
    meshes.append(sphere)
    regions = [{"name": n, "editable": i < editable,
                "material": {"model": "blinn_phong", "kd": kd, "ks": ks, "ns": ns}}
               for i, (n, kd, ks, ns) in enumerate(MATERIALS)]
    if principled:
        for region, (base, metallic, roughness) in zip(regions, PRINCIPLED, strict=True):
            region["material"] = {"model": "principled", "base_color": base, "metallic": metallic,
                                  "roughness": roughness}
    return {**src, "meshes": meshes, "regions": regions, "resolution": {"width": width, "height": height}}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--editable", type=int, default=8, help="how many of the 8 materials are editable")
    ap.add_argument("--resolution", default="512x512", help="WIDTHxHEIGHT")
    ap.add_argument("--principled", action="store_true", help="Principled BSDFs instead of Blinn–Phong values")
    ap.add_argument("--out", required=True)
    args = ap.parse_args()
    if not 0 <= args.editable <= 8:
        ap.error("--editable must be 0…8")
    w, h = (int(v) for v in args.resolution.lower().split("x"))
    out = pathlib.Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(build(args.editable, w, h, args.principled)))
    print(out)


if __name__ == "__main__":
    main()
