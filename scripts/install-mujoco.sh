#!/usr/bin/env bash
# Installs the MuJoCo checker's Python environment (python/legwork/mujoco_check.py): a virtual
# environment in `.venv-mujoco/` at the repository root (git-ignored) with the pinned
# packages below, from PyPI with pip. Idempotent: a venv whose stamp file matches the pins
# is reused as it is; any other is rebuilt. `LEGWORK_MUJOCO_VENV` overrides the location
# (the checker's callers read the same variable). Prints what it did.
set -euo pipefail
cd "$(dirname "$0")/.."

# The MuJoCo version the issue-16 targets are measured in, and numpy for the checker.
PINS=("mujoco==4.0.0" "numpy==2.3.5")
VENV="${LEGWORK_MUJOCO_VENV:-.venv-mujoco}"
STAMP="$VENV/legwork-stamp"
WANT="${PINS[*]}"

if [ -f "$STAMP" ] && [ "$(cat "$STAMP")" = "$WANT" ] && [ -x "$VENV/bin/python" ] \
    && "$VENV/bin/python" -c "import mujoco, numpy" >/dev/null 2>&1; then
    echo "install-mujoco: $VENV already has $WANT; nothing to do"
    exit 0
fi

PYTHON="${PYTHON:-}"
if [ -z "$PYTHON" ]; then
    for candidate in python3 python; do
        if command -v "$candidate" >/dev/null 2>&1; then PYTHON="$candidate"; break; fi
    done
fi
if [ -z "$PYTHON" ]; then
    echo "install-mujoco: no python3 on PATH; install Python 3.10+ (with venv) first" >&2
    exit 1
fi

if ! "$PYTHON" -c "import venv, ensurepip" >/dev/null 2>&1; then
    # Debian splits venv/ensurepip off python3 into python3-venv.
    if command -v apt-get >/dev/null 2>&1; then
        SUDO=()
        if [ "$(id -u)" -ne 0 ]; then SUDO=(sudo); fi
        echo "install-mujoco: $PYTHON has no venv module; installing python3-venv with apt-get"
        source scripts/apt-wait.sh
        apt_get update -q
        apt_get install -y -q --no-install-recommends python3-venv
    else
        echo "install-mujoco: $PYTHON has no venv module and apt-get is not available" >&2
        exit 1
    fi
fi

echo "install-mujoco: creating $VENV with $WANT"
rm -rf "$VENV"
"$PYTHON" -m venv "$VENV"
"$VENV/bin/python" -m pip install -q --disable-pip-version-check "${PINS[@]}"
"$VENV/bin/python" -c "import mujoco, numpy; print('install-mujoco: mujoco', mujoco.__version__, 'numpy', numpy.__version__)"
echo "$WANT" > "$STAMP"
