//! In-place Cholesky factorization of the small `nu x nu` matrix `H` of the backward pass,
//! with solves, allocating nothing after construction.

use nalgebra::{DMatrix, DVector};

/// `H = L L^T`, `L` kept in the lower triangle.
pub(super) struct SmallCholesky {
    l: DMatrix<f64>,
}

impl SmallCholesky {
    pub(super) fn new(n: usize) -> Self {
        Self { l: DMatrix::zeros(n, n) }
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

    /// `b <- H^-1 b`, every column.
    pub(super) fn solve_in_place(&self, b: &mut DMatrix<f64>) {
        let n = b.nrows();
        for c in 0..b.ncols() {
            let col = &mut b.as_mut_slice()[c * n..(c + 1) * n];
            self.solve_column(col);
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
        let indefinite = DMatrix::from_row_slice(2, 2, &[1.0, 2.0, 2.0, 1.0]);
        let mut c = SmallCholesky::new(2);
        assert!(!c.factor(&indefinite));
    }
}
