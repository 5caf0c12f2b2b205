#!/usr/bin/env python3
"""Bakes one scene file at every combination of presets, precisions and seeds with the
`relume` command line, relights each stack at its bake-time materials, and prints what
happened as JSON: bakes completed or lost (with the error), the per-stage counts of values
the bake kept finite (`report.non_finite`), the relight's exit status and warnings.

It is how a scene that lost bakes is checked across seeds (a lost bake depends on the
seed: one sample's value decides it). Example, with a scene exported from Blender
(`bpy.ops.relume.export_scene`):

    python3 scripts/seed_sweep.py S.scene.json --presets draft,preview,final \
        --precisions f16,f32 --seeds 0-31 --out sweep.json
"""

from __future__ import annotations

import argparse
import json
import pathlib
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parent.parent


def seeds(text: str) -> list[int]:
    out: list[int] = []
    for part in text.split(","):
        lo, _, hi = part.partition("-")
        out.extend(range(int(lo), int(hi or lo) + 1))
    return out


def run(cmd: list[str]) -> tuple[int, dict | None, str]:
    p = subprocess.run(cmd, capture_output=True, text=True)
    try:
        data = json.loads(p.stdout) if p.stdout.strip() else None
    except json.JSONDecodeError:
        data = None
    return p.returncode, data, p.stderr.strip().splitlines()[-1] if p.stderr.strip() else ""


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scene")
    ap.add_argument("--relume", default=str(ROOT / "target" / "release" / "relume"))
    ap.add_argument("--presets", default="preview")
    ap.add_argument("--precisions", default="f16")
    ap.add_argument("--seeds", default="0-3", help="e.g. 0-31 or 0,2,5")
    ap.add_argument("--extra", default="", help="further bake flags, space-separated")
    ap.add_argument("--out", help="also write the JSON here")
    a = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        stack = str(pathlib.Path(tmp) / "s.exr")
        image = str(pathlib.Path(tmp) / "r.exr")
        for preset in a.presets.split(","):
            for precision in a.precisions.split(","):
                for seed in seeds(a.seeds):
                    t = time.monotonic()
                    rc, data, err = run([a.relume, "bake", a.scene, "-o", stack, "--preset", preset,
                                         "--precision", precision, "--seed", str(seed), "--json",
                                         *a.extra.split()])
                    row = {"preset": preset, "precision": precision, "seed": seed,
                           "bake_rc": rc, "seconds": round(time.monotonic() - t, 1)}
                    if rc != 0 or data is None:
                        row["error"] = err
                    else:
                        report = data["report"]
                        row["non_finite"] = report.get("non_finite")
                        row["warnings"] = report.get("warnings", [])
                        rrc, rdata, rerr = run([a.relume, "relight", stack, "-o", image,
                                                "--device", "cpu", "--json"])
                        row["relight_rc"] = rrc
                        row["relight_warnings"] = (rdata or {}).get("warnings", [rerr])
                    rows.append(row)
                    print(json.dumps(row), file=sys.stderr, flush=True)
    summary = {
        "scene": a.scene,
        "bakes": len(rows),
        "lost": sum(r["bake_rc"] != 0 for r in rows),
        "relights_failed": sum(r.get("relight_rc", 0) != 0 for r in rows),
        "relights_warned": sum(bool(r.get("relight_warnings")) for r in rows),
        "non_finite_totals": {k: sum((r.get("non_finite") or {}).get(k, 0) for r in rows)
                              for k in ("path_contributions", "layer_values", "lattice_fits",
                                        "stored_values")},
        "rows": rows,
    }
    text = json.dumps(summary, indent=1)
    if a.out:
        pathlib.Path(a.out).write_text(text)
    print(text)
    return 0 if summary["lost"] == 0 and summary["relights_failed"] == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
