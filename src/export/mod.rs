//! Legwork's robots and terrains in other simulators' formats, so that a motion can be
//! checked in physics nobody on the team wrote (issue 16).
//!
//! * [`mjcf`]: MuJoCo's MJCF, written from legwork's own [`crate::model::Model`] and a
//!   [`crate::terrain::TerrainSpec`], with no MuJoCo dependency in the crate.
//! * [`mujoco_check`]: runs the MuJoCo checker (`python/legwork/mujoco_check.py`, Python with the
//!   `mujoco` package from PyPI in a virtual environment, `scripts/install-mujoco.sh`) on a
//!   trajectory and reads its run back as a legwork trajectory.

pub mod mjcf;
pub mod mujoco_check;
pub mod mujoco_plant;
pub mod standing_figures;

pub use mjcf::{mjcf_model, mujoco_qpos, mujoco_qvel, MjcfError, MjcfSettings};
pub use standing_figures::StandingFigures;
pub use mujoco_plant::MujocoPlant;
pub use mujoco_check::{check_plan_in_mujoco, replay_in_mujoco, stand_in_mujoco, CheckController, CheckRun, ControllerSettings, MujocoCheck, MujocoCheckError, MujocoReruns, StandingPd, TrackingGains};
