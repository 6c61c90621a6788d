//! Joint-space PD to a fixed pose: the standing controller, and the initial stable control
//! law of the SLQ optimizer (Neunert 2017, sec. V: "All tasks are initialized with a simple
//! PD feedback controller on all joints and no feedforward control").

use crate::dynamics::{crba, Data};
use crate::model::Model;
use crate::sim::{ControlError, Controller, SimState};
use nalgebra::DVector;

/// `kd / kp` of the default gains (s).
const DAMPING_TIME_CONSTANT: f64 = 0.04;

/// Per-joint PD gains, indexed like `v` (the base entries unused).
#[derive(Clone, Debug, PartialEq)]
pub struct PdGains {
    /// Stiffness (N m / rad).
    pub kp: DVector<f64>,
    /// Damping (N m s / rad).
    pub kd: DVector<f64>,
}

impl PdGains {
    /// Gains derived from the robot itself, so that one rule serves HyQ and A1:
    ///
    /// * `kp_j = effort_j / 0.2 rad`: a joint 0.2 rad off its target asks for its full
    ///   effort (HyQ: 750 N m/rad; A1: 167-222 N m/rad);
    /// * `kd_j = min(kp_j tau_d, M_jj / dt_c)`: a damping time constant `tau_d = 40 ms`,
    ///   which damps the body bouncing on its legs (HyQ: 86.8 kg on four 750 N m/rad legs,
    ///   about 4 Hz) close to critically, capped for a swinging leg: a damper evaluated
    ///   every control period `dt_c` and held in between is unstable beyond
    ///   `kd dt_c / M_jj = 2`, with `M_jj` the joint-space inertia at `q_ref` (CRBA
    ///   diagonal: the leg below the joint); the cap is half of that. HyQ: 30 / 30 / 26
    ///   N m s/rad (HAA, HFE, KFE) at 1 kHz; A1: 6.7 / 6.7 / 7.3.
    ///
    /// Joints without a finite effort limit get the median of the others.
    pub fn from_model(model: &Model, q_ref: &DVector<f64>, control_dt: f64) -> Self {
        let mut data = Data::new(model);
        let m = crba(model, &mut data, q_ref).clone();
        let mut kp = DVector::zeros(model.nv);
        let mut finite: Vec<f64> = Vec::new();
        for j in model.actuated_joints() {
            let e = j.limits.effort[0];
            if e.is_finite() && e > 0.0 {
                finite.push(e);
            }
        }
        finite.sort_by(|a, b| a.total_cmp(b));
        let fallback = finite.get(finite.len() / 2).copied().unwrap_or(100.0);
        let mut kd = DVector::zeros(model.nv);
        for j in model.actuated_joints() {
            let e = j.limits.effort[0];
            let effort = if e.is_finite() && e > 0.0 { e } else { fallback };
            let i = j.idx_v;
            kp[i] = effort / 0.2;
            kd[i] = (kp[i] * DAMPING_TIME_CONSTANT).min(m[(i, i)] / control_dt);
        }
        Self { kp, kd }
    }

    /// These gains with each damper capped for the inertia its joint meets when the robot
    /// is free (in a flight phase; near it, for a swinging leg): `kd_j <= I_j / dt_c`, with
    /// `I_j = 1 / (M^-1)_jj` at `q_ref`, the inertia a torque on joint `j` alone drives when
    /// no other coordinate is held. [`PdGains::from_model`]'s cap uses `M_jj`, the inertia
    /// with every other coordinate held, which is larger, so in flight its dampers act past
    /// half of their discrete stability bound (`kd dt_c / I_j = 2`): past the deadbeat
    /// point, so a free joint's velocity changes sign every control period. For HyQ at
    /// 1 kHz the knees' dampers go from 26.2 to 22.0 N m s/rad; the hips' stay at 30 (bound
    /// by `kp tau_d`).
    pub fn capped_for_free_joints(mut self, model: &Model, q_ref: &DVector<f64>, control_dt: f64) -> Self {
        let mut data = Data::new(model);
        let m = crba(model, &mut data, q_ref).clone();
        // (M^-1)_jj from the Cholesky factor of M (positive definite for any valid model;
        // were it not, the gains would stay as they are).
        let Some(chol) = m.cholesky() else { return self };
        let m_inv = chol.inverse();
        for j in model.actuated_joints() {
            let i = j.idx_v;
            self.kd[i] = self.kd[i].min(1.0 / (m_inv[(i, i)] * control_dt));
        }
        self
    }
}

/// `tau_j = kp_j (q*_j - q_j) - kd_j v_j` on every actuated joint, no feedforward.
///
/// ```
/// use legwork::{model::embedded, control::JointPd};
/// let model = embedded::load("hyq").unwrap();
/// let pd = JointPd::standing(&model, 0.001).unwrap();
/// assert_eq!(pd.target().len(), model.nq);
/// ```
#[derive(Clone, Debug)]
pub struct JointPd {
    target: DVector<f64>,
    gains: PdGains,
}

