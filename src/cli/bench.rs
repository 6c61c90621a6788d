//! `legwork bench slq`: the solver's speed as the paper's Fig. 13 (time per iteration against
//! the number of knots, which must be linear) and every embedded task solved in full.
//! `legwork bench terrain`: Winkler 2015's Table I (forward speed and success rate per
//! terrain) over randomized walk trials, beside the paper's.
//! `legwork bench mpc`: the receding-horizon controller (`super::bench_mpc`).

use anyhow::{bail, Context, Result};
use clap::Subcommand;
use legwork::export::MujocoCheck;
use legwork::job::solve::SolveJob;
use legwork::viz::report::{escape, find_runs, write_report, ReportSection};
use legwork::model::embedded;
use legwork::ocp::{settled_stance, PdPolicy, SolveOptions, TaskSpec, EMBEDDED_TASKS};
use legwork::slq::{Slq, SlqSettings};
use legwork::terrain::Plane;
use legwork::report::walk::{paper_result, terrain_benchmark, TerrainBenchmark, TrialReport, TABLE_I, TARGET_SPEED_FACTOR, TARGET_SUCCESS_RATE};
use legwork::walk::trial::WalkConfig;
use legwork::walk::{ScenarioSpec, EMBEDDED_SCENARIOS};
use super::outcome::{OrCouldNotFinish, Verdict};
use serde_json::json;

