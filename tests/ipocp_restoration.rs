//! ipocp's feasibility restoration (Wächter & Biegler 2006, sec. 3.3) on the problem that
//! makes interior-point methods without one fail (Wächter & Biegler 2000, "Failure of global
//! convergence for a class of interior point methods for nonlinear programming", Math.
//! Programming 88, eq. 1 with a = -1, b = 1/2):
//!
//! ```text
//! min x1   s.t.   x1^2 - x2 - 1 = 0,   x1 - x3 - 1/2 = 0,   x2, x3 >= 0
//! ```
//!
//! with the optimum `x = (1, 0, 1/2)`. From `(0.5, 1, 1)` ipocp's filter line search fails
//! (the bounds are inequality rows with slacks, the steps towards `x1 = 1` are cut by the
//! fraction to the boundary while the violation grows); the restoration gets past that.
//! (From the paper's start `(-2, 1, 1)` the iterates go to `x1 = -1`, a local minimizer of
//! the l1 violation over `x2, x3 >= 0` (1.5); the restoration converges there and the solve
//! reports `LocallyInfeasible`, as it should from there.) Solved as an NLP (one stage) and
//! as an optimal-control problem whose stages share `x1` through their dynamics (the
//! elastic variables of the last stage's rows are then carried as states).

use legwork::ipocp::{nlp_problem, Nlp, Problem, Settings, Solver, Stage, StageDims, StageJacobians, StageMultipliers, StageValues, Status};
use nalgebra::{DMatrix, DVector};

/// The problem as an NLP.
struct WaechterBiegler;

impl Nlp for WaechterBiegler {
    fn sizes(&self) -> (usize, usize, usize) {
        (3, 2, 2)
    }
    fn inequality_bounds(&self, lower: &mut [f64], upper: &mut [f64]) {
        lower.fill(0.0);
        upper.fill(f64::INFINITY);
    }
    fn evaluate(&self, x: &[f64], g: &mut [f64], h: &mut [f64]) -> f64 {
        g[0] = x[0] * x[0] - x[1] - 1.0;
        g[1] = x[0] - x[2] - 0.5;
        h[0] = x[1];
        h[1] = x[2];
        x[0]
    }
    fn jacobians(&self, x: &[f64], grad: &mut [f64], jg: &mut DMatrix<f64>, jh: &mut DMatrix<f64>) {
        grad.copy_from_slice(&[1.0, 0.0, 0.0]);
        jg.copy_from(&DMatrix::from_row_slice(2, 3, &[2.0 * x[0], -1.0, 0.0, 1.0, 0.0, -1.0]));
        jh.copy_from(&DMatrix::from_row_slice(2, 3, &[0.0, 1.0, 0.0, 0.0, 0.0, 1.0]));
    }
    fn lagrangian_hessian(&self, _x: &[f64], _sigma: f64, nu: &[f64], _y: &[f64], out: &mut DMatrix<f64>) {
        out.fill(0.0);
        out[(0, 0)] = 2.0 * nu[0];
    }
}

fn solve_nlp(restoration: bool) -> legwork::ipocp::SolveResult {
    let problem = nlp_problem(WaechterBiegler).unwrap();
    let mut solver = Solver::new(&problem, Settings { restoration, ..Settings::default() }).unwrap();
    solver.solve(&problem, &[DVector::from_column_slice(&[0.5, 1.0, 1.0])]).unwrap()
}

#[test]
fn nlp_fails_without_restoration_and_solves_with_it() {
    let without = solve_nlp(false);
    assert_eq!(without.status, Status::LocallyInfeasible, "without restoration: {:?}", without.status);
    assert!(without.primal_infeasibility > 0.1, "{}", without.primal_infeasibility);

    let with = solve_nlp(true);
    assert_eq!(with.status, Status::Solved, "with restoration: {:?} after {} iterations", with.status, with.iterations);
    assert!(with.restorations >= 1);
    let x = &with.last.primal[0];
    assert!((x[0] - 1.0).abs() < 1e-6 && x[1].abs() < 1e-6 && (x[2] - 0.5).abs() < 1e-6, "{x}");
    assert!(with.primal_infeasibility < 1e-8);
}

/// The same problem spread over stages (from `x = (0.3, 1, 1)` on every stage, where the
/// line search fails without restoration): stage `k` has the state `x1` (copied to the next
/// stage) and the controls `(x2_k, x3_k)` with the two equalities of the NLP; the last stage
/// has the objective `x1`. Every stage meets the same obstacle.
struct ChainStage {
    last: bool,
}

