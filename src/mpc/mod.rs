//! Receding-horizon SLQ (model-predictive control) through contacts: the next step Neunert
//! 2017 names (sec. VI, "apply our approach in MPC fashion"), in the real-time iteration
//! scheme (Diehl, Bock, Schlöder 2005).
//!
//! The controller re-optimizes the task's whole-body problem ([`crate::ocp`]) over a
//! short window (0.5 s) that moves with time, from the measured state, at a set rate
//! (200 Hz):
//!
//! - **window** ([`window_problem`]): the task's own costs at their absolute times (the
//!   waypoints' Gaussian windows, the final cost at the task's end), the plan's value
//!   function (`P_k`, `p_k` of its last backward pass) as the cost beyond the window's end
//!   until the window reaches the task's end (from then on the window ends there, on the
//!   final cost counted once, and shortens tick by tick to at least 0.1 s:
//!   [`MpcSettings::ends_at_task_end`]), a light tracking cost toward the plan's states and
//!   torques
//!   ([`crate::ocp::RecedingHorizon`]), the robot's own contact model and torque limits,
//!   knots spaced by the tick period (5 ms, coarser than the plan's 2 ms; each integrated
//!   in steps of the contact's stable step and linearized once, at its start), or finer
//!   ([`MpcSettings::knot_dt`]), or finer only over the window's first part
//!   ([`MpcSettings::fine_head`]), or with the part after it in knots of two tick periods
//!   ([`MpcSettings::tail_ticks`]);
//! - **warm start**: the previous tick's solution shifted by the knots the window moved
//!   ([`crate::slq::Slq::shift`]), its new last knots from the plan's own policy;
//! - **iteration budget**: a fixed number of SLQ iterations per tick (one by default,
//!   [`crate::slq::Slq::real_time_iteration`]), each linearizing every knot or, with
//!   [`MpcSettings::model_reuse`], only some, the others' models kept from earlier ticks;
//! - **policy**: between solves the robot runs the last solution's
//!   `u = u_k + K_k (x (-) x_k)` ([`MpcPolicy`], Neunert 2017 eq. 2) at the simulator's
//!   control rate.
//!
//! [`closed_loop`] runs it beside a simulator, the solver in its own thread, the measured
//! solve time deciding when its policy takes over.

pub mod closed_loop;

pub use closed_loop::{run_closed_loop, ClosedLoopRun, PolicyLatency, TickRecord};

use crate::linalg::gemv_add;
use crate::model::Model;
use crate::ocp::{fewest_substeps, physical_gain, CoarseTail, KnotLinearization, PhysicalGainWorkspace, PlanValue, RecedingHorizon, ReferenceMotion, RobotState, TaskError, TaskSpec, WholeBodyProblem};
use crate::sim::{ControlError, Controller, SimState};
use crate::slq::{ModelReuse, Policy, Problem, RealTimeIteration, RealTimeIterationError, Slq, SlqError, SlqSettings, SlqSolution};
use crate::terrain::Terrain;
use nalgebra::{DMatrix, DVector};
use std::sync::Mutex;
use std::time::Instant;

/// Weights of the window's pull toward the plan, on the deviation coordinates of
/// [`crate::ocp::StateDeviation`] (per second on the running knots; the terminal ones are
/// `terminal_seconds` times them at the window's end).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct TrackingWeights {
    /// Base position along the world's x, y and z ([1e3, 2e3, 1e3]). The sideways weight is
    /// twice the others: at 1e3 the walk forward (trot) swayed +-0.1 m sideways in MuJoCo at
    /// a ~2 s period, growing until it fell at 1.7 ms latency; at 2e3 it sways at most 0.05 m
    /// peak to peak there. Doubling x too lost the gallop at 1 ms (docs/experiments/mpc-21.md).
    pub base_position: [f64; 3],
    /// Base orientation error `log(R_ref^T R)` (1e3).
    pub base_orientation: f64,
    /// Joint angles (10).
    pub joint_position: f64,
    /// Base linear and angular velocity, base frame (10).
    pub base_velocity: f64,
    /// Joint velocities (0.1).
    pub joint_velocity: f64,
    /// The terminal weights as this many seconds of the running ones (0.5 s).
    pub terminal_seconds: f64,
    /// Joint torques' deviation from the plan's, per N m^2 and second (0.01).
    pub input: f64,
}

impl Default for TrackingWeights {
    fn default() -> Self {
        Self { base_position: [1e3, 2e3, 1e3], base_orientation: 1e3, joint_position: 10.0, base_velocity: 10.0, joint_velocity: 0.1, terminal_seconds: 0.5, input: 0.01 }
    }
}

impl TrackingWeights {
    /// Every weight times `factor` (the terminal seconds as they are).
    pub fn scaled(&self, factor: f64) -> Self {
        Self { base_position: self.base_position.map(|w| w * factor), base_orientation: self.base_orientation * factor, joint_position: self.joint_position * factor, base_velocity: self.base_velocity * factor, joint_velocity: self.joint_velocity * factor, terminal_seconds: self.terminal_seconds, input: self.input * factor }
    }

