#!/usr/bin/env bash
# Runs the whole pipeline on the built-in default campaign (`demo`: the paper's Test
# Case II with 1 % noise) and prints the inertia estimates. Needs only the Rust toolchain.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release -q -p rbprops-cli
bin=target/release
"$bin/frf-sim" --example "${1:-demo}" \
  | "$bin/modal-fit" \
  | "$bin/ni-select" \
  | "$bin/rb-solve" --format table
