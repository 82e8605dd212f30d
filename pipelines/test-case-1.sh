#!/usr/bin/env bash
# Paper Test Case I (numerical): set-ups A (F0x, F0y, F0z) and B (F1x, F2y), no noise.
# Runs the automatic NI selection, the paper's Set 1 (set-up A) and Set 2 (set-up B), and
# force F2y alone (Toivola–Nuutila only: it excites five modes), and writes the MCAP of
# every run, a summary CSV, the figures and a one-page report under OUT.
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=${BIN:-target/release}
OUT=${1:-out/paper/test-case-1}
rm -rf "$OUT" && mkdir -p "$OUT/figures"
CASE=test-case-1

# Simulate and identify once; every set starts from the identified modes.
"$BIN/frf-sim" --example $CASE --plot "$OUT/figures/frf" \
  | "$BIN/modal-fit" --plot "$OUT/figures/modal" \
  | tee "$OUT/fit.mcap" \
  | "$BIN/ni-select" --summary --plot "$OUT/figures/ni" 2>"$OUT/ni-summary.txt" \
  | "$BIN/rb-solve" --uncertainty linearised -o "$OUT/ni.mcap" --format json --method bretl-conti,toivola-nuutila --plot "$OUT/figures/estimates" > "$OUT/ni.json"

run_set() { # label setup manual-set
  "$BIN/ni-select" "$OUT/fit.mcap" --setup "$2" --set "$3" 2>>"$OUT/warnings.txt" \
    | "$BIN/rb-solve" --uncertainty linearised -o "$OUT/$1.mcap" --format json --method bretl-conti,toivola-nuutila > "$OUT/$1.json" 2>>"$OUT/warnings.txt"
  "$BIN/rbprops" summary "$OUT/$1.mcap" --campaign $CASE --set "$1"
}

{
  "$BIN/rbprops" summary "$OUT/ni.mcap" --campaign $CASE --set ni
  run_set set1 A "1:F0x,3:F0x,5:F0y,6:F0y,2:F0z,4:F0z" | tail -n +2
  run_set set2 B "1:F1x,4:F1x,2:F2y,3:F2y,5:F2y,6:F2y" | tail -n +2
  run_set F2y B "1:F2y,2:F2y,3:F2y,5:F2y,6:F2y" | tail -n +2
} > "$OUT/summary.csv"

"$BIN/rbprops" report "$OUT/summary.csv" -o "$OUT/report" --title "Test Case I (paper Sec. 3.1)" \
  $(for f in "$OUT"/figures/*/*.svg; do printf -- '--figure %s ' "$f"; done)
echo "test case I: $(($(wc -l < "$OUT/summary.csv") - 1)) estimates → $OUT/report/report.md" >&2
