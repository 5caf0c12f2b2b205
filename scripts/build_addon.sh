#!/usr/bin/env bash
# Builds the installable Blender extension: the Relume wheel (core/py, release) and the
# add-on zip with it bundled. Prints the zip's path on its last line.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build_wheel.sh >&2
python3 scripts/build_addon.py --out dist
