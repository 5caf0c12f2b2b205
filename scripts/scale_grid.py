"""The issue-14 grid: resolution × editable materials, one `relume bake --json` process per
cell (the eight-material Cornell scene of scripts/make_cornell8.py, a named preset — draft unless
`--preset` says otherwise, with its bounce-layer compression — at the cell's full resolution,
one bounce), then `relume bench relight` on the stack
it made. Prints one JSON object per cell: the forecast, peak memory (RSS growth over the
bake) and its ratio to the stored stack and to the forecast, whether it is within issue 14's
bound (2 × the stack + 500 MB), bake time with its per-layer part (assembly, denoising)
and the write, the per-layer share of bake + write, tile entries, stack bytes (stored, as the
dense layout would hold them, and on disk), full relight time, its ratio to
the machine's memory-bandwidth bound — or, for a cell over the memory budget, the refusal
and the forecast that caused it (no bake then). Run it on a quiet machine.

    python3 scripts/scale_grid.py --relume target/release/relume [--resolutions 512x512,1024x1024]
"""

from __future__ import annotations

import argparse
import json
import pathlib
import subprocess
import sys
import tempfile

ROOT = pathlib.Path(__file__).resolve().parents[1]


def preset_flags(preset: str) -> list[str]:
    """The bake flags of a grid cell: the named preset, one bounce (the grid measures the
    stack's scaling, not the frozen tail)."""
    return ["--preset", preset, "--bounces", "1"]


def cell(relume: str, tmp: pathlib.Path, res: str, k: int, threads: str = "0", preset: str = "draft",
         keep: pathlib.Path | None = None, bench_relight: bool = True) -> dict:
    scene = tmp / f"cornell8-{res}-k{k}.scene.json"
    subprocess.run([sys.executable, str(ROOT / "scripts" / "make_cornell8.py"), "--editable", str(k),
                    "--resolution", res, "--out", str(scene)], check=True, stdout=subprocess.DEVNULL)
    stack = (keep or tmp) / f"cornell8-{res}-k{k}-{preset}.exr"
    out = subprocess.run([relume, "bake", str(scene), "-o", str(stack), "--json", "--threads", threads,
                          *preset_flags(preset)],
                         capture_output=True, text=True)
    row: dict = {"resolution": res, "editable": k, "preset": preset}
    if out.returncode != 0:
        est = subprocess.run([relume, "bake", str(scene), "-o", str(stack), "--estimate-only", *preset_flags(preset)],
                             capture_output=True, text=True)
        row["refused"] = out.stderr.strip().splitlines()[-1] if out.stderr.strip() else f"exit {out.returncode}"
        if est.returncode == 0:
            row["estimate"] = json.loads(est.stdout)
        return row
    j = json.loads(out.stdout)
    r = j["report"]
    row.update({
        "layers_possible": r["layers_possible"],
        "layers_stored": j["layers"],
        "peak_estimate_gib": round(r["estimate"]["peak_bytes"] / 2**30, 2),
        "peak_rss_gib": round((j["peak_rss_bytes"] - j["rss_before_bake_bytes"]) / 2**30, 2),
        "bake_s": round(r["seconds"], 1),
        "assembly_s": round(r["assembly_seconds"], 1),
        "denoise_s": round(r["denoise_seconds"], 1),
        "write_s": round(j["write_seconds"], 1),
        # Per-layer work (assembly with the denoiser, and the write) over bake + write.
        "per_layer_share": round((r["assembly_seconds"] + j["write_seconds"])
                                 / max(r["seconds"] + j["write_seconds"], 1e-9), 3),
        "forecast_over_peak": round(r["estimate"]["peak_bytes"]
                                    / max(j["peak_rss_bytes"] - j["rss_before_bake_bytes"], 1), 2),
        "peak_within_bound": (j["peak_rss_bytes"] - j["rss_before_bake_bytes"])
        <= 2 * r.get("stored_bytes", r["sample_bytes"]) + 500e6,
        "tile_entries": r.get("tile_entries"),
        "stack_stored_mb": round(r.get("stored_bytes", r["sample_bytes"]) / 1e6, 1),
        "stack_dense_equivalent_mb": round(r.get("dense_bytes", r["sample_bytes"]) / 1e6, 1),
        "peak_over_stack": round((j["peak_rss_bytes"] - j["rss_before_bake_bytes"])
                                 / max(r.get("stored_bytes", r["sample_bytes"]), 1), 2),
        "stack_file_mb": round(j["file_bytes"] / 1e6, 1),
        # The bounce-layer compression: relit error against the uncompressed stack at the
        # bake-time materials (relative L2) and the bytes it saved.
        "compression_error": r.get("compression_error"),
        "compression_saved_mb": round(r.get("compression_saved_bytes", 0) / 1e6, 1),
    })
    if not bench_relight:
        return row
    bench = subprocess.run([relume, "bench", "relight", str(stack), "--device", "cpu", "--repeats", "10", "--json"],
                           capture_output=True, text=True)
    if bench.returncode == 0:
        b = json.loads(bench.stdout)
        row.update({"relight_full_ms": round(b["full_ms"], 2),
                    "relight_full_min_ms": round(b.get("full_min_ms", b["full_ms"]), 2),
                    "relight_over_bandwidth_bound": round(b["full_over_bound"], 2),
                    "relight_memory_over_stack": round(b.get("relight_memory_over_stack", 0.0), 3),
                    "incremental_over_full": round(b["fastest_incremental_over_full"], 3)})
    else:
        row["relight_error"] = bench.stderr.strip().splitlines()[-1] if bench.stderr.strip() else "failed"
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--relume", default=str(ROOT / "target" / "release" / "relume"))
    ap.add_argument("--resolutions", default="512x512,1024x1024,1920x1080")
    ap.add_argument("--editable", default="1,2,4,8")
    ap.add_argument("--threads", default="0", help="bake threads (0: all cores)")
    ap.add_argument("--preset", default="draft", choices=["draft", "preview", "final"])
    ap.add_argument("--keep", help="folder to keep each cell's stack in (to re-run the relight bench)")
    ap.add_argument("--no-bench", action="store_true",
                    help="bake only: for cells baked side by side, whose relight is benched afterwards alone")
    args = ap.parse_args()
    if args.keep:
        pathlib.Path(args.keep).mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        for res in args.resolutions.split(","):
            for k in (int(v) for v in args.editable.split(",")):
                print(json.dumps(cell(args.relume, pathlib.Path(tmp), res, k, args.threads, args.preset,
                                      pathlib.Path(args.keep) if args.keep else None,
                                      not args.no_bench)), flush=True)


if __name__ == "__main__":
    main()
