//! The landing QP against closed forms, eq. (5)'s torque law against finite differences,
//! and both controllers holding a standing A1 in the simulator.

use super::*;
use crate::io::Trajectory;
use crate::model::embedded;
use crate::sim::{SimConfig, Simulator};
use crate::terrain::{Plane, Terrain};
use nalgebra::{DMatrix, DVector, Matrix3, Rotation3, Vector3};

const MASS: f64 = 12.0;
const G: f64 = 9.81;

fn inertia() -> Matrix3<f64> {
    Matrix3::from_diagonal(&Vector3::new(0.1, 0.3, 0.35))
}

/// Four feet at (+-0.18, +-0.13) around the CoM, 0.25 m below it, flat ground.
fn symmetric_feet(com: &Vector3<f64>) -> Vec<QpFoot> {
    [(0.18, 0.13), (0.18, -0.13), (-0.18, 0.13), (-0.18, -0.13)]
        .iter()
        .map(|&(x, y)| QpFoot { position: com + Vector3::new(x, y, -0.25), normal: Vector3::z(), in_contact: true, leg_jacobian: leg_jacobian(), torque_limit: Vector3::repeat(33.5) })
        .collect()
}

/// A leg Jacobian of the A1's size (0.2 m links), roughly its standing one.
fn leg_jacobian() -> Matrix3<f64> {
    Matrix3::new(0.0, -0.25, -0.1, 0.25, 0.0, 0.0, 0.05, 0.0, 0.15)
}

fn qp() -> LandingQp {
    LandingQp::new(LandingQpSettings::default(), MASS, inertia(), Vector3::new(0.0, 0.0, -G), 4).unwrap()
}

/// The QP without its inequalities: `f = (A^T S A + alpha I)^-1 A^T S b`.
fn unconstrained(settings: &LandingQpSettings, com: &Vector3<f64>, feet: &[QpFoot], b: &nalgebra::Vector6<f64>) -> DVector<f64> {
    let mut a = DMatrix::zeros(6, 12);
    for (f, foot) in feet.iter().enumerate() {
        if !foot.in_contact {
            continue;
        }
        let lever = crate::spatial::skew(&(foot.position - com));
        a.view_mut((0, 3 * f), (3, 3)).copy_from(&Matrix3::identity());
        a.view_mut((3, 3 * f), (3, 3)).copy_from(&lever);
    }
    let s = DMatrix::from_diagonal(&DVector::from_column_slice(settings.wrench_weight.as_slice()));
    let h = a.transpose() * &s * &a + DMatrix::identity(12, 12) * settings.regularization;
    let rhs = a.transpose() * &s * DVector::from_column_slice(b.as_slice());
    h.lu().solve(&rhs).unwrap()
}

#[test]
fn standing_still_each_foot_carries_a_quarter_of_the_weight() {
    let mut qp = qp();
    let com = Vector3::new(0.3, -0.2, 0.3);
    let state = SrbState { com, rotation: Matrix3::identity(), com_velocity: Vector3::zeros(), angular_velocity: Vector3::zeros() };
    let target = SrbTarget { com, rotation: Matrix3::identity() };
    let feet = symmetric_feet(&com);
    let (forces, info) = qp.solve(&state, &target, &feet).unwrap();
    let forces = forces.to_vec();
    for f in &forces {
        assert!((f.z - MASS * G / 4.0).abs() < 1e-3 * MASS * G, "{f}");
        assert!(f.x.abs() < 1e-4 && f.y.abs() < 1e-4, "{f}");
    }
    assert!(info.wrench_residual < 1e-2, "{info:?}");
    // The same as the closed form (no constraint active).
    let b = qp.desired_wrench(&state, &target);
    assert!((b - nalgebra::Vector6::new(0.0, 0.0, MASS * G, 0.0, 0.0, 0.0)).norm() < 1e-12);
    let exact = unconstrained(qp.settings(), &com, &feet, &b);
    for (f, force) in forces.iter().enumerate() {
        for c in 0..3 {
            assert!((force[c] - exact[3 * f + c]).abs() < 1e-5, "foot {f}: {force} vs {:?}", exact.rows(3 * f, 3));
        }
    }
}

