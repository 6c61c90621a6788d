//! The exported feedback policy of a planned motion: what `trajectory.json` carries for
//! another simulator or a robot,
//!
//! ```text
//! tau = tau_k + K_k [difference(q*(t), q); v - v*(t)],   k = floor(t / dt)
//! ```
//!
//! Neunert 2017, eq. (2), `u = u_ff + K (x - x*)`, on the physical state only (the gains of
//! [`crate::ocp::physical_gain`]). The feedforward `tau_k` and the gain `K_k` are held over
//! the knot interval, as the optimizer holds its input; the reference state `(q*, v*)` is
//! interpolated between knots (`q* = q_k (+) s (q_k+1 (-) q_k)`, `v*` linearly), so that a
//! controller faster than the knots does not pull the robot back to the interval's start.

use crate::linalg::gemv_add;
use super::interpolation::interpolate_state;
use crate::dynamics::difference;
use crate::io::Trajectory;
use crate::model::Model;
use crate::sim::{ControlError, Controller, SimState};
use nalgebra::{DMatrix, DVector};

/// The feedback policy of a trajectory file (its knots' `feedback_gain`).
pub struct FeedbackPolicy {
    dt: f64,
    t0: f64,
    q: Vec<DVector<f64>>,
    v: Vec<DVector<f64>>,
    tau: Vec<DVector<f64>>,
    gains: Vec<DMatrix<f64>>,
    q_ref: DVector<f64>,
    v_ref: DVector<f64>,
    dq: DVector<f64>,
    dx: DVector<f64>,
    u: DVector<f64>,
}

impl FeedbackPolicy {
    /// The policy of `plan` (checked against `model`); an error if a knot has no gains.
    pub fn new(model: &Model, plan: &Trajectory) -> Result<Self, ControlError> {
        let err = |problem: String| ControlError { controller: "policy".into(), problem };
        plan.check_against(model, "planned trajectory").map_err(|e| err(e.to_string()))?;
        plan.validate("planned trajectory").map_err(|e| err(e.to_string()))?;
        let (nv, nu) = (model.nv, model.nv - 6);
        let mut gains = Vec::with_capacity(plan.knots.len());
        for (k, knot) in plan.knots.iter().enumerate() {
            let rows = knot.feedback_gain.as_ref().ok_or_else(|| err(format!("knots[{k}] has no feedback_gain: the plan carries no feedback policy (write it with `legwork solve`)")))?;
            gains.push(DMatrix::from_fn(nu, 2 * nv, |i, j| rows[i][j]));
        }
        Ok(Self {
            dt: plan.metadata.dt,
            t0: plan.knots[0].t,
            q: plan.knots.iter().map(|k| DVector::from_column_slice(&k.q)).collect(),
            v: plan.knots.iter().map(|k| DVector::from_column_slice(&k.v)).collect(),
            tau: plan.knots.iter().map(|k| DVector::from_column_slice(&k.tau)).collect(),
            gains,
            q_ref: DVector::zeros(model.nq),
            v_ref: DVector::zeros(nv),
            dq: DVector::zeros(nv),
            dx: DVector::zeros(2 * nv),
            u: DVector::zeros(nu),
        })
    }
}

impl Controller for FeedbackPolicy {
    fn name(&self) -> &str {
        "policy"
    }

    fn compute(&mut self, model: &Model, state: &SimState, tau: &mut DVector<f64>) -> Result<(), ControlError> {
        let n = self.q.len();
        let position = ((state.t - self.t0) / self.dt).max(0.0);
        let k = ((position + 1e-9).floor() as usize).min(n - 1);
        let s = if k + 1 < n { (position - k as f64).clamp(0.0, 1.0) } else { 0.0 };
        // The reference between knots k and k + 1.
        let next = (k + 1).min(n - 1);
        interpolate_state(model, (&self.q[k], &self.v[k]), (&self.q[next], &self.v[next]), s, &mut self.dq, &mut self.q_ref, &mut self.v_ref);
        // dx = [q (-) q*; v - v*], u = tau_k + K_k dx.
        let nv = model.nv;
        difference(model, &self.q_ref, &state.q, &mut self.dq);
        self.dx.rows_mut(0, nv).copy_from(&self.dq);
        for i in 0..nv {
            self.dx[nv + i] = state.v[i] - self.v_ref[i];
        }
        self.u.copy_from(&self.tau[k]);
        gemv_add(&mut self.u, &self.gains[k], &self.dx);
        tau.rows_mut(6, self.u.len()).copy_from(&self.u);
        Ok(())
    }
}
