"""`legwork.sweep` on a local Ray: two solves as Ray tasks, their folders and the table, the
same numbers as solving them directly."""

import os

import pytest

import legwork


def test_two_task_sweep_on_local_ray(ray_module, tmp_path):
    jobs = [
        legwork.sweep_job("squat_jump", {"iterations": 2}, name="two"),
        ("hyq", "squat_jump", {"iterations": 3, "input.weight": 0.002}),
    ]
    table = legwork.sweep(jobs, out=tmp_path / "sweep", num_cpus=2, progress=False)
    assert list(table["name"]) == ["two", "001-squat_jump"]
    assert set(table["verdict"]) <= {"met", "missed"} and table["error"].isna().all()
    assert (tmp_path / "sweep" / "results.csv").is_file()
    for name in table["name"]:
        assert (tmp_path / "sweep" / name / "trajectory.json").is_file()
    # The Ray task solved what a direct call solves.
    direct = legwork.solve("squat_jump", iterations=3, overrides={"input.weight": 0.002}, threads=1, out=tmp_path / "direct")
    assert table["task_cost"][1] == direct.task_cost
    assert not ray_module.is_initialized()


def test_a_failing_job_is_a_row_not_an_exception(ray_module, tmp_path):
    table = legwork.sweep([legwork.sweep_job("squat_jump", {"input.wieght": 1.0, "iterations": 1})], out=tmp_path, num_cpus=1, progress=False)
    assert table["verdict"][0] == "error" and "InputError" in table["error"][0] and "wieght" in table["error"][0]


def test_sweep_arguments_are_checked(tmp_path):
    with pytest.raises(ValueError, match="same name"):
        legwork.sweep([legwork.sweep_job("squat_jump", name="a"), legwork.sweep_job("gallop", name="a")], out=tmp_path)
    with pytest.raises(ValueError, match="expected SweepJob"):
        legwork.sweep([42], out=tmp_path)
    assert not os.path.exists(tmp_path / "results.csv")
