//! The feedback gains `legwork solve` exports (trajectory.json's `feedback_gain`, on the
//! physical state only) hold a plan in legwork's simulator under a push; the feedforward
//! torques alone do not.

use legwork::control::FeedbackPolicy;
use legwork::io::Trajectory;
use legwork::model::embedded;
use legwork::ocp::{solve_task, SolveOptions, TaskSpec};
use legwork::sim::{Push, SimConfig, Simulator};
use legwork::terrain::Plane;
use nalgebra::Vector3;

const HOLD: &str = r#"
name = "hold"
summary = "stand still for 1.5 s"
robot = "hyq"
duration = 1.5
dt = 0.002
iterations = 5
[desired]
base_position = ["start", "start", "start"]
[running]
base_position = [100.0, 100.0, 100.0]
base_orientation = [100.0, 100.0, 100.0]
joint_position = 1.0
[final]
base_position = [1000.0, 1000.0, 1000.0]
[input]
weight = 1e-4
"#;

/// Replays `plan` with its exported policy and a 300 N sideways push of 0.2 s (a third of
/// HyQ's weight); returns the largest and the final distance of the base from the plan's,
/// or `None` if the run diverged.
fn pushed_replay(plan: &Trajectory) -> Option<(f64, f64)> {
    let model = embedded::load("hyq").unwrap();
    let ground = Plane::flat(0.0);
    let mut sim = Simulator::from_plan(&model, &ground, plan, SimConfig::default()).unwrap();
    sim.add_push(Push { force: Vector3::new(0.0, 300.0, 0.0), start: 0.4, duration: 0.2 });
    let mut policy = FeedbackPolicy::new(&model, plan).unwrap();
    let duration = plan.knots.last().unwrap().t;
    let run = sim.run(duration, &mut policy, |_| {}).ok()?;
    let base = |q: &[f64]| Vector3::new(q[0], q[1], q[2]);
    let planned_at = |t: f64| {
        let k = ((t / plan.metadata.dt).round() as usize).min(plan.knots.len() - 1);
        base(&plan.knots[k].q)
    };
    let errors: Vec<f64> = run.trajectory.knots.iter().map(|k| (base(&k.q) - planned_at(k.t)).norm()).collect();
    Some((errors.iter().copied().fold(0.0, f64::max), *errors.last().unwrap()))
}

#[test]
fn the_exported_gains_hold_the_plan_under_a_push() {
    let model = embedded::load("hyq").unwrap();
    let ground = Plane::flat(0.0);
    let spec = TaskSpec::from_toml(HOLD, "hold.toml").unwrap();
    let run = solve_task(&spec, &model, &ground, "hold.toml", &SolveOptions::default(), |_| {}).unwrap();
    let plan = &run.plan;
    // Gains on the physical state: 12 x 36 at every knot.
    assert!(plan.knots.iter().all(|k| k.feedback_gain.as_ref().is_some_and(|g| g.len() == 12 && g.iter().all(|r| r.len() == 36))));

    let (worst, last) = pushed_replay(plan).expect("the policy keeps the run finite");
    assert!(worst > 0.01, "the push moves the base ({worst} m)");
    assert!(worst < 0.08 && last < 0.01, "the policy brings the base back: worst {worst:.4} m, final {last:.4} m from the plan");

    // The same plan without its gains: the push throws the robot off the plan.
    let mut open_loop = plan.clone();
    for k in &mut open_loop.knots {
        for row in k.feedback_gain.as_mut().unwrap() {
            row.fill(0.0);
        }
    }
    match pushed_replay(&open_loop) {
        None => {}
        Some((worst_open, last_open)) => assert!(last_open > 5.0 * last.max(0.002), "feedforward alone should not recover: final {last_open:.4} m vs {last:.4} m (worst {worst_open:.4})"),
    }
}
