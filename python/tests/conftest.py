"""Shared paths and helpers of the Python package's tests (run by `bash scripts/test`)."""

import json
import os
import pathlib
import shutil
import subprocess

import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]
SHARED = REPO.parent / "shared"


def required(what: str):
    """Skips a test whose prerequisite is missing, or fails it under CI (CI has them all)."""
    if os.environ.get("CI"):
        pytest.fail(f"{what} is missing (CI must have it: scripts/test installs it)")
    pytest.skip(f"{what} is missing")


@pytest.fixture(scope="session")
def shared():
    if not (SHARED / "fixtures").is_dir():
        required(f"{SHARED} (reference robots and Pinocchio fixtures)")
    return SHARED


@pytest.fixture(scope="session")
def legwork_bin():
    """The `legwork` command of this checkout: $LEGWORK_BIN, else target/{release,debug}/legwork."""
    candidates = [os.environ.get("LEGWORK_BIN")] if os.environ.get("LEGWORK_BIN") else [REPO / "target" / "release" / "legwork", REPO / "target" / "debug" / "legwork"]
    for c in candidates:
        if c and pathlib.Path(c).is_file():
            return str(c)
    required("the legwork command (cargo build)")


def run_cli(binary, *args, cwd=None):
    return subprocess.run([binary, *args], capture_output=True, text=True, cwd=cwd, timeout=600)


def load_json(path):
    with open(path) as f:
        return json.load(f)


@pytest.fixture(scope="session")
def mujoco_module():
    try:
        import mujoco
    except ImportError:
        required("the mujoco package (pip install 'legwork[mujoco]')")
    return mujoco


@pytest.fixture(scope="session")
def ray_module():
    try:
        import pandas  # noqa: F401
        import ray
    except ImportError:
        required("ray and pandas (pip install 'legwork[sweep]')")
    return ray


def copy_tree(src, dst):
    shutil.copytree(src, dst)
