//! The robots compiled into legwork (placeholder: being written).
use super::Model;

/// An unknown embedded robot name or a broken embedded description.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct EmbeddedError(pub String);

/// Names of the embedded robots.
pub fn names() -> &'static [&'static str] {
    &["hyq", "a1"]
}

/// Loads an embedded robot by name (`hyq`, `a1`).
pub fn load(name: &str) -> Result<Model, EmbeddedError> {
    Err(EmbeddedError(format!("embedded robot '{name}' not written yet")))
}
