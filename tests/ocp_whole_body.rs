//! SLQ on the whole-body contact problem, end to end: HyQ asked only for a base 5 cm
//! further forward (no contacts, no gait specified) finds a motion that gets there, and the
//! returned feedforward + feedback policy reaches it again when re-run.

use legwork::control::JointPd;
use legwork::dynamics::difference;
use legwork::model::embedded;
use legwork::ocp::{PdPolicy, RobotState, StateCost, WholeBodyProblem};
use legwork::sim::{standing_on_ground, ContactModelWorkspace, SimConfig, Simulator};
use legwork::slq::{Problem, Slq, SlqSettings, Termination};
use legwork::terrain::Plane;
use nalgebra::DVector;

#[test]
fn hyq_shifts_its_base_forward() {
    let model = embedded::load("hyq").unwrap();
    let ground = Plane::flat(0.0);
    let config = SimConfig::default();
    // Start from a settled stance.
    let q0 = standing_on_ground(&model, &ground, 0.0).unwrap();
    let mut sim = Simulator::new(&model, &ground, config.clone(), q0, None).unwrap();
    let mut stand = JointPd::standing(&model, 0.001).unwrap();
    for _ in 0..2000 {
        sim.step(&mut stand).unwrap();
    }
    let start = sim.state().clone();
    let nv = model.nv;
    let mut target = start.q.clone();
    target[0] += 0.05;
    // Weights per coordinate group: base pose 100, joints 1, velocities 0.1; final x20,
    // final base position 5000.
    let mut running = DVector::zeros(2 * nv);
    running.rows_mut(0, 6).fill(100.0);
    running.rows_mut(6, nv - 6).fill(1.0);
    running.rows_mut(nv, nv).fill(0.1);
    let mut terminal = &running * 20.0;
    terminal.rows_mut(0, 3).fill(5000.0);
    let dt = 0.002;
    let problem = WholeBodyProblem {
        model: &model,
        terrain: &ground,
        joint_limits: config.joint_limits,
        dt,
        substeps: 2,
        knots: 500,
        tail: None,
        initial: RobotState { q: start.q.clone(), v: start.v.clone(), anchors: start.anchors.clone() },
        running: StateCost { q: target.clone(), v: DVector::zeros(nv), weights: running, feet: vec![] },
        terminal: StateCost { q: target.clone(), v: DVector::zeros(nv), weights: terminal, feet: vec![] },
        input_weights: DVector::from_element(nv - 6, 1e-4),
        input_desired: DVector::zeros(nv - 6),
        effort_limits: DVector::from_element(nv - 6, f64::INFINITY),
        waypoints: vec![],
        joint_limit_cost: None,
        feasibility: None,
        anchor_states: false,
        linearization: legwork::ocp::KnotLinearization::EverySubstep,
        receding: None,
    };
    let pd = JointPd::standing(&model, dt).unwrap();
    let sol = Slq::new(&problem, SlqSettings { threads: 2, ..Default::default() }).unwrap().solve(&PdPolicy(&pd), |_| {}).unwrap();
    // The line search rolls out one step size per thread at a time and keeps the largest
    // that decreases the cost: the same steps and trajectory on 1, 2 or 3 threads. Not
    // vacuous: the contact problem rejects full steps.
    let alphas: Vec<f64> = sol.iterations.iter().map(|log| log.alpha).collect();
    assert!(alphas.iter().any(|&a| a < 1.0), "{alphas:?}");
    for threads in [1, 3] {
        let other = Slq::new(&problem, SlqSettings { threads, ..Default::default() }).unwrap().solve(&PdPolicy(&pd), |_| {}).unwrap();
        let steps = |s: &legwork::slq::SlqSolution<RobotState>| s.iterations.iter().map(|log| (log.alpha, log.cost)).collect::<Vec<_>>();
        assert_eq!(steps(&sol), steps(&other), "{threads} threads");
        assert!(sol.states.iter().zip(&other.states).all(|(a, b)| a.q == b.q && a.v == b.v), "{threads} threads");
    }
    let last = sol.states.last().unwrap();
    eprintln!(
        "{:?} after {} iterations; cost {:.3e} -> {:.3e}; final base x {:.4} (target {:.4})",
        sol.termination,
        sol.iterations.len(),
        sol.cost_history[0],
        sol.cost_history.last().unwrap(),
        last.q[0],
        target[0]
    );
    assert!(sol.iterations.len() <= 40);
    assert!(matches!(sol.termination, Termination::Converged | Termination::CostStalled | Termination::NormalizedCostFlat), "{:?}", sol.termination);
    assert!(*sol.cost_history.last().unwrap() < 0.2 * sol.cost_history[0]);
    assert!((last.q[0] - target[0]).abs() < 0.01, "final x {} vs {}", last.q[0], target[0]);
    // Still standing on four feet at the end (the height kept, every foot down).
    assert!((last.q[2] - start.q[2]).abs() < 0.02);
    let mut ws = ContactModelWorkspace::new(&model, &ground);
    ws.evaluate_contacts(&last.q, &last.v, &last.anchors);
    assert!(ws.feet().iter().all(|f| f.contact.normal_force > 0.0));

    // Closed loop: the SLQ policy u = u_ff + K (x (-) x*) from a start kicked sideways
    // (0.2 m/s lateral base velocity, joint velocities off by 0.5 rad/s).
    let mut x = problem.initial_state();
    x.v[1] += 0.2;
    for i in 6..nv {
        x.v[i] += 0.5 * if i % 2 == 0 { 1.0 } else { -1.0 };
    }
    let mut dx = DVector::zeros(2 * nv);
    let mut tau = DVector::zeros(nv);
    let mut largest = 0.0f64;
    for k in 0..problem.knots {
        problem.difference(&sol.states[k], &x, &mut dx);
        largest = largest.max(dx.rows(0, 3).norm());
        let u = &sol.inputs[k] + &sol.gains[k] * &dx;
        tau.rows_mut(6, nv - 6).copy_from(&u);
        ws.step(&mut x.q, &mut x.v, &mut x.anchors, &tau, dt);
    }
    let mut err = DVector::zeros(nv);
    difference(&model, &last.q, &x.q, &mut err);
    eprintln!(
        "closed loop after a kick: largest base deviation {:.2} mm, final x {:.4}, final deviation {:.3} mm",
        largest * 1e3,
        x.q[0],
        err.rows(0, 3).norm() * 1e3
    );
    assert!(largest > 1e-3, "the kick should move the robot off the plan ({largest} m), or the check proves nothing");
    assert!((x.q[0] - target[0]).abs() < 0.01 && err.rows(0, 3).norm() < 0.005);
}

