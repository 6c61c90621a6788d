//! Joint position limits as mechanical stops: a smooth, one-sided spring-damper
//! generalized force on every revolute or prismatic coordinate with a finite limit, as
//! MuJoCo and Bullet model soft joint limits, and in the form of the smooth contact model
//! of Neunert 2017 (eq. 9: zero outside contact, quadratic onset over a smoothing band,
//! linear beyond it; never pulling).
//!
//! For a coordinate `q` with upper limit `u` the penetration into the stop is `p = q - u`
//! (lower limit `l`: `p = l - q`), its rate `pdot = +-v`, and
//!
//! ```text
//! s(p)   = 0 (p <= 0),  p^2 / (2 w) (0 < p < w),  p - w / 2 (p >= w)    the profile of eq. (9)
//! F      = max(k s(p) + d s'(p) pdot, 0)                                 the stop's push, >= 0
//! tau_l  = -F (upper stop),  +F (lower stop)
//! ```
//!
//! The damper is gated by `s'(p)` (0 at the limit, 1 beyond the band), so the force is
//! continuous when a joint reaches its stop at speed, and the clamp at zero keeps it from
//! pulling a joint that leaves the stop fast back into it (no adhesion, as the contact
//! model's clamp of `k_n + d_n pd_n`). Its derivatives, where `F > 0` (zero elsewhere):
//!
//! ```text
//! dF/dp    = k s'(p) + d s''(p) pdot,   dF/dpdot = d s'(p)
//! dtau_l/dq = -dF/dp,  dtau_l/dv = -dF/dpdot                             (both stops)
//! ```
//!
//! The generalized force is diagonal: each stop acts on its own coordinate only.

use crate::model::{JointKind, Model};
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

/// Stiffness, damping and smoothing of the joint stops ([`crate::sim::SimConfig::joint_limits`]).
///
/// Defaults for a ~90 kg robot like HyQ (150 N m effort limits):
///
/// * `stiffness` 5000 N m/rad: a stop holds a joint pushed by its full effort, 150 N m,
///   at `150 / 5000 + w / 2 = 0.04 rad` (2.3 deg) past the limit. Seen from the knee, the
///   ground's normal stiffness (3e4-9e4 N/m at a 0.35 m lever, 3700-11000 N m/rad) is of
///   the same order, so the optimizer's linearization meets nothing stiffer than contact.
/// * `damping` 5 N m s/rad: the knee of a swinging HyQ leg has an effective inertia down to
///   0.013 kg m^2 (leg straight, `1 / (M^-1)_kk`), for which the stop is a 100 Hz
///   oscillator damped at 0.3 of critical. The bound is the optimizer's 2 ms semi-implicit
///   Euler step, stable for `h^2 k / I + 2 h d / I < 4`: 1.54 + 1.54 here; a critically
///   damped knee (16 N m s/rad) would make that step unstable.
/// * `smoothing` 0.02 rad (1.15 deg): the band of the quadratic onset, the angle the foot's
///   1 cm contact smoothing (Neunert 2017, Table I) spans at the end of a 0.35 m shank
///   (0.03 rad), a little narrower.
///
/// ```
/// let p = legwork::sim::JointLimitParams::default();
/// p.validate().unwrap();
/// // Held against 150 N m at 0.04 rad past the limit.
/// assert!((p.stop_force(0.04, 0.0).force - 150.0).abs() < 1e-9);
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct JointLimitParams {
    /// Stiffness `k` of the stop (N m/rad, N/m for a prismatic joint) beyond the band.
    pub stiffness: f64,
    /// Damping `d` (N m s/rad), acting only beyond the limit and never pulling.
    pub damping: f64,
    /// Width `w` of the quadratic onset (rad, m for a prismatic joint).
    pub smoothing: f64,
}

impl Default for JointLimitParams {
    fn default() -> Self {
        Self { stiffness: 5000.0, damping: 5.0, smoothing: 0.02 }
    }
}

/// A joint-limit parameter out of its range; names the field.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("joint-limit parameter `{field}`: expected {expected}, got {value}")]
pub struct JointLimitParamsError {
    pub field: &'static str,
    pub expected: &'static str,
    pub value: f64,
}

/// One stop's push `F >= 0` and its derivatives with respect to the penetration and its rate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StopForce {
    pub force: f64,
    pub d_penetration: f64,
    pub d_rate: f64,
}

