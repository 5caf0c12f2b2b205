#!/usr/bin/env bash
# Every test, in this order: the asset checks, style (cargo fmt, clippy, ruff), the wheel
# (manylinux 2_28 at most) and the release workflow's local checks, the Python bindings
# (core/py/tests, on the built wheel), the Blender add-on (blender_tests, on the real `bpy`
# module with the add-on installed from its zip by Blender's extension installer), the Rust
# workspace (unit, integration and CLI tests) and a short fuzzing run of the parsers. Works
# on a fresh machine with the Rust toolchain (with rustfmt and clippy) and Python 3 ≥ 3.11
# with pip: it installs what else it needs (Debian's lavapipe, and bpy, pytest, maturin,
# ziglang, ruff, PyYAML from PyPI).
set -euo pipefail
cd "$(dirname "$0")/.."
# Each stage says when it starts (seconds since the run began), so a slow run shows where
# the time went.
stage() { echo "== [${SECONDS} s] $*"; }
# Mesa's Vulkan drivers (probed by `--device auto`) complain on stderr without it.
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-/tmp/relume-runtime-$(id -u)}"
mkdir -p -m 700 "$XDG_RUNTIME_DIR"
command -v cargo >/dev/null || { echo "test: needs the Rust toolchain (cargo) on PATH" >&2; exit 1; }
# A test run writes its build folders beside the sources (about 6 GiB from a clean clone);
# a full disk shows up as a linker or rustc I/O error far into the run, so say it at the start.
# Incremental artefacts only help repeated local builds, so the run does without them.
export CARGO_INCREMENTAL="${CARGO_INCREMENTAL:-0}"
free_gib=$(df -Pk . | awk 'NR==2 { printf "%d", $4 / 1048576 }')
stage "disk: ${free_gib} GiB free here; a full run from a clean clone needs about ${RELUME_TEST_DISK_GIB:=6} GiB"
[ "$free_gib" -ge "$RELUME_TEST_DISK_GIB" ] || echo "test: warning: less disk free than a full run needs; expect 'No space left on device' from the build" >&2
stage "asset scenes"
python3 assets/build_scenes.py --out assets && git diff --exit-code --stat -- assets/*.scene.json || { echo "assets: committed scene files differ from what build_scenes.py makes" >&2; exit 1; }
stage "Vulkan software driver (lavapipe) for the GPU relight tests"
# The GPU tests run forced on lavapipe (Debian's mesa-vulkan-drivers); without any
# adapter they print SKIPPED and pass, so a machine without apt still runs everything else.
# Where lavapipe is installed an adapter is expected: RELUME_REQUIRE_GPU=1 makes a GPU test
# that finds none fail (a broken driver set-up) instead of skipping.
if dpkg -s mesa-vulkan-drivers >/dev/null 2>&1; then
    echo "mesa-vulkan-drivers: installed"
    export RELUME_REQUIRE_GPU=1
elif command -v apt-get >/dev/null && [ "$(id -u)" = 0 ] \
    && apt-get update -qq >/dev/null 2>&1 \
    && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq mesa-vulkan-drivers >/dev/null 2>&1; then
    echo "mesa-vulkan-drivers: installed now"
    export RELUME_REQUIRE_GPU=1
else
    echo "mesa-vulkan-drivers: could not be installed (no apt, not root, or no network): GPU tests will skip"
fi
stage "Python packages (bpy 5.0.1, pytest, maturin, ziglang, ruff, PyYAML, openjd-cli)"
PYTHON="${PYTHON:-python3}"
"$PYTHON" - <<'PY' || "$PYTHON" -m pip install --quiet --disable-pip-version-check "bpy==5.0.1" "pytest>=7" \
    "maturin>=1.16,<2" "ziglang>=0.13,<0.14" "ruff>=0.8" "PyYAML>=6" "openjd-cli>=0.8"
import importlib.util, sys
missing = [m for m in ("bpy", "pytest", "maturin", "ziglang", "ruff", "yaml", "openjd.cli") if importlib.util.find_spec(m) is None]
sys.exit(1 if missing else 0)
PY
status=0
stage "style: cargo fmt, cargo clippy, ruff, the import graph"
cargo fmt --all --check || { echo "cargo fmt: run 'cargo fmt --all'" >&2; status=1; }
cargo clippy --workspace --all-targets --quiet -- -D warnings || status=1
"$PYTHON" -m ruff check addon blender_tests core/py scripts examples farm || status=1
stage "import graph: no circle in core/engine or addon/relume, nothing below the bake imports it, no file outside the repository cited"
"$PYTHON" scripts/import_graph.py || status=1
stage "the relume wheel and the Blender extension zip"
bash scripts/build_addon.sh
stage "the wheel's platform tag and the release workflow (scripts/check_release.py)"
"$PYTHON" scripts/check_release.py --wheel "$(ls -t dist/relume-*.whl | head -n 1)" || status=1
rm -rf build/py
"$PYTHON" -m pip install --quiet --disable-pip-version-check --no-deps --target build/py dist/relume-*.whl
stage "Python bindings (core/py/tests)"
PYTHONPATH="$PWD/build/py" "$PYTHON" -m pytest -q -p no:cacheprovider core/py/tests || status=1
stage "Blender add-on (blender_tests, bpy $("$PYTHON" -c 'import importlib.metadata as m; print(m.version("bpy"))'))"
"$PYTHON" -m pytest -q -p no:cacheprovider --durations=15 -W ignore::DeprecationWarning blender_tests || status=1
# The Rust tests come after the add-on's: both bake with the Principled basis, which is
# built once and cached (core/engine/src/brdf/principled_basis/cache.rs), and the release
# wheel builds it several times faster than the tests' debug build.
stage "cargo test (workspace)"
cargo test --workspace --no-fail-fast 2>&1 || status=1
# The smoke run: the seed stacks baked by the CLI `cargo test` just built, the targets in
# the fuzz crate's dev profile (scripts/fuzz.sh).
stage "fuzzing: stack reader, scene and materials parsers, 10 s each (scripts/fuzz.sh)"
RELUME_FUZZ_CLI=target/debug/relume RELUME_FUZZ_PROFILE=dev bash scripts/fuzz.sh 10 || status=1
stage "done"
exit $status
