//! The full-body problem of one jump: the stages of [`super::stage`] on the 10 ms grid of the
//! resampled SRB trajectory, started from the initial guess, solved by ipocp, and read back
//! as a plan.

// Index loops over legs and joints read like the equations they implement.
#![allow(clippy::needless_range_loop)]

use super::kinematics::legs;
use super::limits::{check_limits, LimitReport};
use super::settings::{BoxObstacle, FullBodySettings};
use super::stage::{ConstraintKind, FullBodyStage, KnotSpec, Shared};
use super::FullBodyError;
use crate::dynamics::integrate;
use crate::io::{Knot, Trajectory};
use crate::ipocp::{Duals, Problem, Settings, SolveResult, Solver, Stage, StageValues, Status};
use crate::model::Model;
use crate::srb::SrbTrajectory;
use nalgebra::{DVector, Vector3};
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// The full-body problem of a jump.
pub struct FullBodyProblem {
    pub problem: Problem,
    /// The initial primal point: `dq = 0`, the guess's velocities, torques and the SRB forces.
    pub start: Vec<DVector<f64>>,
    shared: Arc<Shared>,
    specs: Vec<KnotSpec>,
    phase_durations: Vec<f64>,
    scenario: String,
}

/// How the solve went.
#[derive(Clone, Debug)]
pub struct SolveReport {
    pub status: Status,
    pub iterations: usize,
    /// ipocp's feasibility restorations and their iterations (not in `iterations`).
    pub restorations: usize,
    pub restoration_iterations: usize,
    /// Wall time of the solve, and its parts in function evaluations and KKT solves.
    pub time: Duration,
    pub evaluation_time: Duration,
    pub kkt_time: Duration,
    pub objective: f64,
    /// Largest violation of the optimizer's constraints (dynamics, equalities, inequalities).
    pub primal_infeasibility: f64,
    /// Largest violation per constraint kind at the returned iterate (equalities: `|g|`;
    /// inequalities: distance outside the bounds), kinds in a fixed order.
    pub max_violation: BTreeMap<String, f64>,
}

/// A solved (or, with its status saying so, unsolved) full-body jump.
#[derive(Clone, Debug)]
pub struct FullBodyPlan {
    /// Per 10 ms knot: `t`, `q`, `v`, `tau`, the stance feet's forces (world), contacts.
    pub trajectory: Trajectory,
    /// The joint angles held over the last `a` knots (`q[7..]` order).
    pub pre_landing_joints: Vec<f64>,
    /// Phase durations on the grid (s).
    pub phase_durations: Vec<f64>,
    pub report: SolveReport,
    /// Every limit checked at every knot of `trajectory`.
    pub limits: LimitReport,
}

/// The start's joint torques by inverse dynamics (eq. 3 solved for `tau`): at every knot with
/// dynamics, the joint rows of `M(q_k) qdd_k + b(q_k, v_k) = S^T tau_k + sum_s J_s^T lambda_s`
/// with `qdd_k = (v_{k+1} - v_k) / dt` of the guess's velocities and the SRB's forces,
/// clamped to 95 % of the torque limits (the base rows stay as the SRB's forces leave them).
/// The massless-leg torques of the guess leave the legs' accelerations off by thousands of
/// rad/s^2 (lateral_down: a start dynamics defect of 60).
fn start_torques_by_inverse_dynamics(shared: &Shared, specs: &[KnotSpec], start: &mut [DVector<f64>]) {
    use super::kinematics::{foot_position, point_jacobian};
    use crate::dynamics::{compute_joint_jacobians, rnea, Data};
    let model = &shared.model;
    let nv = model.nv;
    let nj = nv - 6;
    let dt = shared.settings.dt;
    let mut data = Data::new(model);
    let mut jac = nalgebra::Matrix3xX::zeros(nv);
    for k in 0..specs.len().saturating_sub(1) {
        let spec = &specs[k];
        let v = start[k].rows(nv, nv).into_owned();
        let qdd = (start[k + 1].rows(nv, nv) - &v) / dt;
        let mut tau = rnea(model, &mut data, &spec.qbar, &v, &qdd).clone();
        compute_joint_jacobians(model, &mut data, &spec.qbar);
        let mut i = 2 * nv + nj;
        for f in 0..4 {
            if spec.contacts[f] {
                let p = foot_position(model, &data, &shared.legs[f]);
                point_jacobian(model, &data, shared.legs[f].knee_joint, &p, &mut jac);
                let force = start[k].fixed_rows::<3>(i).into_owned();
                tau.gemv_tr(-1.0, &jac, &force, 1.0);
                i += 3;
            }
        }
        for j in 0..nj {
            let limit = 0.95 * shared.torque_limit[j];
            start[k][2 * nv + j] = tau[6 + j].clamp(-limit, limit);
        }
    }
}

