//! Nguyen 2022's contact-timing optimization on the single rigid body: the A1's parameters
//! against the reference script's, the stages' derivatives against finite differences,
//! and the lateral jump's optimum against `results_srb_costdt.json`.

use legwork::ipocp::{Settings, Stage, StageJacobians, StageMultipliers, Status};
use legwork::jump::Jump;
use legwork::srb::{ContactTimingProblem, ContactTimingSettings, ExpMap, SrbParams};
use nalgebra::{DMatrix, DVector};

#[path = "support/stage_fd.rs"]
mod stage_fd;
use stage_fd::assert_jacobians_match_central_differences;

fn anchor(file: &str) -> serde_json::Value {
    let path = format!("{}/../shared/anchors/nguyen2022/{file}", env!("CARGO_MANIFEST_DIR"));
    serde_json::from_str(&std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"))).unwrap()
}

#[test]
fn a1_parameters_match_the_reference_script() {
    let p = SrbParams::a1().unwrap();
    let j = anchor("a1_srb_params.json");
    assert!((p.mass - j["mass"].as_f64().unwrap()).abs() < 1e-9, "mass {}", p.mass);
    for a in 0..3 {
        for b in 0..3 {
            let e = j["inertia_composite_at_com"][a][b].as_f64().unwrap();
            assert!((p.inertia[(a, b)] - e).abs() < 1e-9, "I[{a}{b}] {} vs {e}", p.inertia[(a, b)]);
        }
        assert!((p.com_in_base[a] - j["com_in_base"][a].as_f64().unwrap()).abs() < 1e-9);
    }
    for f in 0..4 {
        for a in 0..3 {
            let e = j["foot_rel_com"][f][a].as_f64().unwrap();
            assert!((p.foot_rel_com[f][a] - e).abs() < 1e-9, "foot {f} {a}: {} vs {e}", p.foot_rel_com[f][a]);
        }
    }
}

/// Deterministic pseudo-random numbers in [-1, 1).
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }
}

/// Jacobians by central differences of `evaluate`, Hessian by central differences of the
/// Lagrangian's gradient, at a perturbed guess with random multipliers.
fn check_stage(stage: &dyn Stage, z0: &DVector<f64>, rng: &mut Lcg) {
    let d = stage.dims();
    let nz = d.nz();
    let z = DVector::from_fn(nz, |i, _| z0[i] + 0.05 * rng.next());
    let lam = DVector::from_fn(d.nx_next, |_, _| rng.next());
    let nu = DVector::from_fn(d.ng, |_, _| rng.next());
    let y = DVector::from_fn(d.nh, |_, _| rng.next());
    let lagrangian_gradient = |zz: &DVector<f64>| {
        let mut j = StageJacobians::zeros(d);
        stage.jacobians(zz.as_slice(), &mut j);
        &j.cost_gradient + j.dynamics.transpose() * &lam + j.equalities.transpose() * &nu + j.inequalities.transpose() * &y
    };
    let mut hess = DMatrix::zeros(nz, nz);
    let m = StageMultipliers { cost: 1.0, dynamics: lam.as_slice(), equalities: nu.as_slice(), inequalities: y.as_slice() };
    stage.lagrangian_hessian(z.as_slice(), m, &mut hess);
    assert_jacobians_match_central_differences(stage, &z, 1e-6, 1e-6);
    let h = 1e-6;
    for i in 0..nz {
        let (mut zp, mut zm) = (z.clone(), z.clone());
        zp[i] += h;
        zm[i] -= h;
        let gcol = (lagrangian_gradient(&zp) - lagrangian_gradient(&zm)) / (2.0 * h);
        for r in 0..nz {
            let an = hess[(r, i)];
            assert!((gcol[r] - an).abs() < 1e-6 * (1.0 + an.abs()), "Hessian row {r} column {i}: fd {} analytic {an}", gcol[r]);
        }
    }
    assert!((&hess - hess.transpose()).amax() < 1e-12, "Hessian not symmetric");
}

#[test]
fn stage_derivatives_match_finite_differences() {
    let params = SrbParams::a1().unwrap();
    let mut rng = Lcg(5);
    for (name, exp_map) in [("lateral", ExpMap::Taylor4), ("lateral_down", ExpMap::Exact), ("barrel_roll", ExpMap::Exact), ("double_backflip", ExpMap::Taylor4)] {
        let jump = Jump::embedded(name).unwrap().srb();
        let settings = ContactTimingSettings { exp_map, knots_per_phase: 4, ..Default::default() };
        let ct = ContactTimingProblem::new(&jump, &params, &settings).unwrap();
        for k in 0..ct.problem.len() {
            check_stage(ct.problem.stage(k), &ct.guess[k], &mut rng);
        }
    }
}

