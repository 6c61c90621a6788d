//! `legwork bench jumps`: Nguyen 2022's Table I beside legwork's figures, one row per jump.

use super::pipeline::{plan_contact_timing, run, PipelineOptions, Verdict};
use super::spec::{Jump, PaperRow};
use super::PipelineError;
use crate::model::Model;
use crate::srb::SrbParams;
use serde::Serialize;

/// One row of the table; a figure of a stage that did not run is `None`.
#[derive(Clone, Debug, Serialize)]
pub struct JumpBenchRow {
    pub jump: String,
    pub paper: Option<PaperRow>,
    /// The contact timing: status, iterations, cost, phase durations (10 ms), solve times
    /// over the repeats (s, median and fastest).
    pub contact_timing_status: String,
    pub contact_timing_iterations: usize,
    pub contact_timing_cost: f64,
    pub phase_durations_10ms: Vec<f64>,
    pub contact_timing_median_s: f64,
    pub contact_timing_min_s: f64,
    /// The full-body optimization: status, iterations, solve time (s), limits met.
    pub full_body_status: Option<String>,
    pub full_body_iterations: Option<usize>,
    pub full_body_solve_s: Option<f64>,
    pub full_body_limits_met: Option<bool>,
    /// The nominal re-run: landing position error (m), yaw error (deg), on target.
    pub landing_error_m: Option<f64>,
    pub yaw_error_deg: Option<f64>,
    pub landed: Option<bool>,
    /// The trials' success rate and their count.
    pub success_rate: Option<f64>,
    pub trials: usize,
    pub verdict: String,
    /// Stages that did not run or failed, and why.
    pub notes: Vec<String>,
}

/// The row of `jump`: its contact timing solved `repeats` times (at least once) for the
/// timing, then the whole pipeline with `options` (its trials included).
pub fn bench_jump(jump: &Jump, model: &Model, options: &PipelineOptions, repeats: usize) -> Result<JumpBenchRow, PipelineError> {
    let params = SrbParams::from_model(model, "standing")?;
    let report = run(jump, model, options, |_, _| {})?;
    let mut times = vec![report.contact_timing.solve_time_s];
    for _ in 1..repeats {
        times.push(plan_contact_timing(jump, &params, &options.contact_timing, options.contact_timing_solver.clone())?.solve_time_s);
    }
    times.sort_by(f64::total_cmp);
    let ct = &report.contact_timing;
    let fb = report.full_body_plan.as_ref();
    let run = report.rerun.as_ref();
    let mut notes: Vec<String> = report.stance_conflicts.iter().map(|c| c.to_string()).collect();
    for (stage, state) in [("full body", &report.full_body), ("controllers", &report.controllers)] {
        if *state != super::StageState::Done {
            notes.push(format!("{stage}: {state}"));
        }
    }
    if let Some(f) = run.and_then(|r| r.failure.as_ref()) {
        notes.push(format!("re-run: {f}"));
    }
    Ok(JumpBenchRow {
        jump: jump.name.clone(),
        paper: jump.paper.clone(),
        contact_timing_status: format!("{:?}", ct.status),
        contact_timing_iterations: ct.iterations,
        contact_timing_cost: ct.objective,
        phase_durations_10ms: ct.durations.iter().map(|t| (t * 1000.0).round() / 10.0).collect(),
        contact_timing_median_s: times[times.len() / 2],
        contact_timing_min_s: times[0],
        full_body_status: fb.map(|p| format!("{:?}", p.report.status)),
        full_body_iterations: fb.map(|p| p.report.iterations),
        full_body_solve_s: fb.map(|p| p.report.time.as_secs_f64()),
        full_body_limits_met: fb.map(|p| p.limits.all_met(1e-6)),
        landing_error_m: run.map(|r| r.position_error),
        yaw_error_deg: run.map(|r| r.yaw_error.to_degrees()),
        landed: report.landed,
        success_rate: report.trials.as_ref().map(|t| t.success_rate()),
        trials: report.trials.as_ref().map_or(0, |t| t.outcomes.len()),
        verdict: format!("{:?}", report.verdict()),
        notes,
    })
}

impl JumpBenchRow {
    /// Whether the row meets issue 17's targets: contact timing within 0.1 s, full body within
    /// 1 s and within its limits, every trial landed.
    pub fn meets_targets(&self) -> bool {
        self.contact_timing_median_s <= 0.1 && self.full_body_solve_s.is_some_and(|t| t <= 1.0) && self.full_body_limits_met == Some(true) && self.success_rate == Some(1.0) && self.verdict == format!("{:?}", Verdict::Landed)
    }
}
