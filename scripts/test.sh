#!/usr/bin/env bash
# Every test: the Rust workspace (unit, integration and CLI tests) and the asset checks.
# Works on a fresh machine with the Rust toolchain and Python 3.
set -euo pipefail
cd "$(dirname "$0")/.."
# Mesa's Vulkan drivers (probed by `--device auto`) complain on stderr without it.
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-/tmp/relume-runtime-$(id -u)}"
mkdir -p -m 700 "$XDG_RUNTIME_DIR"
command -v cargo >/dev/null || { echo "test: needs the Rust toolchain (cargo) on PATH" >&2; exit 1; }
echo "== asset scenes"
python3 assets/build_scenes.py --out assets && git diff --exit-code --stat -- assets/*.scene.json || { echo "assets: committed scene files differ from what build_scenes.py makes" >&2; exit 1; }
echo "== Vulkan software driver (lavapipe) for the GPU relight tests"
# The GPU tests run forced on lavapipe (Debian's mesa-vulkan-drivers); without any
# adapter they print SKIPPED and pass, so a machine without apt still runs everything else.
if dpkg -s mesa-vulkan-drivers >/dev/null 2>&1; then
    echo "mesa-vulkan-drivers: installed"
elif command -v apt-get >/dev/null && [ "$(id -u)" = 0 ] \
    && apt-get update -qq >/dev/null 2>&1 \
    && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq mesa-vulkan-drivers >/dev/null 2>&1; then
    echo "mesa-vulkan-drivers: installed now"
else
    echo "mesa-vulkan-drivers: could not be installed (no apt, not root, or no network): GPU tests will skip"
fi
echo "== cargo test (workspace)"
cargo test --workspace --no-fail-fast 2>&1
