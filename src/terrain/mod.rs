//! The ground the feet touch: one [`Terrain`] trait giving the surface height and normal at
//! a point `(x, y)`, with two implementations,
//!
//! * [`Plane`]: a plane with elevation and inclination, the ground estimate of Neunert 2017
//!   (sec. IV-A: "a ground plane which is fitted to the last contact point of each foot",
//!   see [`Plane::fit`]);
//! * [`HeightMap`]: a regular grid of heights, bilinear between the grid points, the
//!   normal from the gradient of that interpolant; built in code (boxes, gaps, steps) or
//!   loaded from a TOML file ([`HeightMap::load_file`], format in [`HeightMap`]);
//! * [`Boxes`]: flat ground with axis-aligned boxes on it, exact edges (the platforms the
//!   jumps of Nguyen 2022 start from).
//!
//! The robot's own view of the ground is separate: [`TerrainMap`] (Winkler 2015 sec. III-A)
//! is an on-board grid built from noisy height samples of a `Terrain` around the robot,
//! with a terrain cost per cell from its geometric features ([`CostParams`]).
//!
//! [`TerrainSpec`] is the serialisable description of either, as stored in a trajectory
//! file or a scenario file; [`TerrainSpec::build`] turns it into a `Box<dyn Terrain>`.

mod boxes;
mod cost_features;
mod cost_map;
mod height_map;
mod plane;

pub use boxes::{BoxSpec, Boxes};
pub use cost_features::{CellAssessment, CellFeatures, CostParams, FeatureSaturation, FeatureWeights};
pub use cost_map::{
    standard_normal, CellRect, CellView, MapUpdate, SensorConfig, TerrainMap, TerrainMapConfig, TerrainMapError,
    MAX_BEST_COSTS, MAX_CELLS,
};
pub use height_map::{HeightMap, HeightMapFile};
pub use plane::Plane;

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// A surface `z = h(x, y)` with a unit normal pointing out of the ground (`n_z > 0`).
pub trait Terrain: Send + Sync {
    /// Height of the surface at `(x, y)`.
    fn height(&self, x: f64, y: f64) -> f64;
    /// Unit normal of the surface at `(x, y)`, pointing up (out of the ground).
    fn normal(&self, x: f64, y: f64) -> Vector3<f64>;
    /// Height and normal together (one lookup where an implementation can share work).
    fn surface(&self, x: f64, y: f64) -> (f64, Vector3<f64>) {
        (self.height(x, y), self.normal(x, y))
    }
    /// An upper bound of the surface height over the disk of `radius` around `(x, y)`
    /// (default: none). A foot sphere whose lowest point is above it touches nothing: this
    /// keeps a foot passing above a cliff's edge from touching the edge's tangent plane.
    fn highest_near(&self, _x: f64, _y: f64, _radius: f64) -> f64 {
        f64::INFINITY
    }
    /// The serialisable description of this terrain (for trajectory files and replays).
    fn spec(&self) -> TerrainSpec;
}

/// Problems with a terrain description; each names the file or field at fault.
#[derive(Debug, thiserror::Error)]
pub enum TerrainError {
    #[error("{path}: cannot read the height map: {error}")]
    Io { path: String, error: std::io::Error },
    #[error("{path}: {message}")]
    Parse { path: String, message: String },
    #[error("{origin}: field `{field}`: {problem}")]
    Invalid { origin: String, field: String, problem: String },
}

/// A terrain as data: what trajectory and scenario files store.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum TerrainSpec {
    /// A plane through `(0, 0, elevation)` with unit normal `normal`.
    Plane { elevation: f64, normal: [f64; 3] },
    /// A height map (see [`HeightMap`]).
    HeightMap(HeightMapFile),
    /// Flat ground at `ground` with boxes on it (see [`Boxes`]).
    Boxes { ground: f64, boxes: Vec<BoxSpec> },
}

impl TerrainSpec {
    /// Flat ground at height zero.
    pub fn flat() -> Self {
        TerrainSpec::Plane { elevation: 0.0, normal: [0.0, 0.0, 1.0] }
    }
    /// Checks the numbers and builds the terrain; `origin` names where the spec came from
    /// (a file, a field) for the error message.
    pub fn build(&self, origin: &str) -> Result<Box<dyn Terrain>, TerrainError> {
        Ok(match self {
            TerrainSpec::Plane { elevation, normal } => {
                Box::new(Plane::new(*elevation, Vector3::from(*normal)).map_err(|problem| TerrainError::Invalid {
                    origin: origin.into(),
                    field: "normal".into(),
                    problem,
                })?)
            }
            TerrainSpec::HeightMap(file) => Box::new(HeightMap::from_file_data(file.clone(), origin)?),
            TerrainSpec::Boxes { ground, boxes } => Box::new(
                Boxes::new(*ground, boxes.clone()).map_err(|(field, problem)| TerrainError::Invalid { origin: origin.into(), field, problem })?,
            ),
        })
    }
}
