"""How fast the background refinement removes what a relight misses past the second vertex;
prints JSON lines.

A scene (default: the assets' Cornell box, two editable Blinn–Phong regions) is baked once at a
preset (default preview: 512², the pre-pass picks the bounces). Each edit below is relit with
`relume relight --denoise none --refine T` for T = 0 (the relight alone) and each of
`--seconds`, and compared with `relume reference --brdf projected` of the edited scene at the
same settings and `--reference-spp` samples per pixel (the first two vertices reconstructed
through the basis as the relight has them, every later one with the edited material):
`relume compare`'s relative L2 over 8×8-pixel tile means (which leaves out most of both
images' pixel noise) and per pixel, and the mean ratio. The unedited image is measured the
same way: its error is the bake's own noise and compression against that reference, the
floor a refinement can reach.

    python3 scripts/bench_tail_refine.py --relume target/release/relume --out refine.jsonl
"""

from __future__ import annotations

import argparse
import json
import pathlib
import platform
import subprocess
import sys
import tempfile

ROOT = pathlib.Path(__file__).resolve().parents[1]


def bp(kd: float, ks: float, ns: float) -> dict:
    return {"model": "blinn_phong", "kd": [kd] * 3, "ks": [ks] * 3, "ns": ns}


# The lobe-shape and two-region rows of docs/bounces.md's grid, and one albedo edit.
EDITS = {
    "unedited": {"White walls": bp(0.3, 0.3, 5), "Object": bp(0.2, 0.4, 5)},
    "walls Kd 0.9": {"White walls": bp(0.9, 0.0, 1), "Object": bp(0.2, 0.4, 5)},
    "glossy ns 180": {"White walls": bp(0.3, 0.3, 180), "Object": bp(0.2, 0.4, 180)},
    "walls Ks 1 ns 200 / sphere Kd 1": {"White walls": bp(0.0, 1.0, 200), "Object": bp(1.0, 0.0, 200)},
    "black walls / sphere Kd .5 Ks .5 ns 60": {"White walls": bp(0.0, 0.0, 1), "Object": bp(0.5, 0.5, 60)},
}


def run(cmd: list[str]) -> str:
    out = subprocess.run(cmd, capture_output=True, text=True)
    if out.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed:\n{out.stderr}")
    return out.stdout


def last_json(text: str) -> dict:
    return json.loads(text.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--relume", default=str(ROOT / "target/release/relume"))
    ap.add_argument("--scene", default=str(ROOT / "assets/cornell.scene.json"))
    ap.add_argument("--preset", default="preview")
    ap.add_argument("--seconds", default="1,5,30")
    ap.add_argument("--reference-spp", type=int, default=64)
    ap.add_argument("--work", help="folder for the stack and images (default: a temporary one)")
    ap.add_argument("--out", help="also append the JSON lines to this file")
    ap.add_argument("--reuse", action="store_true",
                    help="keep the stack, references and relit images already in --work")
    a = ap.parse_args()
    work = pathlib.Path(a.work or tempfile.mkdtemp(prefix="relume-refine-"))
    work.mkdir(parents=True, exist_ok=True)
    stack = work / "stack.exr"
    lines = []

    def emit(row: dict) -> None:
        row = {"machine": f"{platform.node()} {platform.machine()}", **row}
        print(json.dumps(row), flush=True)
        lines.append(row)

    if not stack.exists():
        bake = last_json(run([a.relume, "bake", a.scene, "--preset", a.preset, "-o", str(stack), "--json"]))
        emit({"step": "bake", "seconds": bake["report"]["seconds"], "bounces": bake["report"]["bounces"]})
    for name, regions in EDITS.items():
        slug = "".join(c if c.isalnum() else "_" for c in name)
        mats = work / f"{slug}.json"
        mats.write_text(json.dumps({"format": "relume-materials", "version": 1, "regions": regions}))
        ref = work / f"{slug}.ref.exr"
        if not ref.exists():
            run([a.relume, "reference", a.scene, "--materials", str(mats), "--brdf", "projected",
                 "--preset", a.preset, "--spp", str(a.reference_spp), "-o", str(ref)])
        for t in [0.0] + [float(s) for s in a.seconds.split(",")]:
            img = work / f"{slug}.{t:g}.exr"
            report = work / f"{slug}.{t:g}.json"
            if not (a.reuse and img.exists() and report.exists()):
                report.write_text(run([a.relume, "relight", str(stack), "--materials", str(mats), "--scene",
                                       a.scene, "--denoise", "none", "--refine", str(t), "-o", str(img),
                                       "--json"]))
            rep = last_json(report.read_text())
            pixels = last_json(run([a.relume, "compare", str(img), str(ref), "--json"]))
            tiles = last_json(run([a.relume, "compare", str(img), str(ref), "--tiles", "8", "--json"]))
            refine = rep.get("refine") or {}
            emit({"edit": name, "refine_seconds_asked": t, "passes": refine.get("passes", 0),
                  "refine_seconds": refine.get("seconds", 0.0), "bake_samples": refine.get("bake_samples"),
                  "tiles_vs_reference": tiles["rel_l2"], "pixels_vs_reference": pixels["rel_l2"],
                  "mean_ratio": pixels.get("mean_ratio")})
    if a.out:
        with open(a.out, "a") as f:
            for row in lines:
                f.write(json.dumps(row) + "\n")


if __name__ == "__main__":
    main()
