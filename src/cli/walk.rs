//! `legwork walk <scenario|file.toml>`: one trial of Winkler 2015's pipeline (map, ARA* body
//! plan, footsteps, ZMP body trajectory, execution in the simulator with re-planning), with
//! its files: trajectory.json, replay.html (planned footholds, CoG and ZMP drawn over the
//! terrain), plots (Fig. 8's CoG and ZMP over the support triangles) and summary.json.

use super::outcome::Verdict;
use anyhow::Result;
use clap::Args;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use legwork::job::walk::walk;
use legwork::walk::trial::TrialSetup;
use legwork::walk::ScenarioSpec;
use std::path::PathBuf;
use std::time::{Duration, Instant};

#[derive(Debug, Args)]
pub struct WalkArgs {
    /// An embedded scenario (flat, pallet, two_pallets, gap, stepping_stones,
    /// pallet_appears) or a scenario file (`.toml`).
    scenario: String,
    /// Output folder (created); default `out/walk-<scenario>`.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Seed of the map's sensor noise (and of the start offset with --random).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Randomize the trial as `legwork bench terrain` does: start offset +-5 cm, yaw
    /// +-5 deg, map noise 0.5-2 cm (`--random --seed K` is the benchmark's trial K).
    #[arg(long)]
    random: bool,
    /// Also write every plot as PNG (2x, text in the embedded DejaVu Sans) beside its SVG.
    #[arg(long)]
    png: bool,
}

/// `x` with `decimals` places, or `-` when there is none.
fn opt(x: Option<f64>, decimals: usize) -> String {
    x.map_or("-".into(), |x| format!("{x:.decimals$}"))
}

/// The exit code's verdict: met when the trial reached its goal.
pub fn run(args: WalkArgs) -> Result<Verdict> {
    let spec = ScenarioSpec::resolve(&args.scenario)?;
    let (model, _) = super::robot::load(&spec.robot)?;
    let setup = if args.random { TrialSetup::random(args.seed) } else { TrialSetup::nominal(args.seed) };
    let out = args.out.clone().unwrap_or_else(|| PathBuf::from("out").join(format!("walk-{}", spec.name)));
    say!(
        "Walking {} ({}) with {}: from ({}, {}) to ({}, {}, yaw {:.0} deg) within {} s; seed {}{}",
        spec.name,
        spec.summary,
        model.name,
        spec.start[0],
        spec.start[1],
        spec.goal[0],
        spec.goal[1],
        spec.goal[2].to_degrees(),
        spec.time_limit,
        setup.seed,
        if args.random {
            format!(", start offset ({:+.3} m, {:+.3} m, {:+.1} deg), map noise {:.1} cm", setup.start_offset[0], setup.start_offset[1], setup.start_offset[2].to_degrees(), setup.map_noise * 100.0)
        } else {
            format!(", map noise {:.1} cm", setup.map_noise * 100.0)
        }
    );

    // A spinner on standard error (hidden when it is not a terminal), and a line per plan.
    let bar = ProgressBar::with_draw_target(None, ProgressDrawTarget::stderr());
    bar.set_style(ProgressStyle::with_template("{spinner} {msg} [{elapsed}]").expect("static template"));
    bar.enable_steady_tick(Duration::from_millis(120));
    bar.set_message(format!("{}: settling", spec.name));
    let started = Instant::now();
    let mut planned = 0;
    let result = walk(&model, &spec, setup, Some(&out), args.png, |t, what| {
        planned += 1;
        bar.set_message(format!("{}: simulated t = {t:.2} s, plan {planned}: {what}", spec.name));
        bar.suspend(|| say!("  t = {t:6.2} s  {what}  ({:.1} s elapsed)", started.elapsed().as_secs_f64()));
    });
    bar.finish_and_clear();
    let walked = result.map_err(super::solve::job_error)?;
    let wall = started.elapsed().as_secs_f64();
    let (report, past_limits, plots) = (&walked.report, &walked.past_limits, walked.plots);
    let p = &report.planning;

    // The summary.
    match &report.failure {
        None if report.success => say!("{}: reached the goal", spec.name),
        None => say!("{}: FAILED: the goal was not reached", spec.name),
        Some(reason) => say!("{}: FAILED: {reason}", spec.name),
    }
    say!("  goal error            {} m (yaw {} deg)", opt(report.goal_error_m, 3), opt(report.yaw_error_deg, 1));
    let speed = if report.success { format!("speed {:.1} cm/s", report.speed_cm_s) } else { "no speed (the goal was not reached)".into() };
    say!("  walking time          {:.2} s, {speed} (simulated {:.2} s in {:.1} s)", report.walking_time_s, report.simulated_time_s, wall);
    match p.plans {
        0 => say!("  plans                 0"),
        n => say!("  plans                 {n} ({})", report.plan_reasons.join(", ")),
    }
    say!("  ARA* first solution   mean {} ms, max {} ms", opt(p.mean_first_solution_ms, 1), opt(p.max_first_solution_ms, 1));
    say!("  whole plan            mean {} ms, max {} ms", opt(p.mean_plan_ms, 1), opt(p.max_plan_ms, 1));
    say!("  ZMP QP                mean {} ms, max {} ms; worst ZMP margin {} cm", opt(p.mean_zmp_ms, 2), opt(p.max_zmp_ms, 2), opt(p.worst_zmp_margin_m.map(|m| m * 100.0), 2));
    say!("  map updates           {}, worst {:.1} ms", report.map_updates, report.max_map_update_ms);
    say!("  clipped torque ticks  {}", report.clipped_ticks);
    match &past_limits {
        None => say!("  past joint limits     none"),
        Some(e) => say!("  past joint limits     {:.1} deg ({} at t = {:.2} s)", e.excess_deg, e.joint, e.t),
    }
    if report.bad_footholds > 0 {
        say!("  bad footholds         {}", report.bad_footholds);
    }
    if !report.plan_timings.is_empty() {
        say!("  {:>4} {:>7} {:<17} {:>9} {:>8} {:>5} {:>7} {:>5} {:>9} {:>7} {:>8} {:>10}", "plan", "t [s]", "reason", "ARA* 1st", "search", "eps", "actions", "steps", "footsteps", "ZMP QP", "total", "ZMP margin");
        say!("  {:>4} {:>7} {:<17} {:>9} {:>8} {:>5} {:>7} {:>5} {:>9} {:>7} {:>8} {:>10}", "", "", "", "[ms]", "[ms]", "", "", "", "[ms]", "[ms]", "[ms]", "[cm]");
        for (k, plan) in report.plan_timings.iter().enumerate() {
            say!(
                "  {:>4} {:>7.2} {:<17} {:>9.1} {:>8.1} {:>5.2} {:>7} {:>5} {:>9.1} {:>7.2} {:>8.1} {:>10.2}",
                k + 1,
                plan.t,
                plan.reason,
                plan.first_solution_ms,
                plan.body_search_ms,
                plan.epsilon,
                plan.actions,
                plan.steps,
                plan.footstep_ms,
                plan.zmp_ms,
                plan.total_ms,
                plan.zmp_min_margin_m * 100.0
            );
        }
    }
    say!("Wrote {} (trajectory.json, replay.html, summary.json, {plots} plots in plots/)", out.display());
    Ok(walked.verdict)
}
