//! The nominal stance: where the feet stand, in the body frame, when the robot stands still.
//! The body planner puts each leg's nominal foothold there after every action (Winkler 2015
//! sec. III-B, `c_t` "around each leg after performing action a").

use super::BodyPlanError;
use crate::dynamics::{base_orientation, forward_kinematics, frame_position, Data};
use crate::model::description::LEG_ORDER;
use crate::model::Model;
use nalgebra::{Matrix3, Vector2, Vector3};

/// Horizontal foot positions in the body frame (x forward, y left), in the order LF, RF, LH,
/// RH.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NominalStance {
    pub feet: [Vector2<f64>; 4],
}

impl NominalStance {
    /// Checks the numbers: finite, and not all on one line (the orientation cost fits a plane
    /// through the four footholds).
    pub fn new(feet: [[f64; 2]; 4]) -> Result<Self, BodyPlanError> {
        for (leg, foot) in feet.iter().enumerate() {
            if !(foot[0].is_finite() && foot[1].is_finite()) {
                return Err(BodyPlanError::InvalidStance(format!(
                    "foot {} at ({}, {}): expected finite numbers",
                    LEG_ORDER[leg], foot[0], foot[1]
                )));
            }
        }
        let stance = Self { feet: feet.map(Vector2::from) };
        stance.plane_fit_rows().ok_or_else(|| BodyPlanError::InvalidStance("the four feet lie on one line: no plane fits them".into()))?;
        Ok(stance)
    }

    /// The stance of `model`'s `standing` reference configuration: forward kinematics, then
    /// each foot's position relative to the base, rotated into the base frame, its `z` dropped.
    /// For HyQ: (+-0.3708, +-0.3241) m.
    pub fn from_model(model: &Model) -> Result<Self, BodyPlanError> {
        let bad = |problem: &str| BodyPlanError::InvalidStance(format!("robot '{}': {problem}", model.name));
        if !model.has_free_flyer() {
            return Err(bad("expected a floating base (free-flyer root joint)"));
        }
        if model.feet.len() != 4 {
            return Err(bad(&format!("expected four feet (LF, RF, LH, RH), the model declares {}", model.feet.len())));
        }
        let q = model.reference_configuration("standing").ok_or_else(|| bad("expected a `standing` reference configuration"))?;
        let mut data = Data::new(model);
        forward_kinematics(model, &mut data, q);
        let base = Vector3::new(q[0], q[1], q[2]);
        let to_body = base_orientation(q.as_slice()).inverse();
        let mut feet = [[0.0; 2]; 4];
        for (k, foot) in model.feet.iter().enumerate() {
            let in_body = to_body * (frame_position(model, &data, foot.frame) - base);
            feet[k] = [in_body.x, in_body.y];
        }
        Self::new(feet)
    }

    /// The rows of the least-squares plane fit `z = a + b x + c y` through the four feet:
    /// `(a, b, c) = P z` with `P = (A^T A)^-1 A^T`, `A = [1 x_i y_i]`. The feet are fixed in
    /// the body frame, so `P` is computed once and each fit is three dot products. `None`
    /// when the feet are collinear.
    pub(super) fn plane_fit_rows(&self) -> Option<[[f64; 4]; 3]> {
        let mut ata = Matrix3::zeros();
        for f in &self.feet {
            let row = Vector3::new(1.0, f.x, f.y);
            ata += row * row.transpose();
        }
        // Relative to the stance's size, so that the test does not depend on units.
        let scale = ata.norm();
        let inverse = ata.try_inverse().filter(|inv| inv.norm() * scale < 1e12)?;
        let mut rows = [[0.0; 4]; 3];
        for (i, f) in self.feet.iter().enumerate() {
            let column = inverse * Vector3::new(1.0, f.x, f.y);
            for r in 0..3 {
                rows[r][i] = column[r];
            }
        }
        Some(rows)
    }
}
