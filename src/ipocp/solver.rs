//! The primal-dual interior-point loop (Wächter & Biegler 2006, Algorithm A), with the
//! KKT systems solved by the Riccati recursion of [`super::riccati`].
//!
//! Inequalities `lower <= h(z) <= upper` become `h(z) - s = 0` with bounded slacks `s` and
//! the barrier `-mu sum ln(s - lower) + ln(upper - s)`. One iteration:
//!
//! 1. optimality error `E_mu` (eq. 5); the monotone (Fiacco-McCormick) barrier update while
//!    `E_mu <= kappa_epsilon mu` (eq. 7), or the adaptive update ([`BarrierUpdate::Adaptive`]:
//!    `mu` from an oracle after the affine-scaling step, Nocedal, Wächter & Waltz 2009);
//! 2. the primal-dual step: slacks and bound multipliers condensed out (eq. 13 with
//!    `Sigma = Z_L / (s - l) + Z_U / (u - s)`), the remaining equality-constrained QP solved
//!    by the Riccati recursion, with the Hessian regularized until its inertia is right
//!    (sec. 3.1);
//! 3. fraction-to-the-boundary step sizes for the slacks and for the bound multipliers
//!    (eq. 15);
//! 4. the filter line search with second-order corrections (sec. 2.3-2.4).

// Index loops over rows and columns read like the equations they implement.
#![allow(clippy::needless_range_loop)]

use super::filter::Filter;
use super::iterate::{Duals, Iterate, SolveResult, Status, Timings};
use super::problem::{Problem, ProblemError};
use super::restoration;
use super::riccati::{RiccatiSolver, StageQp, StageStep};
use super::settings::{BarrierUpdate, MuOracle, Settings, SettingsError};
use super::stage::{StageJacobians, StageMultipliers, StageValues};
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use std::time::Instant;

/// Per-stage evaluation buffers.
struct StageBuffers {
    values: StageValues,
    trial: StageValues,
    jac: StageJacobians,
    hess: DMatrix<f64>,
    /// Slack step, new inequality multipliers, bound-multiplier steps, `Sigma`.
    ds: DVector<f64>,
    y_new: DVector<f64>,
    dzl: DVector<f64>,
    dzu: DVector<f64>,
    sigma: DVector<f64>,
    /// `h - s` (or its second-order-correction replacement) used by the last QP, and the
    /// original one kept while second-order corrections are tried.
    ineq_residual: DVector<f64>,
    saved_ineq_residual: DVector<f64>,
    trial_primal: DVector<f64>,
    trial_slack: DVector<f64>,
    /// Scratch: the condensed linear term per inequality row.
    lin: DVector<f64>,
    /// The inequality Jacobian's nonzeros by row, gathered once per derivative evaluation:
    /// most rows are simple bounds with one nonzero, so every product with `J_h` goes over
    /// these lists.
    jh_rows: SparseRows,
    /// Scratch: the stage's part of the Lagrangian gradient.
    lagrangian_gradient: DVector<f64>,
    /// The QP's gradient at `mu = 0` (the quality-function oracle's affine step).
    gradient_affine: DVector<f64>,
}

/// Runs `f` on every stage's buffers, on rayon's threads when `parallel` (the stages'
/// evaluations are independent; each stage owns its workspace).
fn for_each_stage(parallel: bool, buffers: &mut [StageBuffers], f: impl Fn(usize, &mut StageBuffers) + Sync + Send) {
    if parallel {
        buffers.par_iter_mut().enumerate().for_each(|(k, b)| f(k, b));
    } else {
        for (k, b) in buffers.iter_mut().enumerate() {
            f(k, b);
        }
    }
}

/// [`for_each_stage`] over every stage's buffers and its QP.
fn for_each_stage_with(parallel: bool, buffers: &mut [StageBuffers], qps: &mut [StageQp], f: impl Fn(usize, &mut StageBuffers, &mut StageQp) + Sync + Send) {
    if parallel {
        buffers.par_iter_mut().zip(qps.par_iter_mut()).enumerate().for_each(|(k, (b, qp))| f(k, b, qp));
    } else {
        for (k, (b, qp)) in buffers.iter_mut().zip(qps.iter_mut()).enumerate() {
            f(k, b, qp);
        }
    }
}

/// A solver for the problems of one stage layout; allocates its workspace once.
pub struct Solver {
    settings: Settings,
    riccati: RiccatiSolver,
    buffers: Vec<StageBuffers>,
    qps: Vec<StageQp>,
    steps: Vec<StageStep>,
    /// The step kept while second-order corrections are tried (restored if they all fail).
    saved_steps: Vec<StageStep>,
    /// Iterative refinement: the correction of a step, and the residuals of the KKT system
    /// at the step (stationarity, dynamics, equalities per stage), swapped in for the QP's
    /// right-hand side while the correction is solved.
    correction: Vec<StageStep>,
    residuals: Vec<KktResidual>,
    /// The adaptive barrier update's complementarity pairs and their steps.
    pairs: ComplementarityPairs,
    filter: Filter,
    /// The last step's fraction-to-the-boundary bound, the step the line search accepted, and
    /// the (stage, row) whose slack set the bound: `verbose`'s `alpha_max`, `alpha_pr`, `block`.
    last_step: LastStep,
}

#[derive(Clone, Copy, Debug, Default)]
struct LastStep {
    alpha_max: f64,
    alpha_primal: f64,
    blocking: Option<(usize, usize)>,
}

/// The complementarity pairs `(gap, z)` of every finite bound (`gap = s - l` with `z_l`,
/// `u - s` with `z_u`) and their steps along `d_aff + sigma d_diff` (the affine-scaling
/// step and the difference of the centering step `d(avg) - d_aff`), flat: the oracles
/// evaluate them many times per iteration.
struct ComplementarityPairs {
    gap: Vec<f64>,
    multiplier: Vec<f64>,
    /// `1 / gap`, `1 / z`: the steps to the boundary without a division per pair.
    gap_inverse: Vec<f64>,
    multiplier_inverse: Vec<f64>,
    gap_affine: Vec<f64>,
    gap_difference: Vec<f64>,
    multiplier_affine: Vec<f64>,
    multiplier_difference: Vec<f64>,
}

impl ComplementarityPairs {
    /// Room for `n` pairs (at most two per inequality row): no allocation in the iterations.
    fn with_capacity(n: usize) -> Self {
        let v = || Vec::with_capacity(n);
        Self { gap: v(), multiplier: v(), gap_inverse: v(), multiplier_inverse: v(), gap_affine: v(), gap_difference: v(), multiplier_affine: v(), multiplier_difference: v() }
    }

    /// The largest primal and dual steps in `(0, 1]` that keep `gap` and `z` above `1 - tau`
    /// of their values (eq. 15) along `d_aff + sigma d_diff`: `alpha = min(1, tau / max(-d /
    /// v))` over the pairs.
    fn step_to_boundary(&self, sigma: f64, tau: f64) -> (f64, f64) {
        let alpha = |largest_ratio: f64| if largest_ratio > tau { tau / largest_ratio } else { 1.0 };
        let primal = largest_decrease_ratio(&self.gap_inverse, &self.gap_affine, &self.gap_difference, sigma);
        let dual = largest_decrease_ratio(&self.multiplier_inverse, &self.multiplier_affine, &self.multiplier_difference, sigma);
        (alpha(primal), alpha(dual))
    }

    /// Mean and mean square of the products `gap z` after the steps `alpha_primal`,
    /// `alpha_dual` along `d_aff + sigma d_diff` (four partial sums: the loop is bound by
    /// the additions' latency otherwise).
    fn after(&self, sigma: f64, alpha_primal: f64, alpha_dual: f64) -> (f64, f64) {
        const LANES: usize = 4;
        let (mut sum, mut squares) = ([0.0; LANES], [0.0; LANES]);
        let n = self.gap.len();
        // Equal-length slices, walked in chunks of LANES: no bounds checks in the loop.
        let (gap, gap_affine, gap_difference) = (&self.gap[..n], &self.gap_affine[..n], &self.gap_difference[..n]);
        let (multiplier, multiplier_affine, multiplier_difference) = (&self.multiplier[..n], &self.multiplier_affine[..n], &self.multiplier_difference[..n]);
        let product = |g: f64, ga: f64, gd: f64, z: f64, za: f64, zd: f64| (g + alpha_primal * (ga + sigma * gd)) * (z + alpha_dual * (za + sigma * zd));
        fn chunks(v: &[f64]) -> std::slice::ChunksExact<'_, f64> {
            v.chunks_exact(LANES)
        }
        let whole = n - n % LANES;
        for (((g, ga), gd), ((z, za), zd)) in chunks(gap).zip(chunks(gap_affine)).zip(chunks(gap_difference)).zip(chunks(multiplier).zip(chunks(multiplier_affine)).zip(chunks(multiplier_difference))) {
            for lane in 0..LANES {
                let c = product(g[lane], ga[lane], gd[lane], z[lane], za[lane], zd[lane]);
                sum[lane] += c;
                squares[lane] += c * c;
            }
        }
        for j in whole..n {
            let c = product(gap[j], gap_affine[j], gap_difference[j], multiplier[j], multiplier_affine[j], multiplier_difference[j]);
            sum[0] += c;
            squares[0] += c * c;
        }
        let n = n.max(1) as f64;
        (sum.iter().sum::<f64>() / n, squares.iter().sum::<f64>() / n)
    }

    /// The quality function of the step `d_aff + sigma d_diff` (Nocedal, Wächter & Waltz
    /// 2009, sec. 4, mean squares): the dual and primal infeasibilities shrink by `1 - alpha`
    /// along a Newton step, the complementarity is evaluated at the new point.
    fn quality(&self, sigma: f64, tau: f64, errors: &Errors) -> f64 {
        let (alpha_primal, alpha_dual) = self.step_to_boundary(sigma, tau);
        let (_, complementarity_mean_square) = self.after(sigma, alpha_primal, alpha_dual);
        (1.0 - alpha_dual).powi(2) * errors.dual_mean_square + (1.0 - alpha_primal).powi(2) * errors.primal_mean_square + complementarity_mean_square
    }
}

