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
        std::process::exit(outcome::COULD_NOT_FINISH.into());
    }
}

mod bench;
mod bench_mpc;
mod check;
mod control;
mod export;
mod jump;
mod mpc;
pub mod outcome;
mod report;
mod resources;
mod robot;
mod simulate;
mod solve;
mod view;
mod walk;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

/// Whole-body motion generation for quadruped robots.
#[derive(Debug, Parser)]
#[command(name = "legwork", version, about, long_about = None, after_help = EXIT_CODES)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
    /// Allow `--threads` above this machine's cores (capped at them otherwise, with a
    /// warning: more threads than cores only slow the work down).
    #[arg(long, global = true)]
    force_threads: bool,
    /// The memory a solve or a simulation may need (GB), estimated before it starts; a run
    /// that would need more is refused. Default: half of this machine's memory.
    #[arg(long, global = true, value_name = "GB", value_parser = resources::parse_gigabytes)]
    memory_limit: Option<f64>,
}

/// The most randomized trials a command runs (`--trials`): the papers use 10-20; a thousand
/// jump trials take minutes on two cores.
pub(crate) const MAX_TRIALS: usize = 1000;

/// Refuses a `--trials` count past [`MAX_TRIALS`].
pub(crate) fn check_trials(trials: usize) -> anyhow::Result<()> {
    if trials > MAX_TRIALS {
        anyhow::bail!("--trials: expected at most {MAX_TRIALS} (the papers run 10-20; a thousand take minutes), got {trials}");
    }
    Ok(())
}

/// Set once from `--force-threads` before a command runs.
static FORCE_THREADS: std::sync::OnceLock<bool> = std::sync::OnceLock::new();

/// The thread count a `--threads` option asked for, capped at the machine's cores unless
/// `--force-threads` was given (0 stays 0: one per core).
pub(crate) fn capped_threads(requested: usize) -> usize {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    if requested > cores && !FORCE_THREADS.get().copied().unwrap_or(false) {
        eprintln!("warning: --threads {requested}: capped at {cores}, this machine's cores (--force-threads to use more)");
        cores
    } else {
        requested
    }
}

/// The exit-code convention of every command ([`outcome`]).
const EXIT_CODES: &str = "Exit codes (every command): 0 the job ran and met its target (a command without a target: it ran); \
1 it ran but missed its target (a solve's [[target]], a walk short of its goal, a jump off target); \
2 bad input (command line, file, field, value); 3 the job could not finish (an optimizer failed, \
a simulation diverged, an output could not be written). --json summaries carry the verdict.";

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
    /// Run a task in closed loop under receding-horizon SLQ (MPC): its plan first, then the
    /// controller re-optimizing a short window from the measured state at a set rate,
    /// beside the simulator. Writes the closed-loop motion, the per-tick solve times and a
    /// summary. Exit code 0: the closed loop met the task's targets (at twice their
    /// tolerances); 1: it missed them.
    Mpc(mpc::MpcArgs),
    /// List the embedded tasks.
    Tasks,
    /// Plan and run one of Nguyen 2022's 3D jumps: contact timing, full-body trajectory
    /// optimization, controllers in legwork's simulator. Writes the trajectory, a replay with
    /// the box, plots and a summary. Exit code 0: landed on target; 1: landed off target or
    /// fell; 3: an optimization failed.
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
    /// One self-contained HTML page for one run or a set of runs (a bench's output folder):
    /// the summary table, each run's target checks and key figures, links to the replays.
    Report(report::ReportArgs),
}

/// Parses the command line, runs the command, prints an error with its causes on failure.
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    let _ = FORCE_THREADS.set(cli.force_threads);
    let _ = resources::MEMORY_LIMIT_GB.set(cli.memory_limit);
    let result = match cli.command {
        Command::Jump(args) => return finish(jump::run(args)),
        Command::Solve(args) => return finish(solve::run(args).map(ExitCode::from)),
        Command::Mpc(args) => return finish(mpc::run(args).map(ExitCode::from)),
        Command::Walk(args) => return finish(walk::run(args).map(ExitCode::from)),
        Command::Bench(cmd) => return finish(bench::run(cmd).map(ExitCode::from)),
        Command::Robot(cmd) => robot::run(cmd),
        Command::Simulate(args) => simulate::run(args),
        Command::Tasks => solve::list(),
        Command::Jumps => jump::list(),
        Command::View(args) => view::run(args),
        Command::Report(args) => report::run(args),
        Command::Export(cmd) => export::run(cmd),
        Command::Check(cmd) => check::run(cmd),
        Command::Control(cmd) => control::run(cmd),
    };
    finish(result.map(|()| ExitCode::SUCCESS))
}

/// The command's exit code, or the error with its causes printed and its code
/// ([`outcome::error_code`]: 3 for a job that could not finish, 2 for bad input).
fn finish(result: anyhow::Result<ExitCode>) -> ExitCode {
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(outcome::error_code(&e))
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

    #[test]
    fn tracking_base_position_sets_the_three_axes_before_the_scale() {
        let default = legwork::mpc::TrackingWeights::default();
        assert_eq!(mpc::tracking_weights(10.0, None).unwrap(), default.scaled(10.0));
        let weights = mpc::tracking_weights(10.0, Some("1000, 3000,500")).unwrap();
        assert_eq!(weights.base_position, [1e4, 3e4, 5e3]);
        assert_eq!(legwork::mpc::TrackingWeights { base_position: default.scaled(10.0).base_position, ..weights }, default.scaled(10.0));
        for bad in ["1000,2000", "1000,2000,1000,1", "1000,nan,1000", "1000,-1,1000", "a,b,c", ""] {
            let message = mpc::tracking_weights(1.0, Some(bad)).unwrap_err().to_string();
            assert!(message.contains(&format!("--tracking-base-position {bad}:")) && message.contains("three finite weights >= 0"), "{message}");
        }
    }
}
