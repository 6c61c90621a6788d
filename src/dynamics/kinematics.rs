//! Forward kinematics: joint placements from `q` (and velocities from `v`).

use super::Data;
use crate::model::{JointKind, Model};
use crate::spatial::{Matrix3, Motion, Vector3, SE3};
use nalgebra::DVector;

/// The motion of a joint: its frame's pose after moving by `q_j` (the joint's own
/// coordinates), relative to its pose at zero.
///
/// Revolute: `R = I + sin(t) [a]x + (1 - cos t) [a]x^2` (Rodrigues); prismatic: `p = a t`;
/// free flyer: translation `q[0..3]`, unit quaternion `q[3..7]` (x, y, z, w; normalised here).
#[inline]
pub fn joint_transform(kind: &JointKind, q_j: &[f64]) -> SE3 {
    match *kind {
        JointKind::Revolute { axis } => {
            let (s, c) = q_j[0].sin_cos();
            SE3::new(axis_rotation(&axis, s, c), Vector3::zeros())
        }
        JointKind::Prismatic { axis } => SE3::new(Matrix3::identity(), axis * q_j[0]),
        JointKind::FreeFlyer => {
            let t = Vector3::new(q_j[0], q_j[1], q_j[2]);
            let (x, y, z, w) = (q_j[3], q_j[4], q_j[5], q_j[6]);
            let n2 = x * x + y * y + z * z + w * w;
            let s = 2.0 / n2;
            let r = Matrix3::new(
                1.0 - s * (y * y + z * z), s * (x * y - z * w), s * (x * z + y * w),
                s * (x * y + z * w), 1.0 - s * (x * x + z * z), s * (y * z - x * w),
                s * (x * z - y * w), s * (y * z + x * w), 1.0 - s * (x * x + y * y),
            );
            SE3::new(r, t)
        }
        JointKind::Universe => SE3::identity(),
    }
}

/// Rotation by angle `t` (given as `sin t`, `cos t`) about the unit `axis`, specialised for
/// the coordinate axes, which almost every robot uses.
#[inline]
fn axis_rotation(a: &Vector3<f64>, s: f64, c: f64) -> Matrix3<f64> {
    if a.y == 0.0 && a.z == 0.0 {
        let s = s * a.x.signum();
        Matrix3::new(1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c)
    } else if a.x == 0.0 && a.z == 0.0 {
        let s = s * a.y.signum();
        Matrix3::new(c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c)
    } else if a.x == 0.0 && a.y == 0.0 {
        let s = s * a.z.signum();
        Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)
    } else {
        let k = 1.0 - c;
        Matrix3::new(
            c + k * a.x * a.x, k * a.x * a.y - s * a.z, k * a.x * a.z + s * a.y,
            k * a.x * a.y + s * a.z, c + k * a.y * a.y, k * a.y * a.z - s * a.x,
            k * a.x * a.z - s * a.y, k * a.y * a.z + s * a.x, c + k * a.z * a.z,
        )
    }
}

/// `liMi = placement * joint_transform(q_i)`. For a revolute joint, with the terms cached in
/// `Data` (Rodrigues' formula premultiplied by the placement rotation):
/// `R = Rp + sin(t) Rp[a]x + (1 - cos t) Rp[a]x^2`, `p = p_placement`.
#[inline]
pub(crate) fn local_placement(model: &Model, data: &Data, i: usize, q: &DVector<f64>) -> SE3 {
    let j = &model.joints[i];
    match j.kind {
        JointKind::Revolute { .. } => {
            let (s, c) = q[j.idx_q].sin_cos();
            let (a, b) = &data.revolute_terms[i];
            SE3::new(j.placement.rotation + a * s + b * (1.0 - c), j.placement.translation)
        }
        _ => {
            let qj = &q.as_slice()[j.idx_q..j.idx_q + j.nq];
            j.placement * joint_transform(&j.kind, qj)
        }
    }
}

/// Joint velocity `S qd` of joint `i` in its own frame.
#[inline]
pub(crate) fn joint_motion(model: &Model, i: usize, x: &DVector<f64>) -> Motion {
    let j = &model.joints[i];
    match j.kind {
        JointKind::FreeFlyer => Motion::from_slice(&x.as_slice()[j.idx_v..j.idx_v + 6]),
        JointKind::Universe => Motion::zero(),
        k => k.subspace() * x[j.idx_v],
    }
}

/// Forward kinematics: `data.li_m_i` and `data.o_m_i` for every joint.
pub fn forward_kinematics(model: &Model, data: &mut Data, q: &DVector<f64>) {
    for i in 1..model.njoints() {
        let li = local_placement(model, data, i, q);
        let p = model.joints[i].parent;
        data.o_m_i[i] = if p > 0 { data.o_m_i[p] * li } else { li };
        data.li_m_i[i] = li;
    }
}

/// Forward kinematics with velocities: also `data.v[i]`, the spatial velocity of each joint
/// in its own frame, `v_i = iXp v_p + S_i qd_i`.
pub fn forward_kinematics_velocity(model: &Model, data: &mut Data, q: &DVector<f64>, v: &DVector<f64>) {
    for i in 1..model.njoints() {
        let li = local_placement(model, data, i, q);
        let p = model.joints[i].parent;
        let vj = joint_motion(model, i, v);
        if p > 0 {
            data.o_m_i[i] = data.o_m_i[p] * li;
            data.v[i] = li.act_inv(&data.v[p]) + vj;
        } else {
            data.o_m_i[i] = li;
            data.v[i] = vj;
        }
        data.li_m_i[i] = li;
    }
}
