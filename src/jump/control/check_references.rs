//! Two jump references that need no trajectory optimization, for the controllers' checks,
//! benchmarks and examples: the A1 standing still, and the A1 dropped sideways.

use super::JumpControlError;
use crate::control::JointPd;
use crate::io::{Knot, Trajectory};
use crate::model::Model;
use crate::sim::{standing_on_ground, SimConfig, Simulator};
use crate::terrain::Terrain;

/// The robot's `standing` pose settled on `terrain` for one second under the standing joint
/// PD, held for `duration` s at 10 ms knots: its joint angles, zero velocity, and the torques
/// that held it (the feed-forward).
pub fn standing_reference(model: &Model, terrain: &dyn Terrain, duration: f64) -> Result<Trajectory, JumpControlError> {
    if !(duration.is_finite() && duration > 0.0) {
        return Err(JumpControlError::Setting { field: "duration", expected: format!("a positive time (s), got {duration}") });
    }
    let q0 = standing_on_ground(model, terrain, 0.0)?;
    let mut sim = Simulator::new(model, terrain, SimConfig::default(), q0, None)?;
    let mut stand = JointPd::standing(model, 0.001).map_err(|e| JumpControlError::Robot(e.to_string()))?;
    sim.run(1.0, &mut stand, |_| {})?;
    let mut knot = sim.knot();
    knot.v.iter_mut().for_each(|x| *x = 0.0);
    let mut reference = Trajectory::new(model, "standing", 0.01, terrain.spec());
    let knots = (duration / 0.01).round() as usize;
    for k in 0..=knots {
        reference.knots.push(Knot { t: 0.01 * k as f64, ..knot.clone() });
    }
    Ok(reference)
}

/// A ballistic reference: the settled standing joint configuration, `drop` m above where
/// it stood, moving along world y at `vy` m/s, falling until the feet reach the ground
/// (10 ms knots, no feed-forward). All of it is pre-landing configuration (`T_posing` = 0);
/// the target is where the feet reach the ground.
pub fn drop_reference(model: &Model, terrain: &dyn Terrain, drop: f64, vy: f64) -> Result<Trajectory, JumpControlError> {
    if !(drop.is_finite() && drop > 0.0 && vy.is_finite()) {
        return Err(JumpControlError::Setting { field: "drop/vy", expected: format!("a positive height (m) and a finite speed, got {drop} and {vy}") });
    }
    let standing = standing_reference(model, terrain, 0.01)?;
    let g = -model.gravity.v.z;
    let knot = &standing.knots[0];
    let fall_time = (2.0 * drop / g).sqrt();
    let knots = (fall_time / 0.01).floor() as usize;
    let nj = model.nv - 6;
    let mut reference = Trajectory::new(model, "drop", 0.01, terrain.spec());
    for k in 0..=knots {
        let t = 0.01 * k as f64;
        let mut q = knot.q.clone();
        q[1] += vy * t;
        q[2] += drop - 0.5 * g * t * t;
        let mut v = vec![0.0; model.nv];
        v[1] = vy;
        v[2] = -g * t;
        let feet = model.feet.len();
        reference.knots.push(Knot { t, q, v, tau: vec![0.0; nj], in_contact: vec![false; feet], contact_force: vec![[0.0; 3]; feet], feedback_gain: None });
    }
    Ok(reference)
}
