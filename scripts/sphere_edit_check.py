"""An edited glossy sphere against the same sphere baked with the edit, with Relume's own bake
and relight (no Blender, no Cycles): how much of a highlight an edit of an editable material
keeps, with the scene reduced to what decides it.

    python3 scripts/sphere_edit_check.py [--light sun|area] [--floor] [--seeds 1] [--spp 64]

One smooth sphere (radius 1) seen by an orthographic camera, a black world, and one light at
the placements of `blender_tests/support/spheres.py` seen from a sphere of its row (37.6°
from the view, "front"; 92°, "side"): a sun of angular radius 0.2 / 0.25 rad
(`--light sun`, what `cargo run --release -p relume-engine --example sphere_highlights`
models), or that scene's 2 × 1 m area light at 3.24 m (`--light area`); `--floor` adds a
diffuse floor under the sphere. Per edit the sphere is baked editable at the preview preset
(`--spp` samples a pixel) with its bake-time material, relit with the edit, and its image sum
divided by that of a bake where the edited material is fixed (evaluated exactly). Needs the
wheel installed in build/py (`bash scripts/build_addon.sh`, then
`pip install --no-deps --target build/py dist/relume-*.whl`). One JSON line per edit and
placement.
"""

from __future__ import annotations

import argparse
import json
import math
import pathlib
import sys
import tempfile

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "build" / "py"))

import relume  # noqa: E402

COPPER = [0.9, 0.65, 0.35]
BLUE = [0.2, 0.35, 0.7]
#: (name, bake-time material, edit): the bench's sharpening edits of its roughness-0.3 spheres.
EDITS = (
    ("metal 0.3 -> 0.1", (COPPER, 1.0, 0.3), (COPPER, 1.0, 0.1)),
    ("metal 0.3 -> 0.15", (COPPER, 1.0, 0.3), (COPPER, 1.0, 0.15)),
    ("dielectric 0.3 -> 0.1", (BLUE, 0.0, 0.3), (BLUE, 0.0, 0.1)),
)
#: Placement: (angle between light and view in degrees, the sun's angular radius in rad).
PLACEMENTS = {"front": (37.6, 0.2), "side": (92.0, 0.25)}


def principled(base, metallic, roughness) -> dict:
    return {"model": "principled", "base_color": base, "metallic": metallic, "roughness": roughness,
            "ior": 1.5, "specular_ior_level": 0.5}


def uv_sphere(nu: int = 160, nv: int = 80):
    """Positions (= normals) and triangles of a unit UV sphere."""
    points = []
    for j in range(nv + 1):
        t = math.pi * j / nv
        for i in range(nu):
            p = 2.0 * math.pi * i / nu
            points.append([math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t)])
    triangles = []
    for j in range(nv):
        for i in range(nu):
            a, b = j * nu + i, j * nu + (i + 1) % nu
            c, d = (j + 1) * nu + i, (j + 1) * nu + (i + 1) % nu
            triangles += [[a, c, b], [b, c, d]]
    return points, triangles


SPHERE = uv_sphere()


def scene(material: dict, editable: bool, placement: str, light: str, floor: bool) -> dict:
    angle, radius = PLACEMENTS[placement]
    a = math.radians(angle)
    toward = [math.sin(a), -math.cos(a), 0.0]
    if light == "sun":
        lights = [{"type": "sun", "direction": [-x for x in toward], "strength": 3.0, "angle": 2.0 * radius}]
    else:
        lights = [{"type": "area", "position": [3.24 * x for x in toward], "axis_u": [math.cos(a), math.sin(a), 0.0],
                   "axis_v": [0.0, 0.0, 1.0], "shape": "rectangle", "size_x": 2.0, "size_y": 1.0, "power": 500.0}]
    points, triangles = SPHERE
    meshes = [{"name": "Sphere", "positions": points, "normals": points, "indices": triangles, "region": 0}]
    regions = [{"name": "Sphere", "editable": editable, "material": material}]
    if floor:
        meshes.append({"name": "Floor", "positions": [[-6, -6, -1], [6, -6, -1], [6, 6, -1], [-6, 6, -1]],
                       "indices": [[0, 1, 2], [0, 2, 3]], "region": 1})
        regions.append({"name": "Floor", "editable": False,
                        "material": {"model": "blinn_phong", "kd": [0.8, 0.8, 0.8], "ks": [0, 0, 0], "ns": 1}})
    return {
        "format": "relume-scene", "version": 1, "meshes": meshes, "regions": regions, "lights": lights,
        "world": {"type": "color", "color": [0, 0, 0], "strength": 1},
        # Blender's camera looks along its local −Z: here along +y, up +z, from y = −10.
        "camera": {"projection": "orthographic",
                   "matrix_world": [[1, 0, 0, 0], [0, 0, -1, -10], [0, 1, 0, 0], [0, 0, 0, 1]],
                   "lens_mm": 50, "sensor_width_mm": 36, "sensor_height_mm": 36, "sensor_fit": "auto",
                   "shift_x": 0, "shift_y": 0, "ortho_scale": 2.2, "clip_start": 0.1, "clip_end": 100},
        "resolution": {"width": 128, "height": 128},
    }


def image_sum(scene_dict: dict, folder: str, seed: int, spp: int, edit=None) -> float:
    path = str(pathlib.Path(folder) / "sphere.relume.exr")
    settings = relume.BakeSettings.preset("preview", seed=seed, bounces=1, spp=spp)
    relume.bake(relume.Scene.from_json(json.dumps(scene_dict), base_dir=folder), settings, path)
    relighter = relume.Relighter(relume.Stack.load(path), device="cpu")
    if edit is not None:
        base, metallic, roughness = edit
        relighter.set_principled("Sphere", base, metallic=metallic, roughness=roughness)
    return float(np.asarray(relighter.relight(), dtype=np.float64)[..., :3].sum())


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--light", choices=("sun", "area"), default="sun")
    parser.add_argument("--floor", action="store_true")
    parser.add_argument("--seeds", type=int, default=1)
    parser.add_argument("--spp", type=int, default=64)
    args = parser.parse_args()
    folder = tempfile.mkdtemp(prefix="relume-sphere-edit-")
    for placement in PLACEMENTS:
        for name, bake, edit in EDITS:
            ratios = []
            for seed in range(args.seeds):
                edited = image_sum(scene(principled(*bake), True, placement, args.light, args.floor),
                                   folder, seed, args.spp, edit)
                exact = image_sum(scene(principled(*edit), False, placement, args.light, args.floor),
                                  folder, seed, args.spp)
                ratios.append(edited / exact)
            print(json.dumps({"light": args.light, "floor": args.floor, "placement": placement, "edit": name,
                              "spp": args.spp, "relit_over_fixed_per_seed": [round(r, 4) for r in ratios]}),
                  flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
