//! Walk trials in numbers (Winkler 2015, sec. VI): a trial's summary, and Table I (forward
//! speed and success rate per terrain) over randomized trials beside the paper's.
//!
//! * [`TrialReport`]: one trial ([`crate::walk::trial::TrialOutcome`]) as plain numbers:
//!   success and why not, goal error, walking time and speed, what planning cost (ARA*
//!   first solution, the whole plan, the ZMP QP, the worst ZMP margin), map updates,
//!   clipped torques. `legwork walk` writes it as `summary.json`.
//! * [`terrain_benchmark`]: `trials` randomized trials ([`TrialSetup::random`] with seeds
//!   `1..=trials`: start offset +-5 cm, yaw +-5 deg, map noise) of each scenario, in
//!   parallel on the current rayon pool, summarized per scenario as a [`TerrainRow`] with
//!   the paper's result ([`TABLE_I`]) and issue 5's targets beside it.
//!
//! Speeds are in cm/s as in the paper; success rates are fractions in [0, 1].

use crate::model::Model;
use crate::walk::trial::{run_trial, PlanRecord, TrialOutcome, TrialSetup, WalkConfig};
use crate::walk::ScenarioSpec;
use rayon::prelude::*;
use serde::Serialize;
use std::time::Instant;

/// One terrain of Winkler 2015's Table I (the "Curr." columns: the paper's framework).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct PaperResult {
    /// The embedded scenario that reproduces the terrain.
    pub scenario: &'static str,
    /// The terrain as the paper names it.
    pub terrain: &'static str,
    pub speed_cm_s: f64,
    pub success_rate: f64,
}

/// Winkler 2015, Table I: forward speed and success rate over 10 trials per terrain.
pub const TABLE_I: [PaperResult; 4] = [
    PaperResult { scenario: "stepping_stones", terrain: "stepping stones", speed_cm_s: 7.3, success_rate: 0.6 },
    PaperResult { scenario: "pallet", terrain: "pallet", speed_cm_s: 9.5, success_rate: 1.0 },
    PaperResult { scenario: "two_pallets", terrain: "two pallets", speed_cm_s: 10.2, success_rate: 0.9 },
    PaperResult { scenario: "gap", terrain: "gap", speed_cm_s: 12.7, success_rate: 0.9 },
];

/// Issue 5's targets: success on at least 95 % of the trials of every terrain, at least
/// twice the paper's speed.
pub const TARGET_SUCCESS_RATE: f64 = 0.95;
pub const TARGET_SPEED_FACTOR: f64 = 2.0;

/// The paper's result for an embedded scenario, if Table I has its terrain.
pub fn paper_result(scenario: &str) -> Option<PaperResult> {
    TABLE_I.iter().find(|p| p.scenario == scenario).copied()
}

/// What one plan cost, and why it was made.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PlanTiming {
    /// Simulation time of the plan (s).
    pub t: f64,
    pub reason: &'static str,
    /// ARA*'s first solution and the whole body-action search (ms), the bound it ended at.
    pub first_solution_ms: f64,
    pub body_search_ms: f64,
    pub epsilon: f64,
    pub actions: usize,
    pub footstep_ms: f64,
    pub zmp_ms: f64,
    /// The whole plan: body actions, footsteps, ZMP trajectory (ms).
    pub total_ms: f64,
    pub steps: usize,
    /// Smallest distance of the ZMP inside its shrunk support polygon (m; negative: outside).
    pub zmp_min_margin_m: f64,
}

impl PlanTiming {
    pub fn new(record: &PlanRecord) -> Self {
        Self {
            t: record.t,
            reason: record.reason.name(),
            first_solution_ms: record.body_first_ms,
            body_search_ms: record.body_ms,
            epsilon: record.epsilon,
            actions: record.actions,
            footstep_ms: record.footstep_ms,
            zmp_ms: record.zmp_ms,
            total_ms: record.total_ms,
            steps: record.steps,
            zmp_min_margin_m: record.zmp_min_margin,
        }
    }
}

/// Planning over any number of plans: means and worst cases (`None` without a plan).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct PlanningStats {
    pub plans: usize,
    pub mean_plan_ms: Option<f64>,
    pub max_plan_ms: Option<f64>,
    /// ARA*'s first solution.
    pub mean_first_solution_ms: Option<f64>,
    pub max_first_solution_ms: Option<f64>,
    /// The ZMP QP.
    pub mean_zmp_ms: Option<f64>,
    pub max_zmp_ms: Option<f64>,
    /// The smallest ZMP margin of any plan (m; negative: the ZMP left its shrunk polygon).
    pub worst_zmp_margin_m: Option<f64>,
}

