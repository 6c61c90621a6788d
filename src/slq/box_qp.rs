//! The box-constrained QP of a control-limited backward pass (Tassa, Mansard, Todorov 2014,
//! "Control-limited differential dynamic programming", sec. III-B, Algorithm 1):
//!
//! ```text
//! min_x  1/2 x^T H x + g^T x      s.t.  lower <= x <= upper
//! ```
//!
//! by projected Newton: at the iterate, the *clamped* set is the coordinates at a bound whose
//! gradient pushes outwards (`x_i = lower_i, (g + H x)_i > 0` or `x_i = upper_i,
//! (g + H x)_i < 0`); the step is Newton's on the *free* coordinates alone (`H_ff` factored),
//! projected onto the box and shortened by an Armijo line search. It ends when the free
//! gradient vanishes, when every coordinate is clamped, or when a step gains almost nothing.
//!
//! The factor of `H_ff` is kept in the full `n x n` [`SmallCholesky`]: the clamped rows and
//! columns are replaced by the identity, so a right-hand side with zero clamped rows solves to
//! `H_ff^-1 r_f` on the free rows and zero on the clamped ones. That is what the backward pass
//! needs for the gain, `K_f = -H_ff^-1 Q_ux,f`, `K_c = 0` (a clamped input does not react to
//! the state, Tassa 2014 eq. 16), and it allocates nothing.

use super::cholesky::SmallCholesky;
use nalgebra::{DMatrix, DVector};

/// Settings of the projected-Newton QP (defaults of Tassa 2014's reference code in
/// parentheses).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoxQpSettings {
    /// Newton iterations at most (100).
    pub max_iterations: usize,
    /// Stop when the norm of the free gradient is below this (1e-8).
    pub gradient_tolerance: f64,
    /// Stop when a step improves the objective by less than this fraction of its value (1e-8).
    pub relative_improvement_tolerance: f64,
    /// Armijo's sufficient-decrease fraction (0.1) and step-size factor (0.6).
    pub armijo: f64,
    pub step_factor: f64,
    /// The line search gives up below this step (1e-22).
    pub min_step: f64,
}

impl Default for BoxQpSettings {
    fn default() -> Self {
        Self { max_iterations: 100, gradient_tolerance: 1e-8, relative_improvement_tolerance: 1e-8, armijo: 0.1, step_factor: 0.6, min_step: 1e-22 }
    }
}

/// How a solve ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BoxQpStatus {
    /// The free gradient vanished (a KKT point; the global optimum, `H` being positive definite).
    Converged,
    /// Every coordinate is clamped.
    AllClamped,
    /// The last step improved the objective by less than the relative tolerance.
    SmallImprovement,
    /// No step along the Newton direction decreased the objective.
    LineSearchFailed,
    MaxIterations,
    /// `H_ff` was not positive definite (`H` itself is not).
    NotPositiveDefinite,
}

/// Scratch and result of the QP, allocated once for `n` variables.
pub struct BoxQp {
    settings: BoxQpSettings,
    /// The solution.
    pub x: DVector<f64>,
    /// `true` for the coordinates clamped at the solution (their gain rows are zero).
    pub clamped: Vec<bool>,
    /// `H_ff` with identity on the clamped coordinates, factored.
    pub(super) free_factor: SmallCholesky,
    free_h: DMatrix<f64>,
    factored: Vec<bool>,
    gradient: DVector<f64>,
    direction: DVector<f64>,
    trial: DVector<f64>,
    hx: DVector<f64>,
}

impl BoxQp {
    pub fn new(n: usize, settings: BoxQpSettings) -> Self {
        Self {
            settings,
            x: DVector::zeros(n),
            clamped: vec![false; n],
            free_factor: SmallCholesky::new(n),
            free_h: DMatrix::zeros(n, n),
            factored: vec![false; n],
            gradient: DVector::zeros(n),
            direction: DVector::zeros(n),
            trial: DVector::zeros(n),
            hx: DVector::zeros(n),
        }
    }

    /// `1/2 x^T H x + g^T x` (with `hx` as scratch for `H x`).
    fn objective(h: &DMatrix<f64>, g: &DVector<f64>, x: &DVector<f64>, hx: &mut DVector<f64>) -> f64 {
        hx.gemv(1.0, h, x, 0.0);
        0.5 * x.dot(hx) + g.dot(x)
    }

    /// Factors `H_ff` (identity on the clamped set); false if not positive definite.
    fn factor_free(&mut self, h: &DMatrix<f64>) -> bool {
        let n = h.nrows();
        for j in 0..n {
            for i in 0..n {
                self.free_h[(i, j)] = if self.clamped[i] || self.clamped[j] {
                    if i == j {
                        1.0
                    } else {
                        0.0
                    }
                } else {
                    h[(i, j)]
                };
            }
        }
        self.factored.copy_from_slice(&self.clamped);
        self.free_factor.factor(&self.free_h)
    }

