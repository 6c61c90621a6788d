"""The MuJoCo helpers with the `mujoco` package: legwork's MJCF, a plan replayed with the
tracking controller and the exported policy, and the task figures of the runs."""

import numpy as np
import pytest

import legwork
import legwork.mujoco


def test_mjcf_is_legworks_robot(mujoco_module):
    hyq = legwork.Robot("hyq")
    model = legwork.mujoco.model(hyq)
    assert model.nu == 12 and model.nq == 19
    assert float(np.sum(model.body_mass)) == pytest.approx(hyq.total_mass, abs=1e-9)
    assert model.opt.timestep == pytest.approx(0.001)
    assert 'friction="0.8' in legwork.mujoco.mjcf("hyq")


@pytest.fixture(scope="module")
def plan(tmp_path_factory):
    return legwork.solve("squat_jump", iterations=3, threads=1, out=tmp_path_factory.mktemp("plan")).plan


def test_replay_and_check_report_the_task_figures(mujoco_module, plan, tmp_path):
    track = legwork.mujoco.replay(plan, controller="track", folder=tmp_path / "track", task="squat_jump")
    assert track["failed"] is None
    run = track["trajectory"]
    assert run.summary["simulator"] == f"MuJoCo {mujoco_module.__version__}"
    assert abs(run.t[-1] - plan.t[-1]) < 1e-9 and run.q.shape[1] == 19
    # The run stays near the plan: the tracking controller on legwork's own model of HyQ.
    assert np.abs(run.q[-1, :3] - plan.q[-1, :3]).max() < 0.1
    assert track["figures"] == legwork.figures(run, legwork.Robot("hyq"))
    assert [t["what"] for t in track["targets"]][0].startswith("base z at the apex")
    both = legwork.mujoco.check(plan, task="squat_jump", folder=tmp_path / "both")
    assert both["version"] == mujoco_module.__version__
    assert set(both) == {"version", "MuJoCo track", "MuJoCo policy"}
    # The checker is deterministic: the same tracking run twice.
    np.testing.assert_array_equal(both["MuJoCo track"]["trajectory"].q, run.q)


def test_solve_checks_in_mujoco_with_this_interpreter(mujoco_module, tmp_path):
    result = legwork.solve("squat_jump", iterations=2, threads=1, out=tmp_path, check_mujoco=True)
    assert set(result.reruns) == {"SLQ policy", "tracking ctrl", "MuJoCo track", "MuJoCo policy"}
    assert result.summary["mujoco_version"] == mujoco_module.__version__
    assert (tmp_path / "mujoco" / "model.xml").is_file()