/// `max(0, max_j -(affine_j + sigma difference_j) inverse_j)`: the largest relative decrease
/// of a positive quantity (`inverse = 1 / value`) along the step, in four lanes.
fn largest_decrease_ratio(inverse: &[f64], affine: &[f64], difference: &[f64], sigma: f64) -> f64 {
    const LANES: usize = 4;
    let mut largest = [0.0f64; LANES];
    let n = affine.len();
    let (inverse, difference) = (&inverse[..n], &difference[..n]);
    let whole = n - n % LANES;
    for ((inv, aff), dif) in inverse.chunks_exact(LANES).zip(affine.chunks_exact(LANES)).zip(difference.chunks_exact(LANES)) {
        for lane in 0..LANES {
            let r = -(aff[lane] + sigma * dif[lane]) * inv[lane];
            if r > largest[lane] {
                largest[lane] = r;
            }
        }
    }
    for j in whole..n {
        let r = -(affine[j] + sigma * difference[j]) * inverse[j];
        if r > largest[0] {
            largest[0] = r;
        }
    }
    largest.iter().fold(0.0, |m, &r| if r > m { r } else { m })
}

/// The residual of one stage's rows of the KKT system at a step (see [`Solver::refine_step`]).
struct KktResidual {
    stationarity: DVector<f64>,
    dynamics: DVector<f64>,
    equalities: DVector<f64>,
}

