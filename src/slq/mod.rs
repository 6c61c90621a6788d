//! Sequential Linear Quadratic control (SLQ), Neunert 2017, Algorithm 1.
//!
//! One loop that reads like the algorithm ([`Slq::solve`]), calling named parts:
//!
//! 1. `rollout`: simulate the system with the current control law;
//! 2. `linearize`: `A_k`, `B_k` and the cost's quadratic model along the
//!    trajectory, knots in parallel (rayon), one problem workspace per thread;
//! 3. `backward_pass`: the Riccati-like difference equations, with
//!    Levenberg-Marquardt regularization of `H` when it is not positive definite; where the
//!    problem bounds the inputs ([`Problem::input_bounds`]), the step `l` is the solution of
//!    the box-constrained QP of Tassa, Mansard, Todorov 2014 ([`BoxQp`]) and the gain rows of
//!    the clamped inputs are zero;
//! 4. `line_search`: `u = u_n + alpha l + K (x - x_n)`, projected onto the input box,
//!    `alpha <- alpha / alpha_d`, until the cost decreases.
//!
//! It stops when the feedforward increments are small (`||l|| < l_t`), when the cost no
//! longer changes, when the normalized cost of the paper's Fig. 12 (cost over the initial
//! cost) has been flat to 0.1 % for five iterations, or after the maximum number of
//! iterations; a line search that cannot
//! decrease the cost, or a non-finite cost, ends the run with the best iterate kept and the
//! reason reported. Every iteration records its cost, step size and time per part.

mod box_qp;
mod cholesky;
mod problem;
mod realtime;
mod receding;
mod warm_start;

pub use box_qp::{BoxQp, BoxQpSettings, BoxQpStatus};
pub use problem::{KnotDerivatives, Policy, Problem};
pub use realtime::{set_realtime_priority, RealtimePriorityError, REALTIME_PRIORITIES};
pub use receding::{RealTimeIteration, RealTimeIterationError};
pub use warm_start::SolutionPolicy;

use crate::linalg::{gemm, gemv_add};
use cholesky::SmallCholesky;
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, AtomicIsize, Ordering};
use std::sync::{Mutex, PoisonError};
use std::time::Instant;

/// Solver settings (defaults in parentheses).
#[derive(Clone, Debug, PartialEq)]
pub struct SlqSettings {
    /// Maximum iterations (40, the upper end of the paper's "10-40").
    pub max_iterations: usize,
    /// Stop when the RMS over knots of the feedforward increment `l_k` is below this (1e-4).
    pub feedforward_tolerance: f64,
    /// Stop when an iteration changes the cost by less than this fraction (1e-6).
    pub relative_cost_tolerance: f64,
    /// Stop when, over the last [`stall_window`](Self::stall_window) iterations, the cost
    /// fell by less than this fraction of the initial rollout's cost (1e-3): the normalized
    /// cost of the paper's Fig. 12 (cost over initial cost) is flat to 0.1 %. 0 disables it.
    pub normalized_cost_tolerance: f64,
    /// Iterations (accepted or not) the normalized-cost test looks back over (5).
    pub stall_window: usize,
    /// Step-size divisor `alpha_d` (2).
    pub alpha_divisor: f64,
    /// Line-search trials per iteration (12).
    pub max_line_search_steps: usize,
    /// Initial and minimum Levenberg-Marquardt regularization of `H` (1e-8, 1e-10).
    pub initial_regularization: f64,
    pub min_regularization: f64,
    /// Regularization above which the backward pass gives up (1e10).
    pub max_regularization: f64,
    /// A small `||l||` counts as convergence only if the step was this little regularized
    /// (1e-6): a large `mu` shrinks `l = -(H + mu I)^-1 g` without the gradient vanishing.
    pub convergence_regularization: f64,
    /// Threads for the linearization (0 = rayon's default: one per core).
    pub threads: usize,
    /// `SCHED_FIFO` priority (1-99) of the solver's pool threads (`None`: the operating
    /// system's default scheduling). With it the pool is built even for one thread, and
    /// the parallel steps run on it. See [`set_realtime_priority`]; [`Slq::new`] fails
    /// with [`SlqError::Settings`] if the system refuses.
    pub realtime_priority: Option<i32>,
    /// With two or more threads, run the backward pass while the linearization is still
    /// under way (true): the knots are linearized from the last one down, and the pass
    /// takes each as soon as it is ready, its thread linearizing the next unclaimed knot
    /// while it waits. The same arithmetic on every knot, so the same iterates to the bit;
    /// only the order in which the threads do the work changes.
    pub overlap_backward_pass: bool,
    /// An accepted step shorter than this raises the regularization by
    /// `short_step_regularization_growth` instead of lowering it tenfold (0: never).
    pub short_step: f64,
    pub short_step_regularization_growth: f64,
    /// How the input box of [`Problem::input_bounds`] is kept ([`ControlLimits::ProjectedRollout`]).
    pub control_limits: ControlLimits,
    /// The projected-Newton QP of [`ControlLimits::BoxQp`] ([`BoxQpSettings`]'s defaults).
    pub box_qp: BoxQpSettings,
    /// Return the local value function of the last backward pass
    /// ([`SlqSolution::value_function`]; false: none, no memory for it).
    pub record_value_function: bool,
    /// Keep the knots' models across real-time iterations ([`ModelReuse`]; `None`: every
    /// knot linearized every iteration). Only [`Slq::real_time_iteration`] reuses them; a
    /// whole solve linearizes every knot.
    pub model_reuse: Option<ModelReuse>,
}

/// Which knots a real-time iteration linearizes anew (the multi-level iteration of Bock et
/// al. 2007, its level "new gradients, old Jacobians"): the window moves on by a knot or
/// two a tick and the trajectory changes by one step, so most knots' `A`, `B` and cost
/// Hessians from an earlier tick still describe them. Each iteration linearizes the first
/// `fresh_head` knots (the robot runs them before the next tick), the knots new to the
/// window, every `refresh_period`-th of the rest in turn (each knot at least every
/// `refresh_period` iterations), and any knot whose state left its model's piece
/// ([`Problem::same_model_piece`]: a foot landed or lifted); every other knot keeps its
/// model, its cost gradient moved to the new trajectory by its Hessian,
///
/// ```text
/// l_x <- l_x + l_xx dx + l_ux^T du,   l_u <- l_u + l_ux dx + l_uu du,
/// dx = x_k (-) x_k^lin,  du = u_k - u_k^lin
/// ```
///
/// (the old quadratic model, centred at the new trajectory: without it the pass would take
/// the last tick's step again). On the whole-body tasks it shortens a tick by about a
/// quarter and costs robustness where feet land and slip (docs/experiments/mpc-6.md).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ModelReuse {
    /// Knots at the window's start linearized every iteration.
    pub fresh_head: usize,
    /// At least 1 (1: every knot, every iteration).
    pub refresh_period: usize,
}

