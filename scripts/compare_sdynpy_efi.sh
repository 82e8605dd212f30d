#!/usr/bin/env bash
# rbprops plan against SDynPy's Effective Independence layout and the paper's layout on
# Test Case II (see compare_sdynpy_efi.py). Installs SDynPy 0.24 into its own venv
# (Python 3.12 from pyenv: SDynPy 0.24 needs it); if that fails, prints the error and
# runs the script's stand-in EfI, labelled as such in every line of the result.
#
# usage: scripts/compare_sdynpy_efi.sh [SEEDS] [OUT_DIR]
set -euo pipefail
seeds=${1:-200}
out=${2:-$(mktemp -d)}
venv=${SDYNPY_VENV:-/tmp/venv-sdynpy}
here=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$out"
# SDynPy imports Qt and matplotlib; no display here.
export QT_QPA_PLATFORM=offscreen MPLBACKEND=Agg
standin=()
if [ ! -x "$venv/bin/python" ] || ! "$venv/bin/python" -c "import sdynpy" 2>/dev/null; then
    py=$(ls -d "$(pyenv root 2>/dev/null || echo ~/.pyenv)"/versions/3.12.*/bin/python 2>/dev/null | tail -1)
    if [ -z "$py" ]; then
        echo "no Python 3.12 under pyenv: SDynPy 0.24 cannot be installed; stand-in EfI" >&2
        standin=(--standin)
        venv=""
    elif ! { "$py" -m venv "$venv" && "$venv/bin/pip" install -q "sdynpy==0.24.*"; } 2>"$out/pip.err"; then
        echo "SDynPy install failed (stand-in EfI used):" >&2
        cat "$out/pip.err" >&2
        standin=(--standin)
    fi
fi
python=$venv/bin/python
if [ ${#standin[@]} -gt 0 ]; then
    # The stand-in needs only numpy: the project's venv (docs: /tmp/venv) or the system's.
    python=$( [ -x /tmp/venv/bin/python ] && echo /tmp/venv/bin/python || echo python3 )
fi
exec "$python" "$here/compare_sdynpy_efi.py" --seeds "$seeds" --out "$out" "${standin[@]}"
