//! A running cost on joint positions outside their limits: the quadratic barrier of
//! Crocoddyl's `ActivationModelQuadraticBarrier` on the joint coordinates, with the limits
//! pulled in by a margin.
//!
//! For a coordinate `q` with limits `[l, u]` and margin `m`,
//!
//! ```text
//! r(q)  = max(q - (u - m), 0) + min(q - (l + m), 0)      how far q is outside [l + m, u - m]
//! c(q)  = w sum_j r_j(q)^2
//! dc/dq = 2 w r(q),   d2c/dq2 = 2 w [r(q) != 0]           exact (piecewise quadratic)
//! ```
//!
//! Why a cost as well as the stops of [`crate::sim::JointStops`]: a stop is part of the
//! dynamics, so the optimizer may lean on it for free (squat_jump's knee carries 569 N m on
//! its stop in the flight); without stops nothing keeps a plan inside the joints' range at
//! all (the gallop bends a knee 135 deg the wrong way). The cost makes leaving the range
//! something the optimizer pays for, with or without stops.

use crate::model::Model;
use crate::sim::joint_limits::{limited_coordinates, LimitedCoordinate};
use nalgebra::{DMatrix, DVector};
use serde::Deserialize;

/// The task file's `[joint_limit_cost]` table.
///
/// ```
/// let spec: legwork::ocp::JointLimitCostSpec = toml::from_str("weight = 1e4\nmargin = 0.05").unwrap();
/// assert_eq!(spec.weight, 1e4);
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointLimitCostSpec {
    /// `w` (per rad^2 per second, as the running weights).
    pub weight: f64,
    /// `m` (rad): the cost starts this far inside each limit (0 if absent).
    #[serde(default)]
    pub margin: f64,
}

/// The cost of [`JointLimitCostSpec`] on a model's revolute and prismatic joints.
#[derive(Clone, Debug, PartialEq)]
pub struct JointLimitCost {
    weight: f64,
    /// Each limited coordinate with its limits pulled in by the margin (an infinite side
    /// never costs).
    bounds: Vec<LimitedCoordinate>,
}

impl JointLimitCost {
    /// The cost on every revolute or prismatic coordinate with a finite limit. A margin
    /// wider than half a joint's range puts both bounds at the middle of the range.
    pub fn new(model: &Model, spec: JointLimitCostSpec) -> Self {
        let bounds = limited_coordinates(model)
            .map(|c| {
                let (lower, upper) = (c.lower + spec.margin, c.upper - spec.margin);
                // Only a finite range can be narrower than twice the margin.
                let middle = 0.5 * (c.lower + c.upper);
                let (lower, upper) = if lower > upper { (middle, middle) } else { (lower, upper) };
                LimitedCoordinate { lower, upper, ..c }
            })
            .collect();
        Self { weight: spec.weight, bounds }
    }

    /// `r(q)` of one coordinate (see the module documentation).
    #[inline]
    fn residual(b: &LimitedCoordinate, q: f64) -> f64 {
        (q - b.upper).max(0.0) + (q - b.lower).min(0.0)
    }

    /// `scale c(q)`.
    pub fn cost(&self, scale: f64, q: &DVector<f64>) -> f64 {
        let sum: f64 = self.bounds.iter().map(|b| Self::residual(b, q[b.idx_q]).powi(2)).sum();
        scale * self.weight * sum
    }

    /// Adds `scale dc/dq` and `scale d2c/dq2` to the configuration block of `(l_x, l_xx)`
    /// (a joint coordinate's tangent is the coordinate itself); returns `scale c(q)`.
    pub fn add_derivatives(&self, scale: f64, q: &DVector<f64>, l_x: &mut DVector<f64>, l_xx: &mut DMatrix<f64>) -> f64 {
        let mut sum = 0.0;
        for b in &self.bounds {
            let r = Self::residual(b, q[b.idx_q]);
            if r != 0.0 {
                sum += r * r;
                l_x[b.idx_v] += 2.0 * scale * self.weight * r;
                l_xx[(b.idx_v, b.idx_v)] += 2.0 * scale * self.weight;
            }
        }
        scale * self.weight * sum
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hyq() -> Model {
        crate::model::embedded::load("hyq").unwrap()
    }

    #[test]
    fn zero_inside_the_margin_and_quadratic_outside() {
        let model = hyq();
        let cost = JointLimitCost::new(&model, JointLimitCostSpec { weight: 10.0, margin: 0.1 });
        let q = model.reference_configuration("standing").unwrap().clone();
        assert_eq!(cost.cost(1.0, &q), 0.0);
        let knee = model.joints.iter().find(|j| j.name == "lf_kfe_joint").unwrap();
        let mut past = q.clone();
        past[knee.idx_q] = knee.limits.upper[0] + 0.2;
        // 0.2 past the limit is 0.3 past the bound.
        assert!((cost.cost(2.0, &past) - 2.0 * 10.0 * 0.09).abs() < 1e-12);
    }

    #[test]
    fn derivatives_match_finite_differences() {
        let model = hyq();
        let cost = JointLimitCost::new(&model, JointLimitCostSpec { weight: 3.0, margin: 0.05 });
        let mut q = model.reference_configuration("standing").unwrap().clone();
        // Every actuated joint: some past the upper bound, some past the lower, some inside.
        for (i, j) in model.joints[1..].iter().enumerate() {
            let (l, u) = (j.limits.lower[0], j.limits.upper[0]);
            q[j.idx_q] = match i % 3 {
                0 => u + 0.1,
                1 => l - 0.07,
                _ => 0.5 * (l + u),
            };
        }
        let nv = model.nv;
        let (mut g, mut h) = (DVector::zeros(nv), DMatrix::zeros(nv, nv));
        let c = cost.add_derivatives(0.5, &q, &mut g, &mut h);
        assert!((c - cost.cost(0.5, &q)).abs() < 1e-12);
        let eps = 1e-6;
        for j in &model.joints[1..] {
            let (mut plus, mut minus) = (q.clone(), q.clone());
            plus[j.idx_q] += eps;
            minus[j.idx_q] -= eps;
            let fd = (cost.cost(0.5, &plus) - cost.cost(0.5, &minus)) / (2.0 * eps);
            assert!((fd - g[j.idx_v]).abs() < 1e-6, "{}: {fd} against {}", j.name, g[j.idx_v]);
            let mut gp = DVector::zeros(nv);
            let mut gm = DVector::zeros(nv);
            cost.add_derivatives(0.5, &plus, &mut gp, &mut DMatrix::zeros(nv, nv));
            cost.add_derivatives(0.5, &minus, &mut gm, &mut DMatrix::zeros(nv, nv));
            let fd2 = (gp[j.idx_v] - gm[j.idx_v]) / (2.0 * eps);
            assert!((fd2 - h[(j.idx_v, j.idx_v)]).abs() < 1e-6, "{}: {fd2} against {}", j.name, h[(j.idx_v, j.idx_v)]);
        }
        // Nothing on the base coordinates.
        assert!(g.rows(0, 6).iter().all(|v| *v == 0.0));
    }
}
