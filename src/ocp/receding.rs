//! The whole-body problem as the window of a receding-horizon controller ([`crate::mpc`]):
//! its knots start at an absolute time that the controller moves between ticks, the task's
//! final cost acts at the task's end wherever that falls in the window, and a reference
//! motion (the plan being tracked) gives every knot, and the window's end, a cost toward
//! its state at that time:
//!
//! ```text
//! J = sum_k dt [ l_task(x_k, u_k, t_0 + k dt) + xr_k^T W_r xr_k ] + xr_N^T H_r xr_N
//!     + xb(t_f)^T H xb(t_f)        (at the knot nearest the task's end t_f, if in the window)
//! xr_k = x_k (-) x_ref(t_0 + k dt)   (the intuitive deviation of [`super::StateDeviation`])
//! ```
//!
//! The terminal term `H_r` stands in for the cost-to-go beyond the window: without it a
//! 0.5 s window of a 3 s gallop sees no reason to keep moving.

use super::RobotState;
use crate::slq::ValueFunction;
use nalgebra::DVector;
use std::sync::atomic::{AtomicU64, Ordering};

/// A motion sampled every `dt` from `t = 0` (the plan), with the weights that pull each
/// knot (`weights`, per second, as the running cost) and the window's last state
/// (`terminal_weights`) toward it; both on the deviation coordinates (`2 nv`).
#[derive(Clone, Debug, PartialEq)]
pub struct ReferenceMotion {
    pub dt: f64,
    pub q: Vec<DVector<f64>>,
    pub v: Vec<DVector<f64>>,
    /// The motion's joint torques (`nv - 6`; one per sample, or one fewer) and the weight
    /// (per second) on the inputs' deviation from them, `w_u |u - u_ref(t)|^2`: the window
    /// changes the plan's torques only where that pays.
    pub tau: Vec<DVector<f64>>,
    pub input_weight: f64,
    pub weights: DVector<f64>,
    pub terminal_weights: DVector<f64>,
}

impl ReferenceMotion {
    /// The reference state at time `t`: the sample nearest it, the first before the start
    /// and the last after the end (the motion's final state held).
    pub fn at(&self, t: f64) -> (&DVector<f64>, &DVector<f64>) {
        let last = self.q.len().saturating_sub(1);
        let k = if t <= 0.0 { 0 } else { ((t / self.dt).round() as usize).min(last) };
        (&self.q[k], &self.v[k])
    }

    /// The reference torques at time `t` (nearest sample; the last held).
    pub fn torque_at(&self, t: f64) -> &DVector<f64> {
        let last = self.tau.len().saturating_sub(1);
        let k = if t <= 0.0 { 0 } else { ((t / self.dt).round() as usize).min(last) };
        &self.tau[k]
    }

    /// The time of the last sample (s).
    pub fn duration(&self) -> f64 {
        self.q.len().saturating_sub(1) as f64 * self.dt
    }
}

/// What makes a [`super::WholeBodyProblem`] a receding-horizon window (module docs).
#[derive(Debug)]
pub struct RecedingHorizon {
    /// The absolute time of knot 0 (s), as `f64` bits: the controller moves it between
    /// ticks while the solver holds the problem (an atomic, so the problem stays `Sync`).
    start: AtomicU64,
    /// The task's end (s): its final cost acts at the window's knot nearest it, and at the
    /// window's last knot once the task's time is over (the final state held).
    pub final_time: f64,
    pub reference: ReferenceMotion,
    /// The plan's cost-to-go as the window's terminal cost (`None`: the reference's
    /// terminal weights only).
    pub value: Option<PlanValue>,
}