impl FullBodyProblem {
    /// The problem on the grid of `srb` (resampled at `settings.dt`), around `guess` (from
    /// [`super::initial_guess`] on the same grid), with the box the jump starts from, if any.
    pub fn new(model: &Model, srb: &SrbTrajectory, guess: &Trajectory, settings: &FullBodySettings, obstacle: Option<BoxObstacle>) -> Result<Self, FullBodyError> {
        settings.validate(obstacle.as_ref())?;
        let legs = legs(model)?;
        let n = srb.knots.len();
        if guess.knots.len() != n {
            return Err(FullBodyError::Guess(format!("the guess has {} knots, the SRB trajectory {n}", guess.knots.len())));
        }
        for (k, (a, b)) in srb.knots.iter().zip(&guess.knots).enumerate() {
            if (a.t - b.t).abs() > 1e-9 || (k > 0 && ((a.t - srb.knots[k - 1].t) - settings.dt).abs() > 1e-9) {
                return Err(FullBodyError::Guess(format!("knot {k}: the SRB trajectory and the guess must share the grid of dt = {} s", settings.dt)));
            }
            if b.q.len() != model.nq || b.v.len() != model.nv || b.tau.len() != model.nv - 6 {
                return Err(FullBodyError::Guess(format!("knot {k}: q, v, tau must have {}, {}, {} entries", model.nq, model.nv, model.nv - 6)));
            }
            if b.q.iter().chain(&b.v).chain(&b.tau).any(|x| !x.is_finite()) {
                return Err(FullBodyError::Guess(format!("knot {k}: the guess is not finite")));
            }
        }
        let last = n - 1;
        let a = settings.pre_landing_knots;
        if a >= last {
            return Err(FullBodyError::Setting { field: "pre_landing_knots", value: a as f64, expected: "fewer than the knots of the jump" });
        }
        let lift_off: [usize; 4] = std::array::from_fn(|f| srb.knots.iter().rposition(|k| k.contacts[f]).map_or(0, |k| k + 1));
        if lift_off.iter().any(|&l| l > last - a) {
            return Err(FullBodyError::Setting { field: "pre_landing_knots", value: a as f64, expected: "a window that starts after every foot has lifted off" });
        }
        let joints: Vec<_> = model.actuated_joints().collect();
        let shared = Arc::new(Shared {
            model: model.clone(),
            legs,
            settings: settings.clone(),
            obstacle,
            joint_lower: joints.iter().map(|j| j.limits.lower[0]).collect(),
            joint_upper: joints.iter().map(|j| j.limits.upper[0]).collect(),
            velocity_limit: joints.iter().map(|j| j.limits.velocity[0]).collect(),
            torque_limit: joints.iter().map(|j| j.limits.effort[0]).collect(),
            foot_radius: model.feet[0].radius,
            curvature: AtomicBool::new(false),
            curvature_by_jacobians: AtomicBool::new(false),
            curvature_phase: AtomicUsize::new(0),
        });
        let q_final = DVector::from_column_slice(&guess.knots[last].q);
        let qbar: Vec<DVector<f64>> = (0..n)
            .map(|k| {
                let mut q = DVector::from_column_slice(&guess.knots[k].q);
                // Pre-landing knots hold the final joint angles, whatever the guess says.
                if k >= last - a {
                    q.as_mut_slice()[7..].copy_from_slice(&q_final.as_slice()[7..]);
                }
                q
            })
            .collect();
        let mut specs = Vec::with_capacity(n);
        let mut stages: Vec<Box<dyn Stage>> = Vec::with_capacity(n);
        let mut start = Vec::with_capacity(n);
        for k in 0..n {
            let knot = &srb.knots[k];
            let is_last = k == last;
            let contacts = if is_last { [false; 4] } else { knot.contacts };
            let spec = KnotSpec {
                knot: k,
                last: is_last,
                qbar: qbar[k].clone(),
                qbar_next: (!is_last).then(|| qbar[k + 1].clone()),
                com_ref: knot.com,
                force_ref: knot.forces,
                contacts,
                // A foot is held at its contact point at the end of every interval it pushes
                // over, the lift-off knot included: left free there, the last stance
                // interval's force would accelerate a loaded foot off its point (a slide the
                // ground does not allow) and buy the take-off an impulse no real contact
                // gives (lateral30: +0.35 N m s of roll momentum in the last 10 ms).
                pinned: std::array::from_fn(|f| {
                    if k >= 1 && contacts[f] {
                        Some(knot.feet[f])
                    } else if k >= 1 && srb.knots[k - 1].contacts[f] {
                        Some(srb.knots[k - 1].feet[f])
                    } else {
                        None
                    }
                }),
                lifting: std::array::from_fn(|f| contacts[f] && !srb.knots[k + 1].contacts[f]),
                airborne: std::array::from_fn(|f| k > lift_off[f]),
                initial: k == 0,
                pre_landing: k >= last - a,
                pre_landing_first: k == last - a,
                is_final: is_last,
            };
            let stage = FullBodyStage::new(shared.clone(), spec.clone());
            let d = stage.dims();
            let mut z = DVector::zeros(d.nz());
            let g = &guess.knots[k];
            z.as_mut_slice()[model.nv..2 * model.nv].copy_from_slice(&g.v);
            if !is_last {
                let nj = model.nv - 6;
                z.as_mut_slice()[2 * model.nv..2 * model.nv + nj].copy_from_slice(&g.tau);
                let mut i = 2 * model.nv + nj;
                for f in 0..4 {
                    if contacts[f] {
                        z.as_mut_slice()[i..i + 3].copy_from_slice(knot.forces[f].as_slice());
                        i += 3;
                    }
                }
            }
            start.push(z);
            stages.push(Box::new(stage));
            specs.push(spec);
        }
        if settings.start_torques_by_inverse_dynamics {
            start_torques_by_inverse_dynamics(&shared, &specs, &mut start);
        }
        Ok(Self {
            problem: Problem::new(stages).map_err(|e| FullBodyError::Model(format!("full-body problem: {e}")))?,
            start,
            shared,
            specs,
            phase_durations: srb.phase_durations.clone(),
            scenario: guess.metadata.scenario.replace("initial guess", "full-body plan"),
        })
    }