#[test]
fn cost_gradient_with_foot_targets_matches_finite_differences() {
    use legwork::ocp::{FootTarget, Waypoint};
    use legwork::slq::KnotDerivatives;
    use nalgebra::Vector3;
    let model = embedded::load("a1").unwrap();
    let ground = Plane::flat(0.0);
    let initial = legwork::ocp::settled_stance(&model, &ground, 0.2).unwrap();
    let nv = model.nv;
    let mut target = initial.q.clone();
    target[0] += 0.1;
    target[8] += 0.3;
    let weights = DVector::from_fn(2 * nv, |i, _| 1.0 + 0.1 * i as f64);
    let feet = vec![
        FootTarget { foot: 0, position: Vector3::new(0.3, 0.15, 0.1), weights: Vector3::new(100.0, 50.0, 200.0) },
        FootTarget { foot: 3, position: Vector3::new(-0.2, -0.1, 0.0), weights: Vector3::new(10.0, 10.0, 10.0) },
    ];
    let cost = StateCost { q: target.clone(), v: DVector::from_element(nv, 0.1), weights, feet };
    let problem = WholeBodyProblem {
        model: &model,
        terrain: &ground,
        joint_limits: Some(Default::default()),
        dt: 0.002,
        substeps: 2,
        knots: 10,
        tail: None,
        initial: initial.clone(),
        running: cost.clone(),
        terminal: cost.clone(),
        input_weights: DVector::from_element(nv - 6, 1e-3),
        input_desired: DVector::zeros(nv - 6),
        effort_limits: DVector::from_element(nv - 6, f64::INFINITY),
        waypoints: vec![Waypoint { time: 0.004, rho: 1e4, cost }],
        joint_limit_cost: None,
        feasibility: None,
        anchor_states: false,
        linearization: legwork::ocp::KnotLinearization::EverySubstep,
        receding: None,
    };
    let mut ws = problem.workspace();
    let mut x = initial.clone();
    x.v = DVector::from_fn(nv, |i, _| 0.05 * (i as f64).sin());
    let u = DVector::from_fn(nv - 6, |i, _| i as f64 - 4.0);
    let mut next = x.clone();
    let mut d = KnotDerivatives::zeros(2 * nv, nv - 6);
    problem.step_with_derivatives(&mut ws, 2, &x, &u, &mut next, &mut d);
    let h = 1e-6;
    for k in 0..2 * nv {
        let mut dx = DVector::zeros(nv);
        let (mut plus, mut minus) = (x.clone(), x.clone());
        if k < nv {
            dx[k] = h;
            legwork::dynamics::integrate(&model, &x.q, &dx, &mut plus.q);
            legwork::dynamics::integrate(&model, &x.q, &(-&dx), &mut minus.q);
        } else {
            plus.v[k - nv] += h;
            minus.v[k - nv] -= h;
        }
        let fp = problem.step(&mut ws, 2, &plus, &u, &mut next);
        let fm = problem.step(&mut ws, 2, &minus, &u, &mut next);
        let numeric = (fp - fm) / (2.0 * h);
        assert!((numeric - d.l_x[k]).abs() < 1e-5 * (1.0 + numeric.abs()), "l_x[{k}]: {} vs {numeric}", d.l_x[k]);
    }
}

