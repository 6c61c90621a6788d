//! Dense matrix products of the hot paths.
//!
//! nalgebra's `gemm` on these sizes (the backward pass's `P' [A B]` is 48 x 36 times 36 x 60,
//! the knots' linearization multiplies 18 to 48 rows) goes through matrixmultiply, which
//! packs both operands into a buffer it allocates on every call. [`gemm`] runs nano-gemm's
//! unpacked kernels on the column-major operands in place and allocates nothing.
//!
//! Every entry is the same sum as matrixmultiply's, `sum_k a_ik b_kj` accumulated by fused
//! multiply-adds from `k = 0` up, then `alpha sum` rounded (`beta = 0`) or `c_ij +- sum`
//! rounded (`beta = 1`, `alpha = +-1`), as matrixmultiply's kernels end. nalgebra hands a product to matrixmultiply when all its dimensions
//! exceed 5: there the results are nalgebra's to the bit, and the plans and closed loops do
//! not move. (Below that nalgebra sums without fusing; the callers keep nalgebra there.)
//!
//! ```
//! use nalgebra::DMatrix;
//! let a = DMatrix::from_fn(6, 4, |i, j| (i + 2 * j) as f64 * 0.1);
//! let b = DMatrix::from_fn(4, 5, |i, j| (i * j) as f64 - 1.5);
//! let mut c = DMatrix::from_element(6, 5, 2.0);
//! legwork::linalg::gemm(&mut c, 1.0, &a, &b, 1.0);
//! assert!((c - (DMatrix::from_element(6, 5, 2.0) + &a * &b)).amax() < 1e-12);
//! ```

use nalgebra::{DMatrix, DMatrixView, DMatrixViewMut, DVector, DVectorView};

/// `c <- beta c + alpha a b` (nalgebra's `gemm` argument order) with `beta = 0`, or `beta = 1`
/// and `alpha = +-1`, rounded as nalgebra's where every dimension exceeds 5 (the module's
/// notes). `beta = 0` ignores `c`'s entries (they may be anything, NaN included). (Other
/// scalings round where matrixmultiply's edge tiles do not, and the reverse: not offered.)
///
/// # Panics
/// If the shapes do not match or the scalings are others: a programming error.
pub fn gemm<'c, 'a, 'b>(c: impl Into<DMatrixViewMut<'c, f64>>, alpha: f64, a: impl Into<DMatrixView<'a, f64>>, b: impl Into<DMatrixView<'b, f64>>, beta: f64) {
    let (mut c, a, b) = (c.into(), a.into(), b.into());
    let ((m, n), (am, k), (bk, bn)) = (c.shape(), a.shape(), b.shape());
    assert!(am == m && bn == n && bk == k, "gemm: {m}x{n} <- {am}x{k} * {bk}x{bn}");
    assert!(beta == 0.0 || (beta == 1.0 && alpha.abs() == 1.0), "gemm: alpha {alpha}, beta {beta}");
    if m == 0 || n == 0 {
        return;
    }
    // nano-gemm's convention is `dst <- alpha dst + beta lhs rhs`; the views' row strides
    // are 1 by their type (column-major, as its column-major plan needs).
    let (c_cs, a_cs, b_cs) = (c.strides().1, a.strides().1, b.strides().1);
    let plan = nano_gemm::Plan::new_colmajor_lhs_and_dst_f64(m, n, k);
    // SAFETY: `c`, `a` and `b` are views of `m x n`, `m x k` and `k x n` (checked above) with
    // unit row strides and the column strides passed: every address the kernels touch is an
    // element of its view. `c` is borrowed mutably, so it aliases neither `a` nor `b`.
    unsafe {
        plan.execute_unchecked(m, n, k, c.as_mut_ptr(), 1, c_cs as isize, a.as_ptr(), 1, a_cs as isize, b.as_ptr(), 1, b_cs as isize, beta, alpha, false, false);
    }
}

/// `y <- beta y + alpha a x` (nalgebra's `gemv` argument order), `beta` in {0, 1}: column by
/// column, for each `j` in order `y_i <- (alpha a_ij) x_j + y_i` (products then a sum,
/// unfused; the first column alone without `beta = 0`), the very operations of nalgebra's
/// `gemv`, so the same bits, over contiguous columns where nalgebra's generic strided loop
/// is scalar (the policy `u = u_k + alpha l_k + K_k dx` of every rollout step, the anchors'
/// columns of a knot's `A`).
///
/// # Panics
/// If the shapes do not match or `beta` is another value: a programming error.
pub fn gemv<'x>(y: &mut DVector<f64>, alpha: f64, a: &DMatrix<f64>, x: impl Into<DVectorView<'x, f64>>, beta: f64) {
    let x = x.into();
    let (m, n) = a.shape();
    assert!(y.len() == m && x.len() == n, "gemv: {} <- {m}x{n} * {}", y.len(), x.len());
    assert!(beta == 0.0 || beta == 1.0, "gemv: beta {beta}");
    let y = y.as_mut_slice();
    if m == 0 {
        return;
    }
    let mut columns = a.as_slice().chunks_exact(m).zip(x.iter());
    if beta == 0.0 {
        match columns.next() {
            Some((column, x_0)) => {
                for (y_i, a_i0) in y.iter_mut().zip(column) {
                    *y_i = alpha * a_i0 * x_0;
                }
            }
            None => y.fill(0.0),
        }
    }
    for (column, x_j) in columns {
        for (y_i, a_ij) in y.iter_mut().zip(column) {
            *y_i += alpha * a_ij * x_j;
        }
    }
}

