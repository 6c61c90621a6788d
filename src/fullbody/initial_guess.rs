//! The full-body initial guess from the single-rigid-body trajectory (Nguyen 2022,
//! sec. II-C2: "We also use q_ref,h as initial guess for the TO"), on the SRB's uniform grid:
//!
//! - base pose: the SRB rotation, and the base placed so that the CoM of the robot in its
//!   nominal pose is the SRB CoM, `t = p - R c_b` (`c_b` the nominal CoM in the base frame);
//! - stance legs by inverse kinematics to their contact points (at the lift-off knot as
//!   close as the joint limits allow); where the SRB's foot sphere (2d) asks for more than
//!   a leg reaches, the base is moved towards the feet until every stance foot is reached
//!   (the move smoothed over +-5 knots, so that it does not start and stop within one
//!   step); a leg in the air blends (smoothstep) from its lift-off angles to the
//!   pre-landing angles, which it holds over the last `a` knots;
//! - the pre-landing angles: inverse kinematics of the SRB's final feet in the final pose;
//! - joint velocities by backward differences (`q_k = q_{k-1} (+) dt v_k`, the semi-implicit
//!   Euler step of the full-body dynamics), `v_0 = 0`;
//! - torques `tau_leg = -J_leg^T f` of each stance foot's SRB force `f` (a massless leg in
//!   equilibrium with the ground force), zero in the air;
//! - with a start box ([`initial_guess_clear_of`]): an airborne foot that the blend puts
//!   closer to the box than its radius plus a margin is moved out along the box's
//!   signed-distance gradient (up above the top while over it, out past the edge beside
//!   it) by inverse kinematics, so the guess starts the box-clearance rows satisfied
//!   where the leg reaches (the lift smoothed over +-5 knots).

// Index loops over legs and joints read like the equations they implement.
#![allow(clippy::needless_range_loop)]

use super::kinematics::{foot_position, leg_inverse_kinematics, legs, point_jacobian, Leg};
use super::settings::BoxObstacle;
use super::FullBodyError;
use crate::dynamics::{compute_joint_jacobians, difference, forward_kinematics, frame_position, Data};
use crate::io::{Knot, Trajectory};
use crate::model::Model;
use crate::srb::{SrbParams, SrbTrajectory};
use crate::terrain::TerrainSpec;
use crate::spatial::SE3;
use nalgebra::{DVector, Matrix3xX, Vector3};

/// Largest distance (m) the inverse kinematics may leave between a stance foot and its
/// contact point.
pub const IK_TOLERANCE: f64 = 1e-6;

/// The nominal pose the guess starts its legs from and whose CoM offset places the base.
pub const NOMINAL_POSE: &str = "standing";

/// The base configuration (position, quaternion x y z w) that puts the nominal CoM at `com`
/// with rotation `rotation`, into `q[0..7]`.
fn set_base(q: &mut DVector<f64>, com: &Vector3<f64>, rotation: &nalgebra::Matrix3<f64>, com_in_base: &Vector3<f64>) {
    let t = com - rotation * com_in_base;
    q.as_mut_slice()[..3].copy_from_slice(t.as_slice());
    q.as_mut_slice()[3..7].copy_from_slice(&SE3::new(*rotation, t).quaternion_xyzw());
}

/// Leg IK to `target`; an error names the leg and the knot if the foot stays away.
fn reach_or_fail(model: &Model, data: &mut Data, legs: &[Leg], f: usize, knot: usize, target: &Vector3<f64>, q: &mut DVector<f64>) -> Result<(), FullBodyError> {
    let distance = leg_inverse_kinematics(model, data, &legs[f], target, q);
    if distance > IK_TOLERANCE {
        return Err(FullBodyError::Unreachable { foot: model.feet[f].name.clone(), knot, distance });
    }
    Ok(())
}

