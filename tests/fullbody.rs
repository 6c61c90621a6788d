//! Nguyen 2022's full-body pipeline (sec. II-C): the SRB solution read back and resampled,
//! the full-body initial guess, the full-body stages' derivatives against finite
//! differences, and the lateral jump solved end to end within every limit.

use legwork::dynamics::{center_of_mass, forward_kinematics, frame_position, Data};
use legwork::fullbody::{initial_guess, BoxObstacle, FullBodyError, FullBodyProblem, FullBodySettings};
use legwork::ipocp::{Settings, Stage, StageMultipliers, Status};
use legwork::model::embedded;
use legwork::srb::{jumps, ContactTimingProblem, ContactTimingSettings, SrbParams, SrbSolutionError, SrbTrajectory};
use nalgebra::{DMatrix, DVector};

#[path = "support/stage_fd.rs"]
mod stage_fd;
use stage_fd::assert_jacobians_match_central_differences;

/// The contact-timing solution of `name` (exact exponential, the default settings).
fn srb_solution(name: &str) -> SrbTrajectory {
    let params = SrbParams::a1().unwrap();
    let jump = jumps().into_iter().find(|j| j.name == name).unwrap();
    let ct = ContactTimingProblem::new(&jump, &params, &ContactTimingSettings::default()).unwrap();
    let mut solver = ct.solver(Settings::default()).unwrap();
    let r = ct.solve(&mut solver).unwrap();
    assert_eq!(r.status, Status::Solved);
    SrbTrajectory::from_solution(&ct, &r.last.primal).unwrap()
}

#[test]
fn srb_solution_reads_back_and_resamples_on_the_10ms_grid() {
    let srb = srb_solution("lateral30");
    assert_eq!(srb.knots.len(), 61);
    let total: f64 = srb.phase_durations.iter().sum();
    assert!((srb.knots[60].t - total).abs() < 1e-12);
    // Stance feet at their contact points, the forward-Euler step of the CoM holds.
    for w in srb.knots.windows(2) {
        let dt = w[1].t - w[0].t;
        assert!((w[0].com + w[0].com_velocity * dt - w[1].com).norm() < 1e-6);
    }
    let r = srb.resample(0.01).unwrap();
    let n: Vec<usize> = srb.phase_durations.iter().map(|t| (t / 0.01).round() as usize).collect();
    assert_eq!(r.phase_knots, n);
    assert_eq!(r.knots.len(), n.iter().sum::<usize>() + 1);
    for (k, knot) in r.knots.iter().enumerate() {
        assert!((knot.t - 0.01 * k as f64).abs() < 1e-12);
        assert!((knot.rotation.transpose() * knot.rotation - nalgebra::Matrix3::identity()).amax() < 1e-9);
        let phase = r.phase_of_knot(k);
        if k < r.knots.len() - 1 {
            assert_eq!(knot.contacts, r.phase_contacts[phase]);
        }
    }
    assert!((r.knots[0].com - srb.knots[0].com).norm() < 1e-12);
    assert!((r.knots.last().unwrap().com - srb.knots.last().unwrap().com).norm() < 1e-12);
    // The phase switch (lift-off) is a grid point with the SRB state of the switch.
    let lift = n[0];
    assert!((r.knots[lift].com - srb.knots[30].com).norm() < 1e-12);
    assert_eq!(srb.resample(0.0).unwrap_err(), SrbSolutionError::Step(0.0));
}

#[test]
fn srb_solution_rejects_a_primal_of_another_problem() {
    let params = SrbParams::a1().unwrap();
    let jump = jumps().into_iter().find(|j| j.name == "lateral30").unwrap();
    let ct = ContactTimingProblem::new(&jump, &params, &ContactTimingSettings::default()).unwrap();
    let err = SrbTrajectory::from_solution(&ct, &ct.guess[..10]).unwrap_err();
    assert_eq!(err, SrbSolutionError::Stages { got: 10, expected: 61 });
    let mut bad = ct.guess.clone();
    bad[0][18] = -0.1;
    assert_eq!(SrbTrajectory::from_solution(&ct, &bad).unwrap_err(), SrbSolutionError::Duration { phase: 0, value: -0.1 });
}

