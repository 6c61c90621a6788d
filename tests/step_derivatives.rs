//! The analytic linearization of the simulator step (`A`, `B` of the SLQ problem) against
//! central finite differences in the tangent space: four feet in contact, feet sliding
//! towards their anchors, a foot in the air, a free-falling robot.

use legwork::control::JointPd;
use legwork::dynamics::{difference, integrate};
use legwork::model::{embedded, Model};
use legwork::sim::{standing_on_ground, ContactModelWorkspace, SimConfig, Simulator, StepDerivatives};
use legwork::terrain::{Plane, Terrain};
use nalgebra::{DMatrix, DVector, Vector3};

struct State {
    q: DVector<f64>,
    v: DVector<f64>,
    anchors: Vec<Option<Vector3<f64>>>,
    tau: DVector<f64>,
}

/// A state after `settle` seconds of standing (from `drop` m up), with a velocity offset.
fn state(model: &Model, terrain: &dyn Terrain, drop: f64, settle: f64, dv: f64) -> State {
    let q0 = standing_on_ground(model, terrain, drop).unwrap();
    let mut sim = Simulator::new(model, terrain, SimConfig::default(), q0, None).unwrap();
    let mut stand = JointPd::standing(model, 0.001).unwrap();
    for _ in 0..(settle / 0.0005) as usize {
        sim.step(&mut stand).unwrap();
    }
    let s = sim.state();
    let mut v = s.v.clone();
    for (i, x) in v.iter_mut().enumerate() {
        *x += dv * ((i as f64 * 1.7).sin());
    }
    State { q: s.q.clone(), v, anchors: s.anchors.clone(), tau: sim.applied_torque().clone() }
}

/// Next state by the plain step.
fn step(ws: &mut ContactModelWorkspace<'_>, s: &State, q: &DVector<f64>, v: &DVector<f64>, tau: &DVector<f64>, dt: f64) -> (DVector<f64>, DVector<f64>) {
    let (mut q, mut v, mut anchors) = (q.clone(), v.clone(), s.anchors.clone());
    ws.step(&mut q, &mut v, &mut anchors, tau, dt);
    (q, v)
}

fn check(model: &Model, terrain: &dyn Terrain, s: &State, what: &str) {
    let dt = 0.0005;
    let nv = model.nv;
    let mut ws = ContactModelWorkspace::new(model, terrain).with_joint_limits(Some(Default::default()));
    let mut deriv = StepDerivatives::new(model);
    let (mut q1, mut v1, mut anchors) = (s.q.clone(), s.v.clone(), s.anchors.clone());
    deriv.step(&mut ws, &mut q1, &mut v1, &mut anchors, &s.tau, dt);
    // Same next state as the simulator's step.
    let (q_ref, v_ref) = step(&mut ws, s, &s.q, &s.v, &s.tau, dt);
    assert!((&q1 - &q_ref).norm() < 1e-14 && (&v1 - &v_ref).norm() < 1e-14, "{what}: next state differs");

    let h = 1e-6;
    let mut fd_a = DMatrix::zeros(2 * nv, 2 * nv);
    let mut fd_b = DMatrix::zeros(2 * nv, nv - 6);
    let mut dq = DVector::zeros(model.nq);
    let column = |plus: (DVector<f64>, DVector<f64>), minus: (DVector<f64>, DVector<f64>)| {
        let mut dp = DVector::zeros(nv);
        let mut dm = DVector::zeros(nv);
        difference(model, &q_ref, &plus.0, &mut dp);
        difference(model, &q_ref, &minus.0, &mut dm);
        let mut col = DVector::zeros(2 * nv);
        col.rows_mut(0, nv).copy_from(&((dp - dm) / (2.0 * h)));
        col.rows_mut(nv, nv).copy_from(&((plus.1 - minus.1) / (2.0 * h)));
        col
    };
    for k in 0..nv {
        let mut e = DVector::zeros(nv);
        e[k] = h;
        integrate(model, &s.q, &e, &mut dq);
        let plus = step(&mut ws, s, &dq, &s.v, &s.tau, dt);
        integrate(model, &s.q, &(-&e), &mut dq);
        let minus = step(&mut ws, s, &dq, &s.v, &s.tau, dt);
        fd_a.set_column(k, &column(plus, minus));
        let plus = step(&mut ws, s, &s.q, &(&s.v + &e), &s.tau, dt);
        let minus = step(&mut ws, s, &s.q, &(&s.v - &e), &s.tau, dt);
        fd_a.set_column(nv + k, &column(plus, minus));
        if k >= 6 {
            let plus = step(&mut ws, s, &s.q, &s.v, &(&s.tau + &e), dt);
            let minus = step(&mut ws, s, &s.q, &s.v, &(&s.tau - &e), dt);
            fd_b.set_column(k - 6, &column(plus, minus));
        }
    }
    // Compare block by block, relative to the block's size.
    for (name, analytic, numeric) in [("A", &deriv.a, &fd_a), ("B", &deriv.b, &fd_b)] {
        for (rows, cols, block) in [((0, nv), (0, nv), "q'/q"), ((0, nv), (nv, nv), "q'/v"), ((nv, nv), (0, nv), "v'/q"), ((nv, nv), (nv, nv), "v'/v")] {
            if name == "B" && cols.0 > 0 {
                continue;
            }
            let c = if name == "B" { (0, nv - 6) } else { cols };
            let a = analytic.view((rows.0, c.0), (rows.1, c.1));
            let n = numeric.view((rows.0, c.0), (rows.1, c.1));
            let err = (a - n).norm() / (1.0 + n.norm());
            assert!(err < 1e-6, "{what}: {name} block {block}: relative error {err:.2e}\nanalytic\n{a:.4}\nnumeric\n{n:.4}");
        }
    }
}