/// How SLQ keeps the inputs in their box (Tassa, Mansard, Todorov 2014 compare the two).
/// Either way every rollout projects its inputs onto the box, so every iterate, and the
/// returned plan, is within the limits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ControlLimits {
    /// The backward pass solves the box-constrained QP of each knot whose Newton step leaves
    /// the box ([`BoxQp`], projected Newton); the gain rows of the clamped inputs are zero
    /// (Tassa 2014's "box-DDP", Crocoddyl's `SolverBoxDDP`). On a convex problem it reaches
    /// the constrained optimum (tests/slq.rs).
    BoxQp,
    /// The backward pass takes the unconstrained Newton step and full gains; the rollouts
    /// project `u_n + alpha l + K dx` onto the box (Tassa 2014's "clamping"). On the
    /// whole-body tasks it is the one that works: with the box QP, squat_jump's cost falls
    /// 1.99e4 -> 1.53e4 in 40 iterations (accepted steps 0.002-0.008), projected it
    /// converges in 26 to 24.6 (docs/experiments/feasible-slq.md). The whole-body `H` is
    /// nearly singular (`l_uu` = 4e-7 against `B^T P B`): the box QP's exact answer to that
    /// model drives most inputs of a knot to their bounds and zeroes their feedback, a
    /// worse step than the clipped Newton step along which the line search searches.
    ProjectedRollout,
}

impl Default for SlqSettings {
    fn default() -> Self {
        Self {
            max_iterations: 40,
            feedforward_tolerance: 1e-4,
            relative_cost_tolerance: 1e-6,
            normalized_cost_tolerance: 1e-3,
            stall_window: 5,
            alpha_divisor: 2.0,
            max_line_search_steps: 12,
            initial_regularization: 1e-8,
            min_regularization: 1e-10,
            max_regularization: 1e10,
            convergence_regularization: 1e-6,
            short_step: 0.0,
            short_step_regularization_growth: 10.0,
            threads: 0,
            realtime_priority: None,
            overlap_backward_pass: true,
            control_limits: ControlLimits::ProjectedRollout,
            box_qp: BoxQpSettings::default(),
            record_value_function: false,
            model_reuse: None,
        }
    }
}

/// Why the solver stopped.
#[derive(Clone, Debug, PartialEq)]
pub enum Termination {
    /// `||l|| < l_t`.
    Converged,
    /// The cost changed by less than the relative tolerance.
    CostStalled,
    /// The normalized cost (over the initial cost) fell by less than its tolerance over the
    /// stall window.
    NormalizedCostFlat,
    MaxIterations,
    /// No step size decreased the cost (iteration number).
    LineSearchFailed { iteration: usize },
    /// `H` stayed indefinite up to the maximum regularization (iteration number).
    BackwardPassFailed { iteration: usize },
}

/// The normalized-cost stopping test: with `costs` the cost after each iteration so far
/// (a rejected step repeats the cost before it), true when the last `window` iterations
/// lowered the cost by less than `tolerance` times the initial cost `initial`.
///
/// ```
/// use legwork::slq::normalized_cost_flat;
/// // 100 -> 10 in three iterations, then 0.01 % of the initial cost per iteration.
/// let costs = [40.0, 15.0, 10.0, 9.99, 9.98, 9.97, 9.96, 9.95];
/// assert!(!normalized_cost_flat(100.0, costs[..6].iter().copied(), 5, 1e-3));
/// assert!(normalized_cost_flat(100.0, costs.iter().copied(), 5, 1e-3));
/// ```
pub fn normalized_cost_flat(initial: f64, costs: impl ExactSizeIterator<Item = f64> + Clone, window: usize, tolerance: f64) -> bool {
    let n = costs.len();
    if tolerance <= 0.0 || window == 0 || n < window {
        return false;
    }
    let before = if n == window { initial } else { costs.clone().nth(n - window - 1).unwrap_or(initial) };
    let last = costs.last().unwrap_or(initial);
    before - last < tolerance * initial.abs()
}

/// Seconds spent in each part of one iteration.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct IterationTiming {
    pub rollout: f64,
    pub linearization: f64,
    pub backward_pass: f64,
    pub line_search: f64,
}

/// One iteration's record.
#[derive(Clone, Debug, PartialEq)]
pub struct IterationLog {
    pub iteration: usize,
    /// Cost after the iteration.
    pub cost: f64,
    /// Accepted step size (0 when the line search failed).
    pub alpha: f64,
    /// RMS over knots of the feedforward increments `l_k`.
    pub feedforward_norm: f64,
    pub regularization: f64,
    pub timing: IterationTiming,
}

/// The solver's answer: the best trajectory found and how it got there.
#[derive(Clone, Debug)]
pub struct SlqSolution<S> {
    /// States `x_0 .. x_N`.
    pub states: Vec<S>,
    /// Inputs `u_0 .. u_{N-1}`.
    pub inputs: Vec<DVector<f64>>,
    /// Feedback gains `K_k` (`nu x nx`): `u = u_k + K_k (x (-) x_k)`.
    pub gains: Vec<DMatrix<f64>>,
    /// Cost of the initial rollout, then after each iteration.
    pub cost_history: Vec<f64>,
    pub iterations: Vec<IterationLog>,
    pub termination: Termination,
    /// Seconds for the initial rollout.
    pub initial_rollout_time: f64,
    pub total_time: f64,
    /// The local value function of the final backward pass, with
    /// [`SlqSettings::record_value_function`].
    pub value_function: Option<ValueFunction>,
}

/// The backward pass's quadratic model of the cost-to-go at every knot `k = 0 .. N`
/// (Neunert 2017, Alg. 1, step 3): `V_k(x_k (+) dx) ~ V_k + p_k^T dx + 1/2 dx^T P_k dx`,
/// `P_N = h_xx`, `p_N = h_x`. A receding-horizon window ends on it ([`crate::mpc`]): the
/// plan's own cost beyond the window.
#[derive(Clone, Debug, PartialEq)]
pub struct ValueFunction {
    pub hessians: Vec<DMatrix<f64>>,
    pub gradients: Vec<DVector<f64>>,
}

/// A problem that cannot be started.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SlqError {
    #[error("the initial rollout with the initial control law is not finite (step {step}): the initial policy does not stabilize the system")]
    InitialRolloutDiverged { step: usize },
    #[error("solver setting `{field}`: {problem}")]
    Settings { field: &'static str, problem: String },
    #[error("input bounds of knot {knot}, input {input}: expected lower <= upper (not NaN), got [{lower}, {upper}]")]
    InputBounds { knot: usize, input: usize, lower: f64, upper: f64 },
}

/// `u <- clamp(u, lower, upper)` componentwise.
#[inline]
fn project(u: &mut DVector<f64>, lower: &DVector<f64>, upper: &DVector<f64>) {
    for ((u, lo), hi) in u.iter_mut().zip(lower.iter()).zip(upper.iter()) {
        *u = u.clamp(*lo, *hi);
    }
}

