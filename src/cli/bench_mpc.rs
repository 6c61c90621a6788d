//! `legwork bench mpc` (issue 21): the receding-horizon controller's tick time against its
//! horizon and threads, and the closed-loop success of the embedded tasks, each also under
//! a lateral push, in legwork's simulator or in MuJoCo.

use super::outcome::{OrCouldNotFinish, Verdict};
use super::solve::job_error;
use anyhow::{bail, Result};
use legwork::export::MujocoCheck;
use legwork::job::mpc::{ClosedLoopOutcome, ClosedLoopSim, MpcJob};
use legwork::job::solve::{SolveJob, SolvedTask};
use legwork::mpc::{MpcSettings, PolicyLatency};
use legwork::ocp::{SolveOptions, TaskSpec, EMBEDDED_TASKS};
use legwork::sim::Push;
use serde_json::{json, Value};
use std::path::Path;

/// What `legwork bench mpc` runs (its flags).
pub struct MpcBench<'a> {
    /// Tasks (embedded names or files); empty: every embedded task.
    pub tasks: &'a [String],
    /// The task of the tick-time table.
    pub timing_task: &'a str,
    pub horizons: &'a [f64],
    pub thread_counts: &'a [usize],
    /// Lateral push of each task's pushed run (N; 0: no pushed runs), 0.2 s from the task's middle.
    pub push: f64,
    pub mujoco: bool,
    /// With `mujoco`: the controllers read the base lowered to legwork's contact depth.
    pub depth_matching: bool,
    pub latency: PolicyLatency,
    /// The tick-time table's latency: measured, or measured and paced on the wall clock.
    pub timing_latency: PolicyLatency,
    pub rate: f64,
    /// Knot spacing of every window (s; `None`: the tick period).
    pub knot_dt: Option<f64>,
    pub fine_head: Option<f64>,
    /// The coarse tail's knots in tick periods (`legwork mpc --tail-ticks`).
    pub tail_ticks: usize,
    pub substeps: Option<usize>,
    /// [`MpcSettings::prepare_ahead`].
    pub prepare_ahead: bool,
    /// Horizon of the task runs (s).
    pub horizon: f64,
    pub model_reuse: Option<legwork::slq::ModelReuse>,
    /// The contact anchors as states of the windows (with them, the windows end on the
    /// plan's value function; without, on the tracking cost's terminal weights).
    pub anchor_states: bool,
    /// Windows that end at the task's end, and their shortest length
    /// ([`legwork::mpc::MpcSettings::ends_at_task_end`]).
    pub ends_at_task_end: Option<f64>,
    /// Scale of the windows' tracking weights (1: the defaults).
    pub tracking: f64,
    /// The windows' tracking weights (the defaults times `tracking`, or with the base
    /// position's from `--tracking-base-position`).
    pub tracking_weights: legwork::mpc::TrackingWeights,
    /// What the robot's policy feeds back between ticks.
    pub feedback: legwork::mpc::MpcFeedback,
    /// SCHED_FIFO priority of the solvers' threads (`None`: the default scheduling).
    pub realtime_priority: Option<i32>,
    pub as_json: bool,
    pub out: &'a Path,
}

/// A task's plan, solved once for every closed loop on it (its value function kept).
struct Planned {
    spec: TaskSpec,
    origin: String,
    model: legwork::model::Model,
    solved: SolvedTask,
}

impl Planned {
    /// Solves `name`'s plan into `out/plan`.
    fn solve(name: &str, threads: usize, out: &Path) -> Result<Self> {
        let (spec, origin) = super::solve::load_task(name, &[])?;
        let model = spec.load_robot(&origin)?;
        let folder = out.join("plan");
        let job = SolveJob { spec: &spec, origin: &origin, model: &model, options: SolveOptions { threads, max_iterations: None, exploration: None, value_function: true }, mujoco: None, out: &folder, memory_limit: super::resources::memory_limit(), png: false };
        let solved = job.run(|_| ()).map_err(job_error)?;
        Ok(Self { spec, origin, model, solved })
    }

    /// One closed loop on the plan with `settings` and `pushes`, its folder `out`
    /// (`ControllerDidNotStart`: no closed loop, a missed row).
    fn closed_loop(&self, settings: MpcSettings, sim: &ClosedLoopSim, latency: PolicyLatency, pushes: Vec<Push>, out: &Path) -> Result<ClosedLoopOutcome> {
        let sim = sim.clone();
        let plan_out = out.join("plan");
        let job = MpcJob {
            solve: SolveJob { spec: &self.spec, origin: &self.origin, model: &self.model, options: SolveOptions { threads: settings.threads, max_iterations: None, exploration: None, value_function: true }, mujoco: None, out: &plan_out, memory_limit: super::resources::memory_limit(), png: false },
            settings,
            sim,
            latency,
            pushes,
            out,
        };
        job.try_run_on_plan(&self.solved, |_| ()).map_err(job_error)
    }
}

