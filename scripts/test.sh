#!/usr/bin/env bash
# Every test: the Rust workspace (unit, integration and CLI tests) and the asset checks.
# Works on a fresh machine with the Rust toolchain and Python 3.
set -euo pipefail
cd "$(dirname "$0")/.."
command -v cargo >/dev/null || { echo "test: needs the Rust toolchain (cargo) on PATH" >&2; exit 1; }
echo "== asset scenes"
python3 assets/build_scenes.py --out assets && git diff --exit-code --stat -- assets/*.scene.json || { echo "assets: committed scene files differ from what build_scenes.py makes" >&2; exit 1; }
echo "== cargo test (workspace)"
cargo test --workspace --no-fail-fast 2>&1