/// SLQ on one problem: the trajectory, gains and scratch, allocated once.
pub struct Slq<'p, P: Problem> {
    problem: &'p P,
    settings: SlqSettings,
    states: Vec<P::State>,
    inputs: Vec<DVector<f64>>,
    /// One trial trajectory per thread: the line search rolls out that many step sizes at once.
    trials: Vec<Trial<P::State>>,
    gains: Vec<DMatrix<f64>>,
    feedforward: Vec<DVector<f64>>,
    /// One local model per knot, each behind its own lock: in the overlapped pass
    /// ([`SlqSettings::overlap_backward_pass`]) helper threads write knots while the backward
    /// pass reads later ones (uncontended: a knot is read only once it is marked ready).
    derivatives: Vec<Mutex<KnotModel>>,
    /// Which knots the overlapped pass has linearized.
    ready: Vec<AtomicBool>,
    /// Where each knot's model was taken, with [`SlqSettings::model_reuse`] (empty without).
    points: Vec<Mutex<ModelPoint<P::State>>>,
    /// Which knots the next pass keeps the model of ([`ModelReuse`]; all false outside
    /// [`Slq::real_time_iteration`]).
    reused: Vec<bool>,
    /// Real-time iterations so far and knots shifted out of the window so far (the refresh
    /// turn of [`ModelReuse`] is by absolute knot).
    reuse_iterations: usize,
    shifted_knots: usize,
    workspaces: Vec<P::Workspace>,
    scratch_states: Vec<P::State>,
    terminal_gradient: DVector<f64>,
    terminal_hessian: DMatrix<f64>,
    riccati: RiccatiScratch,
    regularization: f64,
    /// The solver's threads; `None` with one thread: the work runs on the calling thread
    /// (exploration runs one-thread solvers side by side on its own pool, and a pool per
    /// start would give every start a new thread, and the allocator a new arena).
    pool: Option<rayon::ThreadPool>,
    /// The input box of every knot ([`Problem::input_bounds`]), and whether it has a finite side.
    lower: Vec<DVector<f64>>,
    upper: Vec<DVector<f64>>,
    bounded: Vec<bool>,
    qp: BoxQp,
    /// `P_k`, `p_k` of every knot, filled by a pass with `recording` on (empty without
    /// [`SlqSettings::record_value_function`]).
    value: Option<ValueFunction>,
    recording: bool,
    /// The real-time iterations' step size, adapted tick to tick ([`Slq::real_time_iteration`]).
    real_time_step: f64,
    /// The knots of the window the solution was made for: a receding window may end at its
    /// task's end and lose knots as it moves on ([`Problem::horizon`]; the buffers keep the
    /// first window's length).
    window_knots: usize,
    /// The next real-time iteration's model and backward pass, run ahead of its measurement
    /// ([`Slq::prepare_real_time_iteration`]): whether the pass succeeded, and its timing.
    prepared: Option<(bool, IterationTiming)>,
}

/// Where a knot's model was taken ([`ModelReuse`]), and scratch to move it.
struct ModelPoint<S> {
    x: S,
    u: DVector<f64>,
    /// False until the knot is linearized (and for knots new to the window).
    valid: bool,
    dx: DVector<f64>,
    du: DVector<f64>,
}

impl<S: Clone> ModelPoint<S> {
    fn new(x: S, nx: usize, nu: usize) -> Self {
        Self { x, u: DVector::zeros(nu), valid: false, dx: DVector::zeros(nx), du: DVector::zeros(nu) }
    }

    /// The knot's quadratic cost model centred at `(x, u)` instead of where it was taken
    /// (the gradient update of [`ModelReuse`]); `(x, u)` becomes its point.
    fn recenter<P: Problem<State = S>>(&mut self, problem: &P, x: &S, u: &DVector<f64>, d: &mut KnotDerivatives) {
        problem.difference(&self.x, x, &mut self.dx);
        self.du.copy_from(u);
        self.du -= &self.u;
        // l_x += l_xx dx + l_ux^T du;  l_u += l_ux dx + l_uu du
        d.l_x.gemv(1.0, &d.l_xx, &self.dx, 1.0);
        d.l_x.gemv_tr(1.0, &d.l_ux, &self.du, 1.0);
        d.l_u.gemv(1.0, &d.l_ux, &self.dx, 1.0);
        d.l_u.gemv(1.0, &d.l_uu, &self.du, 1.0);
        self.x.clone_from(x);
        self.u.copy_from(u);
    }
}

/// Knot `k`'s model at `(x, u)`: linearized anew, or with `reuse` the one it has, moved to
/// `(x, u)` ([`ModelReuse`]) if `(x, u)` is in the same piece of the model
/// ([`Problem::same_model_piece`]). `point` is where the model was taken (`None` without
/// reuse).
#[allow(clippy::too_many_arguments)]
fn knot_model<P: Problem>(problem: &P, ws: &mut P::Workspace, k: usize, x: &P::State, u: &DVector<f64>, scratch: &mut P::State, model: &mut KnotModel, point: Option<&Mutex<ModelPoint<P::State>>>, reuse: bool) {
    let Some(point) = point else {
        model.linearize(problem, ws, k, x, u, scratch);
        return;
    };
    let mut point = point.lock().unwrap_or_else(PoisonError::into_inner);
    if reuse && problem.same_model_piece(&point.x, x) {
        // A and B are kept: so is their pass-through count.
        point.recenter(problem, x, u, &mut model.d);
    } else {
        model.linearize(problem, ws, k, x, u, scratch);
        point.x.clone_from(x);
        point.u.copy_from(u);
        point.valid = true;
    }
}

/// A knot's local model, and what the backward pass reads off it: counted where the model
/// is taken (on the linearization's threads), not in the pass, which runs on one thread.
struct KnotModel {
    d: KnotDerivatives,
    /// [`pass_through_rows`] of `[A B]`.
    pass_through: usize,
}

impl KnotModel {
    fn linearize<P: Problem>(&mut self, problem: &P, ws: &mut P::Workspace, k: usize, x: &P::State, u: &DVector<f64>, scratch: &mut P::State) {
        problem.linearize_knot(ws, k, x, u, scratch, &mut self.d);
        self.pass_through = pass_through_rows(&self.d.a, &self.d.b);
    }
}

/// A line-search rollout: its trajectory, scratch and outcome.
struct Trial<S> {
    states: Vec<S>,
    inputs: Vec<DVector<f64>>,
    dx: DVector<f64>,
    /// The trial's cost, `None` if the rollout left the valid states or went non-finite.
    cost: Option<f64>,
    /// The first knot whose step left the valid states (`None`: the trial completed).
    failed_at: Option<usize>,
}

/// `alpha / alpha_d^times` by repeated division: bit for bit the step sizes of a line
/// search that tries them one at a time.
fn divided(alpha: f64, divisor: f64, times: usize) -> f64 {
    (0..times).fold(alpha, |a, _| a / divisor)
}

/// `f` on every job: on `pool`'s threads, or one after another on this thread without one.
fn for_each_job<I, F>(pool: Option<&rayon::ThreadPool>, jobs: I, f: F)
where
    I: Iterator + Send,
    I::Item: Send,
    F: Fn(I::Item) + Sync + Send,
{
    match pool {
        Some(pool) => pool.install(|| jobs.par_bridge().for_each(f)),
        None => jobs.for_each(f),
    }
}

/// The input box `lower_k <= u_k <= upper_k` of every knot ([`Problem::input_bounds`]).
#[derive(Clone, Copy)]
pub struct InputBox<'b> {
    pub lower: &'b [DVector<f64>],
    pub upper: &'b [DVector<f64>],
}

/// The input boxes of `problem`'s knots, from [`Problem::input_bounds`].
pub fn input_boxes<P: Problem>(problem: &P) -> (Vec<DVector<f64>>, Vec<DVector<f64>>) {
    let (n, nu) = (problem.horizon(), problem.nu());
    let (mut lower, mut upper) = (vec![DVector::zeros(nu); n], vec![DVector::zeros(nu); n]);
    for k in 0..n {
        problem.input_bounds(k, &mut lower[k], &mut upper[k]);
    }
    (lower, upper)
}

/// Rolls `policy` out from `states[0]` (Algorithm 1's forward simulation): each input
/// projected onto its knot's box, into `inputs[k]`, each state into `states[k + 1]`.
/// Returns `h(x_N) + sum_k l_k`, or `Err(k)` at the first step whose state is not valid
/// or whose cost is not finite. `states` has `N + 1` entries, `inputs` `N`.
pub fn rollout<P: Problem>(problem: &P, ws: &mut P::Workspace, policy: &dyn Policy<P>, bounds: InputBox<'_>, states: &mut [P::State], inputs: &mut [DVector<f64>]) -> Result<f64, usize> {
    let mut cost = 0.0;
    for k in 0..problem.horizon() {
        policy.control(problem, k, &states[k], &mut inputs[k]);
        project(&mut inputs[k], &bounds.lower[k], &bounds.upper[k]);
        let (head, tail) = states.split_at_mut(k + 1);
        cost += problem.step(ws, k, &head[k], &inputs[k], &mut tail[0]);
        if !problem.is_valid(&tail[0]) || !cost.is_finite() {
            return Err(k);
        }
    }
    Ok(cost + problem.terminal_cost(ws, &states[problem.horizon()]))
}

