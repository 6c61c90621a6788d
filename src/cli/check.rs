//! `legwork check mujoco <folder>`: the plan of an earlier `legwork solve` (its
//! trajectory.json) checked in MuJoCo, beside legwork's own re-runs found in the folder.

use anyhow::{Context, Result};
use clap::{Args, Subcommand};
use legwork::export::{check_plan_in_mujoco, MujocoCheck};
use legwork::io::Trajectory;
use legwork::ocp::{MotionMetrics, TaskSpec};
use serde_json::json;
use std::path::PathBuf;

#[derive(Debug, Subcommand)]
pub enum CheckCommand {
    /// Replay a solve's plan (FOLDER/trajectory.json) in MuJoCo 4.0.0 with the tracking
    /// controller and with the exported feedback policy, print the task figures beside
    /// the plan's and legwork's re-runs (rerun_*.json in FOLDER), and write the runs and
    /// the figures to FOLDER/mujoco/ (summary.json). Needs `scripts/install-mujoco.sh`.
    Mujoco(MujocoArgs),
}

#[derive(Debug, Args)]
pub struct MujocoArgs {
    /// The output folder of `legwork solve` (or any folder with a trajectory.json).
    folder: PathBuf,
    /// The robot (embedded name, URDF or legwork description); default: the file's.
    #[arg(long)]
    robot: Option<String>,
}

pub fn run(cmd: CheckCommand) -> Result<()> {
    match cmd {
        CheckCommand::Mujoco(args) => mujoco(args),
    }
}

fn mujoco(args: MujocoArgs) -> Result<()> {
    let check = MujocoCheck::locate()?;
    let plan_path = args.folder.join("trajectory.json");
    let plan = Trajectory::load_file(&plan_path)?;
    let robot = args.robot.clone().unwrap_or_else(|| plan.metadata.robot.clone());
    let (model, _) = super::robot::load(&robot)?;
    plan.check_against(&model, &plan_path.display().to_string())?;
    let task = plan.summary.get("task").and_then(|t| t.as_str()).and_then(|t| TaskSpec::embedded(t).ok());
    let friction = model.contact.friction;
    let folder = args.folder.join("mujoco");
    say!("Checking {} in MuJoCo (tracking controller, feedback policy), friction {friction} ...", plan_path.display());
    let reruns = check_plan_in_mujoco(&check, &model, &plan, &plan.metadata.terrain, &folder)?;
    let plan_metrics = MotionMetrics::of(&model, &plan, model.contact.friction);
    // legwork's own re-runs, where the solve left them.
    let legwork_rerun = |file: &str| -> Result<Option<(Trajectory, MotionMetrics)>> {
        let path = args.folder.join(file);
        if !path.exists() {
            return Ok(None);
        }
        let traj = Trajectory::load_file(&path)?;
        let metrics = MotionMetrics::of(&model, &traj, model.contact.friction);
        Ok(Some((traj, metrics)))
    };
    let policy = legwork_rerun("rerun_slq_policy.json")?;
    let tracking = legwork_rerun("rerun_tracking.json")?;
    let mut columns = vec![super::solve::Column::completed("plan", &plan_metrics, &plan)];
    for (name, r) in [("SLQ policy", &policy), ("tracking ctrl", &tracking)] {
        if let Some((traj, metrics)) = r {
            columns.push(super::solve::Column::completed(name, metrics, traj));
        }
    }
    columns.push(super::solve::Column::of("MuJoCo track", &reruns.tracking));
    columns.push(super::solve::Column::of("MuJoCo policy", &reruns.policy));
    let waypoints: Vec<f64> = task.as_ref().map(|t| t.waypoints.iter().map(|w| w.time).collect()).unwrap_or_default();
    super::solve::print_figures(&model, &waypoints, &columns);
    let summary = json!({
        "plan": plan_path.display().to_string(),
        "mujoco_version": reruns.version,
        "friction": friction,
        "plan_figures": super::solve::metrics_json(&plan_metrics),
        "mujoco_tracking_controller": super::solve::rerun_json(&reruns.tracking),
        "mujoco_policy": super::solve::rerun_json(&reruns.policy),
    });
    let summary_path = folder.join("summary.json");
    std::fs::write(&summary_path, serde_json::to_string_pretty(&summary)?).with_context(|| format!("cannot write {}", summary_path.display()))?;
    say!("Wrote {} (model.xml, mujoco_track.json, mujoco_policy.json, summary.json)", folder.display());
    Ok(())
}