#[test]
fn a_tilted_target_stays_inside_the_friction_pyramid_and_the_force_bounds() {
    let mut qp = qp();
    let com = Vector3::new(0.0, 0.0, 0.3);
    // 30 deg of roll and a 10 cm lateral error: the unconstrained forces pull on the ground
    // and exceed the friction the feet have.
    let target = SrbTarget { com: com + Vector3::new(0.0, 0.1, 0.0), rotation: Rotation3::from_euler_angles(0.5, 0.0, 0.0).into_inner() };
    let state = SrbState { com, rotation: Matrix3::identity(), com_velocity: Vector3::new(0.0, -0.5, 0.0), angular_velocity: Vector3::zeros() };
    let feet = symmetric_feet(&com);
    let b = qp.desired_wrench(&state, &target);
    let s = *qp.settings();
    let exact = unconstrained(&s, &com, &feet, &b);
    let violated = (0..4).any(|f| exact[3 * f + 2] < 0.0 || exact[3 * f].abs().max(exact[3 * f + 1].abs()) > s.friction_coefficient * exact[3 * f + 2]);
    assert!(violated, "the test case must need the constraints: {exact}");
    let (forces, _) = qp.solve(&state, &target, &feet).unwrap();
    let mut active = false;
    for f in forces {
        let mu_n = s.friction_coefficient * f.z;
        assert!(f.x.abs() <= mu_n + 1e-6 && f.y.abs() <= mu_n + 1e-6, "outside the pyramid: {f}");
        assert!(f.z >= s.normal_force_min - 1e-6 && f.z <= s.normal_force_max + 1e-6, "outside the bounds: {f}");
        active |= (f.y.abs() - mu_n).abs() < 1e-3 * s.normal_force_max || f.z < 1e-3;
    }
    assert!(active, "some constraint must be active: {forces:?}");
    // And it is the best such forces: the objective is below the clipped closed form's.
    let objective = |fs: &[Vector3<f64>]| {
        let mut w = -b;
        for (foot, f) in feet.iter().zip(fs) {
            let lever = crate::spatial::skew(&(foot.position - com)) * f;
            w += nalgebra::Vector6::new(f.x, f.y, f.z, lever.x, lever.y, lever.z);
        }
        0.5 * w.component_mul(&s.wrench_weight).dot(&w) + 0.5 * s.regularization * fs.iter().map(|f| f.norm_squared()).sum::<f64>()
    };
    let clipped: Vec<Vector3<f64>> = (0..4)
        .map(|f| {
            let z = exact[3 * f + 2].clamp(0.0, s.normal_force_max);
            let m = s.friction_coefficient * z;
            Vector3::new(exact[3 * f].clamp(-m, m), exact[3 * f + 1].clamp(-m, m), z)
        })
        .collect();
    assert!(objective(forces) < objective(&clipped));
}

#[test]
fn the_motors_limit_the_forces() {
    let mut qp = qp();
    let com = Vector3::new(0.0, 0.0, 0.3);
    // A hard stop: 2 m/s downwards asks for 40 m/s^2 (over 500 N per foot).
    let state = SrbState { com, rotation: Matrix3::identity(), com_velocity: Vector3::new(0.0, 0.0, -2.0), angular_velocity: Vector3::zeros() };
    let target = SrbTarget { com, rotation: Matrix3::identity() };
    let mut feet = symmetric_feet(&com);
    for foot in feet.iter_mut() {
        foot.torque_limit = Vector3::new(33.5, 33.5, 10.0);
    }
    let (forces, _) = qp.solve(&state, &target, &feet).unwrap();
    let mut binding = false;
    for (f, foot) in forces.iter().zip(&feet) {
        let tau = foot.leg_jacobian.transpose() * f;
        for k in 0..3 {
            assert!(tau[k].abs() <= foot.torque_limit[k] + 1e-6, "{tau} over {}", foot.torque_limit);
        }
        binding |= (tau[2].abs() - 10.0).abs() < 1e-3;
    }
    assert!(binding, "the knee limit must bind: {forces:?}");
}