/// The optimizer's dynamics clip the torques at the effort limits as the simulator does: a
/// clipped input acts as its limit and has a zero column in `B`; the others keep theirs,
/// which match central differences of the step.
#[test]
fn inputs_beyond_the_effort_limit_act_as_the_limit_with_zero_sensitivity() {
    use legwork::slq::KnotDerivatives;
    let spec = legwork::ocp::TaskSpec::embedded("squat_jump").unwrap();
    let model = embedded::load("hyq").unwrap();
    let ground = Plane::flat(0.0);
    let initial = legwork::ocp::settled_stance(&model, &ground, 0.2).unwrap();
    let problem = spec.problem(&model, &ground, initial.clone(), "test").unwrap();
    let nu = model.nv - 6;
    assert!(problem.effort_limits.iter().all(|l| *l == 150.0), "HyQ's limits are 150 N m");
    let mut u = DVector::from_fn(nu, |i, _| 20.0 * (i as f64 - 5.0));
    u[1] = 400.0; // beyond the limit
    u[4] = -300.0;
    let mut ws = problem.workspace();
    let mut d = KnotDerivatives::zeros(problem.nx(), nu);
    let mut next = initial.clone();
    problem.step_with_derivatives(&mut ws, 0, &initial, &u, &mut next, &mut d);
    let mut at_limit = u.clone();
    at_limit[1] = 150.0;
    at_limit[4] = -150.0;
    let mut next_limit = initial.clone();
    problem.step(&mut ws, 0, &initial, &at_limit, &mut next_limit);
    assert_eq!(next.q, next_limit.q);
    assert_eq!(next.v, next_limit.v);
    let mut dx = DVector::zeros(problem.nx());
    let h = 1e-4;
    for i in 0..nu {
        let (mut up, mut um) = (u.clone(), u.clone());
        up[i] += h;
        um[i] -= h;
        let (mut xp, mut xm) = (initial.clone(), initial.clone());
        problem.step(&mut ws, 0, &initial, &up, &mut xp);
        problem.step(&mut ws, 0, &initial, &um, &mut xm);
        problem.difference(&xm, &xp, &mut dx);
        let numeric = &dx / (2.0 * h);
        let analytic = d.b.column(i);
        if i == 1 || i == 4 {
            assert_eq!(analytic.norm(), 0.0);
            assert_eq!(numeric.norm(), 0.0);
        } else {
            assert!(analytic.norm() > 1e-3);
            assert!((analytic - &numeric).norm() < 1e-5 * analytic.norm(), "column {i}");
        }
    }
}

