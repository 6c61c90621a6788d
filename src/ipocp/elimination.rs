//! Row reduction with complete pivoting of a stacked constraint block `[C_u | C_x | c]`:
//! the tool with which the Riccati recursion eliminates stage-wise equality constraints
//! (FATROP's approach, Vanroye et al. 2023, sec. III: the rows that the controls can satisfy
//! fix part of `du`; the remaining rows only involve `dx` and travel to the previous stage).
//!
//! The block lives in one matrix `W = [C_u | C_x | c | T]` with `T` starting as the
//! identity; every row operation is applied to all of `W`, so that at the end `T` is the
//! row transformation with `T C = [U; H; 0]`:
//!
//! - the first `rank_u` rows, `U = [U_11 U_12]`, have an upper-triangular, invertible
//!   `U_11` in the permuted control order `perm_u`;
//! - the next `rank_x` rows have zero control part and independent state parts: the
//!   constraints passed on to the previous stage;
//! - the rest are (numerically) zero on both parts; their right-hand side is the
//!   inconsistency of the linearized constraints (zero for consistent ones).
//!
//! The `C_u` columns are swapped physically (so `U_11` is triangular in place), the `C_x`
//! columns are not (the state rows keep their meaning).

// Index loops over rows and columns read like the equations they implement.
#![allow(clippy::needless_range_loop)]

use nalgebra::DMatrix;

/// Workspace and result of one row reduction.
#[derive(Clone, Debug)]
pub(crate) struct RowReduction {
    /// `[C_u | C_x | c | T]`, `max_rows x (nu + nx + 1 + max_rows)`; rows `0..rows` used.
    pub w: DMatrix<f64>,
    pub nu: usize,
    pub nx: usize,
    pub max_rows: usize,
    /// Rows in use.
    pub rows: usize,
    /// `perm_u[i]`: the original control index in permuted column `i`.
    pub perm_u: Vec<usize>,
    pub rank_u: usize,
    pub rank_x: usize,
    /// Scratch: state columns already used as pivots, elimination factors.
    x_used: Vec<bool>,
    factor: Vec<f64>,
}

impl RowReduction {
    pub fn new(nu: usize, nx: usize, max_rows: usize) -> Self {
        Self {
            w: DMatrix::zeros(max_rows, nu + nx + 1 + max_rows),
            nu,
            nx,
            max_rows,
            rows: 0,
            perm_u: (0..nu).collect(),
            rank_u: 0,
            rank_x: 0,
            x_used: vec![false; nx],
            factor: vec![0.0; max_rows],
        }
    }

    /// Column of the right-hand side `c`.
    pub fn rhs_col(&self) -> usize {
        self.nu + self.nx
    }

    /// First column of `T`.
    pub fn t_col(&self) -> usize {
        self.nu + self.nx + 1
    }

    /// Starts a reduction of `rows` rows: zeroes `W`, sets `T = I`. The caller then fills
    /// `C_u`, `C_x` and `c` in rows `0..rows`.
    pub fn begin(&mut self, rows: usize) {
        debug_assert!(rows <= self.max_rows);
        self.rows = rows;
        let ld = self.w.nrows();
        if rows > 0 {
            for column in self.w.as_mut_slice().chunks_exact_mut(ld) {
                column[..rows].fill(0.0);
            }
        }
        let t = self.t_col();
        for i in 0..rows {
            self.w[(i, t + i)] = 1.0;
        }
        for (i, p) in self.perm_u.iter_mut().enumerate() {
            *p = i;
        }
        self.x_used.fill(false);
        self.rank_u = 0;
        self.rank_x = 0;
    }

