//! In-place Cholesky factorization of the small `nu x nu` matrix `H` of the backward pass,
//! with solves, allocating nothing after construction.

use nalgebra::{DMatrix, DVector};

/// Right-hand-side columns side by side in [`SmallCholesky::solve_in_place`]'s vectors.
const COLUMN_BLOCK: usize = 8;

/// `H = L L^T`, `L` kept in the lower triangle.
pub(super) struct SmallCholesky {
    l: DMatrix<f64>,
    /// `L` again, row by row: the forward substitution reads rows, the backward one columns,
    /// and each reads its copy contiguously.
    l_rows: Vec<f64>,
    /// `n x COLUMN_BLOCK` right-hand sides, row by row.
    block: Vec<[f64; COLUMN_BLOCK]>,
}

impl SmallCholesky {
    pub(super) fn new(n: usize) -> Self {
        Self { l: DMatrix::zeros(n, n), l_rows: vec![0.0; n * n], block: vec![[0.0; COLUMN_BLOCK]; n] }
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
        for (i, row) in self.l_rows.chunks_exact_mut(n).enumerate() {
            for (k, l_ik) in row.iter_mut().enumerate() {
                *l_ik = self.l[(i, k)];
            }
        }
        true
    }

    /// `x <- H^-1 x` for one column (forward then backward substitution).
    fn solve_column(&self, x: &mut [f64]) {
        let n = x.len();
        let (l_rows, l_columns) = (&self.l_rows, self.l.as_slice());
        for i in 0..n {
            let (solved, rest) = x.split_at_mut(i);
            let mut s = rest[0];
            for (lik, xk) in l_rows[i * n..i * n + i].iter().zip(solved.iter()) {
                s -= lik * xk;
            }
            rest[0] = s / l_rows[i * n + i];
        }
        for i in (0..n).rev() {
            let (head, solved) = x.split_at_mut(i + 1);
            let mut s = head[i];
            for (lki, xk) in l_columns[i * n + i + 1..(i + 1) * n].iter().zip(solved.iter()) {
                s -= lki * xk;
            }
            head[i] = s / l_columns[i * n + i];
        }
    }

    /// `b <- H^-1 b`, every column. The columns are solved [`COLUMN_BLOCK`] at a time, laid
    /// side by side so that the substitutions run across columns in vector registers (the
    /// last block padded with zeros rather than its columns solved one by one). Each column
    /// sees exactly the operations of [`Self::solve_column`], in the same order.
    pub(super) fn solve_in_place(&mut self, b: &mut DMatrix<f64>) {
        let n = b.nrows();
        if n == 0 {
            return;
        }
        for columns in b.as_mut_slice().chunks_mut(COLUMN_BLOCK * n) {
            for (row, i) in self.block.iter_mut().zip(0..) {
                for (c, x) in row.iter_mut().enumerate() {
                    *x = columns.get(c * n + i).copied().unwrap_or(0.0);
                }
            }
            self.solve_block();
            for (c, column) in columns.chunks_exact_mut(n).enumerate() {
                for (row, b_ic) in self.block.iter().zip(column) {
                    *b_ic = row[c];
                }
            }
        }
    }

    /// [`Self::solve_column`] on the [`COLUMN_BLOCK`] columns in `self.block` at once.
    fn solve_block(&mut self) {
        let n = self.block.len();
        let (l_rows, l_columns) = (&self.l_rows, self.l.as_slice());
        let x = &mut self.block;
        for i in 0..n {
            let (solved, rest) = x.split_at_mut(i);
            let mut sum = rest[0];
            for (lik, xk) in l_rows[i * n..i * n + i].iter().zip(solved.iter()) {
                for (acc, xk) in sum.iter_mut().zip(xk) {
                    *acc -= lik * xk;
                }
            }
            let d = l_rows[i * n + i];
            for (xi, acc) in rest[0].iter_mut().zip(&sum) {
                *xi = acc / d;
            }
        }
        for i in (0..n).rev() {
            let (head, solved) = x.split_at_mut(i + 1);
            let mut sum = head[i];
            for (lki, xk) in l_columns[i * n + i + 1..(i + 1) * n].iter().zip(solved.iter()) {
                for (acc, xk) in sum.iter_mut().zip(xk) {
                    *acc -= lki * xk;
                }
            }
            let d = l_columns[i * n + i];
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
