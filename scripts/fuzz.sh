#!/usr/bin/env bash
# Fuzzes Relume's three parsers with cargo fuzz (libFuzzer): the stack reader, the scene
# file and the materials file. Usage: bash scripts/fuzz.sh [SECONDS_PER_TARGET] (default 60;
# scripts/test.sh runs 20 s each; docs/reliability.md records the long runs).
# libFuzzer counts any single allocation over -malloc_limit_mb as a crash, so a reader that
# preallocates what a hostile header claims fails here. Installs cargo-fuzz when missing; the
# toolchain is stable, so the sanitizer flags need RUSTC_BOOTSTRAP=1.
set -euo pipefail
cd "$(dirname "$0")/.."
SECONDS_PER_TARGET="${1:-60}"
command -v cargo-fuzz >/dev/null || cargo install --locked --quiet cargo-fuzz
export RUSTC_BOOTSTRAP=1
# The seed stacks are baked by the release CLI (built by the demo and the wheel anyway).
cargo build --release --quiet -p relume-cli
python3 scripts/fuzz_corpus.py --relume target/release/relume
status=0
for target in stack_reader scene_parser materials_parser; do
    echo "== fuzz $target for ${SECONDS_PER_TARGET} s"
    (cd fuzz && cargo fuzz run --sanitizer address "$target" "corpus/$target" -- \
        -max_total_time="$SECONDS_PER_TARGET" -rss_limit_mb=2048 -malloc_limit_mb=1024 \
        -print_final_stats=1 2>&1 | grep -E "^(stat::|==|#[0-9]+ *DONE|.*(ERROR|panicked|crash))" ) || status=1
done
exit $status