#[test]
fn a_foot_in_the_air_carries_nothing_and_the_others_the_weight() {
    let mut qp = qp();
    let com = Vector3::new(0.0, 0.0, 0.3);
    let state = SrbState { com, rotation: Matrix3::identity(), com_velocity: Vector3::zeros(), angular_velocity: Vector3::zeros() };
    let target = SrbTarget { com, rotation: Matrix3::identity() };
    let mut feet = symmetric_feet(&com);
    feet[3].in_contact = false;
    let (forces, _) = qp.solve(&state, &target, &feet).unwrap();
    assert_eq!(forces[3], Vector3::zeros());
    let total: Vector3<f64> = forces.iter().sum();
    assert!((total.z - MASS * G).abs() < 0.02 * MASS * G, "{total}");
    // Three feet, no tangential force needed: the moment about the CoM of the vertical
    // forces is what the residual leaves of zero.
    let (f0, f1, f2) = (forces[0].z, forces[1].z, forces[2].z);
    // The diagonal feet LF (0) and RH (missing) -> RF (1) and LH (2) carry the most.
    assert!(f1 > f0 && f2 > f0, "{forces:?}");
    for f in forces.iter().take(3) {
        assert!(f.z >= -1e-6);
    }
}

fn a1_standing_reference() -> (crate::model::Model, Plane, Trajectory) {
    let model = embedded::load("a1").unwrap();
    let ground = Plane::flat(0.0);
    let reference = check_references::standing_reference(&model, &ground, 1.0).unwrap();
    (model, ground, reference)
}

#[test]
fn eq5_is_the_feed_forward_on_the_reference_and_its_jacobian_off_it() {
    let (model, _, trajectory) = a1_standing_reference();
    let reference = JumpReference::new(&model, &trajectory, PosingTolerance::default()).unwrap();
    let mut sample = ReferenceSample::new(&model);
    reference.sample(&model, 0.123, &mut sample);
    let mut law = JumpTracking::new(&model).unwrap();
    let gains = JumpGains::default();
    let all = [true; 4];
    let mut tau = DVector::zeros(model.nv);
    law.compute(&model, (&sample.q, &sample.v), &sample, &gains, &all, &mut tau);
    assert!((tau.rows(6, 12) - sample.tau.rows(6, 12)).amax() < 1e-9);
    // d tau / d q_k = -(J^T K_p J + K_p,joint) e_k (at zero error, J's own change drops out).
    let mut feet = feet::BaseFrameFeet::new(&model).unwrap();
    feet.evaluate(&model, &sample.q, &sample.v);
    let h = 1e-6;
    for (i, leg) in feet.legs().iter().enumerate() {
        let j = feet.jacobian[i];
        let expected = -(j.transpose() * Matrix3::from_diagonal(&gains.foot_kp) * j) - Matrix3::identity() * gains.joint_kp;
        for k in 0..3 {
            let mut q = sample.q.clone();
            q[leg.q_index[k]] += h;
            let mut tau_h = DVector::zeros(model.nv);
            law.compute(&model, (&q, &sample.v), &sample, &gains, &all, &mut tau_h);
            for r in 0..3 {
                let fd = (tau_h[leg.v_index[r]] - tau[leg.v_index[r]]) / h;
                assert!((fd - expected[(r, k)]).abs() < 1e-3 * (1.0 + expected[(r, k)].abs()), "leg {i} row {r} col {k}: {fd} vs {}", expected[(r, k)]);
            }
        }
        // And the velocity columns: -(J^T K_d J + K_d,joint).
        let expected = -(j.transpose() * Matrix3::from_diagonal(&gains.foot_kd) * j) - Matrix3::identity() * gains.joint_kd;
        let mut v = sample.v.clone();
        v[leg.v_index[1]] += 1.0;
        let mut tau_v = DVector::zeros(model.nv);
        law.compute(&model, (&sample.q, &v), &sample, &gains, &all, &mut tau_v);
        for r in 0..3 {
            assert!((tau_v[leg.v_index[r]] - tau[leg.v_index[r]] - expected[(r, 1)]).abs() < 1e-9);
        }
    }
}

