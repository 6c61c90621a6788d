//! `legwork solve <task>` and `legwork tasks`: Neunert 2017's trajectory optimization.

use super::outcome::{OrCouldNotFinish, Verdict};
use anyhow::Result;
use clap::Args;
use legwork::export::MujocoCheck;
use legwork::job::solve::SolveJob;
use legwork::ocp::{MotionMetrics, Rerun, Snapshot, SolveOptions, Target, TargetResult, TaskSpec, EMBEDDED_TASKS};
use std::path::PathBuf;
use std::time::Instant;

#[derive(Debug, Args)]
pub struct SolveArgs {
    /// An embedded task (`legwork tasks`) or a task file (`.toml`).
    task: String,
    /// The robot (embedded name, URDF or legwork description); default: the task's.
    #[arg(long)]
    robot: Option<String>,
    /// Output folder (created); default `out/<task>`.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Threads for the linearization (default: one per core).
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Overrides the task's iteration limit.
    #[arg(long)]
    iterations: Option<usize>,
    /// Explore: solve from this many initial control laws (the standing PD and perturbed
    /// ones) and keep the best; overrides the task's `[exploration] starts` (1: no
    /// exploration, unless the task has a sampling stage).
    #[arg(long)]
    starts: Option<usize>,
    /// Seed of the exploration's perturbations; overrides the task's `[exploration] seed`.
    #[arg(long)]
    seed: Option<u64>,
    /// Overrides one value of the task: `PATH=VALUE`, the path into the task file's tables
    /// (`input.weight`, `waypoint[0].desired.base_position[0]`), the value in TOML
    /// (`0.1`, `[2.0, "start", "start"]`). Repeatable.
    #[arg(long = "set", value_name = "PATH=VALUE")]
    set: Vec<String>,
    /// Also write every plot as PNG (2x, text in the embedded DejaVu Sans) beside its SVG.
    #[arg(long)]
    png: bool,
    /// After the solve and legwork's re-runs, check the plan in another simulator:
    /// `mujoco` replays it in MuJoCo with the tracking controller and with the exported
    /// feedback policy (needs `scripts/install-mujoco.sh`), two more columns.
    #[arg(long, value_enum)]
    check: Option<CheckSimulator>,
}

/// Simulators a plan can be checked in.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum CheckSimulator {
    /// MuJoCo 4.0.0 (Python package in `.venv-mujoco/`), default contact, 1 ms step.
    Mujoco,
}

/// The task argument (an embedded name or a `.toml` file) with `--set` overrides applied,
/// and where it came from.
pub(super) fn load_task(spec: &str, set: &[String]) -> Result<(TaskSpec, String)> {
    let overrides = set
        .iter()
        .map(|item| {
            let (path, value) = item.split_once('=').ok_or_else(|| anyhow::anyhow!("--set {item}: expected PATH=VALUE, e.g. input.weight=0.1"))?;
            // A TOML value on its own: parsed as the right-hand side of a key.
            let table: toml::Table = toml::from_str(&format!("value = {value}")).map_err(|e| anyhow::anyhow!("--set {item}: the value is not TOML ({}): quote strings", e.message()))?;
            Ok((path.trim().to_string(), table["value"].clone()))
        })
        .collect::<Result<Vec<_>>>()?;
    let (text, origin) = TaskSpec::text_of(spec)?;
    Ok((TaskSpec::from_toml_with_overrides(&text, &origin, &overrides)?, origin))
}

/// `legwork tasks`: one line per embedded task.
pub fn list() -> Result<()> {
    let width = EMBEDDED_TASKS.iter().map(|(n, _)| n.len()).max().unwrap_or(0);
    for (name, _) in EMBEDDED_TASKS {
        let spec = TaskSpec::embedded(name)?;
        say!("{name:<width$}  {} ({}, {} s)", spec.summary, spec.robot, spec.duration);
    }
    Ok(())
}

pub(super) use legwork::job::solve::{metrics_json, rerun_json};

