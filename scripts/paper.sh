#!/usr/bin/env bash
# Reproduce both of the paper's test cases: tables, figures and reports under out/paper/.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release -q -p rbprops-cli
start=$(date +%s%N)
pipelines/test-case-1.sh out/paper/test-case-1
pipelines/test-case-2.sh out/paper/test-case-2
echo "paper: regenerated in $(( ($(date +%s%N) - start) / 1000000 )) ms (build excluded)" >&2