/// Sets its flag if dropped while its thread panics.
struct FlagOnPanic<'a>(&'a AtomicBool);

impl Drop for FlagOnPanic<'_> {
    fn drop(&mut self) {
        if std::thread::panicking() {
            self.0.store(true, Ordering::Release);
        }
    }
}

/// The local model of a knot behind its lock, when the lock is not needed (`&mut` access).
fn knot_mut(d: &mut Mutex<KnotModel>) -> &mut KnotModel {
    d.get_mut().unwrap_or_else(PoisonError::into_inner)
}

/// How many of the last rows of `[A B]` pass their own coordinate through: row `i`'s only
/// nonzero entry is `A_ii` (a contact anchor that a step holds, `1`, or forgets, `0`).
/// [`riccati_knot`] skips them in its products.
fn pass_through_rows(a: &DMatrix<f64>, b: &DMatrix<f64>) -> usize {
    // Column by column (contiguous), from the bottom: the last nonzero off the diagonal
    // ends the candidate block below it.
    let nx = a.nrows();
    let mut start = 0;
    for (j, column) in a.as_slice().chunks_exact(nx).chain(b.as_slice().chunks_exact(nx)).enumerate() {
        if let Some(i) = (start..nx).rev().find(|&i| i != j && column[i] != 0.0) {
            start = i + 1;
        }
    }
    nx - start
}

/// The quadratic model of the Q-function from `P'` in `r.p_mat` (first half of
/// [`riccati_knot`]): `Q_xx`, `H = Q_uu`, `G = Q_ux` into `r`, with the last `nx - nz` rows
/// of `[A B]` passing their coordinate through ([`pass_through_rows`]).
fn q_function_hessian(r: &mut RiccatiScratch, d: &KnotDerivatives, nz: usize) {
    // Q_xx = l_xx + A^T P' A;  H = l_uu + B^T P' B;  G = l_ux + B^T P' A, from M = P' [A B],
    // each block as `l + [A B]^T M` (the unused A^T P'B, G^T's round-off twin, is not
    // formed). Through matrixmultiply (every dimension above nalgebra's small-matrix
    // threshold of 5, as on the robots) every entry is the same fused dot product over the
    // rows of M, in the same order, then rounded once with `l` added, as when
    // [A B]^T P' [A B] was formed first and `l` added after: the same to the bit. (`A^T`
    // is copied: nalgebra's own small-matrix path mishandles a transposed strided view.)
    //
    // The last `nt` rows of [A B] may pass their coordinate through ([`pass_through_rows`]:
    // a held contact anchor, a forgotten one), [A B] = [[A_zz A_zt B_z]; [0 D 0]] with `D`
    // diagonal. Then every product runs over the `nz = nx - nt` other rows only and `D`
    // enters as a scaling (at HyQ's 48 states with four anchors held, 36 rows: 0.78x the
    // multiplications of the pass). The products skip exact zeros and add `D`'s single term
    // where the dense sum would, so for `D` of zeros and ones the result is the dense one to
    // the bit.
    let (nx, nu) = (d.a.nrows(), d.b.ncols());
    d.a.rows(0, nz).transpose_to(&mut r.ab_t.view_mut((0, 0), (nx, nz)));
    d.b.rows(0, nz).transpose_to(&mut r.ab_t.view_mut((nx, 0), (nu, nz)));
    let (a_t, b_t) = (r.ab_t.view((0, 0), (nx, nz)), r.ab_t.view((nx, 0), (nu, nz)));
    // M = P' [A B] = P'_{:z} [A B]_z, then + P'_{:t} D on the pass-through columns.
    let p_z = r.p_mat.columns(0, nz);
    gemm(r.p_ab.columns_mut(0, nx), 1.0, p_z, d.a.rows(0, nz), 0.0);
    gemm(r.p_ab.columns_mut(nx, nu), 1.0, p_z, d.b.rows(0, nz), 0.0);
    let (p_ab, p_mat) = (r.p_ab.as_mut_slice(), r.p_mat.as_slice());
    for j in nz..nx {
        let d_jj = d.a[(j, j)];
        for (m, p) in p_ab[j * nx..(j + 1) * nx].iter_mut().zip(&p_mat[j * nx..(j + 1) * nx]) {
            *m += p * d_jj;
        }
    }
    let m_z = r.p_ab.rows(0, nz);
    // Q_xx = l_xx + A^T M = l_xx + (A_{z:}^T M_z + [0; D M_t]): `l` added last, as the dense
    // product adds it (one product over all rows: nalgebra multiplies fewer than six rows
    // in its own order).
    gemm(&mut r.q_xx, 1.0, a_t, m_z.columns(0, nx), 0.0);
    // Column by column (contiguous): each entry gets the same two additions in the same order.
    let (q_xx, p_ab, l_xx) = (r.q_xx.as_mut_slice(), r.p_ab.as_slice(), d.l_xx.as_slice());
    for ((q, m), l) in q_xx.chunks_exact_mut(nx).zip(p_ab.chunks_exact(nx)).zip(l_xx.chunks_exact(nx)) {
        for i in nz..nx {
            q[i] += d.a[(i, i)] * m[i];
        }
        for (q, l) in q.iter_mut().zip(l) {
            *q += l;
        }
    }
    r.q_uu.copy_from(&d.l_uu);
    gemm(&mut r.q_uu, 1.0, b_t, m_z.columns(nx, nu), 1.0);
    r.q_ux.copy_from(&d.l_ux);
    gemm(&mut r.q_ux, 1.0, b_t, m_z.columns(0, nx), 1.0);
}

