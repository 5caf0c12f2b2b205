#!/usr/bin/env bash
# The demo: build Relume, bake the Cornell scene at the preview preset, relight a sweep of
# material edits into out/, and print timings. Works on a fresh machine with the Rust
# toolchain and Python 3 (installs nothing else).
set -euo pipefail
cd "$(dirname "$0")/.."
# Mesa's Vulkan drivers (probed by `--device auto`) complain on stderr without it.
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-/tmp/relume-runtime-$(id -u)}"
mkdir -p -m 700 "$XDG_RUNTIME_DIR"
t0=$(date +%s.%N)
elapsed() { python3 -c "import sys; print(f'{float(sys.argv[2]) - float(sys.argv[1]):.1f}')" "$1" "$(date +%s.%N)"; }

command -v cargo >/dev/null || { echo "demo: needs the Rust toolchain (cargo) on PATH" >&2; exit 1; }
command -v python3 >/dev/null || { echo "demo: needs python3" >&2; exit 1; }

echo "== building (release)"
cargo build --release -p relume-cli --quiet
relume="$(cargo metadata --format-version 1 --no-deps | python3 -c 'import json, sys; print(json.load(sys.stdin)["target_directory"])')/release/relume"
echo "   built in $(elapsed "$t0") s"

echo "== generating the asset scenes"
python3 assets/build_scenes.py --out assets cornell >/dev/null

mkdir -p out
res=${RELUME_DEMO_RESOLUTION:-512x512}
echo "== baking assets/cornell.scene.json at $res (preview: 16 spp, 4 light samples, one bounce, N_b = 6)"
tb=$(date +%s.%N)
$relume bake assets/cornell.scene.json -o out/cornell.stack.exr --resolution "$res" --spp 16 --light-samples 4 --json > out/bake.json
echo "   bake: $(elapsed "$tb") s  ($(python3 -c "import json; r=json.load(open('out/bake.json')); print(f\"{r['layers']} layers, {r['file_bytes']/1e6:.1f} MB, {r['report']['rays_per_second']/1e6:.2f} Mrays/s\")"))"

echo "== relighting a sweep of material edits"
python3 scripts/material_sweep.py out/sweep
n=0
for m in out/sweep/*.json; do
  name=$(basename "$m" .json)
  $relume relight out/cornell.stack.exr --materials "$m" -o "out/$name.exr" --png "out/$name.png" --json >> out/relight.jsonl
  n=$((n + 1))
done
python3 - <<'PY'
import json
rows = [json.loads(l) for l in open("out/relight.jsonl")]
ms = sorted(r["relight_ms"] for r in rows)
print(f"   {len(rows)} frames relit on the CPU: median {ms[len(ms)//2]:.2f} ms, max {ms[-1]:.2f} ms per frame (plus stack load {rows[0]['load_seconds']*1e3:.0f} ms per process)")
PY
rm -f out/relight.jsonl
echo "== done in $(elapsed "$t0") s: out/*.png (sRGB previews) and out/*.exr (scene-linear)"
