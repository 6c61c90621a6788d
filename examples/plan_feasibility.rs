//! The feasibility figures of saved plans (`legwork solve` writes `trajectory.json`): one
//! table row per file, in the columns of docs/experiments/feasible-slq.md.
//!
//! ```sh
//! cargo run --release --example plan_feasibility -- out/gallop/trajectory.json out/trot/trajectory.json
//! ```
//!
//! The robot is the one the trajectory names (embedded), the friction coefficient its
//! contact model's unless `--mu` is given.

use anyhow::{bail, Context, Result};
use legwork::io::Trajectory;
use legwork::ocp::{MotionMetrics, FRICTION_MARGIN};

fn main() -> Result<()> {
    let mut mu: Option<f64> = None;
    let mut files = Vec::new();
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        if a == "--mu" {
            mu = Some(args.next().context("--mu needs a number")?.parse().context("--mu needs a number")?);
        } else {
            files.push(a);
        }
    }
    if files.is_empty() {
        bail!("usage: plan_feasibility [--mu MU] TRAJECTORY.json ...");
    }
    println!("| plan | max abs(tau)/limit | knots at limit | max joint-limit excess (deg) | max abs(v)/limit | loaded knots over {FRICTION_MARGIN} mu | max friction ratio | slide while loaded per foot (mm) | sliding share per foot (%) | max penetration (mm) |");
    println!("|---|---:|---:|---:|---:|---:|---:|---|---|---:|");
    for file in files {
        let traj = Trajectory::load_file(&file)?;
        let model = legwork::model::embedded::load(&traj.metadata.robot).with_context(|| format!("{file}: robot {}", traj.metadata.robot))?;
        let m = MotionMetrics::of(&model, &traj, mu.unwrap_or(model.contact.friction));
        let f = &m.feasibility;
        println!(
            "| {file} | {:.3} | {:.1} % | {} | {:.2} | {:.1} % | {:.3} | {} | {} | {:.1} |",
            f.max_torque_ratio,
            100.0 * f.knots_at_torque_limit,
            m.joint_limit_excess.as_ref().map_or("none".into(), |e| format!("{:.1} {}", e.excess_deg, e.joint.trim_end_matches("_joint"))),
            f.max_joint_velocity_ratio,
            100.0 * f.friction_margin_excess,
            f.max_friction_ratio,
            m.slide.iter().map(|s| format!("{:.0}", s * 1e3)).collect::<Vec<_>>().join("/"),
            f.sliding_share.iter().map(|s| format!("{:.0}", 100.0 * s)).collect::<Vec<_>>().join("/"),
            1e3 * f.max_penetration,
        );
    }
    Ok(())
}
