//! Closed-loop scenarios of issue 3: drops onto flat ground with the standing controller,
//! a lateral push, divergence detection, integrators, and the tracking controller.

use legwork::control::{JointPd, TrackingController};
use legwork::io::{Knot, Trajectory};
use legwork::model::{embedded, Model};
use legwork::sim::{standing_on_ground, ControlError, Controller, Integrator, Push, SimConfig, SimError, SimState, Simulator};
use legwork::terrain::{HeightMap, Plane, Terrain};
use nalgebra::DVector;

fn base_speed(k: &Knot) -> f64 {
    k.v[..6].iter().map(|x| x * x).sum::<f64>().sqrt()
}

fn distance(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum::<f64>().sqrt()
}

/// Drop from 0.1 m onto flat ground with the standing controller; returns the run.
fn drop(model: &Model, seconds: f64) -> legwork::sim::Run {
    let ground = Plane::flat(0.0);
    let q0 = standing_on_ground(model, &ground, 0.1).unwrap();
    let mut sim = Simulator::new(model, &ground, SimConfig::default(), q0, None).unwrap();
    let mut stand = JointPd::standing(model, 0.001).unwrap();
    sim.run(seconds, &mut stand, |_| {}).unwrap()
}

fn check_drop(name: &str, seconds: f64) {
    let model = embedded::load(name).unwrap();
    let run = drop(&model, seconds);
    let standing = standing_on_ground(&model, &Plane::flat(0.0), 0.0).unwrap()[2];
    let last = run.trajectory.knots.last().unwrap();
    let sag = standing - last.q[2];
    eprintln!(
        "{name}: rest height {:.4} m (standing {:.4} m, {:.1} mm lower), max penetration {:.2} mm, max |Ft|/Fn {:.3}, final base speed {:.4}",
        last.q[2],
        standing,
        sag * 1e3,
        run.stats.max_penetration * 1e3,
        run.stats.max_friction_ratio,
        base_speed(last)
    );
    // Comes to rest ...
    assert!(base_speed(last) < 0.01, "{name} still moving: {}", base_speed(last));
    // ... at its standing height, less the joint PD's sag under the weight and the static
    // penetration (HyQ 22 mm, A1 10 mm).
    assert!(sag > 0.0 && sag < 0.03, "{name}: rest height {} vs standing {}", last.q[2], standing);
    // Upright, not drifted.
    assert!(last.q[3].abs() < 0.02 && last.q[4].abs() < 0.02, "{name}: tilted {:?}", &last.q[3..7]);
    // (A1 slides 20.6 mm at its landing with the calibrated contact, whose stiffer tangential
    // spring meets the friction cone at impact; 12.3 mm with Table I's softer one.)
    assert!(last.q[0].hypot(last.q[1]) < 0.025, "{name}: drifted {:.1} mm", 1e3 * last.q[0].hypot(last.q[1]));
    // The contact targets of the issue.
    assert!(run.stats.max_penetration < 0.02, "{name}: penetration {}", run.stats.max_penetration);
    assert!(run.stats.max_friction_ratio <= model.contact.friction + 1e-9);
    // All four feet on the ground at the end, carrying the weight.
    let weight = model.total_mass() * 9.81;
    let fz: f64 = last.contact_force.iter().map(|f| f[2]).sum();
    assert!(last.in_contact.iter().all(|&c| c));
    assert!((fz - weight).abs() < 0.02 * weight, "{name}: {fz} N carried, weight {weight} N");
}

#[test]
fn hyq_dropped_from_10_cm_comes_to_rest_standing() {
    check_drop("hyq", 3.0);
}

#[test]
fn a1_dropped_from_10_cm_comes_to_rest_standing() {
    // A1 rocks longer on its light legs (about 3.6 s to |v| < 0.01).
    check_drop("a1", 5.0);
}

#[test]
fn hyq_rejects_a_lateral_push() {
    let model = embedded::load("hyq").unwrap();
    let ground = Plane::flat(0.0);
    let q0 = standing_on_ground(&model, &ground, 0.0).unwrap();
    let mut sim = Simulator::new(&model, &ground, SimConfig::default(), q0, None).unwrap();
    sim.add_push(Push::parse("0,50,0@1.0:0.2").unwrap());
    let mut stand = JointPd::standing(&model, 0.001).unwrap();
    let run = sim.run(3.2, &mut stand, |_| {}).unwrap();
    let ks = &run.trajectory.knots;
    let at = |t: f64| ks.iter().min_by(|a, b| (a.t - t).abs().total_cmp(&(b.t - t).abs())).unwrap();
    let before = at(1.0);
    let peak = ks.iter().filter(|k| k.t > 1.0).map(|k| distance(&k.q[..3], &before.q[..3])).fold(0.0, f64::max);
    let after = distance(&at(3.2).q[..3], &before.q[..3]);
    eprintln!("push: peak deviation {:.1} mm, 2 s after the push {:.1} mm", peak * 1e3, after * 1e3);
    assert!(peak > 0.003, "the push did not move the robot ({peak} m): the test would prove nothing");
    assert!(after < 0.02, "not back within 2 cm: {after} m");
}

