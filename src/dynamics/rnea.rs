//! Recursive Newton-Euler algorithm: inverse dynamics `tau = M(q) a + C(q, v) v + g(q)`.

use super::kinematics::{joint_motion, local_placement};
use super::Data;
use crate::model::{JointKind, Model};
use crate::spatial::Motion;
use nalgebra::DVector;

/// Inverse dynamics (Featherstone 2008, Table 5.1, with gravity as a fictitious base
/// acceleration `a_0 = -g`):
///
/// ```text
/// forward:  v_i = iXp v_p + S_i qd_i
///           a_i = iXp a_p + S_i qdd_i + v_i x (S_i qd_i)
///           f_i = I_i a_i + v_i x* (I_i v_i)
/// backward: tau_i = S_i^T f_i,   f_p += pXi* f_i
/// ```
///
/// Returns `data.tau`.
pub fn rnea<'d>(model: &Model, data: &'d mut Data, q: &DVector<f64>, v: &DVector<f64>, a: &DVector<f64>) -> &'d DVector<f64> {
    let a0 = -model.gravity;
    for i in 1..model.njoints() {
        let li = local_placement(model, data, i, q);
        let p = model.joints[i].parent;
        let vj = joint_motion(model, i, v);
        let aj = joint_motion(model, i, a);
        let (vp, ap) = if p > 0 { (li.act_inv(&data.v[p]), li.act_inv(&data.a[p])) } else { (Motion::zero(), li.act_inv(&a0)) };
        let vi = vp + vj;
        let ai = ap + aj + vi.cross(&vj);
        let inertia = &model.inertias[i];
        data.f[i] = inertia.mul_motion(&ai) + vi.cross_force(&inertia.mul_motion(&vi));
        data.v[i] = vi;
        data.a[i] = ai;
        data.o_m_i[i] = if p > 0 { data.o_m_i[p] * li } else { li };
        data.li_m_i[i] = li;
    }
    for i in (1..model.njoints()).rev() {
        let j = &model.joints[i];
        let fi = data.f[i];
        match j.kind {
            JointKind::FreeFlyer => data.tau.as_mut_slice()[j.idx_v..j.idx_v + 6].copy_from_slice(fi.to_vector().as_slice()),
            k => data.tau[j.idx_v] = k.subspace().dot(&fi),
        }
        if j.parent > 0 {
            let fp = data.li_m_i[i].act_force(&fi);
            data.f[j.parent] += fp;
        }
    }
    &data.tau
}

/// Non-linear effects `C(q, v) v + g(q) = rnea(q, v, 0)`, into `data.nle`.
pub fn nonlinear_effects<'d>(model: &Model, data: &'d mut Data, q: &DVector<f64>, v: &DVector<f64>) -> &'d DVector<f64> {
    let zero = std::mem::take(&mut data.tmp_nv);
    let mut zero = zero;
    zero.fill(0.0);
    rnea(model, data, q, v, &zero);
    data.tmp_nv = zero;
    data.nle.copy_from(&data.tau);
    &data.nle
}

/// Generalized gravity `g(q) = rnea(q, 0, 0)`, into `data.g`.
pub fn generalized_gravity<'d>(model: &Model, data: &'d mut Data, q: &DVector<f64>) -> &'d DVector<f64> {
    let mut zero = std::mem::take(&mut data.tmp_nv);
    zero.fill(0.0);
    rnea(model, data, q, &zero, &zero);
    data.tmp_nv = zero;
    data.g.copy_from(&data.tau);
    &data.g
}
