//! The walk job (`legwork walk`, Python's `legwork.walk`): one trial of Winkler 2015's
//! pipeline (map, ARA* body plan, footsteps, ZMP body trajectory, execution in the
//! simulator with re-planning), and its folder: `trajectory.json`, `replay.html` (planned
//! footholds, CoG and ZMP over the terrain), plots (Fig. 8's CoG and ZMP over the support
//! triangles) and `summary.json`.

use super::{JobError, OrCouldNotFinish, Verdict};
use crate::io::Trajectory;
use crate::model::Model;
use crate::ocp::LimitExcess;
use crate::report::walk::TrialReport;
use crate::walk::trial::{run_trial, TrialOutcome, TrialSetup, WalkConfig};
use crate::walk::ScenarioSpec;
use serde_json::json;
use std::path::Path;
use std::time::Instant;

/// A finished trial.
pub struct Walked {
    pub outcome: TrialOutcome,
    pub report: TrialReport,
    /// Met when the trial reached its goal.
    pub verdict: Verdict,
    /// The run, its summary filled.
    pub trajectory: Trajectory,
    /// How far a joint went past its position limit (neither the simulator, by default, nor
    /// the controller has joint stops).
    pub past_limits: Option<LimitExcess>,
    /// Plots written (0 when no folder was given).
    pub plots: usize,
}

/// Runs one trial of `spec` with `model` (`setup`: nominal or randomized, as `legwork bench
/// terrain` randomizes its trials) and, with `out`, writes the folder (`png`: the plots as
/// PNG too); `on_plan` sees each plan (simulated time, what was planned).
pub fn walk(model: &Model, spec: &ScenarioSpec, setup: TrialSetup, out: Option<&Path>, png: bool, on_plan: impl FnMut(f64, &str)) -> Result<Walked, JobError> {
    let config = WalkConfig::hyq(model).map_err(|e| JobError::bad_input(format!("cannot set up the walk for robot {}: {e}", model.name)))?;
    let started = Instant::now();
    let outcome = run_trial(model, spec, &config, setup, on_plan).or_could_not_finish()?;
    let report = TrialReport::new(&outcome, started.elapsed().as_secs_f64());
    let verdict = Verdict::from_met(report.success);
    let mut trajectory = outcome.trajectory.clone();
    let p = &report.planning;
    // The trajectory's own summary is short (the replay shows it in its header); every
    // number is in summary.json.
    let round = |x: f64, decimals: i32| (x * 10f64.powi(decimals)).round() / 10f64.powi(decimals);
    let past_limits = crate::ocp::joint_limit_excess(model, &trajectory);
    let summary = json!({
        "scenario": spec.name,
        "success": report.success,
        "verdict": verdict.as_str(),
        "exit_code": verdict.exit_code(),
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
        trajectory.summary = map;
    }
    let plots = match out {
        Some(out) => write_files(model, spec, &outcome, &report, &trajectory, out, png)?,
        None => 0,
    };
    Ok(Walked { outcome, report, verdict, trajectory, past_limits, plots })
}

fn write_files(model: &Model, spec: &ScenarioSpec, outcome: &TrialOutcome, report: &TrialReport, trajectory: &Trajectory, out: &Path, png: bool) -> Result<usize, JobError> {
    std::fs::create_dir_all(out).map_err(|e| JobError::could_not_finish(format!("cannot create the output folder {}: {e}", out.display())))?;
    trajectory.save_file(out.join("trajectory.json")).or_could_not_finish()?;
    let world = spec.world_at(f64::INFINITY);
    let end_time = trajectory.knots.last().map_or(0.0, |k| k.t);
    let overlay = crate::viz::walk::plan_overlay(&outcome.plans, &world, end_time);
    crate::viz::write_replay_with_overlay(model, trajectory, Some(&overlay), out.join("replay.html")).or_could_not_finish()?;
    let mut plots = crate::viz::write_plots(trajectory, out.join("plots")).or_could_not_finish()?;
    plots.extend(crate::viz::write_limit_plots(model, trajectory, out.join("plots")).or_could_not_finish()?);
    plots.extend(crate::viz::walk::write_walk_plots(model, &outcome.plans, trajectory, out.join("plots")).or_could_not_finish()?);
    if png {
        crate::viz::png::write_pngs(&plots, crate::viz::png::PNG_SCALE).or_could_not_finish()?;
    }
    let summary_path = out.join("summary.json");
    let text = serde_json::to_string_pretty(&json!({ "scenario_summary": spec.summary, "robot": model.name, "trial": report })).or_could_not_finish()?;
    std::fs::write(&summary_path, text + "\n").map_err(|e| JobError::could_not_finish(format!("cannot write {}: {e}", summary_path.display())))?;
    Ok(plots.len())
}
