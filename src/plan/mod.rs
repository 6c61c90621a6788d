//! Planning on terrain, Winkler 2015 sec. III: the generic graph search ([`search`]: A* and
//! ARA*) and the body action planner of sec. III-B ([`body`]), which reads the terrain
//! through the small [`TerrainCostField`] trait, and the footstep sequence planner of sec.
//! III-C ([`footstep`]).

pub mod body;
mod cost_field;
pub mod footstep;
pub mod search;

pub use cost_field::{costs_around, TerrainCostField};
