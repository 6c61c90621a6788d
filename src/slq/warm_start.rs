//! Warm starts: a solution's control law as the initial control law of another problem on
//! the same state and input spaces, such as the same task on a longer horizon.

use super::{Policy, Problem, SlqSolution};
use nalgebra::DVector;
use std::sync::Mutex;

/// `u = u_k + K_k (x (-) x_k)` on the knots of `solution` (Neunert 2017, eq. 2), and
/// `fallback` on the knots after them.
pub struct SolutionPolicy<'s, P: Problem> {
    solution: &'s SlqSolution<P::State>,
    fallback: &'s dyn Policy<P>,
    /// Scratch for `x (-) x_k` (`nx`); the rollout that calls the policy is serial.
    dx: Mutex<DVector<f64>>,
}

impl<'s, P: Problem> SolutionPolicy<'s, P> {
    pub fn new(problem: &P, solution: &'s SlqSolution<P::State>, fallback: &'s dyn Policy<P>) -> Self {
        Self { solution, fallback, dx: Mutex::new(DVector::zeros(problem.nx())) }
    }
}

impl<P: Problem> Policy<P> for SolutionPolicy<'_, P> {
    fn control(&self, problem: &P, k: usize, x: &P::State, u: &mut DVector<f64>) {
        let s = self.solution;
        if k >= s.inputs.len() {
            return self.fallback.control(problem, k, x, u);
        }
        let mut dx = self.dx.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        problem.difference(&s.states[k], x, &mut dx);
        u.copy_from(&s.inputs[k]);
        u.gemv(1.0, &s.gains[k], &dx, 1.0);
    }
}
