//! The whole-body problem linearized with the contact anchors as states
//! (`WholeBodyProblem::anchor_states`): `A` and `B` against central differences of the full
//! step, anchor update included, with feet sticking, slipping and touching down.

use legwork::model::embedded;
use legwork::ocp::{settled_stance, KnotLinearization, RobotState, TaskSpec, WholeBodyProblem};
use legwork::sim::{ContactModelWorkspace, ANCHOR_DIM};
use legwork::slq::{KnotDerivatives, Problem};
use legwork::terrain::Plane;
use nalgebra::{DMatrix, DVector};

/// `x (+) dx` for the extended state: configuration, velocity, and the anchors a foot has.
fn perturbed(problem: &WholeBodyProblem<'_>, x: &RobotState, dx: &DVector<f64>) -> RobotState {
    let nv = problem.model.nv;
    let mut y = x.clone();
    legwork::dynamics::integrate(problem.model, &x.q, &dx.rows(0, nv).into_owned(), &mut y.q);
    for i in 0..nv {
        y.v[i] += dx[nv + i];
    }
    for (f, anchor) in y.anchors.iter_mut().enumerate() {
        if let Some(a) = anchor {
            *a += dx.fixed_rows::<3>(2 * nv + ANCHOR_DIM * f);
        }
    }
    y
}

/// The step's linearization at `(state, u)`, after checking every column of `A` and `B`
/// against central differences of the full step (anchor update included); the columns of a
/// foot without an anchor must be zero.
fn linearization_matching_central_differences(problem: &WholeBodyProblem<'_>, state: &RobotState, u: &DVector<f64>) -> KnotDerivatives {
    let nv = problem.model.nv;
    let (nx, nu) = (problem.nx(), problem.nu());
    let mut ws = problem.workspace();
    let mut d = KnotDerivatives::zeros(nx, nu);
    let mut nominal = state.clone();
    problem.step_with_derivatives(&mut ws, 0, state, u, &mut nominal, &mut d);
    let h = 1e-7;
    let (mut plus, mut minus) = (nominal.clone(), nominal.clone());
    let (mut dplus, mut dminus) = (DVector::zeros(nx), DVector::zeros(nx));
    for k in 0..nx + nu {
        let (mut xp, mut xm, mut up, mut um) = (state.clone(), state.clone(), u.clone(), u.clone());
        if k < nx {
            let anchor_of = (k >= 2 * nv).then(|| (k - 2 * nv) / ANCHOR_DIM);
            if anchor_of.is_some_and(|f| state.anchors[f].is_none()) {
                assert!(d.a.column(k).iter().all(|a| *a == 0.0), "a foot without anchor has zero columns");
                continue;
            }
            let e = DVector::from_fn(nx, |i, _| if i == k { h } else { 0.0 });
            xp = perturbed(problem, state, &e);
            xm = perturbed(problem, state, &(-e));
        } else {
            up[k - nx] += h;
            um[k - nx] -= h;
        }
        problem.step(&mut ws, 0, &xp, &up, &mut plus);
        problem.step(&mut ws, 0, &xm, &um, &mut minus);
        problem.difference(&nominal, &plus, &mut dplus);
        problem.difference(&nominal, &minus, &mut dminus);
        let numeric = (&dplus - &dminus) / (2.0 * h);
        let analytic = if k < nx { d.a.column(k).into_owned() } else { d.b.column(k - nx).into_owned() };
        let err = (&analytic - &numeric).norm() / (1.0 + numeric.norm());
        assert!(err < 1e-5, "column {k}: relative error {err:.2e}\nanalytic {}\nnumeric {}", analytic.transpose(), numeric.transpose());
    }
    d
}

