//! `legwork walk <scenario|file.toml>`: one trial of Winkler 2015's pipeline (map, ARA* body
//! plan, footsteps, ZMP body trajectory, execution in the simulator with re-planning), with
//! its files: trajectory.json, replay.html (planned footholds, CoG and ZMP drawn over the
//! terrain), plots (Fig. 8's CoG and ZMP over the support triangles) and summary.json.

use super::outcome::{OrCouldNotFinish, Verdict};
use anyhow::{Context, Result};
use clap::Args;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use legwork::report::walk::TrialReport;
use legwork::walk::trial::{run_trial, TrialSetup, WalkConfig};
use legwork::walk::ScenarioSpec;
use serde_json::json;
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
}

/// `x` with `decimals` places, or `-` when there is none.
fn opt(x: Option<f64>, decimals: usize) -> String {
    x.map_or("-".into(), |x| format!("{x:.decimals$}"))
}

/// The exit code's verdict: met when the trial reached its goal.
pub fn run(args: WalkArgs) -> Result<Verdict> {
    let spec = ScenarioSpec::resolve(&args.scenario)?;
    let (model, _) = super::robot::load(&spec.robot)?;
    let config = WalkConfig::hyq(&model).with_context(|| format!("cannot set up the walk for robot {}", model.name))?;
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
    let result = run_trial(&model, &spec, &config, setup, |t, what| {
        planned += 1;
        bar.set_message(format!("{}: simulated t = {t:.2} s, plan {planned}: {what}", spec.name));
        bar.suspend(|| say!("  t = {t:6.2} s  {what}  ({:.1} s elapsed)", started.elapsed().as_secs_f64()));
    });
    bar.finish_and_clear();
    let outcome = result.or_could_not_finish()?;
    let wall = started.elapsed().as_secs_f64();
    let report = TrialReport::new(&outcome, wall);

    let mut traj = outcome.trajectory.clone();
    let p = &report.planning;
    // The trajectory's own summary is short (the replay shows it in its header); every
    // number is in summary.json.
    let round = |x: f64, decimals: i32| (x * 10f64.powi(decimals)).round() / 10f64.powi(decimals);
    // Neither the simulator (by default) nor the controller has joint stops: how far a joint
    // went past its position limit says whether the hardware could walk it.
    let past_limits = legwork::ocp::joint_limit_excess(&model, &traj);
    let summary = json!({
        "scenario": spec.name,
        "success": report.success,
        "verdict": Verdict::from_met(report.success).as_str(),
        "exit_code": Verdict::from_met(report.success).exit_code(),
        "failure": report.failure.clone().unwrap_or_else(|| "none".into()),
        "goal_error_m": report.goal_error_m.map(|e| round(e, 3)),
        "walking_time_s": round(report.walking_time_s, 2),
        "speed_cm_s": round(report.speed_cm_s, 1),
        "plans": p.plans,
        "mean_plan_ms": p.mean_plan_ms.map(|m| round(m, 1)),
        "worst_zmp_margin_m": p.worst_zmp_margin_m.map(|m| round(m, 4)),
        "clipped_ticks": report.clipped_ticks,
        "joint_limit_excess": past_limits,
    });
    if let serde_json::Value::Object(map) = summary {
        traj.summary = map;
    }
    std::fs::create_dir_all(&out).with_context(|| format!("cannot create the output folder {}", out.display())).or_could_not_finish()?;
    traj.save_file(out.join("trajectory.json")).or_could_not_finish()?;
    let world = spec.world_at(f64::INFINITY);
    let end_time = traj.knots.last().map_or(0.0, |k| k.t);
    let overlay = legwork::viz::walk::plan_overlay(&outcome.plans, &world, end_time);
    legwork::viz::write_replay_with_overlay(&model, &traj, Some(&overlay), out.join("replay.html")).or_could_not_finish()?;
    let mut plots = legwork::viz::write_plots(&traj, out.join("plots")).or_could_not_finish()?;
    plots.extend(legwork::viz::write_limit_plots(&model, &traj, out.join("plots")).or_could_not_finish()?);
    plots.extend(legwork::viz::walk::write_walk_plots(&model, &outcome.plans, &traj, out.join("plots"))?);
    let summary_path = out.join("summary.json");
    let text = serde_json::to_string_pretty(&json!({ "scenario_summary": spec.summary, "robot": model.name, "trial": report })).or_could_not_finish()?;
    std::fs::write(&summary_path, text + "\n").with_context(|| format!("cannot write {}", summary_path.display())).or_could_not_finish()?;

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
    say!("Wrote {} (trajectory.json, replay.html, summary.json, {} plots in plots/)", out.display(), plots.len());
    Ok(Verdict::from_met(report.success))
}
