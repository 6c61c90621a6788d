//! The solve job (`legwork solve`, Python's `legwork.solve`): Neunert 2017's SLQ on a task,
//! the closed-loop re-runs, the MuJoCo check if asked, the task's targets on every run, and
//! the folder of files: `trajectory.json` (plan, gains, summary), the re-runs,
//! `replay.html` and the plots.

use super::resources::{check_memory, MemoryLimit};
use super::{JobError, OrCouldNotFinish, Verdict};
use crate::export::{check_plan_in_mujoco, MujocoCheck, MujocoReruns};
use crate::io::Trajectory;
use crate::model::Model;
use crate::ocp::{all_met, solve_task, ExplorationReport, ExplorationSpec, MotionMetrics, Rerun, SolveError, SolveOptions, SolveProgress, Target, TargetResult, TaskRun, TaskSpec};
use crate::slq::{SlqError, SlqSettings};
use crate::terrain::{Plane, Terrain};
use serde_json::json;
use std::path::Path;

/// A solve to run: the task, its robot, the solver's options and where the files go.
pub struct SolveJob<'a> {
    pub spec: &'a TaskSpec,
    /// Where the task came from (a path, `embedded task NAME`), for messages.
    pub origin: &'a str,
    pub model: &'a Model,
    /// Threads, iteration limit, exploration (see [`exploration_override`]).
    pub options: SolveOptions,
    /// Also replay the plan in MuJoCo (tracking controller and exported policy).
    pub mujoco: Option<&'a MujocoCheck>,
    /// The output folder (created).
    pub out: &'a Path,
    pub memory_limit: MemoryLimit<'a>,
    /// Also write each plot as PNG (`--png`).
    pub png: bool,
}

/// A finished solve and what it wrote.
pub struct SolvedTask {
    pub run: TaskRun,
    pub target: Target,
    /// The target's checks: the plan's at its tolerances, each re-run's at twice them
    /// (`None`: the re-run failed), named as the summary names them.
    pub checked: Vec<(&'static str, Option<Vec<TargetResult>>)>,
    pub mujoco: Option<MujocoReruns>,
    pub verdict: Verdict,
    /// The plan as written to `trajectory.json`, its `summary` filled.
    pub trajectory: Trajectory,
    /// Plots written (SVG files in `plots/`, `cost.svg` among them).
    pub plots: usize,
}

/// The task's `[exploration]` with `starts` / `seed` over it (the defaults if the task has
/// none); `None` when neither is given. `starts_setting` names the setting in messages
/// (`--starts`, `starts=`).
pub fn exploration_override(spec: &TaskSpec, starts: Option<usize>, seed: Option<u64>, starts_setting: &str) -> Result<Option<ExplorationSpec>, JobError> {
    if starts.is_none() && seed.is_none() {
        return Ok(None);
    }
    let mut e = match (&spec.exploration, &spec.continuation) {
        (Some(e), _) => e.clone(),
        // The first continuation stage is the explored problem: its iterations are the
        // screening's budget.
        (None, Some(c)) => ExplorationSpec { screen_iterations: c.iterations, ..Default::default() },
        (None, None) => ExplorationSpec::default(),
    };
    e.starts = starts.unwrap_or(e.starts);
    e.seed = seed.unwrap_or(e.seed);
    // Only `starts` can be out of range here (the file's own fields were checked on reading).
    e.validate().map_err(|(field, problem)| if field == "starts" { JobError::bad_input(format!("{starts_setting}: {problem}")) } else { JobError::bad_input(format!("[exploration] {field}: {problem}")) })?;
    Ok(Some(e))
}

impl SolveJob<'_> {
    /// The exploration the solve will run (`options`' over the task's), if any.
    fn exploration(&self) -> Option<&ExplorationSpec> {
        self.options.exploration.as_ref().or(self.spec.exploration.as_ref()).filter(|e| e.starts > 1 || e.sampling.is_some())
    }

    /// What can be refused before any work: an iteration limit of 0, a screening that does
    /// not fit the iteration budget, a solve over the memory limit.
    pub fn check(&self) -> Result<(), JobError> {
        if self.options.max_iterations == Some(0) {
            return Err(JobError::bad_input("iterations: expected at least 1 SLQ iteration, got 0"));
        }
        if let Some(e) = self.exploration() {
            let limit = self.options.max_iterations.or(self.spec.iterations).unwrap_or(SlqSettings::default().max_iterations);
            self.spec.exploration_budget(e, limit).map_err(|budget| {
                JobError::bad_input(format!(
                    "{}: the exploration's screening ({} x {} SLQ iterations) does not fit in {budget}; raise the iteration limit or lower [exploration] screen_iterations or rounds",
                    self.origin, e.screen_iterations, e.rounds
                ))
            })?;
        }
        let threads = if self.options.threads == 0 { rayon::current_num_threads() } else { self.options.threads };
        check_memory(
            &format!("{}: {} knots ({} s at dt {} s){}", self.origin, self.spec.knots(), self.spec.duration, self.spec.dt, self.exploration().map_or(String::new(), |e| format!(", {} starts", e.starts))),
            self.spec.estimated_memory_bytes_exploring(self.exploration(), threads),
            "shorten the task's duration, lengthen its dt, or explore from fewer starts",
            self.memory_limit,
        )
    }

