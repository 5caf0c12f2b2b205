"""The three farm routes run end to end on one scene, against the one-machine bake; prints JSON.

For the eight-material Cornell scene (scripts/make_cornell8.py, all eight editable, one
bounce, a named preset) this bakes once on one machine and then, for each partition count N
and each route, runs the whole farm job as the route runs it here:

- **openjd**: the Open Job Description template under `openjd run` (openjd-cli runs the
  tasks one after another on this machine);
- **flamenco**: the Flamenco job type's commands through `farm/flamenco/run_locally.js`
  (node; Flamenco's Manager is not available here), one after another;
- **dask**: `farm/dask_bake.py` on a LocalCluster of N worker processes, each partition's
  `relume` with `--threads max(1, cores / N)`.

Every `relume` the routes start runs under `/usr/bin/time`, through a wrapper given to the
route as its Relume executable, so each task's peak resident memory and wall time are
recorded as the route ran it. Per route and N: the job's wall time, each task's peak and
wall, the bytes each partition writes and the merge reads, and whether the merged file is
byte-identical to the one-machine bake's.

    python3 farm/bench_routes.py --relume target/release/relume --resolution 512x512 \
        --partitions 2 4 --out routes.jsonl
"""

from __future__ import annotations

import argparse
import filecmp
import json
import os
import pathlib
import shlex
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]


def timed_wrapper(tmp: pathlib.Path, relume: str, log: pathlib.Path) -> pathlib.Path:
    """A script that runs `relume` under /usr/bin/time, appending `peak_kb wall_s args` to `log`."""
    wrapper = tmp / "relume-timed"
    wrapper.write_text(
        "#!/usr/bin/env bash\n"
        f"exec /usr/bin/time -f '%M %e %C' -a -o {shlex.quote(str(log))} "
        f"{shlex.quote(str(pathlib.Path(relume).resolve()))} \"$@\"\n")
    wrapper.chmod(0o755)
    return wrapper


def tasks_of(log: pathlib.Path) -> list[dict]:
    """The tasks the wrapper recorded: kind (guide, partition, merge), peak and wall."""
    out = []
    for line in log.read_text().splitlines():
        parts = line.split(" ", 2)
        if len(parts) < 3 or not parts[0].isdigit():
            continue  # /usr/bin/time's note on a non-zero exit; the route fails on it anyway
        peak_kb, wall, command = int(parts[0]), float(parts[1]), parts[2]
        kind = ("guide" if "--guide-only" in command else "partition" if "--partition" in command
                else "merge" if " merge " in f" {command} " else "other")
        out.append({"kind": kind, "peak_rss_gb": round(peak_kb * 1024 / 1e9, 3), "wall_s": wall})
    return out


def run_route(route: str, n: int, scene: pathlib.Path, work: pathlib.Path, output: pathlib.Path,
              options: list[str], wrapper: pathlib.Path) -> float:
    """Runs the whole job through `route`; returns its wall time."""
    opts = " ".join(options)
    if route == "openjd":
        cmd = ["openjd", "run", str(ROOT / "farm/openjd/relume-bake.template.yaml"), "--step", "Merge",
               "--run-dependencies", "-p", f"Scene={scene}", "-p", f"WorkDir={work}",
               "-p", f"Output={output}", "-p", f"Partitions={n}", "-p", f"BakeOptions={opts}",
               "-p", f"Relume={wrapper}"]
    elif route == "flamenco":
        cmd = ["node", str(ROOT / "farm/flamenco/run_locally.js"), str(scene), str(output), str(work),
               str(n), opts, str(wrapper), "--run"]
    elif route == "dask":
        threads = max(1, (os.cpu_count() or 1) // n)
        cmd = [sys.executable, str(ROOT / "farm/dask_bake.py"), str(scene), "-o", str(output),
               "--partitions", str(n), "--workers", str(n), "--workdir", str(work),
               "--options", f"{opts} --threads {threads}", "--relume", str(wrapper)]
    else:
        raise SystemExit(f"unknown route {route!r}")
    start = time.monotonic()
    out = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.monotonic() - start
    if out.returncode != 0:
        raise SystemExit(f"route {route} with {n} partitions failed:\n{out.stdout[-2000:]}\n{out.stderr[-2000:]}")
    return wall


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--relume", default=str(ROOT / "target" / "release" / "relume"))
    ap.add_argument("--resolution", default="512x512")
    ap.add_argument("--editable", type=int, default=8)
    ap.add_argument("--preset", default="preview", choices=["draft", "preview", "final"])
    ap.add_argument("--partitions", type=int, nargs="+", default=[2, 4])
    ap.add_argument("--routes", nargs="+", default=["openjd", "flamenco", "dask"])
    ap.add_argument("--out", help="also append the JSON row to this file (one line)")
    args = ap.parse_args()
    options = ["--preset", args.preset, "--bounces", "1"]
    with tempfile.TemporaryDirectory() as tmp_dir:
        tmp = pathlib.Path(tmp_dir)
        scene = tmp / "cornell8.scene.json"
        subprocess.run([sys.executable, str(ROOT / "scripts" / "make_cornell8.py"), "--editable",
                        str(args.editable), "--resolution", args.resolution, "--out", str(scene)],
                       check=True, stdout=subprocess.DEVNULL)
        log = tmp / "tasks.log"
        wrapper = timed_wrapper(tmp, args.relume, log)
        single = tmp / "single.exr"
        subprocess.run([str(wrapper), "bake", str(scene), "-o", str(single), *options], check=True,
                       capture_output=True)
        [one] = tasks_of(log)
        log.unlink()
        row: dict = {"resolution": args.resolution, "editable": args.editable, "preset": args.preset,
                     "bounces": 1, "cores": os.cpu_count(),
                     "single": {"peak_rss_gb": one["peak_rss_gb"], "wall_s": one["wall_s"],
                                "file_mb": round(single.stat().st_size / 1e6, 1)},
                     "runs": []}
        for n in args.partitions:
            for route in args.routes:
                work = tmp / f"{route}_{n}"
                work.mkdir()
                output = tmp / f"{route}_{n}.exr"
                wall = run_route(route, n, scene, work, output, options, wrapper)
                parts = sorted(work.glob("*.rpart"))
                tasks = tasks_of(log)
                log.unlink()
                row["runs"].append({
                    "route": route, "partitions": n, "job_wall_s": round(wall, 2),
                    "tasks": tasks,
                    "partition_peak_rss_gb_max": max(t["peak_rss_gb"] for t in tasks if t["kind"] == "partition"),
                    "merge_peak_rss_gb": max(t["peak_rss_gb"] for t in tasks if t["kind"] == "merge"),
                    "part_file_mb": [round(p.stat().st_size / 1e6, 1) for p in parts],
                    "merge_reads_mb": round(sum(p.stat().st_size for p in parts) / 1e6, 1),
                    "merged_identical_to_single": filecmp.cmp(single, output, shallow=False),
                })
                # A whole run takes hours at 1920×1080: each route's result is on stderr as it ends.
                print(json.dumps({"single": row["single"], **row["runs"][-1]}), file=sys.stderr, flush=True)
                for p in work.iterdir():
                    p.unlink()
                output.unlink()
        print(json.dumps(row, indent=1))
        if args.out:
            with open(args.out, "a") as f:
                f.write(json.dumps(row) + "\n")


if __name__ == "__main__":
    main()
