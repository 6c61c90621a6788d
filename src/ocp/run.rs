//! A task end to end (Neunert 2017): settle the robot, solve with SLQ from the joint-PD
//! initial policy, then check the motion in closed loop in the simulator, (a) with the SLQ
//! policy `u = u_ff + K (x (-) x*)` and (b) with the tracking controller at 1 kHz.

use super::{settled_stance, MotionMetrics, PdPolicy, RobotState, TaskSpec, WholeBodyProblem};
use crate::control::{JointPd, TrackingController};
use crate::io::{Knot, Trajectory};
use crate::model::Model;
use crate::sim::{ControlError, Controller, SimConfig, SimError, SimState, Simulator};
use crate::slq::{IterationLog, Problem, Slq, SlqError, SlqSettings, SlqSolution, SolutionPolicy, Termination};
use crate::terrain::Terrain;
use nalgebra::{DMatrix, DVector};

/// Why a task could not be solved or checked.
#[derive(Debug, thiserror::Error)]
pub enum SolveError {
    #[error(transparent)]
    Task(#[from] super::TaskError),
    #[error("settling the robot before the optimization: {0}")]
    Settle(SimError),
    #[error(transparent)]
    Slq(#[from] SlqError),
    #[error("{what} could not start")]
    ClosedLoop {
        what: &'static str,
        #[source]
        source: SimError,
    },
    #[error(transparent)]
    Control(#[from] ControlError),
    #[error("an iteration limit of {limit} leaves none for the full horizon after the continuation's {stages} stage iterations")]
    IterationBudget { limit: usize, stages: usize },
    #[error("the exploration's screening ({screening} SLQ iterations: screen_iterations x rounds) does not fit in {budget}; lower [exploration] screen_iterations or rounds, or raise the iteration limit")]
    ExplorationBudget { screening: usize, budget: String },
}

/// A closed-loop re-run: its trajectory and figures, or how it failed (a divergence is a
/// result, reported, not an error of the whole solve).
pub enum Rerun {
    Completed { trajectory: Box<Trajectory>, metrics: Box<MotionMetrics> },
    Failed { reason: String },
}

impl Rerun {
    pub fn metrics(&self) -> Option<&MotionMetrics> {
        match self {
            Rerun::Completed { metrics, .. } => Some(metrics),
            Rerun::Failed { .. } => None,
        }
    }
}

/// Everything a solved task produced.
pub struct TaskRun {
    /// The optimized motion, with feedback gains.
    pub plan: Trajectory,
    pub plan_metrics: MotionMetrics,
    /// (a) The SLQ policy re-run in the simulator (the optimizer's integration step as the
    /// physics step; the policy held over each knot interval, the zero-order hold its gains
    /// were computed for).
    pub policy_rerun: Rerun,
    /// (b) The tracking controller (Neunert 2017, sec. IV-B) at 1 kHz on the plan.
    pub tracking_rerun: Rerun,
    /// SLQ on the full horizon (after the continuation's stages, if any).
    pub solution: SlqSolution<RobotState>,
    /// The continuation's stages ([`super::ContinuationSpec`]), in order; empty without.
    pub stages: Vec<StageReport>,
    /// The augmented-Lagrangian rounds on the full horizon before the last one (its
    /// multipliers updated after each; [`super::FeasibilitySettings::outer_rounds`]), in
    /// order; `solution` is the last round.
    pub rounds: Vec<StageReport>,
    /// The largest violation of each feasibility constraint by the plan.
    pub violation: Option<super::Violation>,
    /// The plan's cost under the task's own terms (eq. 4: running, waypoint and final
    /// costs), without the feasibility constraints' augmented-Lagrangian terms, whose
    /// multipliers differ from solve to solve: the figure to compare two solves by.
    pub task_cost: f64,
    /// The exploration's starts and the kept one, if the solve explored.
    pub exploration: Option<ExplorationReport>,
}

/// What [`super::explore`] did in a solve: every start, which one was kept, the wall time.
#[derive(Clone, Debug, PartialEq)]
pub struct ExplorationReport {
    pub spec: super::ExplorationSpec,
    pub starts: Vec<super::StartReport>,
    pub best: usize,
    /// Wall time of the exploration, s (all starts; part of [`TaskRun::solve_time`]).
    pub time: f64,
    /// SLQ iterations of all starts together.
    pub iterations: usize,
    /// If the kept start was not the single start: both solves to the end, and which won.
    pub single_start: Option<SingleStartFinal>,
    /// Whether the returned plan continues the kept start's screening (false when start 0
    /// was kept, or the single start won the final: the plan is then the single start's own
    /// solve, and the screening's iterations are not among [`TaskRun::iterations`]).
    pub screening_continued: bool,
}

/// The final of an exploration whose kept start is not the single start
/// ([`super::ExplorationSpec::keep_single_start`]): both solved to the end, side by side.
#[derive(Clone, Debug, PartialEq)]
pub struct SingleStartFinal {
    /// [`TaskRun::task_cost`] of the kept start's plan and of the single start's.
    pub explored_task_cost: f64,
    pub single_task_cost: f64,
    /// True if the single start's plan is the one returned (its task cost no higher).
    pub kept_single: bool,
    /// Wall time of the two solves side by side, s.
    pub time: f64,
}

impl StageReport {
    fn of(horizon: f64, solution: &SlqSolution<RobotState>) -> Self {
        Self {
            horizon,
            iterations: solution.iterations.len(),
            termination: solution.termination.clone(),
            initial_cost: solution.cost_history[0],
            final_cost: *solution.cost_history.last().unwrap_or(&f64::NAN),
            time: solution.total_time,
        }
    }
}

impl TaskRun {
    /// SLQ iterations of the kept start in all: the exploration's screening of it, the
    /// stages' and the full horizon's.
    pub fn iterations(&self) -> usize {
        // With a continuation the first stage's report already counts them.
        let screened = match &self.exploration {
            Some(e) if e.screening_continued && self.stages.is_empty() => e.starts[e.best].iterations,
            _ => 0,
        };
        screened + self.stages.iter().chain(&self.rounds).map(|s| s.iterations).sum::<usize>() + self.solution.iterations.len()
    }

    /// Seconds of optimization in all (wall time): the exploration's, the stages' and the
    /// full horizon's.
    pub fn solve_time(&self) -> f64 {
        let exploring = self.exploration.as_ref().map_or(0.0, |e| e.time);
        match self.exploration.as_ref().and_then(|e| e.single_start.as_ref()) {
            // Two solves side by side: their wall time.
            Some(final_) => exploring + final_.time,
            None => exploring + self.stages.iter().chain(&self.rounds).map(|s| s.time).sum::<f64>() + self.solution.total_time,
        }
    }
}

/// One stage of a horizon continuation.
#[derive(Clone, Debug, PartialEq)]
pub struct StageReport {
    /// Its horizon (s).
    pub horizon: f64,
    pub iterations: usize,
    pub termination: Termination,
    pub initial_cost: f64,
    pub final_cost: f64,
    /// Seconds of optimization.
    pub time: f64,
}

/// An SLQ iteration as [`solve_task`] reports it: of a continuation stage (its index and
/// horizon, s) or of the full horizon (`None`).
pub struct SolveProgress<'l> {
    pub stage: Option<(usize, f64)>,
    pub log: &'l IterationLog,
}

/// The optimized states and inputs as a trajectory file: contact forces and flags
/// evaluated at each state, the feedback gains at each knot (the last knot repeats the
/// last input and gain). The gains are on the physical state `[q (-) q*; v - v*]`
/// (`2 nv` columns, the trajectory format): the optimizer's gains on the deviations that
/// keep the knot's stance feet planted, a free joint's damping on a stance foot's own
/// motion ([`super::physical_gain`]); the optimizer's own gains act in
/// [`SlqPolicyController`].
pub fn solution_trajectory(problem: &WholeBodyProblem<'_>, solution: &SlqSolution<RobotState>, scenario: &str) -> Trajectory {
    let model = problem.model;
    let mut traj = Trajectory::new(model, scenario, problem.dt, problem.terrain.spec());
    traj.metadata.initial_anchors = Some(problem.initial.anchors.iter().map(|a| a.map(Into::into)).collect());
    traj.metadata.joint_stops = problem.joint_limits;
    let mut ws = crate::sim::ContactModelWorkspace::new(model, problem.terrain).with_joint_limits(problem.joint_limits);
    let n = solution.inputs.len();
    let mut gain_ws = super::PhysicalGainWorkspace::for_exported_policy(model, &solution.states[0].q);
    let mut gain = DMatrix::zeros(model.nv - 6, 2 * model.nv);
    for (k, x) in solution.states.iter().enumerate() {
        ws.evaluate_contacts(&x.q, &x.v, &x.anchors);
        let i = k.min(n - 1);
        // The gain of knot i acts around state i (the last knot reuses the last gain).
        let around = &solution.states[i];
        super::physical_gain(model, &mut gain_ws, &around.q, &around.anchors, &solution.gains[i], &mut gain);
        traj.knots.push(Knot {
            t: k as f64 * problem.dt,
            q: x.q.iter().copied().collect(),
            v: x.v.iter().copied().collect(),
            tau: solution.inputs[i].iter().copied().collect(),
            contact_force: ws.feet().iter().map(|f| f.contact.force.into()).collect(),
            in_contact: ws.feet().iter().map(|f| f.contact.normal_force > 0.0).collect(),
            feedback_gain: Some(gain.row_iter().map(|r| r.iter().copied().collect()).collect()),
        });
    }
    traj
}

/// The SLQ policy as a simulator controller: at time `t`, knot `k = floor(t / dt)`,
/// `u = u_k + K_k (x (-) x_k)` (Neunert 2017, eq. 2).
pub struct SlqPolicyController<'p, 'a> {
    problem: &'p WholeBodyProblem<'a>,
    solution: &'p SlqSolution<RobotState>,
    dx: DVector<f64>,
    u: DVector<f64>,
    x: RobotState,
}

impl<'p, 'a> SlqPolicyController<'p, 'a> {
    pub fn new(problem: &'p WholeBodyProblem<'a>, solution: &'p SlqSolution<RobotState>) -> Self {
        let (nx, nu) = (problem.nx(), problem.nu());
        Self { problem, solution, dx: DVector::zeros(nx), u: DVector::zeros(nu), x: problem.initial_state() }
    }
}

impl Controller for SlqPolicyController<'_, '_> {
    fn name(&self) -> &str {
        "slq_policy"
    }
    fn compute(&mut self, _model: &Model, state: &SimState, tau: &mut DVector<f64>) -> Result<(), ControlError> {
        let n = self.solution.inputs.len();
        let k = ((state.t / self.problem.dt + 1e-9).floor() as usize).min(n - 1);
        self.x.q.copy_from(&state.q);
        self.x.v.copy_from(&state.v);
        self.x.anchors.clone_from(&state.anchors);
        self.problem.difference(&self.solution.states[k], &self.x, &mut self.dx);
        self.u.copy_from(&self.solution.inputs[k]);
        self.u.gemv(1.0, &self.solution.gains[k], &self.dx, 1.0);
        tau.rows_mut(6, self.u.len()).copy_from(&self.u);
        Ok(())
    }
}

/// Options of [`solve_task`].
#[derive(Clone, Debug, Default)]
pub struct SolveOptions {
    /// Threads for the linearization (0 = one per core).
    pub threads: usize,
    /// Overrides the task's iteration limit.
    pub max_iterations: Option<usize>,
    /// Overrides the task's `[exploration]` (`Some` with one start and no sampling stage:
    /// no exploration).
    pub exploration: Option<super::ExplorationSpec>,
    /// Keep the plan's local value function ([`crate::slq::SlqSettings::record_value_function`]):
    /// a receding-horizon controller's windows end on it.
    pub value_function: bool,
}

/// SLQ on `problem` from `warm`'s policy (the standing PD after its knots), or from the
/// standing PD alone (Neunert 2017, Alg. 1's initial stable control law).
fn solve_from<'a>(problem: &WholeBodyProblem<'a>, settings: SlqSettings, warm: Option<&SlqSolution<RobotState>>, standing: &PdPolicy, report: impl FnMut(&IterationLog)) -> Result<SlqSolution<RobotState>, SlqError> {
    let solver = Slq::new(problem, settings)?;
    match warm {
        None => solver.solve(standing, report),
        Some(previous) => solver.solve(&SolutionPolicy::new(problem, previous, standing), report),
    }
}

/// A task's optimization: its continuation's stages, augmented-Lagrangian rounds and polish.
struct Optimized<'a> {
    problem: WholeBodyProblem<'a>,
    solution: SlqSolution<RobotState>,
    stages: Vec<StageReport>,
    rounds: Vec<StageReport>,
    violation: Option<super::Violation>,
    task_cost: f64,
}

