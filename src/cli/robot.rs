//! `legwork robot list` and `legwork robot info <name|path>`.

use anyhow::{Context, Result};
use clap::Subcommand;
use legwork::model::info::RobotInfo;
use legwork::model::{embedded, Model};

#[derive(Debug, Subcommand)]
pub enum RobotCommand {
    /// List the robots built into legwork, one line each.
    List,
    /// Show a robot: kinematic tree, masses, frames (feet marked), joint limits, the
    /// standing pose and the feet in it.
    Info {
        /// An embedded robot (`legwork robot list`), a URDF file (`.urdf`; the `standing`
        /// pose is read from an SRDF beside it) or a legwork description (`.toml`).
        robot: String,
    },
}

pub fn run(cmd: RobotCommand) -> Result<()> {
    match cmd {
        RobotCommand::List => list(),
        RobotCommand::Info { robot } => info(&robot),
    }
}

fn list() -> Result<()> {
    let width = embedded::names().iter().map(|n| n.len()).max().unwrap_or(0);
    let mut text = String::new();
    for name in embedded::names() {
        text += &format!("{name:<width$}  {}\n", embedded::summary(name)?);
    }
    print_out(&text)
}

/// Writes to standard output; a closed pipe (`legwork robot info hyq | head`) is not an error.
fn print_out(text: &str) -> Result<()> {
    use std::io::Write;
    match std::io::stdout().lock().write_all(text.as_bytes()) {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        other => Ok(other.context("cannot write to standard output")?),
    }
}

/// Where a robot came from, for the header of `robot info`.
pub(super) enum Origin {
    Embedded { summary: String },
    File,
}

/// Loads an embedded robot by name, or a `.urdf` / `.toml` file by path. The library's
/// errors already name the file, the field and the problem.
pub(super) fn load(spec: &str) -> Result<(Model, Origin)> {
    let model = legwork::model::load(spec)?;
    let origin = if legwork::model::is_embedded(spec) { Origin::Embedded { summary: embedded::summary(spec)? } } else { Origin::File };
    Ok((model, origin))
}

fn info(spec: &str) -> Result<()> {
    let (model, origin) = load(spec)?;
    let header = match origin {
        Origin::Embedded { summary } => format!("{} (embedded): {summary}", model.name),
        Origin::File => format!("{} (from {spec})", model.name),
    };
    print_out(&format!("{header}\n{}", RobotInfo::of(&model)))
}
