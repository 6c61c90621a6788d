//! Analytic derivatives of forward dynamics and the inverse of the joint-space inertia
//! matrix.
//!
//! Carpentier & Mansard 2018 (§IV, eq. (21)): differentiating `M(q) qdd + b(q, v) = tau`
//! at `qdd = ABA(q, v, tau)` gives
//!
//! ```text
//! d qdd / dq   = -M^-1 d RNEA/dq (q, v, qdd)
//! d qdd / dv   = -M^-1 d RNEA/dv (q, v, qdd)
//! d qdd / dtau =  M^-1
//! ```
//!
//! `M^-1` comes from the tree-sparse `L^T D L` factorization of `M` (Featherstone 2008,
//! §6.5, Table 6.3), which exploits that `M_ij = 0` unless `i` and `j` lie on one branch.

use crate::linalg::gemm;
use super::aba::aba_keeping_body_inertias;
use super::crba::crba;
use super::minverse_limbs::neg_minv_times_limb_sparse;
use super::rnea_derivatives::compute_rnea_derivatives_after_aba;
use super::Data;
use crate::model::Model;
use nalgebra::{DMatrix, DVector};


const ROOT: usize = usize::MAX;

/// In-place `M = L^T D L` (Featherstone 2008, Table 6.3) on a column-major `n x n` slice: on
/// return the strict lower triangle holds `L` (unit diagonal implied) and the diagonal `D`.
/// `chains`, `starts`: each degree of freedom's branch to the root, itself first
/// ([`Data`]'s `dof_chains`); only the entries on a branch are touched.
pub(super) fn ltdl_in_place(h: &mut [f64], n: usize, (chains, starts): (&[usize], &[usize])) {
    let chain = |k: usize| &chains[starts[k]..starts[k + 1]];
    for k in (0..n).rev() {
        let hkk = h[k + k * n];
        let ancestors = &chain(k)[1..];
        for (m, &i) in ancestors.iter().enumerate() {
            // a = H_ki / H_kk;  H_ij -= a H_kj for j on the branch of i;  H_ki = a
            let a = h[k + i * n] / hkk;
            for &j in &ancestors[m..] {
                h[i + j * n] -= a * h[k + j * n];
            }
            h[k + i * n] = a;
        }
    }
}

/// `M^-1 = L^-1 D^-1 L^-T` from the factor in `h`, into `out` (full, symmetric);
/// `linv` is scratch for `L^-1`, `chain(k)` the branch from `k` to the root (`k` first).
///
/// `L^-1` has the branch pattern of `L`: from `L L^-1 = I`,
/// `L^-1[i, j] = -sum_{k on the branch from i (excluded) to j (included)} L[i, k] L^-1[k, j]`.
/// Then `M^-1[a, b] = sum_{k common ancestor of a and b} L^-1[a, k] L^-1[b, k] / D_k`,
/// summed from `b` towards the root; `L^-1[a, k]` is zero unless `k` is on `a`'s branch, so
/// column `b` is summed for every `a >= b` at once, a column of `L^-1` at a time (vector
/// operations; each entry's sum in the same order).
pub(super) fn minv_from_ltdl(h: &[f64], n: usize, (chains, starts): (&[usize], &[usize]), linv: &mut [f64], d_inv: &mut [f64], column: &mut [f64], out: &mut [f64]) {
    let chain = |k: usize| &chains[starts[k]..starts[k + 1]];
    for k in 0..n {
        d_inv[k] = 1.0 / h[k + k * n];
    }
    linv.fill(0.0);
    for i in 0..n {
        linv[i + i * n] = 1.0;
        let ancestors = &chain(i)[1..];
        for (m, &j) in ancestors.iter().enumerate() {
            let mut acc = 0.0;
            // k from i's parent down to j (the branch's indices decrease towards the root).
            for &k in &ancestors[..=m] {
                acc += h[i + k * n] * linv[k + j * n];
            }
            linv[i + j * n] = -acc;
        }
    }
    for b in 0..n {
        let column = &mut column[b..n];
        column.fill(0.0);
        for &k in chain(b) {
            let (l_bk, d_k) = (linv[b + k * n], d_inv[k]);
            for (acc, l_ak) in column.iter_mut().zip(&linv[b + k * n..(k + 1) * n]) {
                *acc += l_ak * l_bk * d_k;
            }
        }
        for (a, &acc) in (b..n).zip(column.iter()) {
            out[a + b * n] = acc;
            out[b + a * n] = acc;
        }
    }
}

