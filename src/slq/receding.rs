//! SLQ as a receding-horizon controller's solver: the real-time iteration scheme (Diehl,
//! Bock, Schlöder 2005) on Neunert 2017's Algorithm 1. Between ticks the solution is kept,
//! shifted by the ticks' knots ([`Slq::shift`]); each tick runs a fixed budget of
//! iterations ([`Slq::real_time_iteration`]) from the measured state:
//!
//! ```text
//! linearize and backward pass around the shifted solution x_n, u_n   (Alg. 1, steps 2-3)
//! roll out u = clamp(u_n + alpha l + K (x (-) x_n)) from the measured x_0 for one step
//!   size per thread: the adapted step, 0 (the shifted policy), the step halved, ...;
//!   keep the cheapest                                                  (step 4)
//! ```
//!
//! Only the rollouts need the measurement: the shift, the model and the backward pass are
//! the RTI scheme's preparation phase, which a controller runs between ticks
//! ([`Slq::prepare_real_time_iteration`]), so that a measurement waits for its rollouts
//! alone (the feedback phase).
//!
//! The first iteration of a tick starts from a state the shifted trajectory did not start
//! from, so its costs are not comparable with the trajectory's: the cheapest trial is
//! taken whatever the old cost (the step is the controller's answer to the new state).
//! Later iterations of the same tick keep a trial only if it lowers the cost. With
//! [`crate::slq::ModelReuse`] most knots keep their models across ticks (they move with
//! the window in [`Slq::shift`]). Nothing here allocates: the trajectories, gains and
//! trials are the solver's own.

use super::{divided, for_each_job, IterationTiming, ModelPoint, ModelReuse, Policy, Problem, Slq, SlqError};
use std::sync::Mutex;
use nalgebra::{DMatrix, DVector};
use std::time::Instant;

/// One real-time iteration's record.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RealTimeIteration {
    /// Cost of the kept trajectory (from the measured state); infinite when the kept trial
    /// left the valid states before the window's end ([`Self::held_after`]).
    pub cost: f64,
    /// Its step size: 0 for the no-step trial (the shifted policy's own feedback), or when a
    /// later iteration of the tick kept the trajectory as it was.
    pub alpha: f64,
    /// RMS over knots of the feedforward increments `l_k`.
    pub feedforward_norm: f64,
    pub regularization: f64,
    pub timing: IterationTiming,
    /// `Some(k)`: every trial left the valid states, and the kept one (the furthest, past a
    /// quarter of the window or past the last knot its task uses,
    /// [`Problem::last_used_knot`]) did after knot `k`: its states after `k` are held at knot `k`'s
    /// and its cost is infinite. The robot runs only the window's first knots before the
    /// next tick, but a tick like this has no priced trajectory.
    pub held_after: Option<usize>,
}

/// Why a real-time iteration gave no trajectory.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum RealTimeIterationError {
    #[error("the backward pass found no positive-definite H up to the largest regularization")]
    BackwardPass,
    #[error("no step size's rollout from the measured state stayed finite")]
    NoValidTrial,
}

/// Per-knot values of a window with a coarse tail from knot `head`, moved by `m` head knots
/// ([`Slq::shift_head`]): `v_k <- v_{k+m}` in the head, the first tail value copied into the
/// head's last `m`, the tail moved up by one (its last entry left for the caller).
fn shift_into_head<T>(v: &mut [T], head: usize, m: usize, copy: impl Fn(&mut T, &T)) {
    v[..head].rotate_left(m);
    let (front, split) = v.split_at_mut(head);
    for to in &mut front[head - m..] {
        copy(to, &split[0]);
    }
    v[head..].rotate_left(1);
}