#[test]
fn initial_guess_legs_reach_their_contact_points() {
    let model = embedded::load("a1").unwrap();
    let srb = srb_solution("lateral30").resample(0.01).unwrap();
    let guess = initial_guess(&model, &srb, 8).unwrap();
    assert_eq!(guess.knots.len(), srb.knots.len());
    guess.validate("guess").unwrap();
    let mut data = Data::new(&model);
    let nk = guess.knots.len();
    for (k, knot) in guess.knots.iter().enumerate() {
        let q = DVector::from_column_slice(&knot.q);
        forward_kinematics(&model, &mut data, &q);
        for f in 0..4 {
            if knot.in_contact[f] {
                let p = frame_position(&model, &data, model.feet[f].frame);
                assert!((p - srb.knots[k].feet[f]).norm() < 1e-6, "knot {k} foot {f}: {p} vs {}", srb.knots[k].feet[f]);
            }
        }
        // The base carries the nominal CoM offset: the CoM is the SRB's up to the legs' motion
        // and the base's shift towards feet the SRB puts out of the legs' reach near lift-off
        // (5.5 cm at most here; none while standing at the start).
        let com = center_of_mass(&model, &mut data, &q);
        let bound = if k == 0 { 5e-3 } else { 0.06 };
        assert!((com - srb.knots[k].com).norm() < bound, "knot {k}: CoM {com} vs {}", srb.knots[k].com);
        // Pre-landing: the same joint angles over the last 8 knots and the last.
        if k >= nk - 9 {
            assert_eq!(knot.q[7..], guess.knots[nk - 1].q[7..]);
        }
    }
    // The SRB's forces, and the torques that hold them.
    for f in 0..4 {
        let e = srb.knots[0].forces[f];
        assert_eq!(guess.knots[0].contact_force[f], [e.x, e.y, e.z]);
    }
    assert!(guess.knots[0].tau.iter().any(|t| t.abs() > 1.0));
    assert!(guess.knots[0].v.iter().all(|&v| v == 0.0));
}

#[test]
fn initial_guess_moves_the_base_towards_out_of_reach_feet_without_a_jump() {
    // lateral_down's SRB plan puts the CoM beyond the legs' reach over the last stance knots;
    // the guess moves the base towards the feet there. Moved knot by knot, the base jumped
    // 14 cm within one 10 ms step before lift-off (12.8 m/s in the guess; the dynamics rows spent
    // ~40 iterations undoing); smoothed over +-5 knots, its speed stays near the SRB's.
    let model = embedded::load("a1").unwrap();
    let srb = srb_solution("lateral_down").resample(0.01).unwrap();
    let guess = initial_guess(&model, &srb, 8).unwrap();
    let srb_speed = srb.knots.iter().map(|k| k.com_velocity.norm()).fold(0.0, f64::max);
    let base_speed = guess.knots.iter().map(|k| (k.v[0] * k.v[0] + k.v[1] * k.v[1] + k.v[2] * k.v[2]).sqrt()).fold(0.0, f64::max);
    assert!(base_speed < srb_speed + 1.0, "base speed {base_speed:.2} m/s against the SRB's {srb_speed:.2} m/s");
    // The stance feet still reach their contact points.
    let mut data = Data::new(&model);
    for (k, knot) in guess.knots.iter().enumerate() {
        forward_kinematics(&model, &mut data, &DVector::from_column_slice(&knot.q));
        for f in (0..4).filter(|&f| knot.in_contact[f]) {
            let p = frame_position(&model, &data, model.feet[f].frame);
            assert!((p - srb.knots[k].feet[f]).norm() < 1e-6, "knot {k} foot {f}");
        }
    }
}

#[test]
fn initial_guess_rejects_a_pre_landing_window_longer_than_the_flight() {
    let model = embedded::load("a1").unwrap();
    let srb = srb_solution("lateral30").resample(0.01).unwrap();
    let n = srb.knots.len();
    assert!(matches!(initial_guess(&model, &srb, n).unwrap_err(), FullBodyError::Setting { field: "pre_landing_knots", .. }));
    assert!(matches!(initial_guess(&model, &srb, n - 5).unwrap_err(), FullBodyError::Guess(_)));
}

/// Deterministic pseudo-random numbers in [-1, 1).
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }
}

/// The lateral jump's full-body problem, with a box under the right half of the start
/// (only for the derivative test: the lateral jump starts on flat ground).
fn lateral_problem(obstacle: Option<BoxObstacle>) -> (FullBodyProblem, legwork::io::Trajectory) {
    lateral_problem_with(FullBodySettings::default(), obstacle)
}

