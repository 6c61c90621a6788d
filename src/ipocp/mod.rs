//! `ipocp`: a primal-dual interior-point solver for stage-wise optimal-control problems,
//! legwork's own constrained trajectory-optimization engine.
//!
//! - **Problem** ([`Problem`]): stages `k = 0..N` ([`Stage`]), each with a state `x_k` (its
//!   size may change from stage to stage), a control `u_k` (none on the last), dynamics
//!   `x_{k+1} = f_k(x_k, u_k)`, a cost `l_k`, equalities `g_k = 0` (initial and final
//!   conditions are stage equalities) and inequalities `lower <= h_k <= upper`. Parameters
//!   that do not change over time (phase durations) are augmented states with identity
//!   dynamics. A general NLP is a one-stage problem ([`nlp`]).
//! - **Algorithm** ([`Solver`]): IPOPT's (Wächter & Biegler 2006): slacks and a log barrier
//!   for the inequalities, primal-dual steps with the fraction-to-the-boundary rule, the
//!   monotone barrier update (or, as a setting, the adaptive one of Nocedal, Wächter & Waltz
//!   2009: [`BarrierUpdate`]), a filter line search with second-order corrections, inertia
//!   correction by regularizing the Hessian, and the feasibility restoration of sec. 3.3
//!   (`restoration`, stage-wise: the elastic variables of a stage's rows are its own) where
//!   the filter line search fails from an infeasible point; if that finds no acceptable
//!   point either, the solve stops with [`Status::LocallyInfeasible`].
//! - **Linear algebra** ([`riccati`]): each KKT system is solved by a Riccati recursion
//!   over the stages that eliminates the stage equalities inside the recursion (FATROP's
//!   approach), so the cost of a step grows linearly with the number of stages; the
//!   inertia test is the positive definiteness of the reduced Hessians met on the way.
//! - **Result** ([`SolveResult`]): status, iterations, infeasibilities, the last and the
//!   best iterate, timings. Warm starts take primal values and, optionally, duals.

mod elimination;
mod filter;
mod iterate;
pub mod nlp;
mod problem;
pub mod riccati;
mod restoration;
mod settings;
mod solver;
mod stage;

pub use iterate::{Duals, Iterate, SolveResult, Status, Timings};
pub use nlp::{nlp_problem, Nlp, NlpStage};
pub use problem::{Problem, ProblemError};
pub use settings::{BarrierUpdate, MuOracle, Settings, SettingsError};
pub use solver::{SolveError, Solver};
pub use stage::{Stage, StageDims, StageJacobians, StageMultipliers, StageValues};