/// With `substeps` integration steps per knot (the input held), the knot's state is that of
/// `substeps` simulator steps of `dt / substeps`, and its `A`, `B` (the chain rule over the
/// substeps) match central differences of that whole knot step.
#[test]
fn substepped_knot_is_the_simulators_steps_and_its_linearization_matches_finite_differences() {
    use legwork::slq::KnotDerivatives;
    let spec = legwork::ocp::TaskSpec::embedded("squat_jump").unwrap();
    let model = embedded::load("hyq").unwrap();
    let ground = Plane::flat(0.0);
    let initial = legwork::ocp::settled_stance(&model, &ground, 0.2).unwrap();
    let mut problem = spec.problem(&model, &ground, initial.clone(), "test").unwrap();
    problem.substeps = 4;
    let (nv, nu) = (model.nv, model.nv - 6);
    let mut x = initial.clone();
    x.v = DVector::from_fn(nv, |i, _| 0.1 * (i as f64).sin());
    let u = DVector::from_fn(nu, |i, _| 5.0 * (i as f64 - 5.0));
    let mut ws = problem.workspace();
    let mut d = KnotDerivatives::zeros(problem.nx(), nu);
    let mut next = x.clone();
    problem.step_with_derivatives(&mut ws, 0, &x, &u, &mut next, &mut d);
    // Four simulator steps of 0.5 ms with the same torques.
    let mut sim_ws = ContactModelWorkspace::new(&model, &ground);
    let (mut q, mut v, mut anchors) = (x.q.clone(), x.v.clone(), x.anchors.clone());
    let mut tau = DVector::zeros(nv);
    tau.rows_mut(6, nu).copy_from(&u);
    for _ in 0..4 {
        sim_ws.step(&mut q, &mut v, &mut anchors, &tau, 0.0005);
    }
    assert_eq!(next.q, q);
    assert_eq!(next.v, v);
    assert!(sim_ws.feet().iter().all(|f| f.contact.normal_force > 0.0), "the check should go through the contacts");
    let mut dx = DVector::zeros(problem.nx());
    let mut column = |perturb: &dyn Fn(f64, &mut RobotState, &mut DVector<f64>), h: f64, analytic: nalgebra::DVectorView<f64>, what: String| {
        let (mut xp, mut xm, mut up, mut um) = (x.clone(), x.clone(), u.clone(), u.clone());
        perturb(h, &mut xp, &mut up);
        perturb(-h, &mut xm, &mut um);
        let (mut np, mut nm) = (x.clone(), x.clone());
        problem.step(&mut ws, 0, &xp, &up, &mut np);
        problem.step(&mut ws, 0, &xm, &um, &mut nm);
        problem.difference(&nm, &np, &mut dx);
        let numeric = &dx / (2.0 * h);
        assert!((analytic - &numeric).norm() < 1e-4 * analytic.norm().max(1.0), "{what}: {} vs {}", analytic.transpose(), numeric.transpose());
    };
    for i in 0..nu {
        column(&|h, _, u| u[i] += h, 1e-4, d.b.column(i), format!("B column {i}"));
    }
    // The configuration and velocity columns (with anchor states, `tests/ocp_anchor_states.rs`
    // checks the anchor columns).
    for k in 0..2 * nv {
        let perturb = |h: f64, x: &mut RobotState, _: &mut DVector<f64>| {
            if k < nv {
                let mut dq = DVector::zeros(nv);
                dq[k] = h;
                let q0 = x.q.clone();
                legwork::dynamics::integrate(&model, &q0, &dq, &mut x.q);
            } else {
                x.v[k - nv] += h;
            }
        };
        column(&perturb, 1e-7, d.a.column(k), format!("A column {k}"));
    }
}

