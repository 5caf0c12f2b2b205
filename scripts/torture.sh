#!/usr/bin/env bash
# The full numerical torture matrix (core/engine/tests/engine/torture.rs): every generated extreme
# scene at every preset's own sample counts, both precisions, three seeds, 24×24, relit at
# the extreme edits of every editable material. Prints one JSON line of counts; fails if a
# bake is lost or a stored or relit value is not finite. The test command runs a bounded
# version of the same matrix.
set -euo pipefail
cd "$(dirname "$0")/.."
RELUME_TORTURE=full cargo test --release -p relume-engine --test engine torture -- --ignored --nocapture full_torture_matrix
