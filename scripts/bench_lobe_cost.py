"""What the basis of editable materials costs, per preset: the Principled basis (with each region's
bake-time lobe as a slot) against the Blinn–Phong basis, in one run; prints JSON lines.

For a scene whose editable materials are Principled BSDFs (default: the eight-material Cornell
box of scripts/make_cornell8.py with `--principled`, all eight editable), each preset is baked
with `--lobe principled` and `--lobe blinn-phong` (one bounce unless `--bounces`), `--repeats`
times each, alternating, so that load on the machine falls on both alike. Per bake: wall time,
peak resident memory, the file's bytes, the stored stack's bytes, layers and the bake's set-up
seconds (where the basis is read or built). Then a whole `relume relight --denoise none` process
per stack (load, basis from the disk cache, first relight, EXR write), `--repeats` times, with
the seconds from opening the stack to the first relit image and those spent on the bases and the
materials' coefficients (its JSON report). The first Principled bake of a configuration on a
machine builds its basis (the disk cache then holds it): a bake with an empty cache of its own
measures that (`cold_setup_s`) before the timed ones, which read the machine's cache.

    python3 scripts/bench_lobe_cost.py --relume target/release/relume --resolution 256x256 \\
        --presets draft,preview,final --repeats 2 --out lobe-cost.jsonl
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import platform
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]


def timed(cmd: list[str], env: dict | None = None) -> tuple[float, int, str]:
    """Runs `cmd` under /usr/bin/time; (wall seconds, peak RSS bytes, stdout)."""
    with tempfile.NamedTemporaryFile("r", suffix=".time") as log:
        t0 = time.perf_counter()
        out = subprocess.run(["/usr/bin/time", "-f", "%M", "-o", log.name, *cmd], capture_output=True,
                             text=True, env=env)
        wall = time.perf_counter() - t0
        if out.returncode != 0:
            sys.exit(f"failed ({out.returncode}): {' '.join(cmd)}\n{out.stderr[-2000:]}")
        peak_kb = int(pathlib.Path(log.name).read_text().split()[-1])
    return wall, peak_kb * 1024, out.stdout


def summary(values: list[float]) -> dict:
    return {"min": round(min(values), 3), "median": round(statistics.median(values), 3)}


def ratio(p: dict, b: dict) -> dict:
    """`p`'s figures over the Blinn–Phong bake's `b`."""
    return {"bake_wall_median": round(p["wall_s"]["median"] / b["wall_s"]["median"], 3),
            "file": round(p["file_mb"] / b["file_mb"], 3),
            "stored": round(p["stored_mb"] / b["stored_mb"], 3),
            "peak_median": round(p["peak_gb"]["median"] / b["peak_gb"]["median"], 3)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--relume", default=str(ROOT / "target/release/relume"))
    ap.add_argument("--scene", help="scene JSON (default: the Principled eight-material Cornell box)")
    ap.add_argument("--editable", type=int, default=8)
    ap.add_argument("--resolution", default="256x256")
    ap.add_argument("--presets", default="draft,preview,final")
    ap.add_argument("--bounces", type=int, default=1)
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--principled-bases", default="",
                    help="comma-separated Principled basis sizes to bake besides the preset's (e.g. 9,13)")
    ap.add_argument("--out", help="also append the JSON lines to this file")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = pathlib.Path(tmp_name)
        scene = a.scene
        if scene is None:
            scene = str(tmp / "cornell8.scene.json")
            subprocess.run([sys.executable, str(ROOT / "scripts/make_cornell8.py"), "--principled",
                            "--editable", str(a.editable), "--resolution", a.resolution, "--out", scene],
                           check=True, capture_output=True)
        for preset in a.presets.split(","):
            base = [a.relume, "bake", scene, "--preset", preset, "--bounces", str(a.bounces),
                    "--resolution", a.resolution, "--json"]
            variants = {"principled": ["--lobe", "principled"], "blinn-phong": ["--lobe", "blinn-phong"]}
            for n in filter(None, a.principled_bases.split(",")):
                variants[f"principled-{n}"] = ["--lobe", "principled", "--principled-bases", n]
            # Per Principled size: a build from nothing (an empty cache of its own), then one
            # that fills the machine's cache for the timed bakes.
            cold = {}
            for name, flags in variants.items():
                if name == "blinn-phong":
                    continue
                empty = {**os.environ, "RELUME_CACHE_DIR": str(tmp / f"cache-{preset}-{name}")}
                cold[name] = json.loads(timed([*base, "-o", str(tmp / "cold.exr"), *flags], empty)[2])
                timed([*base, "-o", str(tmp / "cold.exr"), *flags])
            rows: dict[str, dict] = {lobe: {"wall_s": [], "peak_gb": [], "relight_process_s": [],
                                            "first_image_s": [], "bases_s": []}
                                     for lobe in variants}
            for _ in range(a.repeats):
                for lobe, row in rows.items():
                    stack = tmp / f"{lobe}.exr"
                    wall, peak, out = timed([*base, "-o", str(stack), *variants[lobe]])
                    bake = json.loads(out)
                    row["wall_s"].append(wall)
                    row["peak_gb"].append(peak / 1e9)
                    row.update(file_mb=round(bake["file_bytes"] / 1e6, 2),
                               stored_mb=round(bake["report"]["stored_bytes"] / 1e6, 2),
                               layers=bake["layers"], setup_s=round(bake["report"]["setup_seconds"], 3),
                               warnings=bake["report"]["warnings"])
            for _ in range(a.repeats):
                for lobe, row in rows.items():
                    wall, _, out = timed([a.relume, "relight", str(tmp / f"{lobe}.exr"), "-o",
                                          str(tmp / "relit.exr"), "--denoise", "none", "--device", "cpu",
                                          "--json"])
                    relit = json.loads(out)
                    row["relight_process_s"].append(wall)
                    row["first_image_s"].append(relit["first_image_seconds"])
                    row["bases_s"].append(relit["bases_seconds"])
            for row in rows.values():
                for key in ("wall_s", "peak_gb", "relight_process_s", "first_image_s", "bases_s"):
                    row[key] = summary(row[key])
            b = rows["blinn-phong"]
            line = {
                "preset": preset, "resolution": a.resolution, "editable": a.editable,
                "bounces": a.bounces, "scene": "cornell8 --principled" if a.scene is None else a.scene,
                "cold_setup_s": round(cold["principled"]["report"]["setup_seconds"], 3),
                "principled": rows["principled"], "blinn_phong": b,
                "ratio": ratio(rows["principled"], b),
                "other_sizes": {k: {**v, "ratio": ratio(v, b)} for k, v in rows.items()
                                if k.startswith("principled-")},
                "machine": {"cores": os.cpu_count(), "platform": platform.platform(),
                            "load_1min": round(os.getloadavg()[0], 2)},
                "date": time.strftime("%Y-%m-%d"),
            }
            text = json.dumps(line)
            print(text, flush=True)
            if a.out:
                with open(a.out, "a") as f:
                    f.write(text + "\n")


if __name__ == "__main__":
    main()