/// The row of one closed loop: its verdict, tick times and why it stopped; a controller
/// that could not start is a missed row without ticks.
fn row(outcome: &ClosedLoopOutcome) -> Value {
    let run = match outcome {
        ClosedLoopOutcome::Ran(run) => run,
        ClosedLoopOutcome::ControllerDidNotStart(e) => return json!({ "met": false, "stopped": e.message, "ticks": 0 }),
    };
    let s = &run.summary;
    json!({
        "met": run.verdict == Verdict::Met,
        "stopped": run.closed_loop.stopped,
        "ticks": s["ticks"],
        "failed_ticks": s["failed_ticks"],
        "held_ticks": s["held_ticks"],
        "ticks_over_period": s["ticks_over_period"],
        "tick_time_p50_s": s["tick_time_p50_s"],
        "tick_time_p99_s": s["tick_time_p99_s"],
        "full_window_ticks": s["full_window_ticks"],
        "tick_time_p50_full_window_s": s["tick_time_p50_full_window_s"],
        "tick_time_p99_full_window_s": s["tick_time_p99_full_window_s"],
        "tick_time_max_s": s["tick_time_max_s"],
        "latency_p50_s": s["latency_p50_s"],
        "latency_p99_s": s["latency_p99_s"],
        "target": s["target"]["mpc"],
    })
}

