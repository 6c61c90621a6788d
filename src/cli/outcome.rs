//! Exit codes, the same for every command, so that a script or a batch job can tell a met
//! target from a missed one and both from bad input:
//!
//! | code | meaning |
//! |---|---|
//! | 0 | the job ran and met its target (a command without a target: it ran) |
//! | 1 | the job ran but missed its target: a solve's `[[target]]`, a walk that did not reach its goal, a jump that did not land on target |
//! | 2 | bad input: the command line, or the file, field or value the message names (also clap's usage errors) |
//! | 3 | the job could not finish: an optimizer failed, a simulation diverged, an output could not be written, the MuJoCo check could not run |
//!
//! `--json` summaries carry the same verdict (`"verdict"`, `"exit_code"`).


pub use legwork::job::{Verdict, BAD_INPUT, COULD_NOT_FINISH};

/// An error of a job that had started from valid input (exit code 3); any other error of a
/// command is its input's (exit code 2).
#[derive(Debug, thiserror::Error)]
#[error("{0:#}")]
pub struct CouldNotFinish(pub anyhow::Error);

/// Marks an error as the job's, not its input's.
pub trait OrCouldNotFinish<T> {
    fn or_could_not_finish(self) -> anyhow::Result<T>;
}

impl<T, E: Into<anyhow::Error>> OrCouldNotFinish<T> for Result<T, E> {
    fn or_could_not_finish(self) -> anyhow::Result<T> {
        self.map_err(|e| anyhow::Error::new(CouldNotFinish(e.into())))
    }
}

/// The exit code of a command's error.
pub fn error_code(e: &anyhow::Error) -> u8 {
    if e.chain().any(|c| c.downcast_ref::<CouldNotFinish>().is_some()) {
        COULD_NOT_FINISH
    } else {
        BAD_INPUT
    }
}