// Parsed once from the command line: the size of its largest variant costs nothing.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Subcommand)]
pub enum BenchCommand {
    /// SLQ: time per iteration against knots (HyQ), and every embedded task solved.
    Slq {
        /// Print the results as JSON.
        #[arg(long)]
        json: bool,
        /// Threads for the linearization (default: one per core).
        #[arg(long, default_value_t = 0)]
        threads: usize,
        /// Iterations timed per horizon.
        #[arg(long, default_value_t = 5)]
        iterations: usize,
        /// Also check every solved task in MuJoCo (tracking controller and feedback
        /// policy; needs `scripts/install-mujoco.sh`); the runs go to `<out>/<task>/mujoco`.
        #[arg(long, value_enum)]
        check: Option<super::solve::CheckSimulator>,
        /// Output folder: each task's solve folder (as `legwork solve` writes it) and
        /// `report.html` (the scaling table and every task's targets, figures and replay).
        #[arg(long, default_value = "out/bench/slq")]
        out: std::path::PathBuf,
    },
    /// Winkler 2015's Table I: randomized walk trials over the paper's four terrains
    /// (start +-5 cm, yaw +-5 deg, map noise), speed and success beside the paper's.
    Terrain {
        /// Trials per terrain (seeds 1..=N).
        #[arg(long, default_value_t = 10)]
        trials: usize,
        /// Print the results as JSON.
        #[arg(long)]
        json: bool,
        /// Trials run at once (default: one per core). Planning times are wall-clock, so
        /// more trials than cores inflate them.
        #[arg(long, default_value_t = 0)]
        threads: usize,
        /// Scenarios, comma-separated (embedded names or .toml files); `all` = every embedded
        /// scenario. Default: the paper's four terrains.
        #[arg(long, value_delimiter = ',', value_name = "NAMES")]
        scenarios: Vec<String>,
        /// Output folder: `report.html` (the paper's Table I beside legwork's, every trial)
        /// and `summary.json` (the benchmark as --json prints it).
        #[arg(long, default_value = "out/bench/terrain")]
        out: std::path::PathBuf,
    },
    /// Receding-horizon SLQ (issue 21): tick time against horizon and threads (the latency
    /// measured), then every task in closed loop and again under a lateral push.
    Mpc {
        /// Tasks, comma-separated (embedded names or .toml files; default: every embedded task).
        #[arg(long, value_delimiter = ',', value_name = "NAMES")]
        tasks: Vec<String>,
        /// The task of the tick-time table.
        #[arg(long, default_value = "sidestep")]
        timing_task: String,
        /// Horizons of the tick-time table (s), comma-separated.
        #[arg(long, value_delimiter = ',', default_values_t = [0.25, 0.5, 1.0])]
        horizons: Vec<f64>,
        /// Thread counts of the tick-time table, comma-separated; the task runs use the largest.
        #[arg(long, value_delimiter = ',', default_values_t = [1, 2])]
        thread_counts: Vec<usize>,
        /// Lateral force (N, +y) of each task's pushed run, for 0.2 s from the task's middle; 0: no pushed runs.
        #[arg(long, default_value_t = 100.0)]
        push: f64,
        /// Ticks per second.
        #[arg(long, default_value_t = 200.0)]
        rate: f64,
        /// Knot spacing of every window (s); default the tick period.
        #[arg(long)]
        knot_dt: Option<f64>,
        /// The windows' first seconds in knots of --knot-dt, the rest in knots of --tail-ticks
        /// tick periods (`legwork mpc --fine-head`).
        #[arg(long)]
        fine_head: Option<f64>,
        /// The knots after --fine-head in tick periods, 1 or 2 (`legwork mpc --tail-ticks`).
        #[arg(long, default_value_t = 1)]
        tail_ticks: usize,
        /// Integration steps per window knot (`legwork mpc --substeps`).
        #[arg(long)]
        substeps: Option<usize>,
        /// Run each whole tick after its measurement (`legwork mpc --no-prepare-ahead`).
        #[arg(long)]
        no_prepare_ahead: bool,
        /// Horizon of the task runs (s).
        #[arg(long, default_value_t = 0.5)]
        horizon: f64,
        /// Keep most knots' models from tick to tick, HEAD,PERIOD (`legwork mpc --reuse-models`).
        #[arg(long, value_name = "HEAD,PERIOD")]
        reuse_models: Option<String>,
        /// Windows linearized without the contact anchors as states, ending on the tracking
        /// cost's terminal weights (`legwork mpc --no-anchor-states --no-plan-value`).
        #[arg(long)]
        no_anchor_states: bool,
        /// Keep the windows' length past the task's end (`legwork mpc --window-past-end`).
        #[arg(long)]
        window_past_end: bool,
        /// Scale of the windows' tracking weights (`legwork mpc --tracking`).
        #[arg(long, default_value_t = 1.0)]
        tracking: f64,
        /// The windows' base-position tracking weights along x, y, z before `--tracking`
        /// (`legwork mpc --tracking-base-position`).
        #[arg(long, value_name = "X,Y,Z")]
        tracking_base_position: Option<String>,
        /// What the robot's policy feeds back between ticks (`legwork mpc --feedback`).
        #[arg(long, value_enum, default_value_t = super::mpc::FeedbackChoice::Optimizer)]
        feedback: super::mpc::FeedbackChoice,
        /// The task runs' latency: `measured` (the solve's wall time), `paced` (measured, each
        /// tick at its time on the wall clock) or seconds.
        #[arg(long, default_value = "measured")]
        latency: String,
        /// The physics of the closed loops.
        #[arg(long, value_enum, default_value_t = super::mpc::SimChoice::Legwork)]
        sim: super::mpc::SimChoice,
        /// With `--sim mujoco`: the controllers read MuJoCo's state as measured
        /// (`legwork mpc --measured-depth`).
        #[arg(long)]
        measured_depth: bool,
        /// The solvers' threads under SCHED_FIFO at this priority (`legwork mpc
        /// --realtime-priority`).
        #[arg(long, value_name = "PRIORITY")]
        realtime_priority: Option<i32>,
        /// The tick-time table's ticks each at its time on the wall clock, as a robot's
        /// control loop (`--latency paced`), instead of back to back.
        #[arg(long)]
        paced_timing: bool,
        /// Print the results as JSON.
        #[arg(long)]
        json: bool,
        /// Output folder: every closed loop's folder (as `legwork mpc` writes it) and `summary.json`.
        #[arg(long, default_value = "out/bench/mpc")]
        out: std::path::PathBuf,
    },
    /// Nguyen 2022's Table I beside legwork's: phase timings, contact-timing and full-body
    /// solve times, landing error and success rate, one row per embedded jump.
    Jumps {
        /// Print the results as JSON.
        #[arg(long)]
        json: bool,
        /// Contact-timing solves per jump (the median and the fastest are reported).
        #[arg(long, default_value_t = 3)]
        repeats: usize,
        /// Overrides the knots per phase `N_i` (the paper's 30).
        #[arg(long)]
        knots: Option<usize>,
        /// Robustness trials per jump after the nominal re-run (issue 17: 20).
        #[arg(long, default_value_t = 20)]
        trials: usize,
        /// Jumps, comma-separated (default: the seven embedded ones).
        #[arg(long, value_delimiter = ',', value_name = "NAMES")]
        jumps: Vec<String>,
        /// The contact timing's and the full body's barrier update (monotone, probing,
        /// quality-function, loqo; default: the pipeline's).
        #[arg(long, value_name = "RULE")]
        barrier_contact_timing: Option<legwork::ipocp::BarrierUpdate>,
        #[arg(long, value_name = "RULE")]
        barrier_full_body: Option<legwork::ipocp::BarrierUpdate>,
        /// The full body's barrier update in its curvature phase (default: as the rest).
        #[arg(long, value_name = "RULE")]
        barrier_curvature: Option<legwork::ipocp::BarrierUpdate>,
        /// Threads of the full body's stage evaluations and of the trials (0: one per core,
        /// the default; 1: sequential), as `legwork jump --threads`.
        #[arg(long, default_value_t = 0)]
        threads: usize,
    },
}