    /// The running weights as a vector over `2 nv` deviation coordinates.
    fn running(&self, nv: usize) -> DVector<f64> {
        let mut w = DVector::zeros(2 * nv);
        w.rows_mut(0, 3).copy_from_slice(&self.base_position);
        w.rows_mut(3, 3).fill(self.base_orientation);
        w.rows_mut(6, nv - 6).fill(self.joint_position);
        w.rows_mut(nv, 6).fill(self.base_velocity);
        w.rows_mut(nv + 6, nv - 6).fill(self.joint_velocity);
        w
    }
}

/// Settings of the receding-horizon controller (defaults in parentheses).
#[derive(Clone, Debug, PartialEq)]
pub struct MpcSettings {
    /// Length of the window (0.5 s, the ct team's quadruped MPC).
    pub horizon: f64,
    /// Ticks per second: a new solve from the measured state every `1 / rate` (200 Hz).
    pub rate: f64,
    /// Knot spacing of the window (`None`: the tick period, so a tick moves the window by
    /// one knot). The tick period must be a whole number of knots.
    pub knot_dt: Option<f64>,
    /// The window's first seconds in knots of `knot_dt`, the rest in knots of
    /// [`Self::tail_ticks`] tick periods, each integrated in the head's steps (`None`, the
    /// default, or a head as long as the horizon: the whole window in knots of `knot_dt`).
    /// The robot runs the head's first knots before the next tick; the coarse rest carries
    /// the cost-to-go at a fraction of the knots ([`crate::ocp::CoarseTail`]).
    pub fine_head: Option<f64>,
    /// The knots after the head in tick periods (1). With 2 (the knots the tick period's, a
    /// head of at least two of them) the knots after the head span two tick periods (ten
    /// 1 ms steps at 200 Hz: with `fine_head` 0.2 s a 0.5 s window is 40 knots of 5 ms and
    /// 30 of 10 ms instead of 100 of 5 ms), on a grid fixed in the task's time: the head
    /// alternates between `fine_head` and one knot less from tick to tick, the window's
    /// length between `horizon` and a tick period more ([`crate::ocp::CoarseTail`];
    /// docs/experiments/mpc-11.md: 0.83x the tick, trot's loop lost). With 1 and knots of
    /// the tick period, the whole window in them; with 1 and finer knots, the tail in knots
    /// of the tick period.
    pub tail_ticks: usize,
    /// Integration steps per knot of the window's head (`None`, the default: the fewest that
    /// keep the step within the robot's `contact.max_step`, as a task's plan does; a coarse
    /// tail's knots take as many steps of the same length). HyQ's 1 ms `max_step` gives one
    /// step per 1 ms knot, and a hard landing measured in MuJoCo then blows up the window's
    /// rollouts (squat_jump with 1 ms knots: 37 failed ticks at a 4 ms latency, none with two
    /// steps); four steps of 0.25 ms a knot carry the gallop through MuJoCo, one does not
    /// (docs/experiments/mpc-18.md). The rollouts take every step, and the linearization
    /// chains its one model over them ([`KnotLinearization::FirstSubstep`]): four steps make
    /// the 1 ms-knot tick 1.3-1.6x.
    pub substeps: Option<usize>,
    /// SLQ iterations per tick (1: the real-time iteration scheme).
    pub iterations_per_tick: usize,
    /// Run each tick's preparation phase ahead of its measurement (true): after a tick's
    /// policy is out, the closed loop moves the window on to the next tick and builds its
    /// model and backward pass ([`Mpc::prepare`]), which do not depend on the measured state
    /// (Diehl, Bock, Schlöder 2005); the next measurement then waits only for the rollouts
    /// from it. The same iterates to the bit; the policy comes out after the rollouts
    /// instead of the whole tick. A tick's solve time still counts both phases (they must
    /// fit the period together); its latency is the wait for the rollouts, plus any part of
    /// the preparation still running when the measurement came. False: the whole tick after
    /// the measurement.
    pub prepare_ahead: bool,
    /// SLQ iterations on the first window before the robot starts (10): the robot waits
    /// for its first plan, as on hardware.
    pub initial_iterations: usize,
    /// Threads of the solver (2).
    pub threads: usize,
    /// `SCHED_FIFO` priority (1-99) of the solver's threads (`None`, the default: the
    /// operating system's scheduling), as robot controllers run their MPC
    /// ([`crate::slq::set_realtime_priority`]; Linux, root or `CAP_SYS_NICE`). The closed
    /// loop's plant keeps the default scheduling.
    pub realtime_priority: Option<i32>,
    /// The contact anchors as states of the linearization (true, as the tasks' plans).
    pub anchor_states: bool,
    /// Keep the task's own state costs (running, waypoints, final) in the window beside the
    /// tracking cost (false: the plan already optimized them; a 0.5 s window that sees a
    /// waypoint coming re-plans toward it without the rest of the task).
    pub task_costs: bool,
    /// End every window that stops short of the task's end on the plan's value function
    /// (true; the plan must have one: [`crate::slq::SlqSettings::record_value_function`]).
    /// A window that reaches the task's end ends on the task's final cost, once.
    pub plan_value: bool,
    /// A window that reaches the task's end ends there, but spans at least this many
    /// seconds (`Some(0.1)`): its knots up to the task's end, fewer tick by tick, the task's
    /// final cost last, as in the plan ([`crate::ocp::RecedingHorizon::ends_at_task_end`];
    /// uniform knots only, a coarse tail keeps its length). Shorter windows turn the gains
    /// deadbeat before the heavy final cost (sidestep with windows down to one knot: a joint
    /// past 200 rad/s 10 ms before its end). `None`: the window keeps its length, its knots
    /// past the end tracking the plan's final state (the closed loop never runs them; on
    /// sidestep their rollouts leave the valid states on 92 of the last 100 ticks:
    /// docs/experiments/mpc-14.md).
    pub ends_at_task_end: Option<f64>,
    /// The feasibility constraints of the task's plan (friction, penetration, joint limits
    /// and speeds) in the window too, as penalties without the plan's multipliers (true).
    pub feasibility: bool,
    /// The smallest Levenberg-Marquardt regularization of `H` (1e-3, against the plan's
    /// 1e-10): the robot runs a tick's gains until the next, and with the tasks' small
    /// input weights the least regularized gains drive free legs into their torque limits
    /// and past the speed limit in the window's rollouts (squat_jump: 227 of 247 ticks
    /// without a usable trial at 1e-10).
    pub regularization: f64,
    /// How a window's knot (several substeps) is linearized (`FirstSubstep`: one
    /// derivative evaluation per knot).
    pub linearization: KnotLinearization,
    pub tracking: TrackingWeights,
    /// Keep most knots' models from tick to tick ([`crate::slq::ModelReuse`]; `None`:
    /// every knot linearized every tick). The initial iterations linearize every knot.
    pub model_reuse: Option<ModelReuse>,
    /// What the robot's feedback between ticks acts on ([`MpcFeedback::Optimizer`]).
    pub feedback: MpcFeedback,
}

