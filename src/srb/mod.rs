//! The single rigid body on SO(3) and Nguyen 2022's contact-timing optimization (sec. II-B):
//! eq. (1) discretized as (2h)-(2i), with the phase durations as decision variables
//! (augmented states), solved by [`crate::ipocp`]; [`solution`] reads a solution back as a
//! time-stamped trajectory and resamples it for the full-body optimization.

pub mod contact_timing;
pub mod exp_map;
mod params;
pub mod solution;
mod stage;

pub use contact_timing::{jumps, reference_jumps, BoxExtent, ContactTimingError, ContactTimingProblem, ContactTimingSettings, Contacts, JumpSpec, MAX_LANDING_EXTENSION};
pub use exp_map::ExpMap;
pub use params::{SrbParams, SrbParamsError};
pub use solution::{SrbKnot, SrbSolutionError, SrbTrajectory};
