//! URDF import (placeholder: being written).
use super::Model;
use std::path::Path;

/// What kind of joint attaches the URDF root link to the world.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RootJoint {
    /// A six-degree-of-freedom free flyer (legged robots).
    FreeFlyer,
    /// The root link is welded to the world.
    Fixed,
}

/// A URDF that cannot become a model.
#[derive(Debug, thiserror::Error)]
#[error("{file}: {message}")]
pub struct UrdfError {
    pub file: String,
    pub message: String,
}

/// Loads a URDF file with a free-flyer root.
pub fn load_file(path: impl AsRef<Path>) -> Result<Model, UrdfError> {
    Err(UrdfError { file: path.as_ref().display().to_string(), message: "URDF import not written yet".into() })
}

/// Builds a model from URDF text; `source` names the file in errors.
pub fn from_str(_xml: &str, source: &str, _root: RootJoint) -> Result<Model, UrdfError> {
    Err(UrdfError { file: source.into(), message: "URDF import not written yet".into() })
}
