//! Articulated-body algorithm: forward dynamics `qdd = M(q)^-1 (tau - C(q, v) v - g(q))`.

use super::kinematics::{joint_motion, local_placement};
use super::Data;
use crate::model::{JointKind, Model};
use crate::spatial::{Force, Motion};
use nalgebra::DVector;

/// Forward dynamics by the articulated-body algorithm (Featherstone 2008, Table 7.1), in
/// the joints' local frames (Pinocchio's `Convention::LOCAL`). Returns `data.ddq`.
///
/// ```
/// use legwork::{model::embedded, dynamics::{Data, aba, crba, nonlinear_effects}};
/// let model = embedded::load("a1").unwrap();
/// let mut data = Data::new(&model);
/// let q = model.reference_configuration("standing").unwrap().clone();
/// let v = nalgebra::DVector::from_element(model.nv, 0.3);
/// let tau = nalgebra::DVector::from_element(model.nv, 1.0);
/// let qdd = aba(&model, &mut data, &q, &v, &tau).clone();
/// let m = crba(&model, &mut data, &q).clone();
/// let nle = nonlinear_effects(&model, &mut data, &q, &v).clone();
/// assert!((m * qdd + nle - tau).norm() < 1e-9);
/// ```
pub fn aba<'d>(model: &Model, data: &'d mut Data, q: &DVector<f64>, v: &DVector<f64>, tau: &DVector<f64>) -> &'d DVector<f64> {
    aba_impl(model, data, q, v, tau, None)
}

/// ABA with an external spatial force on each joint's body, expressed in that joint's
/// frame (`f_ext[i]`, index 0 ignored; Pinocchio's `fext`).
pub fn aba_with_external_forces<'d>(
    model: &Model,
    data: &'d mut Data,
    q: &DVector<f64>,
    v: &DVector<f64>,
    tau: &DVector<f64>,
    f_ext: &[Force],
) -> &'d DVector<f64> {
    assert_eq!(f_ext.len(), model.njoints(), "f_ext needs one force per joint (including the universe)");
    aba_impl(model, data, q, v, tau, Some(f_ext))
}

fn aba_impl<'d>(
    model: &Model,
    data: &'d mut Data,
    q: &DVector<f64>,
    v: &DVector<f64>,
    tau: &DVector<f64>,
    f_ext: Option<&[Force]>,
) -> &'d DVector<f64> {
    let n = model.njoints();
    // Pass 1: velocities, bias accelerations, rigid-body inertias and bias forces.
    //   v_i = iXp v_p + S qd,  c_i = v_i x (S qd),  IA_i = I_i,  pA_i = v_i x* I_i v_i - f_ext_i
    for i in 1..n {
        let li = local_placement(model, i, q);
        let p = model.joints[i].parent;
        let vj = joint_motion(model, i, v);
        let vi = if p > 0 { li.act_inv(&data.v[p]) + vj } else { vj };
        let inertia = &model.inertias[i];
        data.c[i] = vi.cross(&vj);
        data.y_aba[i] = inertia.matrix();
        let mut pa = vi.cross_force(&inertia.mul_motion(&vi));
        if let Some(fe) = f_ext {
            pa -= fe[i];
        }
        data.p_a[i] = pa;
        data.v[i] = vi;
        data.o_m_i[i] = if p > 0 { &data.o_m_i[p] * &li } else { li };
        data.li_m_i[i] = li;
    }
    // Pass 2: articulated inertias, leaves to root.
    //   U = IA S, D = S^T U, u = tau - S^T pA
    //   Ia = IA - U D^-1 U^T, pa = pA + Ia c + U D^-1 u;  IA_p += pXi* Ia iXp,  pA_p += pXi* pa
    for i in (1..n).rev() {
        let j = &model.joints[i];
        match j.kind {
            JointKind::FreeFlyer => {
                // S = I6: U = IA, D = IA, u = tau_base - pA. Handled in pass 3.
                let t = &tau.as_slice()[j.idx_v..j.idx_v + 6];
                let tb = Force::from_vector(&nalgebra::Vector6::from_column_slice(t));
                data.p_a[i] = tb - data.p_a[i];
                continue;
            }
            JointKind::Universe => continue,
            k => {
                let s = k.subspace().to_vector();
                let ya = &data.y_aba[i];
                let u_col = ya * s;
                let d_inv = 1.0 / s.dot(&u_col);
                let u = tau[j.idx_v] - s.dot(&data.p_a[i].to_vector());
                data.u_col[i] = u_col;
                data.d_inv[i] = d_inv;
                data.u_scalar[i] = u;
                if j.parent > 0 {
                    let ia = ya - u_col * (u_col.transpose() * d_inv);
                    let pa = data.p_a[i].to_vector() + ia * data.c[i].to_vector() + u_col * (u * d_inv);
                    let li = &data.li_m_i[i];
                    let y_parent = li.act_inertia_matrix(&ia);
                    data.y_aba[j.parent] += y_parent;
                    let fp = li.act_force(&Force::from_vector(&pa));
                    data.p_a[j.parent] += fp;
                }
            }
        }
    }
    // Pass 3: accelerations, root to leaves.
    //   a' = iXp a_p + c_i,  qdd_i = D^-1 (u - U^T a'),  a_i = a' + S qdd_i
    let a0 = -model.gravity;
    for i in 1..n {
        let j = &model.joints[i];
        let p = j.parent;
        let ap = if p > 0 { data.li_m_i[i].act_inv(&data.a[p]) } else { data.li_m_i[i].act_inv(&a0) };
        let a_prime = ap + data.c[i];
        match j.kind {
            JointKind::FreeFlyer => {
                // IA qdd = (tau - pA) - IA a'
                let ya = data.y_aba[i];
                let rhs = data.p_a[i].to_vector() - ya * a_prime.to_vector();
                let qdd = match ya.cholesky() {
                    Some(ch) => ch.solve(&rhs),
                    None => nalgebra::Vector6::from_element(f64::NAN),
                };
                data.ddq.as_mut_slice()[j.idx_v..j.idx_v + 6].copy_from_slice(qdd.as_slice());
                data.a[i] = a_prime + Motion::from_vector(&qdd);
            }
            JointKind::Universe => {}
            k => {
                let qdd = data.d_inv[i] * (data.u_scalar[i] - data.u_col[i].dot(&a_prime.to_vector()));
                data.ddq[j.idx_v] = qdd;
                data.a[i] = a_prime + k.subspace() * qdd;
            }
        }
    }
    &data.ddq
}