/// `legwork bench jumps`.
fn jumps(as_json: bool, repeats: usize, knots: Option<usize>, trials: usize, names: &[String], barriers: [Option<legwork::ipocp::BarrierUpdate>; 3], threads: usize) -> Result<Verdict> {
    if repeats == 0 {
        bail!("--repeats: expected at least one solve per jump, got 0");
    }
    super::check_trials(trials)?;
    let jumps = if names.is_empty() { legwork::jump::embedded_jumps()? } else { names.iter().map(|n| legwork::jump::Jump::load(n.trim())).collect::<Result<Vec<_>, _>>()? };
    let bar = indicatif::ProgressBar::with_draw_target(Some(jumps.len() as u64), indicatif::ProgressDrawTarget::stderr());
    bar.set_style(indicatif::ProgressStyle::with_template("{msg:30} [{bar:30}] {pos}/{len} jumps ({elapsed})").expect("static template"));
    let mut rows = Vec::new();
    for jump in &jumps {
        bar.set_message(jump.name.clone());
        let model = embedded::load(&jump.robot)?;
        let settings = super::jump::settings_of(jump, knots)?;
        let mut options = legwork::jump::PipelineOptions { contact_timing: settings, trials, ..legwork::jump::PipelineOptions::of(jump) };
        if let Some(rule) = barriers[0] {
            options.contact_timing_solver.barrier_update = rule;
        }
        if let Some(rule) = barriers[1] {
            options.full_body.solver.barrier_update = rule;
        }
        if barriers[2].is_some() {
            options.full_body.curvature_barrier_update = barriers[2];
        }
        rows.push(legwork::job::jump::with_threads(threads, &mut options, |options| legwork::jump::bench_jump(jump, &model, options, repeats).map_err(legwork::job::JobError::could_not_finish)).map_err(super::solve::job_error)?);
        bar.inc(1);
    }
    bar.finish_and_clear();
    let verdict = Verdict::from_met(rows.iter().all(|r| r.meets_targets()));
    if as_json {
        let meets: Vec<bool> = rows.iter().map(|r| r.meets_targets()).collect();
        say!("{}", serde_json::to_string_pretty(&json!({ "repeats": repeats, "trials": trials, "cpu": cpu_name(), "jumps": rows, "meets_targets": meets, "verdict": verdict.as_str(), "exit_code": verdict.exit_code() }))?);
        return Ok(verdict);
    }
    let opt = |x: Option<f64>, d: usize| x.map_or("-".to_string(), |x| format!("{x:.d$}"));
    let list = |v: &[f64]| v.iter().map(|x| format!("{x:.1}")).collect::<Vec<_>>().join(", ");
    say!("Nguyen 2022, Table I, against legwork ({repeats} contact-timing solves per jump, median; {trials} trials per jump; CPU: {})", cpu_name());
    say!("  {:<19} | {:>17} {:>6} {:>5} | {:>17} {:>7} {:>7} {:>6} {:>8} {:>8} {:>8}", "", "paper", "", "", "legwork", "", "", "", "", "", "");
    say!("  {:<19} | {:>17} {:>6} {:>5} | {:>17} {:>7} {:>7} {:>6} {:>8} {:>8} {:>8}", "jump", "T_i [10 ms]", "CT [s]", "FB [s]", "T_i [10 ms]", "CT [s]", "FB [s]", "limits", "land [mm]", "yaw [deg]", "success");
    for r in &rows {
        let (pt, pct, pfb) = r.paper.as_ref().map_or(("-".into(), "-".into(), "-".into()), |p| (list(&p.timings_10ms), format!("{:.2}", p.contact_timing_s), format!("{:.0}", p.full_body_s)));
        say!(
            "  {:<19} | {:>17} {:>6} {:>5} | {:>17} {:>7.3} {:>7} {:>6} {:>8} {:>8} {:>8}",
            r.jump,
            pt,
            pct,
            pfb,
            list(&r.phase_durations_10ms),
            r.contact_timing_median_s,
            opt(r.full_body_solve_s, 3),
            r.full_body_limits_met.map_or("-", |m| if m { "met" } else { "broken" }),
            opt(r.landing_error_m.map(|e| 1e3 * e), 1),
            opt(r.yaw_error_deg, 2),
            r.success_rate.map_or(r.landed.map_or("-".to_string(), |l| if l { "nominal".into() } else { "missed".into() }), |s| format!("{:.0}%", 100.0 * s))
        );
    }
    for r in &rows {
        for n in &r.notes {
            say!("  {}: {n}", r.jump);
        }
    }
    say!("  targets: contact timing at most 0.1 s per jump, full body at most 1 s within every limit; 20 trials per jump, success = upright, within 5 cm and 5 deg of the target");
    let missed: Vec<&str> = rows.iter().filter(|r| !r.meets_targets()).map(|r| r.jump.as_str()).collect();
    say_verdict(verdict, &missed);
    Ok(verdict)
}

