//! The jumping and landing controllers of Nguyen 2022, sec. III, at 1 kHz in legwork's
//! simulator:
//!
//! * [`reference`](mod@reference): the full-body optimization's 10 ms reference, interpolated to 1 kHz;
//! * [`tracking`]: the jumping controller, eq. (5) (Cartesian foot PD + joint PD +
//!   feed-forward);
//! * [`switch`]: the switch to landing when a foot force exceeds `delta` after `T_posing`;
//! * [`landing_qp`]: the landing QP on the single rigid body (clarabel);
//! * [`controller`]: both as one [`crate::sim::Controller`], with the swing legs held at the
//!   pre-landing configuration (Remark 2) and extended along the impact velocity for fast
//!   rotations (Remark 3);
//! * [`check_references`]: a standing and a dropped A1, references that need no optimizer;
//! * [`run`]: a whole jump in the simulator, [`run_jump`], and what it measured, [`JumpRun`].

pub mod check_references;
pub mod controller;
pub mod feet;
pub mod landing_qp;
pub mod reference;
pub mod run;
pub mod switch;
pub mod tracking;

#[cfg(test)]
mod tests;

pub use controller::{JumpController, JumpControllerStats, LandingSettings, LegExtension};
pub use landing_qp::{LandingQp, LandingQpInfo, LandingQpSettings, QpFoot, SrbState, SrbTarget};
pub use reference::{JumpReference, JumpTarget, PosingTolerance, ReferenceSample};
pub use run::{run_jump, run_jump_on, FallCriteria, JumpRun, JumpSettings};
pub use switch::LandingSwitch;
pub use tracking::{JumpGains, JumpTracking};

/// Why a jump controller cannot be built or a jump not run.
#[derive(Debug, thiserror::Error)]
pub enum JumpControlError {
    #[error("jump control setting `{field}`: expected {expected}")]
    Setting { field: &'static str, expected: String },
    #[error("jump reference: {0}")]
    Reference(String),
    #[error("robot: {0}")]
    Robot(String),
    #[error("landing QP: {0}")]
    Qp(String),
    #[error(transparent)]
    Sim(#[from] crate::sim::SimError),
}
