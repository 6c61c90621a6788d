//! The joint stops in the simulator: a joint driven against its limit at full effort is
//! held where the stop's force balances it, `k (p - w / 2) = tau`; without stops it swings
//! through.

use legwork::model::{embedded, Model};
use legwork::sim::{ControlError, Controller, JointLimitParams, SimConfig, SimError, SimState, Simulator};
use legwork::terrain::Plane;
use nalgebra::DVector;

/// A constant torque on one joint (velocity index `dof`).
struct Push {
    dof: usize,
    torque: f64,
}

impl Controller for Push {
    fn name(&self) -> &str {
        "push"
    }
    fn compute(&mut self, _: &Model, _: &SimState, tau: &mut DVector<f64>) -> Result<(), ControlError> {
        tau.fill(0.0);
        tau[self.dof] = self.torque;
        Ok(())
    }
}

/// HyQ in free fall (no gravity torque on the joints, ground far below) with its LF knee
/// starting 0.05 rad short of its upper limit (-20 deg) and pushed towards it at the full
/// 150 N m effort: the knee's angle after `seconds`, and the limit.
fn lf_knee_after(config: SimConfig, seconds: f64) -> (f64, f64) {
    let model = embedded::load("hyq").unwrap();
    let far_below = Plane::flat(-100.0);
    let knee = &model.joints[model.joint_id("lf_kfe_joint").unwrap()];
    let mut q0 = model.reference_configuration("standing").unwrap().clone();
    q0[knee.idx_q] = knee.limits.upper[0] - 0.05;
    let mut sim = Simulator::new(&model, &far_below, config, q0, None).unwrap();
    let run = sim.run(seconds, &mut Push { dof: knee.idx_v, torque: knee.limits.effort[0] }, |_| {}).unwrap();
    let last = run.trajectory.knots.last().unwrap();
    (last.q[knee.idx_q], knee.limits.upper[0])
}

#[test]
fn a_stop_holds_a_joint_at_full_effort_where_its_spring_balances_it() {
    let params = JointLimitParams::default();
    let (angle, upper) = lf_knee_after(SimConfig { joint_limits: Some(params), ..SimConfig::default() }, 0.3);
    // 150 N m = k (p - w / 2): p = 150 / 5000 + 0.01 = 0.04 rad (2.3 deg).
    let expected = 150.0 / params.stiffness + params.smoothing / 2.0;
    assert!((angle - upper - expected).abs() < 1e-3, "knee {:.4} rad past its limit, expected {expected:.4}", angle - upper);
    assert!((angle - upper).to_degrees() < 2.5);
}

#[test]
fn without_stops_the_joint_swings_through_its_limit() {
    // About 7500 rad/s^2 on the shank: 0.3 rad in 10 ms.
    let (angle, upper) = lf_knee_after(SimConfig { joint_limits: None, ..SimConfig::default() }, 0.01);
    assert!(angle - upper > 0.2, "knee only {:.3} rad past its limit", angle - upper);
}

#[test]
fn bad_stop_parameters_are_refused_naming_the_field() {
    let model = embedded::load("hyq").unwrap();
    let ground = Plane::flat(0.0);
    let q0 = model.reference_configuration("standing").unwrap().clone();
    let config = SimConfig { joint_limits: Some(JointLimitParams { damping: -1.0, ..Default::default() }), ..SimConfig::default() };
    match Simulator::new(&model, &ground, config, q0, None) {
        Err(e @ SimError::JointLimits(_)) => assert!(e.to_string().contains("`damping`"), "{e}"),
        Err(e) => panic!("wrong error: {e}"),
        Ok(_) => panic!("negative damping accepted"),
    }
}
