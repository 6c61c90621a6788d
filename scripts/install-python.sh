#!/usr/bin/env bash
# Builds and installs legwork's Python package (python/, pyo3 + maturin) with the tests'
# dependencies into a virtual environment, `.venv-python/` at the repository root
# (git-ignored; `LEGWORK_PYTHON_VENV` overrides the location). Idempotent: the pinned
# packages are installed once (a stamp file records them), and the package is rebuilt by
# `pip install ./python`, which cargo makes incremental (target/ is shared with the crate).
# A user's own install is just `pip install ./python` (README).
set -euo pipefail
cd "$(dirname "$0")/.."

source scripts/venv.sh

# numpy as the MuJoCo checker's; MuJoCo 4.0.0 as legwork's MuJoCo targets; Ray and pandas
# for the sweeps; pytest for the tests; maturin to build.
VENV="${LEGWORK_PYTHON_VENV:-.venv-python}"
ensure_venv install-python "$VENV" "numpy, mujoco, ray, pandas, pytest" \
    "maturin==1.16.0" "numpy==2.3.5" "mujoco==4.0.0" "ray==2.60.0" "pandas==3.1.1" "pytest==9.2.0"

# The package itself, from this checkout: maturin builds the extension (release profile,
# target/ shared with the crate, so a rebuild compiles only what changed).
echo "install-python: building and installing ./python into $VENV"
started=$(date +%s)
VIRTUAL_ENV="$(cd "$VENV" && pwd)" PATH="$(cd "$VENV" && pwd)/bin:$PATH" \
    "$VENV/bin/maturin" develop --release --quiet -m python/Cargo.toml
"$VENV/bin/python" -c "import legwork; print('install-python: legwork', legwork.__version__, 'from', legwork.__file__)"
echo "install-python: done in $(( $(date +%s) - started )) s"
