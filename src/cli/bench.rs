//! `legwork bench slq`: the solver's speed as the paper's Fig. 13 (time per iteration against
//! the number of knots, which must be linear) and every embedded task solved in full.

use anyhow::Result;
use clap::Subcommand;
use legwork::model::embedded;
use legwork::ocp::{settled_stance, solve_task, PdPolicy, SolveOptions, TaskSpec, EMBEDDED_TASKS};
use legwork::slq::{Slq, SlqSettings};
use legwork::terrain::Plane;
use serde_json::json;

#[derive(Debug, Subcommand)]
pub enum BenchCommand {
    /// SLQ: time per iteration against knots (HyQ), and every embedded task solved.
    Slq {
        /// Print the results as JSON.
        #[arg(long)]
        json: bool,
        /// Threads for the linearization (default: one per core).
        #[arg(long, default_value_t = 0)]
        threads: usize,
        /// Iterations timed per horizon.
        #[arg(long, default_value_t = 5)]
        iterations: usize,
    },
}

pub fn run(cmd: BenchCommand) -> Result<()> {
    match cmd {
        BenchCommand::Slq { json, threads, iterations } => slq(json, threads, iterations),
    }
}

/// Least-squares line `y = a + b x` and its R^2.
fn linear_fit(x: &[f64], y: &[f64]) -> (f64, f64, f64) {
    let n = x.len() as f64;
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let sxx: f64 = x.iter().map(|a| (a - mx) * (a - mx)).sum();
    let b = sxy / sxx;
    let a = my - b * mx;
    let ss_res: f64 = x.iter().zip(y).map(|(xi, yi)| (yi - a - b * xi).powi(2)).sum();
    let ss_tot: f64 = y.iter().map(|yi| (yi - my).powi(2)).sum();
    (a, b, 1.0 - ss_res / ss_tot)
}

fn slq(as_json: bool, threads: usize, iterations: usize) -> Result<()> {
    let model = embedded::load("hyq")?;
    let ground = Plane::flat(0.0);
    // Fig. 13: one cost structure (the squat jump's running and final costs, no waypoint),
    // horizons from 0.25 s to 3 s at dt = 2 ms; a fixed number of iterations each.
    let mut base = TaskSpec::embedded("squat_jump")?;
    base.waypoints.clear();
    let initial = settled_stance(&model, &ground, base.contact.unwrap_or_default(), 1.0)?;
    let pd = legwork::control::JointPd::standing(&model, base.dt)?;
    let mut scaling = Vec::new();
    for horizon in [0.25, 0.5, 1.0, 1.5, 2.0, 3.0] {
        let mut spec = base.clone();
        spec.duration = horizon;
        let problem = spec.problem(&model, &ground, initial.clone(), "bench")?;
        let settings = SlqSettings { threads, max_iterations: iterations, feedforward_tolerance: 0.0, relative_cost_tolerance: 0.0, ..Default::default() };
        let sol = Slq::new(&problem, settings)?.solve(&PdPolicy(&pd), |_| {})?;
        let n = sol.iterations.len().max(1) as f64;
        let mean = |f: &dyn Fn(&legwork::slq::IterationTiming) -> f64| sol.iterations.iter().map(|l| f(&l.timing)).sum::<f64>() / n * 1e3;
        let total = mean(&|t| t.linearization + t.backward_pass + t.line_search);
        scaling.push(json!({
            "horizon_s": horizon,
            "knots": spec.knots(),
            "iterations_timed": sol.iterations.len(),
            "ms_per_iteration": total,
            "linearization_ms": mean(&|t| t.linearization),
            "backward_pass_ms": mean(&|t| t.backward_pass),
            "line_search_ms": mean(&|t| t.line_search),
            "us_per_knot_per_iteration": total * 1e3 / spec.knots() as f64,
        }));
    }
    let knots: Vec<f64> = scaling.iter().map(|s| s["knots"].as_f64().unwrap_or(0.0)).collect();
    let times: Vec<f64> = scaling.iter().map(|s| s["ms_per_iteration"].as_f64().unwrap_or(0.0)).collect();
    let (intercept, slope, r2) = linear_fit(&knots, &times);

    let mut tasks = Vec::new();
    for (name, _) in EMBEDDED_TASKS {
        let spec = TaskSpec::embedded(name)?;
        let task_model = embedded::load(&spec.robot)?;
        let run = solve_task(&spec, &task_model, &ground, name, &SolveOptions { threads, max_iterations: None }, |_| {})?;
        let sol = &run.solution;
        tasks.push(json!({
            "task": name,
            "knots": spec.knots(),
            "iterations": sol.iterations.len(),
            "termination": format!("{:?}", sol.termination),
            "solve_time_s": sol.total_time,
            "initial_cost": sol.cost_history[0],
            "final_cost": sol.cost_history.last(),
            "ms_per_iteration": sol.iterations.iter().map(|l| l.timing.linearization + l.timing.backward_pass + l.timing.line_search).sum::<f64>() / sol.iterations.len().max(1) as f64 * 1e3,
        }));
    }
    let threads_used = if threads == 0 { rayon::current_num_threads() } else { threads };
    let report = json!({
        "robot": "hyq",
        "dt_s": base.dt,
        "threads": threads_used,
        "scaling": scaling,
        "linear_fit": { "ms_intercept": intercept, "ms_per_knot": slope, "r_squared": r2 },
        "tasks": tasks,
    });
    if as_json {
        say!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
    say!("SLQ time per iteration against knots (HyQ, dt = {} s, {threads_used} threads, {iterations} iterations each):", base.dt);
    say!("  {:>6} {:>6} {:>12} {:>12} {:>12} {:>12} {:>14}", "T [s]", "knots", "iter [ms]", "linearize", "backward", "line search", "us/knot/iter");
    for s in &scaling {
        say!(
            "  {:>6.2} {:>6} {:>12.1} {:>12.1} {:>12.1} {:>12.1} {:>14.1}",
            s["horizon_s"].as_f64().unwrap_or(0.0),
            s["knots"],
            s["ms_per_iteration"].as_f64().unwrap_or(0.0),
            s["linearization_ms"].as_f64().unwrap_or(0.0),
            s["backward_pass_ms"].as_f64().unwrap_or(0.0),
            s["line_search_ms"].as_f64().unwrap_or(0.0),
            s["us_per_knot_per_iteration"].as_f64().unwrap_or(0.0)
        );
    }
    say!("  linear fit: {intercept:.2} ms + {:.1} us x knots, R^2 = {r2:.4}", slope * 1e3);
    say!("Embedded tasks solved in full:");
    for t in &tasks {
        say!(
            "  {:<14} {:>5} knots  {:>3} iterations ({})  {:>6.2} s  cost {:.4e} -> {:.4e}",
            t["task"].as_str().unwrap_or(""),
            t["knots"],
            t["iterations"],
            t["termination"].as_str().unwrap_or(""),
            t["solve_time_s"].as_f64().unwrap_or(0.0),
            t["initial_cost"].as_f64().unwrap_or(0.0),
            t["final_cost"].as_f64().unwrap_or(0.0)
        );
    }
    Ok(())
}
