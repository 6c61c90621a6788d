//! Single-rigid-body parameters of a quadruped, derived from its legwork model: the robot
//! with its legs locked in the standing pose (Nguyen 2022, sec. II-B, "simplified rigid
//! body dynamics"; the same derivation as `../shared/anchors/nguyen2022/a1_srb_params.py`).

use crate::dynamics::{centroidal_map, update_frame_placements, Data};
use crate::model::{embedded, Model};
use nalgebra::{Matrix3, Vector3};

/// Mass, inertia and nominal feet of the single rigid body.
#[derive(Clone, Debug, PartialEq)]
pub struct SrbParams {
    /// Total mass (kg): the sum of the model's link masses.
    pub mass: f64,
    /// Composite inertia of all links, legs locked in the standing pose, about the
    /// whole-body CoM in base axes (kg m^2): the angular block of the centroidal momentum
    /// matrix for the base's angular velocity (Orin 2013), base orientation identity.
    pub inertia: Matrix3<f64>,
    /// The whole-body CoM in the base frame in the standing pose (m).
    pub com_in_base: Vector3<f64>,
    /// Feet relative to the CoM in base axes, standing pose, order LF, RF, LH, RH (m).
    pub foot_rel_com: [Vector3<f64>; 4],
}

/// What is missing from a model to derive the parameters.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SrbParamsError {
    #[error("model '{model}' has no reference configuration named '{pose}'")]
    NoPose { model: String, pose: String },
    #[error("model '{model}' has {feet} feet; the single rigid body needs 4 (LF, RF, LH, RH)")]
    FeetCount { model: String, feet: usize },
    #[error("embedded model: {0}")]
    Embedded(String),
}

impl SrbParams {
    /// Parameters of `model` in its reference configuration `pose`.
    pub fn from_model(model: &Model, pose: &str) -> Result<Self, SrbParamsError> {
        let q = model
            .reference_configuration(pose)
            .ok_or_else(|| SrbParamsError::NoPose { model: model.name.clone(), pose: pose.into() })?
            .clone();
        if model.feet.len() != 4 {
            return Err(SrbParamsError::FeetCount { model: model.name.clone(), feet: model.feet.len() });
        }
        let mut data = Data::new(model);
        let ag = centroidal_map(model, &mut data, &q).clone();
        let com = data.com;
        update_frame_placements(model, &mut data);
        let base = Vector3::new(q[0], q[1], q[2]);
        // Base orientation is the identity in a standing pose: base axes = world axes.
        let inertia = Matrix3::from_fn(|i, j| ag[(3 + i, 3 + j)]);
        let foot_rel_com = std::array::from_fn(|f| crate::dynamics::frame_position(model, &data, model.feet[f].frame) - com);
        Ok(Self { mass: model.total_mass(), inertia: 0.5 * (inertia + inertia.transpose()), com_in_base: com - base, foot_rel_com })
    }

    /// The Unitree A1 of legwork's embedded models, standing pose (base 0.26 m high, legs
    /// (0, 0.8, -1.81) rad): 13.741 kg, inertia about diag(0.141, 0.360, 0.390) kg m^2.
    pub fn a1() -> Result<Self, SrbParamsError> {
        let model = embedded::load("a1").map_err(|e| SrbParamsError::Embedded(e.to_string()))?;
        Self::from_model(&model, "standing")
    }
}
