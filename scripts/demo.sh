#!/usr/bin/env bash
# The demo: build Relume, bake the Cornell scene with the preview preset (denoised), relight
# a sweep of material edits into out/, draw them on one contact sheet
# (out/contact_sheet.png), and print timings. Works on a fresh machine with the Rust
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
cargo build --release -p relume-cli --bins --example contact_sheet --quiet
relume="$(cargo metadata --format-version 1 --no-deps | python3 -c 'import json, sys; print(json.load(sys.stdin)["target_directory"])')/release/relume"
echo "   built in $(elapsed "$t0") s"

echo "== generating the asset scenes"
python3 assets/build_scenes.py --out assets cornell >/dev/null

mkdir -p out
res=${RELUME_DEMO_RESOLUTION:-512x512}
echo "== baking assets/cornell.scene.json at $res with --preset preview (16 spp x 4 light x 4 indirect samples, guided, denoised; one bounce, so every edit of the sweep relights exactly)"
tb=$(date +%s.%N)
$relume bake assets/cornell.scene.json -o out/cornell.stack.exr --preset preview --bounces 1 --resolution "$res" --json > out/bake.json
echo "   bake: $(elapsed "$tb") s  ($(python3 -c "import json; r=json.load(open('out/bake.json')); b=r['report']; print(f\"bake {b['seconds']:.1f} s of which denoise {b['denoise_seconds']:.1f} s, {r['layers']} layers, {r['file_bytes']/1e6:.1f} MB, {b['rays_per_second']/1e6:.2f} Mrays/s\")"))"

echo "== relighting a sweep of material edits"
python3 scripts/material_sweep.py out/sweep
n=0
for m in out/sweep/frame_*.json; do
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

echo "== contact sheet"
frames=()
while IFS= read -r line; do frames+=("$line"); done < <(python3 -c 'import json; [print(f"out/{k}.png={v}") for k, v in json.load(open("out/sweep/captions.json")).items()]')
sheet=$("$(dirname "$relume")/examples/contact_sheet" out/contact_sheet.png --columns 5 --tile 256 \
    --title "Cornell, one preview bake ($(python3 -c "import json; print(f\"{json.load(open('out/bake.json'))['report']['seconds']:.1f}\")") s), relit for $n material sets" "${frames[@]}")
echo "   $sheet"
echo "== done in $(elapsed "$t0") s"
echo "   out/contact_sheet.png   the sweep on one page (look at this first)"
echo "   out/frame_*.png         the $n relit frames (sRGB), out/frame_*.exr the same in scene-linear float"
echo "   out/cornell.stack.exr   the transfer stack (relume relight out/cornell.stack.exr --materials M.json -o X.exr)"