impl JointPd {
    /// PD to `target` (a full configuration; its base part is ignored).
    pub fn new(model: &Model, target: DVector<f64>, gains: PdGains) -> Result<Self, ControlError> {
        let err = |problem: String| ControlError { controller: "joint PD".into(), problem };
        model.check_configuration(&target).map_err(|e| err(e.to_string()))?;
        if gains.kp.len() != model.nv || gains.kd.len() != model.nv {
            return Err(err(format!("gains need {} entries (nv), got kp {} and kd {}", model.nv, gains.kp.len(), gains.kd.len())));
        }
        if gains.kp.iter().chain(gains.kd.iter()).any(|g| !g.is_finite() || *g < 0.0) {
            return Err(err("gains must be finite and non-negative".into()));
        }
        Ok(Self { target, gains })
    }

    /// The standing controller: PD to the model's `standing` configuration (its neutral
    /// configuration if it has none), gains from [`PdGains::from_model`] for the control
    /// period `control_dt` (s).
    pub fn standing(model: &Model, control_dt: f64) -> Result<Self, ControlError> {
        let target = model.reference_configuration("standing").cloned().unwrap_or_else(|| model.neutral());
        let gains = PdGains::from_model(model, &target, control_dt);
        Self::new(model, target, gains)
    }

    pub fn target(&self) -> &DVector<f64> {
        &self.target
    }

    pub fn gains(&self) -> &PdGains {
        &self.gains
    }

    /// `tau = kp (q* - q) - kd v` into `tau` (actuated entries only), usable outside a
    /// simulation (for example as the optimizer's initial policy).
    pub fn torques(&self, model: &Model, q: &DVector<f64>, v: &DVector<f64>, tau: &mut DVector<f64>) {
        for j in model.actuated_joints() {
            let (iq, iv) = (j.idx_q, j.idx_v);
            tau[iv] = self.gains.kp[iv] * (self.target[iq] - q[iq]) - self.gains.kd[iv] * v[iv];
        }
    }
}

impl JointPd {
    /// The same torques for the actuated joints only (`u`, length `nv - 6`, in `v` order
    /// after the free-flyer base): the optimizer's input vector.
    pub fn actuated_torques(&self, model: &Model, q: &DVector<f64>, v: &DVector<f64>, u: &mut DVector<f64>) {
        for j in model.actuated_joints() {
            let (iq, iv) = (j.idx_q, j.idx_v);
            u[iv - 6] = self.gains.kp[iv] * (self.target[iq] - q[iq]) - self.gains.kd[iv] * v[iv];
        }
    }
}

impl Controller for JointPd {
    fn name(&self) -> &str {
        "stand"
    }
    fn compute(&mut self, model: &Model, state: &SimState, tau: &mut DVector<f64>) -> Result<(), ControlError> {
        self.torques(model, &state.q, &state.v, tau);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::embedded;

    /// HyQ at 1 kHz: the free-robot cap lowers the knee dampers (a leg's inertia with the
    /// body free is smaller than with it held), keeps every damper within the standing
    /// gains, and puts each at most at half its discrete stability bound, `kd dt / I_j <= 1`
    /// with `I_j = 1 / (M^-1)_jj`.
    #[test]
    fn free_joint_cap_halves_the_flight_stability_bound() {
        let model = embedded::load("hyq").unwrap();
        let q = model.reference_configuration("standing").unwrap().clone();
        let dt = 0.001;
        let standing = PdGains::from_model(&model, &q, dt);
        let free = standing.clone().capped_for_free_joints(&model, &q, dt);
        let m_inv = crba(&model, &mut Data::new(&model), &q).clone().cholesky().unwrap().inverse();
        for j in model.actuated_joints() {
            let i = j.idx_v;
            assert!(free.kd[i] <= standing.kd[i]);
            assert!(free.kd[i] * dt * m_inv[(i, i)] <= 1.0 + 1e-12);
            assert_eq!(free.kp[i], standing.kp[i]);
        }
        let kd = |name: &str| free.kd[model.v_index(name).unwrap()];
        let before = |name: &str| standing.kd[model.v_index(name).unwrap()];
        for knee in ["lf_kfe_joint", "rf_kfe_joint", "lh_kfe_joint", "rh_kfe_joint"] {
            assert!(kd(knee) < 0.9 * before(knee), "{knee}: {} against {}", kd(knee), before(knee));
        }
        // The standing gains of the knees were past the deadbeat point in flight.
        let knee = model.v_index("lf_kfe_joint").unwrap();
        assert!(before("lf_kfe_joint") * dt * m_inv[(knee, knee)] > 1.1);
    }
}
