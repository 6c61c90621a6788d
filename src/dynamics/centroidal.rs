//! Centroidal momentum and the centroidal momentum matrix (Orin, Goswami & Lee 2013).

use super::jacobian::compute_joint_jacobians;
use super::Data;
use crate::model::Model;
use crate::spatial::{Force, Motion};
use nalgebra::{DVector, Matrix6xX};

/// Centroidal momentum matrix `A_g` (6 x nv, linear rows first) into
/// `data.centroidal_matrix`, with `h_g = A_g v` the linear momentum and the angular momentum
/// about the centre of mass, in world axes. Also sets `data.com`.
///
/// Column `k` of joint `j`: `A_g[:, k] = gX0* (oIC_j J_k)`, the composite world inertia of
/// the subtree of `j` times the world Jacobian column, moved to the CoM.
pub fn centroidal_map<'d>(model: &Model, data: &'d mut Data, q: &DVector<f64>) -> &'d Matrix6xX<f64> {
    compute_joint_jacobians(model, data, q);
    let n = model.njoints();
    for i in 0..n {
        data.o_y_crb[i] = data.body_moments[i].transformed(&data.o_m_i[i]);
    }
    for i in (1..n).rev() {
        let p = model.joints[i].parent;
        let child = data.o_y_crb[i];
        data.o_y_crb[p] += child;
    }
    let com = data.o_y_crb[0].first / data.o_y_crb[0].mass;
    data.com = com;
    for i in 1..n {
        let j = &model.joints[i];
        let y = data.o_y_crb[i];
        for k in j.idx_v..j.idx_v + j.nv {
            let col = Motion::from_slice(data.jacobian.column(k).as_slice());
            let f = y.mul_motion(&col);
            let fg = Force::new(f.f, f.n - com.cross(&f.f));
            data.centroidal_matrix.column_mut(k).copy_from(&fg.to_vector());
        }
    }
    &data.centroidal_matrix
}

/// Centroidal momentum `h_g = A_g v` (linear momentum, angular momentum about the CoM, world
/// axes) into `data.centroidal_momentum`.
pub fn centroidal_momentum(model: &Model, data: &mut Data, q: &DVector<f64>, v: &DVector<f64>) -> Force {
    centroidal_map(model, data, q);
    let h = &data.centroidal_matrix * v;
    data.centroidal_momentum = Force::from_vector(&h);
    data.centroidal_momentum
}