fn lateral_problem_with(settings: FullBodySettings, obstacle: Option<BoxObstacle>) -> (FullBodyProblem, legwork::io::Trajectory) {
    let model = embedded::load("a1").unwrap();
    let srb = srb_solution("lateral30").resample(0.01).unwrap();
    let guess = initial_guess(&model, &srb, settings.pre_landing_knots).unwrap();
    (FullBodyProblem::new(&model, &srb, &guess, &settings, obstacle).unwrap(), guess)
}

/// First derivatives by central differences of `evaluate` at a perturbed start; the
/// Gauss-Newton Hessian symmetric and positive semi-definite.
fn check_stage(stage: &dyn Stage, z0: &DVector<f64>, rng: &mut Lcg) {
    let d = stage.dims();
    let nz = d.nz();
    let z = DVector::from_fn(nz, |i, _| z0[i] + if i < 36 { 0.02 } else { 0.5 } * rng.next());
    assert_jacobians_match_central_differences(stage, &z, 1e-6, 2e-5);
    let mut hess = DMatrix::zeros(nz, nz);
    let none = vec![0.0; d.nx_next.max(d.ng).max(d.nh)];
    let m = StageMultipliers { cost: 1.0, dynamics: &none[..d.nx_next], equalities: &none[..d.ng], inequalities: &none[..d.nh] };
    stage.lagrangian_hessian(z.as_slice(), m, &mut hess);
    assert!((&hess - hess.transpose()).amax() < 1e-12, "Hessian not symmetric");
    assert!(hess.symmetric_eigenvalues().min() > 0.0, "Gauss-Newton Hessian not positive definite");
}

#[test]
fn stage_derivatives_match_finite_differences() {
    let obstacle = BoxObstacle { top: -0.02, x: [-0.3, 0.3], y: [-0.2, 0.0] };
    let (fb, _) = lateral_problem(Some(obstacle));
    let mut rng = Lcg(7);
    let n = fb.problem.len();
    // The last knot a foot is held at is its lift-off knot (the end of its last push).
    let lift_off = fb.anchors().iter().rposition(|a| a[0].is_some()).unwrap();
    let a = FullBodySettings::default().pre_landing_knots;
    for k in [0, 1, lift_off - 1, lift_off, lift_off + 2, n - 1 - a, n - 2, n - 1] {
        check_stage(fb.problem.stage(k), &fb.start[k], &mut rng);
    }
}

/// The joint-acceleration cost and bound (off by default): derivatives against central
/// differences, and the cost's Gauss-Newton term `2 w J^T J` in the Hessian.
#[test]
fn joint_acceleration_cost_and_bound_derivatives_match_finite_differences() {
    let model = embedded::load("a1").unwrap();
    let srb = srb_solution("lateral30").resample(0.01).unwrap();
    let plain = FullBodySettings::default();
    let settings = FullBodySettings { w_acceleration: 1e-6, max_joint_acceleration: 500.0, ..plain.clone() };
    let guess = initial_guess(&model, &srb, settings.pre_landing_knots).unwrap();
    let fb = FullBodyProblem::new(&model, &srb, &guess, &settings, None).unwrap();
    let fb_plain = FullBodyProblem::new(&model, &srb, &guess, &plain, None).unwrap();
    let mut rng = Lcg(11);
    let n = fb.problem.len();
    let lift_off = fb.anchors().iter().rposition(|a| a[0].is_some()).unwrap();
    for k in [1, lift_off, lift_off + 2, n - 2, n - 1] {
        let stage = fb.problem.stage(k);
        let d = stage.dims();
        // 12 acceleration rows on every knot with dynamics.
        assert_eq!(d.nh, fb_plain.problem.stage(k).dims().nh + if k < n - 1 { 12 } else { 0 });
        check_stage(stage, &fb.start[k], &mut rng);
        if k < n - 1 {
            let z = fb.start[k].as_slice();
            let none = vec![0.0; d.nx_next.max(d.ng).max(d.nh)];
            let hessian = |s: &dyn Stage, nh: usize| {
                let m = StageMultipliers { cost: 1.0, dynamics: &none[..d.nx_next], equalities: &none[..d.ng], inequalities: &none[..nh] };
                let mut h = DMatrix::zeros(d.nz(), d.nz());
                s.lagrangian_hessian(z, m, &mut h);
                h
            };
            let extra = hessian(stage, d.nh) - hessian(fb_plain.problem.stage(k), fb_plain.problem.stage(k).dims().nh);
            assert!(extra.trace() > 0.0 && extra.symmetric_eigenvalues().min() > -1e-9, "knot {k}: the acceleration term is not 2 w J^T J");
        }
    }
}

