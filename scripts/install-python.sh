#!/usr/bin/env bash
# Builds and installs legwork's Python package (python/, pyo3 + maturin) with the tests'
# dependencies into a virtual environment, `.venv-python/` at the repository root
# (git-ignored; `LEGWORK_PYTHON_VENV` overrides the location). Idempotent: the pinned
# packages are installed once (a stamp file records them), and the package is rebuilt by
# `pip install ./python`, which cargo makes incremental (target/ is shared with the crate).
# A user's own install is just `pip install ./python` (README).
set -euo pipefail
cd "$(dirname "$0")/.."

# numpy as the MuJoCo checker's; MuJoCo 4.0.0 as legwork's MuJoCo targets; Ray and pandas
# for the sweeps; pytest for the tests; maturin to build.
PINS=("maturin==1.16.0" "numpy==2.3.5" "mujoco==4.0.0" "ray==2.60.0" "pandas==3.1.1" "pytest==9.2.0")
VENV="${LEGWORK_PYTHON_VENV:-.venv-python}"
STAMP="$VENV/legwork-stamp"
WANT="${PINS[*]}"

PYTHON="${PYTHON:-}"
if [ -z "$PYTHON" ]; then
    for candidate in python3 python; do
        if command -v "$candidate" >/dev/null 2>&1; then PYTHON="$candidate"; break; fi
    done
fi
if [ -z "$PYTHON" ]; then
    echo "install-python: no python3 on PATH; install Python 3.9+ (with venv) first" >&2
    exit 1
fi

if ! [ -f "$STAMP" ] || [ "$(cat "$STAMP")" != "$WANT" ] || ! [ -x "$VENV/bin/python" ]; then
    if ! "$PYTHON" -c "import venv, ensurepip" >/dev/null 2>&1; then
        # Debian splits venv/ensurepip off python3 into python3-venv.
        if command -v apt-get >/dev/null 2>&1; then
            SUDO=()
            if [ "$(id -u)" -ne 0 ]; then SUDO=(sudo); fi
            echo "install-python: $PYTHON has no venv module; installing python3-venv with apt-get"
            source scripts/apt-wait.sh
            apt_get update -q
            apt_get install -y -q --no-install-recommends python3-venv
        else
            echo "install-python: $PYTHON has no venv module and apt-get is not available" >&2
            exit 1
        fi
    fi
    echo "install-python: creating $VENV with $WANT"
    rm -rf "$VENV"
    "$PYTHON" -m venv "$VENV"
    "$VENV/bin/python" -m pip install -q --disable-pip-version-check "${PINS[@]}"
    echo "$WANT" > "$STAMP"
else
    echo "install-python: $VENV already has $WANT"
fi

# The package itself, from this checkout: maturin builds the extension (release profile,
# target/ shared with the crate, so a rebuild compiles only what changed).
echo "install-python: building and installing ./python into $VENV"
started=$(date +%s)
VIRTUAL_ENV="$(cd "$VENV" && pwd)" PATH="$(cd "$VENV" && pwd)/bin:$PATH" \
    "$VENV/bin/maturin" develop --release --quiet -m python/Cargo.toml
"$VENV/bin/python" -c "import legwork; print('install-python: legwork', legwork.__version__, 'from', legwork.__file__)"
echo "install-python: done in $(( $(date +%s) - started )) s"
