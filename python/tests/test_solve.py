"""`legwork.solve` is `legwork solve`: the same plan to the last bit, the same files, the
same verdict; a task as a name, a file, a dict or with overrides; a progress callback."""

import os

import numpy as np
import pytest

import legwork
from conftest import load_json, run_cli

ITERATIONS = "3"


@pytest.fixture(scope="module")
def both(tmp_path_factory, legwork_bin):
    """squat_jump, 3 SLQ iterations on one thread, solved by the command and by Python."""
    root = tmp_path_factory.mktemp("solve")
    cli = run_cli(legwork_bin, "solve", "squat_jump", "--iterations", ITERATIONS, "--threads", "1", "--out", str(root / "cli"))
    assert cli.returncode in (0, 1), cli.stderr
    seen = []
    result = legwork.solve("squat_jump", iterations=int(ITERATIONS), threads=1, out=root / "py", progress=seen.append)
    return root, cli, result, seen


def test_python_and_command_line_give_the_same_plan(both):
    root, cli, result, _ = both
    a, b = load_json(root / "cli" / "trajectory.json"), load_json(root / "py" / "trajectory.json")
    assert len(a["knots"]) == len(b["knots"]) == len(result.plan)
    for ka, kb in zip(a["knots"], b["knots"]):
        assert ka == kb  # every float, bit for bit (JSON round-trips f64 exactly)
    for key in ("verdict", "exit_code", "target", "plan", "slq_policy_rerun", "tracking_controller_rerun", "task_cost", "final_cost", "iterations"):
        assert a["summary"][key] == b["summary"][key], key
    assert cli.returncode == result.exit_code
    # The arrays are the file's numbers.
    np.testing.assert_array_equal(result.plan.q, np.array([k["q"] for k in b["knots"]]))
    np.testing.assert_array_equal(result.plan.tau, np.array([k["tau"] for k in b["knots"]]))
    np.testing.assert_array_equal(result.plan.gains[5], np.array(b["knots"][5]["feedback_gain"]))


def test_python_writes_the_command_lines_files(both):
    root, _, result, _ = both
    listing = lambda d: sorted(os.path.relpath(os.path.join(p, f), d) for p, _, fs in os.walk(d) for f in fs)
    assert listing(root / "cli") == listing(root / "py")
    assert "plots/cost.svg" in listing(root / "py") and "replay.html" in listing(root / "py")
    assert os.fspath(result.out) == os.fspath(root / "py")


def test_result_object(both):
    _, _, result, seen = both
    k = len(result.plan)
    assert result.plan.q.shape == (k, 19) and result.plan.v.shape == (k, 18) and result.plan.tau.shape == (k, 12)
    assert result.plan.gains.shape == (k, 12, 36) and result.plan.in_contact.shape == (k, 4)
    assert result.plan.contact_force.shape == (k, 4, 3) and result.plan.in_contact.dtype == bool
    assert result.verdict in ("met", "missed") and result.met == (result.verdict == "met")
    assert result.iterations >= int(ITERATIONS) and result.solve_time > 0 and len(result.cost_history) >= 2
    assert set(result.reruns) == {"SLQ policy", "tracking ctrl"}
    assert isinstance(result.reruns["tracking ctrl"], legwork.Trajectory)
    assert result.targets["plan"][0]["what"].startswith("base z at the apex")
    # The progress callback saw every iteration, in order, with its cost.
    assert [p["iteration"] for p in seen][:2] == [1, 2] and all(np.isfinite(p["cost"]) for p in seen)
    assert len(seen) >= result.iterations


def test_a_raising_callback_is_raised_after_the_solve(tmp_path):
    def stop(_):
        raise KeyError("from the callback")

    with pytest.raises(KeyError, match="from the callback"):
        legwork.solve("squat_jump", iterations=1, threads=1, out=tmp_path, progress=stop)


def test_tasks_as_dicts_files_and_overrides(tmp_path):
    assert "gallop" in dict(legwork.tasks())
    spec = legwork.task_dict("squat_jump")
    assert spec["name"] == "squat_jump" and spec["robot"] == "hyq"
    spec["input"]["weight"] = spec["input"]["weight"] * 10
    as_dict = legwork.solve(spec, iterations=2, threads=1, out=tmp_path / "dict")
    as_override = legwork.solve("squat_jump", overrides={"input.weight": spec["input"]["weight"]}, iterations=2, threads=1, out=tmp_path / "override")
    plain = legwork.solve("squat_jump", iterations=2, threads=1, out=tmp_path / "plain")
    np.testing.assert_array_equal(as_dict.plan.q, as_override.plan.q)
    assert not np.array_equal(as_dict.plan.q, plain.plan.q)
    # A task file is read as the command line reads it.
    from conftest import REPO

    from_file = legwork.solve(REPO / "tasks" / "squat_jump.toml", iterations=2, threads=1, out=tmp_path / "file")
    np.testing.assert_array_equal(from_file.plan.q, plain.plan.q)


def test_target_checks_follow_overrides(tmp_path):
    result = legwork.solve("squat_jump", iterations=1, threads=1, out=tmp_path)
    robot = legwork.Robot("hyq")
    apex = legwork.check_targets("squat_jump", result.plan, robot)[0]
    lowered = legwork.check_targets("squat_jump", result.plan, robot, overrides={"target[0].base_position[2]": 0.5})[0]
    assert apex["required"].startswith("0.800") and lowered["required"].startswith("0.500")
    assert apex == result.targets["plan"][0]
    figures = legwork.figures(result.plan, robot)
    assert figures == result.summary["plan"]


def test_png_on_request(tmp_path):
    legwork.solve("squat_jump", iterations=1, threads=1, out=tmp_path / "svg")
    legwork.solve("squat_jump", iterations=1, threads=1, out=tmp_path / "png", png=True)
    assert not list((tmp_path / "svg" / "plots").glob("*.png"))
    svgs = sorted(p.stem for p in (tmp_path / "png" / "plots").glob("*.svg"))
    assert svgs and sorted(p.stem for p in (tmp_path / "png" / "plots").glob("*.png")) == svgs
    assert (tmp_path / "png" / "plots" / "cost.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
