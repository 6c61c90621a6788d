//! Time series read off a trajectory's knots, without a robot model: the base position,
//! its roll, pitch and yaw, the base twist, the joint torques, the contact forces. The
//! replay's plots and the SVG figures draw the same [`Panel`]s.

use crate::io::{Knot, Trajectory};
use nalgebra::{Matrix3, UnitQuaternion, Vector3};

/// One named curve, sampled at the panel's times.
#[derive(Clone, Debug)]
pub(crate) struct Series {
    pub name: String,
    pub values: Vec<f64>,
}

/// One plot: a title, the unit of its y axis, curves over the same times.
#[derive(Clone, Debug)]
pub(crate) struct Panel {
    pub title: String,
    pub unit: String,
    pub series: Vec<Series>,
}

impl Panel {
    fn new(title: &str, unit: &str, names: &[&str], columns: Vec<Vec<f64>>) -> Self {
        let series = names.iter().zip(columns).map(|(n, values)| Series { name: (*n).to_string(), values }).collect();
        Panel { title: title.into(), unit: unit.into(), series }
    }
}

/// The knots to draw: the first, then each knot at least `min_dt` after the last one kept,
/// and always the last knot. Knot times need not be uniform.
pub(crate) fn sample_indices(knots: &[Knot], min_dt: f64) -> Vec<usize> {
    let mut kept: Vec<usize> = Vec::new();
    for (k, knot) in knots.iter().enumerate() {
        match kept.last() {
            Some(&last) if knot.t < knots[last].t + min_dt * (1.0 - 1e-9) => {}
            _ => kept.push(k),
        }
    }
    if let (Some(&last), Some(end)) = (kept.last(), knots.len().checked_sub(1)) {
        if last != end {
            kept.push(end);
        }
    }
    kept
}

/// The knots to draw so that at most `max_points` remain (about evenly spaced in time).
pub(crate) fn decimate(traj: &Trajectory, max_points: usize) -> Vec<usize> {
    let n = traj.knots.len();
    if n <= max_points {
        return (0..n).collect();
    }
    sample_indices(&traj.knots, traj.duration() / (max_points.max(2) - 1) as f64)
}

/// Rotation of the base (world from base) from `q[3..7]` (x, y, z, w).
pub(crate) fn base_rotation(q: &[f64]) -> Matrix3<f64> {
    base_quaternion(q).to_rotation_matrix().into_inner()
}

fn base_quaternion(q: &[f64]) -> UnitQuaternion<f64> {
    crate::dynamics::base_orientation(q)
}

/// Removes the 2 pi jumps of an angle sampled along a motion (a yaw passing pi).
pub(crate) fn unwrap_angles(values: &mut [f64]) {
    use std::f64::consts::{PI, TAU};
    for k in 1..values.len() {
        let jump = values[k] - values[k - 1];
        values[k] -= TAU * ((jump + PI) / TAU).floor();
    }
}

/// The times of the knots `idx`.
pub(crate) fn times(traj: &Trajectory, idx: &[usize]) -> Vec<f64> {
    idx.iter().map(|&k| traj.knots[k].t).collect()
}

fn columns(idx: &[usize], n: usize, mut f: impl FnMut(usize) -> Vec<f64>) -> Vec<Vec<f64>> {
    let mut cols = vec![Vec::with_capacity(idx.len()); n];
    for &k in idx {
        for (c, x) in cols.iter_mut().zip(f(k)) {
            c.push(x);
        }
    }
    cols
}

/// Base position in the world, `q[0..3]`, less the first knot's (so that a few
/// centimetres of bobbing show next to a base height of 0.6 m); the title gives the start.
pub(crate) fn base_position(traj: &Trajectory, idx: &[usize]) -> Panel {
    let start = idx.first().map_or([0.0; 3], |&k| [traj.knots[k].q[0], traj.knots[k].q[1], traj.knots[k].q[2]]);
    let cols = columns(idx, 3, |k| (0..3).map(|a| traj.knots[k].q[a] - start[a]).collect());
    let title = format!("Base position minus start ({:.3}, {:.3}, {:.3}), world", start[0], start[1], start[2]);
    Panel::new(&title, "m", &["x", "y", "z"], cols)
}

/// Roll, pitch, yaw of the base (`R = Rz(yaw) Ry(pitch) Rx(roll)`), unwrapped over time.
pub(crate) fn base_orientation(traj: &Trajectory, idx: &[usize]) -> Panel {
    let mut cols = columns(idx, 3, |k| {
        let (r, p, y) = base_quaternion(&traj.knots[k].q).euler_angles();
        vec![r, p, y]
    });
    for c in &mut cols {
        unwrap_angles(c);
    }
    Panel::new("Base roll, pitch, yaw", "rad", &["roll", "pitch", "yaw"], cols)
}

