"""`legwork.simulate` and `legwork.walk` are `legwork simulate` and `legwork walk`: the same
runs, the same files."""

import os

import numpy as np
import pytest

import legwork
from conftest import load_json, run_cli


def listing(d):
    return sorted(os.path.relpath(os.path.join(p, f), d) for p, _, fs in os.walk(d) for f in fs)


def test_simulate_is_the_command(legwork_bin, tmp_path):
    cli = run_cli(legwork_bin, "simulate", "--duration", "0.5", "--drop-height", "0.05", "--push", "0,80,0@0.1:0.1", "--out", str(tmp_path / "cli"))
    assert cli.returncode == 0, cli.stderr
    fractions = []
    run = legwork.simulate("hyq", duration=0.5, drop_height=0.05, pushes=[(0, 80, 0, 0.1, 0.1)], out=tmp_path / "py", progress=fractions.append)
    a, b = load_json(tmp_path / "cli" / "trajectory.json"), load_json(tmp_path / "py" / "trajectory.json")
    assert a["knots"] == b["knots"]
    assert listing(tmp_path / "cli") == listing(tmp_path / "py")
    assert run.summary["final_base_height_m"] == a["summary"]["final_base_height_m"]
    assert fractions[-1] == 1.0 and fractions == sorted(fractions) and len(fractions) <= 101
    assert run.gains is None and run.q.shape == (len(run), 19)


def test_simulate_tracks_a_plan_without_files(tmp_path):
    plan = legwork.solve("squat_jump", iterations=2, threads=1, out=tmp_path / "plan").plan
    tracked = legwork.simulate(controller="track", reference=plan, duration=0.3, write=False)
    from_file = legwork.simulate(controller="track", reference=tmp_path / "plan" / "trajectory.json", duration=0.3, write=False)
    np.testing.assert_array_equal(tracked.q, from_file.q)
    policy = legwork.simulate(controller="policy", reference=plan, duration=0.3, write=False)
    assert policy.summary["controller"] != tracked.summary["controller"]


def test_simulate_arguments_are_checked():
    with pytest.raises(legwork.InputError, match="duration: expected a positive time"):
        legwork.simulate(duration=-1, write=False)
    with pytest.raises(legwork.InputError, match="needs reference="):
        legwork.simulate(controller="track", write=False)
    with pytest.raises(legwork.InputError, match=r"pushes\[0\]"):
        legwork.simulate(pushes=["0,0@1:1"], write=False)
    with pytest.raises(legwork.InputError, match="record_rate"):
        legwork.simulate(duration=10, record_rate=1e9, memory_limit_gb=1, write=False)


def test_walk_is_the_command(legwork_bin, tmp_path):
    cli = run_cli(legwork_bin, "walk", "flat", "--seed", "3", "--out", str(tmp_path / "cli"))
    assert cli.returncode in (0, 1), cli.stderr
    plans = []
    result = legwork.walk("flat", seed=3, out=tmp_path / "py", progress=lambda t, what: plans.append((t, what)))
    a, b = load_json(tmp_path / "cli" / "trajectory.json"), load_json(tmp_path / "py" / "trajectory.json")
    assert a["knots"] == b["knots"]
    assert listing(tmp_path / "cli") == listing(tmp_path / "py")
    assert result.verdict == a["summary"]["verdict"] and cli.returncode == (0 if result.met else 1)
    assert result.report["plans"] == len(plans) == a["summary"]["plans"]
    with pytest.raises(legwork.InputError, match="no_such_scenario"):
        legwork.walk("no_such_scenario", write=False)


def test_jump_is_the_command(legwork_bin, tmp_path):
    cli = run_cli(legwork_bin, "jump", "lateral", "--threads", "1", "--out", str(tmp_path / "cli"))
    assert cli.returncode == 0, cli.stderr
    stages = []
    result = legwork.jump("lateral", threads=1, out=tmp_path / "py", progress=lambda stage, done: stages.append((stage, done)))
    for name in ("trajectory.json", "rerun.json", "contact_timing.json"):
        assert load_json(tmp_path / "cli" / name)["knots"] == load_json(tmp_path / "py" / name)["knots"], name
    assert listing(tmp_path / "cli") == listing(tmp_path / "py")
    assert result.verdict == "landed" and result.met and result.exit_code == 0
    assert len(result.phase_durations) == 2 and result.plan.q.shape[1] == 19 and len(result.rerun) > len(result.plan)
    assert stages[0][1] is False and stages[-1][1] is True
    assert "lateral" in dict(legwork.jumps())
    with pytest.raises(legwork.InputError, match="knots"):
        legwork.jump("lateral", knots=0, write=False)
