//! `legwork report <dir>...`: one self-contained HTML page for one run or a set of runs.

use super::outcome::OrCouldNotFinish;
use anyhow::Result;
use clap::Args;
use legwork::viz::report::{find_runs, write_report};
use std::path::PathBuf;

#[derive(Debug, Args)]
pub struct ReportArgs {
    /// Output folders of `legwork solve`, `simulate`, `walk` or `jump`, or folders of them
    /// (a bench's output): every folder with a trajectory.json is a run.
    #[arg(required = true, num_args = 1..)]
    dirs: Vec<PathBuf>,
    /// The page (default: `report.html` in the first folder).
    #[arg(long)]
    out: Option<PathBuf>,
    /// The page's title (default: "legwork report" and the folders).
    #[arg(long)]
    title: Option<String>,
}

pub fn run(args: ReportArgs) -> Result<()> {
    let runs = find_runs(&args.dirs)?;
    let out = args.out.clone().unwrap_or_else(|| args.dirs[0].join("report.html"));
    let title = args.title.clone().unwrap_or_else(|| format!("legwork report: {}", args.dirs.iter().map(|d| d.display().to_string()).collect::<Vec<_>>().join(", ")));
    write_report(&out, &title, &runs, &[]).or_could_not_finish()?;
    say!("Wrote {} ({} run{}: {})", out.display(), runs.len(), if runs.len() == 1 { "" } else { "s" }, runs.iter().map(|r| r.name.as_str()).collect::<Vec<_>>().join(", "));
    Ok(())
}