/// The feasibility constraints' gradient (friction on the demanded tangential force,
/// penetration, joint limits and speeds) is exact: with heavy penalties and a state that
/// violates each kind (feet pressed 6 mm deeper and dragged sideways, a knee past its
/// limit, a hip too fast), the knot's `l_x` matches central differences of its cost along
/// random tangent directions, anchors included; the friction residual in both of its
/// forms (a force in the robot's weight, and the ratio), the joints' bounds with a margin.
/// `x` moved by `h dx` in the tangent space: the configuration by `integrate`, the
/// velocity and the anchors (3 per foot after `q`, `v`) added.
fn perturbed_state(model: &legwork::model::Model, x: &RobotState, dx: &DVector<f64>, h: f64) -> RobotState {
    let nv = model.nv;
    let mut y = x.clone();
    legwork::dynamics::integrate(model, &x.q, &(dx.rows(0, nv) * h), &mut y.q);
    y.v += dx.rows(nv, nv) * h;
    for (f, a) in y.anchors.iter_mut().enumerate() {
        if let Some(a) = a {
            *a += dx.fixed_rows::<3>(2 * nv + 3 * f) * h;
        }
    }
    y
}

/// The first knot's cost from state `y` under input `u`.
fn knot_cost(problem: &WholeBodyProblem<'_>, y: &RobotState, u: &DVector<f64>) -> f64 {
    let mut ws = problem.workspace();
    let mut next = y.clone();
    problem.step(&mut ws, 0, y, u, &mut next)
}