/// What [`optimize`] needs besides the task: the robot, world and start, and its budget.
struct Pipeline<'s, 'a> {
    spec: &'s TaskSpec,
    model: &'a Model,
    terrain: &'a dyn Terrain,
    origin: &'s str,
    initial: &'s RobotState,
    pd: &'s JointPd,
    limit: usize,
    /// Keep the final solution's value function.
    value_function: bool,
}

impl Pipeline<'_, '_> {
    /// The first problem a solve meets: the continuation's first stage, or the full horizon.
    fn first_problem(&self) -> Result<WholeBodyProblem<'_>, SolveError> {
        let (spec, initial) = (self.spec, self.initial);
        Ok(match &spec.continuation {
            Some(c) => spec.continuation_stage(c.horizons[0], c.progress_exponent, [initial.q[0], initial.q[1], initial.q[2]]).problem(self.model, self.terrain, initial.clone(), self.origin)?,
            None => spec.problem(self.model, self.terrain, initial.clone(), self.origin)?,
        })
    }
}

/// The task's optimization on `threads` threads, from the standing PD or, if `first` is
/// given, from that solution of [`Pipeline::first_problem`] (an exploration's kept start,
/// whose iterations count as that problem's first).
fn optimize<'a>(p: &Pipeline<'_, 'a>, threads: usize, mut first: Option<SlqSolution<RobotState>>, on_iteration: &mut dyn FnMut(SolveProgress)) -> Result<Optimized<'a>, SolveError> {
    let Pipeline { spec, model, terrain, origin, initial, pd, limit, value_function } = *p;
    let standing = PdPolicy(pd);
    let settings = |max_iterations: usize, normalized_cost_tolerance: f64| SlqSettings { threads, max_iterations, normalized_cost_tolerance, record_value_function: value_function, ..SlqSettings::default() };

    // The continuation's stages, each from the last one's policy (the first from standing).
    let mut stages = Vec::new();
    let mut warm: Option<SlqSolution<RobotState>> = None;
    // The augmented Lagrangian's multipliers, updated after each stage and round and carried
    // knot for knot (same dt) into the next problem.
    let mut multipliers: Option<super::FeasibilityConstraints> = None;
    let mut limit_left = limit;
    if let Some(c) = &spec.continuation {
        if c.stage_iterations() >= limit {
            return Err(SolveError::IterationBudget { limit, stages: c.stage_iterations() });
        }
        limit_left -= c.stage_iterations();
        let start = [initial.q[0], initial.q[1], initial.q[2]];
        for (index, &horizon) in c.horizons.iter().enumerate() {
            let stage_spec = spec.continuation_stage(horizon, c.progress_exponent, start);
            let mut problem = stage_spec.problem(model, terrain, initial.clone(), origin)?;
            carry_multipliers(&mut problem, multipliers.as_ref());
            let report = |log: &IterationLog| on_iteration(SolveProgress { stage: Some((index, horizon)), log });
            let solution = match first.take() {
                // The kept start's screening is this stage's first iterations; it finishes
                // the rest (its report counts both, its time only the rest: the
                // exploration's time is counted apart).
                Some(kept) => {
                    let screened = StageReport::of(horizon, &kept);
                    let (solution, rest) = if kept.iterations.len() < c.iterations {
                        let solution = solve_from(&problem, settings(c.iterations - kept.iterations.len(), 0.0), Some(&kept), &standing, report)?;
                        let rest = StageReport::of(horizon, &solution);
                        (solution, Some(rest))
                    } else {
                        (kept, None)
                    };
                    stages.push(StageReport {
                        iterations: screened.iterations + rest.as_ref().map_or(0, |r| r.iterations),
                        termination: rest.as_ref().map_or(screened.termination.clone(), |r| r.termination.clone()),
                        final_cost: rest.as_ref().map_or(screened.final_cost, |r| r.final_cost),
                        time: rest.as_ref().map_or(0.0, |r| r.time),
                        ..screened
                    });
                    solution
                }
                None => {
                    let solution = solve_from(&problem, settings(c.iterations, 0.0), warm.as_ref(), &standing, report)?;
                    stages.push(StageReport::of(horizon, &solution));
                    solution
                }
            };
            problem.update_multipliers(&solution.states);
            multipliers = problem.feasibility.take();
            warm = Some(solution);
        }
    }

    let mut problem = spec.problem(model, terrain, initial.clone(), origin)?;
    carry_multipliers(&mut problem, multipliers.as_ref());
    if let Some(kept) = first.take() {
        limit_left = limit_left.saturating_sub(kept.iterations.len()).max(1);
        warm = Some(kept);
    }
    let flat_cost_tolerance = spec.flat_cost_tolerance.unwrap_or(SlqSettings::default().normalized_cost_tolerance);
    // The full horizon in augmented-Lagrangian rounds, the iterations left split among them:
    // each round from the last one's policy, its multipliers updated after it.
    let rounds_wanted = problem.feasibility.as_ref().map_or(1, |c| c.settings.outer_rounds.max(1)).min(limit_left.max(1));
    let mut rounds = Vec::new();
    let mut left = limit_left;
    let solution = loop {
        let round = rounds.len();
        let iterations = if round + 1 == rounds_wanted { left } else { (limit_left / rounds_wanted).max(1) };
        left = left.saturating_sub(iterations);
        let report = |log: &IterationLog| on_iteration(SolveProgress { stage: None, log });
        let solution = solve_from(&problem, settings(iterations, flat_cost_tolerance), warm.as_ref(), &standing, report)?;
        if round + 1 == rounds_wanted || left == 0 {
            break solution;
        }
        rounds.push(StageReport::of(spec.duration, &solution));
        problem.next_outer_round(&solution.states);
        warm = Some(solution);
    };
    // The polish: more rounds from the finished plan, the multipliers updated before each
    // at its violations of the polish's bounds (inside the targets'; and the penalties grown,
    // if the settings grow them), of at most `polish_share` of the iterations spent so far
    // in all. Unlike a split of the budget into rounds, the task's own solve is untouched
    // and its target kept as the starting point (docs/experiments/feasible-slq-3.md, -4.md).
    let spent = stages.iter().chain(&rounds).map(|s| s.iterations).sum::<usize>() + solution.iterations.len();
    let polish = problem.feasibility.as_ref().map_or(0, |c| (c.settings.polish_share * spent as f64).floor() as usize);
    let violated = |problem: &WholeBodyProblem<'_>, solution: &SlqSolution<RobotState>| problem.constraint_violation(&solution.states).is_some_and(|v| v.max() > 0.0);
    let mut solution = solution;
    if polish > 0 && violated(&problem, &solution) {
        let targets = problem.feasibility.as_ref().map(|c| c.settings);
        let polish_rounds = targets.map_or(1, |s| s.polish_rounds.max(1)).min(polish);
        if let Some(c) = problem.feasibility.as_mut() {
            c.settings = c.settings.with_polish_bounds();
            if c.settings.barrier_from_polish {
                c.start_barrier();
            }
            if c.settings.foot_speed_from_polish {
                c.start_foot_speed_rows();
            }
        }
        let mut left = polish;
        for round in 0..polish_rounds {
            if round > 0 && !violated(&problem, &solution) {
                break;
            }
            let iterations = if round + 1 == polish_rounds { left } else { polish / polish_rounds };
            left -= iterations;
            rounds.push(StageReport::of(spec.duration, &solution));
            problem.next_outer_round(&solution.states);
            let report = |log: &IterationLog| on_iteration(SolveProgress { stage: None, log });
            solution = solve_from(&problem, settings(iterations, flat_cost_tolerance), Some(&solution), &standing, report)?;
        }
        // The plan's violations are reported against the targets.
        if let (Some(c), Some(targets)) = (problem.feasibility.as_mut(), targets) {
            c.settings = targets;
        }
    }
    let violation = problem.constraint_violation(&solution.states);
    // The plan's cost under the task's own terms, without the feasibility constraints'
    // (whose multipliers differ from solve to solve): comparable between solves.
    let task_cost = {
        let mut plain = spec.problem(model, terrain, initial.clone(), origin)?;
        plain.feasibility = None;
        trajectory_cost(&plain, &solution.states, &solution.inputs)
    };
    Ok(Optimized { problem, solution, stages, rounds, violation, task_cost })
}