/// Per-knot values of a window whose first later knot (index `head`) is halved into the
/// head's last two knots ([`Slq::shift_halving`]): `v_k <- v_{k+1}` for `k < head`, the
/// halved knot's value in both halves, the later knots unchanged.
fn halve_into_head<T>(v: &mut [T], head: usize, copy: impl Fn(&mut T, &T)) {
    v[..=head].rotate_left(1);
    let (front, halved) = v.split_at_mut(head);
    copy(&mut halved[0], &front[head - 1]);
}

impl<'p, P: Problem> Slq<'p, P> {
    /// The problem being solved.
    pub fn problem(&self) -> &'p P {
        self.problem
    }

    /// The states `x_0 .. x_N` of the current solution (`N` the window's knots now,
    /// [`Problem::horizon`]).
    pub fn states(&self) -> &[P::State] {
        &self.states[..=self.problem.horizon()]
    }

    /// The inputs `u_0 .. u_{N-1}` of the current solution.
    pub fn inputs(&self) -> &[DVector<f64>] {
        &self.inputs[..self.problem.horizon()]
    }

    /// The feedback gains `K_k` of the last backward pass (`u = u_k + K_k (x (-) x_k)`).
    pub fn gains(&self) -> &[DMatrix<f64>] {
        &self.gains[..self.problem.horizon()]
    }

    /// Rolls `policy` out from `x0` and makes it the current solution (the warm start of
    /// the first tick); returns its cost. The gains stay those of the last pass (zero on a
    /// new solver) until [`Self::real_time_iteration`] computes them.
    pub fn start_from(&mut self, x0: &P::State, policy: &dyn Policy<P>) -> Result<f64, SlqError> {
        self.prepared = None;
        self.forget_models(0);
        self.states[0].clone_from(x0);
        self.rollout(policy)
    }

    /// Back to the initial regularization (after the trajectory was replaced: the
    /// regularization an old one needed says nothing of the new).
    pub fn reset_regularization(&mut self) {
        self.prepared = None;
        self.regularization = self.settings.initial_regularization;
        self.real_time_step = 1.0;
    }

    /// Moves the solution `knots` knots earlier (the window has moved on by as much): knot
    /// `k` takes knot `k + knots`'s state, input and gain; the last `knots` inputs come from
    /// `tail` (the gains repeat the last shifted one) and their states are rolled out with
    /// them (none, or fewer, where the window lost as many knots at its task's end). Call it after moving the problem's window, so the tail's knots are the new
    /// window's. A tail step that leaves the valid states holds the state before it;
    /// returns how many did.
    pub fn shift(&mut self, knots: usize, tail: &dyn Policy<P>) -> usize {
        // A window that ends at its task's end may have lost knots as it moved: the tail
        // to roll out is what the moved solution does not cover.
        self.prepared = None;
        let (before, n) = (self.window_knots, self.problem.horizon());
        self.window_knots = n;
        let m = knots.min(before);
        let mut held_states = 0;
        if m == 0 {
            return held_states;
        }
        self.states.rotate_left(m);
        self.inputs.rotate_left(m);
        self.gains.rotate_left(m);
        self.feedforward.rotate_left(m);
        if !self.points.is_empty() {
            self.derivatives.rotate_left(m);
            self.points.rotate_left(m);
            self.shifted_knots += m;
            self.forget_models(before - m);
        }
        // The old last state is now at before - m: the new tail starts from it.
        for k in before - m..n {
            held_states += usize::from(self.roll_out_tail_knot(k, tail));
        }
        held_states
    }

    /// A new last knot `k` after a shift: its gain the one before it (the last shifted one,
    /// repeated), no feedforward increment, its input from `tail` at `x_k` (projected on
    /// the box) and `x_{k+1}` stepped with it. A step that leaves the valid states holds
    /// `x_k` (the next iteration's trials start from the measured state, not from it);
    /// returns whether it did.
    fn roll_out_tail_knot(&mut self, k: usize, tail: &dyn Policy<P>) -> bool {
        if k > 0 {
            let (before, gains) = self.gains.split_at_mut(k);
            gains[0].copy_from(&before[k - 1]);
        }
        self.feedforward[k].fill(0.0);
        tail.control(self.problem, k, &self.states[k], &mut self.inputs[k]);
        super::project(&mut self.inputs[k], &self.lower[k], &self.upper[k]);
        let (before, next) = self.states.split_at_mut(k + 1);
        self.problem.step(&mut self.workspaces[0], k, &before[k], &self.inputs[k], &mut next[0]);
        let held = !self.problem.is_valid(&next[0]);
        if held {
            next[0].clone_from(&before[k]);
        }
        held
    }

    /// [`Self::shift`] for a window whose first `head` knots are finer than the rest, each
    /// later knot `m` head knots long and the window moved by `m` head knots (one later
    /// knot; [`crate::ocp::CoarseTail`]): head knot `k` takes head knot `k + m`'s state,
    /// input and gain; the first later knot, now in the head, becomes the head's last `m`
    /// knots with its input and gain held (its states stepped; the same trajectory when a
    /// later knot integrates the head's steps), the later knots move up by one and the last
    /// comes from `tail` as in [`Self::shift`]. Returns how many tail steps held their state.
    pub fn shift_head(&mut self, head: usize, m: usize, tail: &dyn Policy<P>) -> usize {
        self.prepared = None;
        let n = self.problem.horizon();
        if m == 0 || head < m || head >= n {
            return self.shift(m, tail);
        }
        // The split knot's model is not its parts' ([`crate::slq::ModelReuse`] keeps none).
        self.forget_models(0);
        // Head: knots m..head move to 0..head - m; the first later knot (index head)
        // fills head - m..head.
        shift_into_head(&mut self.inputs, head, m, DVector::copy_from);
        shift_into_head(&mut self.feedforward, head, m, DVector::copy_from);
        shift_into_head(&mut self.gains, head, m, DMatrix::copy_from);
        // States: x_{k+m} for k <= head - m, then the later knots' x_{j+1} from head on;
        // the split knot's inner states are stepped with its input.
        self.states[..=head].rotate_left(m);
        self.states[head..].rotate_left(1);
        for k in head - m..head - 1 {
            let (before, next) = self.states.split_at_mut(k + 1);
            self.problem.step(&mut self.workspaces[0], k, &before[k], &self.inputs[k], &mut next[0]);
        }
        // The new last knot from `tail`.
        usize::from(self.roll_out_tail_knot(n - 1, tail))
    }

    /// [`Self::shift`] by one knot for a window whose later knots are two head knots long
    /// and stay on their absolute grid ([`crate::ocp::CoarseTail`] with knots of two tick
    /// periods): on the ticks where the first later knot's start becomes the head's end, the
    /// head knots `1..head` move to `0..head - 1` and the first later knot (index `head`)
    /// becomes the head's last two knots, its input and gain held over both and its middle
    /// state stepped with it (the same trajectory: a later knot integrates the head's
    /// steps). The later knots keep their indices and times; no knot is added (the window
    /// is one head knot shorter than after a plain [`Self::shift`], which adds a later knot
    /// at the end; the two alternate and the knot count stays).
    pub fn shift_halving(&mut self, head: usize) {
        self.prepared = None;
        let n = self.problem.horizon();
        assert!(head >= 1 && head < n, "shift_halving: the head ({head} knots) must leave a later knot in a window of {n}");
        // The halved knot's model is not its halves' ([`crate::slq::ModelReuse`] keeps none).
        self.forget_models(0);
        halve_into_head(&mut self.inputs, head, DVector::copy_from);
        halve_into_head(&mut self.feedforward, head, DVector::copy_from);
        halve_into_head(&mut self.gains, head, DMatrix::copy_from);
        // x_{k+1} for k < head, then the halved knot's middle state stepped with its input.
        self.states[..=head].rotate_left(1);
        let (before, next) = self.states.split_at_mut(head);
        self.problem.step(&mut self.workspaces[0], head - 1, &before[head - 1], &self.inputs[head - 1], &mut next[0]);
    }

    /// Turns [`crate::slq::ModelReuse`] on or off for the next real-time iterations (a
    /// controller's first iterations, before the robot starts, can linearize every knot).
    /// The knots' models are kept from the first iteration after this on.
    pub fn set_model_reuse(&mut self, reuse: Option<ModelReuse>) -> Result<(), SlqError> {
        if reuse.is_some_and(|r| r.refresh_period == 0) {
            return Err(SlqError::Settings { field: "model_reuse", problem: "expected a refresh period of at least 1".into() });
        }
        if reuse.is_some() && self.points.is_empty() {
            let (nx, nu) = (self.problem.nx(), self.problem.nu());
            self.points = (0..self.problem.horizon()).map(|_| Mutex::new(ModelPoint::new(self.states[0].clone(), nx, nu))).collect();
        }
        self.prepared = None;
        self.forget_models(0);
        self.settings.model_reuse = reuse;
        Ok(())
    }

    /// Knots `from..` have no model to keep ([`crate::slq::ModelReuse`]).
    fn forget_models(&mut self, from: usize) {
        for point in self.points.iter_mut().skip(from) {
            point.get_mut().unwrap_or_else(std::sync::PoisonError::into_inner).valid = false;
        }
    }

    /// Marks the knots whose models the next pass keeps ([`crate::slq::ModelReuse`]): not
    /// the first `fresh_head`, not those without one, and not this iteration's turn of the
    /// rest (absolute knot `a`'s turn every `refresh_period` iterations).
    fn choose_reused_models(&mut self) {
        let Some(reuse) = self.settings.model_reuse else { return };
        let turn = self.reuse_iterations;
        for (k, (reused, point)) in self.reused.iter_mut().zip(self.points.iter_mut()).enumerate() {
            let valid = point.get_mut().unwrap_or_else(std::sync::PoisonError::into_inner).valid;
            *reused = valid && k >= reuse.fresh_head && (k + self.shifted_knots + turn) % reuse.refresh_period != 0;
        }
        self.reuse_iterations += 1;
    }

    /// The part of the next [`Self::real_time_iteration`] that does not need its measured
    /// state, run now (the preparation phase of Diehl, Bock, Schlöder 2005): the model
    /// around the current solution and the backward pass. A controller runs it after moving
    /// the window on to its next tick and before that tick's measurement; the iteration then
    /// only rolls out from the measurement. The iterates are the same to the bit as the
    /// iteration's own. A shift, a new start or new settings before the iteration discard it.
    pub fn prepare_real_time_iteration(&mut self) {
        self.prepared = Some(self.model_and_backward_pass());
    }

    /// Steps 2-3 of a real-time iteration: whether the pass found its gains, and the timing.
    fn model_and_backward_pass(&mut self) -> (bool, IterationTiming) {
        let mut timing = IterationTiming::default();
        self.choose_reused_models();
        let passed = self.linearize_and_backward_pass(&mut timing);
        self.reused.fill(false);
        (passed, timing)
    }

    /// Whether the next real-time iteration's model and backward pass are ready
    /// ([`Self::prepare_real_time_iteration`]).
    pub fn is_prepared(&self) -> bool {
        self.prepared.is_some()
    }

    /// One real-time iteration from the measured state `x0` (module docs): the model
    /// around the current solution (unless [`Self::prepare_real_time_iteration`] made it),
    /// then one round of trials (a step size per thread) from `x0`. With `must_improve`, a
    /// trial is kept only if it costs less than `cost` (a later iteration of the same tick,
    /// whose trajectory already starts at `x0`).
    pub fn real_time_iteration(&mut self, x0: &P::State, must_improve: Option<f64>) -> Result<RealTimeIteration, RealTimeIterationError> {
        let (passed, mut timing) = match self.prepared.take() {
            Some(prepared) => prepared,
            None => self.model_and_backward_pass(),
        };
        if !passed {
            return Err(RealTimeIterationError::BackwardPass);
        }
        let feedforward_norm = self.feedforward_norm();
        let t = Instant::now();
        let problem = self.problem;
        let divisor = self.settings.alpha_divisor;
        let (states, inputs, feedforward, gains) = (&self.states, &self.inputs, &self.feedforward, &self.gains);
        let bounds = (&self.lower[..], &self.upper[..]);
        let round = self.trials.len();
        // The step sizes of the round: the adapted step, then (with two or more threads)
        // none (the shifted policy's own feedback), then the adapted step halved, ...
        let step = self.real_time_step;
        let alpha_of = move |j: usize| match j {
            0 => step,
            1 => 0.0,
            j => divided(step, divisor, j - 1),
        };
        let jobs = self.trials.iter_mut().zip(self.workspaces.iter_mut()).enumerate();
        for_each_job(self.pool.as_ref(), jobs, |(j, (trial, ws))| {
            trial.states[0].clone_from(x0);
            trial.cost = Self::trial_rollout_from(problem, ws, states, inputs, feedforward, gains, bounds, alpha_of(j), trial);
        });
        let best = (0..round).filter_map(|j| self.trials[j].cost.map(|c| (j, c))).filter(|&(_, c)| must_improve.is_none_or(|old| c < old)).min_by(|a, b| a.1.total_cmp(&b.1));
        timing.line_search = t.elapsed().as_secs_f64();
        let (alpha, cost, held_after) = match (best, must_improve) {
            (Some((j, c)), _) => {
                std::mem::swap(&mut self.states, &mut self.trials[j].states);
                std::mem::swap(&mut self.inputs, &mut self.trials[j].inputs);
                (alpha_of(j), c, None)
            }
            (None, Some(old)) => (0.0, old, None),
            (None, None) => {
                // Every trial left the valid states (a flailing free leg past the speed
                // limit, late in the window): the robot only runs the window's first knots
                // before the next tick, so the trial that went furthest is kept if it held
                // for a quarter of the window, or up to the task's end (a window past it:
                // the robot never runs the later knots), its tail held at its last valid
                // state.
                let (n, used) = (problem.horizon(), problem.last_used_knot());
                let Some((j, k)) = (0..round).filter_map(|j| self.trials[j].failed_at.map(|k| (j, k))).max_by_key(|&(_, k)| k).filter(|&(_, k)| 4 * k >= n || k >= used) else {
                    return Err(RealTimeIterationError::NoValidTrial);
                };
                let trial = &mut self.trials[j];
                for i in k + 1..=n {
                    let (head, tail) = trial.states.split_at_mut(i);
                    tail[0].clone_from(&head[k]);
                }
                for i in k..n {
                    trial.inputs[i].copy_from(&self.inputs[i]);
                }
                std::mem::swap(&mut self.states, &mut trial.states);
                std::mem::swap(&mut self.inputs, &mut trial.inputs);
                (alpha_of(j), f64::INFINITY, Some(k))
            }
        };
        // The regularization only grows where the backward pass needs it (an H that is not
        // positive definite restarts the pass with more) and decays after every tick: a
        // half step is no reason for weaker gains, which the robot runs until the next tick.
        self.regularization = (self.regularization / 10.0).max(self.settings.min_regularization);
        // The step adapts as a trust region: the full adapted step kept doubles it (up to
        // 1), none or a shorter one kept halves it (down to 1e-3). The whole-body steps are
        // short (the gallop's plan accepts alpha ~ 0.01-0.06): full Newton steps every
        // tick drive the torques to their limits and spin free legs up.
        self.real_time_step = if alpha == step { (2.0 * step).min(1.0) } else { (step / divisor).max(1e-3) };
        Ok(RealTimeIteration { cost, alpha, feedforward_norm, regularization: self.regularization, timing, held_after })
    }
}
