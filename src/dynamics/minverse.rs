//! The inverse of the joint-space inertia matrix by an articulated-body recursion
//! (Carpentier & Mansard 2018, §IV: `M^-1` from the quantities of ABA; Pinocchio's
//! `computeMinverse`), in the world frame.
//!
//! Column `c` of `M^-1` is the acceleration ABA returns for a unit torque at `c` with zero
//! velocity and gravity. With `IA_i`, `U_i = IA_i S_i` and `D_i = S_i^T U_i` from ABA's
//! backward pass (world frame, so bias forces are summed into the parent without a change of
//! frame), the bias forces of all `nv` unit torques at once are the columns of `F` (6 x nv):
//!
//! ```text
//! backward, leaves to root, c in sub(i):
//!   Minv_b[i, c] = D_i^-1 (delta_ic - S_i^T F[:, c])           (u_i of ABA, times D_i^-1)
//!   F[:, c]     += U_i Minv_b[i, c]                            (pa_i = pA_i + U_i D_i^-1 u_i)
//! forward, root to leaves, c >= i (upper triangle; Minv_b = 0 outside sub(i)):
//!   Minv[i, c]   = Minv_b[i, c] - (U_i D_i^-1)^T A_p[:, c]     (qdd_i of ABA)
//!   A_i[:, c]    = A_p[:, c] + S_i Minv[i, c]                  (a_i of ABA, A_0 = 0)
//! ```
//!
//! For the free-flyer root (`S = X = oM1` as an action matrix, no parent) the six rows
//! close in `IA^-1`: with `P = IA^-1`, `D^-1 S^T = X^-1 P`, so
//!
//! ```text
//! Minv[b, b] = X^-1 P X^-T,   Minv[b, c] = -X^-1 P F[:, c],   A_1[:, c] = X Minv[b, c].
//! ```
//!
//! `O(n d)` for tree depth `d`, like the `L^T D L` route, but with no factorization of `M`
//! and, after ABA, no second sweep over the bodies: ABA derivatives get `M^-1` almost free.

use super::kinematics::local_placement;
use super::Data;
use crate::model::{JointKind, Model};
use crate::spatial::{Matrix6, Motion, Vector3, Vector6, SE3};
use nalgebra::{DMatrix, DVector};

/// The inverse of the joint-space inertia matrix, full and symmetric, into `data.minv`:
/// the world placements and inertias of ABA's first pass, its articulated inertias, then
/// [`minverse_from_articulated_inertias`].
pub fn compute_minverse<'d>(model: &Model, data: &'d mut Data, q: &DVector<f64>) -> &'d DMatrix<f64> {
    let n = model.njoints();
    // ABA pass 1 without velocities: oMi, s_i = oMi S_i, IA_i = oY_i.
    for i in 1..n {
        let jnt = &model.joints[i];
        let p = jnt.parent;
        let li = local_placement(model, data, i, q);
        let omi = if p > 0 { data.o_m_i[p] * li } else { li };
        if let kind @ (JointKind::Revolute { .. } | JointKind::Prismatic { .. }) = jnt.kind {
            data.o_j[i] = omi.act(&kind.subspace());
        }
        data.y_aba[i] = data.body_moments[i].transformed(&omi).matrix();
        data.o_m_i[i] = omi;
        data.li_m_i[i] = li;
    }
    // ABA pass 2 without bias forces: U = IA s, D = s^T U, IA_p += IA - U D^-1 U^T.
    for i in (1..n).rev() {
        let j = &model.joints[i];
        if let JointKind::Revolute { .. } | JointKind::Prismatic { .. } = j.kind {
            let s = data.o_j[i].to_vector();
            let ya = &data.y_aba[i];
            let u_col = ya * s;
            let d_inv = 1.0 / s.dot(&u_col);
            data.u_col[i] = u_col;
            data.d_inv[i] = d_inv;
            if j.parent > 0 {
                let ia = ya - u_col * (u_col.transpose() * d_inv);
                data.y_aba[j.parent] += ia;
            }
        }
    }
    minverse_from_articulated_inertias(model, data);
    &data.minv
}

#[inline(always)]
fn col6(s: &[f64], k: usize) -> [f64; 6] {
    s[6 * k..6 * k + 6].try_into().expect("6 rows")
}

