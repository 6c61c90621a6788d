//! The centroidal momentum `h_G(q, v) = A_G(q) v` and its exact derivatives, for the
//! ballistic flight of the full-body jumps (Nguyen 2022, sec. II-C: in flight only gravity
//! acts, so `h_G` changes by `m g dt` per interval, its angular part not at all).
//!
//! `d h_G / d v = A_G(q)` (Orin, Goswami & Lee 2013). `d h_G / d q` along the tangent
//! column `c` of joint `i` (world twist `S_c`, the joint Jacobian's column): moving the
//! joint moves its subtree's bodies by `S_c`, so each body's world inertia turns,
//! `dY_b = S_c x* Y_b - Y_b S_c x`, and each body's world velocity gains
//! `dv_b = S_c x (v_b - v_parent(i))`; summed over the subtree, the momentum at the world
//! origin changes by
//!
//! ```text
//! d h_O / d q_c = S_c x* h_sub(i) - Y_sub(i) (S_c x v_parent(i))
//! ```
//!
//! with `h_sub(i)` the subtree's momentum and `Y_sub(i)` its composite inertia (world).
//! Moved to the CoM: `n_G = n_O - c x f`, `d n_G = d n_O - dc x f - c x df`, with
//! `dc = (w_c x first_sub(i) + m_sub(i) v_c) / m` the CoM's shift.

use crate::dynamics::{compute_joint_jacobians, Data};
use crate::model::Model;
use crate::spatial::{Force, InertiaMoments, Motion};
use nalgebra::{DVector, Matrix6xX, Vector6};

/// Buffers of [`centroidal_momentum_derivatives`] (allocated once per stage).
pub(crate) struct MomentumWorkspace {
    pub data: Data,
    /// World spatial velocity (at the origin) of each joint's body.
    velocity: Vec<Motion>,
    /// Each body's world inertia, then (backward pass) its subtree's.
    subtree_inertia: Vec<InertiaMoments>,
    /// The subtree's momentum at the world origin.
    subtree_momentum: Vec<Force>,
    /// `A_G(q)` and `d h_G / d q` (6 x nv, linear rows first, world axes, about the CoM).
    pub a_g: Matrix6xX<f64>,
    pub dh_dq: Matrix6xX<f64>,
    /// The robot's mass (of the last evaluation).
    pub mass: f64,
}

impl MomentumWorkspace {
    pub fn new(model: &Model) -> Self {
        let n = model.njoints();
        Self {
            data: Data::new(model),
            velocity: vec![Motion::zero(); n],
            subtree_inertia: vec![InertiaMoments::zero(); n],
            subtree_momentum: vec![Force::zero(); n],
            a_g: Matrix6xX::zeros(model.nv),
            dh_dq: Matrix6xX::zeros(model.nv),
            mass: 0.0,
        }
    }
}

