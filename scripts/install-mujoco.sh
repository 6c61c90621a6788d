#!/usr/bin/env bash
# Installs the MuJoCo checker's Python environment (python/legwork/mujoco_check.py): a virtual
# environment in `.venv-mujoco/` at the repository root (git-ignored) with the pinned
# packages below, from PyPI with pip. Idempotent: a venv whose stamp file matches the pins
# is reused as it is; any other is rebuilt. `LEGWORK_MUJOCO_VENV` overrides the location
# (the checker's callers read the same variable). Prints what it did.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/venv.sh

# The MuJoCo version the issue-16 targets are measured in, and numpy for the checker.
VENV="${LEGWORK_MUJOCO_VENV:-.venv-mujoco}"
ensure_venv install-mujoco "$VENV" "mujoco, numpy" "mujoco==4.0.0" "numpy==2.3.5"
"$VENV/bin/python" -c "import mujoco, numpy; print('install-mujoco: mujoco', mujoco.__version__, 'numpy', numpy.__version__)"