/// The exit code's verdict: the plan meets the task's `[[target]]` (and, with `--check
/// mujoco`, both MuJoCo runs meet it at twice the tolerances); a task without a target is
/// met when the solve and its re-runs ran.
pub fn run(args: SolveArgs) -> Result<Verdict> {
    let (spec, origin) = load_task(&args.task, &args.set)?;
    // The robot: --robot's, or the task's own (an error then names the task file).
    let model = match &args.robot {
        Some(robot) => super::robot::load(robot)?.0,
        None => spec.load_robot(&origin)?,
    };
    if args.iterations == Some(0) {
        anyhow::bail!("--iterations: expected at least 1 SLQ iteration, got 0");
    }
    let exploration = exploration_override(&spec, args.starts, args.seed)?;
    let out = args.out.clone().unwrap_or_else(|| PathBuf::from("out").join(&spec.name));
    let job = SolveJob {
        spec: &spec,
        origin: &origin,
        model: &model,
        options: SolveOptions { threads: super::capped_threads(args.threads), max_iterations: args.iterations, exploration, value_function: false },
        mujoco: None,
        out: &out,
        memory_limit: super::resources::memory_limit(),
        png: args.png,
    };
    job.check().map_err(job_error)?;
    // A missing MuJoCo environment is reported before the solve, not after it.
    let mujoco = match args.check {
        Some(CheckSimulator::Mujoco) => Some(MujocoCheck::locate().or_could_not_finish()?),
        None => None,
    };
    let job = SolveJob { mujoco: mujoco.as_ref(), ..job };
    say!("Solving {} ({}) for {}: {} s, {} knots of {} s", spec.name, spec.summary, model.name, spec.duration, spec.knots(), spec.dt);
    let started = Instant::now();
    let solved = job
        .run(|progress| {
            let log = progress.log;
            let t = &log.timing;
            if let (Some((index, horizon)), 1) = (progress.stage, log.iteration) {
                say!("  continuation stage {} on {horizon} s:", index + 1);
            } else if let (None, 1, Some(_)) = (progress.stage, log.iteration, &spec.continuation) {
                say!("  full horizon, {} s:", spec.duration);
            }
            say!(
                "  iteration {:2}  cost {:11.5e}  step {:<9}  |l| {:9.3e}  {:6.1} ms (linearize {:5.1}, backward {:5.1}, line search {:5.1})",
                log.iteration,
                log.cost,
                if log.alpha > 0.0 { format!("{:.4}", log.alpha) } else { "rejected".into() },
                log.feedforward_norm,
                (t.linearization + t.backward_pass + t.line_search) * 1e3,
                t.linearization * 1e3,
                t.backward_pass * 1e3,
                t.line_search * 1e3
            );
        })
        .map_err(job_error)?;
    let (run, verdict) = (&solved.run, solved.verdict);
    let (sol, solve_time, plan, traj) = (&run.solution, run.solve_time(), &run.plan_metrics, &solved.trajectory);
    let checked = &solved.checked;
    let mujoco_reruns = &solved.mujoco;
    if let Some(e) = &run.exploration {
        let rounds = if e.spec.rounds > 1 { format!("{} rounds of {} SLQ iterations, the cheaper half going on each round", e.spec.rounds, e.spec.screen_iterations) } else { format!("{} SLQ iterations each", e.spec.screen_iterations) };
        say!("exploration: {} starts (seed {}), {rounds}, {} iterations in all, {:.2} s; kept start {} (cost {:.4e})", e.starts.len(), e.spec.seed, e.iterations, e.time, e.best, e.starts[e.best].cost);
        for s in &e.starts {
            let how = match &s.outcome {
                Ok(t) => format!("{t:?}"),
                Err(err) => format!("could not start: {err}"),
            };
            let met = match s.met {
                Some(true) => "target met",
                Some(false) => "target missed",
                None => "",
            };
            let sampled = s.sampled_cost.map_or(String::new(), |c| format!(" (sampled, rollout cost {c:.4e})"));
            say!("  start {:3}{sampled}: cost {:11.4e} -> {:11.4e} in {:3} iterations ({} round(s)), {:6.2} s, {how} {met}", s.index, s.initial_cost, s.cost, s.iterations, s.rounds, s.time);
        }
    }
    if let Some(f) = run.exploration.as_ref().and_then(|e| e.single_start.as_ref()) {
        say!("kept start and single start solved to the end side by side in {:.2} s: task cost {:.4e} (kept start) vs {:.4e} (single start); the {} plan is returned", f.time, f.explored_task_cost, f.single_task_cost, if f.kept_single { "single start's" } else { "kept start's" });
    }
    for (i, stage) in run.stages.iter().enumerate() {
        say!("continuation stage {} on {} s: {:?} after {} iterations in {:.2} s (cost {:.4e} -> {:.4e})", i + 1, stage.horizon, stage.termination, stage.iterations, stage.time, stage.initial_cost, stage.final_cost);
    }
    for (i, round) in run.rounds.iter().enumerate() {
        say!("augmented-Lagrangian round {} on the full horizon: {:?} after {} iterations in {:.2} s (cost {:.4e} -> {:.4e})", i + 1, round.termination, round.iterations, round.time, round.initial_cost, round.final_cost);
    }
    if let Some(v) = &run.violation {
        say!("largest constraint violations: friction {:.3} m g, penetration {:.3} p_max, joint limit {:.4} rad, joint speed {:.3} v_max, foot speed {:.3}", v.friction, v.penetration, v.joint_limit, v.joint_speed, v.foot_speed);
    }
    let stages_note = if run.stages.is_empty() && run.rounds.is_empty() { String::new() } else { format!(" ({} in the last round on the full horizon)", sol.iterations.len()) };
    say!("{:?} after {} iterations{stages_note} in {:.2} s (cost {:.4e} -> {:.4e}; the task's own terms, without the feasibility constraints': {:.4e})", sol.termination, run.iterations(), solve_time, sol.cost_history[0], sol.cost_history.last().unwrap_or(&f64::NAN), run.task_cost);
    let mut columns = vec![
        Column::completed("plan", plan, traj),
        Column::of("SLQ policy", &run.policy_rerun),
        Column::of("tracking ctrl", &run.tracking_rerun),
    ];
    if let Some(m) = &mujoco_reruns {
        columns.push(Column::of("MuJoCo track", &m.tracking));
        columns.push(Column::of("MuJoCo policy", &m.policy));
    }
    print_figures(&model, &spec.waypoints.iter().map(|w| w.time).collect::<Vec<_>>(), &columns);
    print_target(&solved.target, checked, mujoco_reruns.is_some(), verdict);
    say!("Wrote {} (trajectory.json, closed-loop re-runs, replay.html, {} plots) in {:.1} s", out.display(), solved.plots, started.elapsed().as_secs_f64());
    Ok(verdict)
}