impl PlanningStats {
    pub fn over<'a>(plans: impl IntoIterator<Item = &'a PlanTiming>) -> Self {
        let plans: Vec<&PlanTiming> = plans.into_iter().collect();
        let n = plans.len();
        let mean = |f: fn(&PlanTiming) -> f64| (n > 0).then(|| plans.iter().map(|p| f(p)).sum::<f64>() / n as f64);
        let max = |f: fn(&PlanTiming) -> f64| plans.iter().map(|p| f(p)).reduce(f64::max);
        Self {
            plans: n,
            mean_plan_ms: mean(|p| p.total_ms),
            max_plan_ms: max(|p| p.total_ms),
            mean_first_solution_ms: mean(|p| p.first_solution_ms),
            max_first_solution_ms: max(|p| p.first_solution_ms),
            mean_zmp_ms: mean(|p| p.zmp_ms),
            max_zmp_ms: max(|p| p.zmp_ms),
            worst_zmp_margin_m: plans.iter().map(|p| p.zmp_min_margin_m).reduce(f64::min),
        }
    }
}

/// One trial in numbers.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TrialReport {
    pub scenario: String,
    pub seed: u64,
    /// Offset of the start pose: x, y (m), yaw (deg).
    pub start_offset: [f64; 3],
    /// Standard deviation of the map's height samples (m).
    pub map_noise_m: f64,
    pub success: bool,
    /// Why the trial failed (`None` on success).
    pub failure: Option<String>,
    /// Final distance to the goal and yaw error (`None` when the trial could not run).
    pub goal_error_m: Option<f64>,
    pub yaw_error_deg: Option<f64>,
    /// From the first plan to the end of the last (s), and start-to-goal distance over it.
    pub walking_time_s: f64,
    pub speed_cm_s: f64,
    /// Simulated time, and the wall-clock time the trial took (s).
    pub simulated_time_s: f64,
    pub wall_time_s: f64,
    #[serde(flatten)]
    pub planning: PlanningStats,
    /// Why each plan was made, in order.
    pub plan_reasons: Vec<&'static str>,
    pub map_updates: usize,
    pub max_map_update_ms: f64,
    pub bad_footholds: usize,
    pub clipped_ticks: u64,
    /// Every plan, in order.
    pub plan_timings: Vec<PlanTiming>,
}

impl TrialReport {
    /// The report of `outcome`, which took `wall_time_s` to run.
    pub fn new(outcome: &TrialOutcome, wall_time_s: f64) -> Self {
        let plans: Vec<PlanTiming> = outcome.plans.iter().map(PlanTiming::new).collect();
        let o = outcome.setup.start_offset;
        Self {
            scenario: outcome.scenario.clone(),
            seed: outcome.setup.seed,
            start_offset: [o[0], o[1], o[2].to_degrees()],
            map_noise_m: outcome.setup.map_noise,
            success: outcome.success,
            failure: outcome.failure.clone(),
            goal_error_m: Some(outcome.goal_error),
            yaw_error_deg: Some(outcome.yaw_error.to_degrees()),
            walking_time_s: outcome.walking_time,
            speed_cm_s: 100.0 * outcome.speed,
            simulated_time_s: outcome.trajectory.duration(),
            wall_time_s,
            planning: PlanningStats::over(&plans),
            plan_reasons: plans.iter().map(|p| p.reason).collect(),
            map_updates: outcome.map_updates,
            max_map_update_ms: outcome.max_map_update_ms,
            bad_footholds: outcome.bad_footholds.len(),
            clipped_ticks: outcome.controller.clipped_ticks,
            plan_timings: plans,
        }
    }

    /// A trial that could not run at all (`run_trial` returned `error`): a failure.
    pub fn not_run(scenario: &str, setup: TrialSetup, error: &str, wall_time_s: f64) -> Self {
        let o = setup.start_offset;
        Self {
            scenario: scenario.into(),
            seed: setup.seed,
            start_offset: [o[0], o[1], o[2].to_degrees()],
            map_noise_m: setup.map_noise,
            success: false,
            failure: Some(format!("the trial could not run: {error}")),
            goal_error_m: None,
            yaw_error_deg: None,
            walking_time_s: 0.0,
            speed_cm_s: 0.0,
            simulated_time_s: 0.0,
            wall_time_s,
            planning: PlanningStats::default(),
            plan_reasons: Vec::new(),
            map_updates: 0,
            max_map_update_ms: 0.0,
            bad_footholds: 0,
            clipped_ticks: 0,
            plan_timings: Vec::new(),
        }
    }
}

/// A failed trial of a benchmark row: its seed and why.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TrialFailure {
    pub seed: u64,
    pub reason: String,
}

