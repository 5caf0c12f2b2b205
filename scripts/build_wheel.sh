#!/usr/bin/env bash
# Builds the relume Python wheel (release, abi3: one wheel for CPython ≥ 3.11, i.e.
# Blender 4.2–5.x) into dist/, prints its path, and copies it into addon/relume/wheels/.
# Installs maturin (pip, user site) when it is missing.
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON="${PYTHON:-python3}"
if ! command -v maturin >/dev/null 2>&1 && ! "$PYTHON" -m maturin --version >/dev/null 2>&1; then
    echo "build_wheel: installing maturin" >&2
    "$PYTHON" -m pip install --user --quiet "maturin>=1.16,<2"
fi
MATURIN=(maturin)
command -v maturin >/dev/null 2>&1 || MATURIN=("$PYTHON" -m maturin)
rm -f dist/relume-*.whl
"${MATURIN[@]}" build --release --manifest-path core/py/Cargo.toml --out dist --interpreter "$PYTHON" >&2
wheel=$(ls -t dist/relume-*.whl | head -n 1)
mkdir -p addon/relume/wheels
rm -f addon/relume/wheels/relume-*.whl
cp "$wheel" addon/relume/wheels/
echo "$wheel"
