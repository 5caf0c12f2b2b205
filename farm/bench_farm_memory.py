"""Peak memory and file sizes of a farm bake against the one-machine bake; prints JSON.

The eight-material Cornell scene (scripts/make_cornell8.py), all eight editable, one bounce,
a named preset (draft by default): the one-machine bake, then for each N the guide task,
every `--partition i/N` task and the merge, each run under `/usr/bin/time -v` for its peak
resident memory (max RSS) and wall time, with the bytes each writes. The merged file is
compared with the one-machine bake's byte for byte, and each task's peak is held to the
farm's bounds (printed, not asserted): a partition within 1.2 × the one-machine bake's peak
+ 0.3 GB, the merge within 2 × the stack's stored bytes + 0.5 GB.

    python3 farm/bench_farm_memory.py --resolution 512x512 --splits 2,4 \
        --relume target/release/relume
"""

from __future__ import annotations

import argparse
import filecmp
import json
import pathlib
import re
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]


def run(cmd: list[str]) -> dict:
    """Runs `cmd` under /usr/bin/time -v: its peak RSS (bytes) and wall time (s)."""
    start = time.monotonic()
    out = subprocess.run(["/usr/bin/time", "-v", *cmd], capture_output=True, text=True)
    wall = time.monotonic() - start
    if out.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{out.stderr[-2000:]}")
    rss = re.search(r"Maximum resident set size \(kbytes\): (\d+)", out.stderr)
    return {"peak_rss_bytes": int(rss.group(1)) * 1024 if rss else None, "wall_s": round(wall, 2),
            "stdout": out.stdout}


def gb(n: int | None) -> float | None:
    return None if n is None else round(n / 1e9, 3)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--relume", default=str(ROOT / "target" / "release" / "relume"))
    ap.add_argument("--resolution", default="512x512")
    ap.add_argument("--editable", type=int, default=8)
    ap.add_argument("--preset", default="draft", choices=["draft", "preview", "final"])
    ap.add_argument("--splits", default="2", help="comma-separated partition counts")
    ap.add_argument("--threads", default="0")
    ap.add_argument("--out", help="also append the JSON row to this file (one line)")
    args = ap.parse_args()
    flags = ["--preset", args.preset, "--bounces", "1", "--threads", args.threads]
    with tempfile.TemporaryDirectory() as tmp_dir:
        tmp = pathlib.Path(tmp_dir)
        scene = tmp / "cornell8.scene.json"
        subprocess.run([sys.executable, str(ROOT / "scripts" / "make_cornell8.py"), "--editable",
                        str(args.editable), "--resolution", args.resolution, "--out", str(scene)],
                       check=True, stdout=subprocess.DEVNULL)
        single = tmp / "single.exr"
        row: dict = {"resolution": args.resolution, "editable": args.editable, "preset": args.preset,
                     "bounces": 1}
        s = run([args.relume, "bake", str(scene), "-o", str(single), "--json", *flags])
        stored = json.loads(s["stdout"])["report"]["stored_bytes"]
        row["single"] = {"peak_rss_gb": gb(s["peak_rss_bytes"]), "wall_s": s["wall_s"],
                         "file_mb": round(single.stat().st_size / 1e6, 1),
                         "stack_stored_mb": round(stored / 1e6, 1)}
        part_bound = 1.2 * s["peak_rss_bytes"] + 0.3e9
        merge_bound = 2.0 * stored + 0.5e9
        guide = tmp / "guide.rguide"
        g = run([args.relume, "bake", str(scene), "--guide-only", "-o", str(guide), *flags])
        row["guide"] = {"peak_rss_gb": gb(g["peak_rss_bytes"]), "wall_s": g["wall_s"],
                        "file_mb": round(guide.stat().st_size / 1e6, 3)}
        splits = []
        for n in [int(x) for x in args.splits.split(",") if x]:
            parts = []
            cells = []
            for i in range(n):
                part = tmp / f"part_{n}_{i}.rpart"
                p = run([args.relume, "bake", str(scene), "--partition", f"{i}/{n}", "--guide", str(guide),
                         "-o", str(part), *flags])
                parts.append(part)
                cells.append({"partition": f"{i}/{n}", "peak_rss_gb": gb(p["peak_rss_bytes"]),
                              "wall_s": p["wall_s"], "file_mb": round(part.stat().st_size / 1e6, 1)})
            merged = tmp / f"merged_{n}.exr"
            m = run([args.relume, "merge", *map(str, parts), "-o", str(merged), "--threads", args.threads])
            splits.append({
                "partitions": n,
                "parts": cells,
                "parts_read_by_merge_mb": round(sum(p.stat().st_size for p in parts) / 1e6, 1),
                "merge": {"peak_rss_gb": gb(m["peak_rss_bytes"]), "wall_s": m["wall_s"],
                          "file_mb": round(merged.stat().st_size / 1e6, 1)},
                "merged_identical_to_single": filecmp.cmp(single, merged, shallow=False),
                "partition_bound_gb": gb(int(part_bound)),
                "partitions_within_bound": all(c["peak_rss_gb"] * 1e9 <= part_bound for c in cells),
                "merge_bound_gb": gb(int(merge_bound)),
                "merge_within_bound": m["peak_rss_bytes"] <= merge_bound,
            })
            for part in parts:
                part.unlink()
        row["splits"] = splits
        print(json.dumps(row, indent=1))
        if args.out:
            with open(args.out, "a") as f:
                f.write(json.dumps(row) + "\n")


if __name__ == "__main__":
    main()
