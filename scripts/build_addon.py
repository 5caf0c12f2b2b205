#!/usr/bin/env python3
"""Zip addon/relume into an installable Blender extension, with the Relume wheel bundled.

The manifest's `wheels` list names the wheel file, whose name carries the version and
platform tags, so it is written here from what `scripts/build_wheel.sh` left in
addon/relume/wheels/ instead of being kept by hand. Usage: build_addon.py [--out DIR]
"""

from __future__ import annotations

import argparse
import pathlib
import sys
import zipfile

ROOT = pathlib.Path(__file__).resolve().parent.parent
ADDON = ROOT / "addon" / "relume"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(ROOT / "dist"))
    args = ap.parse_args()
    wheels = sorted((ADDON / "wheels").glob("*.whl"))
    if not wheels:
        print("build_addon: no wheel in addon/relume/wheels/ (run scripts/build_wheel.sh first)",
              file=sys.stderr)
        return 1
    if len(wheels) > 1:
        print(f"build_addon: several wheels in addon/relume/wheels/: {[w.name for w in wheels]}; "
              "keep one", file=sys.stderr)
        return 1
    manifest = (ADDON / "blender_manifest.toml").read_text()
    version = next(line.split("=", 1)[1].strip().strip('"') for line in manifest.splitlines()
                   if line.startswith("version"))
    # Top-level keys must precede the first [table] (here [permissions]) in TOML.
    wheels_line = f'wheels = ["./wheels/{wheels[0].name}"]\n'
    head, sep, tables = manifest.partition("\n[")
    manifest = head.rstrip("\n") + "\n" + wheels_line + (sep + tables if sep else "")
    out_dir = pathlib.Path(args.out)
    out_dir.mkdir(parents=True, exist_ok=True)
    out = out_dir / f"relume-{version}.zip"
    tmp = out.with_suffix(".zip.tmp")
    with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as z:
        for path in sorted(ADDON.rglob("*")):
            rel = path.relative_to(ADDON)
            if path.is_dir() or "__pycache__" in rel.parts or path.suffix == ".pyc":
                continue
            if rel.name == "blender_manifest.toml":
                z.writestr(str(rel), manifest)
            else:
                z.write(path, str(rel))
    tmp.replace(out)
    print(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
