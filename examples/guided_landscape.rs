//! Does a task's own cost prefer the motion its targets ask for? A diagnostic, not a way to
//! solve the task (the general form of `trot_landscape`).
//!
//! 1. a *guided* task file (the task plus whatever waypoints put SLQ near the wanted motion:
//!    a prior the task itself may not carry) is solved from the standing PD;
//! 2. the task is solved by SLQ from the guided solution's policy.
//!
//! Both solutions' costs and target checks are printed; the second's cost is comparable
//! with the first augmented-Lagrangian round of `legwork solve TASK` (the same problem, the
//! same initial multipliers), and with an exploration's.
//!
//! ```text
//! cargo run --release --example guided_landscape -- guided.toml task.toml [iterations]
//! ```

use legwork::control::JointPd;
use legwork::model::embedded;
use legwork::ocp::{all_met, settled_stance, solution_trajectory, MotionMetrics, PdPolicy, TaskSpec};
use legwork::slq::{Slq, SlqSettings, SolutionPolicy};
use legwork::terrain::Plane;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [guided_path, task_path] = [0, 1].map(|i| args.get(i).cloned());
    let (Some(guided_path), Some(task_path)) = (guided_path, task_path) else {
        return Err("usage: guided_landscape guided.toml task.toml [iterations]".into());
    };
    let iterations: usize = args.get(2).map_or(Ok(60), |s| s.parse())?;
    let guided = TaskSpec::load_file(&guided_path)?;
    let task = TaskSpec::load_file(&task_path)?;
    let model = embedded::load(&task.robot)?;
    let terrain = Plane::flat(0.0);
    let initial = settled_stance(&model, &terrain, 1.0)?;
    let pd = JointPd::standing(&model, task.dt)?;
    let standing = PdPolicy(&pd);
    let settings = SlqSettings { max_iterations: iterations, ..SlqSettings::default() };
    let target = task.target(&model, &task_path)?;

    let guided_problem = guided.problem(&model, &terrain, initial.clone(), &guided_path)?;
    let guided_solution = Slq::new(&guided_problem, settings.clone())?.solve(&standing, |_| {})?;
    let problem = task.problem(&model, &terrain, initial, &task_path)?;
    let solution = Slq::new(&problem, settings)?.solve(&SolutionPolicy::new(&problem, &guided_solution, &standing), |_| {})?;
    for (what, problem, solution) in [("guided", &guided_problem, &guided_solution), ("the task from the guided policy", &problem, &solution)] {
        let trajectory = solution_trajectory(problem, solution, what);
        let m = MotionMetrics::of(&model, &trajectory, model.contact.friction);
        let results = target.check(&model, &trajectory, 1.0);
        println!("{what}: {:?} after {} iterations, cost {:.4e} -> {:.4e}", solution.termination, solution.iterations.len(), solution.cost_history[0], solution.cost_history.last().unwrap_or(&f64::NAN));
        println!("  final base {:.3?} m, rpy {:.1?} deg, lift-offs {:?}, foot slide {:.0?} mm", m.final_base_position, m.final_base_rpy_deg, m.liftoffs, m.slide.iter().map(|s| s * 1e3).collect::<Vec<_>>());
        for r in &results {
            println!("  {}: {} (required {}) {}", r.what, r.value, r.required, if r.met { "ok" } else { "MISSED" });
        }
        println!("  target {}", if all_met(&results) { "met" } else { "missed" });
    }
    Ok(())
}
