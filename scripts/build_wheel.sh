#!/usr/bin/env bash
# Builds the relume Python wheel (release, abi3: one wheel for CPython ≥ 3.11, i.e.
# Blender 4.2–5.x) into dist/, prints its path, and copies it into addon/relume/wheels/.
# On Linux it links with zig against glibc 2.28 (`--zig --compatibility manylinux_2_28`,
# the glibc Blender's own Linux builds need), so the wheel installs on older desktops than
# the build machine's. Installs maturin and ziglang (pip, user site) when missing.
# Extra arguments go to `maturin build` (the release workflow passes --target).
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON="${PYTHON:-python3}"
if ! command -v maturin >/dev/null 2>&1 && ! "$PYTHON" -m maturin --version >/dev/null 2>&1; then
    echo "build_wheel: installing maturin" >&2
    "$PYTHON" -m pip install --user --quiet "maturin>=1.16,<2"
fi
MATURIN=(maturin)
command -v maturin >/dev/null 2>&1 || MATURIN=("$PYTHON" -m maturin)
PLATFORM_ARGS=()
if [ "$(uname -s)" = Linux ]; then
    if ! "$PYTHON" -c "import ziglang" >/dev/null 2>&1; then
        echo "build_wheel: installing ziglang (< 0.14: 0.14 links UBSan into C code it compiles, PyO3/maturin-action#335)" >&2
        "$PYTHON" -m pip install --user --quiet "ziglang>=0.13,<0.14"
    fi
    PLATFORM_ARGS=(--zig --compatibility manylinux_2_28)
fi
rm -f dist/relume-*.whl
"${MATURIN[@]}" build --release --manifest-path core/py/Cargo.toml --out dist --interpreter "$PYTHON" \
    "${PLATFORM_ARGS[@]}" "$@" >&2
wheel=$(ls -t dist/relume-*.whl | head -n 1)
mkdir -p addon/relume/wheels
rm -f addon/relume/wheels/relume-*.whl
cp "$wheel" addon/relume/wheels/
echo "$wheel"
