//! One robot argument for every front end (`--robot`, a task's `robot`, Python's
//! `legwork.Robot(...)`): an embedded name, a URDF file or a legwork description.

use super::{description, embedded, urdf, Model};
use std::path::Path;

/// Why a robot argument could not be loaded; the inner errors name the file and the field.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    #[error(transparent)]
    Embedded(#[from] embedded::EmbeddedError),
    #[error(transparent)]
    Urdf(#[from] urdf::UrdfError),
    #[error(transparent)]
    Description(#[from] description::DescriptionError),
    #[error("'{spec}' is neither an embedded robot ({names}) nor a .urdf file nor a legwork robot description (.toml)")]
    Unknown { spec: String, names: String },
}

/// Loads an embedded robot by name (unless a file of that name exists), or a `.urdf` /
/// `.toml` file by path.
///
/// ```
/// let hyq = legwork::model::load("hyq").unwrap();
/// assert_eq!((hyq.nq, hyq.nv), (19, 18));
/// assert!(legwork::model::load("no_such_robot").is_err());
/// ```
pub fn load(spec: &str) -> Result<Model, LoadError> {
    let path = Path::new(spec);
    if embedded::names().contains(&spec) && !path.exists() {
        return Ok(embedded::load(spec)?);
    }
    match path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
        Some("urdf") => Ok(urdf::load_file(path)?),
        Some("toml") => Ok(description::load_file(path)?),
        _ => Err(LoadError::Unknown { spec: spec.to_string(), names: embedded::names().join(", ") }),
    }
}

/// Whether `spec` names an embedded robot (and no file of that name shadows it).
pub fn is_embedded(spec: &str) -> bool {
    embedded::names().contains(&spec) && !Path::new(spec).exists()
}