/// `h_G = A_G(q) v` (linear momentum, angular momentum about the CoM, world axes); with
/// `derivatives`, also `A_G` into `ws.a_g` and `d h_G / d dq` (the tangent `q (+) dq` of
/// `crate::dynamics::integrate` at `dq = 0`) into `ws.dh_dq`.
pub(crate) fn centroidal_momentum_derivatives(model: &Model, ws: &mut MomentumWorkspace, q: &DVector<f64>, v: &DVector<f64>, derivatives: bool) -> Vector6<f64> {
    let data = &mut ws.data;
    compute_joint_jacobians(model, data, q);
    let n = model.njoints();
    // Forward: world velocities v_i = v_parent + sum_c S_c v_c.
    ws.velocity[0] = Motion::zero();
    for i in 1..n {
        let j = &model.joints[i];
        let mut vi = ws.velocity[j.parent];
        for c in j.idx_v..j.idx_v + j.nv {
            vi += Motion::from_slice(data.jacobian.column(c).as_slice()) * v[c];
        }
        ws.velocity[i] = vi;
        ws.subtree_inertia[i] = data.body_moments[i].transformed(&data.o_m_i[i]);
        ws.subtree_momentum[i] = ws.subtree_inertia[i].mul_motion(&vi);
    }
    ws.subtree_inertia[0] = InertiaMoments::zero();
    ws.subtree_momentum[0] = Force::zero();
    // Backward: subtree sums.
    for i in (1..n).rev() {
        let p = model.joints[i].parent;
        let (y, h) = (ws.subtree_inertia[i], ws.subtree_momentum[i]);
        ws.subtree_inertia[p] += y;
        ws.subtree_momentum[p] += h;
    }
    let total = ws.subtree_inertia[0];
    ws.mass = total.mass;
    let com = total.first / total.mass;
    let h_o = ws.subtree_momentum[0];
    let h_g = Force::new(h_o.f, h_o.n - com.cross(&h_o.f));
    if derivatives {
        for i in 1..n {
            let j = &model.joints[i];
            let (y, h_sub, v_parent) = (ws.subtree_inertia[i], ws.subtree_momentum[i], ws.velocity[j.parent]);
            for c in j.idx_v..j.idx_v + j.nv {
                let s = Motion::from_slice(data.jacobian.column(c).as_slice());
                // A_G column: the subtree's momentum of the twist S_c, moved to the CoM.
                let a = y.mul_motion(&s);
                ws.a_g.column_mut(c).copy_from(&Force::new(a.f, a.n - com.cross(&a.f)).to_vector());
                let dh_o = s.cross_force(&h_sub) - y.mul_motion(&s.cross(&v_parent));
                let dcom = (s.w.cross(&y.first) + s.v * y.mass) / total.mass;
                let dn = dh_o.n - dcom.cross(&h_o.f) - com.cross(&dh_o.f);
                ws.dh_dq.column_mut(c).copy_from(&Force::new(dh_o.f, dn).to_vector());
            }
        }
    }
    h_g.to_vector()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dynamics::{centroidal_momentum, integrate};
    use crate::model::embedded;

    /// `A_G` against `dynamics::centroidal_map`, `d h_G / d q` against central differences
    /// of `dynamics::centroidal_momentum` along the tangent, at a tumbling, swinging A1.
    #[test]
    fn centroidal_momentum_derivatives_match_the_map_and_central_differences() {
        let model = embedded::load("a1").unwrap();
        let nv = model.nv;
        let mut q = DVector::zeros(model.nq);
        let dq0 = DVector::from_fn(nv, |i, _| 0.3 * ((i as f64) * 1.7).sin());
        let mut neutral = DVector::zeros(model.nq);
        neutral[6] = 1.0;
        integrate(&model, &neutral, &dq0, &mut q);
        let v = DVector::from_fn(nv, |i, _| 2.0 * ((i as f64) * 0.9 + 0.3).cos());
        let mut ws = MomentumWorkspace::new(&model);
        let h = centroidal_momentum_derivatives(&model, &mut ws, &q, &v, true);
        let mut data = Data::new(&model);
        let reference = centroidal_momentum(&model, &mut data, &q, &v).to_vector();
        assert!((h - reference).norm() < 1e-12 * (1.0 + reference.norm()), "h_G {h} vs {reference}");
        assert!((&ws.a_g - &data.centroidal_matrix).norm() < 1e-12 * (1.0 + ws.a_g.norm()));
        let eps = 1e-6;
        let (mut qp, mut qm) = (q.clone(), q.clone());
        for c in 0..nv {
            let mut e = DVector::zeros(nv);
            e[c] = eps;
            integrate(&model, &q, &e, &mut qp);
            e[c] = -eps;
            integrate(&model, &q, &e, &mut qm);
            let fd = (centroidal_momentum(&model, &mut data, &qp, &v).to_vector() - centroidal_momentum(&model, &mut data, &qm, &v).to_vector()) / (2.0 * eps);
            let exact = ws.dh_dq.column(c);
            assert!((exact - fd).norm() < 1e-6 * (1.0 + fd.norm()), "column {c}: exact {exact} vs differences {fd}");
        }
    }
}