/// A controller that asks for a torque the robot cannot survive.
struct Wild;
impl Controller for Wild {
    fn name(&self) -> &str {
        "wild"
    }
    fn compute(&mut self, model: &Model, state: &SimState, tau: &mut DVector<f64>) -> Result<(), ControlError> {
        for i in 6..model.nv {
            tau[i] = if state.t > 0.01 { 1e9 } else { 0.0 };
        }
        Ok(())
    }
}

#[test]
fn a_blow_up_is_reported_with_step_and_state() {
    let model = embedded::load("a1").unwrap();
    let ground = Plane::flat(0.0);
    let q0 = standing_on_ground(&model, &ground, 0.0).unwrap();
    let config = SimConfig { enforce_effort_limits: false, ..Default::default() };
    let mut sim = Simulator::new(&model, &ground, config, q0, None).unwrap();
    let err = sim.run(1.0, &mut Wild, |_| {}).unwrap_err();
    match &err {
        SimError::Diverged { step, t, q, v, .. } => {
            assert!(*step > 20 && *t > 0.01 && q.len() == model.nq && v.len() == model.nv);
        }
        other => panic!("expected a divergence, got {other}"),
    }
    let text = err.to_string();
    assert!(text.contains("diverged at step") && text.contains("q = ["), "{text}");
}

struct NotANumber;
impl Controller for NotANumber {
    fn name(&self) -> &str {
        "nan"
    }
    fn compute(&mut self, _: &Model, _: &SimState, tau: &mut DVector<f64>) -> Result<(), ControlError> {
        tau[7] = f64::NAN;
        Ok(())
    }
}

#[test]
fn a_nan_torque_is_refused_before_it_enters_the_state() {
    let model = embedded::load("hyq").unwrap();
    let ground = Plane::flat(0.0);
    let q0 = standing_on_ground(&model, &ground, 0.0).unwrap();
    let mut sim = Simulator::new(&model, &ground, SimConfig::default(), q0, None).unwrap();
    let err = sim.run(0.1, &mut NotANumber, |_| {}).unwrap_err().to_string();
    let joint = model.joints.iter().find(|j| j.idx_v == 7).unwrap();
    assert!(err.contains("nan") && err.contains("NaN") && err.contains(&joint.name), "{err}");
    assert!(sim.state().q.iter().all(|x| x.is_finite()));
}

#[test]
fn effort_limits_are_enforced() {
    let model = embedded::load("a1").unwrap();
    let ground = Plane::flat(0.0);
    let q0 = standing_on_ground(&model, &ground, 0.0).unwrap();
    let mut sim = Simulator::new(&model, &ground, SimConfig::default(), q0, None).unwrap();
    let run = sim.run(0.03, &mut Wild, |_| {}).unwrap();
    let max_effort = model.joints.iter().skip(2).map(|j| j.limits.effort[0]).fold(0.0, f64::max);
    assert!(run.stats.max_torque <= max_effort + 1e-12 && run.stats.saturated_controls > 0);
    for k in &run.trajectory.knots {
        for (tau, j) in k.tau.iter().zip(model.joints.iter().skip(2)) {
            assert!(tau.abs() <= j.limits.effort[0] + 1e-12);
        }
    }
}

#[test]
fn bad_settings_are_named() {
    let model = embedded::load("a1").unwrap();
    let ground = Plane::flat(0.0);
    let q0 = standing_on_ground(&model, &ground, 0.0).unwrap();
    let config = SimConfig { control_dt: 0.0007, ..Default::default() };
    let err = Simulator::new(&model, &ground, config, q0.clone(), None).err().unwrap().to_string();
    assert!(err.contains("control_dt") && err.contains("whole multiple"), "{err}");
    let mut bad_q = q0.clone();
    bad_q[9] = f64::NAN;
    assert!(Simulator::new(&model, &ground, SimConfig::default(), bad_q, None).is_err());
    let mut no_smoothing = model.clone();
    no_smoothing.contact.alpha = 0.0;
    assert!(Simulator::new(&no_smoothing, &ground, SimConfig::default(), q0.clone(), None).err().unwrap().to_string().contains("alpha"));
    // The robot's contact model bounds the physics step.
    let coarse = SimConfig { physics_dt: 0.002, control_dt: 0.002, record_dt: 0.002, ..Default::default() };
    let err = Simulator::new(&model, &ground, coarse, q0, None).err().unwrap().to_string();
    assert!(err.contains("physics_dt") && err.contains("contact.max_step"), "{err}");
    assert!(Push::parse("0,50@1:0.2").unwrap_err().contains("X,Y,Z@T:DUR"));
    assert!(Push::parse("0,50,0@1:-1").is_err());
}