impl Stage for ChainStage {
    fn dims(&self) -> StageDims {
        if self.last {
            StageDims { nx: 1, nu: 0, nx_next: 0, ng: 0, nh: 0 }
        } else {
            StageDims { nx: 1, nu: 2, nx_next: 1, ng: 2, nh: 2 }
        }
    }
    fn inequality_bounds(&self, lower: &mut [f64], upper: &mut [f64]) {
        lower.fill(0.0);
        upper.fill(f64::INFINITY);
    }
    fn evaluate(&self, z: &[f64], out: &mut StageValues) {
        if self.last {
            out.cost = z[0];
            return;
        }
        out.cost = 0.0;
        out.dynamics[0] = z[0];
        out.equalities[0] = z[0] * z[0] - z[1] - 1.0;
        out.equalities[1] = z[0] - z[2] - 0.5;
        out.inequalities[0] = z[1];
        out.inequalities[1] = z[2];
    }
    fn jacobians(&self, z: &[f64], out: &mut StageJacobians) {
        if self.last {
            out.cost_gradient[0] = 1.0;
            return;
        }
        out.cost_gradient.fill(0.0);
        out.dynamics.copy_from(&DMatrix::from_row_slice(1, 3, &[1.0, 0.0, 0.0]));
        out.equalities.copy_from(&DMatrix::from_row_slice(2, 3, &[2.0 * z[0], -1.0, 0.0, 1.0, 0.0, -1.0]));
        out.inequalities.copy_from(&DMatrix::from_row_slice(2, 3, &[0.0, 1.0, 0.0, 0.0, 0.0, 1.0]));
    }
    fn lagrangian_hessian(&self, _z: &[f64], m: StageMultipliers<'_>, out: &mut DMatrix<f64>) {
        out.fill(0.0);
        if !self.last {
            out[(0, 0)] = 2.0 * m.equalities[0];
        }
    }
}

fn solve_chain(restoration: bool, stages: usize) -> legwork::ipocp::SolveResult {
    let problem = Problem::new((0..=stages).map(|k| Box::new(ChainStage { last: k == stages }) as Box<dyn Stage>).collect()).unwrap();
    let guess: Vec<DVector<f64>> = (0..=stages).map(|k| if k == stages { DVector::from_element(1, 0.3) } else { DVector::from_column_slice(&[0.3, 1.0, 1.0]) }).collect();
    let mut solver = Solver::new(&problem, Settings { restoration, ..Settings::default() }).unwrap();
    solver.solve(&problem, &guess).unwrap()
}

#[test]
fn ocp_fails_without_restoration_and_solves_with_it() {
    let stages = 5;
    let without = solve_chain(false, stages);
    assert_eq!(without.status, Status::LocallyInfeasible, "without restoration: {:?}", without.status);

    let with = solve_chain(true, stages);
    assert_eq!(with.status, Status::Solved, "with restoration: {:?} after {} iterations", with.status, with.iterations);
    assert!(with.restorations >= 1);
    for (k, z) in with.last.primal.iter().enumerate() {
        assert!((z[0] - 1.0).abs() < 1e-6, "stage {k}: {z}");
        if k < stages {
            assert!(z[1].abs() < 1e-6 && (z[2] - 0.5).abs() < 1e-6, "stage {k}: {z}");
        }
    }
}

#[test]
fn infeasible_problem_still_reported_after_restoration() {
    // x1^2 + 1 = 0 has no solution: the restoration converges to the least violation (1 at
    // x1 = 0) and cannot return.
    let problem = Problem::new(vec![Box::new(Infeasible) as Box<dyn Stage>]).unwrap();
    let mut solver = Solver::new(&problem, Settings::default()).unwrap();
    let r = solver.solve(&problem, &[DVector::from_column_slice(&[1.0, 0.5])]).unwrap();
    assert_eq!(r.status, Status::LocallyInfeasible);
    assert!(r.restorations >= 1);
    assert!(r.primal_infeasibility >= 1.0 - 1e-9);
}

struct Infeasible;

impl Stage for Infeasible {
    fn dims(&self) -> StageDims {
        StageDims { nx: 2, nu: 0, nx_next: 0, ng: 1, nh: 0 }
    }
    fn inequality_bounds(&self, _: &mut [f64], _: &mut [f64]) {}
    fn evaluate(&self, z: &[f64], out: &mut StageValues) {
        out.cost = z[0] * z[0] + z[1] * z[1];
        out.equalities[0] = z[0] * z[0] + z[1] * z[1] + 1.0;
    }
    fn jacobians(&self, z: &[f64], out: &mut StageJacobians) {
        out.cost_gradient.copy_from_slice(&[2.0 * z[0], 2.0 * z[1]]);
        out.equalities.copy_from_slice(&[2.0 * z[0], 2.0 * z[1]]);
    }
    fn lagrangian_hessian(&self, _z: &[f64], m: StageMultipliers<'_>, out: &mut DMatrix<f64>) {
        out.fill(0.0);
        out.fill_diagonal(2.0 * m.cost + 2.0 * m.equalities[0]);
    }
}


