"""Edit-to-pixels latency inside Blender, against the relight alone: the add-on's overhead.

    python blender_tests/bench_edit_latency.py [--sizes 512x512,1024x1024,1920x1080] [--k 2]
                                               [--edits 30] [--device cpu] [--bounces 1]

For every size × k (editable materials) it builds the eight-material Cornell scene of the
scale benchmarks (`scripts/make_cornell8.py`; k of its materials editable, visible ones
first: `EDITABLE_ORDER`) as a Blender scene, with the editable materials driven by their
shader sliders (no Blinn–Phong override), bakes it at that size with the draft preset's
basis and denoiser but one sample of each kind and one bounce (the layers, and so the
relight's work, follow the basis and the editable materials, not the sample counts; with
`--bounces` above 1 the stack also has its tail-edit layers, which every edit re-weighs, and
the add-on's edit path cancels a background refinement as it does after a bake), then
edits the editable materials in turn: a Principled Roughness or Base Color, a Diffuse Color.
Each edit is timed from the `default_value` assignment through `view_layer.update()` —
Blender's depsgraph evaluation, Relume's handler, the relight and the copy into the "Relume"
image — to the moment the image holds the new pixels (checked after every edit).

Per cell it prints, as JSON: edit→pixels, the relighter's own time for the same edits
(`Relighter.last_ms`), the overhead (their difference, edit by edit) and its ratio to the
relight (of the medians, and edit by edit: min and median), where the overhead goes, and
the upload floor: one `Image.pixels.foreach_set` of a float32 buffer of that size alone.
The overhead's parts are the copy of the relit pixels into the image (`image_upload`), the
Python side of the relighter's call, reading the materials' values and the rest of the
add-on's relight call, and what lies outside that call: Blender's depsgraph evaluation, the
handler, and releasing the relit array (`depsgraph_handler_and_release`). Nothing is
asserted.
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
from conftest import ROOT, install_addon  # noqa: E402
from support.scene_import import import_scene  # noqa: E402
from support.scenes import clear_scene  # noqa: E402

sys.path.insert(0, str(ROOT / "scripts"))
import make_cornell8  # noqa: E402

# Which of the scene's materials are editable, the first k of these: every edit must change
# the image, and the ceiling does not show at 16:9 (outside the frame, and lit only by light
# that bounced twice, which a one-bounce bake leaves out), so it comes last.
EDITABLE_ORDER = ["Floor", "Back wall", "Tall box", "Sphere top", "Red wall", "Green wall",
                  "Sphere bottom", "Ceiling"]
WARMUP_EDITS = 2  # first-touch costs (image buffers, caches) are not what a slider sees


def _size(text: str) -> tuple[int, int]:
    w, _, h = text.partition("x")
    return int(w), int(h or w)


def _stats(values: list[float]) -> dict:
    return {"median": round(statistics.median(values), 2), "min": round(min(values), 2)}


def _ratio_stats(values: list[float], over: list[float]) -> dict:
    """Edit by edit `values` ÷ `over`: median and min."""
    ratios = [v / o for v, o in zip(values, over, strict=True)]
    return {"median": round(statistics.median(ratios), 3), "min": round(min(ratios), 3)}


def _minus(values: list[float], *others: list[float]) -> list[float]:
    """Edit by edit: `values` less each of `others`."""
    return [v - sum(rest) for v, *rest in zip(values, *others, strict=True)]


def _surface_node(material):
    """The editable material's BSDF node: Principled, or Diffuse for a region without
    specular (how `support.scene_import` builds them)."""
    nodes = material.node_tree.nodes
    return nodes.get("Principled BSDF") or nodes.get("Diffuse BSDF")


def _edit(node, visit: int) -> None:
    """One slider step: Principled nodes alternate Roughness and Base Color, Diffuse ones
    change Color; each input toggles between two values so every edit changes the image."""
    step = visit // 2 if node.bl_idname == "ShaderNodeBsdfPrincipled" else visit
    if node.bl_idname == "ShaderNodeBsdfPrincipled" and visit % 2 == 0:
        node.inputs["Roughness"].default_value = (0.33, 0.71)[step % 2]
        return
    colour = ((0.61, 0.32, 0.18, 1.0), (0.22, 0.47, 0.66, 1.0))[step % 2]
    node.inputs["Base Color" if "Base Color" in node.inputs else "Color"].default_value = colour


def _upload_floor(width: int, height: int, repeats: int = 10) -> dict:
    """`foreach_set` of a contiguous float32 RGBA buffer into a float image of this size,
    alone: what any add-on pays to put pixels in a Blender image."""
    img = bpy.data.images.new("Relume bench upload", width=width, height=height, alpha=True,
                              float_buffer=True)
    buf = np.random.default_rng(1).random(width * height * 4, dtype=np.float32)
    times = []
    for i in range(repeats + 1):
        buf[0] = i
        t0 = time.perf_counter()
        img.pixels.foreach_set(buf)
        img.update()
        times.append((time.perf_counter() - t0) * 1e3)
    bpy.data.images.remove(img)
    return _stats(times[1:])


def bench_cell(addon, width: int, height: int, k: int, edits: int, workdir: str,
               bounces: int = 1) -> dict:
    import relume

    clear_scene()
    folder = tempfile.mkdtemp(prefix=f"cell-{width}x{height}-k{k}-", dir=workdir)
    bpy.ops.wm.save_as_mainfile(filepath=os.path.join(folder, "bench.blend"))
    scene_file = pathlib.Path(folder) / "cornell8.scene.json"
    scene_file.write_text(json.dumps(make_cornell8.build(0, width, height)))
    import_scene(scene_file, resolution=(width, height))
    names = EDITABLE_ORDER[:k]
    for name in names:  # driven by the shader sliders, as a user edits them
        bpy.data.materials[name].relume.editable = True
        bpy.data.materials[name].relume.override = False
    settings = relume.BakeSettings.preset("draft", resolution_scale=1.0, spp=1, light_samples=1,
                                          indirect_samples=1, bounces=bounces)
    t0 = time.perf_counter()
    addon.api.bake(settings=settings)
    bake_s = time.perf_counter() - t0

    live = addon.runtime.RUNTIME.live
    img = bpy.data.images["Relume"]
    nodes = [_surface_node(bpy.data.materials[name]) for name in names]
    probe = np.empty(width * height * 4, np.float32)
    before = np.empty_like(probe)
    rows = []
    for i in range(WARMUP_EDITS + edits):
        img.pixels.foreach_get(before)
        t0 = time.perf_counter()
        _edit(nodes[i % k], i // k)
        bpy.context.view_layer.update()
        total = (time.perf_counter() - t0) * 1e3
        img.pixels.foreach_get(probe)
        if np.array_equal(before, probe):
            raise RuntimeError(f"edit {i} ({names[i % k]}) did not change the image"
                               f" ({live.relight_error or live.stale_reason or 'no error'})")
        if i >= WARMUP_EDITS:
            rows.append((total, live.relighter.last_ms, live.last_relight_ms,
                         live.last_upload_ms, live.last_latency_ms))
    total, relight, relight_call, upload, relight_now = (list(c) for c in zip(*rows, strict=True))
    overhead = _minus(total, relight)
    cell = {
        "size": [width, height], "k": k, "bounces": bounces, "editable": names,
        "device": live.relighter.device, "layers": live.stack.layer_count,
        "stack_mb": round(live.stack.bytes / 1e6, 1),
        "bake_s": round(bake_s, 1), "edits": edits,
        "edit_to_pixels_ms": _stats(total),
        "relight_ms": _stats(relight),
        "overhead_ms": _stats(overhead),
        "overhead_over_relight": round(statistics.median(overhead) / statistics.median(relight), 3),
        # Edit by edit (the two medians above may come from different edits on a shared
        # machine): min and median of overhead ÷ relight.
        "overhead_over_relight_per_edit": _ratio_stats(overhead, relight),
        "overhead_parts_ms": {
            "image_upload": _stats(upload),
            "relight_call_in_python": _stats(_minus(relight_call, relight)),
            "params_and_rest_of_relight_call": _stats(_minus(relight_now, relight_call, upload)),
            "depsgraph_handler_and_release": _stats(_minus(total, relight_now)),
        },
        "upload_floor_ms": _upload_floor(width, height),
    }
    live.unload()
    return cell


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", default="512x512,1024x1024,1920x1080",
                    help="comma-separated WxH (or W for W×W)")
    ap.add_argument("--k", default="2", help="comma-separated editable-material counts (1–8)")
    ap.add_argument("--edits", type=int, default=30)
    ap.add_argument("--device", default="cpu", choices=["cpu", "gpu", "auto"])
    ap.add_argument("--bounces", type=int, default=1,
                    help="bounces baked (above 1: a tail and its tail-edit layers)")
    args = ap.parse_args()

    addon, prefs = install_addon()
    prefs.device = args.device
    workdir = tempfile.mkdtemp(prefix="relume-bench-")
    cells = [bench_cell(addon, w, h, int(k), args.edits, workdir, args.bounces)
             for w, h in map(_size, args.sizes.split(",")) for k in args.k.split(",")]
    print(json.dumps({
        "benchmark": "edit_to_pixels_latency",
        "scene": "cornell8 (scripts/make_cornell8.py), shader sliders",
        "device": args.device,
        "bpy": bpy.app.version_string,
        "cpu_count": os.cpu_count(),
        "cells": cells,
    }, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