/// The ballistic flight's momentum balance (off by default): six rows on the flight knots
/// before the pre-landing window (with `Full`; with the stance balance also on the pushing
/// knots), none in the window; derivatives against central differences, the penalty's
/// Gauss-Newton term in the Hessian.
#[test]
fn ballistic_flight_rows_and_penalty_derivatives_match_finite_differences() {
    use legwork::fullbody::BallisticFlight;
    let model = embedded::load("a1").unwrap();
    let srb = srb_solution("lateral30").resample(0.01).unwrap();
    let plain = FullBodySettings::default();
    let settings = FullBodySettings { ballistic_flight: BallisticFlight::Full, momentum_balance_in_stance: true, w_flight_momentum: 10.0, ..plain.clone() };
    let guess = initial_guess(&model, &srb, settings.pre_landing_knots).unwrap();
    let fb = FullBodyProblem::new(&model, &srb, &guess, &settings, None).unwrap();
    let fb_plain = FullBodyProblem::new(&model, &srb, &guess, &plain, None).unwrap();
    let mut rng = Lcg(13);
    let n = fb.problem.len();
    let a = plain.pre_landing_knots;
    let lift_off = fb.anchors().iter().rposition(|a| a[0].is_some()).unwrap();
    for (k, rows) in [(1, 6), (lift_off - 1, 6), (lift_off, 6), (lift_off + 2, 6), (n - 2 - a, 6), (n - 1 - a, 0), (n - 2, 0), (n - 1, 0)] {
        let stage = fb.problem.stage(k);
        assert_eq!(stage.dims().ng, fb_plain.problem.stage(k).dims().ng + rows, "knot {k}");
        check_stage(stage, &fb.start[k], &mut rng);
    }
    // Angular rows only: three.
    let angular = FullBodySettings { ballistic_flight: BallisticFlight::Angular, ..plain.clone() };
    let fb_angular = FullBodyProblem::new(&model, &srb, &guess, &angular, None).unwrap();
    assert_eq!(fb_angular.problem.stage(lift_off + 2).dims().ng, fb_plain.problem.stage(lift_off + 2).dims().ng + 3);
    assert_eq!(fb_angular.problem.stage(lift_off - 1).dims().ng, fb_plain.problem.stage(lift_off - 1).dims().ng);
}

/// With the constraint curvature on and the cost weight 0, the Hessian is `sum m_i Hess c_i`:
/// against central differences of `J_c(z)^T m` over every column (the stage differences only
/// the state columns, the control-control block taken as zero).
#[test]
fn constraint_curvature_matches_differences_of_the_jacobians() {
    use legwork::ipocp::StageJacobians;
    let obstacle = BoxObstacle { top: -0.02, x: [-0.3, 0.3], y: [-0.2, 0.0] };
    let (fb, _) = lateral_problem(Some(obstacle));
    fb.set_constraint_curvature(true);
    let mut rng = Lcg(11);
    let lift_off = fb.anchors().iter().rposition(|a| a[0].is_some()).unwrap();
    for k in [1, lift_off, lift_off + 2] {
        let stage = fb.problem.stage(k);
        let d = stage.dims();
        let nz = d.nz();
        let z = DVector::from_fn(nz, |i, _| fb.start[k][i] + if i < 36 { 0.02 } else { 0.5 } * rng.next());
        let lam = DVector::from_fn(d.nx_next, |_, _| rng.next());
        let nu = DVector::from_fn(d.ng, |_, _| rng.next());
        let y = DVector::from_fn(d.nh, |_, _| rng.next());
        let gradient = |zz: &DVector<f64>| {
            let mut j = StageJacobians::zeros(d);
            stage.jacobians(zz.as_slice(), &mut j);
            j.dynamics.transpose() * &lam + j.equalities.transpose() * &nu + j.inequalities.transpose() * &y
        };
        let mut hess = DMatrix::zeros(nz, nz);
        let m = StageMultipliers { cost: 0.0, dynamics: lam.as_slice(), equalities: nu.as_slice(), inequalities: y.as_slice() };
        stage.lagrangian_hessian(z.as_slice(), m, &mut hess);
        let mut fd = DMatrix::zeros(nz, nz);
        for j in 0..nz {
            let h = 1e-5 * (1.0 + z[j].abs());
            let (mut zp, mut zm) = (z.clone(), z.clone());
            zp[j] += h;
            zm[j] -= h;
            fd.set_column(j, &((gradient(&zp) - gradient(&zm)) / (2.0 * h)));
        }
        let scale = fd.amax().max(1.0);
        let err = (&hess - &fd).amax();
        eprintln!("knot {k}: |H - H_fd| {err:.2e}, |H_fd| {scale:.2e}");
        assert!(err < 1e-6 * scale, "knot {k}: curvature off by {err:.2e} (largest entry {scale:.2e})");
        assert!((&hess - hess.transpose()).amax() < 1e-12, "Hessian not symmetric");
    }
    fb.set_constraint_curvature(false);
}