#[inline(always)]
fn dot6(a: &[f64; 6], b: &[f64; 6]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3] + a[4] * b[4] + a[5] * b[5]
}

/// `X^-1 m` for a motion given as six numbers (linear first).
#[inline(always)]
fn act_inv6(x: &SE3, m: &[f64; 6]) -> [f64; 6] {
    let r = Motion::new(Vector3::new(m[0], m[1], m[2]), Vector3::new(m[3], m[4], m[5]));
    let b = x.act_inv(&r);
    [b.v.x, b.v.y, b.v.z, b.w.x, b.w.y, b.w.z]
}

/// `M^-1` into `data.minv` (full, symmetric) from the articulated-body quantities ABA leaves
/// in `data` (the world frame `o_m_i`, `o_j`, `u_col`, `d_inv` of the one-degree-of-freedom
/// joints and the root's articulated inertia `y_aba`): the two sweeps of the module
/// documentation. A free flyer must be a child of the universe.
pub(crate) fn minverse_from_articulated_inertias(model: &Model, data: &mut Data) {
    let n = model.njoints();
    let nv = model.nv;
    let minv = data.minv.as_mut_slice(); // column-major: (r, c) at r + c * nv
    let f = data.minv_f.as_mut_slice(); // 6 x nv, column c at 6 c
    let acc = data.minv_a.as_mut_slice(); // A_i: 6 x nv per joint, column c at 6 (i nv + c)
    // Backward sweep.
    for i in (1..n).rev() {
        let j = &model.joints[i];
        let (iv, end) = (j.idx_v, j.idx_v + model.nv_subtree[i]);
        match j.kind {
            JointKind::Universe => {}
            JointKind::FreeFlyer => {
                debug_assert_eq!(j.parent, 0, "a free flyer must be the root");
                let p = match data.y_aba[i].cholesky() {
                    Some(ch) => ch.inverse(),
                    None => Matrix6::from_element(f64::NAN),
                };
                let x = &data.o_m_i[i];
                let a1 = &mut acc[6 * i * nv..6 * (i + 1) * nv];
                // Children's columns: A_1[:, c] = -P F[:, c],  Minv[b, c] = X^-1 A_1[:, c].
                for c in iv + 6..end {
                    let fc = Vector6::from_column_slice(&f[6 * c..6 * c + 6]);
                    let w = -(p * fc);
                    a1[6 * c..6 * c + 6].copy_from_slice(w.as_slice());
                    let m = act_inv6(x, &col6(a1, c));
                    for (r, mr) in m.iter().enumerate() {
                        minv[iv + r + c * nv] = *mr;
                    }
                }
                // Own block: Q = X^-1 P (column by column), A_1[:, b] = Q^T = P X^-T,
                // Minv[b, b] = X^-1 Q^T.
                let mut qt = Matrix6::zeros();
                for k in 0..6 {
                    let pk: [f64; 6] = p.column(k).as_slice().try_into().expect("6 rows");
                    let qk = act_inv6(x, &pk);
                    for (r, v) in qk.iter().enumerate() {
                        qt[(k, r)] = *v;
                    }
                }
                for k in 0..6 {
                    let col: [f64; 6] = qt.column(k).as_slice().try_into().expect("6 rows");
                    a1[6 * (iv + k)..6 * (iv + k) + 6].copy_from_slice(&col);
                    let m = act_inv6(x, &col);
                    for (r, mr) in m.iter().enumerate() {
                        minv[iv + r + (iv + k) * nv] = *mr;
                    }
                }
            }
            JointKind::Revolute { .. } | JointKind::Prismatic { .. } => {
                let s = data.o_j[i];
                let s6 = [s.v.x, s.v.y, s.v.z, s.w.x, s.w.y, s.w.z];
                let u: [f64; 6] = data.u_col[i].as_slice().try_into().expect("6 rows");
                let d = data.d_inv[i];
                minv[iv + iv * nv] = d;
                for c in iv + 1..end {
                    let fc = &mut f[6 * c..6 * c + 6];
                    let m = -d * dot6(&s6, &(*fc).try_into().expect("6 rows"));
                    minv[iv + c * nv] = m;
                    for r in 0..6 {
                        fc[r] += u[r] * m;
                    }
                }
                let fi = &mut f[6 * iv..6 * iv + 6];
                for r in 0..6 {
                    fi[r] = u[r] * d;
                }
            }
        }
    }
    // Forward sweep (the free-flyer root's rows and A_1 are final already).
    for i in 1..n {
        let j = &model.joints[i];
        let (iv, end) = (j.idx_v, j.idx_v + model.nv_subtree[i]);
        let (JointKind::Revolute { .. } | JointKind::Prismatic { .. }) = j.kind else { continue };
        let p = j.parent;
        let s = data.o_j[i];
        let s6 = [s.v.x, s.v.y, s.v.z, s.w.x, s.w.y, s.w.z];
        let d = data.d_inv[i];
        let ud: [f64; 6] = std::array::from_fn(|r| data.u_col[i][r] * d);
        let has_children = end > iv + 1;
        let (before, rest) = acc.split_at_mut(6 * i * nv);
        let ai = &mut rest[..6 * nv];
        if p > 0 {
            let ap = &before[6 * p * nv..6 * (p + 1) * nv];
            for c in iv..nv {
                let apc = col6(ap, c);
                let b = if c < end { minv[iv + c * nv] } else { 0.0 };
                let m = b - dot6(&ud, &apc);
                minv[iv + c * nv] = m;
                if has_children && c > iv {
                    for r in 0..6 {
                        ai[6 * c + r] = apc[r] + s6[r] * m;
                    }
                }
            }
        } else {
            for c in iv..nv {
                let m = if c < end { minv[iv + c * nv] } else { 0.0 };
                minv[iv + c * nv] = m;
                if has_children && c > iv {
                    for r in 0..6 {
                        ai[6 * c + r] = s6[r] * m;
                    }
                }
            }
        }
    }
    data.minv.fill_lower_triangle_with_upper_triangle();
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dynamics::{aba, compute_aba_derivatives, crba, random_configuration};

    fn uniform(seed: &mut u64) -> f64 {
        *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (*seed >> 11) as f64 / (1u64 << 53) as f64
    }

    /// `compute_minverse` against the inverse of CRBA's `M` (Cholesky), and `M M^-1 = I`, on
    /// random configurations of both embedded robots (HyQ 86 kg, A1 13 kg).
    #[test]
    fn minverse_is_the_inverse_of_crba() {
        for robot in ["hyq", "a1"] {
            let model = crate::model::embedded::load(robot).unwrap();
            let mut data = Data::new(&model);
            let mut seed = 11u64;
            for _ in 0..20 {
                let q = random_configuration(&model, &mut || uniform(&mut seed));
                let minv = compute_minverse(&model, &mut data, &q).clone();
                let m = crba(&model, &mut data, &q).clone();
                let expected = m.clone().cholesky().expect("M is SPD").inverse();
                let err = (&minv - &expected).amax() / expected.amax();
                assert!(err < 1e-10, "{robot}: M^-1 off by {err:.2e} (relative)");
                let id = (&m * &minv - DMatrix::identity(model.nv, model.nv)).amax();
                assert!(id < 1e-10, "{robot}: M M^-1 - I = {id:.2e}");
                assert!(minv == minv.transpose(), "{robot}: M^-1 not symmetric");
            }
        }
    }

    /// The `M^-1` of the ABA derivatives (from ABA's own articulated inertias, with velocity
    /// and torque) is the one of `compute_minverse`.
    #[test]
    fn aba_derivatives_minverse_matches() {
        for robot in ["hyq", "a1"] {
            let model = crate::model::embedded::load(robot).unwrap();
            let mut data = Data::new(&model);
            let mut seed = 5u64;
            for _ in 0..10 {
                let q = random_configuration(&model, &mut || uniform(&mut seed));
                let v = DVector::from_fn(model.nv, |_, _| 2.0 * uniform(&mut seed) - 1.0);
                let tau = DVector::from_fn(model.nv, |_, _| 2.0 * uniform(&mut seed) - 1.0);
                let expected = compute_minverse(&model, &mut data, &q).clone();
                compute_aba_derivatives(&model, &mut data, &q, &v, &tau);
                let err = (&data.minv - &expected).amax() / expected.amax();
                assert!(err < 1e-12, "{robot}: M^-1 of the ABA derivatives off by {err:.2e}");
                let qdd = data.ddq.clone();
                assert!((aba(&model, &mut data, &q, &v, &tau) - qdd).amax() < 1e-12);
            }
        }
    }
}
