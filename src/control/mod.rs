//! Controllers that run inside the simulator (and on a robot): the joint PD that holds a
//! pose, and the tracking controller of Neunert 2017 (sec. IV-B) that executes a planned
//! motion, and the feedback policy exported with a plan.

mod feedback_policy;
mod interpolation;
mod joint_pd;
mod tracking;
pub mod whole_body;

pub use feedback_policy::FeedbackPolicy;
pub use interpolation::{interpolate_state, knot_bracket, KnotBracket};
pub use joint_pd::{JointPd, PdGains};
pub use tracking::{BaseGains, TrackingController};
pub use whole_body::{
    clip_to_friction_cones, contact_forces, BodyMotion, DistributionInfo, DistributionProblem, DistributionSettings, FootKinematics, FootMotion, FrictionConeDistribution, LegMotion, MotionSource, WholeBodyController, WholeBodyError, WholeBodyGains, WholeBodyReference, WholeBodyStats, WholeBodyTick,
};
