#!/usr/bin/env python3
"""Zip addon/relume into an installable Blender extension, with the Relume wheel bundled.

The manifest's `wheels` and `platforms` are written here from the wheel that
`scripts/build_wheel.sh` left in addon/relume/wheels/ (its file name carries the version and
platform tags), instead of being kept by hand: one zip per platform, as Blender's
`extension build --split-platforms` would make, named relume-VERSION-PLATFORM.zip.

Usage: build_addon.py [--out DIR] [--platform PLATFORM] [--manifest-only]
  --platform       the Blender platform of the zip (windows-x64, windows-arm64, macos-arm64,
                   macos-x64, linux-x64); default: the wheel's. It must match the wheel's tag.
  --manifest-only  print the manifest for --platform (no wheel needed; a placeholder wheel
                   name of that platform) and write no zip: for scripts/check_release.py.
"""

from __future__ import annotations

import argparse
import pathlib
import re
import sys
import zipfile

ROOT = pathlib.Path(__file__).resolve().parent.parent
ADDON = ROOT / "addon" / "relume"

# Blender's extension platform names, and a wheel platform tag of each (as the wheel's file
# name spells it): the tag's pattern, and the tag of the placeholder --manifest-only names.
PLATFORMS = {
    "linux-x64": (r"^(many)?linux.*_x86_64$", "manylinux_2_28_x86_64"),
    "windows-x64": (r"^win_amd64$", "win_amd64"),
    "windows-arm64": (r"^win_arm64$", "win_arm64"),
    "macos-x64": (r"^macosx_\d+_\d+_(x86_64|universal2)$", "macosx_10_12_x86_64"),
    "macos-arm64": (r"^macosx_\d+_\d+_(arm64|universal2)$", "macosx_11_0_arm64"),
}


def wheel_platform_tags(wheel_name: str) -> list[str]:
    """The platform tags of a wheel file name (name-ver-py-abi-plat.whl, plat may be a.b)."""
    stem = wheel_name.removesuffix(".whl")
    return stem.split("-")[-1].split(".")


def platform_of(wheel_name: str) -> str | None:
    """The Blender platform a wheel file serves (the first that all its tags match), or None."""
    tags = wheel_platform_tags(wheel_name)
    for name, (pattern, _) in PLATFORMS.items():
        if all(re.match(pattern, t) for t in tags):
            return name
    return None


def manifest_for(template: str, wheel_name: str, platform: str) -> str:
    """The manifest with `platforms` set to [platform] and `wheels` naming the bundled wheel."""
    lines = [line for line in template.splitlines()
             if not line.startswith(("platforms", "wheels"))]
    text = "\n".join(lines) + "\n"
    extra = f'platforms = ["{platform}"]\nwheels = ["./wheels/{wheel_name}"]\n'
    # Top-level keys must precede the first [table] (here [permissions]) in TOML.
    head, sep, tables = text.partition("\n[")
    return head.rstrip("\n") + "\n" + extra + (sep + tables if sep else "")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(ROOT / "dist"))
    ap.add_argument("--platform", choices=sorted(PLATFORMS))
    ap.add_argument("--manifest-only", action="store_true")
    args = ap.parse_args()
    template = (ADDON / "blender_manifest.toml").read_text()
    version = next(line.split("=", 1)[1].strip().strip('"') for line in template.splitlines()
                   if line.startswith("version"))
    if args.manifest_only:
        if not args.platform:
            print("build_addon: --manifest-only needs --platform", file=sys.stderr)
            return 2
        placeholder = f"relume-{version}-cp311-abi3-{PLATFORMS[args.platform][1]}.whl"
        sys.stdout.write(manifest_for(template, placeholder, args.platform))
        return 0
    wheels = sorted((ADDON / "wheels").glob("*.whl"))
    if not wheels:
        print("build_addon: no wheel in addon/relume/wheels/ (run scripts/build_wheel.sh first)",
              file=sys.stderr)
        return 1
    if len(wheels) > 1:
        print(f"build_addon: several wheels in addon/relume/wheels/: {[w.name for w in wheels]}; "
              "keep one", file=sys.stderr)
        return 1
    wheel = wheels[0].name
    served = platform_of(wheel)
    platform = args.platform or served
    if platform is None or platform != served:
        print(f"build_addon: the wheel {wheel} is for {served or 'no Blender platform'}, "
              f"not {platform}", file=sys.stderr)
        return 1
    manifest = manifest_for(template, wheel, platform)
    out_dir = pathlib.Path(args.out)
    out_dir.mkdir(parents=True, exist_ok=True)
    out = out_dir / f"relume-{version}-{platform}.zip"
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
