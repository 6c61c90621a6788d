//! Every limit of a full-body plan checked at every knot, from the trajectory alone (its own
//! kinematics, not the optimizer's rows): joint angles, velocities, torques, the friction
//! pyramid and the minimum normal force of the stance feet, the trunk clearance and the legs
//! apart, the box clearance, and how far stance feet drift from their first contact point.

// Index loops over legs and joints read like the equations they implement.
#![allow(clippy::needless_range_loop)]

use super::kinematics::{foot_position, knee_position, legs};
use super::settings::{BoxObstacle, FullBodySettings};
use crate::dynamics::{forward_kinematics, Data};
use crate::io::Trajectory;
use crate::model::Model;
use nalgebra::{DVector, Vector3};
use std::fmt;

/// The row of the stance feet's drift from their first contact point (an equality: its
/// margin is minus the drift).
pub const STANCE_DRIFT: &str = "stance foot drift";

/// The tightest knot of one kind of limit.
#[derive(Clone, Debug, PartialEq)]
pub struct LimitRow {
    pub kind: &'static str,
    pub unit: &'static str,
    /// Smallest distance inside the limit over all knots and rows (negative: violated).
    pub margin: f64,
    /// Knot of the smallest margin.
    pub knot: usize,
}

/// The margins of every limit kind.
#[derive(Clone, Debug, PartialEq)]
pub struct LimitReport {
    pub rows: Vec<LimitRow>,
}

impl LimitReport {
    /// True if no limit is violated by more than `tolerance`.
    pub fn all_met(&self, tolerance: f64) -> bool {
        self.rows.iter().all(|r| r.margin >= -tolerance)
    }

    /// The inequality kinds whose margin is within `band` of the limit (they bind; the
    /// stance feet's drift, an equality, is never listed).
    pub fn binding(&self, band: f64) -> Vec<&'static str> {
        self.rows.iter().filter(|r| r.margin < band && r.kind != STANCE_DRIFT).map(|r| r.kind).collect()
    }
}

impl fmt::Display for LimitReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "{:20} {:>12}  {:6} knot", "limit", "margin", "unit")?;
        for r in &self.rows {
            let state = if r.margin < -1e-6 {
                "VIOLATED"
            } else if r.margin < 1e-3 && r.kind != STANCE_DRIFT {
                "binds"
            } else {
                ""
            };
            writeln!(f, "{:20} {:>12.3e}  {:6} {:4} {state}", r.kind, r.margin, r.unit, r.knot)?;
        }
        Ok(())
    }
}

struct Tracker(Vec<LimitRow>);

impl Tracker {
    fn put(&mut self, kind: &'static str, unit: &'static str, margin: f64, knot: usize) {
        match self.0.iter_mut().find(|r| r.kind == kind) {
            Some(r) => {
                if margin < r.margin {
                    r.margin = margin;
                    r.knot = knot;
                }
            }
            None => self.0.push(LimitRow { kind, unit, margin, knot }),
        }
    }
}

/// Checks `plan` (a full-body trajectory of `model`) against the model's joint limits and
/// the settings' friction, force and clearance limits, and the box, at every knot. Torques
/// and forces are checked on every knot but the last (they act over the interval that
/// starts at a knot). A feet is airborne at knot `k` if it pushed at neither `k` nor `k-1`.
pub fn check_limits(model: &Model, plan: &Trajectory, settings: &FullBodySettings, obstacle: Option<&BoxObstacle>) -> LimitReport {
    let mut t = Tracker(Vec::new());
    let Ok(legs) = legs(model) else {
        return LimitReport { rows: Vec::new() };
    };
    let joints: Vec<_> = model.actuated_joints().collect();
    let mut data = Data::new(model);
    let s = settings;
    let mut first_contact: [Option<Vector3<f64>>; 4] = [None; 4];
    let n = plan.knots.len();
    for (k, knot) in plan.knots.iter().enumerate() {
        for (j, jnt) in joints.iter().enumerate() {
            let q = knot.q[7 + j];
            t.put("joint angle", "rad", (q - jnt.limits.lower[0]).min(jnt.limits.upper[0] - q), k);
            t.put("joint velocity", "rad/s", jnt.limits.velocity[0] - knot.v[6 + j].abs(), k);
            if k + 1 < n {
                t.put("torque", "N m", jnt.limits.effort[0] - knot.tau[j].abs(), k);
            }
        }
        let q = DVector::from_column_slice(&knot.q);
        forward_kinematics(model, &mut data, &q);
        let base = data.o_m_i[1];
        let in_base = |p: &Vector3<f64>| base.rotation.transpose() * (p - base.translation);
        let feet: [Vector3<f64>; 4] = std::array::from_fn(|f| foot_position(model, &data, &legs[f]));
        let knees: [Vector3<f64>; 4] = std::array::from_fn(|f| knee_position(&data, &legs[f]));
        for f in 0..4 {
            if k + 1 < n && knot.in_contact[f] {
                let [fx, fy, fz] = knot.contact_force[f];
                t.put("friction cone", "N", s.mu * fz - fx.abs().max(fy.abs()), k);
                t.put("min normal force", "N", fz - s.min_normal_force, k);
                let lifting = k + 1 < n && !plan.knots[k + 1].in_contact[f];
                if lifting && s.lift_off_normal_force.is_finite() {
                    t.put("lift-off normal force", "N", s.lift_off_normal_force - fz, k);
                }
                let anchor = *first_contact[f].get_or_insert(feet[f]);
                // The first stance knot is the start (at rest); later stance knots stay put.
                t.put(STANCE_DRIFT, "m", -(feet[f] - anchor).norm(), k);
            }
            for p in [&knees[f], &feet[f]] {
                t.put("trunk clearance", "m", -(s.trunk_half_extents.z + s.clearance) - in_base(p).z, k);
            }
        }
        for points in [&feet, &knees] {
            let pb: [Vector3<f64>; 4] = std::array::from_fn(|f| in_base(&points[f]));
            for m in [pb[0].y - pb[1].y - s.legs_apart_y, pb[2].y - pb[3].y - s.legs_apart_y, pb[0].x - pb[2].x - s.legs_apart_x, pb[1].x - pb[3].x - s.legs_apart_x] {
                t.put("legs apart", "m", m, k);
            }
        }
        if let Some(b) = obstacle {
            let dist = |p: &Vector3<f64>| b.signed_distance(p).0;
            for p in &knees {
                t.put("box clearance", "m", dist(p) - s.clearance, k);
            }
            for c in 0..8 {
                let sign = Vector3::new(if c & 4 == 0 { 1.0 } else { -1.0 }, if c & 2 == 0 { 1.0 } else { -1.0 }, if c & 1 == 0 { 1.0 } else { -1.0 });
                let p = base.act_point(&s.trunk_half_extents.component_mul(&sign));
                t.put("box clearance", "m", dist(&p) - s.clearance, k);
            }
            for f in 0..4 {
                let airborne = !knot.in_contact[f] && (k == 0 || !plan.knots[k - 1].in_contact[f]);
                if airborne {
                    t.put("box clearance", "m", dist(&feet[f]) - model.feet[f].radius - s.airborne_foot_margin, k);
                }
            }
        }
    }
    LimitReport { rows: t.0 }
}