/// The benchmark's verdict line: which rows missed their targets, and the exit code.
fn say_verdict(verdict: Verdict, missed: &[&str]) {
    match verdict {
        Verdict::Met => say!("Targets met by every row (exit code 0)."),
        Verdict::Missed => say!("TARGETS MISSED by {} (exit code {}).", missed.join(", "), verdict.exit_code()),
    }
}

/// The CPU's model name (Linux), for the record.
pub(super) fn cpu_name() -> String {
    std::fs::read_to_string("/proc/cpuinfo").ok().and_then(|s| s.lines().find(|l| l.starts_with("model name")).and_then(|l| l.split(':').nth(1)).map(|s| s.trim().to_string())).unwrap_or_else(|| "unknown".into())
}

/// The exit code's verdict: met when every row of the table meets its targets.
pub fn run(cmd: BenchCommand) -> Result<Verdict> {
    match cmd {
        BenchCommand::Jumps { json, repeats, knots, trials, jumps: names, barrier_contact_timing, barrier_full_body, barrier_curvature, threads } => jumps(json, repeats, knots, trials, &names, [barrier_contact_timing, barrier_full_body, barrier_curvature], super::capped_threads(threads)),
        BenchCommand::Slq { json, threads, iterations, check, out } => slq(json, super::capped_threads(threads), iterations, check.is_some(), &out),
        BenchCommand::Terrain { trials, json, threads, scenarios, out } => terrain(trials, json, super::capped_threads(threads), &scenarios, &out),
        BenchCommand::Mpc { tasks, timing_task, horizons, thread_counts, push, rate, knot_dt, fine_head, tail_ticks, substeps, no_prepare_ahead, horizon, reuse_models, no_anchor_states, window_past_end, tracking, tracking_base_position, feedback, latency, sim, measured_depth, realtime_priority, paced_timing, json, out } => {
            let thread_counts: Vec<usize> = thread_counts.iter().map(|&t| super::capped_threads(t)).collect();
            super::mpc::check_measured_depth(measured_depth, sim)?;
            super::mpc::check_realtime_priority(realtime_priority)?;
            let latency = super::mpc::parse_latency(&latency)?;
            super::bench_mpc::run(&super::bench_mpc::MpcBench { tasks: &tasks, timing_task: &timing_task, horizons: &horizons, thread_counts: &thread_counts, push, mujoco: sim == super::mpc::SimChoice::Mujoco, depth_matching: !measured_depth, latency, timing_latency: if paced_timing { legwork::mpc::PolicyLatency::Paced } else { legwork::mpc::PolicyLatency::Measured }, rate, knot_dt, fine_head, tail_ticks, substeps, prepare_ahead: !no_prepare_ahead, horizon, model_reuse: reuse_models.as_deref().map(super::mpc::parse_model_reuse).transpose()?, anchor_states: !no_anchor_states, ends_at_task_end: if window_past_end { None } else { legwork::mpc::MpcSettings::default().ends_at_task_end }, tracking, tracking_weights: super::mpc::tracking_weights(tracking, tracking_base_position.as_deref())?, feedback: feedback.into(), realtime_priority, as_json: json, out: &out })
        }
    }
}

/// The scenarios of `legwork bench terrain --scenarios`.
fn terrain_scenarios(names: &[String]) -> Result<Vec<ScenarioSpec>> {
    let names: Vec<String> = match names {
        [] => TABLE_I.iter().map(|p| p.scenario.to_string()).collect(),
        [all] if all == "all" => EMBEDDED_SCENARIOS.iter().map(|(n, _)| n.to_string()).collect(),
        names => names.to_vec(),
    };
    names.iter().map(|n| ScenarioSpec::resolve(n.trim()).map_err(Into::into)).collect()
}