#[test]
fn extended_linearization_matches_central_differences_through_the_anchor_update() {
    let model = embedded::load("hyq").unwrap();
    let ground = Plane::flat(0.0);
    let settled = settled_stance(&model, &ground, 0.3).unwrap();
    // A task on the default contact model, the one the stance was settled on.
    let spec = TaskSpec::embedded("turn").unwrap();
    let mut problem = spec.problem(&model, &ground, settled.clone(), "test").unwrap();
    problem.anchor_states = true;
    let nv = model.nv;
    let (nx, nu) = (problem.nx(), problem.nu());
    assert_eq!(nx, 2 * nv + ANCHOR_DIM * model.feet.len());

    // The settled stance, moving: one foot touching down (no anchor yet), one whose anchor
    // is 5 cm behind (the spring beyond the friction cone: it slips); then a state where
    // every foot sticks, one anchor 1 mm behind.
    let mut x = settled.clone();
    x.v[0] = 0.3;
    x.v[6] = 0.5;
    x.anchors[0] = None;
    x.anchors[1] = x.anchors[1].map(|a| a - nalgebra::Vector3::new(0.05, 0.0, 0.0));
    let mut sticking = settled.clone();
    sticking.anchors[3] = sticking.anchors[3].map(|a| a - nalgebra::Vector3::new(0.001, 0.0, 0.0));
    // A kept knot model serves only states with the same feet anchored (ModelReuse).
    assert!(problem.same_model_piece(&settled, &sticking), "an anchor moved, the same feet down");
    assert!(!problem.same_model_piece(&settled, &x), "foot 0 lost its anchor");
    assert!(!problem.same_model_piece(&x, &settled), "foot 0 gained one");
    let mut ws_contacts = ContactModelWorkspace::new(&model, &ground);
    ws_contacts.evaluate_contacts(&x.q, &x.v, &x.anchors);
    assert!(ws_contacts.feet()[1].contact.slipping, "foot 1 slips");
    assert!(ws_contacts.feet()[0].contact.penetration > 0.0, "foot 0 touches down");
    ws_contacts.evaluate_contacts(&sticking.q, &sticking.v, &sticking.anchors);
    assert!(ws_contacts.feet().iter().all(|f| !f.contact.slipping), "every foot sticks");

    let u = DVector::from_fn(nu, |i, _| 10.0 * (i as f64 - 5.5));
    for state in [&x, &sticking] {
        let d = linearization_matching_central_differences(&problem, state, &u);
        // The foot touching down gets an anchor where it is: its row block reads the foot's motion.
        if state.anchors[0].is_none() {
            let rows = d.a.view((2 * nv, 0), (ANCHOR_DIM, nv));
            assert!(rows.norm() > 0.1, "the planted anchor follows the foot: {rows}");
        }
    }
}

#[test]
fn extended_linearization_with_joints_past_their_stops() {
    // The settled stance of a HyQ whose LF knee and RH hip stops sit inside it: the stops'
    // force and its derivatives enter the extended linearization as in the plain one.
    let hyq = embedded::load("hyq").unwrap();
    let ground = Plane::flat(0.0);
    let settled = settled_stance(&hyq, &ground, 0.3).unwrap();
    let mut model = hyq.clone();
    for (name, upper, penetration) in [("lf_kfe_joint", true, 0.04), ("rh_hfe_joint", false, 0.012)] {
        let id = model.joint_id(name).unwrap();
        let j = &mut model.joints[id];
        let angle = settled.q[j.idx_q];
        if upper {
            j.limits.upper[0] = angle - penetration;
        } else {
            j.limits.lower[0] = angle + penetration;
        }
    }
    let spec = TaskSpec::embedded("turn").unwrap();
    let mut problem = spec.problem(&model, &ground, settled.clone(), "test").unwrap();
    problem.anchor_states = true;
    problem.joint_limits = Some(Default::default());
    let nv = model.nv;
    let (nx, nu) = (problem.nx(), problem.nu());
    let mut x = settled.clone();
    x.v[6 + 2] = 0.4; // LF knee further into its stop
    x.v[6 + 10] = -0.2; // RH HFE further into its stop
    let u = DVector::from_fn(nu, |i, _| 10.0 * (i as f64 - 5.5));
    let d = linearization_matching_central_differences(&problem, &x, &u);
    // Without the stops the knee's own column differs: the stops are in the linearization.
    let mut free = spec.problem(&model, &ground, settled.clone(), "test").unwrap();
    free.joint_limits = None;
    let mut ws_free = free.workspace();
    let mut d_free = KnotDerivatives::zeros(nx, nu);
    free.step_with_derivatives(&mut ws_free, 0, &x, &u, &mut x.clone(), &mut d_free);
    let knee = 6 + 2;
    assert!((d.a[(nv + knee, knee)] - d_free.a[(nv + knee, knee)]).abs() > 1.0, "dv'/dq of the LF knee: {} with stops, {} without", d.a[(nv + knee, knee)], d_free.a[(nv + knee, knee)]);
}

