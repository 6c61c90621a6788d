//! Files legwork writes and reads: the trajectory file (JSON, CSV export).

pub mod trajectory;

pub use trajectory::{Knot, Metadata, Summary, Trajectory, TrajectoryError, Units};