/// What the policy `u = u_k + K_k dx` the robot runs between ticks feeds back.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MpcFeedback {
    /// The window's gains as SLQ computed them, on the optimizer's state: with the anchors
    /// as states, their columns act on legwork's estimate of the stance feet's anchors.
    #[default]
    Optimizer,
    /// The window's gains as the physical gains a plan exports
    /// ([`crate::ocp::physical_gain`]): on `[q (-) q*; v - v*]` alone, acting as the
    /// optimizer's on the motions that keep the knot's stance feet planted, the joint
    /// damping of a free joint on a stance foot's own motion. No anchor estimate, and no
    /// negative stiffness of a stance leg against a stiff ground (MuJoCo, a robot). Each
    /// knot's gain is computed once, when the robot first runs it.
    Physical,
}

impl MpcFeedback {
    /// `optimizer` or `physical` (`legwork mpc --feedback`, the summaries' `feedback`).
    pub fn name(self) -> &'static str {
        match self {
            Self::Optimizer => "optimizer",
            Self::Physical => "physical",
        }
    }
}

impl Default for MpcSettings {
    fn default() -> Self {
        Self { horizon: 0.5, rate: 200.0, knot_dt: None, fine_head: None, tail_ticks: 1, substeps: None, iterations_per_tick: 1, prepare_ahead: true, initial_iterations: 10, threads: 2, realtime_priority: None, anchor_states: true, task_costs: true, plan_value: true, ends_at_task_end: Some(0.1), feasibility: true, regularization: 1e-3, linearization: KnotLinearization::FirstSubstep, tracking: TrackingWeights::default(), model_reuse: None, feedback: MpcFeedback::Optimizer }
    }
}

impl MpcSettings {
    /// The tick period (s).
    pub fn period(&self) -> f64 {
        1.0 / self.rate
    }

    /// The window's knot spacing (s).
    pub fn knot_dt(&self) -> f64 {
        self.knot_dt.unwrap_or_else(|| self.period())
    }

    /// Knots per tick period.
    pub fn knots_per_tick(&self) -> usize {
        (self.period() / self.knot_dt()).round() as usize
    }

    /// Integration steps per head knot on a robot whose contact model is stable up to
    /// `max_step` seconds a step: [`Self::substeps`], or the fewest within `max_step`.
    pub fn knot_substeps(&self, max_step: f64) -> usize {
        self.substeps.unwrap_or_else(|| fewest_substeps(self.knot_dt(), max_step))
    }

    /// The coarse tail's knot spacing (s): [`Self::tail_ticks`] tick periods.
    pub fn tail_knot_dt(&self) -> f64 {
        self.tail_ticks as f64 * self.period()
    }

    /// The window's knots: `(head, tail)`, the first `head` of `knot_dt` and `tail` of
    /// [`Self::tail_knot_dt`] after them ([`Self::fine_head`]; `tail` 0 without one).
    pub fn knot_counts(&self) -> (usize, usize) {
        let dt = self.knot_dt();
        match self.fine_head.filter(|&head| self.tail_knot_dt() > dt * 1.5 && head < self.horizon - 0.5 * dt) {
            Some(head) => {
                let fine = (head / dt).round() as usize;
                (fine, ((self.horizon - fine as f64 * dt) / self.tail_knot_dt()).round().max(0.0) as usize)
            }
            None => ((self.horizon / dt).round() as usize, 0),
        }
    }

    /// [`Self::check`], and that the window's integration steps are no longer than
    /// `model`'s contact model allows (`contact.max_step`).
    pub fn check_for(&self, model: &Model) -> Result<(), MpcError> {
        self.check()?;
        let (dt, max_step) = (self.knot_dt(), model.contact.max_step);
        let fewest = fewest_substeps(dt, max_step);
        match self.substeps {
            Some(n) if n < fewest => Err(MpcError::Settings { field: "substeps", problem: format!("{n} steps per knot of {dt} s are steps of {} s: {}'s contact model is stable only up to {max_step} s steps (contact.max_step); use at least {fewest}", dt / n as f64, model.name) }),
            _ => Ok(()),
        }
    }

