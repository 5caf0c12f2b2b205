"""A farm job's wall time on 8–32 machines, projected from a measured route run; prints JSON.

    python3 farm/project_farm.py docs/data/farm-routes-DATE.jsonl [--route openjd]
        [--machines 8 16 32] [--link-gbps 10] [--resolution 1920x1080]

Reads one row of `farm/bench_routes.py` (the route run on one machine with N = 2 and 4,
every task alone on the machine with all its cores, as OpenJD's local runner runs them) and
fits, from the two partition counts, the two lines a farm's wall time is made of:

- a partition's wall `t(N) = o + W / N`: `W` the tracing every partition shares out, `o`
  what every partition repeats (process start, scene load, BVH, bases, writing its part);
- the merge's wall `m(N) = m0 + m1 · N`: `m1` reading and summing one more part, `m0` the
  finish every merge runs once (averaging, denoiser, dropping, compression, writing).

On M machines like this one the job takes `guide + t(M) + transfer + m(M)`: the guide once,
the partitions side by side, then every part copied to the machine that merges (`M` parts
of the measured size over one link of `--link-gbps`, an assumption: nothing here measures a
network) and the merge. Two points fit each line exactly, so this is a projection, not a
measurement: the merge is assumed linear in N, and shared storage, stragglers and
scheduling are left out.
"""

from __future__ import annotations

import argparse
import json
import statistics


def fit_line(points: dict[int, float], inverse: bool) -> tuple[float, float]:
    """(intercept, slope) through two (N, wall) points, in 1/N when `inverse`, else in N."""
    (n1, y1), (n2, y2) = sorted(points.items())[:2]
    x1, x2 = (1 / n1, 1 / n2) if inverse else (n1, n2)
    slope = (y2 - y1) / (x2 - x1)
    return y1 - slope * x1, slope


def project(row: dict, route: str, machines: list[int], link_gbps: float) -> dict:
    runs = {r["partitions"]: r for r in row["runs"] if r["route"] == route}
    if len(runs) < 2:
        raise SystemExit(f"the row has {len(runs)} partition counts for {route}; two are needed")
    part_wall = {n: statistics.median(t["wall_s"] for t in r["tasks"] if t["kind"] == "partition")
                 for n, r in runs.items()}
    merge_wall = {n: next(t["wall_s"] for t in r["tasks"] if t["kind"] == "merge") for n, r in runs.items()}
    guide = statistics.median(t["wall_s"] for r in runs.values() for t in r["tasks"] if t["kind"] == "guide")
    part_gb = statistics.median(mb / 1e3 for r in runs.values() for mb in r["part_file_mb"])
    overhead, work = fit_line(part_wall, inverse=True)
    m0, m1 = fit_line(merge_wall, inverse=False)
    single = row["single"]["wall_s"]
    rows = []
    for m in machines:
        trace = overhead + work / m
        transfer = m * part_gb * 8 / link_gbps
        merge = m0 + m1 * m
        total = guide + trace + transfer + merge
        rows.append({"machines": m, "guide_s": round(guide, 1), "partition_s": round(trace, 1),
                     "transfer_s": round(transfer, 1), "merge_s": round(merge, 1),
                     "total_s": round(total, 1), "speedup_over_one_machine": round(single / total, 2)})
    return {"route": route, "resolution": row["resolution"], "preset": row["preset"],
            "editable": row["editable"], "one_machine_bake_s": single,
            "fit": {"partition_overhead_s": round(overhead, 1), "partition_work_s": round(work, 1),
                    "merge_fixed_s": round(m0, 1), "merge_per_part_s": round(m1, 1),
                    "part_gb": round(part_gb, 2), "link_gbps": link_gbps},
            "measured_n": sorted(runs), "projection": rows}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("rows", help="JSONL written by farm/bench_routes.py --out")
    ap.add_argument("--route", default="openjd", choices=["openjd", "flamenco", "dask"])
    ap.add_argument("--machines", type=int, nargs="+", default=[8, 16, 32])
    ap.add_argument("--link-gbps", type=float, default=10.0,
                    help="the merging machine's network link (assumed, not measured)")
    ap.add_argument("--resolution", help="the row of this resolution (default: the last row)")
    args = ap.parse_args()
    with open(args.rows) as f:
        rows = [json.loads(line) for line in f if line.strip()]
    if args.resolution:
        rows = [r for r in rows if r["resolution"] == args.resolution]
    if not rows:
        raise SystemExit("no row to project from")
    print(json.dumps(project(rows[-1], args.route, args.machines, args.link_gbps), indent=1))


if __name__ == "__main__":
    main()
