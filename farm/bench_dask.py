#!/usr/bin/env python3
"""Benchmark of the Dask route (farm/dask_bake.py) against a one-machine bake, in one run:
prints one JSON object. Not a test: figures depend on the machine and its load.

    python farm/bench_dask.py --relume target/release/relume [--resolution 96x96] [--partitions 2 4]

Measures, on a LocalCluster of 2 worker processes (one thread each; each partition runs
relume with --threads 1):
- the one-machine bake (`relume bake`, all cores) and the farm bake's wall time (guide →
  partitions → merge), and that the two stacks relight to the same image (max |Δ| = 0;
  the bit-identity of the stacks themselves is what core/engine/tests/farm.rs checks);
- Dask's own per-task overhead: submit → result of no-op tasks, one at a time and 200 at once;
- the overhead per partition: what a task adds around relume's own bake (Dask, process
  start, scene load, writing the partial) plus the set-up each partition repeats (BVH,
  basis), measured as a one-sample partition minus one sample's share of the trace;
- a projection, on paper, of a 1920×1080 final-preset bake on 8 and 32 machines like this
  one, from the measured per-sample cost (see docs/farm.md for the assumptions).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import dask_bake  # noqa: E402


def run_json(cmd):
    out = subprocess.run(cmd, check=True, capture_output=True, text=True)
    return json.loads(out.stdout)


def relit_max_abs(relume, a, b, tmp):
    ia, ib = os.path.join(tmp, "a.exr"), os.path.join(tmp, "b.exr")
    subprocess.run([relume, "relight", a, "-o", ia, "--device", "cpu", "--denoise", "none"],
                   check=True, capture_output=True)
    subprocess.run([relume, "relight", b, "-o", ib, "--device", "cpu", "--denoise", "none"],
                   check=True, capture_output=True)
    return run_json([relume, "compare", ia, ib, "--json"])


def dask_overhead():
    from distributed import Client, LocalCluster

    t = time.perf_counter()
    with (
        LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster,
        Client(cluster) as client,
    ):
        start_s = time.perf_counter() - t
        client.submit(lambda: 0, pure=False).result()  # warm
        n = 20
        t = time.perf_counter()
        for i in range(n):
            client.submit(lambda x: x, i, pure=False).result()
        serial = (time.perf_counter() - t) / n
        n = 200
        t = time.perf_counter()
        client.gather([client.submit(lambda x: x, i, pure=False) for i in range(n)])
        batch = (time.perf_counter() - t) / n
    return {"cluster_start_seconds": start_s, "round_trip_seconds": serial, "per_task_in_batch_seconds": batch}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--relume", default=str(HERE.parent / "target/release/relume"))
    ap.add_argument("--scene", default=str(HERE.parent / "assets/cornell.scene.json"))
    ap.add_argument("--preset", default="final")
    ap.add_argument("--resolution", default="96x96")
    ap.add_argument("--partitions", type=int, nargs="+", default=[2, 4])
    a = ap.parse_args()
    options = ["--preset", a.preset, "--resolution", a.resolution, "--seed", "1"]
    w, h = (int(v) for v in a.resolution.split("x"))
    result = {"scene": a.scene, "options": options, "machine": f"{os.cpu_count()} cores (shared)"}
    result["dask"] = dask_overhead()
    with tempfile.TemporaryDirectory() as tmp:
        single = os.path.join(tmp, "single.exr")
        t = time.perf_counter()
        s = run_json([a.relume, "bake", a.scene, *options, "-o", single, "--json"])
        single_wall = time.perf_counter() - t
        rep = s["report"]
        t = time.perf_counter()
        run_json([a.relume, "bake", a.scene, *options, "--guide-only", "-o", os.path.join(tmp, "g.rguide"), "--json"])
        result["guide_seconds"] = time.perf_counter() - t
        result["single"] = {
            "wall_seconds": single_wall,
            "bake_seconds": rep["seconds"],
            "trace_seconds": rep["trace_seconds"],
            "layers": s["layers"],
            "layers_possible": rep["layers_possible"],
            "file_bytes": s["file_bytes"],
        }
        # Set-up every partition repeats (scene load, BVH, basis, subsurface): a partition of
        # one sample minus one sample's share of the one-machine trace.
        one = run_json([a.relume, "bake", a.scene, *options, "--threads", "1", "--partition",
                        "0/128", "-o", os.path.join(tmp, "p.rpart"), "--json"])
        result["setup_per_partition_seconds"] = one["seconds"] - 2 * rep["trace_seconds"] / 128
        runs = []
        for n in a.partitions:
            work = os.path.join(tmp, f"work{n}")
            out = os.path.join(tmp, f"farm{n}.exr")
            r = dask_bake.bake_on_dask(
                a.scene, out, n, options + ["--threads", "1"], workers=2, relume=a.relume, workdir=work,
            )
            part_bytes = [os.path.getsize(os.path.join(work, f"part_{i}.rpart")) for i in range(n)]
            task_walls = [p["task_wall_seconds"] for p in r["parts"]]
            same = relit_max_abs(a.relume, out, single, tmp)
            # What a task adds around relume's own bake: Dask, process start, scene load,
            # writing the partial stack.
            around = sum(t - p["seconds"] for t, p in zip(task_walls, r["parts"], strict=True)) / n
            runs.append({
                "partitions": n,
                "wall_seconds": r["wall_seconds"],
                "wall_vs_single": r["wall_seconds"] / single_wall,
                "merge_seconds": r["merge_seconds"],
                "partition_task_walls": task_walls,
                "partition_seconds_reported": [p["seconds"] for p in r["parts"]],
                "part_file_bytes": part_bytes,
                "task_seconds_around_relume": around,
                "overhead_per_partition_seconds": around + result["setup_per_partition_seconds"],
                "relit_max_abs_difference": same["max_abs"],
                "relit_rel_l2": same["rel_l2"],
            })
        result["farm"] = runs
    # Projection on paper: per pixel-sample cost of the final preset on this machine.
    spp = 128 if a.preset == "final" else None
    if spp:
        pixels = w * h
        cost = result["single"]["trace_seconds"] / (pixels * spp)  # seconds per pixel-sample, 2 cores
        big = 1920 * 1080
        one = cost * big * spp
        scale = big / pixels
        # Partitions that divide spp in powers of two hold one block each: a partial's size
        # scales with the pixels (and the layers reached, which a real interior has more of).
        per_part_bytes = max(result["farm"][-1]["part_file_bytes"]) * scale
        guide = result["guide_seconds"] * scale
        proj = {"per_pixel_sample_seconds_2_cores": cost, "one_machine_seconds": one,
                "guide_seconds_scaled_by_pixels": guide}
        for m in (8, 32):
            overhead = result["farm"][-1]["overhead_per_partition_seconds"]
            merge = result["farm"][-1]["merge_seconds"] * scale
            proj[f"machines_{m}"] = {
                "trace_seconds": one / m,
                "merge_seconds_scaled_by_pixels": merge,
                "overhead_per_partition_seconds": overhead,
                "partial_bytes_each_upper_bound": per_part_bytes,
                "merge_reads_bytes_upper_bound": per_part_bytes * m,
                "total_seconds_without_transfer": guide + one / m + overhead + merge,
            }
        result["projection_1920x1080_final"] = proj
    print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