    /// Solves, re-runs, checks the targets and writes the folder; `on_iteration` sees every
    /// SLQ iteration (of each continuation stage and round).
    pub fn run(&self, on_iteration: impl FnMut(SolveProgress) + Send) -> Result<SolvedTask, JobError> {
        self.check()?;
        let (spec, model, out) = (self.spec, self.model, self.out);
        let target = spec.target(model, self.origin).map_err(JobError::bad_input)?;
        let terrain = Plane::flat(0.0);
        let run = solve_task(spec, model, &terrain, self.origin, &self.options, on_iteration).map_err(|e| match e {
            // The task's own numbers, found wanting once the robot is known: its input.
            SolveError::Task(_) | SolveError::IterationBudget { .. } => JobError::bad_input(e),
            SolveError::Slq(SlqError::InitialRolloutDiverged { .. }) => JobError::bad_input(format!(
                "{}: the robot falls before the optimization starts: with the task's dt = {} s the standing PD, its input held over each knot interval, does not keep it up; try a shorter dt (the embedded tasks use 0.002 s): {e}",
                self.origin, spec.dt
            )),
            e => JobError::could_not_finish(e),
        })?;
        std::fs::create_dir_all(out).map_err(|e| JobError::could_not_finish(format!("cannot create the output folder {}: {e}", out.display())))?;
        // MuJoCo: the plan as solved, on the ground it was solved on, the robot's friction.
        let mujoco = match self.mujoco {
            Some(check) => Some(check_plan_in_mujoco(check, model, &run.plan, &terrain.spec(), &out.join("mujoco")).or_could_not_finish()?),
            None => None,
        };
        // The target: on the plan, and at twice the tolerances on every run of it.
        let rerun_results = |r: &Rerun| match r {
            Rerun::Completed { trajectory, .. } => Some(target.check(model, trajectory, 2.0)),
            Rerun::Failed { .. } => None,
        };
        let mut checked: Vec<(&'static str, Option<Vec<TargetResult>>)> = vec![("plan", Some(target.check(model, &run.plan, 1.0))), ("SLQ policy", rerun_results(&run.policy_rerun)), ("tracking ctrl", rerun_results(&run.tracking_rerun))];
        if let Some(m) = &mujoco {
            checked.push(("MuJoCo track", rerun_results(&m.tracking)));
            checked.push(("MuJoCo policy", rerun_results(&m.policy)));
        }
        let met = |name: &str| checked.iter().find(|(n, _)| *n == name).and_then(|(_, r)| r.as_deref()).is_some_and(all_met);
        let verdict = if target.is_empty() { Verdict::Met } else { Verdict::from_met(met("plan") && (mujoco.is_none() || (met("MuJoCo track") && met("MuJoCo policy")))) };
        let mut trajectory = run.plan.clone();
        if let serde_json::Value::Object(map) = summary(spec, model, &run, &checked, mujoco.as_ref(), verdict) {
            trajectory.summary = map;
        }
        let plots = write_files(spec, model, &run, &trajectory, out, self.png).or_could_not_finish()?;
        Ok(SolvedTask { run, target, checked, mujoco, verdict, trajectory, plots })
    }
}

/// `trajectory.json`, the re-runs, `replay.html` and the plots (and their PNGs); returns
/// the number of plots.
fn write_files(spec: &TaskSpec, model: &Model, run: &TaskRun, trajectory: &Trajectory, out: &Path, png: bool) -> Result<usize, Box<dyn std::error::Error + Send + Sync>> {
    trajectory.save_file(out.join("trajectory.json"))?;
    for (rerun, file) in [(&run.policy_rerun, "rerun_slq_policy.json"), (&run.tracking_rerun, "rerun_tracking.json")] {
        if let Rerun::Completed { trajectory, .. } = rerun {
            trajectory.save_file(out.join(file))?;
        }
    }
    crate::viz::write_replay(model, trajectory, out.join("replay.html"))?;
    let plots = out.join("plots");
    let mut written = crate::viz::write_plots(trajectory, &plots)?;
    written.extend(crate::viz::write_limit_plots(model, trajectory, &plots)?);
    crate::viz::write_cost_plot(&run.solution.cost_history, &format!("{}: normalized cost per SLQ iteration", spec.name), plots.join("cost.svg"))?;
    written.push(plots.join("cost.svg"));
    if png {
        crate::viz::png::write_pngs(&written, crate::viz::png::PNG_SCALE)?;
    }
    Ok(written.len())
}

pub fn metrics_json(m: &MotionMetrics) -> serde_json::Value {
    serde_json::to_value(m).unwrap_or(serde_json::Value::Null)
}

pub fn rerun_json(r: &Rerun) -> serde_json::Value {
    match r {
        Rerun::Completed { metrics, .. } => metrics_json(metrics),
        Rerun::Failed { reason } => json!({ "failed": reason }),
    }
}

/// The summary `trajectory.json` carries: the verdict, the target checks, the solver's
/// figures and the task figures of the plan and of every re-run.
fn summary(spec: &TaskSpec, model: &Model, run: &TaskRun, checked: &[(&str, Option<Vec<TargetResult>>)], mujoco: Option<&MujocoReruns>, verdict: Verdict) -> serde_json::Value {
    let sol = &run.solution;
    let mut summary = json!({
        "task": spec.name,
        "verdict": verdict.as_str(),
        "exit_code": verdict.exit_code(),
        "target": checked.iter().map(|(name, results)| (name.to_string(), results.as_ref().map_or(json!("failed"), |r| json!(r)))).collect::<serde_json::Map<_, _>>(),
        "robot": model.name,
        "knots": spec.knots(),
        "dt_s": spec.dt,
        "iterations": run.iterations(),
        "termination": format!("{:?}", sol.termination),
        "continuation_stages": run.stages.iter().map(|s| json!({ "horizon_s": s.horizon, "iterations": s.iterations, "termination": format!("{:?}", s.termination), "initial_cost": s.initial_cost, "final_cost": s.final_cost, "solve_time_s": s.time })).collect::<Vec<_>>(),
        "augmented_lagrangian_rounds": run.rounds.iter().map(|s| json!({ "iterations": s.iterations, "termination": format!("{:?}", s.termination), "initial_cost": s.initial_cost, "final_cost": s.final_cost, "solve_time_s": s.time })).collect::<Vec<_>>(),
        "exploration": run.exploration.as_ref().map(exploration_json),
        "constraint_violation": run.violation,
        "task_cost": run.task_cost,
        "initial_cost": sol.cost_history[0],
        "final_cost": sol.cost_history.last(),
        "solve_time_s": run.solve_time(),
        "mean_iteration_ms": if sol.iterations.is_empty() { 0.0 } else { sol.iterations.iter().map(|l| l.timing.linearization + l.timing.backward_pass + l.timing.line_search).sum::<f64>() / sol.iterations.len() as f64 * 1e3 },
        "plan": metrics_json(&run.plan_metrics),
        "slq_policy_rerun": rerun_json(&run.policy_rerun),
        "tracking_controller_rerun": rerun_json(&run.tracking_rerun),
    });
    if let (Some(m), serde_json::Value::Object(map)) = (mujoco, &mut summary) {
        map.insert("mujoco_version".into(), json!(m.version));
        map.insert("mujoco_tracking_controller".into(), rerun_json(&m.tracking));
        map.insert("mujoco_policy".into(), rerun_json(&m.policy));
    }
    summary
}

fn exploration_json(e: &ExplorationReport) -> serde_json::Value {
    json!({
        "starts": e.starts.len(),
        "seed": e.spec.seed,
        "screen_iterations": e.spec.screen_iterations,
        "rounds": e.spec.rounds,
        "sampling": e.spec.sampling.as_ref().map(|s| json!({ "population": s.population, "elite": s.elite, "iterations": s.iterations, "knot_interval_s": s.knot_interval, "setpoint_std_rad": s.setpoint_std, "torque_std": s.torque_std, "starts": s.starts })),
        "kept_start": e.best,
        "screening_continued": e.screening_continued,
        "single_start_final": e.single_start.as_ref().map(|f| json!({ "kept_start_task_cost": f.explored_task_cost, "single_start_task_cost": f.single_task_cost, "returned": if f.kept_single { "single start" } else { "kept start" }, "time_s": f.time })),
        "iterations": e.iterations,
        "time_s": e.time,
        "per_start": e.starts.iter().map(|s| json!({
            "index": s.index,
            "seed": s.seed,
            "sampled_rollout_cost": s.sampled_cost,
            "initial_cost": s.initial_cost,
            "cost": s.cost,
            "iterations": s.iterations,
            "rounds": s.rounds,
            "outcome": match &s.outcome { Ok(t) => format!("{t:?}"), Err(e) => e.to_string() },
            "time_s": s.time,
            "finished_at_s": s.finished_at,
            "target_met": s.met,
        })).collect::<Vec<_>>(),
    })
}
