//! `legwork view <trajectory.json> [--robot R] [--out replay.html] [--plots DIR]`.

use anyhow::{Context, Result};
use clap::Args;
use legwork::io::Trajectory;
use legwork::model::embedded;
use legwork::viz;
use std::path::PathBuf;
use std::time::Instant;

#[derive(Debug, Args)]
pub struct ViewArgs {
    /// A trajectory file written by legwork (trajectory.json).
    trajectory: PathBuf,
    /// The robot that plays it: an embedded robot (`legwork robot list`), a `.urdf` or a
    /// legwork description (`.toml`). Default: the file's `metadata.robot`, embedded.
    #[arg(long, value_name = "NAME|FILE")]
    robot: Option<String>,
    /// Where to write the replay page (one self-contained HTML file).
    #[arg(long, value_name = "FILE", default_value = "replay.html")]
    out: PathBuf,
    /// Also write static SVG plots (base pose and twist, torques, contact forces, gait)
    /// into this folder.
    #[arg(long, value_name = "DIR")]
    plots: Option<PathBuf>,
    /// With --plots, also write each plot as PNG (2x, text in the embedded DejaVu Sans).
    #[arg(long, requires = "plots")]
    png: bool,
}

pub fn run(args: ViewArgs) -> Result<()> {
    let started = Instant::now();
    let origin = args.trajectory.display().to_string();
    let traj = Trajectory::load_file(&args.trajectory)?;
    let model = match &args.robot {
        Some(spec) => super::robot::load(spec)?.0,
        None => {
            let name = &traj.metadata.robot;
            embedded::load(name).with_context(|| {
                format!("{origin}: metadata.robot: '{name}' is not an embedded robot; give its file with --robot FILE.urdf or FILE.toml")
            })?
        }
    };
    traj.check_against(&model, &origin)?;
    viz::write_replay(&model, &traj, &args.out)?;
    let size = std::fs::metadata(&args.out).map(|m| m.len()).unwrap_or(0);
    say!(
        "replay: {} ({:.1} kB): robot {}, '{}', {:.3} s, {} knots",
        args.out.display(),
        size as f64 / 1e3,
        model.name,
        traj.metadata.scenario,
        traj.duration(),
        traj.knots.len()
    );
    if let Some(dir) = &args.plots {
        let mut files = viz::write_plots(&traj, dir)?;
        if args.png {
            let pngs = viz::png::write_pngs(&files, viz::png::PNG_SCALE)?;
            files.extend(pngs);
        }
        for file in files {
            say!("plot:   {}", file.display());
        }
    }
    say!("done in {:.2} s; open {} in a web browser (works offline)", started.elapsed().as_secs_f64(), args.out.display());
    Ok(())
}
