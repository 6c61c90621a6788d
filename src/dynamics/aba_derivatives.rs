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

use super::aba::aba;
use super::crba::crba;
use super::rnea_derivatives::compute_rnea_derivatives;
use super::Data;
use crate::model::Model;
use nalgebra::{DMatrix, DVector};

/// In-place `M = L^T D L` (Featherstone 2008, Table 6.3): on return the strict lower triangle
/// of `h` holds `L` (unit diagonal implied) and the diagonal holds `D`. `lambda[k]` is the
/// parent degree of freedom of `k` (`usize::MAX` at the root).
fn ltdl_in_place(h: &mut DMatrix<f64>, lambda: &[usize]) {
    let n = h.nrows();
    for k in (0..n).rev() {
        let mut i = lambda[k];
        while i != usize::MAX {
            let a = h[(k, i)] / h[(k, k)];
            let mut j = i;
            while j != usize::MAX {
                h[(i, j)] -= a * h[(k, j)];
                j = lambda[j];
            }
            h[(k, i)] = a;
            i = lambda[i];
        }
    }
}

/// `M^-1 = L^-1 D^-1 L^-T` from the factor in `h`, into `out` (full, symmetric).
///
/// Column `c` of `M^-1` solves `L^T D L x = e_c`; by symmetry only the rows `>= c` are
/// computed from `y = D^-1 L^-T e_c`, which is non-zero only on the path of `c` to the root.
fn minv_from_ltdl(h: &DMatrix<f64>, lambda: &[usize], out: &mut DMatrix<f64>, y: &mut DVector<f64>) {
    let n = h.nrows();
    for c in 0..n {
        // L^T y = e_c: y_c = 1, then for each i on the path (descending) y_j -= L_ij y_i
        // for every ancestor j of i.
        y.fill(0.0);
        y[c] = 1.0;
        let mut i = c;
        while i != usize::MAX {
            let yi = y[i];
            let mut j = lambda[i];
            while j != usize::MAX {
                y[j] -= h[(i, j)] * yi;
                j = lambda[j];
            }
            i = lambda[i];
        }
        // D z = y
        let mut i = c;
        while i != usize::MAX {
            y[i] /= h[(i, i)];
            i = lambda[i];
        }
        // L x = z: x_i = z_i - sum_{j on path of i} L_ij x_j, in increasing order.
        for i in 0..n {
            let mut j = lambda[i];
            let mut acc = y[i];
            while j != usize::MAX {
                acc -= h[(i, j)] * y[j];
                j = lambda[j];
            }
            y[i] = acc;
        }
        out.column_mut(c).copy_from(y);
    }
}

/// The inverse of the joint-space inertia matrix, full and symmetric, into `data.minv`
/// (also fills `data.mass_matrix`).
pub fn compute_minverse<'d>(model: &Model, data: &'d mut Data, q: &DVector<f64>) -> &'d DMatrix<f64> {
    crba(model, data, q);
    invert_mass_matrix(model, data);
    &data.minv
}

fn invert_mass_matrix(model: &Model, data: &mut Data) {
    data.minv_chol.copy_from(&data.mass_matrix);
    ltdl_in_place(&mut data.minv_chol, &model.dof_parent);
    minv_from_ltdl(&data.minv_chol, &model.dof_parent, &mut data.minv, &mut data.tmp_nv);
}

/// Partial derivatives of forward dynamics `qdd = ABA(q, v, tau)`: `data.ddq_dq`,
/// `data.ddq_dv` (tangent-space convention of `shared/fixtures/README.md`) and
/// `data.minv` (`= d qdd / d tau`). Also sets `data.ddq`.
pub fn compute_aba_derivatives(model: &Model, data: &mut Data, q: &DVector<f64>, v: &DVector<f64>, tau: &DVector<f64>) {
    aba(model, data, q, v, tau);
    let qdd = std::mem::replace(&mut data.ddq, DVector::zeros(0));
    compute_rnea_derivatives(model, data, q, v, &qdd);
    data.ddq = qdd;
    invert_mass_matrix(model, data);
    data.ddq_dq.gemm(-1.0, &data.minv, &data.dtau_dq, 0.0);
    data.ddq_dv.gemm(-1.0, &data.minv, &data.dtau_dv, 0.0);
}
