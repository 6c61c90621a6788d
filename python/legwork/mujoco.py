"""legwork motions in MuJoCo: the MJCF of a robot and its ground, a plan replayed with the
tracking controller or the exported feedback policy, and the task figures of the run.

The replay runs legwork's MuJoCo checker (``legwork/mujoco_check.py``, the same one
``legwork solve --check mujoco`` runs) with this interpreter, which needs the ``mujoco``
package (``pip install "legwork[mujoco]"``, MuJoCo 4.0.0).

>>> import legwork, legwork.mujoco
>>> result = legwork.solve("squat_jump", out="out/squat_jump")            # doctest: +SKIP
>>> runs = legwork.mujoco.check(result.plan, "hyq", task="squat_jump")   # doctest: +SKIP
>>> runs["MuJoCo track"]["targets"]                                     # doctest: +SKIP
"""

from __future__ import annotations

import os
import sys
import tempfile
from typing import Optional, Union

from . import _legwork
from ._legwork import Robot, Trajectory

RobotLike = Union[str, "os.PathLike[str]", Robot]
TaskLike = Union[str, "os.PathLike[str]", dict]


def _robot(robot: RobotLike, plan: Optional[Trajectory] = None) -> Robot:
    if robot is None:
        if plan is None:
            raise _legwork.InputError("robot: expected a robot (name, path or legwork.Robot)")
        robot = plan.robot
    return robot if isinstance(robot, Robot) else Robot(robot)


def _folder(folder) -> str:
    if folder is None:
        return tempfile.mkdtemp(prefix="legwork-mujoco-")
    os.makedirs(folder, exist_ok=True)
    return os.fspath(folder)


def mjcf(robot: RobotLike, terrain: Optional[dict] = None) -> str:
    """The MJCF of ``robot`` on ``terrain`` (flat ground, or a trajectory's
    ``metadata["terrain"]``): bodies, inertias, joint ranges, torque motors at the effort
    limits, foot spheres with the robot's friction, a 1 ms step."""
    return _legwork.mjcf(_robot(robot), terrain)


def model(robot: RobotLike, terrain: Optional[dict] = None):
    """``mujoco.MjModel`` built from :func:`mjcf`."""
    import mujoco

    return mujoco.MjModel.from_xml_string(mjcf(robot, terrain))


def replay(plan: Trajectory, robot: Optional[RobotLike] = None, *, controller: str = "track",
           duration: Optional[float] = None, folder=None, task: Optional[TaskLike] = None) -> dict:
    """Replays ``plan`` in MuJoCo from its first state on its own ground, with
    ``controller``: ``"track"`` (Neunert 2017's tracking controller) or ``"policy"`` (the
    exported ``tau = tau_ff + K [q (-) q*; v - v*]``). Returns ``{"trajectory": the run,
    "failed": why MuJoCo stopped or None, "figures": task figures, "targets": the task's
    checks at twice the tolerances (with ``task``)}``."""
    robot = _robot(robot, plan)
    run, failed = _legwork.mujoco_replay(plan, robot, sys.executable, _folder(folder), controller, duration)
    return _report(run, failed, robot, task)


def check(plan: Trajectory, robot: Optional[RobotLike] = None, *, task: Optional[TaskLike] = None, folder=None) -> dict:
    """Both MuJoCo re-runs of ``plan``, as ``legwork solve --check mujoco`` runs them:
    ``{"version": "4.0.0", "MuJoCo track": {...}, "MuJoCo policy": {...}}``, each as
    :func:`replay` returns it."""
    robot = _robot(robot, plan)
    runs = _legwork.mujoco_check(plan, robot, sys.executable, _folder(folder))
    out = {"version": runs.pop("version")}
    for name, run in runs.items():
        out[name] = _report(run, None, robot, task) if isinstance(run, Trajectory) else {"trajectory": None, "failed": run, "figures": None, "targets": None}
    return out


def _report(run: Trajectory, failed: Optional[str], robot: Robot, task: Optional[TaskLike]) -> dict:
    return {
        "trajectory": run,
        "failed": failed,
        "figures": _legwork.figures(run, robot),
        "targets": _legwork.check_targets(task, run, robot, 2.0) if task is not None else None,
    }
