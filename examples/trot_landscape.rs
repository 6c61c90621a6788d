//! Does the trot task's own cost prefer a trot? A diagnostic, not a way to solve the task.
//!
//! `legwork solve trot` starts from the standing PD controller (Neunert 2017, Alg. 1) and
//! ends in a trajectory that stands, slides its feet and hops at the end (BENCHMARKS.md).
//! This example asks whether a trot exists at a lower cost of the same task:
//!
//! 1. a *guided* task: the trot task plus foot-height waypoints (eq. 5 on the feet) that
//!    lift LF+RH and RF+LH in turn, every `period / 2` seconds from 1 s to 7 s. That is a
//!    gait pattern with timings, which the issue forbids in a task file: it is used here
//!    only to put SLQ near a trot;
//! 2. the plain trot task, solved by SLQ from the guided solution's policy.
//!
//! It prints both solutions' figures; the second's final cost is comparable with
//! `legwork solve trot`'s.
//!
//! ```text
//! cargo run --release --example trot_landscape -- [weight] [period] [task.toml]
//! ```
//! `weight`: the waypoints' foot-height weight (default 1e4); `period`: the gait period in
//! seconds (default 2.0: four steps per diagonal pair, as the paper's trot); `task.toml`:
//! the trot task (default: the embedded one).

use legwork::control::JointPd;
use legwork::model::{embedded, Model};
use legwork::ocp::{settled_stance, solution_trajectory, MotionMetrics, PdPolicy, RobotState, TaskSpec, WholeBodyProblem};
use legwork::slq::{Slq, SlqSettings, SlqSolution, SolutionPolicy};
use legwork::terrain::Plane;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let weight: f64 = args.first().map_or(Ok(1e4), |s| s.parse())?;
    let period: f64 = args.get(1).map_or(Ok(2.0), |s| s.parse())?;
    if !(weight >= 0.0 && period > 0.0) {
        return Err(format!("expected a weight >= 0 and a period > 0 s, got {weight} and {period}").into());
    }
    let (text, origin) = match args.get(2) {
        Some(path) => (std::fs::read_to_string(path)?, path.clone()),
        None => (legwork::ocp::EMBEDDED_TASKS.iter().find(|(name, _)| *name == "trot").map(|(_, text)| text.to_string()).ok_or("no embedded trot")?, "trot".to_string()),
    };
    let task = TaskSpec::from_toml(&text, &origin)?;

    let mut guided_text = text.clone();
    let (mut t, mut first_pair) = (1.0, true);
    while t <= 7.0 + 1e-9 {
        let [a, b] = if first_pair { ["lf_foot", "rh_foot"] } else { ["rf_foot", "lh_foot"] };
        guided_text.push_str(&format!(
            "\n[[waypoint]]\ntime = {t}\nrho = 400.0\ndesired = {{ feet = {{ {a} = [\"start\", \"start\", 0.10], {b} = [\"start\", \"start\", 0.10] }} }}\nweights = {{ feet = {{ {a} = [0.0, 0.0, {weight}], {b} = [0.0, 0.0, {weight}] }} }}\n"
        ));
        t += period / 2.0;
        first_pair = !first_pair;
    }
    let guided = TaskSpec::from_toml(&guided_text, "guided trot")?;

    let model = embedded::load("hyq")?;
    let terrain = Plane::flat(0.0);
    let initial = settled_stance(&model, &terrain, 1.0)?;
    let pd = JointPd::standing(&model, task.dt)?;
    let standing = PdPolicy(&pd);
    let settings = SlqSettings { max_iterations: task.iterations.unwrap_or(40), ..SlqSettings::default() };

    let guided_problem = guided.problem(&model, &terrain, initial.clone(), "guided trot")?;
    let guided_solution = Slq::new(&guided_problem, settings.clone())?.solve(&standing, |_| {})?;
    report("guided (foot-height waypoints)", &model, &guided_problem, &guided_solution);

    let problem = task.problem(&model, &terrain, initial, &origin)?;
    let solution = Slq::new(&problem, settings)?.solve(&SolutionPolicy::new(&problem, &guided_solution, &standing), |_| {})?;
    report("the trot task from the guided policy", &model, &problem, &solution);
    Ok(())
}

fn report(what: &str, model: &Model, problem: &WholeBodyProblem, solution: &SlqSolution<RobotState>) {
    let trajectory = solution_trajectory(problem, solution, what);
    let m = MotionMetrics::of(model, &trajectory);
    let pairs = |c: &[Option<f64>; 2]| c.iter().map(|c| c.map_or("-".into(), |c| format!("{c:.2}"))).collect::<Vec<String>>().join("/");
    println!("{what}:");
    println!("  {:?} after {} iterations, cost {:.4e} -> {:.4e}", solution.termination, solution.iterations.len(), solution.cost_history[0], solution.cost_history.last().unwrap_or(&f64::NAN));
    // A trot: diagonal pairs together (near +1), lateral pairs apart (negative).
    println!("  final base x {:.3} m, diagonal correlation {}, lateral correlation {}, lift-offs {:?}", m.final_base_position[0], pairs(&m.diagonal_correlation), pairs(&m.lateral_correlation), m.liftoffs);
    println!("  all feet down {:.0} %, first lift-off {}, foot slide {:?} mm", 100.0 * m.all_feet_down, m.first_liftoff_time.map_or("none".into(), |t| format!("{t:.2} s")), m.slide.iter().map(|s| (s * 1e3).round()).collect::<Vec<_>>());
}
