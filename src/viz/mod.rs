//! Looking at a motion: the HTML replay of a trajectory and static plots of it.
//!
//! * [`replay_html`] / [`write_replay`]: one self-contained HTML page (no network, no
//!   external file) with the robot in 3D (links drawn from the kinematic tree, feet, contact
//!   forces as arrows, the terrain), play/pause, a time slider, the playback speed, a camera
//!   that orbits (drag) and zooms (wheel) and follows the base; beside it, plots of the base
//!   pose and twist, the joint torques and the contact normal forces with a cursor at the
//!   current time. All geometry is computed here with legwork's own forward kinematics;
//!   the page only projects and draws.
//! * [`report::write_report`]: one self-contained HTML page for one run or a set of runs
//!   (`legwork report`): a summary table, each run's target checks and key figures, links
//!   to the replays.
//! * [`write_plots`]: static SVG figures for papers and reports (base pose, base twist,
//!   joint torques, contact forces, the gait diagram).
//!
//! ```no_run
//! use legwork::{io::Trajectory, model::embedded, viz};
//! let traj = Trajectory::load_file("trajectory.json")?;
//! let model = embedded::load(&traj.metadata.robot)?;
//! traj.check_against(&model, "trajectory.json")?;
//! viz::write_replay(&model, &traj, "replay.html")?;
//! let svgs = viz::write_plots(&traj, "plots")?;
//! println!("{} plots", svgs.len());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod jump;
pub mod mpc;
pub mod plots;
pub mod png;
pub mod replay;
pub mod report;
mod signals;
pub mod walk;

pub use plots::{write_cost_plot, write_limit_plots, write_plots};
pub use replay::{replay_html, replay_html_with_overlay, write_replay, write_replay_with_overlay, OverlayFoothold, OverlayPath, OverlaySupport, ReplayOverlay};

use crate::io::TrajectoryError;
use crate::terrain::TerrainError;

/// What can go wrong drawing a trajectory; each names the file or the field at fault.
#[derive(Debug, thiserror::Error)]
pub enum VizError {
    /// A file or folder cannot be written.
    #[error("{path}: {source}")]
    Io { path: String, source: std::io::Error },
    /// The trajectory is inconsistent, or does not fit the robot model.
    #[error(transparent)]
    Trajectory(#[from] TrajectoryError),
    /// The terrain stored in the trajectory cannot be built.
    #[error("metadata.terrain: {0}")]
    Terrain(#[from] TerrainError),
    /// A replay overlay that the page cannot draw.
    #[error("replay overlay: {field}: {problem}")]
    Overlay { field: String, problem: String },
    /// A folder or file given to a report that is not a run's.
    #[error("{path}: {problem}")]
    Report { path: String, problem: String },
    /// The plotting library failed on a figure.
    #[error("{path}: cannot draw the figure: {message}")]
    Plot { path: String, message: String },
}

impl VizError {
    pub(crate) fn io(path: &std::path::Path, source: std::io::Error) -> Self {
        VizError::Io { path: path.display().to_string(), source }
    }
}