    /// Solves from the initial guess with the settings' solver options.
    pub fn solve(&self) -> Result<FullBodyPlan, FullBodyError> {
        let settings = &self.shared.settings;
        let solver_error = |e: crate::ipocp::SettingsError| FullBodyError::Setting { field: e.field, value: e.value, expected: e.expected };
        let Some(gauss_newton_iterations) = settings.constraint_curvature_after.filter(|&n| n < settings.solver.max_iterations) else {
            let mut solver = Solver::new(&self.problem, settings.solver.clone()).map_err(solver_error)?;
            let t0 = Instant::now();
            self.shared.curvature.store(false, Ordering::Relaxed);
            let result = solver.solve(&self.problem, &self.start).map_err(|e| FullBodyError::Solve(e.to_string()))?;
            return Ok(self.plan(&result, t0.elapsed()));
        };
        // Phase 1: Gauss-Newton for at least `gauss_newton_iterations`, then until the
        // violation is at most `curvature_max_violation` (1: lateral_down 0.46-1.1 after
        // 100 iterations, and solved; double_barrel_roll 6e-4 after 300): the curvature is worth its cost near a
        // solution, where the multipliers mean something, not after a local infeasibility or
        // far from feasible (the violation after a fixed count is not a robust test:
        // lateral_down 0.46 or 1.1 at 100 iterations with round-off-level changes of the
        // steps). Phase 2 (if phase 1 stopped there): warm, with the curvature, for the
        // remaining iterations from phase 1's barrier parameter.
        let t0 = Instant::now();
        self.shared.curvature.store(false, Ordering::Relaxed);
        // With `curvature_on_stall`: also hand over once the violation is at most the bound
        // and has not reached a new low for that many iterations (the Gauss-Newton steps have
        // stopped making the iterate more feasible).
        let mut switched = false;
        let (mut lowest, mut lowest_at) = (f64::INFINITY, 0);
        let mut stop = |iteration: usize, violation: f64| {
            if violation < lowest {
                (lowest, lowest_at) = (violation, iteration);
            }
            let stalled = settings.curvature_on_stall.is_some_and(|window| iteration - lowest_at >= window);
            switched = (iteration >= gauss_newton_iterations || stalled) && violation <= settings.curvature_max_violation;
            switched
        };
        let mut solver = Solver::new(&self.problem, settings.solver.clone()).map_err(solver_error)?;
        let first = solver.solve_warm_until(&self.problem, &self.start, None, &mut stop).map_err(|e| FullBodyError::Solve(e.to_string()))?;
        if !switched {
            return Ok(self.plan(&first, t0.elapsed()));
        }
        self.set_constraint_curvature(true);
        let second_settings = Settings {
            max_iterations: settings.solver.max_iterations - first.iterations,
            mu_init: first.mu,
            barrier_update: settings.curvature_barrier_update.unwrap_or(settings.solver.barrier_update),
            ..settings.solver.clone()
        };
        let mut solver = Solver::new(&self.problem, second_settings).map_err(solver_error)?;
        let last = &first.last;
        let duals = Duals {
            dynamics_multiplier: last.dynamics_multiplier.clone(),
            equality_multiplier: last.equality_multiplier.clone(),
            inequality_multiplier: last.inequality_multiplier.clone(),
            lower_bound_multiplier: last.lower_bound_multiplier.clone(),
            upper_bound_multiplier: last.upper_bound_multiplier.clone(),
        };
        let second = solver.solve_warm(&self.problem, &last.primal, Some(&duals));
        self.shared.curvature.store(false, Ordering::Relaxed);
        let mut second = second.map_err(|e| FullBodyError::Solve(e.to_string()))?;
        second.iterations += first.iterations;
        second.restorations += first.restorations;
        second.restoration_iterations += first.restoration_iterations;
        second.timings.evaluation += first.timings.evaluation;
        second.timings.kkt += first.timings.kkt;
        Ok(self.plan(&second, t0.elapsed()))
    }