    /// Checks every setting: a clear error naming the one that is wrong.
    pub fn check(&self) -> Result<(), MpcError> {
        let bad = |field: &'static str, problem: String| Err(MpcError::Settings { field, problem });
        if !(self.horizon.is_finite() && self.horizon > 0.0) {
            return bad("horizon", format!("expected a positive number of seconds, got {}", self.horizon));
        }
        if !(self.rate.is_finite() && self.rate > 0.0) {
            return bad("rate", format!("expected a positive number of ticks per second, got {}", self.rate));
        }
        let dt = self.knot_dt();
        if !(dt.is_finite() && dt > 0.0) {
            return bad("knot_dt", format!("expected a positive number of seconds, got {dt}"));
        }
        let ratio = self.period() / dt;
        if ratio < 0.999 || (ratio - ratio.round()).abs() > 1e-6 {
            return bad("knot_dt", format!("the tick period 1 / rate = {} s must be a whole number (at least one) of knots of {dt} s", self.period()));
        }
        let knots = self.horizon / dt;
        if knots.round() < 2.0 {
            return bad("horizon", format!("{} s holds fewer than two knots of {dt} s", self.horizon));
        }
        if knots > 100_000.0 {
            return bad("horizon", format!("{} s is {knots:.0} knots of {dt} s: at most 100000", self.horizon));
        }
        if let Some(shortest) = self.ends_at_task_end.filter(|s| !(s.is_finite() && *s >= 0.0)) {
            return bad("ends_at_task_end", format!("expected the shortest window as a finite number of seconds >= 0, got {shortest}"));
        }
        if let Some(priority) = self.realtime_priority.filter(|p| !crate::slq::REALTIME_PRIORITIES.contains(p)) {
            return bad("realtime_priority", crate::slq::RealtimePriorityError::OutOfRange(priority).to_string());
        }
        if !(1..=2).contains(&self.tail_ticks) {
            return bad("tail_ticks", format!("expected 1 or 2 tick periods, got {}", self.tail_ticks));
        }
        if let Some(head) = self.fine_head {
            let fine = head / dt;
            // A tail of two-tick knots shortens the head by one knot every other tick.
            let shortest = self.knots_per_tick().max(self.tail_ticks);
            if !(head.is_finite() && (fine - fine.round()).abs() < 1e-6 && fine.round() as usize >= shortest) {
                return bad("fine_head", format!("expected a whole number of knots of {dt} s, at least {shortest} of them, got {head}"));
            }
            if self.knot_counts().1 > 0 {
                if self.tail_ticks == 2 && self.knots_per_tick() != 1 {
                    return bad("tail_ticks", format!("a tail of two tick periods needs head knots of the tick period ({} s), not {dt} s: with finer knots set tail_ticks to 1 (a tail of the tick period) or fine_head to the horizon (no tail)", self.period()));
                }
                let tail = (self.horizon - head) / self.tail_knot_dt();
                if (tail - tail.round()).abs() > 1e-6 {
                    return bad("fine_head", format!("the rest of the window, horizon - fine_head = {} s, must be a whole number of the tail's knots of {} s (or fine_head at least the horizon: no tail)", self.horizon - head, self.tail_knot_dt()));
                }
            }
        }
        if let Some(reuse) = self.model_reuse {
            if reuse.refresh_period == 0 {
                return bad("model_reuse", "expected a refresh period of at least 1 knot".into());
            }
            if self.knot_counts().1 > 0 {
                // Each tick splits the first coarse knot into fine ones (Slq::shift_head):
                // the knots' models do not carry over.
                return bad("model_reuse", "not with a coarse tail (its knots are resampled every tick or two, so no model carries over): set tail_ticks to 1 with knots of the tick period, or fine_head to the horizon".into());
            }
        }
        if self.substeps == Some(0) {
            return bad("substeps", "expected at least 1 integration step per knot".into());
        }
        if self.iterations_per_tick == 0 {
            return bad("iterations_per_tick", "expected at least 1".into());
        }
        if !(self.regularization.is_finite() && self.regularization > 0.0) {
            return bad("regularization", format!("expected a positive number, got {}", self.regularization));
        }
        if self.threads == 0 {
            return bad("threads", "expected at least 1".into());
        }
        let t = &self.tracking;
        for (field, w) in [("tracking.base_position[0]", t.base_position[0]), ("tracking.base_position[1]", t.base_position[1]), ("tracking.base_position[2]", t.base_position[2]), ("tracking.base_orientation", t.base_orientation), ("tracking.joint_position", t.joint_position), ("tracking.base_velocity", t.base_velocity), ("tracking.joint_velocity", t.joint_velocity), ("tracking.terminal_seconds", t.terminal_seconds), ("tracking.input", t.input)] {
            if !(w.is_finite() && w >= 0.0) {
                return bad(field, format!("expected a finite number >= 0, got {w}"));
            }
        }
        Ok(())
    }
}

