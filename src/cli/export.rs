//! `legwork export mjcf <robot> [--scenario S | --task T | --jump J] [--out FILE]`: the robot
//! (and the ground of a walk scenario, a task or a jump with its box) as MuJoCo MJCF, from legwork's own model.

use anyhow::{Context, Result};
use clap::{Args, Subcommand};
use legwork::export::{mjcf_model, MjcfSettings};
use legwork::terrain::{Terrain, TerrainSpec};
use legwork::walk::ScenarioSpec;
use std::path::PathBuf;

#[derive(Debug, Subcommand)]
pub enum ExportCommand {
    /// MuJoCo MJCF: bodies, inertias, joints with their limits, foot spheres (the only
    /// colliding geoms, the robot's friction), torque motors at the effort limits, and the
    /// ground (flat, or a
    /// scenario's height map as an hfield); MuJoCo's default contact, 1 ms time step.
    Mjcf(MjcfArgs),
}

#[derive(Debug, Args)]
pub struct MjcfArgs {
    /// An embedded robot (`legwork robot list`), a URDF file or a legwork description.
    robot: String,
    /// A walk scenario (embedded name or file): its world at t = 0 as the ground.
    #[arg(long, conflicts_with = "task")]
    scenario: Option<String>,
    /// A task (embedded name or file): its ground (flat).
    #[arg(long, conflicts_with = "jump")]
    task: Option<String>,
    /// A jump (embedded name or file): the ground with its box.
    #[arg(long, conflicts_with = "scenario")]
    jump: Option<String>,
    /// Output file; standard output if absent.
    #[arg(long)]
    out: Option<PathBuf>,
}

pub fn run(cmd: ExportCommand) -> Result<()> {
    match cmd {
        ExportCommand::Mjcf(args) => mjcf(args),
    }
}

fn mjcf(args: MjcfArgs) -> Result<()> {
    let (model, _) = super::robot::load(&args.robot)?;
    let settings = MjcfSettings::default();
    let terrain = match (&args.scenario, &args.task) {
        _ if args.jump.is_some() => legwork::jump::Jump::load(args.jump.as_deref().unwrap_or_default())?.terrain().spec(),
        (Some(s), _) => ScenarioSpec::resolve(s)?.world_at(0.0).spec(),
        (None, Some(t)) => {
            // Tasks are solved on flat ground (`legwork solve`); the file is still checked.
            super::solve::load_task(t, &[])?;
            TerrainSpec::flat()
        }
        (None, None) => TerrainSpec::flat(),
    };
    let xml = mjcf_model(&model, &terrain, &settings)?;
    match &args.out {
        Some(path) => {
            std::fs::write(path, &xml).with_context(|| format!("cannot write {}", path.display()))?;
            eprintln!("Wrote {} ({} bodies, {} motors)", path.display(), model.njoints() - 1, model.actuated_joints().count());
        }
        None => say!("{}", xml.trim_end()),
    }
    Ok(())
}