/// The constraint curvature by forward differences of the multiplier-weighted gradient (the
/// default) against the reference, central differences of the full Jacobians, at perturbed
/// points with random multipliers: knots with held feet, lift-off, flight, the box rows and
/// the joint-acceleration rows.
#[test]
fn constraint_curvature_by_gradients_matches_the_jacobian_differences() {
    let model = embedded::load("a1").unwrap();
    let srb = srb_solution("lateral30").resample(0.01).unwrap();
    let obstacle = BoxObstacle { top: -0.02, x: [-0.3, 0.3], y: [-0.2, 0.0] };
    let settings = FullBodySettings { max_joint_acceleration: 500.0, ..FullBodySettings::default() };
    let guess = initial_guess(&model, &srb, settings.pre_landing_knots).unwrap();
    for (fb, seed) in [(lateral_problem(Some(obstacle)).0, 5), (FullBodyProblem::new(&model, &srb, &guess, &settings, Some(obstacle)).unwrap(), 9)] {
        fb.set_constraint_curvature(true);
        let mut rng = Lcg(seed);
        let n = fb.problem.len();
        let lift_off = fb.anchors().iter().rposition(|a| a[0].is_some()).unwrap();
        for k in [0, 1, lift_off - 1, lift_off, lift_off + 2, n - 2, n - 1] {
            let stage = fb.problem.stage(k);
            let d = stage.dims();
            let nz = d.nz();
            let z = DVector::from_fn(nz, |i, _| fb.start[k][i] + if i < 36 { 0.02 } else { 0.5 } * rng.next());
            let lam = DVector::from_fn(d.nx_next, |_, _| 10.0 * rng.next());
            let nu = DVector::from_fn(d.ng, |_, _| 10.0 * rng.next());
            let y = DVector::from_fn(d.nh, |_, _| 10.0 * rng.next());
            let m = StageMultipliers { cost: 0.0, dynamics: lam.as_slice(), equalities: nu.as_slice(), inequalities: y.as_slice() };
            let hessian = |by_jacobians: bool| {
                fb.set_curvature_by_jacobians(by_jacobians);
                let mut h = DMatrix::zeros(nz, nz);
                stage.lagrangian_hessian(z.as_slice(), m, &mut h);
                h
            };
            let (new, reference) = (hessian(false), hessian(true));
            let scale = reference.amax().max(1.0);
            let err = (&new - &reference).amax();
            eprintln!("knot {k}: |H - H_ref| {err:.2e}, |H_ref| {scale:.2e}");
            assert!(err < 1e-5 * scale, "knot {k}: curvature off by {err:.2e} (largest entry {scale:.2e})");
            assert!((&new - new.transpose()).amax() < 1e-12, "Hessian not symmetric");
        }
        fb.set_curvature_by_jacobians(false);
        fb.set_constraint_curvature(false);
    }
}

