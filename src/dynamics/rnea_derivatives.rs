//! Analytic derivatives of inverse dynamics (Carpentier & Mansard 2018, "Analytical
//! derivatives of rigid body dynamics algorithms", RSS, Alg. 1 and §III).
//!
//! Everything is expressed in the world frame ("o" quantities), where the derivative of a
//! joint's Jacobian column with respect to an ancestor's motion is a plain cross product
//! (`d J_j / d q_k = J_k x J_j` for `k` ancestor of `j`). The derivatives are taken in the
//! tangent space of the configuration manifold: `d/dq` means `d/d delta` at `delta = 0` with
//! `q (+) delta`, the base perturbed by a right (local) SE(3) increment, as Pinocchio.

use super::kinematics::{joint_motion, local_placement};
use super::Data;
use crate::model::{JointKind, Model};
use crate::spatial::{skew, Force, Inertia, Matrix6, Motion};
use nalgebra::{DVector, Vector6};

/// `crm(v)`: the matrix of `m -> v x m` (linear first): `[[w]x, [v]x; 0, [w]x]`.
#[inline]
fn motion_cross_matrix(v: &Motion) -> Matrix6 {
    let mut m = Matrix6::zeros();
    let w = skew(&v.w);
    m.fixed_view_mut::<3, 3>(0, 0).copy_from(&w);
    m.fixed_view_mut::<3, 3>(3, 3).copy_from(&w);
    m.fixed_view_mut::<3, 3>(0, 3).copy_from(&skew(&v.v));
    m
}

/// Time derivative of a world inertia carried with twist `v`, plus the matrix of
/// `m -> m x* h` for the body momentum `h = Y v`:
///
/// `dY = v x* Y - Y v x  +  [m -> m x* h]`   (Carpentier & Mansard 2018, eq. (14)-(15)).
#[inline]
fn inertia_variation_plus_momentum_cross(y: &Inertia, v: &Motion, h: &Force) -> Matrix6 {
    let ym = y.matrix();
    let crm = motion_cross_matrix(v);
    // crf(v) = -crm(v)^T
    let mut out = -(crm.transpose() * ym) - ym * crm;
    // m x* h = [w x h_f; w x h_n + v x h_f] = [[0, -[h_f]x]; [-[h_f]x, -[h_n]x]] [v; w]
    let hf = skew(&h.f);
    let hn = skew(&h.n);
    for r in 0..3 {
        for c in 0..3 {
            out[(r, 3 + c)] -= hf[(r, c)];
            out[(3 + r, c)] -= hf[(r, c)];
            out[(3 + r, 3 + c)] -= hn[(r, c)];
        }
    }
    out
}

#[inline]
fn col_motion(m: &nalgebra::Matrix6xX<f64>, k: usize) -> Motion {
    Motion::from_slice(m.column(k).as_slice())
}
#[inline]
fn set_col(m: &mut nalgebra::Matrix6xX<f64>, k: usize, x: &Vector6<f64>) {
    m.column_mut(k).copy_from(x);
}

