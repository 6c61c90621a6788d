//! The robots compiled into legwork, written in legwork's own description format
//! ([`super::description`]): `robots/hyq.toml` (IIT HyQ) and `robots/a1.toml` (Unitree A1).
//! Each file's header cites where its numbers come from; `tests/embedded_robots.rs` checks
//! them against the reference URDFs and Pinocchio's numbers.
//!
//! ```
//! let model = legwork::model::embedded::load("a1").unwrap();
//! assert_eq!(model.nq, 19);
//! assert!((model.total_mass() - 13.741).abs() < 1e-9);
//! assert!(legwork::model::embedded::load("spot").is_err());
//! ```

use super::description::{self, DescriptionError};
use super::Model;

/// `(name, file name used in errors, description text)`.
const ROBOTS: [(&str, &str, &str); 2] = [
    ("hyq", "hyq.toml", include_str!("../../robots/hyq.toml")),
    ("a1", "a1.toml", include_str!("../../robots/a1.toml")),
];

/// An unknown embedded robot name or a broken embedded description.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EmbeddedError {
    #[error("no embedded robot named '{name}' (embedded robots: {})", names().join(", "))]
    Unknown { name: String },
    #[error(transparent)]
    Description(#[from] DescriptionError),
}

/// Names of the embedded robots.
pub fn names() -> &'static [&'static str] {
    &["hyq", "a1"]
}

/// The description text of an embedded robot (the TOML file compiled in).
pub fn source(name: &str) -> Result<&'static str, EmbeddedError> {
    ROBOTS
        .iter()
        .find(|(n, _, _)| *n == name)
        .map(|(_, _, src)| *src)
        .ok_or_else(|| EmbeddedError::Unknown { name: name.to_string() })
}

fn file_name(name: &str) -> &'static str {
    ROBOTS.iter().find(|(n, _, _)| *n == name).map(|(_, f, _)| *f).unwrap_or("embedded")
}

/// The one-line summary of an embedded robot (its description's `summary`).
pub fn summary(name: &str) -> Result<String, EmbeddedError> {
    let src = source(name)?;
    Ok(description::parse(src, file_name(name))?.summary)
}

/// Loads an embedded robot by name (`hyq`, `a1`).
pub fn load(name: &str) -> Result<Model, EmbeddedError> {
    let src = source(name)?;
    Ok(description::from_str(src, file_name(name))?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_listed_robot_loads_and_has_a_summary() {
        assert_eq!(names().len(), ROBOTS.len());
        for name in names() {
            let m = load(name).unwrap_or_else(|e| panic!("{e}"));
            assert_eq!(m.name, *name);
            assert_eq!((m.nq, m.nv), (19, 18));
            assert_eq!(m.feet.len(), 4);
            assert!(m.reference_configuration("standing").is_some());
            assert!(!summary(name).unwrap().is_empty());
        }
    }

    #[test]
    fn unknown_name_lists_the_known_ones() {
        let e = load("spot").unwrap_err();
        assert_eq!(e.to_string(), "no embedded robot named 'spot' (embedded robots: hyq, a1)");
    }
}
