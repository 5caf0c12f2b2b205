#!/usr/bin/env python3
"""A Relume bake split over a Dask cluster: the guide pass, N sample-range partitions, the
merge — the same three steps as the Open Job Description template (docs/farm.md).

    python farm/dask_bake.py SCENE -o STACK.exr --partitions 8 --options "--preset final"
    python farm/dask_bake.py SCENE -o STACK.exr --scheduler tcp://head:8786 --workdir /shared/x

Without --scheduler it starts a LocalCluster of --workers worker processes on this machine
(one thread each: a partition already uses every core it is given through --threads).
Progress is printed as partitions finish; Ctrl-C cancels: queued tasks are cancelled and
running `relume` processes get SIGINT (a Relume bake stops within a pixel row and writes no
file), and no stack is written. The merged stack is bit-identical to
`relume bake SCENE <options> -o STACK.exr` on one machine.

Dask (`pip install distributed`) was chosen over Ray for this route: it installs from PyPI
in seconds with pure-Python wheels, runs here on 2 cores with a per-task overhead of
milliseconds (measured by farm/bench_dask.py, figures in docs/farm.md), and its futures carry
the guide → partitions → merge dependencies directly. Ray would do the same job but is a
much larger install; a bake's tasks last seconds to minutes, so nothing Ray adds matters here.

`bake_on_dask` is the API (used by examples/blender_farm_bake.py).
"""

from __future__ import annotations

import argparse
import os
import shlex
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path


def _run_relume(relume: str, args: Sequence[str], cancel_name: str | None) -> dict:
    """Runs `relume ARGS --json` on a worker; returns its JSON summary. Polls the cluster's
    cancel event (when named) and interrupts relume with SIGINT when it is set."""
    import json

    cancel = None
    if cancel_name:
        from distributed import Event

        cancel = Event(cancel_name)
    start = time.perf_counter()
    proc = subprocess.Popen(
        [relume, *args, "--json"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    while True:
        try:
            out, err = proc.communicate(timeout=0.25)
            break
        except subprocess.TimeoutExpired as timeout:
            if cancel is not None and cancel.is_set():
                proc.send_signal(signal.SIGINT)
                proc.communicate()
                raise RuntimeError("cancelled") from timeout
    if proc.returncode != 0:
        raise RuntimeError(f"relume {' '.join(args[:1])} failed: {err.strip()}")
    summary = json.loads(out)
    summary["task_wall_seconds"] = time.perf_counter() - start
    return summary


def _guide(relume, scene, options, workdir, cancel_name):
    guide = os.path.join(workdir, "guide.rguide")
    _run_relume(relume, ["bake", scene, *options, "--guide-only", "-o", guide], cancel_name)
    return guide


def _partition(relume, scene, options, workdir, index, count, guide, cancel_name):
    part = os.path.join(workdir, f"part_{index}.rpart")
    summary = _run_relume(
        relume,
        ["bake", scene, *options, "--partition", f"{index}/{count}", "--guide", guide, "-o", part],
        cancel_name,
    )
    return part, summary


def bake_on_dask(
    scene: str,
    output: str,
    partitions: int,
    options: Sequence[str] = ("--preset", "preview"),
    *,
    client=None,
    workers: int = 2,
    relume: str = "relume",
    workdir: str | None = None,
    on_progress: Callable[[int, int, dict], None] | None = None,
) -> dict:
    """Bakes `scene` into `output` over `partitions` Dask tasks and merges (on this machine).

    `client`: a `distributed.Client`; without one a LocalCluster of `workers` processes is
    started and closed. `workdir` must be visible to every worker (default: a temporary
    folder, fine for a local cluster). `on_progress(done, total, summary)` is called as
    partitions finish. Returns timings: guide, partitions (each relume's own seconds and the
    task's wall time), merge, wall. Raises KeyboardInterrupt after cancelling on Ctrl-C.
    """
    from distributed import Client, Event, LocalCluster, as_completed

    scene = str(Path(scene).resolve())
    output = str(Path(output).resolve())
    own_cluster = client is None
    cluster = None
    t0 = time.perf_counter()
    if own_cluster:
        cluster = LocalCluster(
            n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None
        )
        client = Client(cluster)
    cluster_seconds = time.perf_counter() - t0
    tmp = None
    if workdir is None:
        tmp = tempfile.TemporaryDirectory(prefix="relume-farm-")
        workdir = tmp.name
    os.makedirs(workdir, exist_ok=True)
    cancel_name = f"relume-cancel-{os.getpid()}-{time.time_ns()}"
    cancel = Event(cancel_name, client=client)
    futures = []
    try:
        start = time.perf_counter()
        guide = client.submit(
            _guide, relume, scene, list(options), workdir, cancel_name, pure=False
        )
        futures.append(guide)
        parts = [
            client.submit(
                _partition, relume, scene, list(options), workdir, i, partitions, guide,
                cancel_name, pure=False, key=f"relume-partition-{i}-{cancel_name}",
            )
            for i in range(partitions)
        ]
        futures.extend(parts)
        done = []
        for fut in as_completed(parts):
            part, summary = fut.result()
            done.append((part, summary))
            if on_progress:
                on_progress(len(done), partitions, summary)
        guide_done = time.perf_counter() - start
        merge_start = time.perf_counter()
        merge = _run_relume(
            relume,
            ["merge", *[p for p, _ in sorted(done)], "--scene", scene, "-o", output],
            None,
        )
        end = time.perf_counter()
        return {
            "partitions": partitions,
            "cluster_start_seconds": cluster_seconds,
            "guide_and_partitions_seconds": guide_done,
            "merge_seconds": end - merge_start,
            "wall_seconds": end - start,
            "parts": [s for _, s in done],
            "merge": merge,
        }
    except BaseException:
        cancel.set()
        client.cancel(futures)
        raise
    finally:
        if own_cluster:
            client.close()
            cluster.close()
        if tmp is not None:
            tmp.cleanup()


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scene")
    ap.add_argument("-o", "--output", required=True)
    ap.add_argument("--partitions", type=int, default=4)
    ap.add_argument("--options", default="--preset preview", help="relume bake options")
    ap.add_argument("--workers", type=int, default=2, help="local cluster processes")
    ap.add_argument("--scheduler", help="address of a running Dask scheduler")
    ap.add_argument("--relume", default="relume")
    ap.add_argument("--workdir", help="shared folder for guide and parts")
    a = ap.parse_args(argv)
    client = None
    if a.scheduler:
        from distributed import Client

        client = Client(a.scheduler)

    def progress(done, total, summary):
        s = summary["samples"]
        print(
            f"partition {summary['partition'][0]}/{total} done ({done}/{total}): "
            f"samples [{s[0]}, {s[1]}) in {summary['seconds']:.1f} s",
            file=sys.stderr,
        )

    try:
        r = bake_on_dask(
            a.scene, a.output, a.partitions, shlex.split(a.options), client=client,
            workers=a.workers, relume=a.relume, workdir=a.workdir, on_progress=progress,
        )
    except KeyboardInterrupt:
        print("cancelled: no stack written", file=sys.stderr)
        return 130
    print(f"merged {a.partitions} partitions in {r['wall_seconds']:.1f} s → {a.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