#[test]
fn the_feed_forward_is_held_over_each_interval_as_the_plan_applied_it() {
    // The plan's torques are piecewise constant (semi-implicit Euler, `u_k` over
    // `[t_k, t_k+1)`): sampled anywhere in an interval, the feed-forward is its knot's,
    // not a blend towards the next (which would halve a last stance push).
    let (model, _, mut trajectory) = a1_standing_reference();
    let dt = trajectory.knots[1].t - trajectory.knots[0].t;
    for (k, knot) in trajectory.knots.iter_mut().enumerate() {
        knot.tau.iter_mut().for_each(|t| *t = if k % 2 == 0 { 10.0 } else { -10.0 });
    }
    let reference = JumpReference::new(&model, &trajectory, PosingTolerance::default()).unwrap();
    let mut sample = ReferenceSample::new(&model);
    for (k, s) in [(10, 0.0), (10, 0.5), (11, 0.25), (11, 0.999)] {
        let t = trajectory.knots[k].t + s * dt;
        reference.sample(&model, t, &mut sample);
        let expected = trajectory.knots[k].tau[0];
        assert!(sample.tau.rows(6, 12).iter().all(|&x| x == expected), "t = {t}: {:?}, expected {expected}", sample.tau.rows(6, 12));
    }
}

/// The A1's standing reference with each knot's torques set to its index (a sample says
/// which knot's feed-forward it holds), every foot down, and `lifting` in the air from knot
/// 11 on; and the knot interval.
fn numbered_reference_lifting_at_knot_11(lifting: &[usize]) -> (crate::model::Model, Trajectory, f64) {
    let (model, _, mut trajectory) = a1_standing_reference();
    let dt = trajectory.knots[1].t - trajectory.knots[0].t;
    for (k, knot) in trajectory.knots.iter_mut().enumerate() {
        knot.tau.iter_mut().for_each(|t| *t = k as f64);
        knot.in_contact = vec![true; model.feet.len()];
        if k >= 11 {
            lifting.iter().for_each(|&f| knot.in_contact[f] = false);
        }
    }
    (model, trajectory, dt)
}

#[test]
fn a_lifting_leg_ends_its_push_the_lift_off_lead_early_and_the_others_keep_the_plans_timing() {
    // Knot 11 is foot 0's lift-off knot (in contact at 10, not at 11); every other foot
    // stays down. Each knot's torques are its index, so the sample says which knot's it is.
    let (model, trajectory, dt) = numbered_reference_lifting_at_knot_11(&[0]);
    let lead = 0.004;
    let reference = JumpReference::new(&model, &trajectory, PosingTolerance::default()).unwrap().with_lift_off_lead(lead).unwrap();
    let lifting: Vec<usize> = crate::control::whole_body::leg_chains(&model).unwrap().into_iter().find(|l| l.foot == 0).unwrap().v_index.to_vec();
    let mut sample = ReferenceSample::new(&model);
    let knot_of = |sample: &ReferenceSample, i: usize| sample.tau[i];
    for (t, lifting_knot) in [(10.0 * dt, 10.0), (11.0 * dt - lead - 1e-4, 10.0), (11.0 * dt - lead + 1e-4, 11.0), (11.0 * dt - 1e-4, 11.0), (11.5 * dt, 11.0), (12.0 * dt - 1e-4, 11.0)] {
        let t = trajectory.knots[0].t + t;
        reference.sample(&model, t, &mut sample);
        for i in 6..model.nv {
            let expected = if lifting.contains(&i) { lifting_knot } else { (((t - trajectory.knots[0].t) / dt) + 1e-9).floor() };
            assert_eq!(knot_of(&sample, i), expected, "t = {t}, dof {i}");
        }
    }
    // Without the lead (the default), the plan's timing everywhere.
    let plain = JumpReference::new(&model, &trajectory, PosingTolerance::default()).unwrap();
    plain.sample(&model, trajectory.knots[0].t + 11.0 * dt - 1e-4, &mut sample);
    assert!(lifting.iter().all(|&i| sample.tau[i] == 10.0));
    // More than one interval is refused.
    assert!(JumpReference::new(&model, &trajectory, PosingTolerance::default()).unwrap().with_lift_off_lead(1.5 * dt).is_err());
}