/// The pre-landing configuration: the nominal pose with the base at the SRB's final pose and
/// the legs by inverse kinematics to the SRB's final feet.
pub fn pre_landing_configuration(model: &Model, srb: &SrbTrajectory) -> Result<DVector<f64>, FullBodyError> {
    let legs = legs(model)?;
    let params = SrbParams::from_model(model, NOMINAL_POSE).map_err(|e| FullBodyError::Model(e.to_string()))?;
    let mut q = nominal(model)?;
    let mut data = Data::new(model);
    let end = srb.knots.last().ok_or(FullBodyError::Guess("the SRB trajectory has no knots".into()))?;
    set_base(&mut q, &end.com, &end.rotation, &params.com_in_base);
    for f in 0..4 {
        reach_or_fail(model, &mut data, &legs, f, srb.knots.len() - 1, &end.feet[f], &mut q)?;
    }
    Ok(q)
}

fn nominal(model: &Model) -> Result<DVector<f64>, FullBodyError> {
    model
        .reference_configuration(NOMINAL_POSE)
        .cloned()
        .ok_or_else(|| FullBodyError::Model(format!("'{}' has no '{NOMINAL_POSE}' configuration", model.name)))
}

fn smoothstep(s: f64) -> f64 {
    let s = s.clamp(0.0, 1.0);
    s * s * (3.0 - 2.0 * s)
}

/// Margin (m) beyond the foot's radius by which the guess keeps airborne feet off the box.
pub const BOX_MARGIN: f64 = 0.03;

/// Half-width (knots) of the window over which the guess smooths the feet's lift off the box.
pub const BOX_SMOOTHING: usize = 5;

/// Half-width (knots) of the window over which the guess smooths the base's shift towards
/// stance feet the SRB places beyond the legs' reach.
pub const BASE_SMOOTHING: usize = 5;

/// Per knot, the mean over `k - w ..= k + w` of each knot's widest value (by norm) within
/// its own `+-w` window: equal to a value where it is the largest within `2 w` knots, and
/// ramping up to it over the `2 w` knots before and after instead of within one knot.
fn windowed_envelope(values: &[[f64; 3]], w: usize) -> Vec<[f64; 3]> {
    let n = values.len();
    let window = |k: usize| k.saturating_sub(w)..(k + w + 1).min(n);
    let norm = |l: &[f64; 3]| l.iter().map(|x| x * x).sum::<f64>();
    let widest: Vec<[f64; 3]> = (0..n).map(|k| window(k).map(|j| values[j]).max_by(|a, b| norm(a).total_cmp(&norm(b))).unwrap_or_default()).collect();
    (0..n)
        .map(|k| {
            let count = window(k).len() as f64;
            std::array::from_fn(|a| window(k).map(|j| widest[j][a]).sum::<f64>() / count)
        })
        .collect()
}

/// Stance legs by inverse kinematics to their contact points `feet`, with the base moved
/// towards them where the SRB's foot sphere (2d) asks for more than a leg reaches (the knee
/// stops at -52.5 deg); returns the base's move.
fn reach_stance_feet(model: &Model, data: &mut Data, legs: &[Leg], k: usize, feet: &[Vector3<f64>; 4], stance: &[usize], q: &mut DVector<f64>) -> Result<Vector3<f64>, FullBodyError> {
    let mut shift = Vector3::zeros();
    let mut moves_left = 50;
    loop {
        let mut pull = Vector3::zeros();
        let mut worst = 0.0f64;
        for &f in stance {
            let miss = leg_inverse_kinematics(model, data, &legs[f], &feet[f], q);
            if miss > IK_TOLERANCE {
                pull += feet[f] - frame_position(model, data, legs[f].foot_frame);
            }
            worst = worst.max(miss);
        }
        if worst <= IK_TOLERANCE {
            return Ok(shift);
        }
        if moves_left == 0 {
            let d = |f: usize| (feet[f] - frame_position(model, data, legs[f].foot_frame)).norm();
            let f = stance.iter().copied().max_by(|&a, &b| d(a).total_cmp(&d(b))).unwrap_or(0);
            return Err(FullBodyError::Unreachable { foot: model.feet[f].name.clone(), knot: k, distance: worst });
        }
        moves_left -= 1;
        for a in 0..3 {
            q[a] += pull[a];
        }
        shift += pull;
    }
}

