"""Robots and dynamics on numpy arrays: Pinocchio's values (shared/fixtures) through the
package, the embedded robots' properties, and the conventions of the arguments."""

import pickle

import numpy as np
import pytest

import legwork
from conftest import load_json

ROBOTS = [("hyq", "hyq/hyq_no_sensors.urdf"), ("a1", "a1/a1.urdf")]


@pytest.mark.parametrize("name, urdf", ROBOTS)
def test_dynamics_match_pinocchio_fixtures(shared, name, urdf):
    fixture = load_json(shared / "fixtures" / f"{name}_pinocchio.json")
    robot = legwork.Robot(shared / "robots" / urdf)
    assert robot.nq == 19 and robot.nv == 18
    samples = fixture["samples"] + fixture["special_samples"]
    for s in samples:
        q, v, tau, a = (np.array(s[k]) for k in ("q", "v", "tau", "rnea_input_qdd"))
        tol = 1e-9 * max(1.0, np.abs(s["aba_qdd"]).max())
        np.testing.assert_allclose(robot.aba(q, v, tau), s["aba_qdd"], atol=tol, rtol=0)
        np.testing.assert_allclose(robot.rnea(q, v, a), s["rnea_tau"], atol=1e-9 * max(1.0, np.abs(s["rnea_tau"]).max()), rtol=0)
        np.testing.assert_allclose(robot.crba(q), s["crba_M"], atol=1e-10, rtol=0)
        np.testing.assert_allclose(robot.nonlinear_effects(q, v), s["nonlinear_effects"], atol=1e-9, rtol=0)
        np.testing.assert_allclose(robot.gravity(q), s["generalized_gravity"], atol=1e-9, rtol=0)
        np.testing.assert_allclose(robot.center_of_mass(q), s["com_world"], atol=1e-12, rtol=0)
        dq, dv, minv = robot.aba_derivatives(q, v, tau)
        scale = max(1.0, np.abs(s["aba_dqdd_dq"]).max())
        np.testing.assert_allclose(dq, s["aba_dqdd_dq"], atol=1e-8 * scale, rtol=0)
        np.testing.assert_allclose(dv, s["aba_dqdd_dv"], atol=1e-8 * max(1.0, np.abs(s["aba_dqdd_dv"]).max()), rtol=0)
        np.testing.assert_allclose(minv, s["aba_Minv"], atol=1e-8 * max(1.0, np.abs(s["aba_Minv"]).max()), rtol=0)
        assert robot.total_mass == pytest.approx(s["total_mass"], abs=1e-9)


def test_rnea_derivatives_are_the_finite_differences_of_rnea():
    robot = legwork.Robot("hyq")
    rng = np.random.default_rng(3)
    q = robot.integrate(robot.standing, 0.1 * rng.standard_normal(robot.nv))
    v, a = rng.standard_normal(robot.nv), rng.standard_normal(robot.nv)
    dq, dv, mass = robot.rnea_derivatives(q, v, a)
    h = 1e-6
    for i in range(robot.nv):
        e = np.zeros(robot.nv)
        e[i] = h
        fd_q = (robot.rnea(robot.integrate(q, e), v, a) - robot.rnea(robot.integrate(q, -e), v, a)) / (2 * h)
        fd_v = (robot.rnea(q, v + e, a) - robot.rnea(q, v - e, a)) / (2 * h)
        np.testing.assert_allclose(dq[:, i], fd_q, atol=1e-4 * max(1, np.abs(fd_q).max()))
        np.testing.assert_allclose(dv[:, i], fd_v, atol=1e-4 * max(1, np.abs(fd_v).max()))
    np.testing.assert_allclose(mass, robot.crba(q), atol=1e-10)
    np.testing.assert_allclose(robot.minverse(q) @ mass, np.eye(robot.nv), atol=1e-9)


def test_frames_and_jacobians_agree():
    robot = legwork.Robot("hyq")
    q = robot.standing
    feet = robot.foot_positions(q)
    assert feet.shape == (4, 3)
    for i, foot in enumerate(robot.foot_names):
        rotation, position = robot.frame_placement(q, foot)
        np.testing.assert_allclose(position, feet[i], atol=1e-12)
        np.testing.assert_allclose(rotation @ rotation.T, np.eye(3), atol=1e-12)
        # The linear rows of the local-world-aligned Jacobian move the foot as q (+) v does.
        jac = robot.frame_jacobian(q, foot)
        v = np.random.default_rng(i).standard_normal(robot.nv) * 1e-7
        moved = robot.frame_placement(robot.integrate(q, v), foot)[1]
        np.testing.assert_allclose(moved - position, jac[:3] @ v, atol=1e-12)
    # Index and name address the same frame; the three reference frames are distinct.
    index = robot.frame_names.index(robot.foot_names[0])
    np.testing.assert_array_equal(robot.frame_jacobian(q, index, "world"), robot.frame_jacobian(q, robot.foot_names[0], "world"))
    assert not np.allclose(robot.frame_jacobian(q, index, "local"), robot.frame_jacobian(q, index))


def test_embedded_robots_and_their_properties():
    names = dict(legwork.robots())
    assert set(names) >= {"hyq", "a1"}
    hyq = legwork.Robot("hyq")
    assert hyq.name == "hyq" and hyq.total_mass == pytest.approx(86.774, abs=1e-6)
    assert len(hyq.joint_names) == 12 and hyq.foot_names == ["lf_foot", "rf_foot", "lh_foot", "rh_foot"]
    limits = hyq.joint_limits
    assert all(limits[k].shape == (12,) for k in ("lower", "upper", "velocity", "effort"))
    assert np.all(limits["lower"] < limits["upper"]) and np.all(limits["effort"] > 0)
    assert hyq.contact["friction"] == pytest.approx(0.8)
    # Free fall: the base accelerates down at g, and q (-) q = 0.
    ddq = hyq.aba(hyq.standing, np.zeros(18), np.zeros(18))
    assert ddq[2] == pytest.approx(-9.81) and np.allclose(ddq[6:], 0, atol=1e-9)
    np.testing.assert_array_equal(hyq.difference(hyq.standing, hyq.standing), np.zeros(18))
    assert hyq.centroidal_momentum(hyq.standing, np.zeros(18)).shape == (6,)


def test_out_arrays_are_written_in_place_and_robots_pickle_by_name():
    hyq = legwork.Robot("hyq")
    q, v, tau = hyq.standing, np.zeros(18), np.ones(18)
    out = np.empty(18)
    returned = hyq.aba(q, v, tau, out=out)
    assert returned is out
    np.testing.assert_array_equal(out, hyq.aba(q, v, tau))
    # Non-contiguous arrays, other dtypes and lists are read the same.
    wide = np.zeros((18, 2))
    wide[:, 0] = tau
    np.testing.assert_array_equal(hyq.aba(q, v, wide[:, 0]), out)
    np.testing.assert_array_equal(hyq.aba(list(q), [0] * 18, tau.astype(np.float32)), out)
    copy = pickle.loads(pickle.dumps(hyq))
    assert copy.name == "hyq" and np.array_equal(copy.aba(q, v, tau), out)