/// `curvature_refresh = 2`: a knot's second Hessian of a curvature phase adds the curvature
/// its first one formed (at the first point and multipliers), the third forms it anew, and
/// a new phase does not reuse the last one's.
#[test]
fn lagged_curvature_reuses_the_last_formed_one() {
    let (lagged, _) = lateral_problem_with(FullBodySettings { curvature_refresh: 2, ..FullBodySettings::default() }, None);
    let (exact, _) = lateral_problem(None);
    let mut rng = Lcg(3);
    let k = 5;
    let (stage, exact_stage) = (lagged.problem.stage(k), exact.problem.stage(k));
    let d = stage.dims();
    let nz = d.nz();
    let point = |rng: &mut Lcg| DVector::from_fn(nz, |i, _| lagged.start[k][i] + if i < 36 { 0.02 } else { 0.5 } * rng.next());
    let (z1, z2) = (point(&mut rng), point(&mut rng));
    let lam = DVector::from_fn(d.nx_next, |_, _| 10.0 * rng.next());
    let nu = DVector::from_fn(d.ng, |_, _| 10.0 * rng.next());
    let y = DVector::from_fn(d.nh, |_, _| 10.0 * rng.next());
    let m = StageMultipliers { cost: 1.0, dynamics: lam.as_slice(), equalities: nu.as_slice(), inequalities: y.as_slice() };
    let hessian = |stage: &dyn Stage, z: &DVector<f64>| {
        let mut h = DMatrix::zeros(nz, nz);
        stage.lagrangian_hessian(z.as_slice(), m, &mut h);
        h
    };
    let (gauss_newton_1, gauss_newton_2) = (hessian(stage, &z1), hessian(stage, &z2));
    lagged.set_constraint_curvature(true);
    exact.set_constraint_curvature(true);
    let formed = hessian(stage, &z1);
    let reused = hessian(stage, &z2);
    let formed_again = hessian(stage, &z2);
    let curvature_1 = &formed - &gauss_newton_1;
    assert!(curvature_1.amax() > 1e-3, "no curvature formed");
    assert!((&reused - &gauss_newton_2 - &curvature_1).amax() < 1e-9 * curvature_1.amax(), "the second Hessian does not add the first one's curvature");
    let exact_2 = hessian(exact_stage, &z2);
    assert_eq!(formed_again, exact_2, "the third Hessian is not formed anew");
    assert!((&exact_2 - &reused).amax() > 1e-6, "the points give the same curvature: the test cannot tell");
    // A new phase forms its own first.
    lagged.set_constraint_curvature(false);
    lagged.set_constraint_curvature(true);
    assert_eq!(hessian(stage, &z2), exact_2);
}

#[test]
fn lateral_jump_solves_end_to_end_within_every_limit() {
    let (fb, _) = lateral_problem(None);
    let plan = fb.solve().unwrap();
    let r = &plan.report;
    eprintln!("{:?} after {} iterations, {:.3} s, objective {:.6}, violation {:.2e}", r.status, r.iterations, r.time.as_secs_f64(), r.objective, r.primal_infeasibility);
    eprintln!("{:#?}", r.max_violation);
    eprintln!("{}", plan.limits);
    assert_eq!(r.status, Status::Solved);
    assert!(plan.limits.all_met(1e-6), "{}", plan.limits);
}

/// The stages' evaluations on rayon's threads (`solver.parallel`, the default) take the
/// sequential solve's path to the bit: the same iterations, objective and plan.
#[test]
fn parallel_stage_evaluations_take_the_sequential_path() {
    let solve = |parallel: bool| {
        let mut settings = FullBodySettings::default();
        settings.solver.parallel = parallel;
        lateral_problem_with(settings, None).0.solve().unwrap()
    };
    let (sequential, parallel) = (solve(false), solve(true));
    assert_eq!(sequential.report.status, Status::Solved);
    assert_eq!(parallel.report.iterations, sequential.report.iterations);
    assert_eq!(parallel.report.objective.to_bits(), sequential.report.objective.to_bits(), "{} vs {}", parallel.report.objective, sequential.report.objective);
    for (a, b) in parallel.trajectory.knots.iter().zip(&sequential.trajectory.knots) {
        assert!(a.q.iter().chain(&a.tau).zip(b.q.iter().chain(&b.tau)).all(|(x, y)| x.to_bits() == y.to_bits()), "t {}: {:?} vs {:?}", a.t, a.q, b.q);
    }
}

#[test]
fn box_signed_distance_is_the_euclidean_distance_outside_and_the_nearest_face_inside() {
    let b = BoxObstacle { top: 0.4, x: [-0.3, 0.3], y: [-0.2, 0.2] };
    let (d, g) = b.signed_distance(&nalgebra::Vector3::new(0.6, 0.6, 0.8));
    assert!((d - (0.09f64 + 0.16 + 0.16).sqrt()).abs() < 1e-12);
    assert!((g - nalgebra::Vector3::new(0.3, 0.4, 0.4) / d).norm() < 1e-12);
    let (d, g) = b.signed_distance(&nalgebra::Vector3::new(0.0, 0.15, 0.1));
    assert!((d + 0.05).abs() < 1e-12, "nearest face y = 0.2: {d}");
    assert_eq!(g, nalgebra::Vector3::new(0.0, 1.0, 0.0));
    let (d, _) = b.signed_distance(&nalgebra::Vector3::new(0.0, 0.0, 0.45));
    assert!((d - 0.05).abs() < 1e-12);
}