/// A uniform number in [-1, 1) from a 64-bit LCG state (Knuth's MMIX constants).
fn uniform(seed: &mut u64) -> f64 {
    *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
    ((*seed >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
}

/// The first knot's `l_x` against central differences (step 1e-7) of its cost along six
/// random tangent directions drawn from `seed`, to 1e-4 relative.
fn assert_knot_gradient(model: &legwork::model::Model, problem: &WholeBodyProblem<'_>, x: &RobotState, u: &DVector<f64>, l_x: &DVector<f64>, seed: &mut u64, what: &str) {
    for trial in 0..6 {
        let dx = DVector::from_fn(l_x.len(), |_, _| uniform(seed));
        let h = 1e-7;
        let fd = (knot_cost(problem, &perturbed_state(model, x, &dx, h), u) - knot_cost(problem, &perturbed_state(model, x, &dx, -h), u)) / (2.0 * h);
        let analytic = l_x.dot(&dx);
        assert!((fd - analytic).abs() < 1e-4 * (1.0 + analytic.abs()), "{what}, direction {trial}: finite differences {fd} against l_x . dx = {analytic}");
    }
}

#[test]
fn feasibility_constraint_gradients_match_finite_differences() {
    use legwork::ocp::FrictionForm;
    for (friction_form, joint_limit_margin) in [(FrictionForm::Demand, 0.0), (FrictionForm::Ratio, 0.02)] {
        feasibility_gradient_case(friction_form, joint_limit_margin);
    }
}

fn feasibility_gradient_case(friction_form: legwork::ocp::FrictionForm, joint_limit_margin: f64) {
    use legwork::ocp::{settled_stance, FeasibilityConstraints, FeasibilitySettings, TaskSpec};
    use legwork::slq::KnotDerivatives;
    let text = "name = \"fd\"\nsummary = \"fd\"\nrobot = \"hyq\"\nduration = 0.01\ndt = 0.002\n[running]\nbase_position = [1.0, 1.0, 1.0]\n[final]\n[input]\nweight = 1e-4\n";
    let spec = TaskSpec::from_toml(text, "fd.toml").unwrap();
    let model = embedded::load("hyq").unwrap();
    let ground = Plane::flat(0.0);
    let initial = settled_stance(&model, &ground, 0.3).unwrap();
    let mut problem = spec.problem(&model, &ground, initial.clone(), "fd.toml").unwrap();
    let settings = FeasibilitySettings { friction_penalty: 1e6, penetration_penalty: 1e4, joint_limit_penalty: 1e4, joint_speed_penalty: 1e4, friction_form, joint_limit_margin, ..Default::default() };
    problem.feasibility = Some(FeasibilityConstraints::new(&model, problem.knots, settings).unwrap());
    let mut x = initial.clone();
    x.q[2] -= 0.006;
    x.v[0] = 0.4;
    x.v[1] = -0.2;
    let knee = model.joints.iter().find(|j| j.name == "lf_kfe_joint").unwrap();
    x.q[knee.idx_q] = knee.limits.upper[0] + 0.05;
    let hip = model.joints.iter().find(|j| j.name == "rh_hfe_joint").unwrap();
    x.v[hip.idx_v] = 1.3 * hip.limits.velocity[0];
    let (nx, nu) = (problem.nx(), problem.nu());
    let u = DVector::zeros(nu);
    let mut ws = problem.workspace();
    let mut d = KnotDerivatives::zeros(nx, nu);
    let mut next = x.clone();
    problem.step_with_derivatives(&mut ws, 0, &x, &u, &mut next, &mut d);
    let violation = problem.constraint_violation(std::slice::from_ref(&x)).unwrap();
    assert!(violation.friction > 0.0 && violation.penetration > 0.0 && violation.joint_limit > 0.0 && violation.joint_speed > 0.0, "{violation:?}");
    let mut seed = 7u64;
    assert_knot_gradient(&model, &problem, &x, &u, &d.l_x, &mut seed, &format!("{friction_form:?}"));
    let perturbed = |dx: &DVector<f64>, h: f64| perturbed_state(&model, &x, dx, h);
    let mut r = || uniform(&mut seed);
    // The same terms on the last state (`terminal_knot`; the task has no final cost, so
    // `h` is theirs alone): `h_x` against central differences of `h`.
    problem.feasibility.as_mut().unwrap().settings.terminal_knot = true;
    let (mut h_x, mut h_xx) = (DVector::zeros(nx), nalgebra::DMatrix::zeros(nx, nx));
    let h = problem.terminal_cost_derivatives(&mut problem.workspace(), &x, &mut h_x, &mut h_xx);
    assert!(h > 0.0 && (h - problem.terminal_cost(&mut problem.workspace(), &x)).abs() <= 1e-12 * h, "terminal feasibility cost {h}");
    for trial in 0..4 {
        let dx = DVector::from_fn(nx, |_, _| r());
        let step = 1e-7;
        let terminal = |y: &RobotState| problem.terminal_cost(&mut problem.workspace(), y);
        let fd = (terminal(&perturbed(&dx, step)) - terminal(&perturbed(&dx, -step))) / (2.0 * step);
        let analytic = h_x.dot(&dx);
        assert!((fd - analytic).abs() < 1e-4 * (1.0 + analytic.abs()), "{friction_form:?}, terminal direction {trial}: finite differences {fd} against h_x . dx = {analytic}");
    }
}

/// The relaxed barriers' gradient (issue 16, docs/experiments/feasible-slq-6.md): with the
/// augmented-Lagrangian penalties off and only the barrier on, at a state where the rows sit
/// on both sides of the barrier's switch (`h` above and below `delta`, feet loaded above and
/// below `F_load`, a knee past its limit), the knot's `l_x` matches central differences of
/// its cost along random tangent directions, anchors included.
#[test]
fn relaxed_barrier_gradients_match_finite_differences() {
    use legwork::ocp::{relaxed_barrier, settled_stance, FeasibilityConstraints, FeasibilitySettings, TaskSpec};
    use legwork::slq::KnotDerivatives;
    // The barrier function itself: C2 across the switch, derivatives by differences.
    for delta in [0.1, 0.01] {
        for h in [-0.5, 0.3 * delta, delta, 2.0 * delta, 0.7] {
            let (_, d1, d2) = relaxed_barrier(h, delta);
            let e = 1e-6 * delta;
            let fd1 = (relaxed_barrier(h + e, delta).0 - relaxed_barrier(h - e, delta).0) / (2.0 * e);
            let fd2 = (relaxed_barrier(h + e, delta).1 - relaxed_barrier(h - e, delta).1) / (2.0 * e);
            assert!((fd1 - d1).abs() < 1e-5 * (1.0 + d1.abs()), "h {h}: {fd1} vs {d1}");
            assert!((fd2 - d2).abs() < 1e-4 * (1.0 + d2.abs()), "h {h}: {fd2} vs {d2}");
        }
    }
    let text = "name = \"fd\"\nsummary = \"fd\"\nrobot = \"hyq\"\nduration = 0.01\ndt = 0.002\n[running]\n[final]\n[input]\nweight = 1e-4\n";
    let spec = TaskSpec::from_toml(text, "fd.toml").unwrap();
    let model = embedded::load("hyq").unwrap();
    let ground = Plane::flat(0.0);
    let initial = settled_stance(&model, &ground, 0.3).unwrap();
    let mut problem = spec.problem(&model, &ground, initial.clone(), "fd.toml").unwrap();
    let settings = FeasibilitySettings { friction_penalty: 0.0, penetration_penalty: 0.0, joint_limit_penalty: 0.0, joint_speed_penalty: 0.0, barrier_weight: 50.0, barrier_delta: 0.2, ..Default::default() };
    problem.feasibility = Some(FeasibilityConstraints::new(&model, problem.knots, settings).unwrap());
    let nv = model.nv;
    let knee = model.joints.iter().find(|j| j.name == "lf_kfe_joint").unwrap();
    // The base height at which a foot carries under half of F_load (a tenth of a foot's
    // share of the weight) but more than nothing: the load weight's own gradient.
    let light_load = 0.5 * 0.1 * model.total_mass() * 9.81 / model.feet.len() as f64;
    let mut contacts = legwork::sim::ContactModelWorkspace::new(&model, &ground);
    let light = (0..300)
        .map(|i| 1e-4 * i as f64)
        .find(|&dz| {
            let mut q = initial.q.clone();
            q[2] += dz;
            contacts.evaluate_contacts(&q, &DVector::zeros(nv), &initial.anchors);
            contacts.feet().iter().any(|f| f.contact.normal_force > 0.0 && f.contact.normal_force < light_load)
        })
        .expect("a base height with a lightly loaded foot");
    // Three states: pressed in and dragged (friction and penetration past their bounds),
    // lifted to a light load (F_n under F_load), and the same slid sideways.
    for (case, (dz, vx, vy)) in [(-0.006, 0.4, -0.2), (light, 0.0, 0.0), (light, 0.05, 0.03)].into_iter().enumerate() {
        let mut x = initial.clone();
        x.q[2] += dz;
        x.v[0] = vx;
        x.v[1] = vy;
        x.q[knee.idx_q] = knee.limits.upper[0] + 0.05;
        let (nx, nu) = (problem.nx(), problem.nu());
        let u = DVector::zeros(nu);
        let mut ws = problem.workspace();
        let mut d = KnotDerivatives::zeros(nx, nu);
        let mut next = x.clone();
        let c = problem.step_with_derivatives(&mut ws, 0, &x, &u, &mut next, &mut d);
        assert!(c.is_finite() && (c - problem.step(&mut problem.workspace(), 0, &x, &u, &mut next.clone())).abs() <= 1e-9 * c.abs().max(1.0), "case {case}: cost {c}");
        assert_knot_gradient(&model, &problem, &x, &u, &d.l_x, &mut (11u64 + case as u64), &format!("case {case}"));
    }
}

/// The feet's landing, impact and slide rows (docs/experiments/feasible-slq-7.md): with only
/// those on, at states where they act, the knot's `l_x` matches central differences of its
/// cost along random tangent directions, anchors included. The cases: every foot above the
/// ground inside the landing window (clearance about half of `h_0`, where the window's slope
/// is largest) coming down fast and sideways (landing and impact rows, the feet off the
/// ground: their Jacobians must be there without contact); the feet pressed in and dragged
/// (the slide row's normal-force gradient, the landing row at a window of one); the feet
/// pressed in less than `landing_depth`, where the window fades out again.
#[test]
fn foot_speed_row_gradients_match_finite_differences() {
    use legwork::ocp::{settled_stance, FeasibilityConstraints, FeasibilitySettings, TaskSpec};
    use legwork::slq::KnotDerivatives;
    let text = "name = \"fd\"\nsummary = \"fd\"\nrobot = \"hyq\"\nduration = 0.01\ndt = 0.002\n[running]\n[final]\n[input]\nweight = 1e-4\n";
    let spec = TaskSpec::from_toml(text, "fd.toml").unwrap();
    let model = embedded::load("hyq").unwrap();
    let ground = Plane::flat(0.0);
    let initial = settled_stance(&model, &ground, 0.3).unwrap();
    let mut problem = spec.problem(&model, &ground, initial.clone(), "fd.toml").unwrap();
    let settings = FeasibilitySettings { friction_penalty: 0.0, penetration_penalty: 0.0, joint_limit_penalty: 0.0, joint_speed_penalty: 0.0, landing_penalty: 100.0, impact_penalty: 100.0, slide_penalty: 100.0, foot_speed_from_polish: false, ..Default::default() };
    problem.feasibility = Some(FeasibilityConstraints::new(&model, problem.knots, settings).unwrap());
    let nv = model.nv;
    let hip = model.joints.iter().find(|j| j.name == "lf_hfe_joint").unwrap();
    let mut contacts = legwork::sim::ContactModelWorkspace::new(&model, &ground);
    // (base lift, base velocity x, z): in the window, coming down; pressed in and dragged.
    // A third case: the rows fading out again below the ground (`landing_depth` 8 mm, the
    // feet at about 5.5 mm).
    for (case, (dz, vx, vz, depth)) in [(0.004 + 0.5 * settings.landing_clearance, 0.4, -1.5, f64::INFINITY), (-0.006, 0.3, 0.0, f64::INFINITY), (-0.001, 0.5, -0.3, 0.008)].into_iter().enumerate() {
        problem.feasibility = Some(FeasibilityConstraints::new(&model, problem.knots, FeasibilitySettings { landing_depth: depth, ..settings }).unwrap());
        let mut x = initial.clone();
        x.q[2] += dz;
        x.v[0] = vx;
        x.v[2] = vz;
        x.v[1] = 0.1;
        x.v[hip.idx_v] = 2.0; // the feet's speeds differ
        contacts.evaluate_contacts(&x.q, &x.v, &x.anchors);
        let clearances: Vec<f64> = contacts.feet().iter().map(|f| -f.contact.penetration).collect();
        if case == 0 {
            assert!(clearances.iter().all(|&h| h > 0.0 && h < settings.landing_clearance), "every foot in the window, off the ground: {clearances:?}");
        } else if case == 2 {
            assert!(clearances.iter().all(|&h| h < 0.0 && -h < depth), "every foot in the fade below the ground: {clearances:?}");
        } else {
            assert!(contacts.feet().iter().all(|f| f.contact.normal_force > 0.0), "every foot loaded");
        }
        let (nx, nu) = (problem.nx(), problem.nu());
        let u = DVector::zeros(nu);
        let mut ws = problem.workspace();
        let mut d = KnotDerivatives::zeros(nx, nu);
        let mut next = x.clone();
        let c = problem.step_with_derivatives(&mut ws, 0, &x, &u, &mut next, &mut d);
        let violation = problem.constraint_violation(std::slice::from_ref(&x)).unwrap();
        assert!(violation.foot_speed > 0.0 && c > 0.0, "case {case}: the rows act ({violation:?}, cost {c})");
        assert!((c - problem.step(&mut problem.workspace(), 0, &x, &u, &mut next.clone())).abs() <= 1e-9 * c.abs().max(1.0), "case {case}: cost {c}");
        assert_knot_gradient(&model, &problem, &x, &u, &d.l_x, &mut (23u64 + case as u64), &format!("foot speeds, case {case}"));
    }
    let _ = nv;
}
