//! ZMP-stable CoG trajectory (Winkler 2015, sec. IV "Whole-Body Motion Generation").
//!
//! Given a footstep sequence as support phases (which feet stand where, for how long), the
//! CoG's horizontal path is a spline of fifth-order polynomials (eq. 3), continuous in
//! position, velocity and acceleration (eq. 4), whose cart-table ZMP (eq. 5) stays inside
//! the current support polygon shrunk by a stability margin `d` (eq. 6) at every sample
//! time, and which minimizes the weighted integral of the squared acceleration (eq. 7,
//! `w_y = 1.5 w_x`). That is a convex QP, solved here with Clarabel.
//!
//! * [`phases`]: legs, support phases, and the four-leg support phases inserted where
//!   consecutive shrunk support polygons are disjoint ([`insert_four_leg_phases`]);
//! * [`polygon`]: support polygons, the edge lines of eq. (6), shrinking by `d`;
//! * [`quintic`]: the polynomial of eq. (3) and the closed forms the QP is built from;
//! * [`qp`]: the QP (eq. 3-7) and its solution, [`ZmpQp::solve`];
//! * [`trajectory`]: the result, [`CogTrajectory`]: CoG state and ZMP at any time, checks.
//! * [`swing`]: swing-foot trajectories between lift-off and touch-down.
//!
//! ```
//! use legwork::zmp::{phases_from_footsteps, CogState, Footstep, Leg, StepTiming, ZmpQp, ZmpSettings};
//! use nalgebra::{Point2, Vector2};
//! let mut feet = [[0.37, 0.33], [0.37, -0.33], [-0.37, 0.33], [-0.37, -0.33]].map(|[x, y]| Point2::new(x, y));
//! let start = feet;
//! let steps: Vec<Footstep> = [Leg::RH, Leg::RF, Leg::LH, Leg::LF]
//!     .into_iter()
//!     .map(|leg| {
//!         feet[leg.index()].x += 0.15;
//!         Footstep { leg, target: feet[leg.index()] }
//!     })
//!     .collect();
//! let timing = StepTiming { initial_stance: 0.6, swing: 0.6, final_stance: 0.6 };
//! let phases = phases_from_footsteps(start, &steps, timing, 0.6);
//! let mut qp = ZmpQp::new(ZmpSettings::default()).unwrap();
//! let plan = qp.solve(&phases, &CogState::at_rest(Vector2::zeros()), Point2::new(0.15, 0.0)).unwrap();
//! // One four-leg phase inserted, at the diagonal switch RF -> LH.
//! assert_eq!(plan.phases().len(), phases.len() + 1);
//! assert!(plan.check_zmp(0.002).worst_margin > -1e-3);
//! ```

#[cfg(test)]
mod coefficient_qp;
pub mod phases;
pub mod polygon;
pub mod qp;
pub mod quintic;
pub mod swing;
pub mod trajectory;

pub use phases::{
    insert_four_leg_phases, phases_from_footsteps, shrunk_supports_disjoint, Footstep, Leg, PhaseOrigin, PlannedPhase,
    StepTiming, SupportPhase,
};
pub use polygon::{ConvexPolygon, EdgeLine, PolygonError};
pub use qp::{ZmpQp, ZmpSettings};
pub use quintic::Quintic;
pub use swing::{SwingError, SwingShape, SwingTrajectory};
pub use trajectory::{CogSpline, CogState, CogTrajectory, SolveInfo, ZmpCheck};

use nalgebra::Point2;

/// Why no CoG trajectory could be planned. Errors about the input name the phase (its index
/// in the given sequence) and the field; infeasibility names the first phase of the plan
/// that cannot be kept ZMP-stable.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ZmpError {
    #[error("ZMP settings: field `{field}`: expected {expected}, got {value}")]
    InvalidSetting { field: &'static str, expected: &'static str, value: f64 },
    #[error("no support phases given")]
    NoPhases,
    #[error("support phase {phase}: field `{field}`: expected {expected}, got {got}")]
    InvalidPhase { phase: usize, field: String, expected: &'static str, got: String },
    #[error("support phase {phase}: foot {leg} is in stance in this phase and the one before it but moved from ({:.4}, {:.4}) to ({:.4}, {:.4}) m", before.x, before.y, after.x, after.y)]
    StanceFootMoved { phase: usize, leg: Leg, before: Point2<f64>, after: Point2<f64> },
    #[error("{phase}: no support polygon: {error}")]
    DegenerateSupport { phase: String, error: PolygonError },
    #[error("{phase}: the support polygon is too small for the stability margin d = {margin} m (its largest inscribed circle has radius {inscribed_radius:.4} m)")]
    SupportTooSmall { phase: String, margin: f64, inscribed_radius: f64 },
    #[error("{field}: expected finite numbers, got {got}")]
    InvalidBoundary { field: &'static str, got: String },
    #[error("the initial ZMP ({:.4}, {:.4}) m lies {distance:.4} m outside the shrunk support polygon of the first phase ({phase}): no trajectory can start there", zmp.x, zmp.y)]
    InitialZmpOutside { zmp: Point2<f64>, distance: f64, phase: String },
    #[error("the goal CoG ({:.4}, {:.4}) m lies {distance:.4} m outside the shrunk support polygon of the last phase ({phase}): the CoG cannot rest there", goal.x, goal.y)]
    GoalOutside { goal: Point2<f64>, distance: f64, phase: String },
    #[error("no ZMP-stable CoG trajectory: phase {index} ({phase}) would need its ZMP up to {violation:.4} m outside its shrunk support polygon ({others} other phases need some slack too); longer phases, a smaller margin or closer footholds may help")]
    Infeasible { index: usize, phase: String, violation: f64, others: usize },
    #[error("the QP solver (Clarabel) stopped with status {status} after {iterations} iterations")]
    Solver { status: String, iterations: u32 },
    #[error("the QP solver (Clarabel) rejected the problem: {0}")]
    SolverSetup(String),
    #[error("time {t} s: expected a finite time in [0, {duration}] s (times after the end give the final state)")]
    InvalidTime { t: f64, duration: f64 },
}
