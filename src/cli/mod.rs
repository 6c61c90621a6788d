//! Command-line interface (clap derive). One module per command group; errors are
//! `anyhow` here, at the edge, and printed with their causes.

/// `println!` for command output: when standard output is closed early (`legwork tasks |
/// head`) the command ends quietly with success; any other write error ends it with the
/// error printed.
macro_rules! say {
    ($($arg:tt)*) => {
        $crate::cli::emit(format_args!($($arg)*))
    };
}

/// The body of [`say!`].
pub(crate) fn emit(args: std::fmt::Arguments) {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    if let Err(e) = out.write_fmt(args).and_then(|_| out.write_all(b"\n")) {
        if e.kind() == std::io::ErrorKind::BrokenPipe {
            std::process::exit(0);
        }
        eprintln!("error: cannot write to standard output: {e}");
        std::process::exit(1);
    }
}

mod bench;
mod check;
mod control;
mod export;
mod jump;
mod robot;
mod simulate;
mod solve;
mod view;
mod walk;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

/// Whole-body motion generation for quadruped robots.
#[derive(Debug, Parser)]
#[command(name = "legwork", version, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Robot models: list the embedded robots, inspect one.
    #[command(subcommand)]
    Robot(robot::RobotCommand),
    /// Simulate a robot on the ground with a controller; writes the trajectory and prints
    /// a summary.
    Simulate(simulate::SimulateArgs),
    /// Optimize a motion for a task with SLQ (Neunert 2017), then re-run it in closed loop.
    Solve(solve::SolveArgs),
    /// List the embedded tasks.
    Tasks,
    /// Plan and run one of Nguyen 2022's 3D jumps: contact timing, full-body trajectory
    /// optimization, controllers in legwork's simulator. Writes the trajectory, a replay with
    /// the box, plots and a summary. Exit code 0: landed on target; 2: contact timing failed;
    /// 3: full-body optimization failed; 4: landed off target; 5: fell; 1: bad input.
    Jump(jump::JumpArgs),
    /// List the embedded jumps.
    Jumps,
    /// Walk to a goal over terrain (Winkler 2015): plan and execute one trial of a scenario;
    /// writes the trajectory, a replay with the plans drawn, plots and a summary.
    Walk(walk::WalkArgs),
    /// Benchmarks: the SLQ solver's speed and the embedded tasks; the walk over Winkler
    /// 2015's terrains (Table I).
    #[command(subcommand)]
    Bench(bench::BenchCommand),
    /// Write a robot (and the ground) in another simulator's format: MuJoCo's MJCF.
    #[command(subcommand)]
    Export(export::ExportCommand),
    /// Check a solved motion in physics legwork did not write: MuJoCo.
    #[command(subcommand)]
    Check(check::CheckCommand),
    /// Controllers for another simulator: `serve` answers states with torques over a pipe.
    #[command(subcommand)]
    Control(control::ControlCommand),
    /// Replay a trajectory: write a self-contained HTML page (3D robot, plots) and,
    /// optionally, static SVG plots.
    View(view::ViewArgs),
}

/// Parses the command line, runs the command, prints an error with its causes on failure.
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Jump(args) => return finish(jump::run(args)),
        Command::Robot(cmd) => robot::run(cmd),
        Command::Simulate(args) => simulate::run(args),
        Command::Solve(args) => solve::run(args),
        Command::Tasks => solve::list(),
        Command::Jumps => jump::list(),
        Command::Walk(args) => walk::run(args),
        Command::Bench(cmd) => bench::run(cmd),
        Command::View(args) => view::run(args),
        Command::Export(cmd) => export::run(cmd),
        Command::Check(cmd) => check::run(cmd),
        Command::Control(cmd) => control::run(cmd),
    };
    finish(result.map(|()| ExitCode::SUCCESS))
}

/// The command's exit code, or 1 with the error and its causes printed.
fn finish(result: anyhow::Result<ExitCode>) -> ExitCode {
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    #[test]
    fn command_line_definition_is_consistent() {
        Cli::command().debug_assert();
    }
}