pub fn run(bench: &MpcBench<'_>) -> Result<Verdict> {
    if bench.horizons.iter().any(|h| !(h.is_finite() && *h > 0.0)) || bench.horizons.is_empty() {
        bail!("--horizons: expected positive seconds, got {:?}", bench.horizons);
    }
    if bench.thread_counts.contains(&0) || bench.thread_counts.is_empty() {
        bail!("--thread-counts: expected thread counts >= 1, got {:?}", bench.thread_counts);
    }
    if !(bench.push.is_finite() && bench.push >= 0.0) {
        bail!("--push: expected a force >= 0 N, got {}", bench.push);
    }
    // A missing MuJoCo environment is reported before the benchmark, not after it.
    let sim = if bench.mujoco { ClosedLoopSim::Mujoco { check: MujocoCheck::locate().or_could_not_finish()?, depth_matching: bench.depth_matching } } else { ClosedLoopSim::Legwork };
    let sim_name = if bench.mujoco { "MuJoCo" } else { "legwork" };
    let max_threads = *bench.thread_counts.iter().max().unwrap_or(&1);
    let base = MpcSettings { rate: bench.rate, knot_dt: bench.knot_dt, fine_head: bench.fine_head, tail_ticks: bench.tail_ticks, substeps: bench.substeps, prepare_ahead: bench.prepare_ahead, model_reuse: bench.model_reuse, anchor_states: bench.anchor_states, plan_value: bench.anchor_states, ends_at_task_end: bench.ends_at_task_end, feedback: bench.feedback, tracking: bench.tracking_weights.clone(), realtime_priority: bench.realtime_priority, ..MpcSettings::default() };
    // Every window of the benchmark checked against its task's robot before the first plan.
    for name in std::iter::once(bench.timing_task).chain(bench.tasks.iter().map(String::as_str)) {
        let (spec, origin) = super::solve::load_task(name, &[])?;
        let model = spec.load_robot(&origin)?;
        for &horizon in bench.horizons.iter().chain([&bench.horizon]) {
            MpcSettings { horizon, ..base.clone() }.check_for(&model).map_err(|e| anyhow::anyhow!("{name}: {e}"))?;
        }
    }

    // The tick time against horizon and threads, on one task, the latency measured (and the
    // ticks paced on the wall clock with --paced-timing).
    let timing_out = bench.out.join("timing");
    let timing_plan = Planned::solve(bench.timing_task, max_threads, &timing_out)?;
    let mut timing = Vec::new();
    for &horizon in bench.horizons {
        for &threads in bench.thread_counts {
            let settings = MpcSettings { horizon, threads, ..base.clone() };
            let folder = timing_out.join(format!("h{horizon}-t{threads}"));
            let outcome = timing_plan.closed_loop(settings, &sim, bench.timing_latency, Vec::new(), &folder)?;
            let mut r = row(&outcome);
            r["horizon_s"] = json!(horizon);
            r["threads"] = json!(threads);
            r["knots"] = match &outcome {
                ClosedLoopOutcome::Ran(run) => run.summary["knots"].clone(),
                ClosedLoopOutcome::ControllerDidNotStart(_) => Value::Null,
            };
            if !bench.as_json {
                let ms = |key: &str| r[key].as_f64().unwrap_or(f64::NAN) * 1e3;
                say!("tick time {} h {horizon} s, {threads} thread(s): p50 {:.2} ms, p99 {:.2} ms, max {:.2} ms ({} of {} ticks over the period); the {} ticks whose window lies within the task: p50 {:.2} ms, p99 {:.2} ms; latency p50 {:.2} ms, p99 {:.2} ms", timing_plan.spec.name, ms("tick_time_p50_s"), ms("tick_time_p99_s"), ms("tick_time_max_s"), r["ticks_over_period"], r["ticks"], r["full_window_ticks"], ms("tick_time_p50_full_window_s"), ms("tick_time_p99_full_window_s"), ms("latency_p50_s"), ms("latency_p99_s"));
            }
            timing.push(r);
        }
    }

    // Every task in closed loop, then again under the lateral push.
    let names: Vec<String> = if bench.tasks.is_empty() { EMBEDDED_TASKS.iter().map(|(n, _)| n.to_string()).collect() } else { bench.tasks.to_vec() };
    let mut tasks = Vec::new();
    for name in &names {
        // A task file's folder by its stem (`tasks/gallop.toml`: `gallop/`), not its path.
        let task_out = bench.out.join(std::path::Path::new(name).file_stem().unwrap_or(name.as_ref()));
        let plan = Planned::solve(name, max_threads, &task_out)?;
        let settings = MpcSettings { threads: max_threads, horizon: bench.horizon, ..base.clone() };
        let nominal = plan.closed_loop(settings.clone(), &sim, bench.latency, Vec::new(), &task_out.join("nominal"))?;
        let push = (bench.push > 0.0).then(|| Push { force: nalgebra::Vector3::new(0.0, bench.push, 0.0), start: 0.5 * plan.spec.duration, duration: 0.2 });
        let pushed = match push {
            Some(p) => Some(plan.closed_loop(settings, &sim, bench.latency, vec![p], &task_out.join("pushed"))?),
            None => None,
        };
        let plan_met = plan.solved.verdict == Verdict::Met;
        if !bench.as_json {
            let cell = |outcome: &ClosedLoopOutcome| match outcome {
                ClosedLoopOutcome::Ran(r) if r.verdict == Verdict::Met => "met".to_string(),
                ClosedLoopOutcome::Ran(r) => format!("MISSED{}", r.closed_loop.stopped.as_ref().map_or(String::new(), |s| format!(" ({})", s.split(':').next().unwrap_or("")))),
                ClosedLoopOutcome::ControllerDidNotStart(e) => format!("MISSED ({})", e.message),
            };
            say!("{name}: plan {}, closed loop {}, pushed {}", if plan_met { "met" } else { "MISSED" }, cell(&nominal), pushed.as_ref().map_or("-".to_string(), cell));
        }
        tasks.push(json!({
            "task": name,
            "plan_met": plan_met,
            "nominal": row(&nominal),
            "pushed": pushed.as_ref().map(row),
            "push": push.map(|p| json!({ "force_n": [p.force.x, p.force.y, p.force.z], "start_s": p.start, "duration_s": p.duration })),
        }));
    }
    let period = 1.0 / bench.rate;
    // The target row (0.5 s, two threads); not measured counts as missed.
    let p99_met = timing.iter().find(|r| r["horizon_s"] == json!(0.5) && r["threads"] == json!(2)).is_some_and(|r| r["tick_time_p99_full_window_s"].as_f64().is_some_and(|p| p <= period));
    let all_met = tasks.iter().all(|t| t["nominal"]["met"] == true && t["pushed"].get("met").is_none_or(|m| m == true));
    let verdict = Verdict::from_met(p99_met && all_met);
    let report = json!({
        "verdict": verdict.as_str(),
        "exit_code": verdict.exit_code(),
        "sim": sim_name,
        "rate_hz": bench.rate,
        "knot_dt_s": base.knot_dt(),
        "fine_head_s": base.fine_head,
        "substeps": base.substeps,
        "prepare_ahead": base.prepare_ahead,
        "tail_knot_dt_s": base.tail_knot_dt(),
        "model_reuse": base.model_reuse.map(|r| json!({ "fresh_head": r.fresh_head, "refresh_period": r.refresh_period })),
        "anchor_states": base.anchor_states,
        "plan_value": base.plan_value,
        "ends_at_task_end": base.ends_at_task_end,
        "feedback": base.feedback.name(),
        "tracking_scale": bench.tracking,
        "tracking": bench.tracking_weights,
        "realtime_priority": base.realtime_priority,
        "task_horizon_s": bench.horizon,
        "latency": bench.latency.to_json(),
        "timing_latency": bench.timing_latency.to_json(),
        "cpu": super::bench::cpu_name(),
        "timing_task": bench.timing_task,
        "timing": timing,
        "tasks": tasks,
    });
    std::fs::create_dir_all(bench.out)?;
    std::fs::write(bench.out.join("summary.json"), serde_json::to_string_pretty(&report)?)?;
    if bench.as_json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        say!("p99 tick time <= {:.1} ms at a 0.5 s horizon on 2 threads: {} (missed if not measured); closed loops met: {} of {}; wrote {}", period * 1e3, if p99_met { "met" } else { "MISSED" }, tasks.iter().map(|t| (t["nominal"]["met"] == true) as usize + (t["pushed"]["met"] == true) as usize).sum::<usize>(), tasks.iter().map(|t| 1 + t["pushed"].is_object() as usize).sum::<usize>(), bench.out.join("summary.json").display());
    }
    Ok(verdict)
}