    /// Solves the QP from the starting point `x0` (projected onto the box first; the
    /// previous iteration's solution makes a good one, Tassa 2014 sec. III-C). `lower <=
    /// upper` componentwise; infinite bounds are allowed. The solution is in `self.x`, its
    /// clamped set in `self.clamped` and the factor of its free block in `free_factor`.
    pub fn solve(&mut self, h: &DMatrix<f64>, g: &DVector<f64>, lower: &DVector<f64>, upper: &DVector<f64>, x0: &DVector<f64>) -> BoxQpStatus {
        let n = g.len();
        let s = self.settings;
        for i in 0..n {
            self.x[i] = x0[i].clamp(lower[i], upper[i]);
        }
        let mut value = Self::objective(h, g, &self.x, &mut self.hx);
        let mut first = true;
        let mut status = BoxQpStatus::MaxIterations;
        for _ in 0..s.max_iterations {
            // Gradient g + H x (hx holds H x from the objective).
            self.gradient.copy_from(g);
            self.gradient += &self.hx;
            // The clamped set: at a bound with the gradient pushing out of the box.
            let mut all_clamped = true;
            for i in 0..n {
                let at_lower = self.x[i] <= lower[i] && self.gradient[i] > 0.0;
                let at_upper = self.x[i] >= upper[i] && self.gradient[i] < 0.0;
                self.clamped[i] = at_lower || at_upper;
                all_clamped &= self.clamped[i];
            }
            if all_clamped {
                status = BoxQpStatus::AllClamped;
                break;
            }
            if (first || self.clamped != self.factored) && !self.factor_free(h) {
                return BoxQpStatus::NotPositiveDefinite;
            }
            first = false;
            // Free gradient; its norm is the optimality test.
            let mut free_norm2 = 0.0;
            for i in 0..n {
                self.direction[i] = if self.clamped[i] { 0.0 } else { -self.gradient[i] };
                free_norm2 += self.direction[i] * self.direction[i];
            }
            if free_norm2.sqrt() < s.gradient_tolerance {
                status = BoxQpStatus::Converged;
                break;
            }
            // Newton direction on the free coordinates: H_ff d_f = -grad_f, d_c = 0.
            self.free_factor.solve_vector_in_place(&mut self.direction);
            // Projected Armijo line search.
            let mut step = 1.0;
            let mut accepted = None;
            while step >= s.min_step {
                for i in 0..n {
                    self.trial[i] = (self.x[i] + step * self.direction[i]).clamp(lower[i], upper[i]);
                }
                let trial_value = Self::objective(h, g, &self.trial, &mut self.hx);
                // Armijo on the projected step: the decrease is at least a fraction of the
                // linear model's along the step actually taken, `grad^T (trial - x)`.
                let mut predicted = 0.0;
                for i in 0..n {
                    predicted += self.gradient[i] * (self.trial[i] - self.x[i]);
                }
                if predicted < 0.0 && trial_value - value <= s.armijo * predicted {
                    accepted = Some(trial_value);
                    break;
                }
                step *= s.step_factor;
            }
            let Some(new_value) = accepted else {
                status = BoxQpStatus::LineSearchFailed;
                break;
            };
            std::mem::swap(&mut self.x, &mut self.trial);
            let improvement = value - new_value;
            value = new_value;
            if improvement < s.relative_improvement_tolerance * value.abs() {
                status = BoxQpStatus::SmallImprovement;
                // The clamped set and factor of the final iterate, for the gain.
                self.hx.gemv(1.0, h, &self.x, 0.0);
                self.gradient.copy_from(g);
                self.gradient += &self.hx;
                for i in 0..n {
                    self.clamped[i] = (self.x[i] <= lower[i] && self.gradient[i] > 0.0) || (self.x[i] >= upper[i] && self.gradient[i] < 0.0);
                }
                break;
            }
        }
        if self.clamped != self.factored && !self.factor_free(h) {
            return BoxQpStatus::NotPositiveDefinite;
        }
        status
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clarabel::algebra::CscMatrix;
    use clarabel::solver::{DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT};

    /// Dense to CSC, keeping the upper triangle only if `upper`.
    fn csc(m: &DMatrix<f64>, upper: bool) -> CscMatrix<f64> {
        let (mut colptr, mut rowval, mut nzval) = (vec![0], Vec::new(), Vec::new());
        for j in 0..m.ncols() {
            for i in 0..m.nrows() {
                if m[(i, j)] != 0.0 && (!upper || i <= j) {
                    rowval.push(i);
                    nzval.push(m[(i, j)]);
                }
            }
            colptr.push(rowval.len());
        }
        CscMatrix::new(m.nrows(), m.ncols(), colptr, rowval, nzval)
    }

    /// The same QP by Clarabel's interior point: `A = [I; -I]`, `b = [upper; -lower]`.
    pub(crate) fn clarabel_box_qp(h: &DMatrix<f64>, g: &DVector<f64>, lower: &DVector<f64>, upper: &DVector<f64>) -> DVector<f64> {
        let n = g.len();
        let mut a = DMatrix::zeros(2 * n, n);
        let mut b = vec![0.0; 2 * n];
        for i in 0..n {
            a[(i, i)] = 1.0;
            a[(n + i, i)] = -1.0;
            b[i] = upper[i];
            b[n + i] = -lower[i];
        }
        let settings = DefaultSettingsBuilder::default().verbose(false).tol_gap_abs(1e-12).tol_gap_rel(1e-12).tol_feas(1e-12).build().unwrap();
        let cones = [SupportedConeT::NonnegativeConeT(2 * n)];
        let mut solver = DefaultSolver::new(&csc(h, true), g.as_slice(), &csc(&a, false), &b, &cones, settings).unwrap();
        solver.solve();
        assert!(matches!(solver.solution.status, SolverStatus::Solved | SolverStatus::AlmostSolved), "{:?}", solver.solution.status);
        DVector::from_vec(solver.solution.x.clone())
    }

    /// A deterministic stream of numbers in [-1, 1].
    fn stream(seed: u64) -> impl FnMut() -> f64 {
        let mut s = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        move || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((s >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
        }
    }

    /// Random positive-definite QPs with boxes that cut the unconstrained optimum: the
    /// projected Newton solution matches Clarabel's to 1e-6 and satisfies the KKT conditions
    /// (free gradient zero, clamped gradient pointing out of the box).
    #[test]
    fn random_box_qps_match_clarabel() {
        let mut active_cases = 0;
        for case in 0..60u64 {
            let mut r = stream(case);
            let n = 1 + (case as usize % 12);
            let m = DMatrix::from_fn(n, n, |_, _| r());
            let h = &m * m.transpose() + DMatrix::identity(n, n) * (0.05 + r().abs());
            let g = DVector::from_fn(n, |_, _| 3.0 * r());
            let lower = DVector::from_fn(n, |_, _| -0.2 - r().abs());
            let upper = DVector::from_fn(n, |i, _| if i % 5 == 4 { f64::INFINITY } else { 0.2 + r().abs() });
            let x0 = DVector::from_fn(n, |_, _| r());
            let mut qp = BoxQp::new(n, BoxQpSettings::default());
            let status = qp.solve(&h, &g, &lower, &upper, &x0);
            assert!(matches!(status, BoxQpStatus::Converged | BoxQpStatus::SmallImprovement | BoxQpStatus::AllClamped), "case {case}: {status:?}");
            let reference = clarabel_box_qp(&h, &g, &lower, &upper);
            assert!((&qp.x - &reference).amax() < 1e-6, "case {case}: {} vs {}", qp.x, reference);
            let grad = &g + &h * &qp.x;
            for i in 0..n {
                assert!(qp.x[i] >= lower[i] && qp.x[i] <= upper[i]);
                if qp.clamped[i] {
                    assert!(qp.x[i] == lower[i] || qp.x[i] == upper[i], "case {case}: clamped inside the box");
                } else {
                    assert!(grad[i].abs() < 1e-6, "case {case}: free gradient {}", grad[i]);
                }
            }
            active_cases += qp.clamped.iter().any(|&c| c) as usize;
        }
        assert!(active_cases > 30, "the boxes cut the optimum in only {active_cases} cases");
    }

    /// The free-block factor solves `H_ff` on the free rows and leaves the clamped rows zero.
    #[test]
    fn the_free_factor_solves_the_free_block() {
        let h = DMatrix::from_row_slice(3, 3, &[4.0, 1.0, 0.5, 1.0, 3.0, 0.2, 0.5, 0.2, 2.0]);
        let g = DVector::from_row_slice(&[-10.0, 1.0, -1.0]);
        let (lower, upper) = (DVector::from_element(3, -1.0), DVector::from_element(3, 1.0));
        let mut qp = BoxQp::new(3, BoxQpSettings::default());
        qp.solve(&h, &g, &lower, &upper, &DVector::zeros(3));
        // The first coordinate wants 2.5 + and is clamped at its upper bound.
        assert_eq!(qp.clamped, vec![true, false, false]);
        assert_eq!(qp.x[0], 1.0);
        let mut rhs = DMatrix::from_row_slice(3, 2, &[0.0, 0.0, 1.0, 2.0, -1.0, 0.5]);
        qp.free_factor.solve_in_place(&mut rhs);
        let hff = h.view((1, 1), (2, 2)).into_owned();
        let expected = hff.lu().solve(&DMatrix::from_row_slice(2, 2, &[1.0, 2.0, -1.0, 0.5])).unwrap();
        assert_eq!(rhs.row(0).iter().copied().collect::<Vec<_>>(), vec![0.0, 0.0]);
        assert!((rhs.rows(1, 2) - expected).norm() < 1e-12);
    }
}
