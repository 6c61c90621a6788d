//! One stage of an optimal-control problem, FATROP's way of naming it:
//!
//! ```text
//! stage k:  x_k (n_x,k), u_k (n_u,k; none on the last stage)
//!           x_{k+1} = f_k(x_k, u_k)            dynamics (absent on the last stage)
//!           l_k(x_k, u_k)                       cost
//!           g_k(x_k, u_k) = 0                   equalities (initial and final conditions included)
//!           lower_k <= h_k(x_k, u_k) <= upper_k inequalities (bounds included, +-inf allowed)
//! ```
//!
//! A stage sees its variables as one vector `z = [x; u]` of size `n_x + n_u`. Derivatives
//! are with respect to `z`, Jacobians are row-major in the usual sense (`rows = outputs`).
//! Time-invariant parameters (phase durations, ...) are augmented states with the identity
//! as their dynamics (`T_{k+1} = T_k`): the solver needs no special case for them.

use nalgebra::{DMatrix, DVector};

/// The sizes of one stage.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StageDims {
    /// State size `n_x` of this stage.
    pub nx: usize,
    /// Control size `n_u` (0 on the last stage).
    pub nu: usize,
    /// State size of the next stage, the number of rows of `f_k` (0 on the last stage).
    pub nx_next: usize,
    /// Number of equality rows `g_k`.
    pub ng: usize,
    /// Number of inequality rows `h_k`.
    pub nh: usize,
}

impl StageDims {
    /// `n_x + n_u`, the size of the stage's variable `z = [x; u]`.
    pub fn nz(&self) -> usize {
        self.nx + self.nu
    }
}

/// Values of one stage at a point `z`.
#[derive(Clone, Debug)]
pub struct StageValues {
    /// `l_k(z)`.
    pub cost: f64,
    /// `f_k(z)` (size `nx_next`).
    pub dynamics: DVector<f64>,
    /// `g_k(z)` (size `ng`).
    pub equalities: DVector<f64>,
    /// `h_k(z)` (size `nh`).
    pub inequalities: DVector<f64>,
}

impl StageValues {
    /// Zeros of the sizes of `dims`.
    pub fn zeros(dims: StageDims) -> Self {
        Self {
            cost: 0.0,
            dynamics: DVector::zeros(dims.nx_next),
            equalities: DVector::zeros(dims.ng),
            inequalities: DVector::zeros(dims.nh),
        }
    }
}

/// First derivatives of one stage at a point `z`.
#[derive(Clone, Debug)]
pub struct StageJacobians {
    /// `dl/dz` (size `nz`).
    pub cost_gradient: DVector<f64>,
    /// `df/dz = [A B]` (`nx_next x nz`).
    pub dynamics: DMatrix<f64>,
    /// `dg/dz` (`ng x nz`).
    pub equalities: DMatrix<f64>,
    /// `dh/dz` (`nh x nz`).
    pub inequalities: DMatrix<f64>,
}

impl StageJacobians {
    /// Zeros of the sizes of `dims`.
    pub fn zeros(dims: StageDims) -> Self {
        let nz = dims.nz();
        Self {
            cost_gradient: DVector::zeros(nz),
            dynamics: DMatrix::zeros(dims.nx_next, nz),
            equalities: DMatrix::zeros(dims.ng, nz),
            inequalities: DMatrix::zeros(dims.nh, nz),
        }
    }
}

/// Multipliers the stage's Lagrangian Hessian is weighted with.
#[derive(Clone, Copy, Debug)]
pub struct StageMultipliers<'a> {
    /// Weight of the cost (1 in the solver's steps).
    pub cost: f64,
    /// Multipliers of the dynamics rows `f_k` (size `nx_next`).
    pub dynamics: &'a [f64],
    /// Multipliers of `g_k` (size `ng`).
    pub equalities: &'a [f64],
    /// Multipliers of `h_k` (size `nh`).
    pub inequalities: &'a [f64],
}

/// A stage of an optimal-control problem.
///
/// Implementations evaluate into the caller's buffers (sized by [`Stage::dims`]) and should
/// allocate nothing. The Hessian is that of the stage's part of the Lagrangian,
/// `cost * l + dynamics . f + equalities . g + inequalities . h`; a stage may return a
/// Gauss-Newton approximation instead (positive semi-definite, multipliers ignored): say so
/// in its documentation, the solver converges then more slowly but needs no inertia
/// correction for that stage.
pub trait Stage: Send + Sync {
    /// Sizes of this stage.
    fn dims(&self) -> StageDims;

    /// Bounds of the inequality rows: `lower <= h(z) <= upper`, `-inf` / `+inf` for a side
    /// that is absent. A row with both sides infinite is rejected by the solver.
    fn inequality_bounds(&self, lower: &mut [f64], upper: &mut [f64]);

    /// Cost, dynamics, equalities and inequalities at `z`.
    fn evaluate(&self, z: &[f64], out: &mut StageValues);

    /// First derivatives at `z`.
    fn jacobians(&self, z: &[f64], out: &mut StageJacobians);

    /// Hessian (`nz x nz`, symmetric, both triangles) of the stage's Lagrangian at `z`.
    fn lagrangian_hessian(&self, z: &[f64], multipliers: StageMultipliers<'_>, out: &mut DMatrix<f64>);
}
