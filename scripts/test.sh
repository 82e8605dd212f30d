#!/usr/bin/env bash
# The project's test command (README, .ci/run and `just test` all call this).
# Uses cargo-nextest when installed, plain `cargo test` otherwise.
set -euo pipefail
cd "$(dirname "$0")/.."
if cargo nextest --version >/dev/null 2>&1; then
  cargo nextest run --workspace --no-fail-fast "$@"
  cargo test --workspace --doc
else
  cargo test --workspace --no-fail-fast "$@"
fi