#[test]
fn lateral_jump_reaches_the_reference_optimum() {
    let reference = anchor("results_srb_costdt.json");
    assert_eq!(reference["args"]["cost_dt"], true);
    let r0 = reference["results"].as_array().unwrap().iter().find(|r| r["jump"] == "lateral30").unwrap();
    let cost_ref = r0["runs"][0]["cost"].as_f64().unwrap();
    let t_ref: Vec<f64> = r0["T_opt_s"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
    let params = SrbParams::a1().unwrap();
    let jump = Jump::embedded("lateral").unwrap().reference_srb();
    // The script's exponential is the paper's 4th-order Taylor polynomial; it has no
    // stance-speed bound.
    let settings = ContactTimingSettings { exp_map: ExpMap::Taylor4, max_stance_speed: f64::INFINITY, ..Default::default() };
    let ct = ContactTimingProblem::new(&jump, &params, &settings).unwrap();
    // The pipeline's solver settings (the adaptive barrier update) and ipocp's defaults (the
    // monotone one) reach the same optimum.
    for solver_settings in [ContactTimingProblem::solver_settings(), Settings::default()] {
        let barrier_update = solver_settings.barrier_update;
        let mut solver = ct.solver(solver_settings).unwrap();
        let r = ct.solve(&mut solver).unwrap();
        assert_eq!(r.status, Status::Solved, "{barrier_update:?}: after {} iterations", r.iterations);
        assert!((r.objective - cost_ref).abs() < 1e-4 * cost_ref, "{barrier_update:?}: cost {} vs {cost_ref}", r.objective);
        assert!(r.primal_infeasibility < 1e-6, "{barrier_update:?}: constraint violation {}", r.primal_infeasibility);
        let t = ct.durations(&r.last.primal);
        for (a, b) in t.iter().zip(&t_ref) {
            assert!((a - b).abs() < 1e-4, "{barrier_update:?}: T {t:?} vs {t_ref:?}");
        }
    }
}

/// spin_90 leaves the ground within the stance-speed bound; without it the cost (a smaller
/// `Omega` over a longer flight) sends the flight to the time bound with a take-off no A1
/// leg delivers within its joint limits.
#[test]
fn the_stance_speed_bound_holds_the_take_off_of_spin_90() {
    let params = SrbParams::a1().unwrap();
    let jump = Jump::embedded("spin_90").unwrap().srb();
    let lift_off_speed = |max_stance_speed: f64| {
        let settings = ContactTimingSettings { knots_per_phase: 15, max_stance_speed, ..Default::default() };
        let ct = ContactTimingProblem::new(&jump, &params, &settings).unwrap();
        let mut solver = ct.solver(Settings::default()).unwrap();
        let r = ct.solve(&mut solver).unwrap();
        assert_eq!(r.status, Status::Solved, "max_stance_speed {max_stance_speed}: after {} iterations", r.iterations);
        let speeds: Vec<f64> = (0..=ct.knots_per_phase).map(|k| r.last.primal[k].rows(3, 3).amax()).collect();
        (speeds.iter().copied().fold(0.0, f64::max), ct.durations(&r.last.primal))
    };
    let (bounded, t_bounded) = lift_off_speed(ContactTimingSettings::default().max_stance_speed);
    let (free, t_free) = lift_off_speed(f64::INFINITY);
    assert!(bounded <= 1.5 + 1e-6, "stance speed {bounded} m/s over the 1.5 m/s bound (T {t_bounded:?})");
    assert!(free > 2.5, "without the bound the take-off is {free} m/s (T {t_free:?})");
    assert!(t_bounded[1] < t_free[1] - 0.1, "flight {t_bounded:?} vs {t_free:?}");
}

/// ipocp's parallel stage work (`Settings::parallel`: evaluations, QP assembly, step gather,
/// Lagrangian gradients, KKT residuals on rayon's threads) keeps every sum in stage order, so
/// it takes the sequential solve's path exactly: barrel_roll (second-order corrections and a
/// restoration phase on the way) in the same iterations to the same bits.
#[test]
fn parallel_stage_work_takes_the_sequential_path() {
    let params = SrbParams::a1().unwrap();
    let file = Jump::embedded("barrel_roll").unwrap();
    let ct = ContactTimingProblem::new(&file.srb(), &params, &file.contact_timing).unwrap();
    let solve = |parallel: bool| {
        let mut solver = ct.solver(Settings { parallel, ..ContactTimingProblem::solver_settings() }).unwrap();
        ct.solve(&mut solver).unwrap()
    };
    let (sequential, parallel) = (solve(false), solve(true));
    assert_eq!(sequential.status, Status::Solved);
    assert!(sequential.restorations > 0, "the check wants a restoration phase on the path");
    assert_eq!((parallel.iterations, parallel.kkt_solves, parallel.restorations), (sequential.iterations, sequential.kkt_solves, sequential.restorations));
    assert_eq!(parallel.objective.to_bits(), sequential.objective.to_bits(), "{} vs {}", parallel.objective, sequential.objective);
    for (k, (a, b)) in parallel.last.primal.iter().zip(&sequential.last.primal).enumerate() {
        assert!(a.iter().zip(b.iter()).all(|(x, y)| x.to_bits() == y.to_bits()), "knot {k}: {a} vs {b}");
    }
}

/// `jump` on the A1 at 15 knots per phase with the pipeline's solver settings, solved
/// (`what` names the variant in the failure message): the problem and its optimum.
fn solve_at_15_knots(jump: &legwork::srb::JumpSpec, what: &str) -> (ContactTimingProblem, Vec<DVector<f64>>) {
    let settings = ContactTimingSettings { knots_per_phase: 15, ..Default::default() };
    let ct = ContactTimingProblem::new(jump, &SrbParams::a1().unwrap(), &settings).unwrap();
    let mut solver = ct.solver(ContactTimingProblem::solver_settings()).unwrap();
    let r = ct.solve(&mut solver).unwrap();
    assert_eq!(r.status, Status::Solved, "{what}: after {} iterations", r.iterations);
    (ct, r.last.primal)
}

/// A jump's own per-phase duration bounds (`JumpSpec::phase_time`) hold each `T_i` where
/// the settings' common `[t_lo, t_hi]` lets the optimum leave them; bounds that are not one
/// per phase, or cannot sum into `total_time`, are refused.
#[test]
fn phase_time_bounds_hold_each_phase() {
    let params = SrbParams::a1().unwrap();
    let free = Jump::embedded("lateral").unwrap().srb();
    let bounds = vec![(0.45, 0.6), (0.25, 0.35)];
    let bounded = legwork::srb::JumpSpec { phase_time: Some(bounds.clone()), ..free.clone() };
    let settings = ContactTimingSettings { knots_per_phase: 15, ..Default::default() };
    let durations = |jump: &legwork::srb::JumpSpec| {
        let (ct, primal) = solve_at_15_knots(jump, &format!("{:?}", jump.phase_time));
        ct.durations(&primal)
    };
    let (t_free, t_bounded) = (durations(&free), durations(&bounded));
    let inside = |t: &[f64]| t.iter().zip(&bounds).all(|(t, (lo, hi))| *t >= lo - 1e-8 && *t <= hi + 1e-8);
    assert!(!inside(&t_free), "the free optimum {t_free:?} is already inside {bounds:?}: the test shows nothing");
    assert!(inside(&t_bounded), "T {t_bounded:?} outside {bounds:?}");
    for (phase_time, refusal) in [(vec![(0.45, 0.6)], "one [lo, hi] per phase"), (vec![(0.1, 0.2), (0.1, 0.2)], "cannot sum into total_time"), (vec![(0.5, 0.4), (0.2, 0.3)], "0 < lo <= hi")] {
        let jump = legwork::srb::JumpSpec { phase_time: Some(phase_time), ..free.clone() };
        let e = ContactTimingProblem::new(&jump, &params, &settings).err().expect("refused").to_string();
        assert!(e.contains(refusal), "{e}");
    }
}

/// `JumpSpec::landing_extension` raises the final CoM over the landing feet by exactly that
/// much and leaves the landing feet where the standing pose puts them (lateral, 15 knots:
/// 0 and 8 cm solve, the final CoM heights differ by 8 cm, the final feet not at all).
#[test]
fn landing_extension_raises_the_final_com_over_the_same_feet() {
    let standing = Jump::embedded("lateral").unwrap().srb();
    let extended = legwork::srb::JumpSpec { landing_extension: 0.08, ..standing.clone() };
    let last_knot = |jump: &legwork::srb::JumpSpec| {
        let (ct, primal) = solve_at_15_knots(jump, &format!("landing_extension {}", jump.landing_extension));
        let trajectory = legwork::srb::SrbTrajectory::from_solution(&ct, &primal).unwrap();
        trajectory.knots.last().unwrap().clone()
    };
    // Outside [0, MAX_LANDING_EXTENSION], or NaN, the problem is refused.
    for rise in [-0.01, legwork::srb::MAX_LANDING_EXTENSION + 0.01, f64::NAN] {
        let jump = legwork::srb::JumpSpec { landing_extension: rise, ..standing.clone() };
        let e = ContactTimingProblem::new(&jump, &SrbParams::a1().unwrap(), &ContactTimingSettings::default()).err().expect("refused").to_string();
        assert!(e.contains("landing_extension must be within"), "{rise}: {e}");
    }
    let (a, b) = (last_knot(&standing), last_knot(&extended));
    assert!((b.com.z - a.com.z - 0.08).abs() < 1e-6, "final CoM z {} vs {}", b.com.z, a.com.z);
    assert!((b.com.xy() - a.com.xy()).norm() < 1e-6, "final CoM {} vs {}", b.com, a.com);
    for f in 0..4 {
        assert!((b.feet[f] - a.feet[f]).norm() < 1e-12, "foot {f}: {} vs {}", b.feet[f], a.feet[f]);
    }
}
