"""legwork: whole-body motions for four-legged robots, from Python.

The compiled core (``legwork._legwork``, Rust via pyo3) carries the robots, the dynamics on
numpy arrays and the jobs of the ``legwork`` command; ``legwork.mujoco`` replays motions in
MuJoCo and ``legwork.sweep`` runs many solves on Ray.

>>> import legwork, numpy as np
>>> hyq = legwork.Robot("hyq")
>>> ddq = hyq.aba(hyq.standing, np.zeros(hyq.nv), np.zeros(hyq.nv))
>>> round(float(ddq[2]), 2)   # free fall: the base accelerates down at g
-9.81

Errors are :class:`LegworkError`: :class:`InputError` for bad input (a file, field or value,
named in the message; the command line's exit code 2) and :class:`CouldNotFinishError` for a
job that started from valid input and failed (exit code 3).
"""

from ._legwork import (
    CouldNotFinishError,
    InputError,
    JumpResult,
    LegworkError,
    Robot,
    SolveResult,
    Trajectory,
    WalkResult,
    __version__,
    check_targets,
    figures,
    jump,
    jumps,
    robots,
    simulate,
    solve,
    task_dict,
    tasks,
    walk,
)


from .ray_sweep import SweepJob, sweep_job


def sweep(jobs, **kwargs):
    """Solves many (robot, task, overrides) jobs as Ray tasks and returns the table (pandas):
    see :func:`legwork.ray_sweep.run` (needs ``pip install "legwork[sweep]"``)."""
    from .ray_sweep import run

    return run(jobs, **kwargs)


__all__ = [
    "CouldNotFinishError",
    "InputError",
    "JumpResult",
    "LegworkError",
    "Robot",
    "SolveResult",
    "SweepJob",
    "Trajectory",
    "WalkResult",
    "__version__",
    "check_targets",
    "figures",
    "jump",
    "jumps",
    "robots",
    "simulate",
    "solve",
    "sweep",
    "sweep_job",
    "task_dict",
    "tasks",
    "walk",
]