/// A plan's states (every `dt` from `t = 0`, as [`ReferenceMotion`]'s samples) and the local
/// value function of its last backward pass: a window ending at time `t` gets the terminal
/// cost `V(x) = p_k^T dx + 1/2 dx^T P_k dx`, `dx = x (-) x_k`, `k` the plan knot nearest `t`
/// (the last after the plan's end): what the rest of the plan would cost from there.
#[derive(Clone, Debug, PartialEq)]
pub struct PlanValue {
    pub dt: f64,
    pub states: Vec<RobotState>,
    pub value: ValueFunction,
}

impl PlanValue {
    /// The plan knot whose value function ends a window at time `t`.
    pub fn knot_at(&self, t: f64) -> usize {
        let last = self.states.len().min(self.value.hessians.len()).saturating_sub(1);
        if t <= 0.0 {
            0
        } else {
            ((t / self.dt).round() as usize).min(last)
        }
    }
}

impl RecedingHorizon {
    pub fn new(start: f64, final_time: f64, reference: ReferenceMotion) -> Self {
        Self { start: AtomicU64::new(start.to_bits()), final_time, reference, value: None }
    }

    /// The absolute time of knot 0 (s).
    pub fn start(&self) -> f64 {
        f64::from_bits(self.start.load(Ordering::Relaxed))
    }

    /// Moves the window: knot 0 at `t` (s).
    pub fn set_start(&self, t: f64) {
        self.start.store(t.to_bits(), Ordering::Relaxed);
    }

    /// The knot of `knots` (spaced `dt`) that carries the task's final cost: the one nearest
    /// the task's end, the last once the end has passed, none before the window reaches it.
    pub fn final_knot(&self, dt: f64, knots: usize) -> Option<usize> {
        let k = ((self.final_time - self.start()) / dt).round();
        if k > knots as f64 {
            None
        } else {
            Some((k.max(0.0) as usize).min(knots)).map(|k| if self.final_time <= self.start() { knots } else { k })
        }
    }
}

impl Clone for RecedingHorizon {
    fn clone(&self) -> Self {
        Self { value: self.value.clone(), ..Self::new(self.start(), self.final_time, self.reference.clone()) }
    }
}

impl PartialEq for RecedingHorizon {
    fn eq(&self, other: &Self) -> bool {
        self.start() == other.start() && self.final_time == other.final_time && self.reference == other.reference && self.value == other.value
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn reference() -> ReferenceMotion {
        let q = (0..=10).map(|k| DVector::from_element(1, k as f64)).collect();
        let v = (0..=10).map(|_| DVector::zeros(1)).collect();
        let tau = (0..10).map(|k| DVector::from_element(1, -(k as f64))).collect();
        ReferenceMotion { dt: 0.1, q, v, tau, input_weight: 1.0, weights: DVector::zeros(2), terminal_weights: DVector::zeros(2) }
    }

    #[test]
    fn the_reference_is_sampled_at_the_nearest_knot_and_held_after_its_end() {
        let r = reference();
        assert_eq!(r.at(-1.0).0[0], 0.0);
        assert_eq!(r.at(0.34).0[0], 3.0);
        assert_eq!(r.at(0.36).0[0], 4.0);
        assert_eq!(r.at(5.0).0[0], 10.0);
        assert_eq!(r.torque_at(0.36)[0], -4.0);
        assert_eq!(r.torque_at(5.0)[0], -9.0);
        assert!((r.duration() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn the_final_cost_moves_into_the_window_and_stays_at_its_end_afterwards() {
        let h = RecedingHorizon::new(0.0, 1.0, reference());
        // A 0.5 s window of 50 knots: the end at 1 s is beyond it.
        assert_eq!(h.final_knot(0.01, 50), None);
        h.set_start(0.6);
        assert_eq!(h.final_knot(0.01, 50), Some(40));
        h.set_start(0.99);
        assert_eq!(h.final_knot(0.01, 50), Some(1));
        h.set_start(1.0);
        assert_eq!(h.final_knot(0.01, 50), Some(50));
        h.set_start(2.0);
        assert_eq!(h.final_knot(0.01, 50), Some(50));
        assert_eq!(h.clone(), h);
    }
}