fn terrain(trials: usize, as_json: bool, threads: usize, names: &[String], out: &std::path::Path) -> Result<Verdict> {
    if trials == 0 {
        bail!("--trials: expected at least one trial per terrain, got 0");
    }
    super::check_trials(trials)?;
    let scenarios = terrain_scenarios(names)?;
    let robots: Vec<&str> = scenarios.iter().map(|s| s.robot.as_str()).collect();
    if let Some(other) = robots.iter().find(|r| **r != robots[0]) {
        bail!("--scenarios: every scenario must use one robot, got {} and {other}", robots[0]);
    }
    let model = embedded::load(robots[0])?;
    let config = WalkConfig::hyq(&model).with_context(|| format!("cannot set up the walk for robot {}", model.name))?;
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().context("cannot start the trial threads")?;
    let total = trials * scenarios.len();
    let bar = indicatif::ProgressBar::with_draw_target(Some(total as u64), indicatif::ProgressDrawTarget::stderr());
    bar.set_style(indicatif::ProgressStyle::with_template("{msg:30} [{bar:30}] {pos}/{len} trials ({elapsed}, {eta} left)").expect("static template"));
    bar.set_message(format!("walking, {} at once", pool.current_num_threads()));
    let on_trial = |r: &TrialReport| {
        let verdict = if r.success { format!("{:.1} cm/s", r.speed_cm_s) } else { "failed".into() };
        bar.set_message(format!("{} seed {}: {verdict}", r.scenario, r.seed));
        bar.inc(1);
    };
    let bench = pool.install(|| terrain_benchmark(&model, &config, &scenarios, trials, on_trial));
    bar.finish_and_clear();
    // A terrain that is not one of the paper's has no target row (meets_targets = null).
    let missed: Vec<&str> = bench.terrains.iter().filter(|r| r.meets_targets == Some(false)).map(|r| r.scenario.as_str()).collect();
    let verdict = Verdict::from_met(missed.is_empty());
    let mut value = serde_json::to_value(&bench)?;
    if let serde_json::Value::Object(map) = &mut value {
        map.insert("verdict".into(), json!(verdict.as_str()));
        map.insert("exit_code".into(), json!(verdict.exit_code()));
    }
    std::fs::create_dir_all(out).with_context(|| format!("cannot create the output folder {}", out.display())).or_could_not_finish()?;
    std::fs::write(out.join("summary.json"), serde_json::to_string_pretty(&value)? + "\n").with_context(|| format!("cannot write {}", out.join("summary.json").display())).or_could_not_finish()?;
    write_report(out.join("report.html"), "legwork bench terrain: Winkler 2015, Table I, beside legwork", &[], &table_i_sections(&bench, verdict)).or_could_not_finish()?;
    if as_json {
        say!("{}", serde_json::to_string_pretty(&value)?);
    } else {
        print_table_i(&bench);
        say_verdict(verdict, &missed);
        say!("Wrote {} and summary.json", out.join("report.html").display());
    }
    Ok(verdict)
}

/// The report page's sections of `bench terrain`: Table I beside legwork's, then every
/// failed trial.
fn table_i_sections(bench: &TerrainBenchmark, verdict: Verdict) -> Vec<ReportSection> {
    let opt = |x: Option<f64>, decimals: usize| x.map_or("-".to_string(), |x| format!("{x:.decimals$}"));
    let pct = |x: Option<f64>| x.map_or("-".to_string(), |x| format!("{:.0} %", 100.0 * x));
    let mut table = String::from("<table><thead><tr><th rowspan=2>terrain</th><th colspan=2>Winkler 2015, Table I</th><th colspan=2>legwork</th><th rowspan=2>speed / paper's</th><th rowspan=2>mean plan [ms]</th><th rowspan=2>worst ZMP margin [cm]</th><th rowspan=2>targets</th></tr><tr><th>speed [cm/s]</th><th>success</th><th>speed [cm/s]</th><th>success</th></tr></thead><tbody>");
    for r in &bench.terrains {
        let ratio = match (r.speed_cm_s, r.paper_speed_cm_s) {
            (Some(ours), Some(paper)) => format!("{:.1}x", ours / paper),
            _ => "-".into(),
        };
        let targets = match r.meets_targets {
            Some(true) => "<span class=met>met</span>".to_string(),
            Some(false) => "<span class=missed>missed</span>".to_string(),
            None => "-".to_string(),
        };
        table += &format!(
            "<tr><td>{}</td><td class=num>{}</td><td class=num>{}</td><td class=num>{}</td><td class=num>{} ({}/{})</td><td class=num>{ratio}</td><td class=num>{}</td><td class=num>{}</td><td>{targets}</td></tr>",
            escape(&r.scenario),
            opt(r.paper_speed_cm_s, 1),
            pct(r.paper_success_rate),
            opt(r.speed_cm_s, 1),
            pct(Some(r.success_rate)),
            r.successes,
            r.trials,
            opt(r.planning.mean_plan_ms, 1),
            opt(r.planning.worst_zmp_margin_m.map(|m| 100.0 * m), 2),
        );
    }
    table += &format!(
        "</tbody></table><p>{} trials per terrain; {}; {} at once, {:.0} s; targets (issue 5): success on at least {:.0} % of the trials, at least {:.0}x the paper's speed. Verdict: {}. CPU: {}.</p>",
        bench.trials_per_terrain,
        escape(bench.randomization),
        bench.threads,
        bench.wall_time_s,
        100.0 * TARGET_SUCCESS_RATE,
        TARGET_SPEED_FACTOR,
        if verdict == Verdict::Met { "<span class=met>met</span>" } else { "<span class=missed>missed</span>" },
        escape(&cpu_name())
    );
    let mut sections = vec![ReportSection { heading: "Forward speed and success rate per terrain".into(), html: table }];
    let failures: Vec<String> = bench.terrains.iter().flat_map(|r| r.failures.iter().map(move |f| (r, f))).map(|(r, f)| format!("<li>{}: {}</li>", escape(&r.scenario), escape(&serde_json::to_string(f).unwrap_or_default()))).collect();
    if !failures.is_empty() {
        sections.push(ReportSection { heading: "Failed trials".into(), html: format!("<ul>{}</ul>", failures.join("")) });
    }
    sections
}

