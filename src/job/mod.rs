//! Jobs: what a `legwork` command does between reading its arguments and printing, so that
//! every front end (the command line, the Python package) runs the same job and writes the
//! same files. A job ends in a [`Verdict`] or a [`JobError`], which the command line turns
//! into its exit code and Python into an exception:
//!
//! | exit code | meaning |
//! |---|---|
//! | 0 | the job ran and met its target ([`Verdict::Met`]; a job without a target: it ran) |
//! | 1 | the job ran but missed its target ([`Verdict::Missed`]) |
//! | 2 | bad input ([`JobErrorKind::BadInput`]): the file, field or value the message names |
//! | 3 | the job could not finish ([`JobErrorKind::CouldNotFinish`]): an optimizer failed, a simulation diverged, an output could not be written |

pub mod jump;
pub mod mpc;
pub mod resources;
pub mod simulate;
pub mod solve;
pub mod walk;

/// How a job that ran ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Verdict {
    /// It met its target, or it has none and ran to the end.
    Met,
    /// It ran to the end and missed its target.
    Missed,
}

/// Exit code 1: ran, target missed.
pub const TARGET_MISSED: u8 = 1;
/// Exit code 2: bad input.
pub const BAD_INPUT: u8 = 2;
/// Exit code 3: the job could not finish.
pub const COULD_NOT_FINISH: u8 = 3;

impl Verdict {
    pub fn exit_code(self) -> u8 {
        match self {
            Verdict::Met => 0,
            Verdict::Missed => TARGET_MISSED,
        }
    }

    /// `"met"` or `"missed"`, as summaries write it.
    pub fn as_str(self) -> &'static str {
        match self {
            Verdict::Met => "met",
            Verdict::Missed => "missed",
        }
    }

    pub fn from_met(met: bool) -> Self {
        if met {
            Verdict::Met
        } else {
            Verdict::Missed
        }
    }
}

impl From<Verdict> for std::process::ExitCode {
    fn from(v: Verdict) -> Self {
        std::process::ExitCode::from(v.exit_code())
    }
}

/// Whose fault a job's error is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum JobErrorKind {
    /// The input's: a file, field or value (exit code 2).
    BadInput,
    /// The job's, started from valid input (exit code 3).
    CouldNotFinish,
}

/// A job's error: its kind and legwork's message (with its causes, `: `-separated).
#[derive(Debug, thiserror::Error)]
#[error("{message}")]
pub struct JobError {
    pub kind: JobErrorKind,
    pub message: String,
}

impl JobError {
    pub fn bad_input(e: impl std::fmt::Display) -> Self {
        Self { kind: JobErrorKind::BadInput, message: e.to_string() }
    }

    /// An error of a job that had started from valid input; the message carries `e`'s causes.
    pub fn could_not_finish(e: impl Into<Box<dyn std::error::Error + Send + Sync>>) -> Self {
        Self { kind: JobErrorKind::CouldNotFinish, message: chain(e.into().as_ref()) }
    }

    pub fn exit_code(&self) -> u8 {
        match self.kind {
            JobErrorKind::BadInput => BAD_INPUT,
            JobErrorKind::CouldNotFinish => COULD_NOT_FINISH,
        }
    }
}

/// `e` and its sources, `: `-separated (as `anyhow`'s `{:#}` prints them).
fn chain(e: &(dyn std::error::Error + 'static)) -> String {
    let mut text = e.to_string();
    let mut source = e.source();
    while let Some(s) = source {
        let part = s.to_string();
        if !text.contains(&part) {
            text = format!("{text}: {part}");
        }
        source = s.source();
    }
    text
}

/// Marks an error as the job's, not its input's.
pub(crate) trait OrCouldNotFinish<T> {
    fn or_could_not_finish(self) -> Result<T, JobError>;
}

impl<T, E: Into<Box<dyn std::error::Error + Send + Sync>>> OrCouldNotFinish<T> for Result<T, E> {
    fn or_could_not_finish(self) -> Result<T, JobError> {
        self.map_err(JobError::could_not_finish)
    }
}
