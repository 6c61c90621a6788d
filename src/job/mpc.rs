//! The receding-horizon job (`legwork mpc`): the task's plan (the solve job, its folder in
//! `plan/`), then the task in closed loop under [`crate::mpc`] in legwork's simulator or in
//! MuJoCo ([`crate::export::MujocoPlant`], its files in `mujoco/`), with pushes if asked;
//! the task's targets on the closed-loop motion at twice their tolerances (as every re-run
//! of a plan), and the folder: `trajectory.json` (the closed-loop motion
//! and the summary), `summary.json`, `ticks.json` (every tick), `replay.html` and the plots
//! (`plots/tick_times.svg` the per-tick solve times).

use super::solve::{metrics_json, SolveJob, SolvedTask};
use super::{JobError, OrCouldNotFinish, Verdict};
use crate::io::Trajectory;
use crate::mpc::{run_closed_loop, window_problem, ClosedLoopRun, Mpc, MpcSettings, PolicyLatency, TickRecord};
use crate::ocp::{all_met, MotionMetrics, SolveProgress, TargetResult};
use crate::export::{MujocoCheck, MujocoPlant};
use crate::sim::{Push, SimConfig, Simulator};
use crate::terrain::Plane;
use serde_json::json;

/// The physics the closed loop runs in.
#[derive(Clone, Debug)]
pub enum ClosedLoopSim {
    /// legwork's simulator: the optimizer's own world.
    Legwork,
    /// MuJoCo through the checker's Python (physics nobody on the team wrote);
    /// `depth_matching`: the controllers read the base lowered to legwork's contact depth
    /// ([`MujocoPlant::set_depth_matching`]).
    Mujoco { check: MujocoCheck, depth_matching: bool },
}

/// A closed-loop run to make: the plan's solve job (its `out` is the plan's folder), the
/// controller's settings, the physics, the pushes and where the files go.
pub struct MpcJob<'a> {
    pub solve: SolveJob<'a>,
    pub settings: MpcSettings,
    pub sim: ClosedLoopSim,
    pub latency: PolicyLatency,
    pub pushes: Vec<Push>,
    pub out: &'a std::path::Path,
}

/// A finished closed-loop run and what it wrote.
pub struct MpcRun {
    pub closed_loop: ClosedLoopRun,
    /// The closed-loop motion's figures (`None` if it stopped early).
    pub metrics: Option<MotionMetrics>,
    /// The task's target on the closed-loop motion at twice its tolerances (`None`: it stopped early).
    pub checked: Option<Vec<TargetResult>>,
    pub verdict: Verdict,
    pub summary: serde_json::Value,
}

