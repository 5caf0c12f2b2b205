#!/usr/bin/env bash
# Regenerates core/engine/src/brdf/principled_fit/table.rs: fits the Blinn–Phong closest to
# Cycles' Principled BSDF per roughness row (the ignored test `generate_table`, about 30 s in
# a debug build) and prints the per-row figures that docs/principled_fit.md quotes.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo test -p relume-engine --lib brdf::principled_fit::tests::generate_table -- --ignored --nocapture
cargo fmt --all
