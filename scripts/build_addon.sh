#!/usr/bin/env bash
# Builds the installable Blender extension: the Relume wheel (core/py, release) and the
# add-on zip with it bundled (dist/relume-VERSION-PLATFORM.zip, the platform the wheel is
# for: linux-x64 here). Prints the zip's path on its last line. Arguments go to
# build_addon.py (e.g. --platform).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build_wheel.sh >&2
rm -f dist/relume-*.zip
python3 scripts/build_addon.py --out dist "$@"
