//! Nguyen 2022's full-body trajectory optimization of the jumps (sec. II-C, eq. (3)-(4)) on
//! legwork's own rigid-body dynamics, solved by [`crate::ipocp`], from the contact-timing
//! result of [`crate::srb`]:
//!
//! - [`initial_guess`]: the robot's configuration, velocities, torques and contact forces
//!   per 10 ms knot from the single-rigid-body trajectory ([`crate::srb::SrbTrajectory`]).

mod initial_guess;
pub mod kinematics;

pub use initial_guess::{initial_guess, pre_landing_configuration, IK_TOLERANCE, NOMINAL_POSE};

/// What is wrong with a full-body problem's inputs.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FullBodyError {
    #[error("full-body setting `{field}` = {value}: expected {expected}")]
    Setting { field: &'static str, value: f64, expected: &'static str },
    #[error("robot model: {0}")]
    Model(String),
    #[error("initial guess: {0}")]
    Guess(String),
    #[error("initial guess: foot '{foot}' cannot reach its contact point at knot {knot} (inverse kinematics leaves {distance:.2e} m)")]
    Unreachable { foot: String, knot: usize, distance: f64 },
}