impl JointLimitParams {
    /// Every parameter finite; `stiffness` and `smoothing` positive, `damping` non-negative.
    pub fn validate(&self) -> Result<(), JointLimitParamsError> {
        let checks: [(&'static str, f64, bool); 3] = [("stiffness", self.stiffness, true), ("damping", self.damping, false), ("smoothing", self.smoothing, true)];
        for (field, value, strictly_positive) in checks {
            let ok = value.is_finite() && if strictly_positive { value > 0.0 } else { value >= 0.0 };
            if !ok {
                let expected = if strictly_positive { "a finite number > 0" } else { "a finite number >= 0" };
                return Err(JointLimitParamsError { field, expected, value });
            }
        }
        Ok(())
    }

    /// The profile of eq. (9) with width `smoothing` and its first two derivatives:
    /// `(s, s', s'')`.
    #[inline]
    pub fn profile(&self, p: f64) -> (f64, f64, f64) {
        let w = self.smoothing;
        if p <= 0.0 {
            (0.0, 0.0, 0.0)
        } else if p < w {
            (p * p / (2.0 * w), p / w, 1.0 / w)
        } else {
            (p - 0.5 * w, 1.0, 0.0)
        }
    }

    /// `F = max(k s(p) + d s'(p) pdot, 0)` at penetration `p` and rate `pdot` (see the
    /// module documentation), with its derivatives (zero where the clamp acts).
    #[inline]
    pub fn stop_force(&self, penetration: f64, rate: f64) -> StopForce {
        let (s, ds, dds) = self.profile(penetration);
        let force = self.stiffness * s + self.damping * ds * rate;
        if force > 0.0 {
            StopForce { force, d_penetration: self.stiffness * ds + self.damping * dds * rate, d_rate: self.damping * ds }
        } else {
            StopForce { force: 0.0, d_penetration: 0.0, d_rate: 0.0 }
        }
    }
}

/// One limited coordinate: its configuration and velocity index and its limits (an
/// infinite side has no stop).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct LimitedCoordinate {
    pub idx_q: usize,
    pub idx_v: usize,
    pub lower: f64,
    pub upper: f64,
}

/// The revolute and prismatic coordinates of `model` with a finite limit on either side.
pub(crate) fn limited_coordinates(model: &Model) -> impl Iterator<Item = LimitedCoordinate> + '_ {
    model.joints[1..]
        .iter()
        .filter(|j| matches!(j.kind, JointKind::Revolute { .. } | JointKind::Prismatic { .. }))
        .map(|j| LimitedCoordinate { idx_q: j.idx_q, idx_v: j.idx_v, lower: j.limits.lower[0], upper: j.limits.upper[0] })
        .filter(|c| c.lower.is_finite() || c.upper.is_finite())
}

/// The stops of a model's revolute and prismatic joints with finite limits, evaluated
/// without allocation; `None` parameters switch them off.
#[derive(Clone, Debug, PartialEq)]
pub struct JointStops {
    params: Option<JointLimitParams>,
    coordinates: Vec<LimitedCoordinate>,
}

impl JointStops {
    pub fn new(model: &Model, params: Option<JointLimitParams>) -> Self {
        Self { params, coordinates: limited_coordinates(model).collect() }
    }

    /// Calls `f(idx_v, tau_l, dtau_l/dq, dtau_l/dv)` for every stop engaged at `(q, v)`.
    #[inline]
    fn for_each_engaged(&self, q: &DVector<f64>, v: &DVector<f64>, mut f: impl FnMut(usize, f64, f64, f64)) {
        let Some(params) = &self.params else { return };
        for c in &self.coordinates {
            let (x, xdot) = (q[c.idx_q], v[c.idx_v]);
            // Upper stop: p = q - u, pushes down; lower stop: p = l - q, pushes up. Either
            // way dtau/dq = -dF/dp and dtau/dv = -dF/dpdot.
            if x > c.upper {
                let s = params.stop_force(x - c.upper, xdot);
                f(c.idx_v, -s.force, -s.d_penetration, -s.d_rate);
            }
            if x < c.lower {
                let s = params.stop_force(c.lower - x, -xdot);
                f(c.idx_v, s.force, -s.d_penetration, -s.d_rate);
            }
        }
    }

    /// Adds the stops' generalized force `tau_l(q, v)` to `tau` (`nv`).
    pub fn add_torques(&self, q: &DVector<f64>, v: &DVector<f64>, tau: &mut DVector<f64>) {
        self.for_each_engaged(q, v, |i, t, _, _| tau[i] += t);
    }

    /// Adds `d tau_l / dq` and `d tau_l / dv` (diagonal; `q` in the tangent space, which for
    /// a revolute or prismatic coordinate is the coordinate itself) to `dtau_dq`, `dtau_dv`.
    pub fn add_derivatives(&self, q: &DVector<f64>, v: &DVector<f64>, dtau_dq: &mut DMatrix<f64>, dtau_dv: &mut DMatrix<f64>) {
        self.for_each_engaged(q, v, |i, _, dq, dv| {
            dtau_dq[(i, i)] += dq;
            dtau_dv[(i, i)] += dv;
        });
    }

