"""legwork's errors as Python exceptions: the class says whose fault (InputError: the input,
exit code 2; CouldNotFinishError: the job, exit code 3), the message names the file, field
and expectation."""

import numpy as np
import pytest

import legwork


def raises(cls, *fragments):
    class Check:
        def __enter__(self):
            self.ctx = pytest.raises(cls)
            self.info = self.ctx.__enter__()
            return self.info

        def __exit__(self, *exc):
            handled = self.ctx.__exit__(*exc)
            message = str(self.info.value)
            for f in fragments:
                assert f in message, f"{f!r} not in {message!r}"
            return handled

    return Check()


def test_exception_classes():
    assert issubclass(legwork.InputError, legwork.LegworkError)
    assert issubclass(legwork.CouldNotFinishError, legwork.LegworkError)
    assert issubclass(legwork.LegworkError, Exception)


def test_bad_dynamics_arguments_are_named():
    hyq = legwork.Robot("hyq")
    q, v = hyq.standing, np.zeros(18)
    with raises(legwork.InputError, "aba: q", "expected 19 values", "got 5"):
        hyq.aba(q[:5], v, v)
    with raises(legwork.InputError, "rnea: a", "element 3 is not finite"):
        a = v.copy()
        a[3] = np.nan
        hyq.rnea(q, v, a)
    with raises(legwork.InputError, "crba: q", "quaternion", "norm 2.0"):
        bad = q.copy()
        bad[3:7] = [0, 0, 0, 2]
        hyq.crba(bad)
    with raises(legwork.InputError, "frame", "no frame named 'nose'"):
        hyq.frame_placement(q, "nose")
    with raises(legwork.InputError, "frame: index 999"):
        hyq.frame_jacobian(q, 999)
    with raises(legwork.InputError, "reference", "local_world_aligned"):
        hyq.frame_jacobian(q, "lf_foot", "body")
    with raises(legwork.InputError, "out: expected an array of 18 values, got 3"):
        hyq.aba(q, v, v, out=np.empty(3))


def test_bad_robots_are_named(tmp_path):
    with raises(legwork.InputError, "'nope' is neither an embedded robot"):
        legwork.Robot("nope")
    broken = tmp_path / "broken.urdf"
    broken.write_text("<robot name='x'><link name='a'/><joint name='j' type='revolute'><parent link='a'/><child link='missing'/></joint></robot>")
    with raises(legwork.InputError, str(broken)):
        legwork.Robot(broken)
    with raises(legwork.InputError, "missing.toml"):
        legwork.Robot(tmp_path / "missing.toml")


def test_bad_tasks_and_solver_settings_are_named(tmp_path):
    with raises(legwork.InputError, "no embedded task named 'nope'", "gallop"):
        legwork.solve("nope")
    with raises(legwork.InputError, "unknown field `wieght`", "overrides"):
        legwork.solve("squat_jump", overrides={"input.wieght": 1.0})
    with raises(legwork.InputError, "waypoint[9].time", "the array has 1 entries"):
        legwork.solve("squat_jump", overrides={"waypoint[9].time": 1.0})
    with raises(legwork.InputError, "overrides", "finite"):
        legwork.solve("squat_jump", overrides={"input.weight": float("nan")})
    with raises(legwork.InputError, "iterations: expected at least 1"):
        legwork.solve("squat_jump", iterations=0, out=tmp_path / "x")
    with raises(legwork.InputError, "starts"):
        legwork.solve("squat_jump", starts=100000, out=tmp_path / "x")
    with raises(legwork.InputError, "would need about", "memory_limit_gb=0.000001", "raise the limit with memory_limit_gb"):
        legwork.solve("squat_jump", memory_limit_gb=1e-6, out=tmp_path / "x")
    task = tmp_path / "bad.toml"
    task.write_text("name = 'x'\nsummary = 's'\nrobot = 'hyq'\nduration = -1.0\ndt = 0.002\n")
    with raises(legwork.InputError, str(task)):
        legwork.solve(task, out=tmp_path / "x")


def test_bad_trajectory_files_are_named(tmp_path):
    bad = tmp_path / "trajectory.json"
    bad.write_text('{"metadata": {}, "knots": []}')
    with raises(legwork.InputError, str(bad)):
        legwork.Trajectory.load(bad)