/// The first line of `text`, cut at `max` characters.
fn first_line(text: &str, max: usize) -> String {
    let line = text.lines().next().unwrap_or("");
    match line.char_indices().nth(max) {
        Some((cut, _)) => format!("{}...", &line[..cut]),
        None => line.to_string(),
    }
}

/// The table: the paper's Table I beside ours, the planning figures, the targets.
fn print_table_i(bench: &TerrainBenchmark) {
    let opt = |x: Option<f64>, decimals: usize| x.map_or("-".to_string(), |x| format!("{x:.decimals$}"));
    say!(
        "Winkler 2015, Table I, against legwork: {} trials per terrain; {}; {} at once, {:.0} s",
        bench.trials_per_terrain,
        bench.randomization,
        bench.threads,
        bench.wall_time_s
    );
    say!("  {:<16} {:>14} {:>14} | {:>10} {:>10} {:>9} {:>9} {:>8} {:>10} {:>9} | {:>14}", "", "paper", "", "legwork", "", "plan", "ARA* 1st", "ZMP QP", "worst ZMP", "map upd.", "targets");
    say!(
        "  {:<16} {:>14} {:>14} | {:>10} {:>10} {:>9} {:>9} {:>8} {:>10} {:>9} | {:>14}",
        "terrain",
        "speed [cm/s]",
        "success",
        "speed",
        "success",
        "mean [ms]",
        "mean [ms]",
        "mean [ms]",
        "margin [cm]",
        "max [ms]",
        "met"
    );
    for row in &bench.terrains {
        let paper = paper_result(&row.scenario);
        let name = paper.map_or(row.scenario.clone(), |p| p.terrain.to_string());
        let targets = match (row.meets_targets, row.target_speed_cm_s) {
            (Some(met), Some(speed)) => format!("{} (>= {speed:.1})", if met { "yes" } else { "no" }),
            _ => "-".into(),
        };
        let p = &row.planning;
        say!(
            "  {:<16} {:>14} {:>14} | {:>10} {:>10} {:>9} {:>9} {:>8} {:>10} {:>9.1} | {:>14}",
            name,
            opt(row.paper_speed_cm_s, 1),
            row.paper_success_rate.map_or("-".into(), |r| format!("{:.0} %", 100.0 * r)),
            opt(row.speed_cm_s, 1),
            format!("{}/{} ({:.0} %)", row.successes, row.trials, 100.0 * row.success_rate),
            opt(p.mean_plan_ms, 1),
            opt(p.mean_first_solution_ms, 1),
            opt(p.mean_zmp_ms, 2),
            opt(p.worst_zmp_margin_m.map(|m| 100.0 * m), 2),
            row.max_map_update_ms,
            targets
        );
    }
    say!("  targets: success >= {:.0} % and speed >= {TARGET_SPEED_FACTOR} x the paper's on every terrain", 100.0 * TARGET_SUCCESS_RATE);
    let failures: Vec<String> = bench.terrains.iter().flat_map(|row| row.failures.iter().map(move |f| format!("  {} seed {}: {}", row.scenario, f.seed, first_line(&f.reason, 140)))).collect();
    if !failures.is_empty() {
        say!("Failed trials (the reason's start; --json has all of it):");
        for f in failures {
            say!("{f}");
        }
    }
}

/// Least-squares line `y = a + b x` and its R^2.
fn linear_fit(x: &[f64], y: &[f64]) -> (f64, f64, f64) {
    let n = x.len() as f64;
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let sxx: f64 = x.iter().map(|a| (a - mx) * (a - mx)).sum();
    let b = sxy / sxx;
    let a = my - b * mx;
    let ss_res: f64 = x.iter().zip(y).map(|(xi, yi)| (yi - a - b * xi).powi(2)).sum();
    let ss_tot: f64 = y.iter().map(|yi| (yi - my).powi(2)).sum();
    (a, b, 1.0 - ss_res / ss_tot)
}

