"""Builds the seed corpus of the cargo fuzz targets (fuzz/) into fuzz/corpus/<target>/.

Seeds: every assets scene file and broken variants of one (scene_parser); the materials
file examples of the docs and broken ones (materials_parser); tiny stacks baked by the
`relume` binary given, their truncations and hostile variants whose headers claim far more
pixels than the file holds (stack_reader, via scripts/hostile_stack.py).

    python3 scripts/fuzz_corpus.py --relume target/release/relume
"""

from __future__ import annotations

import argparse
import json
import pathlib
import subprocess
import sys
import tempfile

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "scripts"))
import hostile_stack  # noqa: E402

MATERIALS = [
    {"format": "relume-materials", "version": 1, "regions": {
        "Object": {"model": "blinn_phong", "kd": [0.2, 0.2, 0.2], "ks": [0.4, 0.4, 0.4], "ns": 50},
        "Walls": {"model": "principled", "base_color": [0.8, 0.8, 0.8], "roughness": 0.4}}},
    {"format": "relume-materials", "version": 1, "regions": {
        "Wax": {"model": "principled", "base_color": [0.9, 0.75, 0.55], "subsurface_weight": 1,
                "subsurface_radius": [1, 0.5, 0.25], "subsurface_scale": 0.1}},
     "light_groups": {"Key": {"strength": 2.5, "color": [1, 0.9, 0.8]}}},
    {"format": "relume-materials", "version": 1, "regions": {
        "Object": {"model": "blinn_phong", "kd": [0.75, 0.75, 0.75], "ks": [0.5, 0.5, 0.5], "ns": 0}}},
    {"format": "relume-materials", "version": 2, "regions": {}},
    {"format": "relume-materials", "version": 1, "regions": {
        "Object": {"model": "principled", "base_color": [1e38, -1, 0.5], "roughnes": 2}}},
]


def write(folder: pathlib.Path, name: str, data: bytes) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / name).write_bytes(data)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--relume", required=True, help="the relume binary (to bake seed stacks)")
    ap.add_argument("--out", default=str(ROOT / "fuzz" / "corpus"))
    args = ap.parse_args()
    out = pathlib.Path(args.out)

    scenes = out / "scene_parser"
    for path in sorted((ROOT / "assets").glob("*.scene.json")):
        text = path.read_text()
        write(scenes, path.name, text.encode())
        data = json.loads(text)
        data["version"] = 99
        write(scenes, "version-" + path.name, json.dumps(data).encode())
        data["version"] = 1
        data["resolution"] = {"width": 100000, "height": 0}
        write(scenes, "resolution-" + path.name, json.dumps(data).encode())
        write(scenes, "cut-" + path.name, text[: len(text) // 3].encode())

    materials = out / "materials_parser"
    for i, m in enumerate(MATERIALS):
        write(materials, f"materials-{i}.json", json.dumps(m).encode())

    stacks = out / "stack_reader"
    with tempfile.TemporaryDirectory() as tmp:
        for scene in ("cornell", "translucent", "hdri"):
            stack = pathlib.Path(tmp) / f"{scene}.exr"
            cmd = [args.relume, "bake", str(ROOT / "assets" / f"{scene}.scene.json"), "-o", str(stack),
                   "--resolution", "8x8", "--spp", "1", "--light-samples", "1",
                   "--subsurface-samples", "256", "--json"]
            if scene == "cornell":
                cmd += ["--light-groups", "per-light"]
            subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
            data = stack.read_bytes()
            write(stacks, f"{scene}.exr", data)
            write(stacks, f"{scene}-cut.exr", data[: len(data) // 2])
            for w, h in ((16384, 16384), (65536, 16), (9, 8)):
                write(stacks, f"{scene}-claims-{w}x{h}.exr", hostile_stack.with_claimed_size(data, w, h))
    print(f"seed corpus in {out}: " + ", ".join(
        f"{d.name} {len(list(d.iterdir()))}" for d in sorted(out.iterdir()) if d.is_dir()))


if __name__ == "__main__":
    main()
