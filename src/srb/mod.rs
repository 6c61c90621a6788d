//! The single rigid body on SO(3) and Nguyen 2022's contact-timing optimization (sec. II-B):
//! eq. (1) discretized as (2h)-(2i), with the phase durations as decision variables
//! (augmented states), solved by [`crate::ipocp`].

pub mod contact_timing;
pub mod exp_map;
mod params;
mod stage;

pub use contact_timing::{ContactTimingError, ContactTimingProblem, ContactTimingSettings, Contacts, JumpSpec, SrbKnot};
pub use exp_map::ExpMap;
pub use params::{SrbParams, SrbParamsError};