/// The initial guess on the grid of `srb` (uniform, as [`SrbTrajectory::resample`] makes
/// it), with the pre-landing angles over the last `pre_landing_knots` knots (and the last).
pub fn initial_guess(model: &Model, srb: &SrbTrajectory, pre_landing_knots: usize) -> Result<Trajectory, FullBodyError> {
    initial_guess_clear_of(model, srb, pre_landing_knots, None)
}

/// [`initial_guess`] with the airborne feet kept off the box `obstacle` (the one the
/// full-body problem gets: the same geometry as its clearance rows).
pub fn initial_guess_clear_of(model: &Model, srb: &SrbTrajectory, pre_landing_knots: usize, obstacle: Option<&BoxObstacle>) -> Result<Trajectory, FullBodyError> {
    let n = srb.knots.len();
    if n < 2 {
        return Err(FullBodyError::Guess(format!("the SRB trajectory needs at least 2 knots, it has {n}")));
    }
    let dt = srb.knots[1].t - srb.knots[0].t;
    for (k, w) in srb.knots.windows(2).enumerate() {
        if ((w[1].t - w[0].t) - dt).abs() > 1e-9 || dt <= 0.0 {
            return Err(FullBodyError::Guess(format!("the SRB trajectory is not on a uniform grid (knots {k}, {}): resample it first", k + 1)));
        }
    }
    let last = n - 1;
    if pre_landing_knots >= last {
        return Err(FullBodyError::Setting { field: "pre_landing_knots", value: pre_landing_knots as f64, expected: "fewer than the knots of the trajectory" });
    }
    let legs = legs(model)?;
    let params = SrbParams::from_model(model, NOMINAL_POSE).map_err(|e| FullBodyError::Model(e.to_string()))?;
    let q_pre = pre_landing_configuration(model, srb)?;
    let prelanding_start = last - pre_landing_knots;
    // Lift-off knot of each leg: the knot after its last stance interval.
    let lift_off: [usize; 4] = std::array::from_fn(|f| srb.knots.iter().rposition(|k| k.contacts[f]).map_or(0, |k| k + 1));
    if let Some(f) = (0..4).find(|&f| lift_off[f] > prelanding_start) {
        return Err(FullBodyError::Guess(format!(
            "foot '{}' lifts off at knot {} after the pre-landing window starts (knot {prelanding_start})",
            model.feet[f].name, lift_off[f]
        )));
    }
    let mut data = Data::new(model);
    let mut qs: Vec<DVector<f64>> = Vec::with_capacity(n);
    let mut q = nominal(model)?;
    let stance_at = |k: usize| -> Vec<usize> { (0..4).filter(|&f| k < lift_off[f]).collect() };
    // The base shift each knot's stance legs need, smoothed over time: a shift that starts
    // and stops within one knot is a velocity jump the dynamics rows cannot follow.
    let mut base_shift = vec![[0.0f64; 3]; n];
    for (k, knot) in srb.knots.iter().enumerate() {
        set_base(&mut q, &knot.com, &knot.rotation, &params.com_in_base);
        let shift = reach_stance_feet(model, &mut data, &legs, k, &knot.feet, &stance_at(k), &mut q)?;
        base_shift[k] = [shift.x, shift.y, shift.z];
    }
    let base_shift = windowed_envelope(&base_shift, BASE_SMOOTHING);
    let mut lift_off_angles = [[0.0; 3]; 4];
    // Per knot and leg, the joint-angle change that lifts an airborne foot off the box.
    let mut box_lift = vec![[[0.0f64; 3]; 4]; n];
    for (k, knot) in srb.knots.iter().enumerate() {
        set_base(&mut q, &knot.com, &knot.rotation, &params.com_in_base);
        for a in 0..3 {
            q[a] += base_shift[k][a];
        }
        // Stance legs, with the base moved further towards the feet if the smoothed shift
        // still leaves one out of reach.
        reach_stance_feet(model, &mut data, &legs, k, &knot.feet, &stance_at(k), &mut q)?;
        for f in 0..4 {
            let leg = &legs[f];
            if k < lift_off[f] {
                lift_off_angles[f] = std::array::from_fn(|a| q[leg.q_index[a]]);
            } else if k == lift_off[f] {
                // The lift-off knot: as close to the contact point as the joint limits allow.
                let anchor = srb.knots[k - 1].feet[f];
                leg_inverse_kinematics(model, &mut data, leg, &anchor, &mut q);
                lift_off_angles[f] = std::array::from_fn(|a| q[leg.q_index[a]]);
            } else {
                let s = smoothstep((k - lift_off[f]) as f64 / (prelanding_start - lift_off[f]).max(1) as f64);
                for a in 0..3 {
                    let i = leg.q_index[a];
                    q[i] = lift_off_angles[f][a] + (q_pre[i] - lift_off_angles[f][a]) * s;
                }
            }
        }
        if let Some(b) = obstacle {
            // Airborne feet out of the box's clearance: moved along the signed distance's
            // gradient to `radius + BOX_MARGIN` (as far as the leg reaches); the change of
            // the leg's angles is kept apart and smoothed over time below.
            forward_kinematics(model, &mut data, &q);
            let mut lifted = q.clone();
            for f in (0..4).filter(|&f| k > lift_off[f]) {
                let clearance = model.feet[f].radius + BOX_MARGIN;
                let p = foot_position(model, &data, &legs[f]);
                let (distance, gradient) = b.signed_distance(&p);
                if distance < clearance {
                    let target = p + gradient * (clearance - distance);
                    leg_inverse_kinematics(model, &mut data, &legs[f], &target, &mut lifted);
                    for a in 0..3 {
                        let i = legs[f].q_index[a];
                        box_lift[k][f][a] = lifted[i] - q[i];
                    }
                }
            }
        }
        qs.push(q.clone());
    }
    if obstacle.is_some() {
        // A lift applied knot by knot would start and stop within one step (a velocity
        // jump the dynamics rows cannot follow): each leg gets the largest lift within
        // +-BOX_SMOOTHING knots, averaged over the same window, so the foot rises before
        // it needs to and comes down after it has passed the edge.
        let w = BOX_SMOOTHING;
        for f in 0..4 {
            let lift_of_leg: Vec<[f64; 3]> = box_lift.iter().map(|l| l[f]).collect();
            let smoothed = windowed_envelope(&lift_of_leg, w);
            for k in (0..n).filter(|&k| k > lift_off[f] && k < prelanding_start) {
                for a in 0..3 {
                    let i = legs[f].q_index[a];
                    let jnt = &model.joints[model.joint_of_dof[legs[f].v_index[a]]];
                    qs[k][i] = (qs[k][i] + smoothed[k][a]).clamp(jnt.limits.lower[0], jnt.limits.upper[0]);
                }
            }
        }
    }
    let mut traj = Trajectory::new(model, "fullbody initial guess (Nguyen 2022, sec. II-C)", dt, TerrainSpec::flat());
    let mut v = DVector::zeros(model.nv);
    let mut jac = Matrix3xX::zeros(model.nv);
    for (k, knot) in srb.knots.iter().enumerate() {
        if k > 0 {
            difference(model, &qs[k - 1], &qs[k], &mut v);
            v /= dt;
        }
        compute_joint_jacobians(model, &mut data, &qs[k]);
        let mut tau = vec![0.0; model.nv - 6];
        for f in 0..4 {
            if !knot.contacts[f] {
                continue;
            }
            let leg = &legs[f];
            let p = frame_position(model, &data, leg.foot_frame);
            point_jacobian(model, &data, leg.knee_joint, &p, &mut jac);
            for a in 0..3 {
                let c = leg.v_index[a];
                tau[c - 6] = -(jac[(0, c)] * knot.forces[f].x + jac[(1, c)] * knot.forces[f].y + jac[(2, c)] * knot.forces[f].z);
            }
        }
        traj.knots.push(Knot {
            t: knot.t,
            q: qs[k].as_slice().to_vec(),
            v: v.as_slice().to_vec(),
            tau,
            contact_force: knot.forces.iter().map(|f| [f.x, f.y, f.z]).collect(),
            in_contact: knot.contacts.to_vec(),
            feedback_gain: None,
        });
    }
    traj.summary.insert("pre_landing_knots".into(), pre_landing_knots.into());
    Ok(traj)
}