impl MpcJob<'_> {
    /// What can be refused before any work: the plan's checks, the controller's settings.
    pub fn check(&self) -> Result<(), JobError> {
        self.settings.check_for(self.solve.model).map_err(JobError::bad_input)?;
        if let PolicyLatency::Fixed(l) = self.latency {
            if !(l.is_finite() && l >= 0.0) {
                return Err(JobError::bad_input(format!("latency: expected a finite number of seconds >= 0, got {l}")));
            }
        }
        self.solve.check()
    }

    /// Solves the plan, runs the closed loop, checks the targets and writes the folder;
    /// `on_iteration` sees the plan's SLQ iterations, `on_tick` every tick.
    pub fn run(&self, on_iteration: impl FnMut(SolveProgress) + Send, on_tick: impl FnMut(&TickRecord)) -> Result<(SolvedTask, MpcRun), JobError> {
        self.check()?;
        let plan = self.solve.run(on_iteration)?;
        let run = self.run_on_plan(&plan, on_tick)?;
        Ok((plan, run))
    }

    /// The closed loop on a plan already solved by this job's solve job (its value
    /// function recorded, [`crate::ocp::SolveOptions::value_function`]): one plan, several
    /// controllers or pushes (`legwork bench mpc`). A controller that could not start is
    /// this job's error ([`ClosedLoopOutcome::ControllerDidNotStart`]).
    pub fn run_on_plan(&self, plan: &SolvedTask, on_tick: impl FnMut(&TickRecord)) -> Result<MpcRun, JobError> {
        match self.try_run_on_plan(plan, on_tick)? {
            ClosedLoopOutcome::Ran(run) => Ok(*run),
            ClosedLoopOutcome::ControllerDidNotStart(e) => Err(e),
        }
    }

    /// [`Self::run_on_plan`], telling a controller that could not start (its first window's
    /// iterations failed: no closed loop ran, nothing written) from the errors that stop a
    /// benchmark (bad settings, the plant, the files).
    pub fn try_run_on_plan(&self, plan: &SolvedTask, on_tick: impl FnMut(&TickRecord)) -> Result<ClosedLoopOutcome, JobError> {
        self.check()?;
        let (spec, model, origin) = (self.solve.spec, self.solve.model, self.solve.origin);
        let terrain = Plane::flat(0.0);
        let solution = &plan.run.solution;
        let problem = window_problem(spec, model, &terrain, solution, spec.dt, &self.settings, origin).map_err(JobError::bad_input)?;
        let mpc = match Mpc::new(&problem, solution, spec.dt, self.settings.clone()) {
            Ok(mpc) => mpc,
            Err(e) => return Ok(ClosedLoopOutcome::ControllerDidNotStart(JobError::could_not_finish(ControllerDidNotStart(e)))),
        };
        // The robot's world at the window's integration step (1 ms), the policy applied every
        // step: the gains are those of that discrete system (as the plan's SLQ-policy re-run;
        // at 0.5 ms physics the stiff contact is another system at touch-down, and the
        // gallop's closed loop spun a free leg past 200 rad/s within 0.4-2 s).
        let step = problem.dt / problem.substeps as f64;
        let config = SimConfig { physics_dt: step, control_dt: step, ..SimConfig::default() };
        let mut closed_loop = match &self.sim {
            ClosedLoopSim::Legwork => {
                let mut sim = Simulator::from_plan(model, &terrain, &plan.run.plan, config).or_could_not_finish()?;
                for push in &self.pushes {
                    sim.add_push(*push);
                }
                run_closed_loop(mpc, &mut sim, spec.duration, self.latency, on_tick).or_could_not_finish()?
            }
            ClosedLoopSim::Mujoco { check, depth_matching } => {
                let mut plant = MujocoPlant::from_plan(check, model, &terrain, &plan.run.plan, config, &self.out.join("mujoco")).or_could_not_finish()?;
                plant.set_depth_matching(*depth_matching);
                for push in &self.pushes {
                    plant.add_push(*push);
                }
                run_closed_loop(mpc, &mut plant, spec.duration, self.latency, on_tick).or_could_not_finish()?
            }
        };
        closed_loop.trajectory.metadata.scenario = format!("mpc {} at {} Hz, {} s horizon", spec.name, self.settings.rate, self.settings.horizon);
        let (metrics, checked) = match closed_loop.stopped {
            None => (Some(MotionMetrics::of(model, &closed_loop.trajectory, model.contact.friction)), Some(plan.target.check(model, &closed_loop.trajectory, 2.0))),
            Some(_) => (None, None),
        };
        let met = checked.as_deref().is_some_and(all_met);
        let verdict = if plan.target.is_empty() && closed_loop.stopped.is_none() { Verdict::Met } else { Verdict::from_met(met) };
        let summary = summary(self, plan, &closed_loop, metrics.as_ref(), checked.as_deref(), verdict);
        let mut run = MpcRun { closed_loop, metrics, checked, verdict, summary };
        write_files(self, model, &mut run).or_could_not_finish()?;
        Ok(ClosedLoopOutcome::Ran(Box::new(run)))
    }
}

/// How a closed loop on a plan ended ([`MpcJob::try_run_on_plan`]).
pub enum ClosedLoopOutcome {
    /// It ran (to the task's end or until the motion diverged): met or missed (boxed: the
    /// run is a thousand bytes, the other variant a message).
    Ran(Box<MpcRun>),
    /// The controller's first window could not be solved from the plan
    /// ([`crate::mpc::Mpc::new`]); the error says why (exit code 3 for `legwork mpc`).
    ControllerDidNotStart(JobError),
}

