//! An inclined plane: the ground model of Neunert 2017 (sec. IV-A).

use super::{Terrain, TerrainSpec};
use nalgebra::{Matrix3, Vector3};

/// The plane `n . (p - (0, 0, elevation)) = 0`, with unit normal `n` (`n_z > 0`).
///
/// ```
/// use legwork::terrain::{Plane, Terrain};
/// use nalgebra::Vector3;
/// // 10 % slope rising along x.
/// let plane = Plane::new(0.2, Vector3::new(-0.1, 0.0, 1.0)).unwrap();
/// assert!((plane.height(1.0, 5.0) - 0.3).abs() < 1e-12);
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct Plane {
    elevation: f64,
    normal: Vector3<f64>,
}

impl Plane {
    /// Horizontal ground at `elevation`.
    pub fn flat(elevation: f64) -> Self {
        Self { elevation, normal: Vector3::z() }
    }

    /// A plane through `(0, 0, elevation)` with normal `normal` (normalised here). The
    /// normal must be finite and point up: `normal.z > 0` (a vertical wall is no ground).
    pub fn new(elevation: f64, normal: Vector3<f64>) -> Result<Self, String> {
        if !elevation.is_finite() || !normal.iter().all(|x| x.is_finite()) {
            return Err(format!("elevation {elevation} and normal {normal:?} must be finite"));
        }
        let len = normal.norm();
        if len == 0.0 || normal.z / len < 1e-3 {
            return Err(format!(
                "normal ({}, {}, {}) must point up (positive z component)",
                normal.x, normal.y, normal.z
            ));
        }
        Ok(Self { elevation, normal: normal / len })
    }

    /// The ground estimate of Neunert 2017 (sec. IV-A): the plane `z = a x + b y + c`
    /// fitted by least squares to the last contact point of each foot (at least three,
    /// not collinear). Returns `None` when the points do not determine a plane.
    pub fn fit(points: &[Vector3<f64>]) -> Option<Self> {
        if points.len() < 3 {
            return None;
        }
        // Normal equations of min sum (a x + b y + c - z)^2.
        let mut ata = Matrix3::zeros();
        let mut atz = Vector3::zeros();
        for p in points {
            let row = Vector3::new(p.x, p.y, 1.0);
            ata += row * row.transpose();
            atz += row * p.z;
        }
        let abc = ata.try_inverse()? * atz;
        Plane::new(abc.z, Vector3::new(-abc.x, -abc.y, 1.0)).ok()
    }

    /// Unit normal.
    pub fn normal_vector(&self) -> Vector3<f64> {
        self.normal
    }
}

impl Terrain for Plane {
    /// `z = elevation - (n_x x + n_y y) / n_z`.
    fn height(&self, x: f64, y: f64) -> f64 {
        self.elevation - (self.normal.x * x + self.normal.y * y) / self.normal.z
    }
    fn normal(&self, _x: f64, _y: f64) -> Vector3<f64> {
        self.normal
    }
    fn spec(&self) -> TerrainSpec {
        TerrainSpec::Plane { elevation: self.elevation, normal: self.normal.into() }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fit_recovers_a_plane_from_four_feet() {
        let truth = Plane::new(0.05, Vector3::new(0.1, -0.2, 1.0)).unwrap();
        let feet: Vec<_> = [(0.37, 0.2), (0.37, -0.2), (-0.37, 0.2), (-0.37, -0.2)]
            .iter()
            .map(|&(x, y)| Vector3::new(x, y, truth.height(x, y)))
            .collect();
        let fitted = Plane::fit(&feet).unwrap();
        assert!((fitted.normal_vector() - truth.normal_vector()).norm() < 1e-12);
        assert!((fitted.height(1.0, 2.0) - truth.height(1.0, 2.0)).abs() < 1e-12);
        // Collinear points determine no plane.
        let line: Vec<_> = (0..4).map(|i| Vector3::new(i as f64, 0.0, 0.0)).collect();
        assert!(Plane::fit(&line).is_none());
    }

    #[test]
    fn walls_and_nan_are_refused() {
        assert!(Plane::new(0.0, Vector3::new(1.0, 0.0, 0.0)).is_err());
        assert!(Plane::new(f64::NAN, Vector3::z()).is_err());
        assert!(Plane::new(0.0, Vector3::zeros()).is_err());
    }
}