/// Solves `spec` for `model` on `terrain` (by horizon continuation if the task asks for
/// it; from an exploration's kept start if it asks for one) and re-runs it in closed loop;
/// `on_iteration` sees each SLQ iteration (of the kept start's solve, when two run).
pub fn solve_task(spec: &TaskSpec, model: &Model, terrain: &dyn Terrain, origin: &str, options: &SolveOptions, mut on_iteration: impl FnMut(SolveProgress) + Send) -> Result<TaskRun, SolveError> {
    let initial = settled_stance(model, terrain, 1.0).map_err(SolveError::Settle)?;
    let pd = JointPd::standing(model, spec.dt)?;
    let limit = options.max_iterations.or(spec.iterations).unwrap_or(SlqSettings::default().max_iterations);
    let threads = if options.threads == 0 { rayon::current_num_threads() } else { options.threads };
    let pipeline = Pipeline { spec, model, terrain, origin, initial: &initial, pd: &pd, limit, value_function: options.value_function };

    // Exploration (issue 19) on the first problem solved: the continuation's first stage,
    // or the full horizon. The kept start's solution is that problem's first solve.
    let exploration_spec = options.exploration.clone().or_else(|| spec.exploration.clone()).filter(|e| e.starts > 1 || e.sampling.is_some());
    let mut exploration: Option<ExplorationReport> = None;
    let mut kept: Option<SlqSolution<RobotState>> = None;
    if let Some(e) = &exploration_spec {
        // The kept start's screening is part of the first problem's iterations.
        let screening = e.screen_iterations * e.rounds;
        spec.exploration_budget(e, limit).map_err(|budget| SolveError::ExplorationBudget { screening, budget })?;
        let problem = pipeline.first_problem()?;
        let target = spec.target(model, origin)?;
        let scenario = format!("exploration of {}", spec.name);
        // Each start's plan judged against the task's targets (reported, not used to choose).
        let judge = |solution: &SlqSolution<RobotState>| !target.is_empty() && super::all_met(&target.check(model, &solution_trajectory(&problem, solution, &scenario), 1.0));
        let settings = SlqSettings { threads, ..SlqSettings::default() };
        let found = super::explore(&problem, &pd, e, &settings, threads, &judge)?;
        let iterations = found.starts.iter().map(|s| s.iterations).sum();
        exploration = Some(ExplorationReport { spec: e.clone(), starts: found.starts, best: found.best, time: found.time, iterations, single_start: None, screening_continued: true });
        kept = Some(found.solution);
    }
    let optimized = match (kept, &mut exploration) {
        // A perturbed or sampled start was kept: it and the single start (the standing PD's
        // own solve) are both taken to the end, side by side, and the lower task cost wins.
        (Some(kept), Some(report)) if report.best != 0 && report.spec.keep_single_start => {
            let started = std::time::Instant::now();
            let progress = std::sync::Mutex::new(&mut on_iteration);
            let explored_run = || optimize(&pipeline, threads.div_ceil(2), Some(kept), &mut |p| (progress.lock().unwrap_or_else(|e| e.into_inner()))(p));
            let single_run = || optimize(&pipeline, (threads / 2).max(1), None, &mut |_| ());
            let (explored, single) = if threads > 1 { rayon::join(explored_run, single_run) } else { (explored_run(), single_run()) };
            let (explored, single) = (explored?, single?);
            let single_wins = single.task_cost <= explored.task_cost;
            report.single_start = Some(SingleStartFinal { explored_task_cost: explored.task_cost, single_task_cost: single.task_cost, kept_single: single_wins, time: started.elapsed().as_secs_f64() });
            if single_wins {
                single
            } else {
                explored
            }
        }
        // Start 0 kept: the single start's own solve, as without exploration (its
        // screening is not continued: a warm restart ends elsewhere than the plain solve).
        (Some(_), Some(report)) if report.best == 0 => {
            report.screening_continued = false;
            optimize(&pipeline, threads, None, &mut on_iteration)?
        }
        (kept, _) => optimize(&pipeline, threads, kept, &mut on_iteration)?,
    };
    if let Some(report) = exploration.as_mut().filter(|r| r.single_start.as_ref().is_some_and(|f| f.kept_single)) {
        report.screening_continued = false;
    }
    let Optimized { problem, solution, stages, rounds, violation, task_cost } = optimized;
    let plan = solution_trajectory(&problem, &solution, &format!("solve {}", spec.name));

    // Closed loop, both from the optimizer's initial state, contact anchors (spring
    // pre-loads) included, in the robot's contact model, with the plan's joint stops: the
    // world the plan's file records (`Simulator::from_plan`, as `legwork simulate` replays it).
    let duration = problem.knots as f64 * problem.dt;
    let rerun = |controller: &mut dyn Controller, what: &'static str, config: SimConfig| -> Result<Rerun, SolveError> {
        let mut sim = Simulator::from_plan(model, terrain, &plan, config).map_err(|source| SolveError::ClosedLoop { what, source })?;
        Ok(match sim.run(duration, controller, |_| {}) {
            Ok(run) => {
                let mut trajectory = run.trajectory;
                trajectory.metadata.scenario = format!("{what}: {}", spec.name);
                let metrics = MotionMetrics::of(model, &trajectory, model.contact.friction);
                Rerun::Completed { trajectory: Box::new(trajectory), metrics: Box::new(metrics) }
            }
            Err(SimError::Diverged { step, t, reason, .. }) => Rerun::Failed { reason: format!("diverged at t = {t:.3} s (step {step}): {reason}") },
            Err(e) => Rerun::Failed { reason: e.to_string() },
        })
    };
    // (a) The SLQ gains are those of the discrete system the optimizer linearized: its
    // integration step (dt / substeps) as the physics step, the policy held over each knot
    // interval. At a finer physics step than the optimizer's, the stiff contact is a
    // different system at touch-down, for which the time-varying LQR gains are not made.
    let physics_dt = problem.dt / problem.substeps as f64;
    let policy_config = SimConfig { physics_dt, control_dt: problem.dt, record_dt: problem.dt, ..SimConfig::default() };
    let policy_rerun = rerun(&mut SlqPolicyController::new(&problem, &solution), "SLQ policy re-run", policy_config)?;
    // (b) The tracking controller at 1 kHz on the simulator's own 2 kHz physics.
    let config = SimConfig::default();
    let mut tracking = TrackingController::with_default_gains(model, &plan, config.control_dt)?;
    let tracking_rerun = rerun(&mut tracking, "tracking-controller re-run", config)?;
    let plan_metrics = MotionMetrics::of(model, &plan, model.contact.friction);
    Ok(TaskRun { plan, plan_metrics, policy_rerun, tracking_rerun, solution, stages, rounds, violation, task_cost, exploration })
}

/// `h(x_N) + sum_k l_k(x_k, u_k)` along a solution's own states and inputs.
fn trajectory_cost<P: Problem>(problem: &P, states: &[P::State], inputs: &[DVector<f64>]) -> f64 {
    let mut ws = problem.workspace();
    let mut next = problem.initial_state();
    let running: f64 = inputs.iter().enumerate().map(|(k, u)| problem.step(&mut ws, k, &states[k], u, &mut next)).sum();
    running + states.last().map_or(0.0, |x| problem.terminal_cost(&mut ws, x))
}

/// Gives `problem` the multipliers of the last stage's constraints, knot for knot.
fn carry_multipliers(problem: &mut WholeBodyProblem<'_>, from: Option<&super::FeasibilityConstraints>) {
    if let (Some(constraints), Some(from)) = (problem.feasibility.as_mut(), from) {
        constraints.carry_multipliers_from(from);
    }
}
