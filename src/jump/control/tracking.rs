//! The jumping controller of Nguyen 2022, eq. (5): feed-forward torques of the full-body
//! optimization, a Cartesian PD on each foot relative to its hip mapped by the leg
//! Jacobian's transpose, and a joint PD.
//!
//! ```text
//! tau_ff = J(q_j)^T [K_p (p_f,d - p_f) + K_d (v_f,d - v_f)] + tau_d
//! tau    = tau_ff + K_p,joint (q_j,d - q) + K_d,joint (qd_j,d - qd)              (5)
//! ```

use super::feet::BaseFrameFeet;
use super::reference::ReferenceSample;
use super::JumpControlError;
use crate::model::Model;
use nalgebra::{DVector, Vector3};

/// Gains of eq. (5), the same on every leg. The paper prints no values; the defaults are
/// legwork's, chosen for the A1 at 1 kHz (see `docs/experiments/jump-control.md`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JumpGains {
    /// `K_p` (N/m), diagonal, base axes. Default 500 N/m.
    pub foot_kp: Vector3<f64>,
    /// `K_d` (N s/m). Default 10 N s/m: a foot of the A1 weighs about 0.3 kg seen from
    /// its hip, and a damper held over a 1 ms control period is stable for
    /// `K_d dt / m < 2`; 10 N s/m keeps it a factor 20 inside that.
    pub foot_kd: Vector3<f64>,
    /// `K_p,joint` (N m/rad). Default 40 N m/rad: a joint 0.2 rad off its target asks for
    /// a quarter of the A1's 33.5 N m, the feed-forward does the rest.
    pub joint_kp: f64,
    /// `K_d,joint` (N m s/rad). Default 1 N m s/rad (the A1's calf, about 5e-3 kg m^2
    /// about the knee, is stable at 1 kHz up to 10).
    pub joint_kd: f64,
}

impl Default for JumpGains {
    fn default() -> Self {
        Self { foot_kp: Vector3::repeat(500.0), foot_kd: Vector3::repeat(10.0), joint_kp: 40.0, joint_kd: 1.0 }
    }
}

impl JumpGains {
    pub fn validate(&self, field: &'static str) -> Result<(), JumpControlError> {
        let ok = |x: f64| x.is_finite() && x >= 0.0;
        if self.foot_kp.iter().chain(self.foot_kd.iter()).all(|&x| ok(x)) && ok(self.joint_kp) && ok(self.joint_kd) {
            Ok(())
        } else {
            Err(JumpControlError::Setting { field, expected: "finite, non-negative gains".into() })
        }
    }
}

/// Eq. (5) with its kinematics buffers, allocated once.
pub struct JumpTracking {
    feet: BaseFrameFeet,
}

impl JumpTracking {
    pub fn new(model: &Model) -> Result<Self, JumpControlError> {
        Ok(Self { feet: BaseFrameFeet::new(model)? })
    }

    /// Writes eq. (5)'s torques into `tau` for the joints of every leg whose foot has
    /// `legs[foot]` set (the others are left untouched), at the measured `(q, v)` and the
    /// reference `r`.
    pub fn compute(&mut self, model: &Model, q: &DVector<f64>, v: &DVector<f64>, r: &ReferenceSample, gains: &JumpGains, legs: &[bool], tau: &mut DVector<f64>) {
        self.feet.evaluate(model, q, v);
        let feet = &self.feet;
        for (i, leg) in feet.legs().iter().enumerate() {
            if !legs[leg.foot] {
                continue;
            }
            let dp = r.foot_position[leg.foot] - feet.position[i];
            let dv = r.foot_velocity[leg.foot] - feet.velocity[i];
            let force = gains.foot_kp.component_mul(&dp) + gains.foot_kd.component_mul(&dv);
            let cartesian = feet.jacobian[i].transpose() * force;
            for k in 0..3 {
                let (iq, iv) = (leg.q_index[k], leg.v_index[k]);
                tau[iv] = r.tau[iv] + cartesian[k] + gains.joint_kp * (r.q[iq] - q[iq]) + gains.joint_kd * (r.v[iv] - v[iv]);
            }
        }
    }
}
