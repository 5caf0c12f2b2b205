#!/usr/bin/env bash
# OpenImageDenoise on a GPU against its CPU device, through the release CLI: the shown
# image's cost per size (`relume bench denoise`, OIDN's default device and its CPU device),
# a real 512² and 1920×1080 relight through OIDN's default device, and how far the GPU's
# denoised image is from the CPU's. Prints JSON lines and the bake's summary.
# Usage: RELUME=path/to/relume RELUME_OIDN_LIBRARY=path/to/oidn/lib bash scripts/oidn_gpu_check.sh
# (the bpy wheel's `bpy/lib` holds OIDN with its CUDA, HIP and SYCL devices; docs/denoise.md).
set -u
R="${RELUME:-target/release/relume}"
S=assets/cornell.scene.json
T="$(mktemp -d)"
log() { echo "== $*"; }
for q in high balanced; do
    log "bench denoise, OIDN's default device, $q"
    $R bench denoise $S --repeats 10 --quality $q --json
done
log "bench denoise, OIDN's CPU device, high"
$R bench denoise $S --repeats 3 --cpu --quality high --json
log "bake 512² (preview)"
$R bake $S -o "$T/c.exr" --preset preview --resolution 512x512 2>&1 | tail -1
$R bench relight "$T/c.exr" --device gpu --repeats 20 --json
log "relight + OIDN: default device, then forced to the CPU (OIDN_DEFAULT_DEVICE=cpu)"
$R relight "$T/c.exr" --scene $S -o "$T/default.exr" --device gpu --denoise oidn --json
OIDN_DEFAULT_DEVICE=cpu $R relight "$T/c.exr" --scene $S -o "$T/cpu.exr" --device gpu --denoise oidn --json
$R relight "$T/c.exr" -o "$T/raw.exr" --device gpu --denoise none --json > /dev/null
log "the default device's image against the CPU device's, and against the raw relight"
$R compare "$T/default.exr" "$T/cpu.exr" --json
$R compare "$T/raw.exr" "$T/default.exr" --json
log "bake 1920×1080 (preview), relight + OIDN three times"
$R bake $S -o "$T/h.exr" --preset preview --resolution 1920x1080 2>&1 | tail -1
for _ in 1 2 3; do $R relight "$T/h.exr" --scene $S -o "$T/h_oidn.exr" --device gpu --denoise oidn --json; echo; done
rm -rf "$T"