/// The largest normal force of a foot over its last pushing interval (a stance knot whose
/// next knot has the foot in the air).
fn largest_lift_off_force(plan: &legwork::io::Trajectory) -> f64 {
    let knots = &plan.knots;
    let mut largest: f64 = 0.0;
    for k in 0..knots.len() - 1 {
        for f in 0..4 {
            if knots[k].in_contact[f] && !knots[k + 1].in_contact[f] {
                largest = largest.max(knots[k].contact_force[f][2]);
            }
        }
    }
    largest
}

#[test]
fn lift_off_force_bound_holds_on_the_last_pushing_interval() {
    let model = embedded::load("a1").unwrap();
    let srb = srb_solution("lateral30").resample(0.01).unwrap();
    let plain = FullBodySettings::default();
    let guess = initial_guess(&model, &srb, plain.pre_landing_knots).unwrap();
    let bound = 20.0;
    let free = FullBodyProblem::new(&model, &srb, &guess, &plain, None).unwrap().solve().unwrap();
    // Without the bound the rigid-contact optimum pushes hardest at lift-off.
    assert!(largest_lift_off_force(&free.trajectory) > 2.0 * bound, "{}", largest_lift_off_force(&free.trajectory));
    let settings = FullBodySettings { lift_off_normal_force: bound, ..plain };
    let plan = FullBodyProblem::new(&model, &srb, &guess, &settings, None).unwrap().solve().unwrap();
    assert_eq!(plan.report.status, Status::Solved);
    assert!(plan.limits.all_met(1e-6), "{}", plan.limits);
    assert!(largest_lift_off_force(&plan.trajectory) <= bound + 1e-6, "{}", largest_lift_off_force(&plan.trajectory));
}

#[test]
fn full_body_problem_rejects_bad_input() {
    let model = embedded::load("a1").unwrap();
    let srb = srb_solution("lateral30").resample(0.01).unwrap();
    let settings = FullBodySettings::default();
    let guess = initial_guess(&model, &srb, settings.pre_landing_knots).unwrap();
    let new = |s: &FullBodySettings, b: Option<BoxObstacle>, g: &legwork::io::Trajectory| FullBodyProblem::new(&model, &srb, g, s, b).err().unwrap();
    let e = new(&FullBodySettings { w_torque: 0.0, ..settings.clone() }, None, &guess);
    assert_eq!(e, FullBodyError::Setting { field: "w_torque", value: 0.0, expected: "> 0" });
    let e = new(&FullBodySettings { curvature_refresh: 0, ..settings.clone() }, None, &guess);
    assert_eq!(e, FullBodyError::Setting { field: "curvature_refresh", value: 0.0, expected: ">= 1" });
    let e = new(&FullBodySettings { lift_off_normal_force: 1.0, ..settings.clone() }, None, &guess);
    assert!(matches!(e, FullBodyError::Setting { field: "lift_off_normal_force", .. }), "{e}");
    let e = new(&FullBodySettings { dt: 0.02, ..settings.clone() }, None, &guess);
    assert!(matches!(e, FullBodyError::Guess(ref m) if m.contains("dt = 0.02")), "{e}");
    let e = new(&settings, Some(BoxObstacle { top: 0.3, x: [0.2, -0.2], y: [-0.1, 0.1] }), &guess);
    assert!(matches!(e, FullBodyError::Setting { field: "box", .. }), "{e}");
    let e = new(&FullBodySettings { pre_landing_knots: 30, ..settings.clone() }, None, &guess);
    assert!(matches!(e, FullBodyError::Setting { field: "pre_landing_knots", .. }), "{e}");
    let mut short = guess.clone();
    short.knots.pop();
    assert!(matches!(new(&settings, None, &short), FullBodyError::Guess(_)));
    let mut nan = guess.clone();
    nan.knots[3].tau[0] = f64::NAN;
    assert!(matches!(new(&settings, None, &nan), FullBodyError::Guess(ref m) if m.contains("knot 3")));
}