/// Why the controller could not be set up or could not go on.
#[derive(Debug, thiserror::Error)]
pub enum MpcError {
    #[error("MPC setting `{field}`: {problem}")]
    Settings { field: &'static str, problem: String },
    #[error(transparent)]
    Task(#[from] TaskError),
    #[error(transparent)]
    Slq(#[from] SlqError),
    #[error("the plan to track has no knots")]
    EmptyPlan,
    /// The plant (another simulator's process) failed; not the motion.
    #[error("the closed loop's plant: {0}")]
    Plant(#[source] crate::sim::SimError),
    /// The measured state is not a state of the problem ([`crate::slq::Problem::is_valid`]:
    /// not finite, or a joint past the speed limit): a sensor's glitch. The tick does no work
    /// and leaves the solver's solution as it was.
    #[error("tick at t = {t:.3} s: the measured state is not valid (not finite, or a joint past the speed limit)")]
    InvalidMeasurement { t: f64 },
    #[error("tick at t = {t:.3} s: {source}")]
    Tick {
        t: f64,
        #[source]
        source: RealTimeIterationError,
    },
}

/// The window problem of `spec` for `model` on `terrain`: the task's costs on `settings`'
/// horizon and knot spacing, starting at `t = 0` from the plan's first state, ending on the
/// plan's value function (with [`MpcSettings::plan_value`]) and tracking the plan (its
/// states and inputs, knots every `plan_dt` seconds from `t = 0`; module docs).
pub fn window_problem<'a>(spec: &TaskSpec, model: &'a Model, terrain: &'a dyn Terrain, plan: &SlqSolution<RobotState>, plan_dt: f64, settings: &MpcSettings, origin: &str) -> Result<WholeBodyProblem<'a>, MpcError> {
    settings.check_for(model)?;
    if plan.inputs.is_empty() {
        return Err(MpcError::EmptyPlan);
    }
    let initial = plan.states[0].clone();
    let mut window = spec.clone();
    let (head, tail) = settings.knot_counts();
    window.dt = settings.knot_dt();
    // The knots' count (the feasibility rows are per knot); a coarse tail spaces the last
    // `tail` of them by its own knot spacing below.
    window.duration = settings.knot_dt() * (head + tail) as f64;
    // The task's own `substeps` are its plan knots'; the window's are the settings'.
    window.substeps = settings.substeps;
    window.continuation = None;
    window.exploration = None;
    let mut problem = window.problem(model, terrain, initial, origin)?;
    let weights = settings.tracking.running(model.nv);
    let reference = ReferenceMotion {
        dt: plan_dt,
        q: plan.states.iter().map(|x| x.q.clone()).collect(),
        v: plan.states.iter().map(|x| x.v.clone()).collect(),
        tau: plan.inputs.clone(),
        input_weight: settings.tracking.input,
        terminal_weights: &weights * settings.tracking.terminal_seconds,
        weights,
    };
    if !settings.task_costs {
        for cost in [&mut problem.running, &mut problem.terminal] {
            cost.weights.fill(0.0);
            cost.feet.clear();
        }
        problem.waypoints.clear();
    }
    if !settings.feasibility {
        problem.feasibility = None;
    }
    problem.anchor_states = settings.anchor_states;
    problem.linearization = settings.linearization;
    if tail > 0 {
        let head_knots_per_tail_knot = (settings.tail_knot_dt() / settings.knot_dt()).round() as usize;
        problem.tail = Some(CoarseTail { from: head, dt: settings.tail_knot_dt(), substeps: problem.substeps * head_knots_per_tail_knot });
    }
    let mut receding = RecedingHorizon::new(0.0, spec.duration, reference);
    receding.ends_at_task_end = settings.ends_at_task_end;
    if settings.plan_value {
        let mut value = plan.value_function.clone().ok_or(MpcError::Settings { field: "plan_value", problem: "the plan has no value function: solve it with record_value_function".into() })?;
        let (plan_nx, nx) = (value.gradients.first().map_or(0, |g| g.len()), problem.nx());
        if plan_nx < nx {
            return Err(MpcError::Settings { field: "anchor_states", problem: format!("the plan's value function has {plan_nx} coordinates, the window's state {nx}: solve the plan with the anchors as states too") });
        }
        if plan_nx > nx {
            // A window without the anchor states ends on the plan's value at the plan's
            // anchors (dx_anchors = 0): the leading [dq; dv] block.
            for (p, g) in value.hessians.iter_mut().zip(value.gradients.iter_mut()) {
                *p = p.view((0, 0), (nx, nx)).into_owned();
                *g = g.rows(0, nx).into_owned();
            }
        }
        receding.value = Some(PlanValue { dt: plan_dt, states: plan.states.clone(), value });
    }
    problem.receding = Some(receding);
    Ok(problem)
}

/// The plan's own policy at absolute times, as the plan runs it: at a window knot's time
/// `t`, the plan's knot `i` whose interval holds `t` (`i = floor(t / plan_dt)`),
/// `u = u_i + K_i (x (-) y_i)`. The warm start of the first window and of every new last
/// knot, and the restart of a failed tick. Past the plan's end, its last input and gain
/// around its last state.
struct PlanPolicy<'s> {
    plan: &'s SlqSolution<RobotState>,
    plan_dt: f64,
    /// `x (-) y_i` on the plan's own state.
    dx: Mutex<DVector<f64>>,
}

impl<'s> PlanPolicy<'s> {
    fn new(plan: &'s SlqSolution<RobotState>, plan_dt: f64) -> Self {
        Self { plan, plan_dt, dx: Mutex::new(DVector::zeros(plan.gains[0].ncols())) }
    }

    /// `x (-) y` on the plan's own state (its gains have anchor columns when it was solved
    /// with the anchors as states, whatever the window's state is), into `out`.
    fn deviation(model: &Model, y: &RobotState, x: &RobotState, out: &mut DVector<f64>) {
        let nv = model.nv;
        crate::dynamics::difference_into(model, &y.q, &x.q, &mut out.as_mut_slice()[..nv]);
        for j in 0..nv {
            out[nv + j] = x.v[j] - y.v[j];
        }
        for (f, (ay, ax)) in y.anchors.iter().zip(&x.anchors).enumerate() {
            let at = 2 * nv + crate::sim::ANCHOR_DIM * f;
            if at + crate::sim::ANCHOR_DIM <= out.len() {
                let d = match (ay, ax) {
                    (Some(ay), Some(ax)) => ax - ay,
                    _ => nalgebra::Vector3::zeros(),
                };
                out.fixed_rows_mut::<3>(at).copy_from(&d);
            }
        }
    }
}

impl<'a> Policy<WholeBodyProblem<'a>> for PlanPolicy<'_> {
    fn control(&self, problem: &WholeBodyProblem<'a>, k: usize, x: &RobotState, u: &mut DVector<f64>) {
        let last = self.plan.inputs.len() - 1;
        // The knot holding t (not the nearest: a window knot at 5 ms is in the plan's
        // [4, 6) ms knot, whose state is at 4 ms).
        let i = ((problem.knot_time(k) / self.plan_dt + 1e-9).floor().max(0.0) as usize).min(last);
        let mut dx = self.dx.lock().unwrap_or_else(|e| e.into_inner());
        Self::deviation(problem.model, &self.plan.states[i], x, &mut dx);
        u.copy_from(&self.plan.inputs[i]);
        u.gemv(1.0, &self.plan.gains[i], &dx, 1.0);
    }
}

/// A solution of the window as the robot runs it until the next one arrives: knot `k`
/// over `[t_k, t_{k+1})`, `u = u_k + K_k (x (-) x_k)`; past the window's end, its last
/// knot's law.
#[derive(Clone, Debug)]
pub struct MpcPolicy {
    /// The window's start (s).
    pub start: f64,
    /// Where its knots fall from the start ([`crate::ocp::KnotGrid`]).
    pub grid: crate::ocp::KnotGrid,
    pub states: Vec<RobotState>,
    pub inputs: Vec<DVector<f64>>,
    pub gains: Vec<DMatrix<f64>>,
}

impl MpcPolicy {
    /// A policy with room for `problem`'s window (all zero).
    pub fn for_problem(problem: &WholeBodyProblem<'_>) -> Self {
        let (n, nx, nu) = (problem.horizon(), problem.nx(), problem.nu());
        Self { start: 0.0, grid: problem.grid(), states: vec![problem.initial.clone(); n + 1], inputs: vec![DVector::zeros(nu); n], gains: vec![DMatrix::zeros(nu, nx); n] }
    }

    /// Copies the solver's current solution in (no allocation).
    fn copy_from(&mut self, start: f64, slq: &Slq<'_, WholeBodyProblem<'_>>) {
        self.start = start;
        self.grid = slq.problem().grid();
        for (to, from) in self.states.iter_mut().zip(slq.states()) {
            to.clone_from(from);
        }
        for (to, from) in self.inputs.iter_mut().zip(slq.inputs()) {
            to.copy_from(from);
        }
        for (to, from) in self.gains.iter_mut().zip(slq.gains()) {
            to.copy_from(from);
        }
    }

    /// The knot acting at time `t` (the first before the window, the last after it) and how
    /// far into it `t` is, as a fraction of the knot.
    pub fn knot_at(&self, t: f64) -> (usize, f64) {
        self.grid.interval_at(t - self.start)
    }
}

/// The receding-horizon controller on a window problem (module docs).
pub struct Mpc<'p, 'a> {
    problem: &'p WholeBodyProblem<'a>,
    slq: Slq<'p, WholeBodyProblem<'a>>,
    settings: MpcSettings,
    plan_policy: PlanPolicy<'p>,
    /// The window's start at the last tick (s), or at the tick prepared for.
    last_start: f64,
    cost: f64,
    /// The last preparation's wall time (s; [`Self::prepare`]).
    preparation_time: f64,
}

/// What one tick did.
#[derive(Clone, Debug, PartialEq)]
pub struct TickReport {
    /// The window's start (s).
    pub t: f64,
    /// Wall time of the tick's solve (s): shift, iterations, nothing else; with the tick
    /// prepared ahead ([`Mpc::prepare`]), the preparation's time too.
    pub solve_time: f64,
    /// Wall time of the preparation before the measurement (s; 0 if the tick was not
    /// prepared ahead) and from the measurement to the policy (the rest).
    pub preparation_time: f64,
    pub feedback_time: f64,
    /// The kept trajectory's cost and the iterations' records.
    pub cost: f64,
    pub iterations: Vec<RealTimeIteration>,
    /// Whether the tick restarted from the plan's policy (the shifted solution failed).
    pub restarted: bool,
}

impl<'p, 'a> Mpc<'p, 'a> {
    /// The controller on `problem` (from [`window_problem`]), warm-started from `plan`
    /// (the task's SLQ solution, knots every `plan_dt` s from `t = 0`): rolls the plan's
    /// policy out over the first window from `problem.initial` and runs
    /// `settings.initial_iterations` SLQ iterations on it.
    pub fn new(problem: &'p WholeBodyProblem<'a>, plan: &'p SlqSolution<RobotState>, plan_dt: f64, settings: MpcSettings) -> Result<Self, MpcError> {
        settings.check()?;
        if plan.inputs.is_empty() {
            return Err(MpcError::EmptyPlan);
        }
        let receding = problem.receding.as_ref().ok_or(MpcError::Settings { field: "problem", problem: "not a receding-horizon window (build it with mpc::window_problem)".into() })?;
        receding.set_start(0.0);
        let slq_settings = SlqSettings { threads: settings.threads, realtime_priority: settings.realtime_priority, min_regularization: settings.regularization, initial_regularization: settings.regularization, ..SlqSettings::default() };
        let mut slq = Slq::new(problem, slq_settings)?;
        let plan_policy = PlanPolicy::new(plan, plan_dt);
        let initial = problem.initial.clone();
        let mut cost = slq.start_from(&initial, &plan_policy)?;
        for i in 0..settings.initial_iterations {
            let it = slq.real_time_iteration(&initial, (i > 0).then_some(cost)).map_err(|source| MpcError::Tick { t: 0.0, source })?;
            cost = it.cost;
        }
        slq.set_model_reuse(settings.model_reuse)?;
        Ok(Self { problem, slq, settings, plan_policy, last_start: 0.0, cost, preparation_time: 0.0 })
    }

    pub fn settings(&self) -> &MpcSettings {
        &self.settings
    }

    pub fn problem(&self) -> &'p WholeBodyProblem<'a> {
        self.problem
    }

    /// Moves the window to tick time `t` (a multiple of the knot spacing after the last
    /// tick's) and runs the part of that tick's first iteration that does not need its
    /// measurement, the model and the backward pass
    /// ([`Slq::prepare_real_time_iteration`]): the preparation phase, run between ticks
    /// ([`MpcSettings::prepare_ahead`]). Returns its wall time (s). A [`Self::tick`] at `t`
    /// then only rolls out from its measurement.
    pub fn prepare(&mut self, t: f64) -> f64 {
        let started = Instant::now();
        self.move_window(t);
        self.slq.prepare_real_time_iteration();
        self.preparation_time = started.elapsed().as_secs_f64();
        self.preparation_time
    }

    /// The window moved on to start at `t` and the solution shifted with it.
    fn move_window(&mut self, t: f64) {
        if let Some(tail) = self.problem.tail {
            // A coarse tail: the window moves by whole tick periods, a tail knot of one
            // period (split into the head's knots) or a head knot of a two-period tail.
            let period = self.settings.period();
            let ticks = ((t - self.last_start) / period).round().max(0.0) as usize;
            let m = self.settings.knots_per_tick();
            for i in 1..=ticks {
                if let Some(r) = &self.problem.receding {
                    r.set_start(self.last_start + i as f64 * period);
                }
                if self.settings.tail_ticks == 1 {
                    self.slq.shift_head(tail.from, m, &self.plan_policy);
                } else if self.problem.grid().tail.is_some_and(|now| now.from == tail.from) {
                    // The first tail knot now starts a tick after the head's end.
                    self.slq.shift_halving(tail.from - 1);
                } else {
                    self.slq.shift(1, &self.plan_policy);
                }
            }
            self.last_start += ticks as f64 * period;
        } else {
            let dt = self.problem.dt;
            let knots = ((t - self.last_start) / dt).round().max(0.0) as usize;
            let start = self.last_start + knots as f64 * dt;
            if let Some(r) = &self.problem.receding {
                r.set_start(start);
            }
            self.last_start = start;
            self.slq.shift(knots, &self.plan_policy);
        }
    }

    /// One tick at time `t` (a multiple of the knot spacing after the last tick's) from the
    /// measured state `x`: the window moved to `t`, the solution shifted, the iteration
    /// budget spent (the first iteration's model and backward pass already done if
    /// [`Self::prepare`] prepared `t`). The new policy is then in [`Self::write_policy`].
    pub fn tick(&mut self, t: f64, x: &RobotState) -> Result<TickReport, MpcError> {
        let started = Instant::now();
        // A garbled measurement would leave the solution to the next tick as rollouts from
        // it leave it (NaN states to linearize around): the next tick moves the window on
        // by the ticks passed, from the solution the robot's policy came from.
        if !self.problem.is_valid(x) {
            return Err(MpcError::InvalidMeasurement { t });
        }
        // Prepared for this tick: the solver still holds a preparation (any shift since
        // would have discarded it) and the window already starts at `t`.
        let prepared = self.slq.is_prepared() && self.is_tick_time(self.last_start, t);
        let preparation_time = if prepared { self.preparation_time } else { 0.0 };
        if !prepared {
            self.move_window(t);
        }
        let start = self.last_start;
        let mut iterations = Vec::with_capacity(self.settings.iterations_per_tick);
        let mut restarted = false;
        for i in 0..self.settings.iterations_per_tick {
            let it = match self.slq.real_time_iteration(x, (i > 0).then_some(self.cost)) {
                Ok(it) => it,
                // The shifted solution is no longer a usable model (its backward pass found
                // no positive-definite H, or none of its steps stayed valid from the new
                // state): start the window again from the plan's own policy, rolled out
                // from the measured state, and iterate on that.
                Err(_) if !restarted => {
                    restarted = true;
                    self.slq.reset_regularization();
                    self.slq.start_from(x, &self.plan_policy).map_err(|_| MpcError::Tick { t, source: RealTimeIterationError::NoValidTrial })?;
                    self.slq.real_time_iteration(x, None).map_err(|source| MpcError::Tick { t, source })?
                }
                Err(source) => return Err(MpcError::Tick { t, source }),
            };
            self.cost = it.cost;
            iterations.push(it);
        }
        let feedback_time = started.elapsed().as_secs_f64();
        Ok(TickReport { t: start, solve_time: preparation_time + feedback_time, preparation_time, feedback_time, cost: self.cost, iterations, restarted })
    }

    /// Whether tick times `a` and `b` fall on the same knot.
    fn is_tick_time(&self, a: f64, b: f64) -> bool {
        (a - b).abs() < 0.5 * self.problem.dt
    }

    /// The current solution as the policy the robot runs.
    pub fn write_policy(&self, policy: &mut MpcPolicy) {
        policy.copy_from(self.last_start, &self.slq);
    }
}

/// A [`MpcPolicy`] as a simulator controller, called every control period (1 ms) inside
/// the window's knots (5 ms): `u = u_k + K_k (x(t) (-) x*(t))` with `k` the knot of time `t`
/// and the reference `x*(t)` interpolated along the knot,
/// `x (-) x*(t) ~ (x (-) x_k) - s (x_{k+1} (-) x_k)`, `s = (t - t_k) / dt` (to first order on
/// the base's SE(3)). Against `x_k` itself the feedback would read the knot's own planned
/// motion as an error: 4 ms into a 5 ms knot of a take-off, several rad/s on a knee.
/// With [`MpcFeedback::Physical`], `K_k` is knot `k`'s physical gain on the `[dq; dv]`
/// rows of that deviation, computed the first time the robot runs the knot.
pub struct MpcPolicyController<'p, 'a> {
    problem: &'p WholeBodyProblem<'a>,
    policy: MpcPolicy,
    x: RobotState,
    dx: DVector<f64>,
    knot_step: DVector<f64>,
    u: DVector<f64>,
    physical: Option<PhysicalFeedback>,
}

/// The physical gains of the policy's knots, each computed when first needed.
struct PhysicalFeedback {
    workspace: PhysicalGainWorkspace,
    gains: Vec<DMatrix<f64>>,
    ready: Vec<bool>,
}

impl<'p, 'a> MpcPolicyController<'p, 'a> {
    /// With [`MpcFeedback::Physical`], a stance foot's own motion damped as in the plans'
    /// exported gains ([`PhysicalGainWorkspace::for_exported_policy`]).
    pub fn new(problem: &'p WholeBodyProblem<'a>, policy: MpcPolicy, feedback: MpcFeedback) -> Self {
        let (nx, nu, nv) = (problem.nx(), problem.nu(), problem.model.nv);
        let physical = (feedback == MpcFeedback::Physical).then(|| {
            let knots = policy.gains.len();
            PhysicalFeedback { workspace: PhysicalGainWorkspace::for_exported_policy(problem.model, &problem.initial.q), gains: vec![DMatrix::zeros(nu, 2 * nv); knots], ready: vec![false; knots] }
        });
        Self { problem, policy, x: problem.initial.clone(), dx: DVector::zeros(nx), knot_step: DVector::zeros(nx), u: DVector::zeros(nu), physical }
    }

    /// Runs `policy` from now on; the one it replaces comes back in `policy` (no allocation).
    pub fn swap_policy(&mut self, policy: &mut MpcPolicy) {
        std::mem::swap(&mut self.policy, policy);
        if let Some(p) = &mut self.physical {
            p.ready.fill(false);
        }
    }
}

impl Controller for MpcPolicyController<'_, '_> {
    fn name(&self) -> &str {
        "mpc"
    }
    fn compute(&mut self, model: &Model, state: &SimState, tau: &mut DVector<f64>) -> Result<(), ControlError> {
        let (k, along) = self.policy.knot_at(state.t);
        self.x.q.copy_from(&state.q);
        self.x.v.copy_from(&state.v);
        self.x.anchors.clone_from(&state.anchors);
        self.problem.difference(&self.policy.states[k], &self.x, &mut self.dx);
        if along > 0.0 {
            self.problem.difference(&self.policy.states[k], &self.policy.states[k + 1], &mut self.knot_step);
            self.dx.axpy(-along, &self.knot_step, 1.0);
        }
        self.u.copy_from(&self.policy.inputs[k]);
        match &mut self.physical {
            None => gemv_add(&mut self.u, &self.policy.gains[k], &self.dx),
            Some(p) => {
                if !p.ready[k] {
                    let knot = &self.policy.states[k];
                    physical_gain(model, &mut p.workspace, &knot.q, &knot.anchors, &self.policy.gains[k], &mut p.gains[k]);
                    p.ready[k] = true;
                }
                gemv_add(&mut self.u, &p.gains[k], self.dx.rows(0, 2 * model.nv));
            }
        }
        tau.rows_mut(6, self.u.len()).copy_from(&self.u);
        Ok(())
    }
}
