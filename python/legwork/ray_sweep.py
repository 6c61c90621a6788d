"""Sweeps: many solves (robot, task, overrides) as Ray tasks, collected as files and a table.

Ray does the scheduling: each job is one ``ray.remote`` task asking for ``threads`` CPUs
(one solve per core by default), on a local Ray instance unless ``address`` names a cluster.
Each solve writes the folder ``legwork solve`` writes (``out/<job name>/``) and returns one row
of the table; the table is written as ``out/results.csv`` (and ``results.parquet`` when
pyarrow is installed) and returned as a pandas DataFrame.

>>> import legwork
>>> jobs = [legwork.sweep_job("squat_jump", {"iterations": n}, name=f"it{n}") for n in (5, 10)]
>>> table = legwork.sweep(jobs, out="out/sweep")          # doctest: +SKIP

On a cluster (``address="ray://head:10001"`` or ``"auto"`` on a node of it) every node needs
legwork installed (the same wheel, or ``runtime_env={"pip": [...]}``) and ``out`` must be a
folder every node writes to (shared storage); the rows come back to the caller either way.
"""

from __future__ import annotations

import dataclasses
import os
import time
from typing import Any, Iterable, Optional, Sequence, Union


@dataclasses.dataclass
class SweepJob:
    """One solve of a sweep: a task (embedded name, ``.toml`` path or dict), the values to
    override in it (``{"input.weight": 0.1}``, paths as :func:`legwork.solve` takes them),
    the robot (default: the task's) and a name (the job's output folder)."""

    task: Union[str, dict]
    overrides: dict = dataclasses.field(default_factory=dict)
    robot: Optional[str] = None
    name: Optional[str] = None
    iterations: Optional[int] = None


def sweep_job(task, overrides: Optional[dict] = None, robot: Optional[str] = None, name: Optional[str] = None, iterations: Optional[int] = None) -> SweepJob:
    """A :class:`SweepJob`; ``overrides`` may also hold ``"iterations"`` (the solver's limit)."""
    overrides = dict(overrides or {})
    iterations = overrides.pop("iterations", iterations)
    return SweepJob(task=task, overrides=overrides, robot=robot, name=name, iterations=iterations)


def _name(job: SweepJob, index: int) -> str:
    if job.name:
        return job.name
    base = job.task if isinstance(job.task, str) else job.task.get("name", "task")
    base = os.path.splitext(os.path.basename(base))[0]
    return f"{index:03d}-{base}"


def solve_row(job: SweepJob, name: str, out: str, threads: int) -> dict:
    """Solves one job (in whichever process runs it) and returns its row; a job that fails
    is a row with its error, not an exception (a sweep goes on)."""
    import legwork

    row: dict[str, Any] = {"name": name, "task": job.task if isinstance(job.task, str) else job.task.get("name", "dict"), "robot": job.robot}
    row.update({f"override:{k}": v for k, v in job.overrides.items()})
    started = time.perf_counter()
    try:
        result = legwork.solve(job.task, robot=job.robot, out=os.path.join(out, name), threads=threads, iterations=job.iterations, overrides=job.overrides or None)
    except legwork.LegworkError as e:
        row.update(verdict="error", error=f"{type(e).__name__}: {e}", wall_time_s=time.perf_counter() - started)
        return row
    summary = result.summary
    plan = summary.get("plan", {})
    final = plan.get("final_base_position", [None] * 3)
    row.update(
        verdict=result.verdict,
        met=result.met,
        task_cost=result.task_cost,
        final_cost=float(result.cost_history[-1]),
        iterations=result.iterations,
        solve_time_s=result.solve_time,
        wall_time_s=time.perf_counter() - started,
        final_x_m=final[0],
        final_y_m=final[1],
        liftoffs=plan.get("liftoffs"),
        out=os.fspath(result.out),
        error=None,
    )
    return row


def run(jobs: Iterable[Union[SweepJob, dict, tuple]], *, out: str = "out/sweep", address: Optional[str] = None,
        threads: int = 1, num_cpus: Optional[int] = None, runtime_env: Optional[dict] = None,
        progress: bool = True):
    """Solves ``jobs`` as Ray tasks and returns the table (pandas DataFrame), one row per job
    in the jobs' order: name, task, robot, the overrides, verdict, task and final cost,
    iterations, solve and wall time, the plan's final x / y and lift-offs, output folder,
    error.

    ``jobs``: :class:`SweepJob` s, dicts of its fields, or ``(robot, task, overrides)`` tuples.
    ``address``: a Ray cluster (``"auto"``, ``"ray://host:10001"``); default: start a local
    Ray with ``num_cpus`` CPUs (default: all). ``threads``: CPUs (and SLQ threads) per
    solve. ``runtime_env``: Ray's, e.g. to pip-install legwork on a cluster's nodes.
    Ray is shut down afterwards if this call started it.
    """
    import pandas as pd
    import ray

    jobs = [_as_job(j) for j in jobs]
    if threads < 1:
        raise ValueError(f"threads: expected at least 1 CPU per solve, got {threads}")
    names = [_name(j, i) for i, j in enumerate(jobs)]
    if len(set(names)) != len(names):
        raise ValueError("jobs: two jobs have the same name (each names its output folder)")
    os.makedirs(out, exist_ok=True)
    started_here = not ray.is_initialized()
    if started_here:
        init = dict(address=address, include_dashboard=False, log_to_driver=False, runtime_env=runtime_env)
        if address is None:
            init["num_cpus"] = num_cpus
        ray.init(**init)
    try:
        remote = ray.remote(num_cpus=threads, max_retries=0)(solve_row)
        out_abs = os.path.abspath(out)
        refs = [remote.remote(job, name, out_abs, threads) for job, name in zip(jobs, names)]
        rows = _collect(ray, refs, names, progress)
    finally:
        if started_here:
            ray.shutdown()
    table = pd.DataFrame(rows)
    table.to_csv(os.path.join(out, "results.csv"), index=False)
    try:
        table.to_parquet(os.path.join(out, "results.parquet"), index=False)
    except ImportError:
        pass
    return table


def _collect(ray, refs: Sequence, names: Sequence[str], progress: bool) -> list:
    """Waits for every task, printing one line per finished job; returns the rows in order."""
    index = {ref: i for i, ref in enumerate(refs)}
    rows: list = [None] * len(refs)
    pending = list(refs)
    while pending:
        done, pending = ray.wait(pending, num_returns=1)
        for ref in done:
            i = index[ref]
            try:
                rows[i] = ray.get(ref)
            except Exception as e:  # a worker that died: the job's row says so
                rows[i] = {"name": names[i], "verdict": "error", "error": f"{type(e).__name__}: {e}"}
            if progress:
                r = rows[i]
                print(f"sweep: {len(refs) - len(pending)}/{len(refs)} {r['name']}: {r.get('verdict')}" + (f" ({r['error']})" if r.get("error") else f", task cost {r.get('task_cost', float('nan')):.4g}, {r.get('solve_time_s', float('nan')):.2f} s"), flush=True)
    return rows


def _as_job(job) -> SweepJob:
    if isinstance(job, SweepJob):
        return job
    if isinstance(job, dict):
        return sweep_job(**job)
    if isinstance(job, tuple) and len(job) == 3:
        robot, task, overrides = job
        return sweep_job(task, overrides, robot=robot)
    raise ValueError(f"jobs: expected SweepJob, dict or (robot, task, overrides), got {job!r}")
