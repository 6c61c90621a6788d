//! The primal-dual point of the interior-point method and the result of a solve.

use nalgebra::DVector;
use std::time::Duration;

/// Primal and dual values, stage by stage.
///
/// The Lagrangian they belong to is
/// `sum_k l_k + lambda_k^T (f_k(z_k) - x_{k+1}) + nu_k^T g_k + y_k^T (h_k - s_k)
///  - zl_k^T (s_k - lower_k) - zu_k^T (upper_k - s_k)`.
#[derive(Clone, Debug, PartialEq)]
pub struct Iterate {
    /// `z_k = [x_k; u_k]`.
    pub primal: Vec<DVector<f64>>,
    /// Slacks `s_k` of the inequality rows (`lower <= s <= upper`, `h(z) = s` at a solution).
    pub slack: Vec<DVector<f64>>,
    /// `lambda_k`: multipliers of stage `k`'s dynamics `x_{k+1} = f_k(z_k)` (size `nx_next`).
    pub dynamics_multiplier: Vec<DVector<f64>>,
    /// `nu_k`: multipliers of `g_k = 0`.
    pub equality_multiplier: Vec<DVector<f64>>,
    /// `y_k`: multipliers of `h_k(z_k) = s_k`.
    pub inequality_multiplier: Vec<DVector<f64>>,
    /// Multipliers of `s_k >= lower_k` (0 where the bound is absent).
    pub lower_bound_multiplier: Vec<DVector<f64>>,
    /// Multipliers of `s_k <= upper_k` (0 where the bound is absent).
    pub upper_bound_multiplier: Vec<DVector<f64>>,
}

impl Iterate {
    /// Copies `other` (of the same sizes) into `self` without allocating.
    pub fn copy_from(&mut self, other: &Iterate) {
        let pairs = [
            (&mut self.primal, &other.primal),
            (&mut self.slack, &other.slack),
            (&mut self.dynamics_multiplier, &other.dynamics_multiplier),
            (&mut self.equality_multiplier, &other.equality_multiplier),
            (&mut self.inequality_multiplier, &other.inequality_multiplier),
            (&mut self.lower_bound_multiplier, &other.lower_bound_multiplier),
            (&mut self.upper_bound_multiplier, &other.upper_bound_multiplier),
        ];
        for (dst, src) in pairs {
            for (d, s) in dst.iter_mut().zip(src) {
                d.copy_from(s);
            }
        }
    }
}

/// Dual values for a warm start (sizes as in [`Iterate`]); slacks are taken from `h(z)`
/// pushed into the interior when absent.
#[derive(Clone, Debug, PartialEq)]
pub struct Duals {
    pub dynamics_multiplier: Vec<DVector<f64>>,
    pub equality_multiplier: Vec<DVector<f64>>,
    pub inequality_multiplier: Vec<DVector<f64>>,
    pub lower_bound_multiplier: Vec<DVector<f64>>,
    pub upper_bound_multiplier: Vec<DVector<f64>>,
}

/// How a solve ended.
#[derive(Clone, Debug, PartialEq)]
pub enum Status {
    /// The scaled optimality error is below `tolerance` and the unscaled tolerances hold.
    Solved,
    /// `max_iterations` reached; the result keeps the best iterate.
    MaxIterations,
    /// The filter line search could not reduce the constraint violation, which is above
    /// `constraint_violation_tolerance`: the problem is (locally) infeasible from here.
    /// With [`super::Settings::restoration`], the feasibility restoration found no point
    /// the filter accepts either (it converged to a local minimum of the violation, or hit
    /// its limits).
    LocallyInfeasible,
    /// The line search failed at a point that is feasible but not optimal (a search
    /// direction that the barrier objective cannot follow, usually bad derivatives).
    LineSearchFailed,
    /// The inertia correction reached `regularization_max`, or the functions returned
    /// non-finite values at the current iterate.
    NumericalFailure(String),
}

/// Wall time spent in the parts of a solve.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Timings {
    pub total: Duration,
    /// Function values, Jacobians and Hessians.
    pub evaluation: Duration,
    /// Riccati solves (inertia corrections and second-order corrections included).
    pub kkt: Duration,
}

/// The result of [`super::Solver::solve`].
#[derive(Clone, Debug)]
pub struct SolveResult {
    pub status: Status,
    /// Iterations taken.
    pub iterations: usize,
    /// Objective `sum_k l_k` at `last`.
    pub objective: f64,
    /// Largest constraint violation (`inf`-norm of dynamics defects, `g`, `h - s`) at `last`.
    pub primal_infeasibility: f64,
    /// Largest entry of the Lagrangian's gradient (unscaled) at `last`.
    pub dual_infeasibility: f64,
    /// Largest complementarity `|(s - lower) zl|`, `|(upper - s) zu|` at `last`.
    pub complementarity: f64,
    /// IPOPT's scaled optimality error `E_0` at `last`.
    pub optimality_error: f64,
    /// The final barrier parameter.
    pub mu: f64,
    /// The last iterate.
    pub last: Iterate,
    /// The iterate with the smallest `E_0` seen (equal to `last` when solved).
    pub best: Iterate,
    /// Iteration of `best`, its `E_0`, objective and primal infeasibility.
    pub best_iteration: usize,
    pub best_optimality_error: f64,
    pub best_objective: f64,
    pub best_primal_infeasibility: f64,
    /// Times the Hessian needed regularization, and the last regularization used.
    pub regularizations: usize,
    pub last_regularization: f64,
    /// Feasibility restorations entered, and the iterations they took (not in `iterations`).
    pub restorations: usize,
    pub restoration_iterations: usize,
    /// Riccati solves of the search directions (inertia corrections included, second-order
    /// corrections not).
    pub kkt_solves: usize,
    pub timings: Timings,
}
