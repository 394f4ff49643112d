#!/usr/bin/env bash
# Makes (once) the Python environment the cross-checks and the Python
# baseline use: target/py-venv with mcap, mcap-ros2-support and numpy from
# PyPI. Idempotent; prints the venv's python. Used by the tests, so `cargo
# test` needs no manual set-up beyond python3 with venv and network access
# to PyPI (or a wheel mirror configured for pip).
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
venv="${EXO_PY_VENV:-$root/target/py-venv}"
stamp="$venv/.exo-ready-2"
if [ ! -f "$stamp" ]; then
    mkdir -p "$(dirname "$venv")"
    # Another test may be making it: serialise with a lock file.
    exec 9>"$venv.lock"
    flock 9
    if [ ! -f "$stamp" ]; then
        python3 -m venv "$venv" >&2
        "$venv/bin/pip" install --quiet "mcap>=1.1" "mcap-ros2-support>=0.6" "numpy>=1.24" >&2
        touch "$stamp"
    fi
fi
echo "$venv/bin/python"