/// The inverse of the joint-space inertia matrix, full and symmetric, into `data.minv`
/// (also fills `data.mass_matrix`).
pub fn compute_minverse<'d>(model: &Model, data: &'d mut Data, q: &DVector<f64>) -> &'d DMatrix<f64> {
    crba(model, data, q);
    invert_mass_matrix(model, data);
    &data.minv
}

/// `data.minv` from `data.mass_matrix`: on a trunk with equal serial limbs by
/// [`super::minverse_limbs`] (the same bits), otherwise by the general factor below (which
/// leaves `L^T D L` in `data.ltdl`).
fn invert_mass_matrix(model: &Model, data: &mut Data) {
    if let Some(layout) = data.limb_layout {
        super::minverse_limbs::invert(layout, &data.mass_matrix, &mut data.minv);
        return;
    }
    invert_mass_matrix_general(model, data);
}

fn invert_mass_matrix_general(model: &Model, data: &mut Data) {
    let n = model.nv;
    data.ltdl.copy_from(&data.mass_matrix);
    ltdl_in_place(data.ltdl.as_mut_slice(), n, (&data.dof_chains, &data.dof_chain_starts));
    minv_from_ltdl(
        data.ltdl.as_slice(),
        n,
        (&data.dof_chains, &data.dof_chain_starts),
        data.linv.as_mut_slice(),
        data.tmp_nv.as_mut_slice(),
        &mut data.minv_column,
        data.minv.as_mut_slice(),
    );
}

/// `x <- M^-1 x` for the mass matrix in `data.mass_matrix` (as [`crba`] or
/// `compute_rnea_derivatives` leave it), by the sparse `L^T D L` factor (Featherstone 2008,
/// Table 6.4): `L^T y = x` from the leaves up, `y <- D^-1 y`, `L x = y` from the root down.
/// `O(n d)` for depth `d`, no inverse formed; the factor is left in `data.ltdl`.
pub fn mass_matrix_solve(model: &Model, data: &mut Data, x: &mut [f64]) {
    mass_matrix_factor(model, data);
    mass_matrix_factored_solve(model, data, x);
}

/// The sparse `M = L^T D L` factor (Featherstone 2008, Table 6.3) of `data.mass_matrix` into
/// `data.ltdl`, for [`mass_matrix_factored_solve`]: `M` depends on `q` only, so solves at one
/// configuration with other velocities or right-hand sides share it.
pub fn mass_matrix_factor(model: &Model, data: &mut Data) {
    data.ltdl.copy_from(&data.mass_matrix);
    ltdl_in_place(data.ltdl.as_mut_slice(), model.nv, (&data.dof_chains, &data.dof_chain_starts));
}

/// `x <- M^-1 x` with the factor [`mass_matrix_factor`] left in `data.ltdl` (Featherstone
/// 2008, Table 6.4): `L^T y = x` from the leaves up, `y <- D^-1 y`, `L x = y` from the root
/// down.
pub fn mass_matrix_factored_solve(model: &Model, data: &Data, x: &mut [f64]) {
    let n = model.nv;
    let lambda = &model.dof_parent;
    let h = data.ltdl.as_slice();
    for i in (0..n).rev() {
        let mut j = lambda[i];
        while j != ROOT {
            x[j] -= h[i + j * n] * x[i];
            j = lambda[j];
        }
    }
    for i in 0..n {
        x[i] /= h[i + i * n];
    }
    for i in 0..n {
        let mut j = lambda[i];
        while j != ROOT {
            x[i] -= h[i + j * n] * x[j];
            j = lambda[j];
        }
    }
}