    /// Reduces the filled rows; pivots below `pivot_tolerance * max(1, max |C|)` count as zero.
    pub fn reduce(&mut self, pivot_tolerance: f64) {
        let (nu, nx, rows) = (self.nu, self.nx, self.rows);
        if rows == 0 {
            return; // nothing to reduce: both ranks stay 0 (from `begin`)
        }
        let ld = self.w.nrows();
        // The scans below run down the contiguous columns of the column-major `W`; a tie
        // goes to the smallest row, then the smallest column (the row-by-row scan's choice).
        let mut scale: f64 = 1.0;
        for column in self.w.as_slice()[..(nu + nx) * ld].chunks_exact(ld) {
            for v in &column[..rows] {
                scale = scale.max(v.abs());
            }
        }
        let tol = pivot_tolerance * scale;
        // Control columns: complete pivoting, columns swapped into place.
        let mut row = 0;
        while row < rows && row < nu {
            let (mut best, mut bi, mut bj) = (0.0, row, row);
            for j in row..nu {
                let column = &self.w.as_slice()[j * ld + row..j * ld + rows];
                for (o, v) in column.iter().enumerate() {
                    let (a, i) = (v.abs(), row + o);
                    if a > best || (a == best && i < bi) {
                        (best, bi, bj) = (a, i, j);
                    }
                }
            }
            if best <= tol {
                break;
            }
            self.w.swap_rows(row, bi);
            if bj != row {
                self.w.swap_columns(row, bj);
                self.perm_u.swap(row, bj);
            }
            self.eliminate_below(row, row);
            row += 1;
        }
        self.rank_u = row;
        // State columns of the remaining rows: complete pivoting, columns left in place.
        while row < rows {
            let (mut best, mut bi, mut bj) = (0.0, row, 0);
            for j in 0..nx {
                if self.x_used[j] {
                    continue;
                }
                let column = &self.w.as_slice()[(nu + j) * ld + row..(nu + j) * ld + rows];
                for (o, v) in column.iter().enumerate() {
                    let (a, i) = (v.abs(), row + o);
                    if a > best || (a == best && i < bi) {
                        (best, bi, bj) = (a, i, j);
                    }
                }
            }
            if best <= tol {
                break;
            }
            self.w.swap_rows(row, bi);
            self.x_used[bj] = true;
            self.eliminate_below(row, nu + bj);
            row += 1;
        }
        self.rank_x = row - self.rank_u;
        // Rows below are numerically zero in C: clear the round-off so they read as zero.
        for column in self.w.as_mut_slice()[..(nu + nx) * ld].chunks_exact_mut(ld) {
            column[row..rows].fill(0.0);
        }
    }

    /// `c = T c_raw` in the right-hand-side column: the reduction of a new right-hand side
    /// `c_raw` (`rows` entries) with the row operations of the last [`Self::reduce`].
    pub fn transform_rhs(&mut self, raw: &[f64]) {
        let (t, c, rows) = (self.t_col(), self.rhs_col(), self.rows);
        for i in 0..rows {
            let mut s = 0.0;
            for (j, r) in raw.iter().enumerate().take(rows) {
                s += self.w[(i, t + j)] * r;
            }
            self.w[(i, c)] = s;
        }
    }

    /// Largest |c| of the rows that reduced to zero: the inconsistency of the constraints.
    pub fn inconsistency(&self) -> f64 {
        let c = self.rhs_col();
        (self.rank_u + self.rank_x..self.rows).map(|i| self.w[(i, c)].abs()).fold(0.0, f64::max)
    }

    fn eliminate_below(&mut self, row: usize, col: usize) {
        let pivot = self.w[(row, col)];
        let rows = self.rows;
        for i in row + 1..rows {
            self.factor[i] = self.w[(i, col)] / pivot;
        }
        // Column by column (contiguous in the column-major storage).
        let used = self.t_col() + rows;
        let ld = self.w.nrows();
        let data = self.w.as_mut_slice();
        for j in 0..used {
            let c = &mut data[j * ld..j * ld + rows];
            let v = c[row];
            if v == 0.0 {
                continue;
            }
            for (ci, f) in c[row + 1..].iter_mut().zip(&self.factor[row + 1..rows]) {
                *ci -= f * v;
            }
        }
        for i in row + 1..rows {
            self.w[(i, col)] = 0.0;
        }
    }

    /// `mu = T^T mu_reduced` (size `rows`): multipliers of the original rows from those of
    /// the reduced rows.
    pub fn original_multipliers(&self, reduced: &[f64], out: &mut [f64]) {
        let t = self.t_col();
        for (j, o) in out.iter_mut().enumerate().take(self.rows) {
            let mut s = 0.0;
            for (i, r) in reduced.iter().enumerate().take(self.rows) {
                s += self.w[(i, t + j)] * r;
            }
            *o = s;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reduction_reproduces_t_c_and_ranks() {
        // Rows: r2 = 2 r0 (dependent), r1 acts on u, r3 only on x.
        let (nu, nx) = (2, 3);
        let c = DMatrix::from_row_slice(4, 6, &[
            1.0, 2.0, 0.5, 0.0, 1.0, 3.0, //
            0.0, 1.0, 0.0, 2.0, 0.0, -1.0, //
            2.0, 4.0, 1.0, 0.0, 2.0, 6.0, //
            0.0, 0.0, 1.0, 1.0, 1.0, 0.5,
        ]);
        let mut red = RowReduction::new(nu, nx, 5);
        red.begin(4);
        red.w.view_mut((0, 0), (4, 6)).copy_from(&c);
        red.reduce(1e-12);
        assert_eq!((red.rank_u, red.rank_x), (2, 1));
        assert!(red.inconsistency() < 1e-12);
        // T C (with C's u columns permuted) equals the reduced block.
        let t = red.w.view((0, red.t_col()), (4, 4)).clone_owned();
        let tc = &t * &c;
        for i in 0..4 {
            for (jp, &j) in red.perm_u.iter().enumerate() {
                assert!((tc[(i, j)] - red.w[(i, jp)]).abs() < 1e-12);
            }
            for j in nu..6 {
                assert!((tc[(i, j)] - red.w[(i, j)]).abs() < 1e-12);
            }
        }
    }
}