/// Partial derivatives of `tau = RNEA(q, v, a)`: `data.dtau_dq`, `data.dtau_dv`, and
/// `data.mass_matrix` (`= d tau / d a`, full and symmetric); `data.tau` is set too.
///
/// Forward pass, for every joint `i` with parent `p` (world frame, `a^gf = a - g`):
///
/// ```text
/// J_i = oMi S_i,  dJ_i = ov_i x J_i
/// dV/dq_i = ov_p x J_i,  dA/dq_i = oa^gf_p x J_i + ov_p x dV/dq_i,  dA/dv_i = dJ_i + dV/dq_i
/// f_i = oY_i oa^gf_i + ov_i x* oY_i ov_i,  dY_i = ov_i x* oY_i - oY_i ov_i x + [. x* oh_i]
/// ```
///
/// Backward pass (composite quantities of the subtree of `i`, `sub(i)` its columns):
///
/// ```text
/// dtau/da[i, sub]  = J_i^T (oYc_i J_sub)
/// dtau/dq[i, sub]  = J_i^T (dYc_i dV/dq_sub + oYc_i dA/dq_sub)
/// dtau/dq[sub, i]  = (oYc J)_sub^T dA/dq_i + (dYc^T J)_sub^T dV/dq_i   (strict subtree)
/// dtau/dv likewise with dA/dv and J.
/// ```
pub fn compute_rnea_derivatives(model: &Model, data: &mut Data, q: &DVector<f64>, v: &DVector<f64>, a: &DVector<f64>) {
    let n = model.njoints();
    let minus_g = -model.gravity;
    // ---- forward pass
    for i in 1..n {
        let jnt = &model.joints[i];
        let p = jnt.parent;
        let li = local_placement(model, i, q);
        let vj = joint_motion(model, i, v);
        let aj = joint_motion(model, i, a);
        let (vi, ai, omi) = if p > 0 {
            let vi = li.act_inv(&data.v[p]) + vj;
            (vi, li.act_inv(&data.a[p]) + aj + vi.cross(&vj), &data.o_m_i[p] * &li)
        } else {
            (vj, aj + vj.cross(&vj), li)
        };
        data.li_m_i[i] = li;
        data.o_m_i[i] = omi;
        data.v[i] = vi;
        data.a[i] = ai;
        let oy = model.inertias[i].transformed(&omi);
        let ov = omi.act(&vi);
        let oa_gf = omi.act(&ai) + minus_g;
        let oh = oy.mul_motion(&ov);
        data.of[i] = oy.mul_motion(&oa_gf) + ov.cross_force(&oh);
        data.o_y_crb[i] = oy;
        data.ov[i] = ov;
        data.oa[i] = oa_gf;
        data.oh[i] = oh;
        let (ov_p, oa_gf_p) = if p > 0 { (data.ov[p], data.oa[p]) } else { (Motion::zero(), minus_g) };
        for k in jnt.idx_v..jnt.idx_v + jnt.nv {
            let s_local = match jnt.kind {
                JointKind::FreeFlyer => {
                    let mut e = Vector6::zeros();
                    e[k - jnt.idx_v] = 1.0;
                    Motion::from_vector(&e)
                }
                kind => kind.subspace(),
            };
            let jc = omi.act(&s_local);
            let dj = ov.cross(&jc);
            let dvdq = ov_p.cross(&jc);
            let dadq = oa_gf_p.cross(&jc) + ov_p.cross(&dvdq);
            let dadv = dj + dvdq;
            set_col(&mut data.jacobian, k, &jc.to_vector());
            set_col(&mut data.dj, k, &dj.to_vector());
            set_col(&mut data.dvdq, k, &dvdq.to_vector());
            set_col(&mut data.dadq, k, &dadq.to_vector());
            set_col(&mut data.dadv, k, &dadv.to_vector());
        }
        data.do_y_crb[i] = inertia_variation_plus_momentum_cross(&oy, &ov, &oh);
    }
    // ---- backward pass
    for i in (1..n).rev() {
        let jnt = &model.joints[i];
        let p = jnt.parent;
        let (iv, nvj) = (jnt.idx_v, jnt.nv);
        let sub_end = iv + model.nv_subtree[i];
        let oyc = data.o_y_crb[i];
        let doyc = data.do_y_crb[i];
        let of = data.of[i];
        for k in iv..iv + nvj {
            let jc = col_motion(&data.jacobian, k);
            data.tau[k] = jc.dot(&of);
            // dF/da (= A_g column, in the world origin), dY^T J
            let dfda = oyc.mul_motion(&jc).to_vector();
            set_col(&mut data.dfda, k, &dfda);
            let dytj = doyc.transpose() * jc.to_vector();
            set_col(&mut data.dytj, k, &dytj);
            let dvdq = col_motion(&data.dvdq, k);
            let dadq = col_motion(&data.dadq, k);
            let dadv = col_motion(&data.dadv, k);
            let mut dfdq = oyc.mul_motion(&dadq).to_vector();
            if p > 0 {
                dfdq += doyc * dvdq.to_vector();
            }
            set_col(&mut data.dfdq, k, &dfdq);
            let dfdv = doyc * jc.to_vector() + oyc.mul_motion(&dadv).to_vector();
            set_col(&mut data.dfdv, k, &dfdv);
        }
        for k in iv..iv + nvj {
            let jc = data.jacobian.column(k).clone_owned();
            let dvdq = data.dvdq.column(k).clone_owned();
            let dadq = data.dadq.column(k).clone_owned();
            let dadv = data.dadv.column(k).clone_owned();
            // rows of the joint, columns of the subtree
            for c in iv..sub_end {
                data.mass_matrix[(k, c)] = jc.dot(&data.dfda.column(c));
                data.dtau_dq[(k, c)] = jc.dot(&data.dfdq.column(c));
                data.dtau_dv[(k, c)] = jc.dot(&data.dfdv.column(c));
            }
            // rows of the strict subtree, columns of the joint
            for r in iv + nvj..sub_end {
                let fa = data.dfda.column(r);
                let yt = data.dytj.column(r);
                data.dtau_dq[(r, k)] = fa.dot(&dadq) + yt.dot(&dvdq);
                data.dtau_dv[(r, k)] = fa.dot(&dadv) + yt.dot(&jc);
            }
        }
        // dF/dq += J x* f (for the ancestors' rows)
        for k in iv..iv + nvj {
            let jc = col_motion(&data.jacobian, k);
            let add = jc.cross_force(&of).to_vector();
            let mut col = data.dfdq.column_mut(k);
            col += add;
        }
        if p > 0 {
            data.o_y_crb[p] = data.o_y_crb[p] + oyc;
            data.do_y_crb[p] += doyc;
            data.of[p] += of;
        }
    }
    // M: mirror the upper triangle.
    let nv = model.nv;
    for r in 0..nv {
        for c in 0..r {
            data.mass_matrix[(r, c)] = data.mass_matrix[(c, r)];
        }
    }
}