/// One knot of the backward pass (Step 3 of Algorithm 1), from `P'`, `p'` in `r.p_mat`,
/// `r.p_vec` to this knot's `P`, `p` there:
///
/// ```text
/// H = l_uu + B^T P' B,  G = l_ux + B^T P' A,  g = l_u + B^T p'
/// K = -H^-1 G,  l = -H^-1 g
/// P = l_xx + A^T P' A + K^T H K + K^T G + G^T K
/// p = l_x + A^T p' + K^T H l + K^T g + G^T l
/// ```
///
/// with `H` regularized to `H + mu I`; the gain and feedforward into `gain`, `ff`. False if
/// `H + mu I` is not positive definite (the pass restarts with more regularization).
#[allow(clippy::too_many_arguments)]
fn riccati_knot(
    r: &mut RiccatiScratch,
    qp: &mut BoxQp,
    control_limits: ControlLimits,
    regularization: f64,
    model: &KnotModel,
    u: &DVector<f64>,
    (lower, upper, bounded): (&DVector<f64>, &DVector<f64>, bool),
    gain: &mut DMatrix<f64>,
    ff: &mut DVector<f64>,
) -> bool {
    let d = &model.d;
    let nx = d.a.nrows();
    q_function_hessian(r, d, nx - model.pass_through);
    // Q_x = l_x + A^T p';  g = l_u + B^T p'
    r.q_x.copy_from(&d.l_x);
    r.q_x.gemv_tr(1.0, &d.a, &r.p_vec, 1.0);
    r.q_u.copy_from(&d.l_u);
    r.q_u.gemv_tr(1.0, &d.b, &r.p_vec, 1.0);
    // Regularized factorization of H.
    for i in 0..r.q_uu.nrows() {
        r.q_uu[(i, i)] += regularization;
    }
    if !r.chol.factor(&r.q_uu) {
        return false;
    }
    // K = -H^-1 G, l = -H^-1 g
    r.warm.copy_from(ff);
    ff.copy_from(&r.q_u);
    r.chol.solve_vector_in_place(ff);
    ff.neg_mut();
    // Control limits (Tassa 2014, sec. III-B): if the Newton step leaves the
    // box, l is the box-QP solution from the last step at this knot, and K has
    // the free rows -H_ff^-1 G_f and zero rows for the clamped inputs (eq. 16).
    let inside = control_limits == ControlLimits::ProjectedRollout || !bounded || (0..u.len()).all(|i| (lower[i]..=upper[i]).contains(&(u[i] + ff[i])));
    if inside {
        gain.copy_from(&r.q_ux);
        r.chol.solve_in_place(gain);
        gain.neg_mut();
    } else {

        r.du_lower.copy_from(lower);
        r.du_lower -= u;
        r.du_upper.copy_from(upper);
        r.du_upper -= u;
        let status = qp.solve(&r.q_uu, &r.q_u, &r.du_lower, &r.du_upper, &r.warm);
        if status == BoxQpStatus::NotPositiveDefinite {
            return false;
        }
        ff.copy_from(&qp.x);
        gain.copy_from(&r.q_ux);
        for (i, &clamped) in qp.clamped.iter().enumerate() {
            if clamped {
                gain.row_mut(i).fill(0.0);
            }
        }
        qp.free_factor.solve_in_place(gain);
        gain.neg_mut();
    }
    // P = Q_xx + K^T H K + K^T G + G^T K and p = Q_x + K^T H l + K^T g + G^T l.
    // With K = -H^-1 G from this same (regularized) H, or its free rows
    // -H_ff^-1 G_f and zero clamped rows, K^T H K = -K^T G, so P = Q_xx + G^T K;
    // and p = Q_x + G^T l + K^T (H l + g), the last term zero for the Newton step
    // (and on the free rows of a box-QP solution, up to its tolerance).
    // G^T K as a plain product of G^T (one small transpose): `gemm_tr` forms it
    // from 48 x 48 scalar dot products, a quarter of this pass's time in `perf`
    // (the pass: 36.7 -> 28 ms per 1500 knots, BENCHMARKS.md). Q_xx is not needed after
    // this: the product adds onto it, which then becomes P (its buffer traded with P').
    r.q_ux.transpose_to(&mut r.q_ux_t);
    gemm(&mut r.q_xx, 1.0, &r.q_ux_t, &*gain, 1.0);
    std::mem::swap(&mut r.p_mat, &mut r.q_xx);
    r.p_vec.copy_from(&r.q_x);
    r.p_vec.gemv_tr(1.0, &r.q_ux, ff, 1.0);
    if !inside {
        r.qp_residual.copy_from(&r.q_u);
        r.qp_residual.gemv(1.0, &r.q_uu, ff, 1.0);
        r.p_vec.gemv_tr(1.0, gain, &r.qp_residual, 1.0);
    }
    // Keep P symmetric against round-off: P_ij = P_ji = (P_ij + P_ji) / 2 (column-major).
    let p = r.p_mat.as_mut_slice();
    for j in 0..nx {
        for i in 0..j {
            let s = 0.5 * (p[i + j * nx] + p[j + i * nx]);
            p[i + j * nx] = s;
            p[j + i * nx] = s;
        }
    }
    true
}

/// Scratch of the backward pass.
struct RiccatiScratch {
    p_mat: DMatrix<f64>,
    p_vec: DVector<f64>,
    /// `[A B]^T` (its first `nz` columns, [`q_function_hessian`]) and `P' [A B]`.
    ab_t: DMatrix<f64>,
    p_ab: DMatrix<f64>,
    q_xx: DMatrix<f64>,
    q_uu: DMatrix<f64>,
    q_ux: DMatrix<f64>,
    q_ux_t: DMatrix<f64>,
    q_x: DVector<f64>,
    q_u: DVector<f64>,
    chol: SmallCholesky,
    /// The box of the step, `lower - u_k <= du <= upper - u_k`, the QP's warm start (the last
    /// step at the knot) and `H l + g`.
    du_lower: DVector<f64>,
    du_upper: DVector<f64>,
    warm: DVector<f64>,
    qp_residual: DVector<f64>,
}

impl RiccatiScratch {
    fn new(nx: usize, nu: usize) -> Self {
        Self {
            p_mat: DMatrix::zeros(nx, nx),
            p_vec: DVector::zeros(nx),
            ab_t: DMatrix::zeros(nx + nu, nx),
            p_ab: DMatrix::zeros(nx, nx + nu),
            q_xx: DMatrix::zeros(nx, nx),
            q_uu: DMatrix::zeros(nu, nu),
            q_ux: DMatrix::zeros(nu, nx),
            q_ux_t: DMatrix::zeros(nx, nu),
            q_x: DVector::zeros(nx),
            q_u: DVector::zeros(nu),
            chol: SmallCholesky::new(nu),
            du_lower: DVector::zeros(nu),
            du_upper: DVector::zeros(nu),
            warm: DVector::zeros(nu),
            qp_residual: DVector::zeros(nu),
        }
    }
}

impl<'p, P: Problem> Slq<'p, P> {
    /// Sets up the solver: trajectories, gains and workspaces allocated once.
    pub fn new(problem: &'p P, settings: SlqSettings) -> Result<Self, SlqError> {
        if settings.alpha_divisor.is_nan() || settings.alpha_divisor <= 1.0 {
            return Err(SlqError::Settings { field: "alpha_divisor", problem: format!("expected a number > 1, got {}", settings.alpha_divisor) });
        }
        if !((0.0..=1.0).contains(&settings.short_step) && settings.short_step_regularization_growth >= 1.0 && settings.short_step_regularization_growth.is_finite()) {
            return Err(SlqError::Settings { field: "short_step", problem: format!("expected a step in [0, 1] and a finite growth >= 1, got {} and {}", settings.short_step, settings.short_step_regularization_growth) });
        }
        let (nx, nu, n) = (problem.nx(), problem.nu(), problem.horizon());
        if n == 0 {
            return Err(SlqError::Settings { field: "horizon", problem: "the problem has no knots".into() });
        }
        let threads = if settings.threads == 0 { rayon::current_num_threads() } else { settings.threads };
        let pool = if threads == 1 && settings.realtime_priority.is_none() {
            None
        } else {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().map_err(|e| SlqError::Settings { field: "threads", problem: e.to_string() })?;
            if let Some(priority) = settings.realtime_priority {
                let refused = pool.broadcast(|_| set_realtime_priority(priority)).into_iter().find_map(Result::err);
                if let Some(e) = refused {
                    return Err(SlqError::Settings { field: "realtime_priority", problem: e.to_string() });
                }
            }
            Some(pool)
        };
        let x0 = problem.initial_state();
        let (lower, upper) = input_boxes(problem);
        for k in 0..n {
            for i in 0..nu {
                let (lo, hi) = (lower[k][i], upper[k][i]);
                if lo.is_nan() || hi.is_nan() || lo > hi {
                    return Err(SlqError::InputBounds { knot: k, input: i, lower: lo, upper: hi });
                }
            }
        }
        let bounded = (0..n).map(|k| lower[k].iter().chain(upper[k].iter()).any(|b| b.is_finite())).collect();
        let mut slq = Self {
            problem,
            states: vec![x0.clone(); n + 1],
            inputs: vec![DVector::zeros(nu); n],
            trials: (0..threads).map(|_| Trial { states: vec![x0.clone(); n + 1], inputs: vec![DVector::zeros(nu); n], dx: DVector::zeros(nx), cost: None, failed_at: None }).collect(),
            gains: vec![DMatrix::zeros(nu, nx); n],
            feedforward: vec![DVector::zeros(nu); n],
            derivatives: (0..n).map(|_| Mutex::new(KnotModel { d: KnotDerivatives::zeros(nx, nu), pass_through: 0 })).collect(),
            ready: (0..n).map(|_| AtomicBool::new(false)).collect(),
            // Checked and allocated by set_model_reuse below.
            points: Vec::new(),
            reused: vec![false; n],
            reuse_iterations: 0,
            shifted_knots: 0,
            workspaces: (0..threads).map(|_| problem.workspace()).collect(),
            scratch_states: vec![x0; threads],
            terminal_gradient: DVector::zeros(nx),
            terminal_hessian: DMatrix::zeros(nx, nx),
            riccati: RiccatiScratch::new(nx, nu),
            lower,
            upper,
            bounded,
            qp: BoxQp::new(nu, settings.box_qp),
            value: settings.record_value_function.then(|| ValueFunction { hessians: vec![DMatrix::zeros(nx, nx); n + 1], gradients: vec![DVector::zeros(nx); n + 1] }),
            recording: false,
            real_time_step: 1.0,
            window_knots: n,
            prepared: None,
            regularization: settings.initial_regularization,
            settings,
            pool,
        };
        slq.set_model_reuse(slq.settings.model_reuse)?;
        Ok(slq)
    }

