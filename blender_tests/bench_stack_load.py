"""Reopening a baked .blend until the "Relume" image shows the relit pixels; prints JSON.

    python blender_tests/bench_stack_load.py [--size 512x512] [--k 2] [--preset preview]
                                             [--repeats 5]

Builds the eight-material Cornell scene of the scale benchmarks (`scripts/make_cornell8.py`,
the first k materials of `bench_edit_latency.EDITABLE_ORDER` editable and driven by their
shader sliders), bakes it through the add-on with the preset's basis (the Principled basis
for the Principled materials) but one sample of each kind and one bounce (a stack's load
and its first relight follow its layers, not its sample counts), saves the .blend and then
reopens it with `wm.open_mainfile`, as a user reopening their file does. Opening runs the
add-on's load handler: the scene's export for the stale check, `Stack.load`, the
relighter with the editable materials' bases, the first relight and the copy into the
image. Each reopen is checked to show the image the bake showed.

Timed, `--repeats` times each (min and median):

- `reopen_s_same_process`: the whole `open_mainfile` in the Blender that baked (its bases
  already built in memory);
- `reopen_s_new_process_warm` / `_cold`: the same in a fresh Blender (Python with bpy and
  the add-on installed), the Principled basis in the machine's disk cache, or in an empty
  cache folder (a stack baked on another machine, or the first open after an engine
  update: the basis is built);
- `reopen_without_stack_s`: the same file with its stack moved away: Blender's own load
  and the handler finding nothing to load. The difference is what Relume adds.

Nothing is asserted.
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))

import bench_edit_latency as latency  # noqa: E402  (sets Blender's user folder first)
import bpy  # noqa: E402
import numpy as np  # noqa: E402
from conftest import addon_zip, install_addon  # noqa: E402
from support.scene_import import import_scene  # noqa: E402
from support.scenes import clear_scene  # noqa: E402


def _pixels() -> np.ndarray:
    img = bpy.data.images["Relume"]
    out = np.empty(len(img.pixels), np.float32)
    img.pixels.foreach_get(out)
    return out


def _reopen(addon, blend: str, expect: np.ndarray | None) -> float:
    """One `open_mainfile` of `blend`, timed; with `expect`, checks the image shows it."""
    addon.runtime.RUNTIME.live.unload()
    t0 = time.perf_counter()
    bpy.ops.wm.open_mainfile(filepath=blend)
    seconds = time.perf_counter() - t0
    live = addon.runtime.RUNTIME.live
    if expect is not None:
        if not live.ready:
            raise RuntimeError(f"the reopened file shows no relit image: {live.load_error or live.stale_reason}")
        got = _pixels()
        if not np.allclose(got, expect, rtol=1e-5, atol=1e-6):
            raise RuntimeError("the reopened file's image differs from the one the bake showed")
    return seconds


_NEW_PROCESS = """
import importlib, sys, time, bpy
bpy.ops.extensions.package_install_files(filepath=sys.argv[1], repo="user_default", enable_on_install=True)
addon = importlib.import_module("bl_ext.user_default.relume")
bpy.context.preferences.addons["bl_ext.user_default.relume"].preferences.device = "cpu"
t0 = time.perf_counter()
bpy.ops.wm.open_mainfile(filepath=sys.argv[2])
seconds = time.perf_counter() - t0
live = addon.runtime.RUNTIME.live
assert live.ready, live.load_error or live.stale_reason
print("RELOAD_SECONDS", seconds)
"""


def _reopen_in_new_process(blend: str, cache: str | None) -> float:
    """`open_mainfile` of `blend` in a fresh Python with the add-on installed and the basis
    cache folder `cache` (None: the machine's): what a user reopening Blender waits for."""
    env = dict(os.environ)
    if cache is None:
        env.pop("RELUME_CACHE_DIR", None)
    else:
        env["RELUME_CACHE_DIR"] = cache
    env["BLENDER_USER_RESOURCES"] = tempfile.mkdtemp(prefix="relume-bench-user-")
    out = subprocess.run([sys.executable, "-c", _NEW_PROCESS, str(addon_zip()), blend], env=env,
                         capture_output=True, text=True, check=True)
    return float(out.stdout.split("RELOAD_SECONDS")[-1].split()[0])


def _basis_of(region: dict) -> str:
    """Which basis the stack's header records for an editable region."""
    if region.get("principled_basis_with_bake_lobe"):
        return f"principled {region['principled_basis_with_bake_lobe']} + bake-time slot"
    if region.get("principled_basis"):
        return f"principled {region['principled_basis']}"
    return "blinn-phong"


def _stats(values: list[float]) -> dict:
    return {"median": round(statistics.median(values), 3), "min": round(min(values), 3)}


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--size", default="512x512", help="WxH (or W for W×W)")
    ap.add_argument("--k", type=int, default=2, help="editable materials (1–8)")
    ap.add_argument("--preset", default="preview", choices=["draft", "preview", "final"])
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    width, height = latency._size(args.size)

    addon, prefs = install_addon()
    prefs.device = "cpu"
    import relume

    workdir = tempfile.mkdtemp(prefix="relume-load-bench-")
    clear_scene()
    blend = os.path.join(workdir, "bench.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend)
    scene_file = pathlib.Path(workdir) / "cornell8.scene.json"
    scene_file.write_text(json.dumps(latency.make_cornell8.build(0, width, height)))
    import_scene(scene_file, resolution=(width, height))
    names = latency.EDITABLE_ORDER[:args.k]
    for name in names:
        bpy.data.materials[name].relume.editable = True
        bpy.data.materials[name].relume.override = False
    settings = relume.BakeSettings.preset(args.preset, resolution_scale=1.0, spp=1, light_samples=1,
                                          indirect_samples=1, bounces=1)
    t0 = time.perf_counter()
    addon.api.bake(settings=settings)
    bake_s = time.perf_counter() - t0
    live = addon.runtime.RUNTIME.live
    stack_path = live.stack_path
    row = {"benchmark": "stack_load_in_blender", "size": [width, height], "k": args.k,
           "preset": args.preset, "editable": names, "layers": live.stack.layer_count,
           "stack_mb": round(live.stack.bytes / 1e6, 1),
           "bases": {r["name"]: _basis_of(r) for r in live.stack.header["regions"] if r["editable"]},
           "bake_s": round(bake_s, 1), "bpy": bpy.app.version_string, "cpu_count": os.cpu_count(),
           "repeats": args.repeats}
    expect = _pixels()
    bpy.ops.wm.save_mainfile()

    row["reopen_s_same_process"] = _stats([_reopen(addon, blend, expect) for _ in range(args.repeats)])
    for label, cache in (("warm", os.environ.get("RELUME_CACHE_DIR")), ("cold", "")):
        times = [_reopen_in_new_process(blend, cache if cache != "" else tempfile.mkdtemp(dir=workdir))
                 for _ in range(args.repeats)]
        row[f"reopen_s_new_process_{label}"] = _stats(times)
    moved = stack_path + ".away"
    shutil.move(stack_path, moved)
    try:
        row["reopen_without_stack_s"] = _stats([_reopen(addon, blend, None) for _ in range(args.repeats)])
    finally:
        shutil.move(moved, stack_path)
    row["relume_share_same_process_s"] = round(
        row["reopen_s_same_process"]["median"] - row["reopen_without_stack_s"]["median"], 3)
    print(json.dumps(row, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
