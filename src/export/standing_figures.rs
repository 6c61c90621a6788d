//! Figures of a robot dropped onto the ground and standing under a joint PD: what the
//! contact model does at rest (how deep the feet sink, where the base comes to rest) and
//! on landing (how far the base sinks below its rest height and bounces back), the
//! calibration data that compares one simulator's contact with another's.

use crate::dynamics::{forward_kinematics, frame_position, Data};
use crate::io::Trajectory;
use crate::model::Model;
use crate::terrain::Terrain;
use nalgebra::DVector;
use serde::Serialize;

/// The figures of a drop-and-stand run.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StandingFigures {
    /// Per foot: how deep the foot sphere is in the ground at rest (m; the mean over the
    /// rest window), along the surface normal.
    pub penetration: Vec<f64>,
    /// Base height at rest (m; mean over the rest window).
    pub rest_height: f64,
    /// When the first foot touched the ground (s), `None` if none did.
    pub touchdown_time: Option<f64>,
    /// How far the base sank below its rest height after touch-down (m).
    pub undershoot: f64,
    /// How far the base rose above its rest height after its lowest point (m): the bounce.
    pub overshoot: f64,
    /// Lift-offs of any foot after the first touch-down (a foot bouncing off the ground).
    pub liftoffs_after_touchdown: usize,
    /// The last time the base height was more than 1 mm from its rest height (s).
    pub settle_time: f64,
}

impl StandingFigures {
    /// The figures of `traj` (a motion of `model` on `terrain`); the rest window is the
    /// final `rest_window` seconds.
    pub fn of(model: &Model, terrain: &dyn Terrain, traj: &Trajectory, rest_window: f64) -> Self {
        let knots = &traj.knots;
        let last_t = knots.last().map_or(0.0, |k| k.t);
        let rest: Vec<_> = knots.iter().filter(|k| k.t >= last_t - rest_window).collect();
        let mean = |f: &dyn Fn(&crate::io::Knot) -> f64| rest.iter().map(|k| f(k)).sum::<f64>() / rest.len().max(1) as f64;
        let rest_height = mean(&|k| k.q[2]);
        let mut data = Data::new(model);
        let mut penetration = vec![0.0; model.feet.len()];
        for k in &rest {
            forward_kinematics(model, &mut data, &DVector::from_column_slice(&k.q));
            for (i, foot) in model.feet.iter().enumerate() {
                let p = frame_position(model, &data, foot.frame);
                let (h, n) = terrain.surface(p.x, p.y);
                // Depth of the sphere's lowest point below the local tangent plane.
                penetration[i] += (foot.radius - n.dot(&(p - nalgebra::Vector3::new(p.x, p.y, h)))) / rest.len() as f64;
            }
        }
        let touchdown = knots.iter().position(|k| k.in_contact.iter().any(|&c| c));
        let (mut undershoot, mut overshoot, mut liftoffs) = (0.0, 0.0, 0);
        if let Some(td) = touchdown {
            let after = &knots[td..];
            let (lowest, low) = after.iter().enumerate().map(|(i, k)| (i, k.q[2])).fold((0, f64::INFINITY), |a, b| if b.1 < a.1 { b } else { a });
            undershoot = rest_height - low;
            overshoot = after[lowest..].iter().map(|k| k.q[2]).fold(f64::NEG_INFINITY, f64::max) - rest_height;
            for w in after.windows(2) {
                liftoffs += w[0].in_contact.iter().zip(&w[1].in_contact).filter(|(a, b)| **a && !**b).count();
            }
        }
        let settle_time = knots.iter().rev().find(|k| (k.q[2] - rest_height).abs() > 1e-3).map_or(0.0, |k| k.t);
        Self { penetration, rest_height, touchdown_time: touchdown.map(|i| knots[i].t), undershoot, overshoot, liftoffs_after_touchdown: liftoffs, settle_time }
    }
}
