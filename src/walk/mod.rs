//! Winkler 2015's pipeline put together: a scenario (world and goal), the on-board terrain
//! map, the body-action and footstep planners, the ZMP body trajectory and its execution
//! in the simulator, with re-planning.

pub mod motion;
pub mod scenario;
pub mod trial;

pub use scenario::{BlockSpec, ScenarioError, ScenarioSpec, WorldSpec, EMBEDDED_SCENARIOS};