#[test]
fn free_fall_is_a_parabola_with_either_integrator() {
    // 0.2 s of free fall from 1 m: z(t) = z0 - g t^2 / 2, no contact. Semi-implicit Euler
    // falls exactly g dt T / 2 further (z_n = z0 - g dt^2 n (n + 1) / 2); RK4 is exact.
    let model = embedded::load("a1").unwrap();
    let ground = Plane::flat(0.0);
    let q0 = standing_on_ground(&model, &ground, 1.0).unwrap();
    let mut hold = JointPd::standing(&model, 0.001).unwrap();
    let dt = SimConfig::default().physics_dt;
    for (integrator, euler_error) in [(Integrator::SemiImplicitEuler, 9.81 * dt * 0.2 / 2.0), (Integrator::Rk4, 0.0)] {
        let config = SimConfig { integrator, ..Default::default() };
        let mut sim = Simulator::new(&model, &ground, config, q0.clone(), None).unwrap();
        let run = sim.run(0.2, &mut hold, |_| {}).unwrap();
        let last = run.trajectory.knots.last().unwrap();
        let expected = q0[2] - 0.5 * 9.81 * 0.2 * 0.2 - euler_error;
        assert!((last.q[2] - expected).abs() < 1e-9, "{integrator:?}: {} vs {expected}", last.q[2]);
    }
}

#[test]
fn rk4_and_euler_agree_on_the_resting_pose() {
    let model = embedded::load("hyq").unwrap();
    let ground = Plane::flat(0.0);
    let q0 = standing_on_ground(&model, &ground, 0.0).unwrap();
    let mut rest = Vec::new();
    for integrator in [Integrator::SemiImplicitEuler, Integrator::Rk4] {
        let config = SimConfig { integrator, ..Default::default() };
        let mut sim = Simulator::new(&model, &ground, config, q0.clone(), None).unwrap();
        let mut stand = JointPd::standing(&model, 0.001).unwrap();
        rest.push(sim.run(1.5, &mut stand, |_| {}).unwrap().trajectory.knots.last().unwrap().q[2]);
    }
    assert!((rest[0] - rest[1]).abs() < 5e-4, "{rest:?}");
}

#[test]
fn standing_on_a_height_map_step() {
    // A1 standing with its front feet on a 5 cm step: the feet rest on the surface there.
    let model = embedded::load("a1").unwrap();
    let mut map = HeightMap::flat([-1.0, -1.0], 0.02, 101, 101, 0.0);
    map.set_rect([0.05, 1.0], [-1.0, 1.0], 0.05);
    let q0 = standing_on_ground(&model, &map, 0.02).unwrap();
    let mut sim = Simulator::new(&model, &map, SimConfig::default(), q0, None).unwrap();
    let mut stand = JointPd::standing(&model, 0.001).unwrap();
    let run = sim.run(2.0, &mut stand, |_| {}).unwrap();
    let last = run.trajectory.knots.last().unwrap();
    assert!(last.in_contact[0] && last.in_contact[1], "front feet should rest on the step");
    for (k, foot) in sim.feet().iter().enumerate() {
        let surface = map.height(foot.position.x, foot.position.y);
        let bottom = foot.position.z - model.feet[k].radius;
        assert!((bottom - surface).abs() < 0.01, "foot {k}: bottom {bottom} vs surface {surface}");
    }
    assert!(run.stats.max_penetration < 0.02);
}

#[test]
fn tracking_controller_reproduces_a_recorded_motion_and_corrects_a_disturbance() {
    // Reference: HyQ standing, pushed sideways (so the motion is not trivial).
    let model = embedded::load("hyq").unwrap();
    let ground = Plane::flat(0.0);
    let q0 = standing_on_ground(&model, &ground, 0.0).unwrap();
    let mut sim = Simulator::new(&model, &ground, SimConfig::default(), q0.clone(), None).unwrap();
    sim.add_push(Push::parse("0,80,0@0.3:0.3").unwrap());
    let mut stand = JointPd::standing(&model, 0.001).unwrap();
    let reference = sim.run(2.0, &mut stand, |_| {}).unwrap().trajectory;

    // Track it from the same state, without the push: the planned feedforward carries the
    // robot along the reference, the feedback corrects the missing push.
    let track = |push: Option<&str>| -> (f64, Trajectory) {
        let mut sim = Simulator::new(&model, &ground, SimConfig::default(), q0.clone(), None).unwrap();
        if let Some(p) = push {
            sim.add_push(Push::parse(p).unwrap());
        }
        let mut ctrl = TrackingController::with_default_gains(&model, &reference, 0.001).unwrap();
        let run = sim.run(2.0, &mut ctrl, |_| {}).unwrap().trajectory;
        let worst = run.knots.iter().zip(&reference.knots).map(|(a, b)| distance(&a.q[..3], &b.q[..3])).fold(0.0, f64::max);
        (worst, run)
    };
    let (same, _) = track(Some("0,80,0@0.3:0.3"));
    let (without_push, _) = track(None);
    let peak_push = reference.knots.iter().map(|k| distance(&k.q[..3], &reference.knots[0].q[..3])).fold(0.0, f64::max);
    eprintln!(
        "tracking: same conditions worst base error {:.2} mm; without the push {:.2} mm (the push moved the reference {:.1} mm)",
        same * 1e3,
        without_push * 1e3,
        peak_push * 1e3
    );
    assert!(same < 0.002, "tracking its own reference: {same} m");
    assert!(without_push < 0.5 * peak_push, "feedback should recover most of the unmodelled push: {without_push} vs {peak_push}");
}
