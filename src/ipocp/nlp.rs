//! A general nonlinear program `min f(x) s.t. g(x) = 0, lower <= h(x) <= upper` as a
//! one-stage optimal-control problem (`x` the state of the only stage, no control, no
//! dynamics), so that NLPs go through the same solver as OCPs.

use super::problem::{Problem, ProblemError};
use super::stage::{Stage, StageDims, StageJacobians, StageMultipliers, StageValues};
use nalgebra::DMatrix;

/// A nonlinear program; sizes fixed, buffers sized by them.
pub trait Nlp: Send + Sync {
    /// Numbers of variables, equality rows and inequality rows.
    fn sizes(&self) -> (usize, usize, usize);
    /// `lower <= h(x) <= upper` (`+-inf` where a side is absent).
    fn inequality_bounds(&self, lower: &mut [f64], upper: &mut [f64]);
    /// `f(x)`, `g(x)`, `h(x)`.
    fn evaluate(&self, x: &[f64], g: &mut [f64], h: &mut [f64]) -> f64;
    /// `grad f`, `dg/dx`, `dh/dx`.
    fn jacobians(&self, x: &[f64], grad: &mut [f64], jg: &mut DMatrix<f64>, jh: &mut DMatrix<f64>);
    /// Hessian of `sigma f + nu . g + y . h`.
    fn lagrangian_hessian(&self, x: &[f64], sigma: f64, nu: &[f64], y: &[f64], out: &mut DMatrix<f64>);
}

/// An [`Nlp`] seen as the single stage of a problem.
pub struct NlpStage<T: Nlp>(pub T);

impl<T: Nlp> Stage for NlpStage<T> {
    fn dims(&self) -> StageDims {
        let (n, ng, nh) = self.0.sizes();
        StageDims { nx: n, nu: 0, nx_next: 0, ng, nh }
    }
    fn inequality_bounds(&self, lower: &mut [f64], upper: &mut [f64]) {
        self.0.inequality_bounds(lower, upper);
    }
    fn evaluate(&self, z: &[f64], out: &mut StageValues) {
        out.cost = self.0.evaluate(z, out.equalities.as_mut_slice(), out.inequalities.as_mut_slice());
    }
    fn jacobians(&self, z: &[f64], out: &mut StageJacobians) {
        self.0.jacobians(z, out.cost_gradient.as_mut_slice(), &mut out.equalities, &mut out.inequalities);
    }
    fn lagrangian_hessian(&self, z: &[f64], m: StageMultipliers<'_>, out: &mut DMatrix<f64>) {
        self.0.lagrangian_hessian(z, m.cost, m.equalities, m.inequalities, out);
    }
}

/// The one-stage problem of `nlp`.
pub fn nlp_problem<T: Nlp + 'static>(nlp: T) -> Result<Problem, ProblemError> {
    Problem::new(vec![Box::new(NlpStage(nlp))])
}
