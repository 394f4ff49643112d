#!/usr/bin/env bash
# Makes (once) the Python environment the cross-checks and the Python
# baseline and the live-view client use: target/py-venv with mcap,
# mcap-ros2-support, numpy and websockets from
# PyPI. Idempotent; prints the venv's python. Used by the tests, so `cargo
# test` needs no manual set-up beyond network access to PyPI (or a wheel
# mirror configured for pip); python3 and its venv module are installed with
# apt-get when missing and permitted.
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
venv="${EXO_PY_VENV:-$root/target/py-venv}"
stamp="$venv/.exo-ready-3"
if [ ! -f "$stamp" ]; then
    mkdir -p "$(dirname "$venv")"
    # Another test may be making it: serialise with a lock file.
    exec 9>"$venv.lock"
    flock 9
    if [ ! -f "$stamp" ]; then
        # A fresh Debian/Ubuntu machine may lack python3 or its venv module:
        # install them with the system's package manager when we may.
        if ! python3 -c 'import venv, ensurepip' >/dev/null 2>&1; then
            if command -v apt-get >/dev/null 2>&1 && [ "$(id -u)" = 0 ]; then
                echo "ensure_venv: installing python3 and python3-venv with apt-get" >&2
                apt-get update -qq >&2 && apt-get install -y -qq python3 python3-venv >&2
            else
                echo "ensure_venv: python3 with the venv module is needed (e.g. sudo apt-get install python3-venv)" >&2
                exit 1
            fi
        fi
        rm -rf "$venv"
        python3 -m venv "$venv" >&2
        "$venv/bin/pip" install --quiet "mcap>=1.1" "mcap-ros2-support>=0.6" "numpy>=1.24" "websockets>=13" >&2
        touch "$stamp"
    fi
fi
echo "$venv/bin/python"