/// [`ClosedLoopOutcome::ControllerDidNotStart`]'s error: the controller's, with its cause.
#[derive(Debug, thiserror::Error)]
#[error("the receding-horizon controller could not start")]
struct ControllerDidNotStart(#[source] crate::mpc::MpcError);

/// Every tick's solve time, a failed tick's too (it held the solver as long).
fn tick_times(ticks: &[TickRecord]) -> Vec<f64> {
    ticks.iter().map(|t| t.solve_time).collect()
}

/// The summary: the verdict, the tick times, the closed loop's target checks and figures
/// beside the plan's.
fn summary(job: &MpcJob<'_>, plan: &SolvedTask, run: &ClosedLoopRun, metrics: Option<&MotionMetrics>, checked: Option<&[TargetResult]>, verdict: Verdict) -> serde_json::Value {
    use crate::mpc::closed_loop::percentile;
    let s = &job.settings;
    let times = tick_times(&run.ticks);
    // The ticks whose window lies within the task, its whole horizon long (a window that
    // ends at the task's end is shorter after them, [`crate::mpc::MpcSettings::ends_at_task_end`],
    // and its ticks cheaper): the figure for a tick time "with a horizon of h".
    let full_window: Vec<f64> = run.ticks.iter().filter(|t| t.t + s.horizon <= job.solve.spec.duration + 1e-9).map(|t| t.solve_time).collect();
    let period = s.period();
    let mut summary = json!({
        "task": job.solve.spec.name,
        "robot": job.solve.model.name,
        "verdict": verdict.as_str(),
        "exit_code": verdict.exit_code(),
        "sim": match &job.sim { ClosedLoopSim::Legwork => json!("legwork"), ClosedLoopSim::Mujoco { check, .. } => json!(format!("MuJoCo {}", check.version().unwrap_or_default())) },
        "mujoco_depth_matching": matches!(job.sim, ClosedLoopSim::Mujoco { depth_matching: true, .. }),
        "horizon_s": s.horizon,
        "rate_hz": s.rate,
        "knot_dt_s": s.knot_dt(),
        "knots": s.knot_counts().0 + s.knot_counts().1,
        "fine_head_s": s.fine_head,
        "tail_knots": s.knot_counts().1,
        "tail_knot_dt_s": s.tail_knot_dt(),
        "iterations_per_tick": s.iterations_per_tick,
        "model_reuse": s.model_reuse.map(|r| json!({ "fresh_head": r.fresh_head, "refresh_period": r.refresh_period })),
        "threads": s.threads,
        "realtime_priority": s.realtime_priority,
        "anchor_states": s.anchor_states,
        "ends_at_task_end": s.ends_at_task_end.map_or(json!(false), |shortest| json!({ "shortest_window_s": shortest })),
        "feedback": s.feedback.name(),
        "tracking": s.tracking,
        "latency": job.latency.to_json(),
        "pushes": job.pushes.iter().map(|p| json!({ "force_n": [p.force.x, p.force.y, p.force.z], "start_s": p.start, "duration_s": p.duration })).collect::<Vec<_>>(),
        "ticks": run.ticks.len(),
        "failed_ticks": run.ticks.iter().filter(|t| t.failure.is_some()).count(),
        "restarted_ticks": run.ticks.iter().filter(|t| t.restarted).count(),
        "held_ticks": run.ticks.iter().filter(|t| t.held_after_knot.is_some()).count(),
        "ticks_over_period": times.iter().filter(|t| **t > period).count(),
        "tick_time_p50_s": percentile(times.clone(), 50.0),
        "tick_time_p99_s": percentile(times.clone(), 99.0),
        "tick_time_max_s": percentile(times.clone(), 100.0),
        "full_window_ticks": full_window.len(),
        // None without such ticks (a task shorter than the window).
        "tick_time_p50_full_window_s": (!full_window.is_empty()).then(|| percentile(full_window.clone(), 50.0)),
        "tick_time_p99_full_window_s": (!full_window.is_empty()).then(|| percentile(full_window.clone(), 99.0)),
        "tick_time_mean_s": if times.is_empty() { 0.0 } else { times.iter().sum::<f64>() / times.len() as f64 },
        "stopped": run.stopped,
        "target": {
            "plan": plan.checked.iter().find(|(n, _)| *n == "plan").and_then(|(_, r)| r.as_ref()).map_or(json!("failed"), |r| json!(r)),
            "mpc": checked.map_or(json!("failed"), |r| json!(r)),
        },
        "plan": metrics_json(&plan.run.plan_metrics),
        "mpc": metrics.map_or(json!({ "failed": run.stopped }), metrics_json),
        "plan_solve_time_s": plan.run.solve_time(),
    });
    // Beside the macro's object: one more key would pass its recursion limit.
    summary["substeps"] = json!(s.knot_substeps(job.solve.model.contact.max_step));
    summary["prepare_ahead"] = json!(s.prepare_ahead);
    // What the robot waited for: from a tick's time to its policy (the feedback phase and
    // any wait for the last preparation, or the fixed latency).
    let latencies: Vec<f64> = run.ticks.iter().map(|t| t.latency).collect();
    summary["latency_p50_s"] = json!(percentile(latencies.clone(), 50.0));
    summary["latency_p99_s"] = json!(percentile(latencies, 99.0));
    summary["feedback_time_p50_s"] = json!(percentile(run.ticks.iter().map(|t| t.feedback_time).collect(), 50.0));
    summary
}

/// `trajectory.json`, `summary.json`, `ticks.json`, `replay.html` and the plots.
fn write_files(job: &MpcJob<'_>, model: &crate::model::Model, run: &mut MpcRun) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
    let out = job.out;
    std::fs::create_dir_all(out)?;
    let trajectory: &mut Trajectory = &mut run.closed_loop.trajectory;
    if let serde_json::Value::Object(map) = &run.summary {
        trajectory.summary = map.clone();
    }
    trajectory.save_file(out.join("trajectory.json"))?;
    std::fs::write(out.join("summary.json"), serde_json::to_string_pretty(&run.summary)?)?;
    std::fs::write(out.join("ticks.json"), serde_json::to_string(&run.closed_loop.ticks)?)?;
    crate::viz::write_replay(model, trajectory, out.join("replay.html"))?;
    let plots = out.join("plots");
    let mut written = crate::viz::write_plots(trajectory, &plots)?;
    written.extend(crate::viz::write_limit_plots(model, trajectory, &plots)?);
    let title = format!("{}: MPC at {} Hz, {} s horizon", job.solve.spec.name, job.settings.rate, job.settings.horizon);
    crate::viz::mpc::write_tick_time_histogram(&tick_times(&run.closed_loop.ticks), job.settings.period(), &title, plots.join("tick_times.svg"))?;
    written.push(plots.join("tick_times.svg"));
    if job.solve.png {
        crate::viz::png::write_pngs(&written, crate::viz::png::PNG_SCALE)?;
    }
    Ok(())
}