/// What can go wrong before the iterations start.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SolveError {
    #[error(transparent)]
    Problem(#[from] ProblemError),
    #[error(transparent)]
    Settings(#[from] SettingsError),
    #[error("the solver was built for stage sizes that differ from this problem's")]
    LayoutMismatch,
}

/// A test that ends a solve early, given the iteration count, the iterate and its constraint
/// violation ([`Solver::solve_warm_until`], the restoration phase's return test).
type ExitTest<'a> = dyn FnMut(usize, &Iterate, f64) -> bool + 'a;

/// Measures of the current iterate.
#[derive(Clone, Copy, Debug, Default)]
struct Errors {
    objective: f64,
    primal: f64,
    dual: f64,
    complementarity_0: f64,
    error_0: f64,
    error_mu: f64,
    /// Mean squares of the primal and the dual infeasibility's entries (the quality function).
    primal_mean_square: f64,
    dual_mean_square: f64,
}

/// The adaptive barrier update's globalization (Nocedal, Wächter & Waltz 2009, sec. 5): in
/// the free mode the oracle picks `mu` while the optimality error keeps decreasing against
/// the last accepted errors; otherwise the monotone rule runs until it does again.
struct AdaptiveBarrier {
    free: bool,
    /// The optimality errors of the last accepted free-mode iterates, oldest first.
    references: std::collections::VecDeque<f64>,
    /// Upper bound on `mu`: a multiple of the first iterate's average complementarity.
    mu_max: f64,
}

impl AdaptiveBarrier {
    /// Sufficient progress: `E_0 <= reduction * E_ref` for one of the full set of references
    /// (IPOPT's KKT-error test; always true until the set is full).
    fn sufficient_progress(&self, error: f64, s: &Settings) -> bool {
        self.references.len() < s.adaptive_mu_error_references || self.references.iter().any(|&r| error <= s.adaptive_mu_error_reduction * r)
    }

    fn remember(&mut self, error: f64, s: &Settings) {
        if self.references.len() == s.adaptive_mu_error_references {
            self.references.pop_front();
        }
        self.references.push_back(error);
    }
}

/// Golden-section steps of the quality-function oracle on `log sigma` (IPOPT's
/// `quality_function_max_section_steps`).
const QUALITY_SECTION_STEPS: usize = 8;

impl Solver {
    /// A solver for problems with the stage sizes of `problem`.
    pub fn new(problem: &Problem, settings: Settings) -> Result<Self, SettingsError> {
        settings.validate()?;
        let buffers = problem
            .dims()
            .iter()
            .map(|&d| StageBuffers {
                values: StageValues::zeros(d),
                trial: StageValues::zeros(d),
                jac: StageJacobians::zeros(d),
                hess: DMatrix::zeros(d.nz(), d.nz()),
                ds: DVector::zeros(d.nh),
                y_new: DVector::zeros(d.nh),
                dzl: DVector::zeros(d.nh),
                dzu: DVector::zeros(d.nh),
                sigma: DVector::zeros(d.nh),
                ineq_residual: DVector::zeros(d.nh),
                saved_ineq_residual: DVector::zeros(d.nh),
                trial_primal: DVector::zeros(d.nz()),
                trial_slack: DVector::zeros(d.nh),
                lin: DVector::zeros(d.nh),
                jh_rows: SparseRows::new(d.nh, d.nz()),
                lagrangian_gradient: DVector::zeros(d.nz()),
                gradient_affine: DVector::zeros(d.nz()),
            })
            .collect();
        Ok(Self {
            riccati: RiccatiSolver::new(problem.dims(), settings.pivot_tolerance),
            qps: problem.dims().iter().map(|&d| StageQp::zeros(d)).collect(),
            steps: problem.dims().iter().map(|&d| StageStep::zeros(d)).collect(),
            saved_steps: problem.dims().iter().map(|&d| StageStep::zeros(d)).collect(),
            correction: problem.dims().iter().map(|&d| StageStep::zeros(d)).collect(),
            residuals: problem.dims().iter().map(|&d| KktResidual { stationarity: DVector::zeros(d.nz()), dynamics: DVector::zeros(d.nx_next), equalities: DVector::zeros(d.ng) }).collect(),
            pairs: ComplementarityPairs::with_capacity(2 * problem.dims().iter().map(|d| d.nh).sum::<usize>()),
            settings,
            buffers,
            last_step: LastStep::default(),
            filter: Filter::default(),
        })
    }

    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    /// Solves from the primal guess `primal` (`z_k = [x_k; u_k]` per stage).
    pub fn solve(&mut self, problem: &Problem, primal: &[DVector<f64>]) -> Result<SolveResult, SolveError> {
        self.solve_warm(problem, primal, None)
    }

    /// Solves from a primal guess and, optionally, dual values (a warm start; set a small
    /// `mu_init` in the settings when the guess is close to the optimum).
    pub fn solve_warm(&mut self, problem: &Problem, primal: &[DVector<f64>], duals: Option<&Duals>) -> Result<SolveResult, SolveError> {
        self.solve_with_exit(problem, primal, duals, None)
    }

    /// [`Self::solve_warm`] that also stops at the first iterate after the start that `stop`
    /// accepts, given the iteration count and the iterate's constraint violation (the
    /// `primal_infeasibility` of [`SolveResult`]). Such a stop is reported as
    /// [`Status::Solved`]: the caller's closure knows whether it fired. What a solve in
    /// phases uses (`fullbody`: Gauss-Newton until close enough to feasible, then the exact
    /// curvature).
    pub fn solve_warm_until(&mut self, problem: &Problem, primal: &[DVector<f64>], duals: Option<&Duals>, stop: &mut dyn FnMut(usize, f64) -> bool) -> Result<SolveResult, SolveError> {
        self.solve_with_exit(problem, primal, duals, Some(&mut |iteration: usize, _: &Iterate, violation: f64| stop(iteration, violation)))
    }

    /// [`Self::solve_warm`] that also stops, reporting [`Status::Solved`], at the first
    /// iterate after the start that `exit` accepts (the restoration phase's return test),
    /// given the iteration count, the iterate and its constraint violation.
    pub(super) fn solve_with_exit(&mut self, problem: &Problem, primal: &[DVector<f64>], duals: Option<&Duals>, mut exit: Option<&mut ExitTest<'_>>) -> Result<SolveResult, SolveError> {
        let start = Instant::now();
        self.check_layout(problem, primal, duals)?;
        let s = self.settings.clone();
        let mut timings = Timings::default();
        let mut it = self.initial_iterate(problem, primal, duals, &mut timings);
        let mut mu = s.mu_init;
        let mut regularization_last = 0.0;
        let mut regularizations = 0;
        let mut kkt_solves = 0;
        let mut adaptive: Option<AdaptiveBarrier> = None;
        let (mut restorations, mut restoration_iterations) = (0, 0);

        let mut best = it.clone();
        let mut best_stats = (0usize, f64::INFINITY, f64::NAN, f64::NAN);
        let status;
        let mut iteration = 0;
        let mut errors;
        // Filter initialization (sec. 2.3).
        let theta0 = self.evaluate_values_at(problem, &it, &mut timings);
        self.filter.reset();
        self.filter.theta_max = 1e4 * theta0.max(1.0);
        let theta_min = 1e-4 * theta0.max(1.0);
        loop {
            // Derivatives at the current iterate (values were left there by the line search).
            let t = Instant::now();
            self.evaluate_derivatives(problem, &it);
            timings.evaluation += t.elapsed();
            errors = self.errors(problem, &it, mu);
            if !errors.error_0.is_finite() {
                status = Status::NumericalFailure(format!("non-finite optimality error at iteration {iteration}"));
                break;
            }
            if errors.error_0 < best_stats.1 {
                best.copy_from(&it);
                best_stats = (iteration, errors.error_0, errors.objective, errors.primal);
            }
            if s.verbose {
                eprintln!(
                    "ipocp {iteration:4} obj {:+.8e} inf_pr {:.2e} inf_du {:.2e} lg(mu) {:5.2} reg {:.1e} alpha_max {:.2e} alpha_pr {:.2e} block {:?}",
                    errors.objective,
                    errors.primal,
                    errors.dual,
                    mu.log10(),
                    regularization_last,
                    self.last_step.alpha_max,
                    self.last_step.alpha_primal,
                    self.last_step.blocking
                );
            }
            if errors.error_0 <= s.tolerance
                && errors.dual <= s.dual_infeasibility_tolerance
                && errors.primal <= s.constraint_violation_tolerance
                && errors.complementarity_0 <= s.complementarity_tolerance
            {
                status = Status::Solved;
                break;
            }
            if iteration > 0 && exit.as_mut().is_some_and(|exit| exit(iteration, &it, errors.primal)) {
                status = Status::Solved;
                break;
            }
            if iteration >= s.max_iterations {
                status = Status::MaxIterations;
                break;
            }
            // 1. Barrier parameter: the monotone rule (eq. 7), or the adaptive update's mode
            // (free: the oracle picks `mu` from the affine-scaling step of step 2).
            let mut oracle = None;
            match (s.barrier_update, complementarity(problem, &it)) {
                (BarrierUpdate::Adaptive(o), Some((average, smallest))) => {
                    let adaptive = adaptive.get_or_insert_with(|| AdaptiveBarrier { free: true, references: Default::default(), mu_max: s.adaptive_mu_max_factor * average });
                    if adaptive.sufficient_progress(errors.error_0, &s) {
                        adaptive.remember(errors.error_0, &s);
                        adaptive.free = true;
                        self.filter.reset();
                        if o == MuOracle::Loqo {
                            // LOQO's rule needs no step (Nocedal, Wächter & Waltz 2009, eq. 3.6).
                            let xi = smallest / average;
                            let sigma = 0.1 * (0.05 * (1.0 - xi) / xi).min(2.0).powi(3);
                            mu = (sigma * average).clamp(s.adaptive_mu_min, adaptive.mu_max);
                        } else {
                            oracle = Some((o, average, adaptive.mu_max));
                        }
                    } else if adaptive.free {
                        // No progress: the monotone rule from a fraction of the complementarity.
                        adaptive.free = false;
                        mu = (s.adaptive_mu_monotone_init_factor * average).clamp(s.adaptive_mu_min, adaptive.mu_max);
                        self.filter.reset();
                    } else {
                        self.monotone_barrier_update(problem, &it, &mut mu, &mut errors);
                    }
                }
                _ => self.monotone_barrier_update(problem, &it, &mut mu, &mut errors),
            }
            // 2. Primal-dual step with inertia correction.
            let t = Instant::now();
            let mut delta = 0.0;
            let mut attempts = 0;
            // The free mode's first solve is the affine-scaling step (`mu = 0`).
            self.assemble_qp(problem, &it, if oracle.is_some() { 0.0 } else { mu }, 0.0, None);
            loop {
                kkt_solves += 1;
                match self.riccati.solve(&self.qps, &mut self.steps) {
                    Ok(()) => break,
                    Err(_) => {
                        attempts += 1;
                        let previous = delta;
                        delta = if attempts == 1 {
                            if regularization_last == 0.0 {
                                s.regularization_first
                            } else {
                                s.regularization_min.max(s.regularization_decrease * regularization_last)
                            }
                        } else if regularization_last == 0.0 {
                            delta * s.regularization_increase_first
                        } else {
                            delta * s.regularization_increase
                        };
                        if delta > s.regularization_max {
                            break;
                        }
                        // Only the diagonal changes: H + delta I.
                        for qp in &mut self.qps {
                            for i in 0..qp.hessian.nrows() {
                                qp.hessian[(i, i)] += delta - previous;
                            }
                        }
                    }
                }
            }
            timings.kkt += t.elapsed();
            if delta > s.regularization_max {
                status = Status::NumericalFailure("the Hessian regularization exceeded `regularization_max`".into());
                break;
            }
            if delta > 0.0 {
                regularization_last = delta;
                regularizations += 1;
            }
            if let Some((o, average, mu_max)) = oracle {
                // The oracle's `mu` and the step for it (with the factorization just computed:
                // only the right-hand side changes with `mu`).
                let t = Instant::now();
                let solved = self.oracle_mu(problem, &it, o, average, (s.adaptive_mu_min, mu_max), &errors);
                timings.kkt += t.elapsed();
                if let Some(m) = solved {
                    mu = m;
                } else {
                    status = Status::NumericalFailure("the re-solve for the adaptive barrier parameter failed".into());
                    break;
                }
            }
            let tau = s.tau_min.max(1.0 - mu);
            self.refine_step();
            self.gather_step(problem, &it, mu);
            // 3. Fraction to the boundary (eq. 15).
            let alpha_max = self.max_primal_step(problem, &it, tau);
            let alpha_z = self.max_dual_step(&it, tau);
            // 4. Filter line search.
            match self.line_search(problem, &mut it, mu, tau, alpha_max, alpha_z, theta_min, delta, &mut timings) {
                Ok(()) => {}
                Err(theta) if theta > s.constraint_violation_tolerance && s.restoration && restorations < s.max_restorations => {
                    // Feasibility restoration (sec. 3.3), then on from the restored point.
                    restorations += 1;
                    let restoration = restoration::restore(problem, &it, mu, &s, &mut self.filter);
                    restoration_iterations += restoration.iterations;
                    timings.evaluation += restoration.timings.evaluation;
                    timings.kkt += restoration.timings.kkt;
                    let Some(restored) = restoration.iterate else {
                        status = Status::LocallyInfeasible;
                        break;
                    };
                    it = restored;
                    if s.least_squares_multipliers {
                        self.least_squares_multipliers(problem, &mut it, &mut timings);
                    }
                    self.evaluate_values_at(problem, &it, &mut timings);
                }
                Err(theta) => {
                    status = if theta > s.constraint_violation_tolerance { Status::LocallyInfeasible } else { Status::LineSearchFailed };
                    break;
                }
            }
            self.reset_bound_multipliers(problem, &mut it, mu);
            iteration += 1;
        }
        if status == Status::Solved {
            best.copy_from(&it);
            best_stats = (iteration, errors.error_0, errors.objective, errors.primal);
        }
        timings.total = start.elapsed();
        Ok(SolveResult {
            status,
            iterations: iteration,
            objective: errors.objective,
            primal_infeasibility: errors.primal,
            dual_infeasibility: errors.dual,
            complementarity: errors.complementarity_0,
            optimality_error: errors.error_0,
            mu,
            last: it,
            best,
            best_iteration: best_stats.0,
            best_optimality_error: best_stats.1,
            best_objective: best_stats.2,
            best_primal_infeasibility: best_stats.3,
            regularizations,
            last_regularization: regularization_last,
            kkt_solves,
            restorations,
            restoration_iterations,
            timings,
        })
    }

    fn check_layout(&self, problem: &Problem, primal: &[DVector<f64>], duals: Option<&Duals>) -> Result<(), SolveError> {
        let dims = problem.dims();
        if dims.len() != self.buffers.len() || dims.iter().zip(&self.buffers).any(|(d, b)| b.hess.nrows() != d.nz() || b.ds.len() != d.nh || b.values.equalities.len() != d.ng) {
            return Err(SolveError::LayoutMismatch);
        }
        if primal.len() != dims.len() {
            return Err(ProblemError::GuessStages { got: primal.len(), expected: dims.len() }.into());
        }
        for (k, (z, d)) in primal.iter().zip(dims).enumerate() {
            if z.len() != d.nz() {
                return Err(ProblemError::GuessSize { stage: k, got: z.len(), expected: d.nz() }.into());
            }
            if z.iter().any(|v| !v.is_finite()) {
                return Err(ProblemError::GuessNotFinite { stage: k }.into());
            }
        }
        if let Some(du) = duals {
            for (k, d) in dims.iter().enumerate() {
                let checks: [(&'static str, &Vec<DVector<f64>>, usize); 5] = [
                    ("dynamics_multiplier", &du.dynamics_multiplier, d.nx_next),
                    ("equality_multiplier", &du.equality_multiplier, d.ng),
                    ("inequality_multiplier", &du.inequality_multiplier, d.nh),
                    ("lower_bound_multiplier", &du.lower_bound_multiplier, d.nh),
                    ("upper_bound_multiplier", &du.upper_bound_multiplier, d.nh),
                ];
                for (what, v, n) in checks {
                    let got = v.get(k).map_or(0, |x| x.len());
                    if v.len() != dims.len() || got != n {
                        return Err(ProblemError::DualSize { stage: k, what, got, expected: n }.into());
                    }
                }
            }
        }
        Ok(())
    }

    /// The starting point: slacks pushed into the interior, bound multipliers at their
    /// initial value, equality multipliers by least squares (sec. 3.6).
    fn initial_iterate(&mut self, problem: &Problem, primal: &[DVector<f64>], duals: Option<&Duals>, timings: &mut Timings) -> Iterate {
        let s = &self.settings;
        let dims = problem.dims();
        let t = Instant::now();
        for (k, b) in self.buffers.iter_mut().enumerate() {
            problem.stage(k).evaluate(primal[k].as_slice(), &mut b.values);
        }
        timings.evaluation += t.elapsed();
        let mut it = Iterate {
            primal: primal.to_vec(),
            slack: Vec::new(),
            dynamics_multiplier: dims.iter().map(|d| DVector::zeros(d.nx_next)).collect(),
            equality_multiplier: dims.iter().map(|d| DVector::zeros(d.ng)).collect(),
            inequality_multiplier: dims.iter().map(|d| DVector::zeros(d.nh)).collect(),
            lower_bound_multiplier: Vec::new(),
            upper_bound_multiplier: Vec::new(),
        };
        for k in 0..dims.len() {
            let (lo, up) = problem.bounds(k);
            let h = &self.buffers[k].values.inequalities;
            let mut slack = DVector::zeros(dims[k].nh);
            let mut zl = DVector::zeros(dims[k].nh);
            let mut zu = DVector::zeros(dims[k].nh);
            for i in 0..dims[k].nh {
                slack[i] = push_into_interior(h[i], lo[i], up[i], s.bound_push, s.bound_frac);
                if lo[i].is_finite() {
                    zl[i] = s.bound_multiplier_init;
                }
                if up[i].is_finite() {
                    zu[i] = s.bound_multiplier_init;
                }
            }
            it.slack.push(slack);
            it.lower_bound_multiplier.push(zl);
            it.upper_bound_multiplier.push(zu);
        }
        if let Some(du) = duals {
            it.dynamics_multiplier = du.dynamics_multiplier.clone();
            it.equality_multiplier = du.equality_multiplier.clone();
            it.inequality_multiplier = du.inequality_multiplier.clone();
            for k in 0..dims.len() {
                let (lo, up) = problem.bounds(k);
                for i in 0..dims[k].nh {
                    // Keep the given bound multipliers positive where a bound exists.
                    it.lower_bound_multiplier[k][i] = if lo[i].is_finite() { du.lower_bound_multiplier[k][i].max(s.tolerance) } else { 0.0 };
                    it.upper_bound_multiplier[k][i] = if up[i].is_finite() { du.upper_bound_multiplier[k][i].max(s.tolerance) } else { 0.0 };
                }
            }
        } else if s.least_squares_multipliers {
            self.least_squares_multipliers(problem, &mut it, timings);
        }
        it
    }

    /// IPOPT's least-squares multipliers: the multipliers of
    /// `min 1/2 |dz|^2 + 1/2 |ds|^2 + grad l^T dz + (zu - zl)^T ds` on the null space of the
    /// constraint Jacobian, discarded if larger than `multiplier_init_max`.
    fn least_squares_multipliers(&mut self, problem: &Problem, it: &mut Iterate, timings: &mut Timings) {
        let t = Instant::now();
        for (k, b) in self.buffers.iter_mut().enumerate() {
            problem.stage(k).jacobians(it.primal[k].as_slice(), &mut b.jac);
            b.jh_rows.gather(&b.jac.inequalities);
        }
        timings.evaluation += t.elapsed();
        let t = Instant::now();
        for (k, b) in self.buffers.iter_mut().enumerate() {
            let nz = b.hess.nrows();
            self.qps[k].hessian.fill(0.0);
            self.qps[k].hessian.fill_diagonal(1.0);
            // I + J_h^T J_h and J_h^T (z_u - z_l) over the rows' nonzeros.
            let qp = &mut self.qps[k];
            qp.gradient.copy_from(&b.jac.cost_gradient);
            let (hessian, gradient) = (qp.hessian.as_mut_slice(), qp.gradient.as_mut_slice());
            for i in 0..b.ds.len() {
                let (columns, values) = b.jh_rows.row(i);
                let c = it.upper_bound_multiplier[k][i] - it.lower_bound_multiplier[k][i];
                for (&a, &ja) in columns.iter().zip(values) {
                    gradient[a] += ja * c;
                    for (&r, &jr) in columns.iter().zip(values) {
                        hessian[a * nz + r] += ja * jr;
                    }
                }
            }
            self.qps[k].dynamics.copy_from(&b.jac.dynamics);
            self.qps[k].defect.fill(0.0);
            self.qps[k].equality_jacobian.copy_from(&b.jac.equalities);
            self.qps[k].equality_residual.fill(0.0);
            debug_assert_eq!(nz, self.qps[k].gradient.len());
        }
        let ok = self.riccati.solve(&self.qps, &mut self.steps).is_ok();
        timings.kkt += t.elapsed();
        if !ok {
            return;
        }
        let mut largest: f64 = 0.0;
        for (k, b) in self.buffers.iter().enumerate() {
            // y = J_h dz + z_u - z_l
            let y = &mut it.inequality_multiplier[k];
            y.copy_from(&it.upper_bound_multiplier[k]);
            *y -= &it.lower_bound_multiplier[k];
            b.jh_rows.add_times(self.steps[k].dz.as_slice(), y.as_mut_slice());
            largest = largest.max(y.amax()).max(self.steps[k].dynamics_multiplier.amax()).max(self.steps[k].equality_multiplier.amax());
            it.dynamics_multiplier[k].copy_from(&self.steps[k].dynamics_multiplier);
            it.equality_multiplier[k].copy_from(&self.steps[k].equality_multiplier);
        }
        if largest.is_nan() || largest > self.settings.multiplier_init_max {
            for k in 0..self.buffers.len() {
                it.inequality_multiplier[k].fill(0.0);
                it.dynamics_multiplier[k].fill(0.0);
                it.equality_multiplier[k].fill(0.0);
            }
        }
    }

    /// Evaluates values at `it` into `values` and returns the violation `theta`.
    fn evaluate_values_at(&mut self, problem: &Problem, it: &Iterate, timings: &mut Timings) -> f64 {
        let t = Instant::now();
        for_each_stage(self.settings.parallel, &mut self.buffers, |k, b| problem.stage(k).evaluate(it.primal[k].as_slice(), &mut b.values));
        timings.evaluation += t.elapsed();
        let n = self.buffers.len();
        let mut theta = 0.0;
        for k in 0..n {
            theta += violation_1(&self.buffers[k].values, it.primal.get(k + 1), problem.dims()[k].nx_next, &it.slack[k]);
        }
        theta
    }

    fn evaluate_derivatives(&mut self, problem: &Problem, it: &Iterate) {
        for_each_stage(self.settings.parallel, &mut self.buffers, |k, b| {
            let stage = problem.stage(k);
            let z = it.primal[k].as_slice();
            stage.jacobians(z, &mut b.jac);
            let m = StageMultipliers {
                cost: 1.0,
                dynamics: it.dynamics_multiplier[k].as_slice(),
                equalities: it.equality_multiplier[k].as_slice(),
                inequalities: it.inequality_multiplier[k].as_slice(),
            };
            stage.lagrangian_hessian(z, m, &mut b.hess);
            b.jh_rows.gather(&b.jac.inequalities);
        });
    }

    /// Optimality errors (eq. 5) from the values and derivatives in the buffers.
    fn errors(&mut self, problem: &Problem, it: &Iterate, mu: f64) -> Errors {
        let dims = problem.dims();
        let (mut objective, mut primal, mut dual, mut compl_0, mut compl_mu) = (0.0, 0.0f64, 0.0f64, 0.0f64, 0.0f64);
        let (mut sum_mult, mut n_mult, mut sum_bound, mut n_bound) = (0.0, 0usize, 0.0, 0usize);
        let (mut primal_squares, mut n_primal, mut dual_squares, mut n_dual) = (0.0, 0usize, 0.0, 0usize);
        // The stages' Lagrangian gradients first (the products with the Jacobians, stage by
        // stage, on rayon's threads when `parallel`), then the sums in stage order.
        for_each_stage(self.settings.parallel, &mut self.buffers, |k, b| {
            // grad l + F^T lambda + G^T nu + J_h^T y - [lambda_{k-1}; 0]
            let g = &mut b.lagrangian_gradient;
            g.copy_from(&b.jac.cost_gradient);
            g.gemv_tr(1.0, &b.jac.dynamics, &it.dynamics_multiplier[k], 1.0);
            g.gemv_tr(1.0, &b.jac.equalities, &it.equality_multiplier[k], 1.0);
            b.jh_rows.add_transpose_times(it.inequality_multiplier[k].as_slice(), g.as_mut_slice());
            if k > 0 {
                for (gi, lambda) in g.iter_mut().zip(it.dynamics_multiplier[k - 1].iter()) {
                    *gi -= lambda;
                }
            }
        });
        for (k, b) in self.buffers.iter_mut().enumerate() {
            let d = dims[k];
            let (lo, up) = problem.bounds(k);
            objective += b.values.cost;
            // Primal: dynamics defects, equalities, h - s.
            for i in 0..d.nx_next {
                let r = b.values.dynamics[i] - it.primal[k + 1][i];
                primal = primal.max(r.abs());
                primal_squares += r * r;
            }
            primal = primal.max(b.values.equalities.amax());
            primal_squares += b.values.equalities.norm_squared();
            for i in 0..d.nh {
                let r = b.values.inequalities[i] - it.slack[k][i];
                primal = primal.max(r.abs());
                primal_squares += r * r;
            }
            n_primal += d.nx_next + d.ng + d.nh;
            // Dual: the Lagrangian gradient above, and -y - zl + zu.
            let g = &b.lagrangian_gradient;
            dual = dual.max(g.amax());
            dual_squares += g.norm_squared();
            n_dual += d.nz() + d.nh;
            for i in 0..d.nh {
                let (zl, zu, y, s) = (it.lower_bound_multiplier[k][i], it.upper_bound_multiplier[k][i], it.inequality_multiplier[k][i], it.slack[k][i]);
                dual = dual.max((-y - zl + zu).abs());
                dual_squares += (-y - zl + zu).powi(2);
                if lo[i].is_finite() {
                    let c = (s - lo[i]) * zl;
                    compl_0 = compl_0.max(c.abs());
                    compl_mu = compl_mu.max((c - mu).abs());
                    sum_bound += zl.abs();
                    n_bound += 1;
                }
                if up[i].is_finite() {
                    let c = (up[i] - s) * zu;
                    compl_0 = compl_0.max(c.abs());
                    compl_mu = compl_mu.max((c - mu).abs());
                    sum_bound += zu.abs();
                    n_bound += 1;
                }
            }
            sum_mult += it.dynamics_multiplier[k].lp_norm(1) + it.equality_multiplier[k].lp_norm(1) + it.inequality_multiplier[k].lp_norm(1);
            n_mult += d.nx_next + d.ng + d.nh;
        }
        let smax = self.settings.s_max;
        let s_d = smax.max((sum_mult + sum_bound) / ((n_mult + n_bound).max(1) as f64)) / smax;
        let s_c = smax.max(sum_bound / (n_bound.max(1) as f64)) / smax;
        Errors {
            objective,
            primal,
            dual,
            complementarity_0: compl_0,
            error_0: (dual / s_d).max(primal).max(compl_0 / s_c),
            error_mu: (dual / s_d).max(primal).max(compl_mu / s_c),
            primal_mean_square: primal_squares / n_primal.max(1) as f64,
            dual_mean_square: dual_squares / n_dual.max(1) as f64,
        }
    }

    /// Fills the stage QPs: `H = hess + J_h^T Sigma J_h + delta I`,
    /// `q = grad l + J_h^T (Sigma r_h + mu/(u - s) - mu/(s - l))` with `r_h = h - s`
    /// (eq. 13 condensed). `soc`: replace the constraint residuals by those of a
    /// second-order correction (`Some(alpha)`: `alpha c(current) + c(trial)`, the trial values
    /// in `trial`; only the vectors are rebuilt, the matrices stay those of the corrected step).
    fn assemble_qp(&mut self, problem: &Problem, it: &Iterate, mu: f64, delta: f64, soc: Option<f64>) {
        self.assemble_qp_parts(problem, it, mu, delta, soc, soc.is_none());
    }

    /// The vectors of [`Self::assemble_qp`] for another `mu` (the matrices do not depend on it:
    /// the adaptive barrier update's re-solves).
    fn assemble_qp_vectors(&mut self, problem: &Problem, it: &Iterate, mu: f64) {
        self.assemble_qp_parts(problem, it, mu, 0.0, None, false);
    }

    fn assemble_qp_parts(&mut self, problem: &Problem, it: &Iterate, mu: f64, delta: f64, soc: Option<f64>, matrices: bool) {
        if let Some(alpha) = soc {
            // c_soc = alpha c(z) + c(z_trial) (eq. 27); c(z) is what the last QP used. The
            // dynamics defect reads the next stage's trial state: done here, stage by stage.
            let n = self.buffers.len();
            for k in 0..n {
                let next_x = self.buffers.get(k + 1).map(|nb| &nb.trial_primal);
                let (b, qp) = (&self.buffers[k], &mut self.qps[k]);
                for i in 0..qp.defect.len() {
                    qp.defect[i] = alpha * qp.defect[i] + (b.trial.dynamics[i] - next_x.map_or(0.0, |x| x[i]));
                }
            }
        }
        // The rest of a stage's QP reads that stage's buffers only: stage by stage, on
        // rayon's threads when `parallel`.
        for_each_stage_with(self.settings.parallel, &mut self.buffers, &mut self.qps, |k, b, qp| {
            let (lo, up) = problem.bounds(k);
            let d = problem.dims()[k];
            match soc {
                None => {
                    for i in 0..d.nh {
                        b.ineq_residual[i] = b.values.inequalities[i] - it.slack[k][i];
                    }
                    for i in 0..d.nx_next {
                        qp.defect[i] = b.values.dynamics[i] - it.primal[k + 1][i];
                    }
                    qp.equality_residual.copy_from(&b.values.equalities);
                }
                Some(alpha) => {
                    for i in 0..d.nh {
                        b.ineq_residual[i] = alpha * b.ineq_residual[i] + (b.trial.inequalities[i] - b.trial_slack[i]);
                    }
                    for i in 0..d.ng {
                        qp.equality_residual[i] = alpha * qp.equality_residual[i] + b.trial.equalities[i];
                    }
                }
            }
            // A second-order correction changes the right-hand side only: the matrices (and
            // the Riccati factorization) stay those of the step it corrects.
            if matrices {
                qp.hessian.as_mut_slice().copy_from_slice(b.hess.as_slice());
                if delta > 0.0 {
                    for i in 0..d.nz() {
                        qp.hessian[(i, i)] += delta;
                    }
                }
            }
            qp.gradient.copy_from(&b.jac.cost_gradient);
            for i in 0..d.nh {
                let s = it.slack[k][i];
                let mut sigma = 0.0;
                let mut c = 0.0;
                if lo[i].is_finite() {
                    sigma += it.lower_bound_multiplier[k][i] / (s - lo[i]);
                    c -= mu / (s - lo[i]);
                }
                if up[i].is_finite() {
                    sigma += it.upper_bound_multiplier[k][i] / (up[i] - s);
                    c += mu / (up[i] - s);
                }
                b.sigma[i] = sigma;
                b.lin[i] = sigma * b.ineq_residual[i] + c;
            }
            // J_h^T Sigma J_h and J_h^T lin row by row over each row's nonzeros (most rows
            // are simple bounds with one; gathered by `evaluate_derivatives`).
            let nz = d.nz();
            let (gradient, hessian) = (qp.gradient.as_mut_slice(), qp.hessian.as_mut_slice());
            for i in 0..d.nh {
                let (sigma, lin) = (b.sigma[i], b.lin[i]);
                let (columns, values) = b.jh_rows.row(i);
                for (&a, &ja) in columns.iter().zip(values) {
                    gradient[a] += ja * lin;
                    if sigma != 0.0 && matrices {
                        let hessian_column = &mut hessian[a * nz..(a + 1) * nz];
                        for (&c, &jc) in columns.iter().zip(values) {
                            hessian_column[c] += sigma * ja * jc;
                        }
                    }
                }
            }
            if matrices {
                qp.dynamics.as_mut_slice().copy_from_slice(b.jac.dynamics.as_slice());
                qp.equality_jacobian.as_mut_slice().copy_from_slice(b.jac.equalities.as_slice());
            }
        });
    }

    /// Slack and bound-multiplier steps from the Riccati solution (eq. 13 expanded), stage
    /// by stage (on rayon's threads when `parallel`).
    fn gather_step(&mut self, problem: &Problem, it: &Iterate, mu: f64) {
        let steps = &self.steps;
        for_each_stage(self.settings.parallel, &mut self.buffers, |k, b| {
            let (lo, up) = problem.bounds(k);
            let nh = b.ds.len();
            b.ds.copy_from(&b.ineq_residual);
            b.jh_rows.add_times(steps[k].dz.as_slice(), b.ds.as_mut_slice());
            for i in 0..nh {
                let s = it.slack[k][i];
                let ds = b.ds[i];
                let mut y = b.sigma[i] * ds;
                b.dzl[i] = 0.0;
                b.dzu[i] = 0.0;
                if lo[i].is_finite() {
                    let dl = s - lo[i];
                    let zl = it.lower_bound_multiplier[k][i];
                    b.dzl[i] = mu / dl - zl - zl / dl * ds;
                    y -= mu / dl;
                }
                if up[i].is_finite() {
                    let du = up[i] - s;
                    let zu = it.upper_bound_multiplier[k][i];
                    b.dzu[i] = mu / du - zu + zu / du * ds;
                    y += mu / du;
                }
                b.y_new[i] = y;
            }
        });
    }

    fn max_primal_step(&mut self, problem: &Problem, it: &Iterate, tau: f64) -> f64 {
        let mut alpha: f64 = 1.0;
        let mut blocking = None;
        for (k, b) in self.buffers.iter().enumerate() {
            let (lo, up) = problem.bounds(k);
            for i in 0..b.ds.len() {
                let (s, ds) = (it.slack[k][i], b.ds[i]);
                let bound = if lo[i].is_finite() && ds < 0.0 {
                    -tau * (s - lo[i]) / ds
                } else if up[i].is_finite() && ds > 0.0 {
                    tau * (up[i] - s) / ds
                } else {
                    f64::INFINITY
                };
                if bound < alpha {
                    alpha = bound;
                    blocking = Some((k, i));
                }
            }
        }
        self.last_step.alpha_max = alpha;
        self.last_step.blocking = blocking;
        alpha
    }

    /// The monotone (Fiacco-McCormick) update (eq. 7): while the barrier problem is solved to
    /// `kappa_epsilon mu`, `mu <- max(tol / 10, min(kappa_mu mu, mu^theta_mu))`.
    fn monotone_barrier_update(&mut self, problem: &Problem, it: &Iterate, mu: &mut f64, errors: &mut Errors) {
        let (mu_min, kappa_epsilon, kappa_mu, theta_mu) = (self.settings.tolerance / 10.0, self.settings.kappa_epsilon, self.settings.kappa_mu, self.settings.theta_mu);
        while errors.error_mu <= kappa_epsilon * *mu && *mu > mu_min {
            *mu = mu_min.max((kappa_mu * *mu).min(mu.powf(theta_mu)));
            self.filter.reset();
            *errors = self.errors(problem, it, *mu);
        }
    }

    /// The adaptive update's `mu = sigma avg(s z)` (Nocedal, Wächter & Waltz 2009), within
    /// `mu_bounds`, from the affine-scaling step in `steps` (solved with the QP's right-hand
    /// side at `mu = 0`); leaves the QPs' vectors and the step of that `mu` in `qps` and
    /// `steps`. `None` if a re-solve fails.
    fn oracle_mu(&mut self, problem: &Problem, it: &Iterate, oracle: MuOracle, average: f64, mu_bounds: (f64, f64), errors: &Errors) -> Option<f64> {
        let s = &self.settings;
        let (sigma_min, sigma_max, tau) = (s.sigma_min, s.sigma_max, s.tau_min);
        self.gather_step(problem, it, 0.0);
        self.collect_pairs(problem, it, false);
        match oracle {
            MuOracle::Probing => {
                // Mehrotra's probing (sec. 3): the complementarity after the affine step to
                // the boundary, `sigma = (mu_aff / avg)^3`.
                let (alpha_primal, alpha_dual) = self.pairs.step_to_boundary(0.0, 1.0);
                let (mu_affine, _) = self.pairs.after(0.0, alpha_primal, alpha_dual);
                let mu = ((mu_affine / average).powi(3).clamp(sigma_min, sigma_max) * average).clamp(mu_bounds.0, mu_bounds.1);
                self.assemble_qp_vectors(problem, it, mu);
                self.riccati.resolve(&self.qps, &mut self.steps).ok()?;
                Some(mu)
            }
            MuOracle::QualityFunction => {
                // The step is affine in `mu`: `d(sigma avg) = d_aff + sigma (d(avg) - d_aff)`,
                // and so is the QPs' gradient (the affine ones kept for the combination).
                for (k, b) in self.buffers.iter_mut().enumerate() {
                    self.saved_steps[k].copy_from(&self.steps[k]);
                    b.gradient_affine.copy_from(&self.qps[k].gradient);
                }
                self.assemble_qp_vectors(problem, it, average);
                self.riccati.resolve(&self.qps, &mut self.steps).ok()?;
                self.gather_step(problem, it, average);
                self.collect_pairs(problem, it, true);
                let pairs = &self.pairs;
                let quality = |log_sigma: f64| pairs.quality(log_sigma.exp(), tau, errors);
                // The side of sigma = 1 on which the quality decreases, then golden section
                // on `log sigma` there (sec. 4), keeping the best sigma met.
                // (The quality at sigma = 1 is one end of the interval: evaluated once.)
                let quality_at_one = quality(0.0);
                let ((mut lo, mut hi), (q_lo, q_hi)) = if quality(0.99f64.ln()) < quality_at_one {
                    ((sigma_min.ln(), 0.0), (quality(sigma_min.ln()), quality_at_one))
                } else {
                    ((0.0, sigma_max.ln()), (quality_at_one, quality(sigma_max.ln())))
                };
                let golden = 0.5 * (5f64.sqrt() - 1.0);
                let (mut a, mut b) = (hi - golden * (hi - lo), lo + golden * (hi - lo));
                let (mut qa, mut qb) = (quality(a), quality(b));
                let mut best = [(lo, q_lo), (hi, q_hi), (a, qa), (b, qb)].into_iter().fold((0.0, f64::INFINITY), |m, p| if p.1 < m.1 { p } else { m });
                for _ in 0..QUALITY_SECTION_STEPS {
                    if qa <= qb {
                        (hi, b, qb) = (b, a, qa);
                        a = hi - golden * (hi - lo);
                        qa = quality(a);
                        if qa < best.1 {
                            best = (a, qa);
                        }
                    } else {
                        (lo, a, qa) = (a, b, qb);
                        b = lo + golden * (hi - lo);
                        qb = quality(b);
                        if qb < best.1 {
                            best = (b, qb);
                        }
                    }
                }
                let mu = (best.0.exp() * average).clamp(mu_bounds.0, mu_bounds.1);
                let sigma = mu / average;
                for (k, b) in self.buffers.iter().enumerate() {
                    let (step, affine) = (&mut self.steps[k], &self.saved_steps[k]);
                    for (d, a) in [(&mut step.dz, &affine.dz), (&mut step.dynamics_multiplier, &affine.dynamics_multiplier), (&mut step.equality_multiplier, &affine.equality_multiplier), (&mut self.qps[k].gradient, &b.gradient_affine)] {
                        // d <- a + sigma (d - a)
                        d.axpy(1.0 - sigma, a, sigma);
                    }
                }
                Some(mu)
            }
            MuOracle::Loqo => unreachable!("LOQO's rule needs no affine step"),
        }
    }

    /// Fills [`ComplementarityPairs`] from the iterate and the step in `ds`, `dzl`, `dzu`:
    /// as the affine-scaling step (`centering = false`, no difference yet), or as the
    /// centering step `d(avg)` whose difference to the affine step is kept.
    fn collect_pairs(&mut self, problem: &Problem, it: &Iterate, centering: bool) {
        let p = &mut self.pairs;
        if !centering {
            for v in [&mut p.gap, &mut p.multiplier, &mut p.gap_inverse, &mut p.multiplier_inverse, &mut p.gap_affine, &mut p.gap_difference, &mut p.multiplier_affine, &mut p.multiplier_difference] {
                v.clear();
            }
        }
        let mut j = 0;
        for (k, b) in self.buffers.iter().enumerate() {
            let (lo, up) = problem.bounds(k);
            let (slack, zl, zu) = (it.slack[k].as_slice(), it.lower_bound_multiplier[k].as_slice(), it.upper_bound_multiplier[k].as_slice());
            let (ds, dzl, dzu) = (b.ds.as_slice(), b.dzl.as_slice(), b.dzu.as_slice());
            for i in 0..ds.len() {
                // (gap, z, d gap, d z) of the lower and the upper bound.
                let mut pair = |gap: f64, z: f64, d_gap: f64, d_z: f64| {
                    if centering {
                        p.gap_difference[j] = d_gap - p.gap_affine[j];
                        p.multiplier_difference[j] = d_z - p.multiplier_affine[j];
                    } else {
                        p.gap.push(gap);
                        p.multiplier.push(z);
                        p.gap_inverse.push(1.0 / gap);
                        p.multiplier_inverse.push(1.0 / z);
                        p.gap_affine.push(d_gap);
                        p.multiplier_affine.push(d_z);
                        p.gap_difference.push(0.0);
                        p.multiplier_difference.push(0.0);
                    }
                    j += 1;
                };
                if lo[i].is_finite() {
                    pair(slack[i] - lo[i], zl[i], ds[i], dzl[i]);
                }
                if up[i].is_finite() {
                    pair(up[i] - slack[i], zu[i], -ds[i], dzu[i]);
                }
            }
        }
    }

    fn max_dual_step(&self, it: &Iterate, tau: f64) -> f64 {
        let mut alpha: f64 = 1.0;
        for (k, b) in self.buffers.iter().enumerate() {
            for i in 0..b.ds.len() {
                let (zl, zu) = (it.lower_bound_multiplier[k][i], it.upper_bound_multiplier[k][i]);
                if zl > 0.0 && b.dzl[i] < 0.0 {
                    alpha = alpha.min(-tau * zl / b.dzl[i]);
                }
                if zu > 0.0 && b.dzu[i] < 0.0 {
                    alpha = alpha.min(-tau * zu / b.dzu[i]);
                }
            }
        }
        alpha
    }

    /// Barrier objective `phi` of the trial point in `trial`, and its violation `theta`.
    fn measure_trial(&mut self, problem: &Problem, mu: f64, timings: &mut Timings) -> (f64, f64) {
        let t = Instant::now();
        for_each_stage(self.settings.parallel, &mut self.buffers, |k, b| problem.stage(k).evaluate(b.trial_primal.as_slice(), &mut b.trial));
        timings.evaluation += t.elapsed();
        let n = self.buffers.len();
        let (mut theta, mut phi) = (0.0, 0.0);
        for k in 0..n {
            let (lo, up) = problem.bounds(k);
            let b = &self.buffers[k];
            phi += b.trial.cost;
            phi += barrier(&b.trial_slack, lo, up, mu);
            let next = if k + 1 < n { Some(&self.buffers[k + 1].trial_primal) } else { None };
            theta += violation_1(&b.trial, next, problem.dims()[k].nx_next, &b.trial_slack);
        }
        (theta, phi)
    }

    fn set_trial(&mut self, it: &Iterate, alpha: f64) {
        for (k, b) in self.buffers.iter_mut().enumerate() {
            b.trial_primal.copy_from(&it.primal[k]);
            b.trial_primal.axpy(alpha, &self.steps[k].dz, 1.0);
            b.trial_slack.copy_from(&it.slack[k]);
            b.trial_slack.axpy(alpha, &b.ds, 1.0);
        }
    }

    /// The filter line search (Algorithm A, steps ). `Err(theta)` if the step
    /// size fell below `alpha_min`.
    #[allow(clippy::too_many_arguments)]
    fn line_search(&mut self, problem: &Problem, it: &mut Iterate, mu: f64, tau: f64, alpha_max: f64, alpha_z: f64, theta_min: f64, delta: f64, timings: &mut Timings) -> Result<(), f64> {
        let s = self.settings.clone();
        // theta and phi at the current point (values are those of `it`).
        let n = self.buffers.len();
        let (mut theta, mut phi, mut dphi) = (0.0, 0.0, 0.0);
        for k in 0..n {
            let (lo, up) = problem.bounds(k);
            let b = &self.buffers[k];
            theta += violation_1(&b.values, it.primal.get(k + 1), problem.dims()[k].nx_next, &it.slack[k]);
            phi += b.values.cost + barrier(&it.slack[k], lo, up, mu);
            dphi += b.jac.cost_gradient.dot(&self.steps[k].dz);
            for i in 0..b.ds.len() {
                let sl = it.slack[k][i];
                if lo[i].is_finite() {
                    dphi -= mu * b.ds[i] / (sl - lo[i]);
                }
                if up[i].is_finite() {
                    dphi += mu * b.ds[i] / (up[i] - sl);
                }
            }
        }
        // Tiny step: accept it whole (IPOPT's heuristic; sec. 3.9).
        let tiny = self.buffers.iter().enumerate().all(|(k, _)| {
            self.steps[k].dz.iter().zip(it.primal[k].iter()).all(|(d, z)| d.abs() <= 10.0 * f64::EPSILON * (1.0 + z.abs()))
        });
        let alpha_min = {
            let g = s.gamma_theta;
            if dphi < 0.0 {
                let a = g.min(s.gamma_phi * theta / (-dphi));
                if theta <= theta_min { s.gamma_alpha * a.min(s.switching_delta * theta.powf(s.s_theta) / (-dphi).powf(s.s_phi)) } else { s.gamma_alpha * a }
            } else {
                s.gamma_alpha * g
            }
        };
        let mut alpha = alpha_max;
        let mut first = true;
        loop {
            if !tiny && alpha < alpha_min {
                return Err(theta);
            }
            self.set_trial(it, alpha);
            let (theta_t, phi_t) = self.measure_trial(problem, mu, timings);
            let switching = dphi < 0.0 && alpha * (-dphi).powf(s.s_phi) > s.switching_delta * theta.powf(s.s_theta);
            let mut verdict = acceptance(&self.filter, &s, theta, phi, dphi, alpha, theta_t, phi_t, theta_min, switching);
            if tiny && !(theta_t.is_finite() && phi_t.is_finite()) {
                verdict = None;
            } else if tiny {
                verdict = Some(false);
            }
            // Second-order corrections when the first trial is rejected and worsens theta.
            if verdict.is_none() && first && s.max_second_order_corrections > 0 && theta_t >= theta && theta_t.is_finite() {
                let mut theta_soc_old = theta;
                let mut theta_trial = theta_t;
                let mut alpha_soc = alpha;
                self.save_step();
                for _ in 0..s.max_second_order_corrections {
                    if theta_trial > s.kappa_soc * theta_soc_old && theta_soc_old != theta {
                        break;
                    }
                    theta_soc_old = theta_trial;
                    let t = Instant::now();
                    self.assemble_qp(problem, it, mu, delta, Some(alpha_soc));
                    let ok = self.riccati.resolve(&self.qps, &mut self.steps).is_ok();
                    if ok {
                        self.refine_step();
                    }
                    timings.kkt += t.elapsed();
                    if !ok {
                        break;
                    }
                    self.gather_step(problem, it, mu);
                    alpha_soc = self.max_primal_step(problem, it, tau);
                    self.set_trial(it, alpha_soc);
                    let (th, ph) = self.measure_trial(problem, mu, timings);
                    theta_trial = th;
                    let v = acceptance(&self.filter, &s, theta, phi, dphi, alpha, th, ph, theta_min, switching);
                    if let Some(f_type) = v {
                        if !f_type {
                            self.filter.add((1.0 - s.gamma_theta) * theta, phi - s.gamma_phi * theta);
                        }
                        let az = self.max_dual_step(it, tau);
                        self.accept(it, alpha_soc, az);
                        return Ok(());
                    }
                }
                // Restore the original direction for further backtracking (kept, not
                // solved again: the same QP gives the same step).
                self.restore_step();
                self.gather_step(problem, it, mu);
            }
            first = false;
            if let Some(f_type) = verdict {
                if !f_type {
                    self.filter.add((1.0 - s.gamma_theta) * theta, phi - s.gamma_phi * theta);
                }
                self.accept(it, alpha, alpha_z);
                return Ok(());
            }
            alpha *= s.backtracking_factor;
        }
    }

    /// Iterative refinement of the step in `steps` (Wächter & Biegler 2006, sec. 3.1; IPOPT's
    /// residual test): `r = K s - rhs` on every stage's rows, and while
    /// `|r| / (|s| + |rhs|) > refinement_residual_ratio`, `s -= K^{-1} r`, re-solved with
    /// the last factorization (the matrices are unchanged, only the right-hand side is `r`:
    /// [`RiccatiSolver::resolve`], the vector half of the recursion). Returns the number of
    /// re-solves.
    fn refine_step(&mut self) -> usize {
        let mut solves = 0;
        let mut ratio = self.kkt_residual();
        while ratio > self.settings.refinement_residual_ratio && solves < self.settings.max_refinement_steps {
            // The correction solves K c = r: the residuals stand in for the QPs' right-hand
            // sides for one re-solve, then the right-hand sides are put back.
            self.swap_right_hand_sides_with_residuals();
            let ok = self.riccati.resolve(&self.qps, &mut self.correction).is_ok();
            self.swap_right_hand_sides_with_residuals();
            solves += 1;
            if !ok {
                break;
            }
            for (step, c) in self.steps.iter_mut().zip(&self.correction) {
                step.dz += &c.dz;
                step.dynamics_multiplier += &c.dynamics_multiplier;
                step.equality_multiplier += &c.equality_multiplier;
            }
            let previous = ratio;
            ratio = self.kkt_residual();
            if ratio > 0.5 * previous {
                // Round-off level reached: further corrections do not pay.
                break;
            }
        }
        solves
    }

    /// Exchanges the QPs' right-hand sides (gradient, defect, equality residual) with the
    /// KKT residuals of [`Self::kkt_residual`]; twice is the identity.
    fn swap_right_hand_sides_with_residuals(&mut self) {
        for (qp, r) in self.qps.iter_mut().zip(&mut self.residuals) {
            std::mem::swap(&mut qp.gradient, &mut r.stationarity);
            std::mem::swap(&mut qp.defect, &mut r.dynamics);
            std::mem::swap(&mut qp.equality_residual, &mut r.equalities);
        }
    }

    /// The residuals of the KKT system of the QPs at `steps` into `residuals`:
    /// `H dz + q + F^T lambda + G^T nu - [lambda_{k-1}; 0]`, `F dz + b - dx_{k+1}`,
    /// `G dz + g`; returns `|r| / (|s| + |rhs|)` (max norms).
    fn kkt_residual(&mut self) -> f64 {
        let n = self.qps.len();
        let (qps, steps) = (&self.qps, &self.steps);
        // Stage k's residual rows and its largest residual, step and right-hand side entries.
        let stage = |k: usize, r: &mut KktResidual| -> [f64; 3] {
            let (qp, step) = (&qps[k], &steps[k]);
            let g = &mut r.stationarity;
            g.copy_from(&qp.gradient);
            g.gemv(1.0, &qp.hessian, &step.dz, 1.0);
            g.gemv_tr(1.0, &qp.dynamics, &step.dynamics_multiplier, 1.0);
            g.gemv_tr(1.0, &qp.equality_jacobian, &step.equality_multiplier, 1.0);
            if k > 0 {
                for (gi, lam) in g.iter_mut().zip(steps[k - 1].dynamics_multiplier.iter()) {
                    *gi -= lam;
                }
            }
            r.dynamics.copy_from(&qp.defect);
            if k + 1 < n {
                r.dynamics.gemv(1.0, &qp.dynamics, &step.dz, 1.0);
                for (ri, dx) in r.dynamics.iter_mut().zip(steps[k + 1].dz.iter()) {
                    *ri -= dx;
                }
            }
            r.equalities.copy_from(&qp.equality_residual);
            r.equalities.gemv(1.0, &qp.equality_jacobian, &step.dz, 1.0);
            [
                g.amax().max(r.dynamics.amax()).max(r.equalities.amax()),
                step.dz.amax().max(step.dynamics_multiplier.amax()).max(step.equality_multiplier.amax()),
                qp.gradient.amax().max(qp.defect.amax()).max(qp.equality_residual.amax()),
            ]
        };
        // Maxima: the same in any order.
        let largest = |a: [f64; 3], b: [f64; 3]| [a[0].max(b[0]), a[1].max(b[1]), a[2].max(b[2])];
        let [residual, solution, rhs] = if self.settings.parallel {
            self.residuals.par_iter_mut().enumerate().map(|(k, r)| stage(k, r)).reduce(|| [0.0; 3], largest)
        } else {
            self.residuals.iter_mut().enumerate().map(|(k, r)| stage(k, r)).fold([0.0; 3], largest)
        };
        if residual == 0.0 {
            0.0
        } else {
            residual / (solution + rhs)
        }
    }

    /// Keeps the current step and the residuals of its QP (before second-order corrections).
    fn save_step(&mut self) {
        for (k, b) in self.buffers.iter_mut().enumerate() {
            b.saved_ineq_residual.copy_from(&b.ineq_residual);
            self.saved_steps[k].copy_from(&self.steps[k]);
        }
    }

    /// Brings back what [`Self::save_step`] kept; `gather_step` then rebuilds the slack and
    /// bound-multiplier steps (`Sigma` is that of the current iterate, unchanged).
    fn restore_step(&mut self) {
        for (k, b) in self.buffers.iter_mut().enumerate() {
            b.ineq_residual.copy_from(&b.saved_ineq_residual);
            self.steps[k].copy_from(&self.saved_steps[k]);
        }
    }

    /// Takes the trial point in the buffers and the multiplier steps.
    fn accept(&mut self, it: &mut Iterate, alpha: f64, alpha_z: f64) {
        self.last_step.alpha_primal = alpha;
        for (k, b) in self.buffers.iter_mut().enumerate() {
            it.primal[k].copy_from(&b.trial_primal);
            it.slack[k].copy_from(&b.trial_slack);
            std::mem::swap(&mut b.values, &mut b.trial);
            let lam = &mut it.dynamics_multiplier[k];
            *lam *= 1.0 - alpha;
            lam.axpy(alpha, &self.steps[k].dynamics_multiplier, 1.0);
            let nu = &mut it.equality_multiplier[k];
            *nu *= 1.0 - alpha;
            nu.axpy(alpha, &self.steps[k].equality_multiplier, 1.0);
            let y = &mut it.inequality_multiplier[k];
            *y *= 1.0 - alpha;
            y.axpy(alpha, &b.y_new, 1.0);
            it.lower_bound_multiplier[k].axpy(alpha_z, &b.dzl, 1.0);
            it.upper_bound_multiplier[k].axpy(alpha_z, &b.dzu, 1.0);
        }
    }

    /// Keeps `zl (s - l)` within `[mu / kappa_sigma, kappa_sigma mu]` (eq. 16).
    fn reset_bound_multipliers(&self, problem: &Problem, it: &mut Iterate, mu: f64) {
        let ks = self.settings.kappa_sigma;
        for k in 0..it.slack.len() {
            let (lo, up) = problem.bounds(k);
            for i in 0..it.slack[k].len() {
                let s = it.slack[k][i];
                if lo[i].is_finite() {
                    let d = s - lo[i];
                    let z = &mut it.lower_bound_multiplier[k][i];
                    *z = z.min(ks * mu / d).max(mu / (ks * d));
                }
                if up[i].is_finite() {
                    let d = up[i] - s;
                    let z = &mut it.upper_bound_multiplier[k][i];
                    *z = z.min(ks * mu / d).max(mu / (ks * d));
                }
            }
        }
    }
}

/// Filter acceptance of a trial: `Some(true)` for an f-type step (Armijo
/// on `phi`, the filter is not augmented), `Some(false)` for a step accepted by sufficient
/// decrease of `theta` or `phi`, `None` if rejected.
#[allow(clippy::too_many_arguments)]
fn acceptance(filter: &Filter, s: &Settings, theta: f64, phi: f64, dphi: f64, alpha: f64, theta_t: f64, phi_t: f64, theta_min: f64, switching: bool) -> Option<bool> {
    if !(theta_t.is_finite() && phi_t.is_finite() && filter.acceptable(theta_t, phi_t)) {
        return None;
    }
    if theta <= theta_min && switching {
        if phi_t <= phi + s.eta_phi * alpha * dphi {
            return Some(true);
        }
        return None;
    }
    if theta_t <= (1.0 - s.gamma_theta) * theta || phi_t <= phi - s.gamma_phi * theta {
        return Some(false);
    }
    None
}

/// The nonzeros of a matrix by row (row `i`'s columns, increasing, and values in slots
/// `i * cols ..`), gathered in one pass down its contiguous columns.
struct SparseRows {
    cols: usize,
    count: Vec<usize>,
    columns: Vec<usize>,
    values: Vec<f64>,
}

impl SparseRows {
    fn new(rows: usize, cols: usize) -> Self {
        Self { cols, count: vec![0; rows], columns: vec![0; rows * cols], values: vec![0.0; rows * cols] }
    }

    fn gather(&mut self, a: &DMatrix<f64>) {
        let (rows, cols) = (a.nrows(), self.cols);
        self.count.fill(0);
        if rows == 0 {
            return;
        }
        for (j, column) in a.as_slice().chunks_exact(rows).enumerate() {
            for (i, &v) in column.iter().enumerate() {
                if v != 0.0 {
                    let slot = i * cols + self.count[i];
                    self.columns[slot] = j;
                    self.values[slot] = v;
                    self.count[i] += 1;
                }
            }
        }
    }

    /// Columns and values of row `i`'s nonzeros.
    fn row(&self, i: usize) -> (&[usize], &[f64]) {
        let range = i * self.cols..i * self.cols + self.count[i];
        (&self.columns[range.clone()], &self.values[range])
    }

    /// `out += A x`.
    fn add_times(&self, x: &[f64], out: &mut [f64]) {
        for (i, o) in out.iter_mut().enumerate() {
            let (columns, values) = self.row(i);
            for (&a, &v) in columns.iter().zip(values) {
                *o += v * x[a];
            }
        }
    }

    /// `out += A^T y`.
    fn add_transpose_times(&self, y: &[f64], out: &mut [f64]) {
        for (i, &yi) in y.iter().enumerate() {
            let (columns, values) = self.row(i);
            for (&a, &v) in columns.iter().zip(values) {
                out[a] += v * yi;
            }
        }
    }
}

/// The average and the smallest complementarity product `(s - l) z_l`, `(u - s) z_u` over all
/// bounds; `None` without bounds.
fn complementarity(problem: &Problem, it: &Iterate) -> Option<(f64, f64)> {
    let (mut sum, mut smallest, mut count) = (0.0, f64::INFINITY, 0usize);
    for k in 0..it.slack.len() {
        let (lo, up) = problem.bounds(k);
        for i in 0..it.slack[k].len() {
            let s = it.slack[k][i];
            if lo[i].is_finite() {
                let c = (s - lo[i]) * it.lower_bound_multiplier[k][i];
                sum += c;
                smallest = smallest.min(c);
                count += 1;
            }
            if up[i].is_finite() {
                let c = (up[i] - s) * it.upper_bound_multiplier[k][i];
                sum += c;
                smallest = smallest.min(c);
                count += 1;
            }
        }
    }
    (count > 0).then(|| (sum / count as f64, smallest))
}

/// `-mu sum ln(s - l) + ln(u - s)`; `+inf` outside the interior.
pub(super) fn barrier(slack: &DVector<f64>, lo: &[f64], up: &[f64], mu: f64) -> f64 {
    let mut b = 0.0;
    for i in 0..slack.len() {
        let s = slack[i];
        if lo[i].is_finite() {
            let d = s - lo[i];
            if d <= 0.0 {
                return f64::INFINITY;
            }
            b -= mu * d.ln();
        }
        if up[i].is_finite() {
            let d = up[i] - s;
            if d <= 0.0 {
                return f64::INFINITY;
            }
            b -= mu * d.ln();
        }
    }
    b
}

/// `|f - x_next|_1 + |g|_1 + |h - s|_1` of one stage.
pub(super) fn violation_1(v: &StageValues, next_primal: Option<&DVector<f64>>, nx_next: usize, slack: &DVector<f64>) -> f64 {
    let mut t = 0.0;
    if let Some(xn) = next_primal {
        for i in 0..nx_next {
            t += (v.dynamics[i] - xn[i]).abs();
        }
    }
    t += v.equalities.lp_norm(1);
    for i in 0..slack.len() {
        t += (v.inequalities[i] - slack[i]).abs();
    }
    t
}

/// IPOPT's initial slack (sec. 3.6): `h` projected into `[l + p_l, u - p_u]`.
fn push_into_interior(h: f64, lo: f64, up: f64, push: f64, frac: f64) -> f64 {
    let mut pl = push * lo.abs().max(1.0);
    let mut pu = push * up.abs().max(1.0);
    if lo.is_finite() && up.is_finite() {
        pl = pl.min(frac * (up - lo));
        pu = pu.min(frac * (up - lo));
    }
    let mut s = h;
    if lo.is_finite() {
        s = s.max(lo + pl);
    }
    if up.is_finite() {
        s = s.min(up - pu);
    }
    s
}
