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
//! 0.5 s window of a 3 s gallop sees no reason to keep moving. With a [`PlanValue`] the
//! plan's value function at the window's end adds to it while the task's end lies beyond
//! the window; a window that holds the task's end has `H` in it, and the value (which
//! includes `H`) would count it twice. With [`RecedingHorizon::ends_at_task_end`] such a
//! window ends at the task's end, `H` on its last knot (`N` the knots up to the end,
//! [`super::WholeBodyProblem::active_knots`]), as the plan's problem ends.

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

/// A window's coarse tail: from knot `from` on, knots of `dt` seconds integrated in
/// `substeps` steps, after the finer head knots of the problem's own `dt` (the part of the
/// window the robot runs before the next tick is exact; the rest only has to carry the
/// cost-to-go). [`crate::slq::Slq::shift_head`] moves such a window by one tail knot, and
/// [`crate::slq::Slq::shift`] and [`crate::slq::Slq::shift_halving`] by one head knot.
///
/// The tail's knots stay on a grid fixed in the task's time: a window that starts `j` head
/// knots past a multiple of the tail's `dt` has the head `from - j` ([`Self::at_start`]), so
/// its knot count stays and its length varies by less than a tail knot.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CoarseTail {
    pub from: usize,
    pub dt: f64,
    pub substeps: usize,
}

impl CoarseTail {
    /// The tail of a window starting `start` seconds into the task, with head knots of
    /// `head_dt`: `from - j`, `j = round(start / head_dt) mod round(dt / head_dt)` (the head
    /// knots since the last tail knot boundary; `start` a multiple of `head_dt`).
    pub fn at_start(self, head_dt: f64, start: f64) -> Self {
        let per_tail_knot = ((self.dt / head_dt).round() as u64).max(1);
        let past_boundary = ((start / head_dt).round().max(0.0) as u64 % per_tail_knot) as usize;
        Self { from: self.from.saturating_sub(past_boundary), ..self }
    }
}

/// Where a problem's knots fall: `knots` transitions of `dt` seconds, or with a
/// [`CoarseTail`] the first `tail.from` of `dt` and the rest of `tail.dt`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KnotGrid {
    pub dt: f64,
    pub knots: usize,
    pub tail: Option<CoarseTail>,
}

impl KnotGrid {
    /// Knots every `dt`.
    pub fn uniform(dt: f64, knots: usize) -> Self {
        Self { dt, knots, tail: None }
    }

    /// The length of knot `k`'s interval (s).
    pub fn dt_of(&self, k: usize) -> f64 {
        match self.tail {
            Some(tail) if k >= tail.from => tail.dt,
            _ => self.dt,
        }
    }

    /// The time of knot `k` from the grid's start (s).
    pub fn offset(&self, k: usize) -> f64 {
        match self.tail {
            Some(tail) if k > tail.from => tail.from as f64 * self.dt + (k - tail.from) as f64 * tail.dt,
            _ => k as f64 * self.dt,
        }
    }

    /// The knot whose interval holds `offset` seconds from the grid's start (the first
    /// before it, the last, `knots - 1`, after its end) and how far into the interval
    /// `offset` is, as a fraction of it (0 to 1).
    pub fn interval_at(&self, offset: f64) -> (usize, f64) {
        let last = self.knots.saturating_sub(1);
        let in_units = |offset: f64, dt: f64| (offset / dt + 1e-9).floor().max(0.0);
        let (k, fraction) = match self.tail {
            Some(tail) if offset >= tail.from as f64 * self.dt => {
                let local = offset - tail.from as f64 * self.dt;
                let j = in_units(local, tail.dt);
                (tail.from + j as usize, local / tail.dt - j)
            }
            _ => {
                let j = in_units(offset, self.dt);
                (j as usize, offset / self.dt - j)
            }
        };
        if k > last {
            (last, 1.0)
        } else {
            (k, fraction.clamp(0.0, 1.0))
        }
    }

    /// The index of the knot nearest `offset` seconds from the grid's start, as if the grid
    /// went on past its end and before its start (a whole number; may lie outside
    /// `0..=knots`).
    pub fn nearest(&self, offset: f64) -> f64 {
        match self.tail {
            Some(tail) if offset > tail.from as f64 * self.dt => tail.from as f64 + ((offset - tail.from as f64 * self.dt) / tail.dt).round(),
            _ => (offset / self.dt).round(),
        }
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
    /// `Some(shortest)`: the window ends at the task's end once it reaches it, its final
    /// cost last, but spans at least `shortest` seconds (past the end by what it lacks)
    /// ([`super::WholeBodyProblem::active_knots`]; uniform knots only). `None`: the window
    /// keeps its length, its knots past the end tracking the final state held.
    pub ends_at_task_end: Option<f64>,
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
        Self { start: AtomicU64::new(start.to_bits()), final_time, reference, value: None, ends_at_task_end: None }
    }

