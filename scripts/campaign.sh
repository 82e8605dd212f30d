#!/usr/bin/env bash
# Run every campaign spec or recording under DIR in parallel; summary table on stdout
# (or -o FILE). A progress bar is drawn on stderr when it is a terminal.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release -q -p rbprops-cli
exec target/release/rbprops campaign "$@"