    /// The largest distance (rad or m) by which a coordinate of `q` is past one of its
    /// limits, with its velocity index (`None` when every coordinate is within its limits).
    pub fn worst_excess(&self, q: &[f64]) -> Option<(usize, f64)> {
        self.coordinates
            .iter()
            .map(|c| (c.idx_v, (q[c.idx_q] - c.upper).max(c.lower - q[c.idx_q])))
            .filter(|(_, e)| *e > 0.0)
            .max_by(|a, b| a.1.total_cmp(&b.1))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn profile_is_zero_inside_quadratic_in_the_band_then_linear() {
        let p = JointLimitParams { stiffness: 1000.0, damping: 0.0, smoothing: 0.02 };
        assert_eq!(p.stop_force(-0.1, 5.0).force, 0.0);
        assert_eq!(p.stop_force(0.0, 5.0).force, 0.0);
        assert!((p.stop_force(0.01, 0.0).force - 1000.0 * 0.01 * 0.01 / 0.04).abs() < 1e-12);
        assert!((p.stop_force(0.05, 0.0).force - 1000.0 * (0.05 - 0.01)).abs() < 1e-12);
        // Continuous at the band's end, value and slope.
        let (a, b) = (p.stop_force(0.02 - 1e-12, 0.0), p.stop_force(0.02 + 1e-12, 0.0));
        assert!((a.force - b.force).abs() < 1e-8 && (a.d_penetration - b.d_penetration).abs() < 1e-6);
    }

    #[test]
    fn damper_never_pulls_and_is_gated_by_the_profile_slope() {
        let p = JointLimitParams { stiffness: 1000.0, damping: 10.0, smoothing: 0.02 };
        // Leaving the stop fast: k s + d s' pdot < 0 is clamped to no force.
        let leaving = p.stop_force(0.01, -10.0);
        assert_eq!((leaving.force, leaving.d_penetration, leaving.d_rate), (0.0, 0.0, 0.0));
        // Entering at the band's middle: d s'(p) pdot with s' = 1/2.
        let entering = p.stop_force(0.01, 2.0);
        assert!((entering.force - (1000.0 * 0.0025 + 10.0 * 0.5 * 2.0)).abs() < 1e-12);
        assert!((entering.d_rate - 5.0).abs() < 1e-12);
        assert!((entering.d_penetration - (1000.0 * 0.5 + 10.0 * 2.0 / 0.02)).abs() < 1e-9);
    }

    #[test]
    fn derivatives_match_central_differences() {
        let p = JointLimitParams { stiffness: 5000.0, damping: 5.0, smoothing: 0.02 };
        for (x, r) in [(0.005, 1.0), (0.015, -0.3), (0.04, 2.0), (0.1, -1.0)] {
            let s = p.stop_force(x, r);
            let h = 1e-7;
            let dp = (p.stop_force(x + h, r).force - p.stop_force(x - h, r).force) / (2.0 * h);
            let dr = (p.stop_force(x, r + h).force - p.stop_force(x, r - h).force) / (2.0 * h);
            assert!((s.d_penetration - dp).abs() < 1e-5 * (1.0 + dp.abs()), "p = {x}: {} vs {dp}", s.d_penetration);
            assert!((s.d_rate - dr).abs() < 1e-5 * (1.0 + dr.abs()), "p = {x}: {} vs {dr}", s.d_rate);
        }
    }

    #[test]
    fn validation_names_the_field() {
        let bad = JointLimitParams { smoothing: 0.0, ..Default::default() };
        assert_eq!(bad.validate().unwrap_err().field, "smoothing");
        let bad = JointLimitParams { damping: f64::NAN, ..Default::default() };
        assert_eq!(bad.validate().unwrap_err().field, "damping");
        let bad = JointLimitParams { stiffness: -1.0, ..Default::default() };
        assert_eq!(bad.validate().unwrap_err().field, "stiffness");
    }

    #[test]
    fn stops_push_each_coordinate_back_towards_its_range() {
        let model = crate::model::embedded::load("hyq").unwrap();
        let stops = JointStops::new(&model, Some(JointLimitParams::default()));
        let mut q = model.reference_configuration("standing").unwrap().clone();
        let v = DVector::zeros(model.nv);
        let mut tau = DVector::zeros(model.nv);
        stops.add_torques(&q, &v, &mut tau);
        assert_eq!(tau.norm(), 0.0, "standing is inside every limit");
        assert_eq!(stops.worst_excess(q.as_slice()), None);
        // LF knee 0.1 rad past its upper limit (-20 deg), LH knee 0.1 rad below its lower (20 deg).
        let (lf_kfe, lh_kfe) = (&model.joints[model.joint_id("lf_kfe_joint").unwrap()], &model.joints[model.joint_id("lh_kfe_joint").unwrap()]);
        q[lf_kfe.idx_q] = lf_kfe.limits.upper[0] + 0.1;
        q[lh_kfe.idx_q] = lh_kfe.limits.lower[0] - 0.1;
        stops.add_torques(&q, &v, &mut tau);
        let expected = 5000.0 * (0.1 - 0.01);
        assert!((tau[lf_kfe.idx_v] + expected).abs() < 1e-9 && (tau[lh_kfe.idx_v] - expected).abs() < 1e-9, "{tau}");
        assert_eq!(tau.iter().filter(|t| **t != 0.0).count(), 2);
        let (i, e) = stops.worst_excess(q.as_slice()).unwrap();
        assert!((e - 0.1).abs() < 1e-12 && (i == lf_kfe.idx_v || i == lh_kfe.idx_v));
        // Switched off: nothing.
        let mut tau_off = DVector::zeros(model.nv);
        JointStops::new(&model, None).add_torques(&q, &v, &mut tau_off);
        assert_eq!(tau_off.norm(), 0.0);
    }
}