    /// The absolute time of knot 0 (s).
    pub fn start(&self) -> f64 {
        f64::from_bits(self.start.load(Ordering::Relaxed))
    }

    /// Moves the window: knot 0 at `t` (s).
    pub fn set_start(&self, t: f64) {
        self.start.store(t.to_bits(), Ordering::Relaxed);
    }

    /// The knot of `grid` that carries the task's final cost: the one nearest the task's
    /// end, the last once the end has passed, none before the window reaches it.
    pub fn final_knot(&self, grid: &KnotGrid) -> Option<usize> {
        let knots = grid.knots;
        let k = grid.nearest(self.final_time - self.start());
        if k > knots as f64 {
            None
        } else if self.final_time <= self.start() {
            Some(knots)
        } else {
            Some((k.max(0.0) as usize).min(knots))
        }
    }
}

impl Clone for RecedingHorizon {
    fn clone(&self) -> Self {
        Self { value: self.value.clone(), ends_at_task_end: self.ends_at_task_end, ..Self::new(self.start(), self.final_time, self.reference.clone()) }
    }
}

impl PartialEq for RecedingHorizon {
    fn eq(&self, other: &Self) -> bool {
        self.start() == other.start() && self.final_time == other.final_time && self.reference == other.reference && self.value == other.value && self.ends_at_task_end == other.ends_at_task_end
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
        let grid = KnotGrid::uniform(0.01, 50);
        assert_eq!(h.final_knot(&grid), None);
        h.set_start(0.6);
        assert_eq!(h.final_knot(&grid), Some(40));
        h.set_start(0.99);
        assert_eq!(h.final_knot(&grid), Some(1));
        h.set_start(1.0);
        assert_eq!(h.final_knot(&grid), Some(50));
        h.set_start(2.0);
        assert_eq!(h.final_knot(&grid), Some(50));
        assert_eq!(h.clone(), h);
    }

    #[test]
    fn a_tail_of_two_head_knots_stays_on_its_grid_as_the_window_starts_later() {
        // Head knots of 5 ms, tail knots of 10 ms from 40 ms at a window start of 0.
        let tail = CoarseTail { from: 8, dt: 0.01, substeps: 10 };
        for (start, from) in [(0.0, 8), (0.005, 7), (0.01, 8), (0.015, 7), (1.235, 7), (1.24, 8)] {
            let now = tail.at_start(0.005, start);
            assert_eq!(now.from, from, "start {start}");
            // The first tail knot's absolute time is a multiple of 10 ms past 40 ms.
            let first = start + now.from as f64 * 0.005;
            assert!(((first - 0.04) / 0.01 - ((first - 0.04) / 0.01).round()).abs() < 1e-9, "start {start}");
        }
        // A tail of one tick period (a 1 ms head) never moves.
        let one_tick = CoarseTail { from: 20, dt: 0.005, substeps: 5 };
        assert_eq!(one_tick.at_start(0.001, 0.735).from, 20);
    }

    #[test]
    fn a_coarse_tail_spaces_the_knots_after_the_head() {
        // 0.5 s: 20 knots of 1 ms, then 96 of 5 ms.
        let grid = KnotGrid { dt: 0.001, knots: 116, tail: Some(CoarseTail { from: 20, dt: 0.005, substeps: 5 }) };
        assert!((grid.offset(20) - 0.02).abs() < 1e-12);
        assert!((grid.offset(21) - 0.025).abs() < 1e-12);
        assert!((grid.offset(116) - 0.5).abs() < 1e-12);
        assert_eq!((grid.dt_of(19), grid.dt_of(20)), (0.001, 0.005));
        assert_eq!(grid.nearest(0.0194), 19.0);
        assert_eq!(grid.interval_at(0.0194).0, 19);
        assert_eq!(grid.interval_at(0.0224).0, 20);
        assert!((grid.interval_at(0.0224).1 - 0.48).abs() < 1e-9);
        assert_eq!(grid.interval_at(-1.0), (0, 0.0));
        assert_eq!(grid.interval_at(0.7), (115, 1.0));
        assert_eq!(grid.nearest(0.0224), 20.0);
        assert_eq!(grid.nearest(0.0226), 21.0);
        let h = RecedingHorizon::new(0.0, 0.3, reference());
        assert_eq!(h.final_knot(&grid), Some(76));
        h.set_start(0.29);
        assert_eq!(h.final_knot(&grid), Some(10));
        h.set_start(-0.3);
        assert_eq!(h.final_knot(&grid), None);
    }
}
