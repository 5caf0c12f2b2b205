"""Edit-to-image latency inside Blender: slider change → pixels in the "Relume" image.

    python blender_tests/bench_edit_latency.py [--scene cornell|box] [--size 512] [--edits 40] [--device cpu]

Imports the assets Cornell scene (the paper's configuration: two editable regions, "White
walls" and "Object", N_b = 6 bases, one bounce) at --size², driven by their Principled
sliders, bakes it at a low sample count (latency does not depend on samples), then changes
the walls' Roughness and the object's Base Color in turn, --edits times. (`--scene box`: the
tests' box with an editable Floor and Ball instead.) Each
edit is timed from the `default_value` assignment through `view_layer.update()` — Blender's
depsgraph evaluation, Relume's handler, the relight and `image.pixels.foreach_set` — to the
moment the image holds the new pixels. Prints JSON; nothing is asserted.
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import statistics
import sys
import tempfile
import time

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="relume-bench-user-"))

import bpy  # noqa: E402
import numpy as np  # noqa: E402
from conftest import ROOT, addon_zip  # noqa: E402
from support.scenes import box_scene, clear_scene  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--edits", type=int, default=40)
    ap.add_argument("--device", default="cpu", choices=["cpu", "gpu", "auto"])
    ap.add_argument("--spp", type=int, default=2)
    ap.add_argument("--scene", default="cornell", choices=["cornell", "box"])
    args = ap.parse_args()

    bpy.ops.extensions.package_install_files(filepath=str(addon_zip()), repo="user_default",
                                             enable_on_install=True)
    import importlib

    import relume

    addon = importlib.import_module("bl_ext.user_default.relume")
    prefs = bpy.context.preferences.addons["bl_ext.user_default.relume"].preferences
    prefs.device = args.device
    tmp = tempfile.mkdtemp(prefix="relume-bench-")
    clear_scene()
    bpy.ops.wm.save_as_mainfile(filepath=os.path.join(tmp, "bench.blend"))
    if args.scene == "cornell":
        from support.scene_import import import_scene

        import_scene(ROOT / "assets" / "cornell.scene.json", resolution=(args.size, args.size))
        rough_mat, colour_mat = "White walls", "Object"
        for name in (rough_mat, colour_mat):  # driven by the Principled sliders, not overrides
            bpy.data.materials[name].relume.override = False
    else:
        box_scene(resolution=args.size)
        rough_mat, colour_mat = "Floor", "Ball"
    settings = relume.BakeSettings(spp=args.spp, light_samples=1, indirect_samples=1, bounces=1,
                                   bases=6)
    t0 = time.perf_counter()
    report = addon.api.bake(settings=settings)
    bake_s = time.perf_counter() - t0

    img = bpy.data.images["Relume"]
    floor = bpy.data.materials[rough_mat].node_tree.nodes["Principled BSDF"].inputs["Roughness"]
    ball = bpy.data.materials[colour_mat].node_tree.nodes["Principled BSDF"].inputs["Base Color"]
    probe = np.empty(args.size * args.size * 4, np.float32)
    latencies, relights = [], []
    for i in range(args.edits):
        img.pixels.foreach_get(probe)
        before = probe.copy()
        t0 = time.perf_counter()
        if i % 2 == 0:
            floor.default_value = 0.3 + 0.5 * ((i // 2) % 2)
        else:
            ball.default_value = (0.6 - 0.4 * ((i // 2) % 2), 0.3, 0.8, 1.0)
        bpy.context.view_layer.update()
        latencies.append((time.perf_counter() - t0) * 1e3)
        relights.append(addon.runtime.RUNTIME.live.last_relight_ms)
        img.pixels.foreach_get(probe)
        if np.array_equal(before, probe):
            print(json.dumps({"error": f"edit {i} did not change the image"}))
            return 1
    live = addon.runtime.RUNTIME.live
    print(json.dumps({
        "benchmark": "edit_to_image_latency",
        "scene": args.scene,
        "size": [args.size, args.size],
        "device": live.relighter.device, "device_reason": live.relighter.device_reason,
        "layers": live.stack.layer_count, "stack_mb": round(live.stack.bytes / 1e6, 1),
        "editable_regions": live.stack.editable_regions,
        "bake_s": round(bake_s, 2), "bake_report_s": report.get("seconds"),
        "edits": args.edits,
        "latency_ms": {"median": round(statistics.median(latencies), 2),
                       "p90": round(sorted(latencies)[int(0.9 * (len(latencies) - 1))], 2),
                       "max": round(max(latencies), 2), "min": round(min(latencies), 2)},
        "relight_ms_median": round(statistics.median(relights), 2),
        "target_ms": 50,
        "cpu_count": os.cpu_count(),
    }, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
