"""What the tail-edit layers cost: bakes and relights of one scene by two `relume` builds,
one without tail-edit layers (an older build, e.g. the last commit before them) and this one,
alternated, in one run. Prints one JSON object (and writes it with `--out`).

    python3 scripts/bench_tail_edit_cost.py --old OLD/relume --new target/release/relume \\
        --scene assets/cornell.scene.json --preset preview --bakes 2 --relights 6 --out F.json

Per bake: wall and CPU time (user + system of the child), peak resident memory (the
child's maximum RSS), and `relume info --json` of the stack (bytes stored, file bytes,
layers, tail-edit layers). Per relight run: `relume bench relight --device cpu --json`
(full relight median and minimum, the fastest incremental edit). Summary: min / median over
runs for each build, and the ratio new / old of the medians. Run it on a quiet machine: the
CPU time of a bake is the steadier figure on a loaded one, the relight times are not.
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import resource
import statistics
import subprocess
import tempfile
import time


def _run_measured(cmd: list[str]) -> tuple[str, dict]:
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    # A fresh child per command: ru_maxrss of RUSAGE_CHILDREN is the largest child so far,
    # so each bake runs through its own wrapper process to be measured alone.
    wrapper = [
        "python3", "-c",
        "import resource,subprocess,sys,json;"
        "r=subprocess.run(sys.argv[1:],capture_output=True,text=True);"
        "u=resource.getrusage(resource.RUSAGE_CHILDREN);"
        "sys.stderr.write(r.stderr);print(r.stdout,end='');"
        "print('\\n@@'+json.dumps({'rc':r.returncode,'maxrss_kb':u.ru_maxrss}))",
        *cmd,
    ]
    out = subprocess.run(wrapper, capture_output=True, text=True, check=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    body, _, tail = out.stdout.rpartition("\n@@")
    meta = json.loads(tail)
    if meta["rc"] != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({meta['rc']}):\n{out.stderr[-2000:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return body, {"wall_s": wall, "cpu_s": cpu, "peak_rss_bytes": meta["maxrss_kb"] * 1024}


def bake(relume: str, scene: str, preset: str, out: pathlib.Path, extra: list[str]) -> dict:
    _, figures = _run_measured([relume, "bake", scene, "-o", str(out), "--preset", preset, *extra])
    info = json.loads(subprocess.run([relume, "info", str(out), "--json"], capture_output=True,
                                     text=True, check=True).stdout)
    return {**figures, "info": info}


def relight(relume: str, stack: pathlib.Path, repeats: int) -> dict:
    out = subprocess.run([relume, "bench", "relight", str(stack), "--device", "cpu", "--repeats",
                          str(repeats), "--json"], capture_output=True, text=True, check=True)
    return json.loads(out.stdout)


def _stat(values: list[float]) -> dict:
    return {"min": min(values), "median": statistics.median(values)}


def _find(d, *names):
    """The first key of `names` found anywhere in the nested dict `d` (info and bench JSON
    differ between builds in where they put a figure)."""
    if isinstance(d, dict):
        for n in names:
            if n in d and not isinstance(d[n], (dict, list)):
                return d[n]
        for v in d.values():
            found = _find(v, *names)
            if found is not None:
                return found
    return None


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--old", required=True, help="relume built without tail-edit layers")
    ap.add_argument("--new", required=True, help="relume built with them (this tree)")
    ap.add_argument("--scene", required=True)
    ap.add_argument("--preset", default="preview")
    ap.add_argument("--bake-args", default="", help="more `relume bake` arguments, space-separated")
    ap.add_argument("--bakes", type=int, default=1, help="bakes per build, alternated")
    ap.add_argument("--relights", type=int, default=4, help="relight runs per build, alternated")
    ap.add_argument("--repeats", type=int, default=20, help="relights timed per run")
    ap.add_argument("--work", type=pathlib.Path, default=None, help="folder for the stacks")
    ap.add_argument("--reuse", type=pathlib.Path, default=None,
                    help="an earlier run's --out: its bakes are kept (the stacks must still be in "
                    "--work) and only the relights run, e.g. on a quieter machine")
    ap.add_argument("--out", type=pathlib.Path, default=None)
    args = ap.parse_args()
    work = args.work or pathlib.Path(tempfile.mkdtemp(prefix="tail-edit-cost-"))
    work.mkdir(parents=True, exist_ok=True)
    builds = {"old": args.old, "new": args.new}
    extra = args.bake_args.split()
    runs: dict[str, list[dict]] = {"old": [], "new": []}
    relights: dict[str, list[dict]] = {"old": [], "new": []}
    if args.reuse:
        runs = json.loads(args.reuse.read_text())["runs"]
    for i in range(0 if args.reuse else args.bakes):
        for name, exe in builds.items():
            stack = work / f"{name}.relume.exr"
            r = bake(exe, args.scene, args.preset, stack, extra)
            runs[name].append(r)
            print(f"bake {i} {name}: {r['wall_s']:.1f} s wall, {r['cpu_s']:.1f} s CPU, "
                  f"{_find(r['info'], 'stored_bytes')} bytes stored", flush=True)
    for _ in range(args.relights):
        for name, exe in builds.items():
            relights[name].append(relight(exe, work / f"{name}.relume.exr", args.repeats))
    summary = {}
    for name in builds:
        info = runs[name][0]["info"]
        full_median = [_find(r, "full_ms") for r in relights[name]]
        full_min = [_find(r, "full_min_ms") for r in relights[name]]
        incremental = [_find(r, "fastest_incremental_ms") for r in relights[name]]
        summary[name] = {
            "stored_bytes": _find(info, "stored_bytes"),
            "file_bytes": _find(info, "file_bytes"),
            "layers_stored": _find(info, "layers_stored"),
            "tail_edit_layers_stored": _find(info, "tail_edit_layers_stored") or 0,
            "tail_edit_bytes": _find(info, "tail_edit_bytes") or 0,
            "bake_wall_s": _stat([r["wall_s"] for r in runs[name]]),
            "bake_cpu_s": _stat([r["cpu_s"] for r in runs[name]]),
            "peak_rss_bytes": _stat([r["peak_rss_bytes"] for r in runs[name]]),
        }
        for key, values in (("relight_full_median_ms", full_median), ("relight_full_min_ms", full_min),
                            ("relight_fastest_incremental_ms", incremental)):
            if values and all(v is not None for v in values):
                summary[name][key] = _stat(values)
    ratio = {}
    for key, value in summary["new"].items():
        old = summary["old"].get(key)
        if isinstance(value, dict) and isinstance(old, dict) and old["median"]:
            ratio[key] = value["median"] / old["median"]
        elif isinstance(value, (int, float)) and isinstance(old, (int, float)) and old:
            ratio[key] = value / old
    result = {
        "what": f"{args.scene}, relume bake --preset {args.preset} {args.bake_args}".strip()
        + f"; {args.bakes} bake(s) per build, {args.relights} relight runs of {args.repeats}",
        "cpus": os.cpu_count(),
        "date": time.strftime("%Y-%m-%d"),
        "summary": summary,
        "ratio_new_over_old": ratio,
        "runs": runs,
        "relight_runs": relights,
    }
    text = json.dumps(result, indent=1)
    if args.out:
        args.out.write_text(text + "\n")
    print(json.dumps({"summary": summary, "ratio_new_over_old": ratio}, indent=1))


if __name__ == "__main__":
    main()
