#!/usr/bin/env bash
# Fuzzes Relume's three parsers with cargo fuzz (libFuzzer): the stack reader, the scene
# file and the materials file. Usage: bash scripts/fuzz.sh [SECONDS_PER_TARGET] (default 60;
# scripts/test.sh runs 10 s each; docs/reliability.md records the long runs).
# RELUME_FUZZ_PROFILE=dev builds the targets with fuzz/Cargo.toml's dev profile (parsers
# unoptimised: a build minutes shorter, a few times fewer runs a second; the test command's
# smoke run), else the release profile. RELUME_FUZZ_CLI names a relume binary already built
# to bake the seed stacks with (the test command passes the one `cargo test` built), else
# the release CLI is built.
# libFuzzer counts any single allocation over -malloc_limit_mb as a crash, so a reader that
# preallocates what a hostile header claims fails here. Installs cargo-fuzz when missing; the
# toolchain is stable, so the sanitizer flags need RUSTC_BOOTSTRAP=1.
set -euo pipefail
cd "$(dirname "$0")/.."
SECONDS_PER_TARGET="${1:-60}"
command -v cargo-fuzz >/dev/null || cargo install --locked --quiet cargo-fuzz
export RUSTC_BOOTSTRAP=1
RELUME_CLI="${RELUME_FUZZ_CLI:-}"
if [ -z "$RELUME_CLI" ]; then
    cargo build --release --quiet -p relume-cli
    RELUME_CLI=target/release/relume
fi
python3 scripts/fuzz_corpus.py --relume "$RELUME_CLI"
PROFILE_ARGS=()
if [ "${RELUME_FUZZ_PROFILE:-release}" = dev ]; then PROFILE_ARGS=(--dev); fi
status=0
for target in stack_reader scene_parser materials_parser; do
    echo "== fuzz $target for ${SECONDS_PER_TARGET} s"
    (cd fuzz && cargo fuzz run "${PROFILE_ARGS[@]}" --sanitizer address "$target" "corpus/$target" -- \
        -max_total_time="$SECONDS_PER_TARGET" -rss_limit_mb=2048 -malloc_limit_mb=1024 \
        -print_final_stats=1 2>&1 | grep -E "^(stat::|==|#[0-9]+ *DONE|.*(ERROR|panicked|crash))" ) || status=1
done
exit $status