/// The target's checks, one row each with a column per run, and the verdict.
fn print_target(target: &Target, checked: &[(&str, Option<Vec<TargetResult>>)], mujoco: bool, verdict: Verdict) {
    if target.is_empty() {
        say!("Target: none declared (a task file's [[target]] entries say what counts as done); exit code 0 means the solve and its re-runs ran.");
        return;
    }
    let plan = checked[0].1.as_deref().unwrap_or_default();
    say!("Target (the plan; the runs at twice the tolerances):");
    let what = plan.iter().map(|r| r.what.len() + r.required.len() + 3).max().unwrap_or(0);
    let cell = |results: &Option<Vec<TargetResult>>, i: usize| results.as_ref().map_or("failed".to_string(), |rs| format!("{} {}", rs[i].value, if rs[i].met { "ok" } else { "MISSED" }));
    // Columns as wide as their widest cell, at least 16 characters, two spaces apart.
    let width = checked.iter().flat_map(|(name, results)| std::iter::once(name.len()).chain((0..plan.len()).map(|i| cell(results, i).len()))).max().unwrap_or(0).max(14) + 2;
    let header: String = checked.iter().map(|(name, _)| format!("{name:<width$}")).collect();
    say!("  {:<what$} {}", "", header.trim_end());
    for (i, r) in plan.iter().enumerate() {
        let cells: String = checked.iter().map(|(_, results)| format!("{:<width$}", cell(results, i))).collect();
        say!("  {:<what$} {}", format!("{} ({})", r.what, r.required), cells.trim_end());
    }
    let whose = if mujoco { "the plan and both MuJoCo runs" } else { "the plan" };
    match verdict {
        Verdict::Met => say!("Target met by {whose} (exit code 0)."),
        Verdict::Missed => say!("TARGET MISSED: {whose} must meet every check above (exit code {}).", verdict.exit_code()),
    }
}

