"""Render a sweep of material edits with Relume, without the UI.

    blender -b scene.blend --python examples/batch_sweep.py -- \
        --material Floor --input Roughness --values 0.1,0.3,0.6,0.9 --out out/sweep
    python examples/batch_sweep.py --blend scene.blend --material Floor ...   (bpy module)

Bakes once if the scene has no usable stack (or with --bake), then for each value sets the
material's Principled input and writes the relit frame (EXR, scene-linear; --png adds an
sRGB PNG). The Relume add-on must be installed; --addon-zip installs it first (bpy module).
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
import time

import bpy

ADDON = "bl_ext.user_default.relume"


def _args(argv):
    ap = argparse.ArgumentParser(description="Relume batch sweep of one material input")
    ap.add_argument("--blend", help="the .blend to open (default: the one Blender opened)")
    ap.add_argument("--material", required=True)
    ap.add_argument("--input", default="Roughness", help="Principled BSDF input name")
    ap.add_argument("--values", required=True, help="comma-separated values")
    ap.add_argument("--out", required=True, help="output folder")
    ap.add_argument("--png", action="store_true", help="also write sRGB PNGs")
    ap.add_argument("--bake", action="store_true", help="rebake even if a valid stack exists")
    ap.add_argument("--addon-zip", help="install the Relume extension from this zip first")
    return ap.parse_args(argv)


def _ensure_addon(zip_path):
    if ADDON not in bpy.context.preferences.addons:
        if zip_path:
            bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default",
                                                     enable_on_install=True)
        else:
            bpy.ops.preferences.addon_enable(module=ADDON)
    return importlib.import_module(ADDON)


def main(argv) -> int:
    args = _args(argv)
    if args.blend:
        bpy.ops.wm.open_mainfile(filepath=os.path.abspath(args.blend))
    relume_addon = _ensure_addon(args.addon_zip)
    api = relume_addon.api
    if args.bake or not api.load_stack():
        print(f"Relume batch: baking ({api.status()['load_error'] or api.status()['stale'] or 'forced'})")
        api.bake()
    material = bpy.data.materials[args.material]
    node = next(n for n in material.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    socket = node.inputs[args.input]
    os.makedirs(args.out, exist_ok=True)
    for i, value in enumerate(float(v) for v in args.values.split(",")):
        socket.default_value = value
        t0 = time.perf_counter()
        stem = os.path.join(args.out, f"{args.material}_{args.input.replace(' ', '_')}_{i:03d}")
        api.render(stem + ".exr", check_stale=(i == 0))
        if args.png:
            api.render(stem + ".png", check_stale=False)
        print(f"Relume batch: {args.input} = {value:g} → {stem}.exr "
              f"({(time.perf_counter() - t0) * 1e3:.1f} ms)")
    return 0


if __name__ == "__main__":
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]
    sys.exit(main(argv))
