//! What the SLQ solver needs of an optimal-control problem (Crocoddyl's shape: a sequence
//! of knots, each with dynamics and a running cost, and a terminal cost).

use nalgebra::{DMatrix, DVector};

/// A discrete-time optimal-control problem on a manifold,
///
/// ```text
/// min  h(x_N) + sum_{k<N} l_k(x_k, u_k)      s.t.  x_{k+1} = f_k(x_k, u_k),  x_0 given
/// ```
///
/// with states in a manifold whose tangent space has dimension `nx` (deviations `x (-) y`
/// from [`Problem::difference`]) and inputs in `R^nu`. Implementations keep whatever one
/// thread needs to evaluate a knot in a [`Problem::Workspace`], so the solver linearizes
/// knots in parallel with one workspace per thread.
pub trait Problem: Sync {
    /// A point of the state manifold (may carry hidden states, such as contact anchors).
    type State: Clone + Send + Sync;
    /// Per-thread scratch.
    type Workspace: Send;

    /// Tangent dimension of the state.
    fn nx(&self) -> usize;
    /// Input dimension.
    fn nu(&self) -> usize;
    /// Number of transitions `N` (states `x_0 .. x_N`).
    fn horizon(&self) -> usize;
    fn workspace(&self) -> Self::Workspace;
    fn initial_state(&self) -> Self::State;
    /// The tangent vector `dx = x (-) y` with `y (+) dx = x` (into `dx`, length `nx`).
    fn difference(&self, y: &Self::State, x: &Self::State, dx: &mut DVector<f64>);
    /// `x_next = f_k(x, u)`; returns the running cost `l_k(x, u)`.
    fn step(&self, ws: &mut Self::Workspace, k: usize, x: &Self::State, u: &DVector<f64>, x_next: &mut Self::State) -> f64;
    /// As [`Problem::step`], and the linearization of `f_k` and quadratization of `l_k`
    /// at `(x, u)` into `d`.
    fn step_with_derivatives(&self, ws: &mut Self::Workspace, k: usize, x: &Self::State, u: &DVector<f64>, x_next: &mut Self::State, d: &mut KnotDerivatives) -> f64;
    /// The linearization of `f_k` and quadratization of `l_k` at `(x, u)` into `d`, with
    /// `l_k(x, u)`, for the backward pass, which has `x_{k+1}` from its rollout already:
    /// `scratch` holds whatever the linearization needed of the step (not necessarily
    /// `f_k(x, u)`). By default [`Problem::step_with_derivatives`].
    fn linearize_knot(&self, ws: &mut Self::Workspace, k: usize, x: &Self::State, u: &DVector<f64>, scratch: &mut Self::State, d: &mut KnotDerivatives) -> f64 {
        self.step_with_derivatives(ws, k, x, u, scratch, d)
    }
    /// `h(x_N)`.
    fn terminal_cost(&self, ws: &mut Self::Workspace, x: &Self::State) -> f64;
    /// `h(x_N)` with its gradient `h_x` and Hessian `h_xx` (tangent space).
    fn terminal_cost_derivatives(&self, ws: &mut Self::Workspace, x: &Self::State, h_x: &mut DVector<f64>, h_xx: &mut DMatrix<f64>) -> f64;
    /// The box `lower <= u_k <= upper` the input of knot `k` must stay in (Tassa, Mansard,
    /// Todorov 2014): the backward pass solves a box-constrained QP for the step, and every
    /// rollout projects its inputs onto the box. Infinite entries leave an input unbounded
    /// (the default: no bounds). `lower` and `upper` arrive with length `nu`.
    fn input_bounds(&self, k: usize, lower: &mut DVector<f64>, upper: &mut DVector<f64>) {
        let _ = k;
        lower.fill(f64::NEG_INFINITY);
        upper.fill(f64::INFINITY);
    }
    /// `true` if a state is usable (finite, not blown up): a rollout reaching an unusable
    /// state is a failed line-search trial, not a result.
    fn is_valid(&self, x: &Self::State) -> bool;
    /// The last knot whose state the task still uses, `m <= N` (`N` by default). A window of
    /// a receding horizon that reaches past its task's end uses the states up to the end;
    /// [`crate::slq::Slq::real_time_iteration`] keeps a trial that stayed valid that far.
    fn last_used_knot(&self) -> usize {
        self.horizon()
    }
    /// `true` if a knot's model taken at `y` may serve at `x` ([`crate::slq::ModelReuse`]):
    /// false where the two lie in different pieces of a piecewise model (another set of
    /// feet in contact), whose derivatives the kept model does not describe. By default
    /// always true.
    fn same_model_piece(&self, y: &Self::State, x: &Self::State) -> bool {
        let _ = (y, x);
        true
    }
}

/// A control law `u = pi_k(x)` for the first rollout (Neunert 2017, Alg. 1: "initial stable
/// control law"; for the quadruped a joint PD around the default stance).
pub trait Policy<P: Problem>: Sync {
    fn control(&self, problem: &P, k: usize, x: &P::State, u: &mut DVector<f64>);
}

/// The local model of one knot: `dx' = A dx + B du`, and the second-order expansion of its
/// running cost `l + l_x dx + l_u du + 1/2 dx^T l_xx dx + 1/2 du^T l_uu du + du^T l_ux dx`.
#[derive(Clone, Debug)]
pub struct KnotDerivatives {
    pub a: DMatrix<f64>,
    pub b: DMatrix<f64>,
    pub l_x: DVector<f64>,
    pub l_u: DVector<f64>,
    pub l_xx: DMatrix<f64>,
    pub l_uu: DMatrix<f64>,
    pub l_ux: DMatrix<f64>,
}

impl KnotDerivatives {
    pub fn zeros(nx: usize, nu: usize) -> Self {
        Self {
            a: DMatrix::zeros(nx, nx),
            b: DMatrix::zeros(nx, nu),
            l_x: DVector::zeros(nx),
            l_u: DVector::zeros(nu),
            l_xx: DMatrix::zeros(nx, nx),
            l_uu: DMatrix::zeros(nu, nu),
            l_ux: DMatrix::zeros(nu, nx),
        }
    }
}