    /// Adds (or no longer adds) the constraints' curvature to the stages' Hessians: what the
    /// second phase of [`Self::solve`] with `constraint_curvature_after` does. Each call
    /// that turns it on starts a new curvature phase: no knot reuses a curvature formed
    /// before it (`FullBodySettings::curvature_refresh`).
    pub fn set_constraint_curvature(&self, on: bool) {
        if on {
            self.shared.curvature_phase.fetch_add(1, Ordering::Relaxed);
        }
        self.shared.curvature.store(on, Ordering::Relaxed);
    }

    /// Takes the constraints' curvature by central differences of the full constraint
    /// Jacobians (`2 nx` Jacobian passes per knot, the reference) instead of forward
    /// differences of the multiplier-weighted gradient (`nx + 1` gradient passes, the default).
    pub fn set_curvature_by_jacobians(&self, on: bool) {
        self.shared.curvature_by_jacobians.store(on, Ordering::Relaxed);
    }

    /// The plan of a solve's last iterate.
    pub fn plan(&self, result: &SolveResult, time: Duration) -> FullBodyPlan {
        let primal = &result.last.primal;
        let trajectory = self.trajectory(primal);
        let sh = &self.shared;
        let limits = check_limits(&sh.model, &trajectory, &sh.settings, sh.obstacle.as_ref());
        FullBodyPlan {
            pre_landing_joints: trajectory.knots.last().map(|k| k.q[7..].to_vec()).unwrap_or_default(),
            phase_durations: self.phase_durations.clone(),
            report: SolveReport {
                status: result.status.clone(),
                iterations: result.iterations,
                restorations: result.restorations,
                restoration_iterations: result.restoration_iterations,
                time,
                evaluation_time: result.timings.evaluation,
                kkt_time: result.timings.kkt,
                objective: result.objective,
                primal_infeasibility: result.primal_infeasibility,
                max_violation: self.violations(primal),
            },
            limits,
            trajectory,
        }
    }