/// One column of the figures table: a plan or a re-run, or why a re-run failed.
pub(super) struct Column<'a> {
    pub name: &'a str,
    pub metrics: Option<&'a MotionMetrics>,
    pub trajectory: Option<&'a legwork::io::Trajectory>,
    pub failure: Option<&'a str>,
}

impl<'a> Column<'a> {
    pub fn completed(name: &'a str, metrics: &'a MotionMetrics, trajectory: &'a legwork::io::Trajectory) -> Self {
        Self { name, metrics: Some(metrics), trajectory: Some(trajectory), failure: None }
    }
    pub fn of(name: &'a str, rerun: &'a Rerun) -> Self {
        match rerun {
            Rerun::Completed { trajectory, metrics } => Self::completed(name, metrics, trajectory),
            Rerun::Failed { reason } => Self { name, metrics: None, trajectory: None, failure: Some(reason) },
        }
    }
}

/// The task figures of each column side by side, the state at each waypoint time, and
/// why any re-run failed.
pub(super) fn print_figures(model: &legwork::model::Model, waypoints: &[f64], columns: &[Column]) {
    // The rows first, then each column as wide as its widest cell.
    let mut rows: Vec<(&str, Vec<String>)> = Vec::new();
    let mut row = |name: &'static str, f: &dyn Fn(&MotionMetrics) -> String| rows.push((name, columns.iter().map(|c| c.metrics.map_or("failed".to_string(), f)).collect()));
    row("final base x [m]", &|m| format!("{:.3}", m.final_base_position[0]));
    row("final base y [m]", &|m| format!("{:.3}", m.final_base_position[1]));
    row("final yaw [deg]", &|m| format!("{:.1}", m.final_base_rpy_deg[2]));
    row("apex height [m]", &|m| format!("{:.4}", m.apex_base_height));
    row("apex pitch [deg]", &|m| format!("{:.1}", m.apex_pitch_deg));
    row("feet down at apex", &|m| m.apex_in_contact.iter().map(|&c| if c { "1" } else { "0" }).collect::<String>());
    row("flight time [s]", &|m| format!("{:.3}", m.flight_time));
    row("lift-offs per foot", &|m| m.liftoffs.iter().map(|l| l.to_string()).collect::<Vec<_>>().join("/"));
    row("all feet down [%]", &|m| format!("{:.0}", 100.0 * m.all_feet_down));
    row("first lift-off [s]", &|m| m.first_liftoff_time.map_or("none".into(), |t| format!("{t:.2}")));
    row("off ground last 2 s [%]", &|m| m.off_ground_final_2s.iter().map(|f| format!("{:.0}", 100.0 * f)).collect::<Vec<_>>().join("/"));
    row("foot slide [mm]", &|m| m.slide.iter().map(|s| format!("{:.0}", s * 1e3)).collect::<Vec<_>>().join("/"));
    let pairs = |c: &[Option<f64>; 2]| c.iter().map(|c| c.map_or("-".into(), |c| format!("{c:.2}"))).collect::<Vec<String>>().join("/");
    row("diagonal correlation", &|m| pairs(&m.diagonal_correlation));
    row("lateral correlation", &|m| pairs(&m.lateral_correlation));
    row("past joint limit [deg]", &|m| m.joint_limit_excess.as_ref().map_or("none".into(), |e| format!("{:.0} {}", e.excess_deg, e.joint.trim_end_matches("_joint"))));
    row("max |tau| / limit", &|m| format!("{:.3}", m.feasibility.max_torque_ratio));
    row("knots at torque limit [%]", &|m| format!("{:.1}", 100.0 * m.feasibility.knots_at_torque_limit));
    row("max |v| / limit", &|m| format!("{:.2}", m.feasibility.max_joint_velocity_ratio));
    row("max friction |Ft|/Fn", &|m| format!("{:.3}", m.feasibility.max_friction_ratio));
    row("loaded over 0.75 mu [%]", &|m| format!("{:.1}", 100.0 * m.feasibility.friction_margin_excess));
    row("loaded sliding [%]", &|m| m.feasibility.sliding_share.iter().map(|s| format!("{:.0}", 100.0 * s)).collect::<Vec<_>>().join("/"));
    row("max penetration [mm]", &|m| format!("{:.1}", 1e3 * m.feasibility.max_penetration));
    let label = rows.iter().map(|(n, _)| n.len()).max().unwrap_or(0);
    let widths: Vec<usize> = (0..columns.len()).map(|c| rows.iter().map(|(_, cells)| cells[c].len()).chain([columns[c].name.len()]).max().unwrap_or(0) + 2).collect();
    let line = |name: &str, cells: &mut dyn Iterator<Item = &str>| {
        let text: String = cells.zip(&widths).map(|(cell, w)| format!("{cell:<w$}", w = *w)).collect();
        say!("  {name:<label$} {}", text.trim_end());
    };
    line("", &mut columns.iter().map(|c| c.name));
    for (name, cells) in &rows {
        line(name, &mut cells.iter().map(String::as_str));
    }
    for &time in waypoints {
        say!("  at the waypoint t = {time:.2} s:");
        for c in columns {
            let text = c.trajectory.map_or("failed".to_string(), |traj| {
                let s = Snapshot::at(model, traj, time);
                let feet: String = s.in_contact.iter().map(|&c| if c { '1' } else { '0' }).collect();
                let foot_positions: Vec<String> = s.feet.iter().map(|p| format!("({:.2}, {:.2}, {:.2})", p[0], p[1], p[2])).collect();
                format!("z {:.3}, rpy ({:.1}, {:.1}, {:.1}), feet down {feet} at {}", s.base_position[2], s.base_rpy_deg[0], s.base_rpy_deg[1], s.base_rpy_deg[2], foot_positions.join(" "))
            });
            say!("    {:<18}  {text}", c.name);
        }
    }
    for c in columns {
        if let Some(reason) = c.failure {
            say!("  {} failed: {reason}", c.name);
        }
    }
}

/// The task's `[exploration]` with `--starts` / `--seed` over it (the defaults if the task
/// has none); `None` when neither asks for one.
fn exploration_override(spec: &TaskSpec, starts: Option<usize>, seed: Option<u64>) -> Result<Option<legwork::ocp::ExplorationSpec>> {
    if spec.exploration.is_none() && starts.is_some() {
        if let Some(c) = &spec.continuation {
            say!("exploring the first continuation stage: {} SLQ iterations per start (the stage's)", c.iterations);
        }
    }
    legwork::job::solve::exploration_override(spec, starts, seed, "--starts").map_err(job_error)
}

/// A job's error for the command line: exit code 3 when the job could not finish, else 2.
pub(super) fn job_error(e: legwork::job::JobError) -> anyhow::Error {
    match e.kind {
        legwork::job::JobErrorKind::CouldNotFinish => anyhow::Error::new(super::outcome::CouldNotFinish(anyhow::Error::msg(e.message))),
        legwork::job::JobErrorKind::BadInput => anyhow::Error::msg(e.message),
    }
}