#[test]
fn posing_starts_where_the_joints_stop_moving() {
    let (model, _, mut trajectory) = a1_standing_reference();
    // The joints move until knot 60, then hold the final configuration.
    for k in 0..60 {
        let knot = &mut trajectory.knots[k];
        knot.q[7] += 0.01 * (60 - k) as f64;
        knot.v[6] = -1.0;
    }
    let reference = JumpReference::new(&model, &trajectory, PosingTolerance::default()).unwrap();
    assert!((reference.t_posing() - 0.60).abs() < 1e-12, "{}", reference.t_posing());
}

/// Runs `controller` on the standing A1 for `duration` s; the base's largest distance
/// from where it started.
fn hold(model: &crate::model::Model, ground: &dyn Terrain, reference: &Trajectory, controller: &mut JumpController, duration: f64) -> f64 {
    let q0 = DVector::from_column_slice(&reference.knots[0].q);
    let mut sim = Simulator::new(model, ground, SimConfig::default(), q0.clone(), None).unwrap();
    let mut drift: f64 = 0.0;
    while sim.state().t < duration {
        controller.sense(sim.feet());
        sim.step(controller).unwrap();
        drift = drift.max((sim.state().q.rows(0, 3) - q0.rows(0, 3)).norm());
    }
    drift
}

#[test]
fn the_jumping_controller_holds_a_standing_reference() {
    let (model, ground, trajectory) = a1_standing_reference();
    // T_posing at the reference's end: the switch cannot happen in the first second.
    let reference = JumpReference::new(&model, &trajectory, PosingTolerance::default()).unwrap();
    let pre = reference.pre_landing().clone();
    let reference = reference.with_posing(1.0, &pre).unwrap();
    let mut controller = JumpController::new(&model, reference, JumpGains::default(), LandingSettings::default(), LegExtension::default()).unwrap();
    let drift = hold(&model, &ground, &trajectory, &mut controller, 0.9);
    assert_eq!(controller.switch().switched_at(), None);
    assert!(drift < 5e-3, "base moved {drift} m");
}

#[test]
fn the_landing_controller_holds_a_standing_robot_with_its_qp() {
    let (model, ground, trajectory) = a1_standing_reference();
    // The whole reference is "posing": the loaded feet switch to landing at once.
    let reference = JumpReference::new(&model, &trajectory, PosingTolerance::default()).unwrap();
    assert_eq!(reference.t_posing(), 0.0);
    let mut controller = JumpController::new(&model, reference, JumpGains::default(), LandingSettings::default(), LegExtension::default()).unwrap();
    let drift = hold(&model, &ground, &trajectory, &mut controller, 1.0);
    assert!(controller.switch().switched_at().is_some_and(|t| t <= 1e-3));
    assert_eq!(controller.switch().in_contact(), &[true; 4]);
    let stats = controller.stats();
    assert!(stats.qp_solves >= 999 && stats.qp_failures == 0, "{stats:?}");
    assert!(drift < 1e-2, "base moved {drift} m");
    // The QP carries the robot: its forces add up to the weight.
    let total: Vector3<f64> = controller.commanded_forces().iter().sum();
    assert!((total.z - model.total_mass() * G).abs() < 0.05 * model.total_mass() * G, "{total}");
}

