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
//! `M^-1` comes from ABA's articulated inertias (`minverse.rs`). The tree-sparse `L^T D L`
//! factorization of `M` (Featherstone 2008, §6.5, Table 6.3), which exploits that
//! `M_ij = 0` unless `i` and `j` lie on one branch, solves with `M` without forming `M^-1`.

use super::aba::aba;
use super::minverse::minverse_from_articulated_inertias;
use super::rnea_derivatives::rnea_derivatives_after_aba;
use super::Data;
use crate::model::Model;
use nalgebra::{DMatrix, DVector};


const ROOT: usize = usize::MAX;

/// In-place `M = L^T D L` (Featherstone 2008, Table 6.3) on a column-major `n x n` slice: on
/// return the strict lower triangle holds `L` (unit diagonal implied) and the diagonal `D`.
/// `lambda[k]` is the parent degree of freedom of `k` (`ROOT` at the root); only the
/// entries on a branch are touched.
fn ltdl_in_place(h: &mut [f64], n: usize, lambda: &[usize]) {
    for k in (0..n).rev() {
        let hkk = h[k + k * n];
        let mut i = lambda[k];
        while i != ROOT {
            // a = H_ki / H_kk;  H_ij -= a H_kj for j on the branch of i;  H_ki = a
            let a = h[k + i * n] / hkk;
            let mut j = i;
            while j != ROOT {
                h[i + j * n] -= a * h[k + j * n];
                j = lambda[j];
            }
            h[k + i * n] = a;
            i = lambda[i];
        }
    }
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
    ltdl_in_place(data.ltdl.as_mut_slice(), model.nv, &model.dof_parent);
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

/// `out = -M^-1 X` for a derivative `X` of RNEA (`d tau / dq` or `d tau / dv`), on its
/// sparsity: column `c` of joint `j` has nonzeros only on the rows of `j`'s ancestors and of
/// `j`'s subtree (Carpentier & Mansard 2018, Alg. 1: `dtau/dq[i, sub(j)]` for `i` on the
/// path to `j`, `dtau/dq[sub(j), j]`), so for a leg joint of a quadruped 9 of the 18 rows.
/// Exact zeros (the free flyer's translation columns of `d tau / dq`: gravity is uniform)
/// are skipped too. On x86-64 CPUs with AVX2 and FMA the same loops run compiled for them
/// (runtime detection, as `matrixmultiply` does for nalgebra's `gemm`), also in a portable
/// build.
fn minus_minv_times(model: &Model, minv: &DMatrix<f64>, x: &DMatrix<f64>, out: &mut DMatrix<f64>, rows: &[usize], starts: &[usize]) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
        // SAFETY: the CPU has the features the function is compiled for.
        unsafe { minus_minv_times_avx2_fma(model, minv, x, out, rows, starts) };
        return;
    }
    minus_minv_times_impl::<false>(model, minv, x, out, rows, starts);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn minus_minv_times_avx2_fma(model: &Model, minv: &DMatrix<f64>, x: &DMatrix<f64>, out: &mut DMatrix<f64>, rows: &[usize], starts: &[usize]) {
    minus_minv_times_impl::<true>(model, minv, x, out, rows, starts);
}

#[inline(always)]
fn minus_minv_times_impl<const FMA: bool>(model: &Model, minv: &DMatrix<f64>, x: &DMatrix<f64>, out: &mut DMatrix<f64>, rows: &[usize], starts: &[usize]) {
    let nv = model.nv;
    let (minv, x, out) = (minv.as_slice(), x.as_slice(), out.as_mut_slice());
    for (j, jnt) in model.joints.iter().enumerate().skip(1) {
        let rows = &rows[starts[j]..starts[j + 1]];
        for c in jnt.idx_v..jnt.idx_v + jnt.nv {
            let xc = &x[c * nv..(c + 1) * nv];
            let oc = &mut out[c * nv..(c + 1) * nv];
            // Rows `lo..lo + W` of out[:, c] = -sum_r M^-1[:, r] X[r, c] (M^-1 symmetric:
            // column r = row r), summed in registers over the rows r of the pattern.
            let block = |lo: usize, acc: &mut [f64]| {
                let w = acc.len();
                let mut add = |r: usize| {
                    let a = xc[r];
                    if a != 0.0 {
                        let m = &minv[r * nv + lo..r * nv + lo + w];
                        for (s, &mr) in acc.iter_mut().zip(m) {
                            *s = if FMA { mr.mul_add(a, *s) } else { *s + mr * a };
                        }
                    }
                };
                for &r in rows {
                    add(r);
                }
            };
            let mut lo = 0;
            while lo + 16 <= nv {
                let mut acc = [0.0; 16];
                block(lo, &mut acc);
                for (o, s) in oc[lo..lo + 16].iter_mut().zip(acc) {
                    *o = -s;
                }
                lo += 16;
            }
            // The last rows: one block of 4 ending at nv (overlapping the previous block,
            // whose rows it recomputes identically), else one row at a time.
            if lo < nv && nv >= 4 {
                let lo = nv - 4;
                let mut acc = [0.0; 4];
                block(lo, &mut acc);
                for (o, s) in oc[lo..].iter_mut().zip(acc) {
                    *o = -s;
                }
            } else {
                while lo < nv {
                    let mut acc = [0.0; 1];
                    block(lo, &mut acc);
                    oc[lo] = -acc[0];
                    lo += 1;
                }
            }
        }
    }
}

/// Partial derivatives of forward dynamics `qdd = ABA(q, v, tau)`: `data.ddq_dq`,
/// `data.ddq_dv` (tangent-space convention of `shared/fixtures/README.md`) and
/// `data.minv` (`= d qdd / d tau`). Also sets `data.ddq`.
///
/// ```text
/// qdd = ABA(q, v, tau);  M^-1 from ABA's articulated inertias (minverse.rs)
/// d qdd / dq = -M^-1 d RNEA/dq (q, v, qdd),   d qdd / dv = -M^-1 d RNEA/dv (q, v, qdd)
/// ```
pub fn compute_aba_derivatives(model: &Model, data: &mut Data, q: &DVector<f64>, v: &DVector<f64>, tau: &DVector<f64>) {
    aba(model, data, q, v, tau);
    minverse_from_articulated_inertias(model, data);
    rnea_derivatives_after_aba(model, data);
    minus_minv_times(model, &data.minv, &data.dtau_dq, &mut data.ddq_dq, &data.dtau_rows, &data.dtau_rows_start);
    minus_minv_times(model, &data.minv, &data.dtau_dv, &mut data.ddq_dv, &data.dtau_rows, &data.dtau_rows_start);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dynamics::{compute_minverse, crba, random_configuration};

    /// `mass_matrix_solve` against `M^-1 x` of the inverse (A1, random configurations).
    #[test]
    fn mass_matrix_solve_matches_the_inverse() {
        let model = crate::model::embedded::load("a1").unwrap();
        let mut data = Data::new(&model);
        let mut seed = 3u64;
        let mut uniform = || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        for _ in 0..3 {
            let q = random_configuration(&model, &mut uniform);
            let x = DVector::from_fn(model.nv, |i, _| (i as f64 * 0.7).sin() * 3.0);
            let expected = compute_minverse(&model, &mut data, &q) * &x;
            crba(&model, &mut data, &q);
            let mut solved = x.clone();
            mass_matrix_solve(&model, &mut data, solved.as_mut_slice());
            let err = (&solved - &expected).amax();
            assert!(err < 1e-10 * expected.amax().max(1.0), "M^-1 x off by {err:.2e}");
        }
    }
}