    /// Step 1 (first iteration): `x_{k+1} = f(x_k, pi_k(x_k))` with the initial policy.
    fn rollout(&mut self, policy: &dyn Policy<P>) -> Result<f64, SlqError> {
        let bounds = InputBox { lower: &self.lower, upper: &self.upper };
        rollout(self.problem, &mut self.workspaces[0], policy, bounds, &mut self.states, &mut self.inputs).map_err(|step| SlqError::InitialRolloutDiverged { step })
    }

    /// Step 2: linearize the dynamics and quadratize the cost at every knot, in parallel.
    fn linearize(&mut self) {
        let problem = self.problem;
        let n = problem.horizon();
        let threads = self.workspaces.len();
        let chunk = n.div_ceil(threads);
        let (states, inputs, points, reused) = (&self.states, &self.inputs, &self.points, &self.reused);
        let jobs = self.derivatives[..n].chunks_mut(chunk).zip(self.workspaces.iter_mut().zip(self.scratch_states.iter_mut())).enumerate();
        for_each_job(self.pool.as_ref(), jobs, |(c, (derivs, (ws, scratch)))| {
            for (i, d) in derivs.iter_mut().enumerate() {
                let k = c * chunk + i;
                knot_model(problem, ws, k, &states[k], &inputs[k], scratch, knot_mut(d), points.get(k), reused[k]);
            }
        });
        let ws = &mut self.workspaces[0];
        problem.terminal_cost_derivatives(ws, &self.states[n], &mut self.terminal_gradient, &mut self.terminal_hessian);
    }

    /// Steps 2 and 3 of an iteration at a new trajectory: [`Self::linearize`] then
    /// [`Self::backward_pass`], or, with two or more threads and
    /// [`SlqSettings::overlap_backward_pass`], both at once: the knots are claimed from the
    /// last one down by every thread, and this thread runs the pass over each knot as soon
    /// as it is linearized, linearizing the next unclaimed knot itself while it waits. Each
    /// knot's model and each step of the pass are computed as in the two separate steps (the
    /// same iterates to the bit); the pass no longer waits for the slowest chunk of the
    /// linearization, and the other threads linearize while it runs. Records the time of
    /// each (overlapped: the pass's own per-knot time, the rest as linearization).
    fn linearize_and_backward_pass(&mut self, timing: &mut IterationTiming) -> bool {
        let started = Instant::now();
        if self.pool.is_none() || self.workspaces.len() < 2 || !self.settings.overlap_backward_pass || self.regularization > self.settings.max_regularization {
            self.linearize();
            timing.linearization = started.elapsed().as_secs_f64();
            let t = Instant::now();
            let ok = self.backward_pass();
            timing.backward_pass = t.elapsed().as_secs_f64();
            return ok;
        }
        let Self { problem, settings, states, inputs, gains, feedforward, derivatives, ready, points, reused, workspaces, scratch_states, terminal_gradient, terminal_hessian, riccati: r, regularization, pool, lower, upper, bounded, qp, value, recording, .. } = self;
        let (problem, n) = (*problem, problem.horizon());
        problem.terminal_cost_derivatives(&mut workspaces[0], &states[n], terminal_gradient, terminal_hessian);
        for flag in ready.iter() {
            flag.store(false, Ordering::Relaxed);
        }
        let (states, inputs, derivatives, ready, points, reused) = (&*states, &*inputs, &*derivatives, &*ready, &*points, &*reused);
        // The next knot to linearize (counting down; negative when all are claimed), and
        // whether a thread panicked in a knot (which then never becomes ready: the pass
        // panics too instead of waiting for it).
        let next = AtomicIsize::new(n as isize - 1);
        let abandoned = AtomicBool::new(false);
        let claim_and_linearize = |ws: &mut P::Workspace, scratch: &mut P::State| -> bool {
            let Ok(k) = usize::try_from(next.fetch_sub(1, Ordering::Relaxed)) else { return false };
            let _flag = FlagOnPanic(&abandoned);
            let mut d = derivatives[k].lock().unwrap_or_else(PoisonError::into_inner);
            knot_model(problem, ws, k, &states[k], &inputs[k], scratch, &mut d, points.get(k), reused[k]);
            drop(d);
            ready[k].store(true, Ordering::Release);
            true
        };
        let claim = &claim_and_linearize;
        let (own_workspace, helper_workspaces) = workspaces.split_at_mut(1);
        let (own_scratch, helper_scratch) = scratch_states.split_at_mut(1);
        let (own_workspace, own_scratch) = (&mut own_workspace[0], &mut own_scratch[0]);
        let mut backward_time = 0.0;
        let mut ok = true;
        let mut overlapped = || {
            rayon::scope(|s| {
                for (ws, scratch) in helper_workspaces.iter_mut().zip(helper_scratch.iter_mut()) {
                    s.spawn(move |_| while claim(ws, scratch) {});
                }
                r.p_mat.copy_from(terminal_hessian);
                r.p_vec.copy_from(terminal_gradient);
                for k in (0..n).rev() {
                    let mut waits = 0u32;
                    while !ready[k].load(Ordering::Acquire) {
                        assert!(!abandoned.load(Ordering::Acquire), "a thread linearizing the knots panicked");
                        // Knot k is another thread's, under way: help with the next one, or wait.
                        if !claim(own_workspace, own_scratch) {
                            waits += 1;
                            if waits < 64 {
                                std::hint::spin_loop();
                            } else {
                                std::thread::yield_now();
                            }
                        }
                    }
                    let t = Instant::now();
                    let d = derivatives[k].lock().unwrap_or_else(PoisonError::into_inner);
                    let knot_ok = riccati_knot(r, qp, settings.control_limits, *regularization, &d, &inputs[k], (&lower[k], &upper[k], bounded[k]), &mut gains[k], &mut feedforward[k]);
                    drop(d);
                    if let (true, Some(v)) = (knot_ok && *recording, value.as_mut()) {
                        v.hessians[k].copy_from(&r.p_mat);
                        v.gradients[k].copy_from(&r.p_vec);
                    }
                    backward_time += t.elapsed().as_secs_f64();
                    if !knot_ok {
                        ok = false;
                        break;
                    }
                }
                // A pass that has to restart needs every knot: finish the linearization.
                while claim(own_workspace, own_scratch) {}
            });
        };
        // Two or more threads here, so there is a pool (without, the scope would take the
        // caller's).
        match pool.as_ref() {
            Some(pool) => pool.install(overlapped),
            None => overlapped(),
        }
        timing.linearization = started.elapsed().as_secs_f64() - backward_time;
        timing.backward_pass = backward_time;
        if ok {
            return true;
        }
        // H + mu I was not positive definite at some knot: the restarts of Self::backward_pass.
        self.regularization = (self.regularization * 10.0).max(self.settings.min_regularization * 10.0);
        let t = Instant::now();
        let ok = self.backward_pass();
        timing.backward_pass += t.elapsed().as_secs_f64();
        ok
    }

