//! `legwork bench jumps`: Nguyen 2022's Table I beside legwork's figures, one row per jump.

use super::pipeline::{plan_contact_timing, MISSING_CONTROLLERS, MISSING_FULL_BODY};
use super::spec::{Jump, PaperRow};
use super::PipelineError;
use crate::ipocp::Settings as SolverSettings;
use crate::srb::{ContactTimingSettings, SrbParams};
use serde::Serialize;

/// One row of the table. A figure of a stage this build does not have is `None`, and
/// `missing` says why.
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
    pub full_body_solve_s: Option<f64>,
    /// Landing position error of the controllers' re-run (m) and the trials' success rate.
    pub landing_error_m: Option<f64>,
    pub success_rate: Option<f64>,
    /// Feet the jump file's target puts over its box (see [`Jump::stance_conflicts`]).
    pub stance_conflicts: Vec<String>,
    pub missing: Vec<&'static str>,
}

/// The row of `jump`: its contact timing solved `repeats` times (at least once).
pub fn bench_jump(jump: &Jump, params: &SrbParams, foot_radius: f64, settings: &ContactTimingSettings, repeats: usize) -> Result<JumpBenchRow, PipelineError> {
    let mut stage = plan_contact_timing(jump, params, settings, SolverSettings::default())?;
    let mut times = vec![stage.solve_time_s];
    for _ in 1..repeats {
        stage = plan_contact_timing(jump, params, settings, SolverSettings::default())?;
        times.push(stage.solve_time_s);
    }
    times.sort_by(f64::total_cmp);
    Ok(JumpBenchRow {
        jump: jump.name.clone(),
        paper: jump.paper.clone(),
        contact_timing_status: format!("{:?}", stage.status),
        contact_timing_iterations: stage.iterations,
        contact_timing_cost: stage.objective,
        phase_durations_10ms: stage.durations.iter().map(|t| (t * 1000.0).round() / 10.0).collect(),
        contact_timing_median_s: times[times.len() / 2],
        contact_timing_min_s: times[0],
        full_body_solve_s: None,
        landing_error_m: None,
        success_rate: None,
        stance_conflicts: jump.stance_conflicts(params, foot_radius).iter().map(|c| c.to_string()).collect(),
        missing: vec![MISSING_FULL_BODY, MISSING_CONTROLLERS],
    })
}
