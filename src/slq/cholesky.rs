//! In-place Cholesky factorization of the small `nu x nu` matrix `H` of the backward pass,
//! with solves, allocating nothing after construction.

use nalgebra::{DMatrix, DVector};

/// Right-hand-side columns solved together by [`SmallCholesky::solve_in_place`].
const COLUMN_BLOCK: usize = 8;

/// `H = L L^T`, `L` kept in the lower triangle.
pub(super) struct SmallCholesky {
    l: DMatrix<f64>,
    /// `n x COLUMN_BLOCK` right-hand sides, row by row.
    block: Vec<[f64; COLUMN_BLOCK]>,
}

impl SmallCholesky {
    pub(super) fn new(n: usize) -> Self {
        Self { l: DMatrix::zeros(n, n), block: vec![[0.0; COLUMN_BLOCK]; n] }
    }

    /// Factors the symmetric `h`; false if it is not (numerically) positive definite.
    pub(super) fn factor(&mut self, h: &DMatrix<f64>) -> bool {
        let n = h.nrows();
        self.l.copy_from(h);
        for j in 0..n {
            let mut d = self.l[(j, j)];
            for k in 0..j {
                d -= self.l[(j, k)] * self.l[(j, k)];
            }
            if d.is_nan() || d <= 0.0 {
                return false;
            }
            let d = d.sqrt();
            self.l[(j, j)] = d;
            for i in (j + 1)..n {
                let mut s = self.l[(i, j)];
                for k in 0..j {
                    s -= self.l[(i, k)] * self.l[(j, k)];
                }
                self.l[(i, j)] = s / d;
            }
        }
        true
    }

    /// `x <- H^-1 x` for one column (forward then backward substitution).
    #[allow(clippy::needless_range_loop)] // the triangular solves read clearest with indices
    fn solve_column(&self, x: &mut [f64]) {
        let n = x.len();
        for i in 0..n {
            let mut s = x[i];
            for k in 0..i {
                s -= self.l[(i, k)] * x[k];
            }
            x[i] = s / self.l[(i, i)];
        }
        for i in (0..n).rev() {
            let mut s = x[i];
            for k in (i + 1)..n {
                s -= self.l[(k, i)] * x[k];
            }
            x[i] = s / self.l[(i, i)];
        }
    }

    /// `b <- H^-1 b`, every column. Columns are solved [`COLUMN_BLOCK`] at a time, laid side
    /// by side so that the substitutions run across columns in vector registers; each
    /// column sees exactly the operations of [`Self::solve_column`], in the same order.
    pub(super) fn solve_in_place(&mut self, b: &mut DMatrix<f64>) {
        let n = b.nrows();
        let ncols = b.ncols();
        let mut c0 = 0;
        while c0 + COLUMN_BLOCK <= ncols {
            for i in 0..n {
                for c in 0..COLUMN_BLOCK {
                    self.block[i][c] = b[(i, c0 + c)];
                }
            }
            self.solve_block();
            for i in 0..n {
                for c in 0..COLUMN_BLOCK {
                    b[(i, c0 + c)] = self.block[i][c];
                }
            }
            c0 += COLUMN_BLOCK;
        }
        for c in c0..ncols {
            let col = &mut b.as_mut_slice()[c * n..(c + 1) * n];
            self.solve_column(col);
        }
    }

    /// [`Self::solve_column`] on the [`COLUMN_BLOCK`] columns in `self.block` at once.
    fn solve_block(&mut self) {
        let n = self.block.len();
        let l = &self.l;
        let x = &mut self.block;
        for i in 0..n {
            let mut sum = x[i];
            for k in 0..i {
                let lik = l[(i, k)];
                for (acc, xk) in sum.iter_mut().zip(&x[k]) {
                    *acc -= lik * xk;
                }
            }
            let d = l[(i, i)];
            for (xi, acc) in x[i].iter_mut().zip(&sum) {
                *xi = acc / d;
            }
        }
        for i in (0..n).rev() {
            let mut sum = x[i];
            for k in (i + 1)..n {
                let lki = l[(k, i)];
                for (acc, xk) in sum.iter_mut().zip(&x[k]) {
                    *acc -= lki * xk;
                }
            }
            let d = l[(i, i)];
            for (xi, acc) in x[i].iter_mut().zip(&sum) {
                *xi = acc / d;
            }
        }
    }

    pub(super) fn solve_vector_in_place(&self, b: &mut DVector<f64>) {
        self.solve_column(b.as_mut_slice());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solves_and_refuses_indefinite() {
        let a = DMatrix::from_row_slice(3, 3, &[4.0, 1.0, 0.5, 1.0, 3.0, 0.2, 0.5, 0.2, 2.0]);
        let mut c = SmallCholesky::new(3);
        assert!(c.factor(&a));
        let mut b = DMatrix::from_row_slice(3, 2, &[1.0, 0.0, 2.0, 1.0, 3.0, -1.0]);
        let b0 = b.clone();
        c.solve_in_place(&mut b);
        assert!((&a * &b - b0).norm() < 1e-12);
        // The blocked solve of many columns is bit for bit the column-by-column one.
        let h = DMatrix::from_fn(12, 12, |i, j| if i == j { 20.0 + i as f64 } else { ((i * 7 + j * 7) as f64).sin() });
        let mut c = SmallCholesky::new(12);
        assert!(c.factor(&h));
        let mut many = DMatrix::from_fn(12, 19, |i, j| ((i * 5 + j * 11) as f64 * 0.3).cos() * 10f64.powi(j as i32 % 4));
        let mut one_by_one = many.clone();
        c.solve_in_place(&mut many);
        for j in 0..one_by_one.ncols() {
            let n = one_by_one.nrows();
            c.solve_column(&mut one_by_one.as_mut_slice()[j * n..(j + 1) * n]);
        }
        assert!(many.iter().zip(one_by_one.iter()).all(|(x, y)| x.to_bits() == y.to_bits()));
        assert!((&h * &many - DMatrix::from_fn(12, 19, |i, j| ((i * 5 + j * 11) as f64 * 0.3).cos() * 10f64.powi(j as i32 % 4))).norm() < 1e-9);
        let indefinite = DMatrix::from_row_slice(2, 2, &[1.0, 2.0, 2.0, 1.0]);
        let mut c = SmallCholesky::new(2);
        assert!(!c.factor(&indefinite));
    }
}