    /// Step 3: the Riccati-like difference equations of Algorithm 1, backwards from
    /// `P_N = h_xx`, `p_N = h_x` (each knot: [`riccati_knot`]).
    /// `H` is regularized to `H + mu I` (mu grows tenfold and the pass restarts while a
    /// Cholesky factorization fails). Returns false if `mu` exceeds its maximum.
    fn backward_pass(&mut self) -> bool {
        let n = self.problem.horizon();
        'restart: loop {
            if self.regularization > self.settings.max_regularization {
                return false;
            }
            let r = &mut self.riccati;
            r.p_mat.copy_from(&self.terminal_hessian);
            r.p_vec.copy_from(&self.terminal_gradient);
            for k in (0..n).rev() {
                let d = knot_mut(&mut self.derivatives[k]);
                if !riccati_knot(r, &mut self.qp, self.settings.control_limits, self.regularization, d, &self.inputs[k], (&self.lower[k], &self.upper[k], self.bounded[k]), &mut self.gains[k], &mut self.feedforward[k]) {
                    self.regularization = (self.regularization * 10.0).max(self.settings.min_regularization * 10.0);
                    continue 'restart;
                }
                if let (true, Some(v)) = (self.recording, self.value.as_mut()) {
                    v.hessians[k].copy_from(&r.p_mat);
                    v.gradients[k].copy_from(&r.p_vec);
                }
            }
            return true;
        }
    }

    /// Step 4: rollouts with `u = clamp(u_n + alpha l + K (x (-) x_n))` (projected onto the
    /// input box), `alpha = 1, 1/alpha_d, ...`
    /// until the cost is below `cost`; the accepted trajectory replaces the nominal one.
    /// Returns `(alpha, new cost)`, or `None` if no trial decreased the cost.
    ///
    /// The trials are rolled out one per thread at a time (`alpha_j = alpha / alpha_d^j`,
    /// j = 0 .. threads - 1) and the largest decreasing step is taken: the same step as
    /// trying them one by one, in fewer rounds.
    fn line_search(&mut self, cost: f64) -> Option<(f64, f64)> {
        let problem = self.problem;
        let divisor = self.settings.alpha_divisor;
        let (states, inputs, feedforward, gains) = (&self.states, &self.inputs, &self.feedforward, &self.gains);
        let bounds = (&self.lower[..], &self.upper[..]);
        let mut alpha = 1.0;
        let mut remaining = self.settings.max_line_search_steps;
        while remaining > 0 {
            let round = remaining.min(self.trials.len());
            let jobs = self.trials[..round].iter_mut().zip(self.workspaces.iter_mut()).enumerate();
            for_each_job(self.pool.as_ref(), jobs, |(j, (trial, ws))| {
                let step = divided(alpha, divisor, j);
                trial.cost = Self::trial_rollout(problem, ws, states, inputs, feedforward, gains, bounds, step, trial);
            });
            for j in 0..round {
                if let Some(trial_cost) = self.trials[j].cost.filter(|&c| c < cost) {
                    std::mem::swap(&mut self.states, &mut self.trials[j].states);
                    std::mem::swap(&mut self.inputs, &mut self.trials[j].inputs);
                    return Some((divided(alpha, divisor, j), trial_cost));
                }
            }
            alpha = divided(alpha, divisor, round);
            remaining -= round;
        }
        None
    }

    /// One line-search rollout from the nominal initial state with step `alpha`: the
    /// trial's cost, or `None` if it left the valid states or its cost went non-finite.
    #[allow(clippy::too_many_arguments)]
    fn trial_rollout(
        problem: &P,
        ws: &mut P::Workspace,
        states: &[P::State],
        inputs: &[DVector<f64>],
        feedforward: &[DVector<f64>],
        gains: &[DMatrix<f64>],
        (lower, upper): (&[DVector<f64>], &[DVector<f64>]),
        alpha: f64,
        trial: &mut Trial<P::State>,
    ) -> Option<f64> {
        trial.states[0].clone_from(&states[0]);
        Self::trial_rollout_from(problem, ws, states, inputs, feedforward, gains, (lower, upper), alpha, trial)
    }

    /// [`Self::trial_rollout`] from the state already in `trial.states[0]` (a receding
    /// horizon's measured state, [`Slq::real_time_iteration`]).
    #[allow(clippy::too_many_arguments)]
    fn trial_rollout_from(
        problem: &P,
        ws: &mut P::Workspace,
        states: &[P::State],
        inputs: &[DVector<f64>],
        feedforward: &[DVector<f64>],
        gains: &[DMatrix<f64>],
        (lower, upper): (&[DVector<f64>], &[DVector<f64>]),
        alpha: f64,
        trial: &mut Trial<P::State>,
    ) -> Option<f64> {
        let n = problem.horizon();
        trial.failed_at = None;
        let mut cost = 0.0;
        for k in 0..n {
            problem.difference(&states[k], &trial.states[k], &mut trial.dx);
            let u = &mut trial.inputs[k];
            u.copy_from(&inputs[k]);
            u.axpy(alpha, &feedforward[k], 1.0);
            gemv_add(u, &gains[k], &trial.dx);
            project(u, &lower[k], &upper[k]);
            let (head, tail) = trial.states.split_at_mut(k + 1);
            cost += problem.step(ws, k, &head[k], u, &mut tail[0]);
            if !problem.is_valid(&tail[0]) || !cost.is_finite() {
                trial.failed_at = Some(k);
                return None;
            }
        }
        cost += problem.terminal_cost(ws, &trial.states[n]);
        cost.is_finite().then_some(cost)
    }

    /// RMS over knots of the feedforward increments.
    fn feedforward_norm(&self) -> f64 {
        let n = self.problem.horizon();
        let sum: f64 = self.feedforward[..n].iter().map(|l| l.norm_squared()).sum();
        (sum / n as f64).sqrt()
    }

    /// Algorithm 1. `on_iteration` sees each iteration's record as it finishes (for a
    /// progress line).
    pub fn solve(mut self, initial_policy: &dyn Policy<P>, mut on_iteration: impl FnMut(&IterationLog)) -> Result<SlqSolution<P::State>, SlqError> {
        let started = Instant::now();
        let t = Instant::now();
        let mut cost = self.rollout(initial_policy)?;
        let initial_rollout_time = t.elapsed().as_secs_f64();
        let mut cost_history = vec![cost];
        let initial_cost = cost;
        let mut iterations: Vec<IterationLog> = Vec::new();
        // Cost before the last `stall_window` iterations (accepted or not) fell by less than
        // the tolerance times the initial cost.
        let (tolerance, window) = (self.settings.normalized_cost_tolerance, self.settings.stall_window);
        let flat = |iterations: &[IterationLog]| normalized_cost_flat(initial_cost, iterations.iter().map(|log| log.cost), window, tolerance);
        let mut termination = Termination::MaxIterations;
        // After a rejected step the trajectory is unchanged: its linearization still holds,
        // only the backward pass is redone with more regularization (as Crocoddyl does).
        let mut linearized = false;
        for iteration in 1..=self.settings.max_iterations {
            let mut timing = IterationTiming::default();
            let ok = if linearized {
                let t = Instant::now();
                let ok = self.backward_pass();
                timing.backward_pass = t.elapsed().as_secs_f64();
                ok
            } else {
                linearized = true;
                self.linearize_and_backward_pass(&mut timing)
            };
            if !ok {
                termination = Termination::BackwardPassFailed { iteration };
                break;
            }
            let feedforward_norm = self.feedforward_norm();
            let small_step = feedforward_norm < self.settings.feedforward_tolerance && self.regularization <= self.settings.convergence_regularization;
            let t = Instant::now();
            let accepted = self.line_search(cost);
            timing.line_search = t.elapsed().as_secs_f64();
            let (alpha, new_cost) = accepted.unwrap_or((0.0, cost));
            let log = IterationLog { iteration, cost: new_cost, alpha, feedforward_norm, regularization: self.regularization, timing };
            on_iteration(&log);
            iterations.push(log);
            if accepted.is_none() {
                // Nothing better along this direction: more regularization next time (a
                // shorter, more gradient-like step), unless the Newton step was negligible.
                if small_step {
                    termination = Termination::Converged;
                    break;
                }
                self.regularization = (self.regularization * 100.0).max(self.settings.min_regularization * 100.0);
                if self.regularization > self.settings.max_regularization {
                    termination = Termination::LineSearchFailed { iteration };
                    break;
                }
                if flat(&iterations) {
                    termination = Termination::NormalizedCostFlat;
                    break;
                }
                continue;
            }
            linearized = false;
            let change = (cost - new_cost).abs() / cost.abs().max(1e-300);
            cost = new_cost;
            cost_history.push(cost);
            // Levenberg-Marquardt on the accepted step: a full step says the local model holds
            // (less regularization); a short one that it does not (more), so the poorly
            // determined directions of `H` shrink instead of the whole step.
            self.regularization = if alpha < self.settings.short_step {
                (self.regularization * self.settings.short_step_regularization_growth).max(self.settings.min_regularization * 10.0)
            } else {
                (self.regularization / 10.0).max(self.settings.min_regularization)
            };
            if small_step {
                termination = Termination::Converged;
                break;
            }
            if change < self.settings.relative_cost_tolerance {
                termination = Termination::CostStalled;
                break;
            }
            if flat(&iterations) {
                termination = Termination::NormalizedCostFlat;
                break;
            }
        }
        // Feedback gains for the returned trajectory (the last backward pass was made at the
        // trajectory before the last step).
        if matches!(termination, Termination::Converged | Termination::CostStalled | Termination::NormalizedCostFlat | Termination::MaxIterations) {
            self.recording = self.value.is_some();
            if linearized {
                self.backward_pass();
            } else {
                self.linearize_and_backward_pass(&mut IterationTiming::default());
            }
        }
        // The value function of that pass, ending on the terminal cost's model.
        let value_function = self.value.take().filter(|_| self.recording).map(|mut v| {
            let n = v.hessians.len() - 1;
            v.hessians[n].copy_from(&self.terminal_hessian);
            v.gradients[n].copy_from(&self.terminal_gradient);
            v
        });
        Ok(SlqSolution {
            value_function,
            states: self.states,
            inputs: self.inputs,
            gains: self.gains,
            cost_history,
            iterations,
            termination,
            initial_rollout_time,
            total_time: started.elapsed().as_secs_f64(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A knot whose last `held + forgotten` rows pass their anchor through (HyQ's shape:
    /// 36 rows of joints and base, four anchors), pseudo-random entries.
    fn anchored_knot(nx: usize, nu: usize, held: usize, forgotten: usize, seed: u64) -> KnotDerivatives {
        let mut state = seed;
        let mut next = move || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((state >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
        };
        let mut d = KnotDerivatives::zeros(nx, nu);
        let nz = nx - held - forgotten;
        d.a = DMatrix::from_fn(nx, nx, |i, j| if i < nz { next() } else if i == j && i < nz + held { 1.0 } else { 0.0 });
        d.b = DMatrix::from_fn(nx, nu, |i, _| if i < nz { next() } else { 0.0 });
        let l = DMatrix::from_fn(nx, nx, |_, _| next());
        d.l_xx = &l * l.transpose();
        d.l_ux = DMatrix::from_fn(nu, nx, |_, _| next());
        d.l_uu = DMatrix::from_fn(nu, nu, |i, j| if i == j { 2.0 } else { 0.0 });
        d
    }

    fn scratch(nx: usize, nu: usize, p_seed: f64) -> RiccatiScratch {
        let p = DMatrix::from_fn(nx, nx, |i, j| ((i * 7 + j * 3) as f64 * p_seed).sin());
        let mut r = RiccatiScratch::new(nx, nu);
        r.p_mat = &p + p.transpose();
        r
    }

    #[test]
    fn pass_through_rows_are_counted_from_the_end() {
        let d = anchored_knot(48, 12, 6, 6, 1);
        assert_eq!(pass_through_rows(&d.a, &d.b), 12);
        let mut touching = d.a.clone();
        touching[(46, 3)] = 0.5; // an anchor set where the foot lands
        assert_eq!(pass_through_rows(&touching, &d.b), 1);
        let mut coupled = d.b.clone();
        coupled[(47, 0)] = 1.0;
        assert_eq!(pass_through_rows(&d.a, &coupled), 0);
    }

    /// Skipping the pass-through rows changes no bit of `Q_xx`, `H`, `G`.
    #[test]
    fn q_function_skips_pass_through_rows_to_the_bit() {
        let (nx, nu) = (48, 12);
        for (seed, (held, forgotten)) in [(12, 0), (9, 3), (3, 9), (0, 12), (6, 0), (3, 0), (0, 3), (1, 0)].into_iter().enumerate() {
            let d = anchored_knot(nx, nu, held, forgotten, seed as u64 + 3);
            let nt = held + forgotten;
            assert_eq!(pass_through_rows(&d.a, &d.b), nt);
            let (mut dense, mut skipping) = (scratch(nx, nu, 0.37), scratch(nx, nu, 0.37));
            q_function_hessian(&mut dense, &d, nx);
            q_function_hessian(&mut skipping, &d, nx - nt);
            for (name, x, y) in [("Q_xx", &dense.q_xx, &skipping.q_xx), ("H", &dense.q_uu, &skipping.q_uu), ("G", &dense.q_ux, &skipping.q_ux)] {
                let differ = x.iter().zip(y.iter()).filter(|(a, b)| a.to_bits() != b.to_bits()).count();
                assert_eq!(differ, 0, "{name}: {differ} entries differ with {held} anchors held and {forgotten} forgotten (max {:e})", (x - y).abs().max());
            }
        }
    }
}
