//! Nguyen 2022's full-body trajectory optimization of the jumps (sec. II-C, eq. (3)-(4)) on
//! legwork's own rigid-body dynamics, solved by [`crate::ipocp`], from the contact-timing
//! result of [`crate::srb`]:
//!
//! - [`initial_guess`]: the robot's configuration, velocities, torques and contact forces
//!   per 10 ms knot from the single-rigid-body trajectory ([`crate::srb::SrbTrajectory`]).
//! - [`FullBodyProblem`]: eq. (3)-(4) as an ipocp problem (the formulation is in the
//!   documentation of `stage.rs`): the state is the configuration's deviation in the tangent
//!   space around the guess plus the velocity, the controls the joint torques and the stance
//!   feet's forces; [`FullBodyProblem::solve`] gives a [`FullBodyPlan`].
//! - [`check_limits`]: every limit of a plan at every knot, from its trajectory alone.

mod initial_guess;
pub mod kinematics;
mod limits;
mod momentum;
mod problem;
mod settings;
mod stage;

pub use initial_guess::{initial_guess, initial_guess_clear_of, pre_landing_configuration, BOX_MARGIN, IK_TOLERANCE, NOMINAL_POSE};
pub use limits::{check_limits, LimitReport, LimitRow, STANCE_DRIFT};
pub use problem::{FullBodyPlan, FullBodyProblem, SolveReport};
pub use settings::{BallisticFlight, BoxObstacle, FullBodySettings};
pub use stage::ConstraintKind;

/// What is wrong with a full-body problem's inputs.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FullBodyError {
    #[error("full-body setting `{field}` = {value}: expected {expected}")]
    Setting { field: &'static str, value: f64, expected: &'static str },
    #[error("robot model: {0}")]
    Model(String),
    #[error("initial guess: {0}")]
    Guess(String),
    #[error("full-body solve: {0}")]
    Solve(String),
    #[error("initial guess: foot '{foot}' cannot reach its contact point at knot {knot} (inverse kinematics leaves {distance:.2e} m)")]
    Unreachable { foot: String, knot: usize, distance: f64 },
}