#[test]
fn a_sideways_drop_lands_upright_near_its_target() {
    let model = embedded::load("a1").unwrap();
    let ground = Plane::flat(0.0);
    let reference = check_references::drop_reference(&model, &ground, 0.15, 0.6).unwrap();
    let settings = JumpSettings::default();
    let run = run_jump(&model, &ground, &reference, &settings).unwrap();
    assert!(run.failure.is_none() && !run.fell, "{:?}", run.failure);
    // Falling from the first step, touching down after about sqrt(2 h / g) = 0.175 s.
    assert!(run.lift_off.is_some_and(|t| t < 0.01), "{:?}", run.lift_off);
    let td = run.touch_down.unwrap();
    assert!((td - 0.175).abs() < 0.03, "touch-down at {td}");
    assert!(run.switch.is_some_and(|t| (t - td).abs() < 2e-3), "{:?} vs {td}", run.switch);
    assert!(run.roll < 2f64.to_radians() && run.pitch < 2f64.to_radians(), "roll {} pitch {}", run.roll, run.pitch);
    assert!(run.position_error < 0.05, "{} m from the target", run.position_error);
    assert!(run.yaw_error.abs() < 2f64.to_radians());
    assert_eq!(run.controller.qp_failures, 0);
    let duration = run.trajectory.knots.last().unwrap().t;
    assert!((duration - (td + 1.0)).abs() < 0.011, "{duration}");
}

#[test]
fn the_release_lead_grows_with_the_last_push_and_stops_at_the_interval() {
    // Feet 0 and 1 lift off at knot 11 after pushes of 260 N and 20 N; foot 2 after 1e6 N
    // (a lead longer than the interval is cut to it); foot 3 stays down. Each knot's torques
    // are its index, so the sample says which knot's feed-forward a leg gets.
    let (model, mut trajectory, dt) = numbered_reference_lifting_at_knot_11(&[0, 1, 2]);
    for (k, knot) in trajectory.knots.iter_mut().enumerate() {
        knot.contact_force = vec![[0.0, 0.0, 50.0]; model.feet.len()];
        if k == 10 {
            knot.contact_force[0][2] = 260.0;
            knot.contact_force[1][2] = 20.0;
            knot.contact_force[2][2] = 1e6;
        }
    }
    let (k_n, v_r) = (28_000.0, 2.3);
    let reference = JumpReference::new(&model, &trajectory, PosingTolerance::default()).unwrap().with_lift_off_release(k_n, v_r).unwrap();
    let legs = crate::control::whole_body::leg_chains(&model).unwrap();
    let dofs_of = |foot: usize| legs.iter().find(|l| l.foot == foot).unwrap().v_index;
    let mut sample = ReferenceSample::new(&model);
    let t_lift = trajectory.knots[0].t + 11.0 * dt;
    // Switches between `t_lift - lead` (knot 10's push) and after it (knot 11's).
    let switches = |sample: &mut ReferenceSample, foot: usize, lead: f64| {
        reference.sample(&model, t_lift - lead - 1e-5, sample);
        let before = sample.tau[dofs_of(foot)[0]];
        reference.sample(&model, t_lift - lead + 1e-5, sample);
        let after = sample.tau[dofs_of(foot)[0]];
        (before, after)
    };
    let lead_260 = 260.0 / k_n / v_r;
    assert!((0.003..0.005).contains(&lead_260));
    assert_eq!(switches(&mut sample, 0, lead_260), (10.0, 11.0));
    let lead_20 = 20.0 / k_n / v_r;
    assert_eq!(switches(&mut sample, 1, lead_20), (10.0, 11.0));
    // The lightly loaded foot is still pushing where the hard one has stopped.
    reference.sample(&model, t_lift - 0.5 * lead_260, &mut sample);
    assert_eq!((sample.tau[dofs_of(0)[0]], sample.tau[dofs_of(1)[0]]), (11.0, 10.0));
    // At most one interval: foot 2 gets knot 11's torques over all of knot 10's interval.
    reference.sample(&model, t_lift - dt + 1e-5, &mut sample);
    assert_eq!(sample.tau[dofs_of(2)[0]], 11.0);
    // A stance foot keeps the plan's timing.
    reference.sample(&model, t_lift - 1e-5, &mut sample);
    assert_eq!(sample.tau[dofs_of(3)[0]], 10.0);
    assert!(JumpReference::new(&model, &trajectory, PosingTolerance::default()).unwrap().with_lift_off_release(0.0, v_r).is_err());
}