/// One terrain of the benchmark: ours over `trials` randomized trials, the paper's beside.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TerrainRow {
    pub scenario: String,
    /// Winkler 2015, Table I (absent for scenarios the paper has no row for).
    pub paper_speed_cm_s: Option<f64>,
    pub paper_success_rate: Option<f64>,
    pub trials: usize,
    pub successes: usize,
    pub success_rate: f64,
    /// Mean forward speed over the successful trials (`None` without one).
    pub speed_cm_s: Option<f64>,
    /// Over every plan of every trial.
    #[serde(flatten)]
    pub planning: PlanningStats,
    pub max_map_update_ms: f64,
    /// Control ticks with a torque at its limit, over all trials.
    pub clipped_ticks: u64,
    /// Mean wall-clock time of a trial (s).
    pub mean_trial_wall_s: f64,
    /// Issue 5's targets, and whether they are met (`None` without a paper row).
    pub target_success_rate: f64,
    pub target_speed_cm_s: Option<f64>,
    pub meets_targets: Option<bool>,
    pub failures: Vec<TrialFailure>,
}

impl TerrainRow {
    /// The row of `scenario` from its trials' reports.
    pub fn new(scenario: &str, reports: &[TrialReport]) -> Self {
        let paper = paper_result(scenario);
        let trials = reports.len();
        let successes = reports.iter().filter(|r| r.success).count();
        let success_rate = if trials > 0 { successes as f64 / trials as f64 } else { 0.0 };
        let speed_cm_s = (successes > 0).then(|| reports.iter().filter(|r| r.success).map(|r| r.speed_cm_s).sum::<f64>() / successes as f64);
        let target_speed_cm_s = paper.map(|p| TARGET_SPEED_FACTOR * p.speed_cm_s);
        let meets_targets = target_speed_cm_s.map(|target| success_rate >= TARGET_SUCCESS_RATE && speed_cm_s.is_some_and(|s| s >= target));
        Self {
            scenario: scenario.into(),
            paper_speed_cm_s: paper.map(|p| p.speed_cm_s),
            paper_success_rate: paper.map(|p| p.success_rate),
            trials,
            successes,
            success_rate,
            speed_cm_s,
            planning: PlanningStats::over(reports.iter().flat_map(|r| r.plan_timings.iter())),
            max_map_update_ms: reports.iter().map(|r| r.max_map_update_ms).fold(0.0, f64::max),
            clipped_ticks: reports.iter().map(|r| r.clipped_ticks).sum(),
            mean_trial_wall_s: if trials > 0 { reports.iter().map(|r| r.wall_time_s).sum::<f64>() / trials as f64 } else { 0.0 },
            target_success_rate: TARGET_SUCCESS_RATE,
            target_speed_cm_s,
            meets_targets,
            failures: reports.iter().filter(|r| !r.success).map(|r| TrialFailure { seed: r.seed, reason: r.failure.clone().unwrap_or_else(|| "goal not reached".into()) }).collect(),
        }
    }
}

/// Runs one trial of `scenario` and reports it (an error of `run_trial` is a failed trial).
pub fn run_and_report(model: &Model, scenario: &ScenarioSpec, config: &WalkConfig, setup: TrialSetup) -> TrialReport {
    let started = Instant::now();
    match run_trial(model, scenario, config, setup, |_, _| {}) {
        Ok(outcome) => TrialReport::new(&outcome, started.elapsed().as_secs_f64()),
        Err(e) => TrialReport::not_run(&scenario.name, setup, &e.to_string(), started.elapsed().as_secs_f64()),
    }
}

/// The randomization of the benchmark's trials, in words.
pub const RANDOMIZATION: &str = "start offset +-5 cm in x and y, yaw +-5 deg, map noise 0.5-2 cm (TrialSetup::random, seeds 1..=trials)";

/// Table I over randomized trials: what `legwork bench terrain --json` prints.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TerrainBenchmark {
    pub robot: String,
    pub trials_per_terrain: usize,
    pub randomization: &'static str,
    /// Trials run at once.
    pub threads: usize,
    pub wall_time_s: f64,
    pub terrains: Vec<TerrainRow>,
}

