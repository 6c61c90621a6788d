//! The feet relative to the base, in base axes, from the joint angles alone: what the jump
//! controller's Cartesian PD (Nguyen 2022, eq. 5) tracks. The kinematics are evaluated with
//! the base at the identity pose, so world quantities are base-frame ones.

use super::JumpControlError;
use crate::control::whole_body::{foot_position, leg_chains, leg_jacobian, LegChain};
use crate::dynamics::{compute_joint_jacobians, Data};
use crate::model::Model;
use nalgebra::{DVector, Matrix3, Vector3};

/// Buffers of the base-frame leg kinematics, allocated once.
pub struct BaseFrameFeet {
    legs: Vec<LegChain>,
    data: Data,
    q_local: DVector<f64>,
    /// Per leg (order of [`Self::legs`]): foot position relative to the base (m), base axes.
    pub position: Vec<Vector3<f64>>,
    /// Foot velocity relative to the base, `J_leg(q) qd_leg` (m/s), base axes.
    pub velocity: Vec<Vector3<f64>>,
    /// The 3 x 3 leg Jacobian `d p_f / d q_leg`, base axes.
    pub jacobian: Vec<Matrix3<f64>>,
}

impl BaseFrameFeet {
    pub fn new(model: &Model) -> Result<Self, JumpControlError> {
        let legs = leg_chains(model).map_err(|e| JumpControlError::Robot(e.to_string()))?;
        let n = legs.len();
        Ok(Self {
            legs,
            data: Data::new(model),
            q_local: DVector::zeros(model.nq),
            position: vec![Vector3::zeros(); n],
            velocity: vec![Vector3::zeros(); n],
            jacobian: vec![Matrix3::zeros(); n],
        })
    }

    /// The legs (hip to knee joints of each foot).
    pub fn legs(&self) -> &[LegChain] {
        &self.legs
    }

    /// Feet positions, velocities and leg Jacobians at the joint state of `(q, v)`.
    pub fn evaluate(&mut self, model: &Model, q: &DVector<f64>, v: &DVector<f64>) {
        self.q_local.copy_from(q);
        // Base at the origin, identity quaternion (x, y, z, w).
        self.q_local.rows_mut(0, 7).copy_from_slice(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]);
        compute_joint_jacobians(model, &mut self.data, &self.q_local);
        for (i, leg) in self.legs.iter().enumerate() {
            let p = foot_position(&self.data, leg);
            let j = leg_jacobian(&self.data, leg, &p);
            let qd = Vector3::new(v[leg.v_index[0]], v[leg.v_index[1]], v[leg.v_index[2]]);
            self.position[i] = p;
            self.velocity[i] = j * qd;
            self.jacobian[i] = j;
        }
    }
}