fn slq(as_json: bool, threads: usize, iterations: usize, check_mujoco: bool, out: &std::path::Path) -> Result<Verdict> {
    if !(1..=1000).contains(&iterations) {
        bail!("--iterations: expected 1-1000 timed iterations per horizon, got {iterations}");
    }
    // A missing MuJoCo environment is reported before the benchmark, not after it.
    let mujoco = if check_mujoco { Some(MujocoCheck::locate().or_could_not_finish()?) } else { None };
    let model = embedded::load("hyq")?;
    let ground = Plane::flat(0.0);
    // Fig. 13: one cost structure (the squat jump's running and final costs, no waypoint),
    // horizons from 0.25 s to 3 s at dt = 2 ms; a fixed number of iterations each.
    let mut base = TaskSpec::embedded("squat_jump")?;
    base.waypoints.clear();
    let initial = settled_stance(&model, &ground, 1.0)?;
    let pd = legwork::control::JointPd::standing(&model, base.dt)?;
    let mut scaling = Vec::new();
    for horizon in [0.25, 0.5, 1.0, 1.5, 2.0, 3.0] {
        let mut spec = base.clone();
        spec.duration = horizon;
        let problem = spec.problem(&model, &ground, initial.clone(), "bench")?;
        let settings = SlqSettings { threads, max_iterations: iterations, feedforward_tolerance: 0.0, relative_cost_tolerance: 0.0, normalized_cost_tolerance: 0.0, ..Default::default() };
        let sol = Slq::new(&problem, settings)?.solve(&PdPolicy(&pd), |_| {}).or_could_not_finish()?;
        let n = sol.iterations.len().max(1) as f64;
        let mean = |f: &dyn Fn(&legwork::slq::IterationTiming) -> f64| sol.iterations.iter().map(|l| f(&l.timing)).sum::<f64>() / n * 1e3;
        let total = mean(&|t| t.linearization + t.backward_pass + t.line_search);
        scaling.push(json!({
            "horizon_s": horizon,
            "knots": spec.knots(),
            "iterations_timed": sol.iterations.len(),
            "ms_per_iteration": total,
            "linearization_ms": mean(&|t| t.linearization),
            "backward_pass_ms": mean(&|t| t.backward_pass),
            "line_search_ms": mean(&|t| t.line_search),
            "us_per_knot_per_iteration": total * 1e3 / spec.knots() as f64,
        }));
    }
    let knots: Vec<f64> = scaling.iter().map(|s| s["knots"].as_f64().unwrap_or(0.0)).collect();
    let times: Vec<f64> = scaling.iter().map(|s| s["ms_per_iteration"].as_f64().unwrap_or(0.0)).collect();
    let (intercept, slope, r2) = linear_fit(&knots, &times);

    let mut tasks = Vec::new();
    for (name, _) in EMBEDDED_TASKS {
        let spec = TaskSpec::embedded(name)?;
        let task_model = embedded::load(&spec.robot)?;
        // Each task as `legwork solve` runs it (with `--check mujoco` when asked), its folder
        // written for the report.
        let folder = out.join(name);
        let job = SolveJob { spec: &spec, origin: name, model: &task_model, options: SolveOptions { threads, ..SolveOptions::default() }, mujoco: mujoco.as_ref(), out: &folder, memory_limit: super::resources::memory_limit(), png: false };
        let solved = job.run(|_| ()).map_err(super::solve::job_error)?;
        let run = &solved.run;
        let sol = &run.solution;
        // The task's target on the plan, and at twice its tolerances in MuJoCo (as `solve`).
        let target_met = solved.verdict == Verdict::Met;
        // The plan and legwork's tracking re-run beside MuJoCo's two runs, when asked.
        let mujoco_figures = match &solved.mujoco {
            Some(m) => json!({
                "plan": super::solve::metrics_json(&run.plan_metrics),
                "tracking_controller_rerun": super::solve::rerun_json(&run.tracking_rerun),
                "mujoco_tracking_controller": super::solve::rerun_json(&m.tracking),
                "mujoco_policy": super::solve::rerun_json(&m.policy),
            }),
            None => serde_json::Value::Null,
        };
        tasks.push(json!({
            "mujoco": mujoco_figures,
            "task": name,
            "target_met": target_met,
            "knots": spec.knots(),
            "iterations": run.iterations(),
            // The costs are the full horizon's: after the stages, its first rollout is warm-started.
            "continuation_stages": run.stages.len(),
            "termination": format!("{:?}", sol.termination),
            "solve_time_s": run.solve_time(),
            "initial_cost": sol.cost_history[0],
            "final_cost": sol.cost_history.last(),
            "ms_per_iteration": sol.iterations.iter().map(|l| l.timing.linearization + l.timing.backward_pass + l.timing.line_search).sum::<f64>() / sol.iterations.len().max(1) as f64 * 1e3,
        }));
    }
    let threads_used = if threads == 0 { rayon::current_num_threads() } else { threads };
    let missed: Vec<&str> = tasks.iter().filter(|t| t["target_met"] != true).filter_map(|t| t["task"].as_str()).collect();
    let verdict = Verdict::from_met(missed.is_empty());
    let report = json!({
        "verdict": verdict.as_str(),
        "exit_code": verdict.exit_code(),
        "robot": "hyq",
        "dt_s": base.dt,
        "threads": threads_used,
        "scaling": scaling,
        "linear_fit": { "ms_intercept": intercept, "ms_per_knot": slope, "r_squared": r2 },
        "tasks": tasks,
    });
    // The report page: the scaling table, then every task's folder.
    let folders: Vec<std::path::PathBuf> = EMBEDDED_TASKS.iter().map(|(name, _)| out.join(name)).collect();
    let mut rows = String::from("<table><thead><tr><th>T [s]</th><th>knots</th><th>iteration [ms]</th><th>linearize [ms]</th><th>backward [ms]</th><th>line search [ms]</th><th>us / knot / iteration</th></tr></thead><tbody>");
    for s in &scaling {
        let f = |k: &str, d: usize| format!("{:.d$}", s[k].as_f64().unwrap_or(f64::NAN));
        rows += &format!("<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>", f("horizon_s", 2), s["knots"], f("ms_per_iteration", 1), f("linearization_ms", 1), f("backward_pass_ms", 1), f("line_search_ms", 1), f("us_per_knot_per_iteration", 1));
    }
    rows += &format!("</tbody></table><p>Linear fit: {intercept:.2} ms + {:.1} us x knots, R<sup>2</sup> = {r2:.4}. HyQ, dt = {} s, {threads_used} threads, {iterations} iterations per horizon; CPU: {}.</p>", slope * 1e3, base.dt, escape(&cpu_name()));
    let sections = [ReportSection { heading: "SLQ time per iteration against knots (Neunert 2017, Fig. 13)".into(), html: rows }];
    let runs = find_runs(&folders).or_could_not_finish()?;
    write_report(out.join("report.html"), "legwork bench slq: the nine tasks of Neunert 2017", &runs, &sections).or_could_not_finish()?;
    if as_json {
        say!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(verdict);
    }
    say!("Wrote {} (each task's folder beside it)", out.join("report.html").display());
    say!("SLQ time per iteration against knots (HyQ, dt = {} s, {threads_used} threads, {iterations} iterations each):", base.dt);
    say!("  {:>6} {:>6} {:>12} {:>12} {:>12} {:>12} {:>14}", "T [s]", "knots", "iter [ms]", "linearize", "backward", "line search", "us/knot/iter");
    for s in &scaling {
        say!(
            "  {:>6.2} {:>6} {:>12.1} {:>12.1} {:>12.1} {:>12.1} {:>14.1}",
            s["horizon_s"].as_f64().unwrap_or(0.0),
            s["knots"],
            s["ms_per_iteration"].as_f64().unwrap_or(0.0),
            s["linearization_ms"].as_f64().unwrap_or(0.0),
            s["backward_pass_ms"].as_f64().unwrap_or(0.0),
            s["line_search_ms"].as_f64().unwrap_or(0.0),
            s["us_per_knot_per_iteration"].as_f64().unwrap_or(0.0)
        );
    }
    say!("  linear fit: {intercept:.2} ms + {:.1} us x knots, R^2 = {r2:.4}", slope * 1e3);
    say!("Embedded tasks solved in full:");
    for t in &tasks {
        let stages = t["continuation_stages"].as_u64().unwrap_or(0);
        say!(
            "  {:<14} {:>5} knots  {:>3} iterations ({}){}  {:>6.2} s  cost {:.4e} -> {:.4e}  target {}",
            t["task"].as_str().unwrap_or(""),
            t["knots"],
            t["iterations"],
            t["termination"].as_str().unwrap_or(""),
            if stages > 0 { format!(", {stages} continuation stages first") } else { String::new() },
            t["solve_time_s"].as_f64().unwrap_or(0.0),
            t["initial_cost"].as_f64().unwrap_or(0.0),
            t["final_cost"].as_f64().unwrap_or(0.0),
            if t["target_met"] == true { "met" } else { "MISSED" }
        );
        if !t["mujoco"].is_null() {
            let cell = |key: &str| {
                let m = &t["mujoco"][key];
                match m.get("failed") {
                    Some(reason) => format!("failed ({})", first_line(reason.as_str().unwrap_or(""), 40)),
                    None => format!(
                        "apex {:.3} m, final ({:.2}, {:.2}) m yaw {:.0} deg, flight {:.2} s",
                        m["apex_base_height"].as_f64().unwrap_or(f64::NAN),
                        m["final_base_position"][0].as_f64().unwrap_or(f64::NAN),
                        m["final_base_position"][1].as_f64().unwrap_or(f64::NAN),
                        m["final_base_rpy_deg"][2].as_f64().unwrap_or(f64::NAN),
                        m["flight_time"].as_f64().unwrap_or(f64::NAN)
                    ),
                }
            };
            for (label, key) in [("plan", "plan"), ("legwork tracking", "tracking_controller_rerun"), ("MuJoCo tracking", "mujoco_tracking_controller"), ("MuJoCo policy", "mujoco_policy")] {
                say!("      {label:<17} {}", cell(key));
            }
        }
    }
    say_verdict(verdict, &missed);
    Ok(verdict)
}
