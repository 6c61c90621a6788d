//! Nguyen 2022's 3D jumps: the jump files ([`spec`]), the jump and landing controllers
//! ([`control`]) with the robustness trials ([`trials`]), and the pipeline that plans, runs
//! and reports a jump ([`pipeline`], [`bench`](mod@bench)).

pub mod bench;
pub mod control;
pub mod pipeline;
pub mod spec;
pub mod trials;

pub use bench::{bench_jump, JumpBenchRow};
pub use pipeline::{box_obstacle, plan_contact_timing, plan_full_body, srb_plan_trajectory, ContactTimingStage, JumpReport, PipelineError, PipelineOptions, Stage, StageState, Verdict};
pub use spec::{embedded_jumps, ContactTimingOverrides, FullBodyOverrides, Jump, JumpError, PaperRow, Platform, StanceConflict, EMBEDDED_JUMPS, FOOT_NAMES};
