"""Bake a .blend's Relume stack on a farm, from Blender: export → farm → the stack folder.

    blender -b scene.blend --python examples/blender_farm_bake.py -- \
        --partitions 8 --options "--preset final" [--scheduler tcp://head:8786 --workdir /shared/x]
    python examples/blender_farm_bake.py --blend scene.blend ...        (bpy module)

1. Exports the scene with the add-on's `bpy.ops.relume.export_scene` (textures go beside it)
   into --workdir (default: a folder next to the .blend, "<name>_relume_farm").
2. Runs the farm driver (farm/dask_bake.py: guide → N partitions → merge) on a Dask
   cluster: the one at --scheduler, or a LocalCluster of --workers processes. Workers need
   `relume` (--relume) and must see --workdir. For Deadline Cloud or Flamenco instead,
   submit farm/openjd/relume-bake.template.yaml or farm/flamenco/relume-bake.js with the
   exported scene file and wait for the stack (docs/farm.md); step 3 is the same.
3. Copies the merged stack into the .blend's stack folder (where the add-on's Bake button
   writes it: `stack_location`), atomically, and loads it: the Image Editor's Relume panel
   then relights it; a stack that does not match the scene is reported stale, as always.

The stack is bit-identical to a one-machine `relume bake` of the exported scene with the same
options. The add-on must be installed; --addon-zip installs it first (bpy module).
Untested here end to end inside Blender (the pieces are: the farm driver by its benchmark and
the farm tests, the exporter by blender_tests); see docs/farm.md.
"""

from __future__ import annotations

import argparse
import importlib
import os
import shlex
import shutil
import sys

import bpy

ADDON = "bl_ext.user_default.relume"
REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _args(argv):
    ap = argparse.ArgumentParser(description="Relume farm bake of a .blend")
    ap.add_argument("--blend", help="the .blend to open (default: the one Blender opened)")
    ap.add_argument("--partitions", type=int, default=4)
    ap.add_argument("--options", default="--preset preview", help="relume bake options")
    ap.add_argument("--scheduler", help="Dask scheduler address (default: a local cluster)")
    ap.add_argument("--workers", type=int, default=2, help="local cluster processes")
    ap.add_argument("--workdir", help="shared folder for the scene, guide and parts")
    ap.add_argument("--relume", default="relume", help="the relume binary on the workers")
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
    addon = _ensure_addon(args.addon_zip)
    blend = bpy.data.filepath or os.path.join(os.getcwd(), "untitled.blend")
    workdir = os.path.abspath(args.workdir or os.path.splitext(blend)[0] + "_relume_farm")
    os.makedirs(workdir, exist_ok=True)

    # 1. Export (the add-on's operator: warnings are reported as for the Bake button).
    scene_file = os.path.join(workdir, "scene.scene.json")
    if bpy.ops.relume.export_scene(filepath=scene_file) != {"FINISHED"}:
        print("Relume farm: export failed", file=sys.stderr)
        return 1

    # 2. The farm: guide → partitions → merge, with progress; Ctrl-C cancels.
    sys.path.insert(0, os.path.join(REPO, "farm"))
    import dask_bake

    client = None
    if args.scheduler:
        from distributed import Client

        client = Client(args.scheduler)
    merged = os.path.join(workdir, "merged.exr")

    def progress(done, total, summary):
        print(f"Relume farm: {done}/{total} partitions ({summary['seconds']:.1f} s the last)")

    try:
        report = dask_bake.bake_on_dask(
            scene_file, merged, args.partitions, shlex.split(args.options), client=client,
            workers=args.workers, relume=args.relume, workdir=workdir, on_progress=progress,
        )
    except KeyboardInterrupt:
        print("Relume farm: cancelled; the .blend's stack is unchanged", file=sys.stderr)
        return 130

    # 3. Into the stack folder, atomically (copy beside the target, then rename over it).
    stack_location = importlib.import_module(ADDON + ".stack_location").stack_location
    stack_path, _, temporary = stack_location(bpy.context)
    os.makedirs(os.path.dirname(stack_path), exist_ok=True)
    tmp = stack_path + ".farm-tmp"
    shutil.copyfile(merged, tmp)
    os.replace(tmp, stack_path)
    loaded = addon.api.load_stack()
    status = addon.api.status()
    print(f"Relume farm: {args.partitions} partitions in {report['wall_seconds']:.1f} s → "
          f"{stack_path}{' (temporary folder: save the .blend to keep it)' if temporary else ''}; "
          f"loaded: {loaded}, stale: {status.get('stale')}")
    return 0 if loaded else 1


if __name__ == "__main__":
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]
    sys.exit(main(argv))