/// Base linear velocity turned into the world frame (`R v_B`; the file stores `v_B`).
pub(crate) fn base_linear_velocity(traj: &Trajectory, idx: &[usize]) -> Panel {
    let cols = columns(idx, 3, |k| {
        let knot = &traj.knots[k];
        let v = base_rotation(&knot.q) * Vector3::new(knot.v[0], knot.v[1], knot.v[2]);
        vec![v.x, v.y, v.z]
    });
    Panel::new("Base linear velocity (world)", "m/s", &["vx", "vy", "vz"], cols)
}

/// Base angular velocity in the base frame, `v[3..6]` as stored.
pub(crate) fn base_angular_velocity(traj: &Trajectory, idx: &[usize]) -> Panel {
    let cols = columns(idx, 3, |k| traj.knots[k].v[3..6].to_vec());
    Panel::new("Base angular velocity (base frame)", "rad/s", &["wx", "wy", "wz"], cols)
}

/// Torques of the joints `joints` (indices into `metadata.joint_names`).
pub(crate) fn joint_torques(traj: &Trajectory, idx: &[usize], joints: &[usize], title: &str) -> Panel {
    let names: Vec<String> = joints.iter().map(|&j| short_joint_name(&traj.metadata.joint_names[j])).collect();
    let names: Vec<&str> = names.iter().map(String::as_str).collect();
    let cols = columns(idx, joints.len(), |k| joints.iter().map(|&j| traj.knots[k].tau[j]).collect());
    Panel::new(title, "N m", &names, cols)
}

/// The world-frame force on foot `foot`, one series per axis.
pub(crate) fn contact_force(traj: &Trajectory, idx: &[usize], foot: usize) -> Panel {
    let cols = columns(idx, 3, |k| traj.knots[k].contact_force[foot].to_vec());
    let title = format!("Contact force on {} (world)", traj.metadata.foot_names[foot]);
    Panel::new(&title, "N", &["fx", "fy", "fz"], cols)
}

/// `lf_haa_joint` -> `lf_haa`: the suffix every joint shares says nothing on a legend.
pub(crate) fn short_joint_name(name: &str) -> String {
    name.strip_suffix("_joint").filter(|s| !s.is_empty()).unwrap_or(name).to_string()
}

/// The joints grouped by leg, from the name's prefix before the first `_` (`lf_haa_joint`,
/// `FL_hip_joint`), when that splits them into 2 to 6 groups of equal size; otherwise one
/// group of all joints.
pub(crate) fn joint_groups(names: &[String]) -> Vec<(String, Vec<usize>)> {
    let mut groups: Vec<(String, Vec<usize>)> = Vec::new();
    for (j, name) in names.iter().enumerate() {
        let prefix = name.split('_').next().unwrap_or("").to_string();
        match groups.iter_mut().find(|(p, _)| *p == prefix) {
            Some((_, members)) => members.push(j),
            None => groups.push((prefix, vec![j])),
        }
    }
    let even = groups.iter().all(|(p, m)| !p.is_empty() && m.len() == groups[0].1.len());
    if (2..=6).contains(&groups.len()) && even && groups[0].1.len() > 1 {
        groups
    } else {
        vec![(String::new(), (0..names.len()).collect())]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unwrapping_removes_jumps_of_two_pi() {
        let mut a = vec![3.0, 3.1, -3.1, -3.0, 3.1];
        unwrap_angles(&mut a);
        let tau = std::f64::consts::TAU;
        let expected = [3.0, 3.1, tau - 3.1, tau - 3.0, 3.1];
        for (x, e) in a.iter().zip(expected) {
            assert!((x - e).abs() < 1e-12, "{a:?}");
        }
    }

    #[test]
    fn legs_are_grouped_by_name_prefix() {
        let names: Vec<String> = ["lf_haa_joint", "lf_hfe_joint", "rf_haa_joint", "rf_hfe_joint"].iter().map(|s| s.to_string()).collect();
        let g = joint_groups(&names);
        assert_eq!(g, vec![("lf".to_string(), vec![0, 1]), ("rf".to_string(), vec![2, 3])]);
        let odd: Vec<String> = ["a", "b_x", "b_y"].iter().map(|s| s.to_string()).collect();
        assert_eq!(joint_groups(&odd), vec![(String::new(), vec![0, 1, 2])]);
        assert_eq!(short_joint_name("lf_haa_joint"), "lf_haa");
        assert_eq!(short_joint_name("_joint"), "_joint");
    }
}