/// `trials` randomized trials of each of `scenarios` (seeds `1..=trials`), in parallel on
/// the current rayon pool (one trial per task; each makes its own planners and simulator),
/// one row per scenario in the given order. `on_trial` hears of each trial as it ends (from
/// any thread).
pub fn terrain_benchmark(model: &Model, config: &WalkConfig, scenarios: &[ScenarioSpec], trials: usize, on_trial: impl Fn(&TrialReport) + Sync) -> TerrainBenchmark {
    let started = Instant::now();
    let jobs: Vec<(usize, u64)> = (0..scenarios.len()).flat_map(|s| (1..=trials as u64).map(move |seed| (s, seed))).collect();
    let reports: Vec<(usize, TrialReport)> = jobs
        .par_iter()
        .map(|&(s, seed)| {
            let report = run_and_report(model, &scenarios[s], config, TrialSetup::random(seed));
            on_trial(&report);
            (s, report)
        })
        .collect();
    let terrains = scenarios
        .iter()
        .enumerate()
        .map(|(s, spec)| {
            let mine: Vec<TrialReport> = reports.iter().filter(|(k, _)| *k == s).map(|(_, r)| r.clone()).collect();
            TerrainRow::new(&spec.name, &mine)
        })
        .collect();
    TerrainBenchmark {
        robot: model.name.clone(),
        trials_per_terrain: trials,
        randomization: RANDOMIZATION,
        threads: rayon::current_num_threads(),
        wall_time_s: started.elapsed().as_secs_f64(),
        terrains,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn report(success: bool, speed_cm_s: f64, plans: &[(f64, f64, f64, f64)]) -> TrialReport {
        let plans: Vec<PlanTiming> = plans
            .iter()
            .map(|&(total, first, zmp, margin)| PlanTiming {
                t: 0.3,
                reason: "start",
                first_solution_ms: first,
                body_search_ms: first,
                epsilon: 1.0,
                actions: 3,
                footstep_ms: 0.1,
                zmp_ms: zmp,
                total_ms: total,
                steps: 12,
                zmp_min_margin_m: margin,
            })
            .collect();
        let setup = TrialSetup::nominal(7);
        TrialReport { success, speed_cm_s, failure: (!success).then(|| "fell".to_string()), planning: PlanningStats::over(&plans), plan_timings: plans, ..TrialReport::not_run("pallet", setup, "-", 2.0) }
    }

    #[test]
    fn a_row_averages_speed_over_successes_and_plans_over_all_trials() {
        let reports = [report(true, 20.0, &[(10.0, 2.0, 1.0, 0.04), (30.0, 4.0, 3.0, 0.02)]), report(true, 30.0, &[(20.0, 3.0, 2.0, 0.05)]), report(false, 5.0, &[(60.0, 11.0, 6.0, -0.01)])];
        let row = TerrainRow::new("pallet", &reports);
        assert_eq!((row.trials, row.successes), (3, 2));
        assert!((row.success_rate - 2.0 / 3.0).abs() < 1e-15);
        assert_eq!(row.speed_cm_s, Some(25.0));
        assert_eq!(row.planning.plans, 4);
        assert_eq!(row.planning.mean_plan_ms, Some(30.0));
        assert_eq!(row.planning.max_plan_ms, Some(60.0));
        assert_eq!(row.planning.mean_first_solution_ms, Some(5.0));
        assert_eq!(row.planning.mean_zmp_ms, Some(3.0));
        assert_eq!(row.planning.worst_zmp_margin_m, Some(-0.01));
        assert_eq!((row.paper_speed_cm_s, row.paper_success_rate), (Some(9.5), Some(1.0)));
        assert_eq!(row.target_speed_cm_s, Some(19.0));
        // 2 of 3 is below 95 %.
        assert_eq!(row.meets_targets, Some(false));
        assert_eq!(row.failures, vec![TrialFailure { seed: 7, reason: "fell".into() }]);
        assert!((row.mean_trial_wall_s - 2.0).abs() < 1e-15);
    }

    #[test]
    fn targets_are_twice_the_paper_and_95_percent() {
        let fast = [report(true, 19.0, &[]), report(true, 19.0, &[])];
        assert_eq!(TerrainRow::new("pallet", &fast).meets_targets, Some(true));
        let slow = [report(true, 18.9, &[])];
        assert_eq!(TerrainRow::new("pallet", &slow).meets_targets, Some(false));
        let row = TerrainRow::new("flat", &fast);
        assert_eq!((row.paper_speed_cm_s, row.meets_targets), (None, None));
        let none = TerrainRow::new("gap", &[report(false, 0.0, &[])]);
        assert_eq!((none.speed_cm_s, none.planning.mean_plan_ms, none.meets_targets), (None, None, Some(false)));
    }

    #[test]
    fn table_i_is_the_papers() {
        let speeds: Vec<f64> = TABLE_I.iter().map(|p| p.speed_cm_s).collect();
        let success: Vec<f64> = TABLE_I.iter().map(|p| p.success_rate).collect();
        assert_eq!(speeds, [7.3, 9.5, 10.2, 12.7]);
        assert_eq!(success, [0.6, 1.0, 0.9, 0.9]);
        for p in TABLE_I {
            assert!(ScenarioSpec::embedded(p.scenario).is_ok(), "{}", p.scenario);
        }
    }
}
