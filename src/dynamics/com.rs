//! Centre of mass and its Jacobian.

use super::jacobian::compute_joint_jacobians;
use super::kinematics::forward_kinematics;
use super::Data;
use crate::model::Model;
use nalgebra::{DVector, Matrix3xX, Vector3};

/// Whole-body centre of mass in the world, `c = sum m_i c_i / sum m_i`, into `data.com`;
/// also the mass and CoM of every subtree (`data.subtree_mass`, `data.subtree_com`).
pub fn center_of_mass(model: &Model, data: &mut Data, q: &DVector<f64>) -> Vector3<f64> {
    forward_kinematics(model, data, q);
    subtree_coms(model, data);
    data.com
}

fn subtree_coms(model: &Model, data: &mut Data) {
    let n = model.njoints();
    for i in 0..n {
        let inertia = &model.inertias[i];
        data.subtree_mass[i] = inertia.mass;
        data.subtree_com[i] = data.o_m_i[i].act_point(&inertia.com) * inertia.mass;
    }
    for i in (1..n).rev() {
        let p = model.joints[i].parent;
        data.subtree_mass[p] += data.subtree_mass[i];
        let s = data.subtree_com[i];
        data.subtree_com[p] += s;
    }
    for i in 0..n {
        if data.subtree_mass[i] > 0.0 {
            data.subtree_com[i] /= data.subtree_mass[i];
        }
    }
    data.com = data.subtree_com[0];
}

/// Jacobian of the centre of mass (3 x nv), `d c / dt = J_c v`, into `data.com_jacobian`.
///
/// Column of degree of freedom `k` of joint `j`: `(m_sub(j) / m) (v0_k + w_k x c_sub(j))`,
/// where `[v0_k; w_k]` is the world Jacobian column (Pinocchio `jacobianCenterOfMass`).
pub fn com_jacobian<'d>(model: &Model, data: &'d mut Data, q: &DVector<f64>) -> &'d Matrix3xX<f64> {
    compute_joint_jacobians(model, data, q);
    subtree_coms(model, data);
    let total = data.subtree_mass[0];
    for i in 1..model.njoints() {
        let j = &model.joints[i];
        let ratio = data.subtree_mass[i] / total;
        let c = data.subtree_com[i];
        for k in j.idx_v..j.idx_v + j.nv {
            let col = data.jacobian.column(k);
            let v0 = Vector3::new(col[0], col[1], col[2]);
            let w = Vector3::new(col[3], col[4], col[5]);
            data.com_jacobian.column_mut(k).copy_from(&((v0 + w.cross(&c)) * ratio));
        }
    }
    let _ = forward_kinematics;
    &data.com_jacobian
}

/// Unused import guard for Matrix3xX in docs.
#[allow(dead_code)]
type _J = Matrix3xX<f64>;
