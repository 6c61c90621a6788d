//! Nguyen 2022's 3D jumps: the jump files ([`spec`]) and the pipeline that plans, runs and
//! reports a jump ([`pipeline`]).

pub mod bench;
pub mod pipeline;
pub mod spec;

pub use spec::{embedded_jumps, ContactTimingOverrides, Jump, JumpError, PaperRow, Platform, StanceConflict, EMBEDDED_JUMPS, FOOT_NAMES};
pub use pipeline::{plan_contact_timing, srb_plan_trajectory, ContactTimingStage, JumpReport, PipelineError, Stage, StageState, Verdict};
pub use bench::{bench_jump, JumpBenchRow};