/// Partial derivatives of forward dynamics `qdd = ABA(q, v, tau)`: `data.ddq_dq`,
/// `data.ddq_dv` (tangent-space convention of `shared/fixtures/README.md`) and
/// `data.minv` (`= d qdd / d tau`). Also sets `data.ddq`.
///
/// ABA, then the RNEA derivatives at its `qdd` on its own placements, inertias, velocities and
/// accelerations, `M^-1` from their `M`, and the products `-M^-1 dtau`; on a trunk with equal
/// serial limbs these skip `dtau`'s zero blocks between two limbs
/// (`minverse_limbs::neg_minv_times_limb_sparse`).
pub fn compute_aba_derivatives(model: &Model, data: &mut Data, q: &DVector<f64>, v: &DVector<f64>, tau: &DVector<f64>) {
    aba_keeping_body_inertias(model, data, q, v, tau);
    compute_rnea_derivatives_after_aba(model, data);
    invert_mass_matrix(model, data);
    if let Some(layout) = data.limb_layout {
        neg_minv_times_limb_sparse(layout, &data.minv, &data.dtau_dq, &mut data.ddq_dq);
        neg_minv_times_limb_sparse(layout, &data.minv, &data.dtau_dv, &mut data.ddq_dv);
    } else {
        gemm(&mut data.ddq_dq, -1.0, &data.minv, &data.dtau_dq, 0.0);
        gemm(&mut data.ddq_dv, -1.0, &data.minv, &data.dtau_dv, 0.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dynamics::{random_configuration, uniform_from};

    /// The limbs' path gives the general factorization's bits (HyQ and A1, random
    /// configurations, including ones far from the stance).
    #[test]
    fn limbs_path_matches_the_general_factorization_to_the_bit() {
        for robot in ["hyq", "a1"] {
            let model = crate::model::embedded::load(robot).unwrap();
            let mut data = Data::new(&model);
            assert_eq!(data.limb_layout, Some(super::super::minverse_limbs::LimbLayout { count: 4, len: 3 }), "{robot}");
            let mut uniform = uniform_from(11);
            for _ in 0..20 {
                let q = random_configuration(&model, &mut uniform);
                let fast = compute_minverse(&model, &mut data, &q).clone();
                invert_mass_matrix_general(&model, &mut data);
                for (k, (x, y)) in fast.iter().zip(data.minv.iter()).enumerate() {
                    assert_eq!(x.to_bits(), y.to_bits(), "{robot}: M^-1 entry {k}: {x:e} against {y:e}");
                }
            }
        }
    }

    /// `compute_aba_derivatives` (the RNEA derivatives on ABA's own kinematics, the products
    /// on the limbs' zero blocks) against ABA, the stand-alone RNEA derivatives at its `qdd`,
    /// `M^-1` and dense products (HyQ and A1, random states): `M^-1` to the bit (it depends on
    /// the placements and inertias only), the derivatives to round-off.
    #[test]
    fn aba_derivatives_match_their_definition() {
        use crate::dynamics::{aba, compute_rnea_derivatives};
        for robot in ["hyq", "a1"] {
            let model = crate::model::embedded::load(robot).unwrap();
            let (mut shared, mut separate) = (Data::new(&model), Data::new(&model));
            let mut uniform = uniform_from(5);
            for _ in 0..10 {
                let q = random_configuration(&model, &mut uniform);
                let v = DVector::from_fn(model.nv, |_, _| 4.0 * uniform() - 2.0);
                let tau = DVector::from_fn(model.nv, |_, _| 40.0 * uniform() - 20.0);
                compute_aba_derivatives(&model, &mut shared, &q, &v, &tau);
                let qdd = aba(&model, &mut separate, &q, &v, &tau).clone();
                compute_rnea_derivatives(&model, &mut separate, &q, &v, &qdd);
                invert_mass_matrix_general(&model, &mut separate);
                gemm(&mut separate.ddq_dq, -1.0, &separate.minv, &separate.dtau_dq, 0.0);
                gemm(&mut separate.ddq_dv, -1.0, &separate.minv, &separate.dtau_dv, 0.0);
                assert!(shared.ddq.iter().zip(qdd.iter()).all(|(x, y)| x.to_bits() == y.to_bits()), "{robot}: qdd is ABA's");
                assert!(shared.minv.iter().zip(separate.minv.iter()).all(|(x, y)| x.to_bits() == y.to_bits()), "{robot}: M^-1 differs");
                for (name, x, y) in [("ddq_dq", &shared.ddq_dq, &separate.ddq_dq), ("ddq_dv", &shared.ddq_dv, &separate.ddq_dv)] {
                    let err = (x - y).amax();
                    assert!(err <= 1e-11 * y.amax(), "{robot}: {name} off by {err:.2e} of {:.2e}", y.amax());
                }
            }
        }
    }

    /// `mass_matrix_solve` against `M^-1 x` of the inverse (A1, random configurations).
    #[test]
    fn mass_matrix_solve_matches_the_inverse() {
        let model = crate::model::embedded::load("a1").unwrap();
        let mut data = Data::new(&model);
        let mut uniform = uniform_from(3);
        for _ in 0..3 {
            let q = random_configuration(&model, &mut uniform);
            let x = DVector::from_fn(model.nv, |i, _| (i as f64 * 0.7).sin() * 3.0);
            let expected = compute_minverse(&model, &mut data, &q) * &x;
            let mut solved = x.clone();
            mass_matrix_solve(&model, &mut data, solved.as_mut_slice());
            let err = (&solved - &expected).amax();
            assert!(err < 1e-10 * expected.amax().max(1.0), "M^-1 x off by {err:.2e}");
        }
    }
}
