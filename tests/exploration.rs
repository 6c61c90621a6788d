//! Exploration (issue 19): multi-start SLQ with successive halving and a sampling stage.
//! On a short task so each case takes a fraction of a second: the pick does not depend on
//! the number of threads, start 0 is the single start, the kept start is the cheapest, the
//! sampling stage never does worse than the standing PD's rollout, and bad settings are
//! named.

use legwork::control::JointPd;
use legwork::model::embedded;
use legwork::ocp::{explore, settled_stance, solve_task, Exploration, ExplorationSpec, PdPolicy, SamplingSpec, SolveOptions, TaskSpec};
use legwork::slq::{Slq, SlqSettings};
use legwork::terrain::Plane;

/// A 0.2 s task: shift the base 3 cm forward and 2 cm down.
const TASK: &str = r#"
name = "shift"
summary = "shift the base"
robot = "hyq"
duration = 0.2
dt = 0.002
[desired]
base_position = [0.03, "start", -0.02]
joints = "stance"
[running]
base_orientation = [100.0, 100.0, 100.0]
joint_velocity = 0.01
[final]
base_position = [1000.0, 1000.0, 1000.0]
base_linear_velocity = [10.0, 10.0, 10.0]
[input]
weight = 1e-4
"#;

fn spec(extra: &str) -> TaskSpec {
    TaskSpec::from_toml(&format!("{TASK}\n{extra}"), "shift.toml").unwrap()
}

/// `exploration` of the short task on `threads` threads, and the standing PD's own first
/// rollout cost (a plain SLQ's).
fn explore_shift(exploration: &ExplorationSpec, threads: usize) -> (Exploration, f64) {
    let model = embedded::load("hyq").unwrap();
    let ground = Plane::flat(0.0);
    let task = spec("");
    let initial = settled_stance(&model, &ground, 0.5).unwrap();
    let problem = task.problem(&model, &ground, initial, "shift.toml").unwrap();
    let pd = JointPd::standing(&model, task.dt).unwrap();
    let judge = |_: &legwork::slq::SlqSolution<legwork::ocp::RobotState>| false;
    let found = explore(&problem, &pd, exploration, &SlqSettings::default(), threads, &judge).unwrap();
    let plain = Slq::new(&problem, SlqSettings { threads: 1, max_iterations: 1, ..SlqSettings::default() }).unwrap().solve(&PdPolicy(&pd), |_| {}).unwrap();
    (found, plain.cost_history[0])
}

#[test]
fn the_pick_is_the_cheapest_start_and_does_not_depend_on_threads() {
    let exploration = ExplorationSpec { starts: 5, seed: 11, screen_iterations: 3, rounds: 2, ..Default::default() };
    let (two, standing_rollout) = explore_shift(&exploration, 2);
    let (one, _) = explore_shift(&exploration, 1);
    assert_eq!(two.best, one.best);
    for (a, b) in two.starts.iter().zip(&one.starts) {
        assert_eq!((a.index, a.seed, a.cost, a.iterations, a.rounds), (b.index, b.seed, b.cost, b.iterations, b.rounds));
    }
    // Halving: five starts in round one, the cheaper three in round two.
    assert_eq!(two.starts.iter().filter(|s| s.rounds == 2).count(), 3);
    let best = &two.starts[two.best];
    assert_eq!(best.rounds, 2);
    assert!(two.starts.iter().filter(|s| s.rounds == 2).all(|s| best.cost <= s.cost), "{:#?}", two.starts);
    assert_eq!(*two.solution.cost_history.last().unwrap(), best.cost);
    // The random starts differ from each other and from the standing PD.
    let initial_costs: Vec<f64> = two.starts.iter().map(|s| s.initial_cost).collect();
    assert!(initial_costs.windows(2).all(|w| w[0] != w[1]), "{initial_costs:?}");
    // Start 0 is the single start: the standing PD, its first rollout a plain solve's.
    assert_eq!(two.starts[0].initial_cost, standing_rollout);
    assert_eq!(two.starts[0].seed, 0);
}

#[test]
fn the_sampling_stage_starts_no_worse_than_standing() {
    let sampling = SamplingSpec { population: 6, elite: 2, iterations: 2, starts: 2, ..Default::default() };
    let exploration = ExplorationSpec { starts: 1, screen_iterations: 2, sampling: Some(sampling), ..Default::default() };
    let (found, standing_rollout) = explore_shift(&exploration, 2);
    assert_eq!(found.starts.len(), 3);
    assert_eq!(found.starts[0].initial_cost, standing_rollout);
    for s in &found.starts[1..] {
        // The first sample is the standing PD itself, so the cheapest samples cost at most its rollout.
        let sampled = s.sampled_cost.expect("a sampled start");
        assert!(sampled <= standing_rollout, "{sampled} > {standing_rollout}");
        // SLQ's first rollout of a sampled start is that sample's rollout.
        assert!((s.initial_cost - sampled).abs() <= 1e-9 * sampled.abs(), "{} vs {sampled}", s.initial_cost);
    }
}

#[test]
fn solve_task_explores_and_reports_the_kept_start() {
    let model = embedded::load("hyq").unwrap();
    let task = spec("[exploration]\nstarts = 3\nscreen_iterations = 2\n[[target]]\nbase_position = [0.03, \"start\", \"any\"]\nposition_tolerance = 0.5");
    let run = solve_task(&task, &model, &Plane::flat(0.0), "shift.toml", &SolveOptions { threads: 2, max_iterations: Some(6), ..SolveOptions::default() }, |_| ()).unwrap();
    let e = run.exploration.as_ref().expect("explored");
    assert_eq!(e.starts.len(), 3);
    assert_eq!(e.iterations, e.starts.iter().map(|s| s.iterations).sum::<usize>());
    assert!(e.starts.iter().all(|s| s.met == Some(true)), "{:#?}", e.starts);
    // --starts 1 (an override with one start and no sampling) is no exploration.
    let single = SolveOptions { threads: 2, max_iterations: Some(4), exploration: Some(ExplorationSpec { starts: 1, ..Default::default() }), value_function: false };
    assert!(solve_task(&task, &model, &Plane::flat(0.0), "shift.toml", &single, |_| ()).unwrap().exploration.is_none());
}

#[test]
fn bad_exploration_settings_name_the_file_and_field() {
    for (extra, expected) in [
        ("[exploration]\nstarts = 0", "exploration.starts"),
        ("[exploration]\nstarts = 4\nscreen_iterations = 20\nrounds = 2", "exploration.screen_iterations"),
        ("[exploration]\nsetpoint_noise = -0.1", "exploration.setpoint_noise"),
        ("[exploration.sampling]\nelite = 40", "exploration.sampling.elite"),
        ("[exploration.sampling]\nknot_interval = 0.0", "exploration.sampling.knot_interval"),
        ("[exploration]\nstart = 4", "start"),
        ("[exploration.sampling]\npopulations = 4", "populations"),
    ] {
        let message = TaskSpec::from_toml(&format!("{TASK}\n{extra}"), "shift.toml").unwrap_err().to_string();
        assert!(message.contains("shift.toml") && message.contains(expected), "'{message}' does not name {expected}");
    }
}
