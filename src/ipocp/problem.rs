//! A problem: a sequence of stages whose sizes chain (`nx_next` of stage `k` is `nx` of
//! stage `k + 1`; the last stage has no control and no dynamics).

use super::stage::{Stage, StageDims};
use std::sync::Arc;

/// What is wrong with a problem's stages.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ProblemError {
    #[error("a problem needs at least one stage")]
    NoStages,
    #[error("stage {stage}: `nx_next` is {nx_next} but stage {next} has `nx` = {nx}; the sizes must chain")]
    SizesDoNotChain { stage: usize, nx_next: usize, next: usize, nx: usize },
    #[error("the last stage ({stage}) must have `nu` = 0 and `nx_next` = 0, it has {nu} and {nx_next}")]
    LastStageHasControlsOrDynamics { stage: usize, nu: usize, nx_next: usize },
    #[error("stage {stage}, inequality row {row}: bounds [{lower}, {upper}] must satisfy lower <= upper, not both infinite, none NaN")]
    BadBounds { stage: usize, row: usize, lower: f64, upper: f64 },
    #[error("stage {stage}: the initial guess has size {got}, expected nx + nu = {expected}")]
    GuessSize { stage: usize, got: usize, expected: usize },
    #[error("the initial guess has {got} stages, the problem {expected}")]
    GuessStages { got: usize, expected: usize },
    #[error("stage {stage}: the initial guess is not finite")]
    GuessNotFinite { stage: usize },
    #[error("stage {stage}: `{what}` of the warm-start duals has size {got}, expected {expected}")]
    DualSize { stage: usize, what: &'static str, got: usize, expected: usize },
}

/// An optimal-control problem: stages `0..N`.
pub struct Problem {
    /// Shared so that the feasibility restoration's stages can wrap them.
    stages: Vec<Arc<dyn Stage>>,
    dims: Vec<StageDims>,
    lower: Vec<Vec<f64>>,
    upper: Vec<Vec<f64>>,
}

impl Problem {
    /// Checks that the stage sizes chain and the inequality bounds are sound.
    pub fn new(stages: Vec<Box<dyn Stage>>) -> Result<Self, ProblemError> {
        if stages.is_empty() {
            return Err(ProblemError::NoStages);
        }
        let dims: Vec<StageDims> = stages.iter().map(|s| s.dims()).collect();
        let n = dims.len();
        for k in 0..n - 1 {
            if dims[k].nx_next != dims[k + 1].nx {
                return Err(ProblemError::SizesDoNotChain { stage: k, nx_next: dims[k].nx_next, next: k + 1, nx: dims[k + 1].nx });
            }
        }
        let last = dims[n - 1];
        if last.nu != 0 || last.nx_next != 0 {
            return Err(ProblemError::LastStageHasControlsOrDynamics { stage: n - 1, nu: last.nu, nx_next: last.nx_next });
        }
        let mut lower = Vec::with_capacity(n);
        let mut upper = Vec::with_capacity(n);
        for (k, (s, d)) in stages.iter().zip(&dims).enumerate() {
            let mut lo = vec![f64::NEG_INFINITY; d.nh];
            let mut up = vec![f64::INFINITY; d.nh];
            s.inequality_bounds(&mut lo, &mut up);
            for row in 0..d.nh {
                let (l, u) = (lo[row], up[row]);
                if l.is_nan() || u.is_nan() || l > u || (l == f64::NEG_INFINITY && u == f64::INFINITY) || l == f64::INFINITY || u == f64::NEG_INFINITY {
                    return Err(ProblemError::BadBounds { stage: k, row, lower: l, upper: u });
                }
            }
            lower.push(lo);
            upper.push(up);
        }
        let stages = stages.into_iter().map(Arc::from).collect();
        Ok(Self { stages, dims, lower, upper })
    }

    /// Number of stages `N + 1`.
    pub fn len(&self) -> usize {
        self.stages.len()
    }

    /// Always false (a problem has at least one stage).
    pub fn is_empty(&self) -> bool {
        false
    }

    pub fn dims(&self) -> &[StageDims] {
        &self.dims
    }

    pub fn stage(&self, k: usize) -> &dyn Stage {
        self.stages[k].as_ref()
    }

    /// Stage `k`, shared (the restoration problem wraps it).
    pub(crate) fn stage_shared(&self, k: usize) -> Arc<dyn Stage> {
        self.stages[k].clone()
    }

    /// Lower and upper bounds of stage `k`'s inequality rows.
    pub fn bounds(&self, k: usize) -> (&[f64], &[f64]) {
        (&self.lower[k], &self.upper[k])
    }

    /// Total numbers of variables and of equality rows (dynamics included), inequality rows.
    pub fn sizes(&self) -> (usize, usize, usize) {
        let nvar = self.dims.iter().map(|d| d.nz()).sum();
        let neq = self.dims.iter().map(|d| d.nx_next + d.ng).sum();
        let nineq = self.dims.iter().map(|d| d.nh).sum();
        (nvar, neq, nineq)
    }
}
