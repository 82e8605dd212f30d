#!/usr/bin/env bash
# The project's test command (README, .ci/run and `just test` all call this).
# Uses cargo-nextest when installed, plain `cargo test` otherwise. Arguments go to
# `cargo nextest run`: `scripts/test.sh` runs nextest's `default` profile (the quick
# run, without the few end-to-end model-check tests listed in .config/nextest.toml),
# `scripts/test.sh --profile ci` runs every test that is not #[ignore]d (what CI runs).
set -euo pipefail
cd "$(dirname "$0")/.."
if cargo nextest --version >/dev/null 2>&1; then
  cargo nextest run --workspace --no-fail-fast "$@"
  cargo test --workspace --doc
else
  # `cargo test` knows no nextest profile: it runs every test that is not ignored, as
  # the `ci` profile does, so `--profile NAME` is dropped; other arguments pass through.
  args=()
  skip_value=0
  for a in "$@"; do
    if [ "$skip_value" = 1 ]; then skip_value=0; continue; fi
    case "$a" in
      --profile) skip_value=1 ;;
      --profile=*) ;;
      *) args+=("$a") ;;
    esac
  done
  echo "cargo-nextest not found: running every test that is not ignored with cargo test" >&2
  cargo test --workspace --no-fail-fast ${args[@]+"${args[@]}"}
fi
# The reference generator's own exact tests (Python with numpy and pyuff; 4–10 s).
PY="${RBPROPS_PYTHON:-python3}"
if "$PY" -c "import numpy, pyuff" 2>/dev/null; then
  # With the frf-sim just built, they also compare the two simulators (Test Case II,
  # gravity stiffness and 19 effect fixtures).
  FRF_SIM="${CARGO_TARGET_DIR:-target}/debug/frf-sim"
  if [ -x "$FRF_SIM" ]; then
    export RBPROPS_FRF_SIM="$FRF_SIM"
  elif [ -n "${RBPROPS_REQUIRE_PYTHON:-}" ]; then
    # CI requires every cross-check it can run: the simulator comparisons need frf-sim.
    echo "error: $FRF_SIM not built: the generator's comparisons with frf-sim cannot run" >&2
    exit 1
  fi
  if [ -n "${RBPROPS_REQUIRE_PYTHON:-}" ]; then
    # And each comparison fails, rather than skips, if the binary goes missing.
    export RBPROPS_REQUIRE_FRF_SIM=1
  fi
  "$PY" scripts/refgen/test_rbref.py
elif [ -n "${RBPROPS_REQUIRE_PYTHON:-}" ]; then
  echo "error: $PY lacks numpy/pyuff, needed by scripts/refgen/test_rbref.py" >&2
  exit 1
else
  echo "skipping scripts/refgen/test_rbref.py: $PY lacks numpy/pyuff (set RBPROPS_REQUIRE_PYTHON=1 to make this fatal)" >&2
fi