    /// The trajectory of a primal point: `q_k = qbar_k (+) dq_k`.
    pub fn trajectory(&self, primal: &[DVector<f64>]) -> Trajectory {
        let model = &self.shared.model;
        let nv = model.nv;
        let nj = nv - 6;
        let mut traj = Trajectory::new(model, self.scenario.clone(), self.shared.settings.dt, crate::terrain::TerrainSpec::flat());
        let mut q = DVector::zeros(model.nq);
        for (spec, z) in self.specs.iter().zip(primal) {
            integrate(model, &spec.qbar, &z.rows(0, nv).into_owned(), &mut q);
            let mut forces = vec![[0.0; 3]; 4];
            let mut tau = vec![0.0; nj];
            if !spec.last {
                tau.copy_from_slice(&z.as_slice()[2 * nv..2 * nv + nj]);
                let mut i = 2 * nv + nj;
                for f in 0..4 {
                    if spec.contacts[f] {
                        forces[f] = [z[i], z[i + 1], z[i + 2]];
                        i += 3;
                    }
                }
            }
            traj.knots.push(Knot {
                t: spec.knot as f64 * self.shared.settings.dt,
                q: q.as_slice().to_vec(),
                v: z.as_slice()[nv..2 * nv].to_vec(),
                tau,
                contact_force: forces,
                in_contact: spec.contacts.to_vec(),
                feedback_gain: None,
            });
        }
        traj
    }

    /// Largest violation per constraint kind of the optimizer's own rows at `primal`.
    fn violations(&self, primal: &[DVector<f64>]) -> BTreeMap<String, f64> {
        let mut out: BTreeMap<String, f64> = BTreeMap::new();
        let mut put = |name: &str, v: f64| {
            let e = out.entry(name.to_string()).or_insert(0.0);
            *e = e.max(v);
        };
        let nv = self.shared.model.nv;
        let nj = nv - 6;
        for (k, z) in primal.iter().enumerate() {
            let stage = self.problem.stage(k);
            let d = stage.dims();
            let mut values = StageValues::zeros(d);
            stage.evaluate(z.as_slice(), &mut values);
            if k + 1 < primal.len() {
                put("dynamics", (&values.dynamics - primal[k + 1].rows(0, 2 * nv)).amax());
            }
            let spec = &self.specs[k];
            let g = &values.equalities;
            let mut r = 0;
            let mut take = |name: &str, rows: usize, r: &mut usize| {
                if rows > 0 {
                    put(name, g.rows(*r, rows).amax());
                }
                *r += rows;
            };
            if spec.initial {
                take("initial state", 2 * nv, &mut r);
            } else {
                take("stance feet", 3 * spec.pinned.iter().filter(|p| p.is_some()).count(), &mut r);
            }
            if spec.pre_landing {
                take("pre-landing joints", nj, &mut r);
            }
            if spec.pre_landing_first {
                take("pre-landing joints", nj, &mut r);
            }
            if spec.is_final {
                take("final pose", 6, &mut r);
            }
            let (lo, up) = self.problem.bounds(k);
            let kinds: Vec<ConstraintKind> = self.kinds(k);
            for (row, kind) in kinds.iter().enumerate() {
                let h = values.inequalities[row];
                put(kind.name(), (lo[row] - h).max(h - up[row]).max(0.0));
            }
        }
        out
    }

    fn kinds(&self, k: usize) -> Vec<ConstraintKind> {
        FullBodyStage::kinds_of(&self.shared, &self.specs[k])
    }

    /// Contact points of the stance feet per knot (`None` off the ground).
    pub fn anchors(&self) -> Vec<[Option<Vector3<f64>>; 4]> {
        self.specs.iter().map(|s| s.pinned).collect()
    }
}
