//! Articulated-body algorithm: forward dynamics `qdd = M(q)^-1 (tau - C(q, v) v - g(q))`.

use super::kinematics::{joint_motion, local_placement};
use super::Data;
use crate::model::{JointKind, Model};
use crate::spatial::{Force, Motion, Vector3};
use nalgebra::DVector;

/// Forward dynamics by the articulated-body algorithm (Featherstone 2008, Table 7.1),
/// written in the world frame (Pinocchio's `Convention::WORLD`): articulated inertias are
/// then summed into the parent without a change of frame. Returns `data.ddq`; the world
/// spatial accelerations of the joints (gravity included, `a_0 = -g`) are in `data.oa`.
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
    aba_impl::<false>(model, data, q, v, tau, None, Placements::Compute)
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
    aba_impl::<false>(model, data, q, v, tau, Some(f_ext), Placements::Compute)
}

/// [`aba_with_external_forces`] after a forward kinematics at the same `q`
/// ([`super::forward_kinematics_velocity`]): the joints' placements `data.li_m_i`,
/// `data.o_m_i` are taken as they are, not recomputed (the same products in the same order:
/// the same result to the bit, without the first pass's trigonometry). The simulator's
/// step evaluates its contacts by that kinematics just before.
pub fn aba_with_external_forces_after_kinematics<'d>(
    model: &Model,
    data: &'d mut Data,
    q: &DVector<f64>,
    v: &DVector<f64>,
    tau: &DVector<f64>,
    f_ext: &[Force],
) -> &'d DVector<f64> {
    assert_eq!(f_ext.len(), model.njoints(), "f_ext needs one force per joint (including the universe)");
    aba_impl::<false>(model, data, q, v, tau, Some(f_ext), Placements::Known)
}

/// [`aba`] that also keeps each body's world inertia in `data.o_y_body` (for the RNEA
/// derivatives at the same configuration, [`super::compute_aba_derivatives`]).
pub(super) fn aba_keeping_body_inertias<'d>(model: &Model, data: &'d mut Data, q: &DVector<f64>, v: &DVector<f64>, tau: &DVector<f64>) -> &'d DVector<f64> {
    aba_impl::<true>(model, data, q, v, tau, None, Placements::Compute)
}

/// Whether an algorithm's first pass computes the joint placements or finds them in `data`.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Placements {
    Compute,
    Known,
}

fn aba_impl<'d, const KEEP_BODY_INERTIAS: bool>(
    model: &Model,
    data: &'d mut Data,
    q: &DVector<f64>,
    v: &DVector<f64>,
    tau: &DVector<f64>,
    f_ext: Option<&[Force]>,
    placements: Placements,
) -> &'d DVector<f64> {
    let n = model.njoints();
    // Pass 1 (world frame): joint axes, velocities, bias accelerations, inertias, bias forces.
    //   s_i = oMi S_i,  v_i = v_p + s_i qd,  c_i = v_p x (s_i qd),  IA_i = oY_i,
    //   pA_i = v_i x* oY_i v_i - oMi f_ext_i
    for i in 1..n {
        let jnt = &model.joints[i];
        let p = jnt.parent;
        let (li, omi) = match placements {
            Placements::Known => (data.li_m_i[i], data.o_m_i[i]),
            Placements::Compute => {
                let li = local_placement(model, data, i, q);
                (li, if p > 0 { data.o_m_i[p] * li } else { li })
            }
        };
        let ov_p = if p > 0 { data.ov[p] } else { Motion::zero() };
        let ov = match jnt.kind {
            JointKind::FreeFlyer => {
                data.c[i] = Motion::zero();
                ov_p + omi.act(&joint_motion(model, i, v))
            }
            JointKind::Universe => ov_p,
            kind => {
                let s = omi.act(&kind.subspace());
                let vj = s * v[jnt.idx_v];
                data.o_j[i] = s;
                data.c[i] = ov_p.cross(&vj);
                ov_p + vj
            }
        };
        let oy = data.body_moments[i].transformed(&omi);
        data.y_aba[i] = oy.matrix();
        if KEEP_BODY_INERTIAS {
            data.o_y_body[i] = oy;
        }
        let mut pa = ov.cross_force(&oy.mul_motion(&ov));
        if let Some(fe) = f_ext {
            pa -= omi.act_force(&fe[i]);
        }
        data.p_a[i] = pa;
        data.ov[i] = ov;
        data.o_m_i[i] = omi;
        data.li_m_i[i] = li;
    }
    // Pass 2: articulated inertias, leaves to root (world frame, so no transform):
    //   U = IA s, D = s^T U, u = tau - s^T pA
    //   Ia = IA - U D^-1 U^T,  pa = pA + Ia c + U D^-1 u;  IA_p += Ia,  pA_p += pa
    for i in (1..n).rev() {
        let j = &model.joints[i];
        match j.kind {
            JointKind::FreeFlyer => {
                // S = oX1: the base wrench moved to the world origin, minus the bias force.
                let t = &tau.as_slice()[j.idx_v..j.idx_v + 6];
                let tb = Force::new(Vector3::new(t[0], t[1], t[2]), Vector3::new(t[3], t[4], t[5]));
                data.p_a[i] = data.o_m_i[i].act_force(&tb) - data.p_a[i];
            }
            JointKind::Universe => {}
            _ => {
                let s = data.o_j[i].to_vector();
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
                    data.y_aba[j.parent] += ia;
                    data.p_a[j.parent] += Force::from_vector(&pa);
                }
            }
        }
    }
    // Pass 3: accelerations, root to leaves (world frame, a_0 = -g):
    //   a' = a_p + c_i,  qdd_i = D^-1 (u - U^T a'),  a_i = a' + s_i qdd_i
    // For the free-flyer root (s = oX1, c = 0): IA a_1 = oX1* tau_b - pA, qdd_b = oX1^-1 (a_1 - a_0).
    let a0 = -model.gravity;
    for i in 1..n {
        let j = &model.joints[i];
        let p = j.parent;
        let a_prime = if p > 0 { data.oa[p] + data.c[i] } else { a0 + data.c[i] };
        match j.kind {
            JointKind::FreeFlyer => {
                let ya = data.y_aba[i];
                let rhs = data.p_a[i].to_vector();
                let a1 = match ya.cholesky() {
                    Some(ch) => ch.solve(&rhs),
                    None => nalgebra::Vector6::from_element(f64::NAN),
                };
                let a1 = Motion::from_vector(&a1);
                let qdd = data.o_m_i[i].act_inv(&(a1 - a_prime));
                data.ddq.as_mut_slice()[j.idx_v..j.idx_v + 6].copy_from_slice(qdd.to_vector().as_slice());
                data.oa[i] = a1;
            }
            JointKind::Universe => data.oa[i] = a_prime,
            _ => {
                let qdd = data.d_inv[i] * (data.u_scalar[i] - data.u_col[i].dot(&a_prime.to_vector()));
                data.ddq[j.idx_v] = qdd;
                data.oa[i] = a_prime + data.o_j[i] * qdd;
            }
        }
    }
    &data.ddq
}
