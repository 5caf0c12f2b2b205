"""How close the bake's memory forecast is: for each case, `relume bake --json` (one process
per bake) reports its estimate (made before tracing) beside the measured peak resident memory
over the bake (peak RSS minus RSS before the bake) and the stack's size in memory. Prints one
JSON object per case and a summary; memory figures do not depend on the machine's load.

    python3 scripts/estimate_accuracy.py --relume target/release/relume [--quick]
"""

from __future__ import annotations

import argparse
import json
import pathlib
import subprocess
import sys
import tempfile

ROOT = pathlib.Path(__file__).resolve().parents[1]


def cases(tmp: pathlib.Path, quick: bool):
    for name in ("cornell", "ring", "textured", "hdri", "translucent"):
        yield name + " preview", ROOT / "assets" / f"{name}.scene.json", ["--preset", "preview", "--bounces", "1"] + (
            ["--resolution", "128x128"] if quick else [])
    for k in (2, 8):
        res = "256x256" if quick else "1024x1024"
        scene = tmp / f"cornell8-k{k}.scene.json"
        subprocess.run([sys.executable, str(ROOT / "scripts" / "make_cornell8.py"), "--editable", str(k),
                        "--resolution", res, "--out", str(scene)], check=True, stdout=subprocess.DEVNULL)
        yield f"cornell8 k={k} {res} draft-samples", scene, [
            "--spp", "4", "--light-samples", "2", "--indirect-samples", "2", "--sampling", "mixture",
            "--tolerance", "0.05", "--denoise-bounce", "2", "--bounces", "1"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--relume", default=str(ROOT / "target" / "release" / "relume"))
    ap.add_argument("--quick", action="store_true", help="small resolutions (a smoke run)")
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        for label, scene, flags in cases(tmp, args.quick):
            out = subprocess.run([args.relume, "bake", str(scene), "-o", str(tmp / "s.exr"), "--json", *flags],
                                 check=True, capture_output=True, text=True)
            j = json.loads(out.stdout)
            est = j["report"]["estimate"]
            measured_peak = j["peak_rss_bytes"] - j["rss_before_bake_bytes"]
            row = {
                "case": label,
                "layers_reached_probe": est["layers_reached"],
                "layers_stored": j["layers"],
                "peak_estimate_mb": round(est["peak_bytes"] / 2**20, 1),
                "peak_measured_mb": round(measured_peak / 2**20, 1),
                "peak_ratio": round(est["peak_bytes"] / measured_peak, 3),
                "stack_estimate_mb": round(est["stack_bytes"] / 2**20, 1),
                "stack_measured_mb": round(j["report"]["sample_bytes"] / 2**20, 1),
                "stack_ratio": round(est["stack_bytes"] / j["report"]["sample_bytes"], 3),
                "file_mb": round(j["file_bytes"] / 2**20, 1),
            }
            rows.append(row)
            print(json.dumps(row), flush=True)
    worst = max(max(abs(r["peak_ratio"] - 1), abs(r["stack_ratio"] - 1)) for r in rows)
    print(json.dumps({"summary": "estimate / measured", "worst_relative_error": round(worst, 3),
                      "within_25_percent": worst <= 0.25}))


if __name__ == "__main__":
    main()