#[test]
fn standing_on_four_feet() {
    let model = embedded::load("hyq").unwrap();
    let ground = Plane::flat(0.0);
    let s = state(&model, &ground, 0.0, 0.4, 0.05);
    check(&model, &ground, &s, "HyQ standing");
}

#[test]
fn landing_on_an_incline_with_one_foot_in_the_air() {
    // A1 dropped onto a 10 % slope: after 0.12 s some feet touch, the state is moving fast.
    let model = embedded::load("a1").unwrap();
    let slope = Plane::new(0.0, Vector3::new(-0.1, 0.05, 1.0)).unwrap();
    let s = state(&model, &slope, 0.05, 0.105, 0.3);
    let mut ws = ContactModelWorkspace::new(&model, &slope);
    ws.evaluate_contacts(&s.q, &s.v, &s.anchors);
    let touching = ws.feet().iter().filter(|f| f.contact.normal_force > 0.0).count();
    assert!((1..4).contains(&touching), "wanted a partial contact, got {touching} feet down");
    check(&model, &slope, &s, "A1 landing on a slope");
}

#[test]
fn in_flight() {
    let model = embedded::load("hyq").unwrap();
    let ground = Plane::flat(0.0);
    let s = state(&model, &ground, 0.5, 0.05, 0.5);
    check(&model, &ground, &s, "HyQ in flight");
}

/// `model` with position limits moved next to the configuration `q`: for each
/// `(joint, upper, penetration)` that joint's upper (or lower) stop is put `penetration`
/// rad inside `q`'s angle, so that `q` is that far past it.
fn with_stops_past(model: &Model, q: &DVector<f64>, stops: &[(&str, bool, f64)]) -> Model {
    let mut model = model.clone();
    for &(name, upper, penetration) in stops {
        let id = model.joint_id(name).unwrap();
        let j = &mut model.joints[id];
        let angle = q[j.idx_q];
        if upper {
            j.limits.upper[0] = angle - penetration;
        } else {
            j.limits.lower[0] = angle + penetration;
        }
    }
    model
}

#[test]
fn standing_with_joints_past_their_stops() {
    // Four feet in contact and four stops engaged: past the smoothing band (0.03, 0.05 rad),
    // inside it (0.01 rad), and one inside it whose joint leaves the stop fast enough that
    // the damper's push is clamped to zero (k s + d s' pdot = 12.5 - 25 N m).
    let hyq = embedded::load("hyq").unwrap();
    let ground = Plane::flat(0.0);
    let mut s = state(&hyq, &ground, 0.0, 0.4, 0.05);
    let model = with_stops_past(&hyq, &s.q, &[("lf_kfe_joint", true, 0.03), ("rh_kfe_joint", false, 0.01), ("lh_hfe_joint", false, 0.05), ("rf_haa_joint", true, 0.01)]);
    let rf_haa = model.joints[model.joint_id("rf_haa_joint").unwrap()].idx_v;
    s.v[rf_haa] = -10.0;
    let ws = ContactModelWorkspace::new(&model, &ground).with_joint_limits(Some(Default::default()));
    let mut tau = DVector::zeros(model.nv);
    ws.joint_stops().add_torques(&s.q, &s.v, &mut tau);
    assert_eq!(tau.iter().filter(|t| **t != 0.0).count(), 3, "three stops push, the fourth is clamped: {tau}");
    check(&model, &ground, &s, "HyQ standing past its stops");
}

#[test]
fn in_flight_with_joints_past_their_stops() {
    let hyq = embedded::load("hyq").unwrap();
    let ground = Plane::flat(0.0);
    let s = state(&hyq, &ground, 0.5, 0.05, 0.5);
    let model = with_stops_past(&hyq, &s.q, &[("lf_kfe_joint", true, 0.3), ("rf_kfe_joint", true, 0.015), ("lh_haa_joint", false, 0.1), ("rh_hfe_joint", true, 0.005)]);
    check(&model, &ground, &s, "HyQ in flight past its stops");
}
