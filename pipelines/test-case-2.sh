#!/usr/bin/env bash
# Paper Test Case II (the experimental article, CAD inertia): three impacts, three
# triaxial accelerometers. Runs the automatic NI selection and the paper's Sets I–V, each
# about Origins I–III (accelerometers 1, 2, 3), with both modal estimators, on the
# noise-free simulation and on the 1 %-noise one (`demo`), and writes MCAP runs, a
# summary CSV, figures and a report under OUT.
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=${BIN:-target/release}
OUT=${1:-out/paper/test-case-2}
rm -rf "$OUT" && mkdir -p "$OUT"

declare -A SETS=(
  [set-I]="1:force2,2:force2,3:force3,4:force3,5:force1,6:force1"
  [set-II]="1:force1,2:force2,3:force3,4:force2,5:force2,6:force1"
  [set-III]="1:force1,2:force2,3:force3,4:force3,5:force2,6:force1"
  [set-IV]="1:force1,2:force2,3:force3,4:force3,5:force1,6:force3"
  [set-V]="1:force1,2:force3,3:force3,4:force3,5:force1,6:force1"
)

for example in test-case-2 demo; do
  D="$OUT/$example"
  mkdir -p "$D/figures"
  "$BIN/frf-sim" --example $example --plot "$D/figures/frf" \
    | "$BIN/modal-fit" --plot "$D/figures/modal" \
    | tee "$D/fit.mcap" \
    | "$BIN/ni-select" --summary --plot "$D/figures/ni" 2>"$D/ni-summary.txt" \
    | "$BIN/rb-solve" --uncertainty linearised -o "$D/ni.mcap" --format json --method bretl-conti,toivola-nuutila > "$D/ni.json" 2>>"$D/warnings.txt"
  {
    "$BIN/rbprops" summary "$D/ni.mcap" --campaign $example --set ni
    for set in set-I set-II set-III set-IV set-V; do
      "$BIN/ni-select" "$D/fit.mcap" --set "${SETS[$set]}" -o "$D/$set.sel.mcap" 2>>"$D/warnings.txt"
      for origin in 1 2 3; do
        "$BIN/rb-solve" --uncertainty linearised "$D/$set.sel.mcap" --origin $origin --method bretl-conti,toivola-nuutila \
          -o "$D/$set.origin-$origin.mcap" --format json > /dev/null 2>>"$D/warnings.txt"
        "$BIN/rbprops" summary "$D/$set.origin-$origin.mcap" --campaign $example --set $set --origin "accelerometer $origin" | tail -n +2
      done
    done
  } > "$D/summary.csv"
done
{ cat "$OUT/test-case-2/summary.csv"; tail -n +2 "$OUT/demo/summary.csv"; } > "$OUT/summary.csv"
"$BIN/rbprops" report "$OUT/summary.csv" -o "$OUT/report" --title "Test Case II (paper Sec. 3.2)" \
  $(for f in "$OUT"/*/figures/*/*.svg; do printf -- '--figure %s ' "$f"; done)
echo "test case II: $(($(wc -l < "$OUT/summary.csv") - 1)) estimates → $OUT/report/report.md" >&2