/// `y <- y + a x`: [`gemv`] with `alpha = beta = 1`.
pub fn gemv_add<'x>(y: &mut DVector<f64>, a: &DMatrix<f64>, x: impl Into<DVectorView<'x, f64>>) {
    gemv(y, 1.0, a, x, 1.0);
}

/// `dst`'s block at `(row, col)` <- `src`, column by column (contiguous copies, where
/// nalgebra's `copy_from` on a view walks the entries one by one).
///
/// # Panics
/// If `src` does not fit at `(row, col)`: a programming error.
pub fn copy_block(dst: &mut DMatrix<f64>, (row, col): (usize, usize), src: &DMatrix<f64>) {
    let (m, n) = src.shape();
    let rows = dst.nrows();
    assert!(row + m <= rows && col + n <= dst.ncols(), "copy_block: {m}x{n} at ({row}, {col}) in {rows}x{}", dst.ncols());
    if m == 0 {
        return;
    }
    for (j, column) in src.as_slice().chunks_exact(m).enumerate() {
        let start = (col + j) * rows + row;
        dst.as_mut_slice()[start..start + m].copy_from_slice(column);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::DMatrix;

    fn entries(rows: usize, cols: usize, seed: u64) -> DMatrix<f64> {
        let mut s = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
        DMatrix::from_fn(rows, cols, |_, _| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        })
    }

    /// The same bits as nalgebra's `gemm` on the shapes of the backward pass and the knots'
    /// linearization (every dimension above 5), on views with strides, for the scalings
    /// they use and others; on smaller shapes the same product to round-off.
    #[test]
    fn matches_nalgebra_to_the_bit() {
        for (seed, (m, n, k)) in [(48, 60, 36), (48, 48, 36), (12, 60, 36), (48, 48, 12), (18, 18, 18), (18, 36, 18), (6, 18, 12), (3, 18, 3), (1, 7, 5), (30, 1, 2)].into_iter().enumerate() {
            let fused = m > 5 && n > 5 && k > 5;
            let (a, b, c0) = (entries(m + 3, k + 1, seed as u64), entries(k + 2, n, seed as u64 + 100), entries(m + 1, n + 2, seed as u64 + 200));
            for (alpha, beta) in [(1.0, 0.0), (1.0, 1.0), (-1.0, 0.0), (-1.0, 1.0), (0.005, 0.0), (-2.5e-5, 0.0)] {
                let (mut ours, mut theirs) = (c0.clone(), c0.clone());
                gemm(ours.view_mut((1, 2), (m, n)), alpha, a.view((2, 1), (m, k)), b.rows(1, k), beta);
                theirs.view_mut((1, 2), (m, n)).gemm(alpha, &a.view((2, 1), (m, k)), &b.rows(1, k), beta);
                let differ = ours.iter().zip(theirs.iter()).filter(|(x, y)| x.to_bits() != y.to_bits()).count();
                if fused {
                    assert_eq!(differ, 0, "{m}x{n}x{k}, alpha {alpha}, beta {beta}");
                } else {
                    assert!((&ours - &theirs).amax() <= 1e-14 * (k + 1) as f64 * alpha.abs().max(1.0), "{m}x{n}x{k}, alpha {alpha}, beta {beta}");
                }
            }
        }
    }

    /// The same bits as nalgebra's `gemv`, on a contiguous and a strided `x`.
    #[test]
    fn gemv_matches_nalgebra_to_the_bit() {
        for (seed, (m, n)) in [(12, 48), (12, 36), (1, 5), (7, 1), (48, 48), (18, 18), (4, 0)].into_iter().enumerate() {
            let (a, x, y0) = (entries(m, n, seed as u64), entries(n, 2, seed as u64 + 7), entries(m, 1, seed as u64 + 9));
            for (alpha, beta) in [(1.0, 1.0), (1.0, 0.0), (0.005, 0.0), (-0.3, 1.0)] {
                let (mut ours, mut theirs) = (DVector::from_column_slice(y0.as_slice()), DVector::from_column_slice(y0.as_slice()));
                gemv(&mut ours, alpha, &a, x.column(1), beta);
                theirs.gemv(alpha, &a, &x.column(1), beta);
                assert!(ours.iter().zip(theirs.iter()).all(|(p, q)| p.to_bits() == q.to_bits()), "{m}x{n}, alpha {alpha}, beta {beta}");
            }
        }
    }

    #[test]
    fn copy_block_places_the_columns() {
        let src = entries(3, 4, 1);
        let mut dst = DMatrix::zeros(6, 7);
        copy_block(&mut dst, (2, 3), &src);
        let mut expected = DMatrix::zeros(6, 7);
        expected.view_mut((2, 3), (3, 4)).copy_from(&src);
        assert_eq!(dst, expected);
    }

    #[test]
    #[should_panic(expected = "gemm: 3x4 <- 3x2 * 3x4")]
    fn refuses_mismatched_shapes() {
        gemm(&mut DMatrix::zeros(3, 4), 1.0, &DMatrix::zeros(3, 2), &DMatrix::zeros(3, 4), 0.0);
    }
}