/// A receding window's 5 ms knot held at its first substep's model
/// (`KnotLinearization::FirstSubstep`: `A_1`'s powers by `SubstepProduct::power`, `B` chained by `SubstepProduct::mul`):
/// `A = A_1^5` and `B = sum_i A_1^i B_1` as dense products of the 1 ms substep's own
/// linearization, whichever way each foot's anchor rows go (touching down, slipping,
/// sticking, in the air). The backward pass's `linearize_knot`, which does not integrate the
/// later substeps, gives the same model, cost and derivatives as `step_with_derivatives` to
/// the bit, and `step_with_derivatives` still the exact next state.
#[test]
fn first_substep_knot_is_the_first_substeps_model_chained() {
    let model = embedded::load("hyq").unwrap();
    let ground = Plane::flat(0.0);
    let settled = settled_stance(&model, &ground, 0.3).unwrap();
    let spec = TaskSpec::embedded("turn").unwrap();
    let window = |dt: f64, substeps: usize| {
        let mut p = spec.problem(&model, &ground, settled.clone(), "test").unwrap();
        p.anchor_states = true;
        p.linearization = KnotLinearization::FirstSubstep;
        p.dt = dt;
        p.substeps = substeps;
        p
    };
    let (knot, substep) = (window(0.005, 5), window(0.001, 1));
    let (nx, nu) = (knot.nx(), knot.nu());

    let mut moving = settled.clone();
    moving.v[0] = 0.3;
    moving.v[6] = 0.5;
    moving.anchors[0] = None;
    moving.anchors[1] = moving.anchors[1].map(|a| a - nalgebra::Vector3::new(0.05, 0.0, 0.0));
    let mut flying = settled.clone();
    flying.q[2] += 0.3;
    flying.anchors.iter_mut().for_each(|a| *a = None);
    let u = DVector::from_fn(nu, |i, _| 10.0 * (i as f64 - 5.5));
    let (mut ws_knot, mut ws_substep) = (knot.workspace(), substep.workspace());
    for (name, x) in [("touch-down and slip", &moving), ("standing", &settled), ("in the air", &flying)] {
        let mut one = KnotDerivatives::zeros(nx, nu);
        substep.step_with_derivatives(&mut ws_substep, 0, x, &u, &mut x.clone(), &mut one);
        let (mut a_ref, mut b_ref) = (DMatrix::<f64>::identity(nx, nx), DMatrix::<f64>::zeros(nx, nu));
        for _ in 0..5 {
            b_ref = &one.a * &b_ref + &one.b;
            a_ref = &one.a * &a_ref;
        }
        let mut d = KnotDerivatives::zeros(nx, nu);
        let mut scratch = x.clone();
        let cost = knot.linearize_knot(&mut ws_knot, 0, x, &u, &mut scratch, &mut d);
        let a_err = (&d.a - &a_ref).norm() / a_ref.norm();
        let b_err = (&d.b - &b_ref).norm() / b_ref.norm();
        assert!(a_err < 1e-12 && b_err < 1e-12, "{name}: A off by {a_err:.1e}, B by {b_err:.1e} (relative)");

        let mut exact = KnotDerivatives::zeros(nx, nu);
        let mut next = x.clone();
        let exact_cost = knot.step_with_derivatives(&mut ws_knot, 0, x, &u, &mut next, &mut exact);
        assert_eq!(cost, exact_cost, "{name}: cost");
        assert!(d.a == exact.a && d.b == exact.b && d.l_x == exact.l_x && d.l_xx == exact.l_xx && d.l_u == exact.l_u && d.l_uu == exact.l_uu && d.l_ux == exact.l_ux, "{name}: linearize_knot and step_with_derivatives differ");
        let mut stepped = x.clone();
        knot.step(&mut ws_knot, 0, x, &u, &mut stepped);
        assert!(next.q == stepped.q && next.v == stepped.v && next.anchors == stepped.anchors, "{name}: step_with_derivatives' next state is not the step's");
    }
}
