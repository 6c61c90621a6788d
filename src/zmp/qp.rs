//! The ZMP QP of Winkler 2015, sec. IV: quintic spline coefficients (eq. 3) minimizing the
//! squared CoG acceleration (eq. 7) subject to continuity at the spline junctions (eq. 4),
//! the initial and goal states, and the cart-table ZMP (eq. 5) inside the shrunk support
//! polygon (eq. 6) at sample times. Solved with Clarabel (the paper used QuadProg++).
//!
//! Layout. Each phase of the plan is cut into `ceil(duration / max_spline_duration)`
//! splines of equal duration; spline `s` owns unknowns `12 s .. 12 s + 12`: the six
//! normalized-time coefficients of `x` then of `y` (see [`super::quintic`]). In Clarabel's
//! form `A x + s = b`, the equality rows (initial state, eq. 4 at every junction, goal at
//! rest) come first in a zero cone, then the rows of eq. (6) in a nonnegative cone: for an
//! edge line `p x + q y + r >= 0` at a sample, `-(p x_zmp + q y_zmp) <= r`.
//!
//! ZMP samples: every spline is sampled at `ceil(T / sample_interval)` equal steps, its end
//! included; the first spline of each phase also at its start, so each phase's closed time
//! interval is constrained, both sides of a phase switch included.

use super::phases::{insert_four_leg_phases_into, PlannedPhase, SupportPhase};
use super::quintic::{acceleration_row, position_row, squared_acceleration_gram, velocity_row, zmp_row, Quintic};
use super::trajectory::{CogSpline, CogState, CogTrajectory, SolveInfo};
use super::ZmpError;
use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettings, DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT,
};
use nalgebra::Point2;

/// Unknowns per spline: six coefficients for x, six for y.
const PER_SPLINE: usize = 12;

/// Price per metre of slack in the elastic QP that names an infeasible phase: large against
/// eq. (7)'s cost of a plan (order 1 m²/s³), so that the slacks are as small as possible.
const ELASTIC_PENALTY: f64 = 1e4;

/// Slacks above this (m) count as a phase that needs one.
const ELASTIC_SLACK_REPORTED: f64 = 1e-6;

/// Parameters of the CoG trajectory optimization.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ZmpSettings {
    /// Stability margin `d` (m) by which support polygons shrink (sec. IV-B; the paper's
    /// experiments: 0.06 m).
    pub stability_margin: f64,
    /// Duration of an inserted four-leg support phase (s).
    pub four_leg_duration: f64,
    /// Longest spline (s): a phase gets `ceil(duration / max_spline_duration)` splines.
    pub max_spline_duration: f64,
    /// Longest time between two ZMP constraint samples (s). Eq. (6) holds at the samples;
    /// between them the ZMP, a quintic in time, can bulge out slightly. Measured on the HyQ
    /// crawls of the tests and benchmark (1 ms grid): at most 1.0e-5 m outside with 0.1 s
    /// (the default: 4 samples per 0.3 s spline), 2.6e-6 m with 0.05 s, 9e-7 m with 0.03 s,
    /// at about 1.0x, 2.0x and 3.0x the solve time.
    pub sample_interval: f64,
    /// Weight `w_x` of eq. (7).
    pub weight_x: f64,
    /// Weight `w_y` of eq. (7); the paper: `w_y = 1.5 w_x`, sideways accelerations being the
    /// more destabilizing.
    pub weight_y: f64,
    /// Gravitational acceleration `g_0` (m/s²) of eq. (5).
    pub gravity: f64,
}

impl Default for ZmpSettings {
    fn default() -> Self {
        Self {
            stability_margin: 0.05,
            four_leg_duration: 0.3,
            max_spline_duration: 0.3,
            sample_interval: 0.1,
            weight_x: 1.0,
            weight_y: 1.5,
            gravity: 9.81,
        }
    }
}

impl ZmpSettings {
    /// Every field finite; the margin non-negative, the rest positive.
    pub fn validate(&self) -> Result<(), ZmpError> {
        let fields = [
            ("stability_margin", self.stability_margin, true),
            ("four_leg_duration", self.four_leg_duration, false),
            ("max_spline_duration", self.max_spline_duration, false),
            ("sample_interval", self.sample_interval, false),
            ("weight_x", self.weight_x, false),
            ("weight_y", self.weight_y, false),
            ("gravity", self.gravity, false),
        ];
        for (field, value, zero_allowed) in fields {
            let ok = value.is_finite() && (value > 0.0 || (zero_allowed && value == 0.0));
            if !ok {
                let expected = if zero_allowed { "a finite number >= 0" } else { "a finite number > 0" };
                return Err(ZmpError::InvalidSetting { field, expected, value });
            }
        }
        Ok(())
    }
}

/// One spline of the layout.
#[derive(Clone, Copy, Debug)]
struct SplineSlot {
    phase: usize,
    start_time: f64,
    duration: f64,
    first_in_phase: bool,
}

/// The QP solver with its reusable buffers: a planner that re-plans keeps one `ZmpQp` and
/// calls [`ZmpQp::solve`] repeatedly; the matrices are rebuilt in the same allocations.
/// (Clarabel copies the problem into its own KKT structures on every solve, as the number
/// of phases changes from plan to plan.)
pub struct ZmpQp {
    settings: ZmpSettings,
    solver_settings: DefaultSettings<f64>,
    phases: Vec<PlannedPhase>,
    splines: Vec<SplineSlot>,
    /// Triplets of `A`, generated in increasing row order.
    triplets: Vec<(usize, usize, f64)>,
    a: CscMatrix<f64>,
    p: CscMatrix<f64>,
    q: Vec<f64>,
    b: Vec<f64>,
    /// Solution, then corrected coefficients.
    alpha: Vec<f64>,
}

/// Outcome of one Clarabel run.
enum Run {
    Solved { iterations: u32, seconds: f64, equality_rows: usize, inequality_rows: usize, reduced_accuracy: bool },
    Infeasible,
}

impl ZmpQp {
    pub fn new(settings: ZmpSettings) -> Result<Self, ZmpError> {
        settings.validate()?;
        let solver_settings = DefaultSettingsBuilder::default()
            .verbose(false)
            .build()
            .map_err(|e| ZmpError::SolverSetup(e.to_string()))?;
        let empty = || CscMatrix::new(0, 0, vec![0], Vec::new(), Vec::new());
        Ok(Self {
            settings,
            solver_settings,
            phases: Vec::new(),
            splines: Vec::new(),
            triplets: Vec::new(),
            a: empty(),
            p: empty(),
            q: Vec::new(),
            b: Vec::new(),
            alpha: Vec::new(),
        })
    }

    pub fn settings(&self) -> &ZmpSettings {
        &self.settings
    }

    /// Plans the CoG trajectory over `phases` from `initial` to rest at `goal`.
    ///
    /// Four-leg support phases are inserted where consecutive shrunk support polygons are
    /// disjoint ([`super::insert_four_leg_phases`]). Errors: invalid input (naming the phase
    /// and field), an initial ZMP or goal outside its shrunk polygon, an infeasible QP (naming
    /// the phase that would need the largest violation of eq. 6, found by an elastic
    /// re-solve), or a solver failure.
    pub fn solve(
        &mut self,
        phases: &[SupportPhase],
        initial: &CogState,
        goal: Point2<f64>,
    ) -> Result<CogTrajectory, ZmpError> {
        if !initial.is_finite() {
            return Err(ZmpError::InvalidBoundary { field: "initial CoG state", got: format!("{initial:?}") });
        }
        if !(goal.x.is_finite() && goal.y.is_finite()) {
            return Err(ZmpError::InvalidBoundary { field: "goal CoG position", got: format!("{goal}") });
        }
        let s = self.settings;
        insert_four_leg_phases_into(phases, s.stability_margin, s.four_leg_duration, &mut self.phases)?;
        self.check_boundaries(initial, goal)?;

        let n = self.phases.len();
        match self.run(initial, goal, false)? {
            Run::Solved { iterations, seconds, equality_rows, inequality_rows, reduced_accuracy } => {
                let correction = self.enforce_equalities(initial, goal);
                let splines: Vec<CogSpline> = self
                    .splines
                    .iter()
                    .enumerate()
                    .map(|(i, slot)| {
                        let alpha = &self.alpha[PER_SPLINE * i..PER_SPLINE * (i + 1)];
                        CogSpline {
                            start_time: slot.start_time,
                            duration: slot.duration,
                            phase: slot.phase,
                            x: Quintic::from_normalized(&alpha[..6], slot.duration),
                            y: Quintic::from_normalized(&alpha[6..], slot.duration),
                        }
                    })
                    .collect();
                let info = SolveInfo {
                    phases: n,
                    splines: splines.len(),
                    variables: PER_SPLINE * splines.len(),
                    equality_constraints: equality_rows,
                    inequality_constraints: inequality_rows,
                    iterations,
                    reduced_accuracy,
                    solver_seconds: seconds,
                    cost: 0.0,
                    continuity_correction: correction,
                };
                let mut trajectory = CogTrajectory {
                    splines,
                    phases: self.phases.clone(),
                    gravity: s.gravity,
                    weights: [s.weight_x, s.weight_y],
                    info,
                };
                trajectory.info.cost = trajectory.cost();
                Ok(trajectory)
            }
            Run::Infeasible => Err(self.diagnose_infeasibility(initial, goal)?),
        }
    }

    /// The initial ZMP must lie in the first shrunk polygon and the goal (where the CoG rests,
    /// so the ZMP equals it) in the last: otherwise no trajectory exists, for a reason that
    /// is better named here than as an infeasible QP.
    fn check_boundaries(&self, initial: &CogState, goal: Point2<f64>) -> Result<(), ZmpError> {
        let (first, last) = (&self.phases[0], &self.phases[self.phases.len() - 1]);
        let zmp = initial.zmp(first.phase.cog_height, self.settings.gravity);
        let margin = first.shrunk_support.margin(zmp);
        if margin < 0.0 {
            return Err(ZmpError::InitialZmpOutside { zmp, distance: -margin, phase: first.to_string() });
        }
        let margin = last.shrunk_support.margin(goal);
        if margin < 0.0 {
            return Err(ZmpError::GoalOutside { goal, distance: -margin, phase: last.to_string() });
        }
        Ok(())
    }

    /// Names the phase that makes the QP infeasible: the elastic QP, in which every phase's
    /// edge lines may be moved out by a slack `sigma_k >= 0` at the price `ELASTIC_PENALTY
    /// sigma_k` (an exact L1 penalty: its solution keeps the slacks at the smallest total
    /// that makes the problem feasible, eq. 7's cost only breaking ties), always has a
    /// solution; the phase with the largest slack is where the footstep sequence asks too
    /// much (too short, too far, too fast).
    fn diagnose_infeasibility(&mut self, initial: &CogState, goal: Point2<f64>) -> Result<ZmpError, ZmpError> {
        match self.run(initial, goal, true)? {
            Run::Solved { .. } => {
                let slacks = &self.alpha[PER_SPLINE * self.splines.len()..];
                let (index, violation) =
                    slacks.iter().copied().enumerate().fold((0, f64::NEG_INFINITY), |best, (k, v)| {
                        if v > best.1 {
                            (k, v)
                        } else {
                            best
                        }
                    });
                if violation <= ELASTIC_SLACK_REPORTED {
                    // The elastic problem needs no slack: the first solve's verdict was numerical.
                    return Err(ZmpError::Solver {
                        status: "PrimalInfeasible, but the elastic problem needs no slack".into(),
                        iterations: 0,
                    });
                }
                let others = slacks.iter().filter(|&&v| v > ELASTIC_SLACK_REPORTED).count() - 1;
                Ok(ZmpError::Infeasible { index, phase: self.phases[index].to_string(), violation, others })
            }
            // Cannot happen (the elastic problem is feasible by construction), but if the
            // solver says so, say that rather than guess.
            Run::Infeasible => {
                Err(ZmpError::Solver { status: "PrimalInfeasible (elastic problem)".into(), iterations: 0 })
            }
        }
    }

    /// Lays out the splines, assembles the QP (elastic: with one slack per phase on eq. 6)
    /// and runs Clarabel; the solution goes to `self.alpha` (coefficients, then slacks).
    fn run(&mut self, initial: &CogState, goal: Point2<f64>, elastic: bool) -> Result<Run, ZmpError> {
        self.layout_splines();
        let slacks = if elastic { self.phases.len() } else { 0 };
        self.assemble_cost(slacks);
        let (equality_rows, inequality_rows) = self.assemble_constraints(initial, goal, elastic);
        let cones = [SupportedConeT::ZeroConeT(equality_rows), SupportedConeT::NonnegativeConeT(inequality_rows)];
        let mut solver = DefaultSolver::new(&self.p, &self.q, &self.a, &self.b, &cones, self.solver_settings.clone())
            .map_err(|e| ZmpError::SolverSetup(e.to_string()))?;
        solver.solve();
        let solution = &solver.solution;
        match solution.status {
            SolverStatus::Solved | SolverStatus::AlmostSolved => {
                self.alpha.clear();
                self.alpha.extend_from_slice(&solution.x);
                Ok(Run::Solved {
                    iterations: solution.iterations,
                    seconds: solution.solve_time,
                    equality_rows,
                    inequality_rows,
                    reduced_accuracy: solution.status == SolverStatus::AlmostSolved,
                })
            }
            SolverStatus::PrimalInfeasible | SolverStatus::AlmostPrimalInfeasible => Ok(Run::Infeasible),
            status => Err(ZmpError::Solver { status: format!("{status:?}"), iterations: solution.iterations }),
        }
    }

    fn layout_splines(&mut self) {
        self.splines.clear();
        for (index, planned) in self.phases.iter().enumerate() {
            let duration = planned.phase.duration;
            // The small slack keeps 0.6 / 0.3 at 2 splines despite rounding.
            let count = ((duration / self.settings.max_spline_duration) - 1e-9).ceil().max(1.0) as usize;
            let piece = duration / count as f64;
            for j in 0..count {
                self.splines.push(SplineSlot {
                    phase: index,
                    start_time: planned.start_time + j as f64 * piece,
                    duration: piece,
                    first_in_phase: j == 0,
                });
            }
        }
    }

    /// `P` of Clarabel's `x^T P x / 2` (upper triangle, CSC): `2 w G(T)` per spline and axis,
    /// so that the objective is eq. (7) exactly. Built column by column. `slacks` extra
    /// columns (elastic mode) have no quadratic term and the linear price `ELASTIC_PENALTY`.
    fn assemble_cost(&mut self, slacks: usize) {
        let n = PER_SPLINE * self.splines.len() + slacks;
        let p = &mut self.p;
        p.m = n;
        p.n = n;
        p.colptr.clear();
        p.rowval.clear();
        p.nzval.clear();
        p.colptr.push(0);
        let weights = [self.settings.weight_x, self.settings.weight_y];
        for (s, slot) in self.splines.iter().enumerate() {
            let gram = squared_acceleration_gram(slot.duration);
            for (axis, weight) in weights.iter().enumerate() {
                let base = PER_SPLINE * s + 6 * axis;
                for k in 0..6 {
                    // G vanishes on the constant and linear coefficients (rows and columns 0, 1).
                    if k >= 2 {
                        for (j, row) in gram.iter().enumerate().take(k + 1).skip(2) {
                            p.rowval.push(base + j);
                            p.nzval.push(2.0 * weight * row[k]);
                        }
                    }
                    p.colptr.push(p.rowval.len());
                }
            }
        }
        for _ in 0..slacks {
            p.colptr.push(p.rowval.len());
        }
        self.q.clear();
        self.q.resize(n - slacks, 0.0);
        self.q.resize(n, ELASTIC_PENALTY);
    }

    /// Rows of `A` and `b`: equalities (initial state, eq. 4, goal), then eq. (6) samples.
    /// Elastic mode: each eq. (6) row of phase k gets `- sigma_k` (its line moved out by the
    /// slack), and rows `-sigma_k <= 0` follow. Returns the two row counts.
    fn assemble_constraints(&mut self, initial: &CogState, goal: Point2<f64>, elastic: bool) -> (usize, usize) {
        self.triplets.clear();
        self.b.clear();
        let mut row = 0;
        let triplets = &mut self.triplets;
        let b = &mut self.b;
        // One row `sum_k left[k] alpha_left[k] - right[k] alpha_right[k] = value` per call.
        let mut push_row = |left: (usize, &[f64; 6]), right: Option<(usize, &[f64; 6])>, value: f64| {
            for (k, &v) in left.1.iter().enumerate() {
                if v != 0.0 {
                    triplets.push((row, left.0 + k, v));
                }
            }
            if let Some((base, coefficients)) = right {
                for (k, &v) in coefficients.iter().enumerate() {
                    if v != 0.0 {
                        triplets.push((row, base + k, -v));
                    }
                }
            }
            b.push(value);
            row += 1;
        };

        let boundary_rows =
            |tau: f64, duration: f64| [position_row(tau), velocity_row(tau, duration), acceleration_row(tau, duration)];
        // Initial state at the start of the first spline.
        let first = &self.splines[0];
        let start_rows = boundary_rows(0.0, first.duration);
        for axis in 0..2 {
            let values = [initial.position[axis], initial.velocity[axis], initial.acceleration[axis]];
            for (rows, value) in start_rows.iter().zip(values) {
                push_row((6 * axis, rows), None, value);
            }
        }
        // Eq. (4): end state of spline s equals start state of spline s + 1.
        for s in 0..self.splines.len() - 1 {
            let end_rows = boundary_rows(1.0, self.splines[s].duration);
            let next_rows = boundary_rows(0.0, self.splines[s + 1].duration);
            for axis in 0..2 {
                for (end, next) in end_rows.iter().zip(&next_rows) {
                    push_row((PER_SPLINE * s + 6 * axis, end), Some((PER_SPLINE * (s + 1) + 6 * axis, next)), 0.0);
                }
            }
        }
        // Goal: at rest at the goal at the end of the last spline.
        let last = self.splines.len() - 1;
        let end_rows = boundary_rows(1.0, self.splines[last].duration);
        for axis in 0..2 {
            for (rows, value) in end_rows.iter().zip([goal[axis], 0.0, 0.0]) {
                push_row((PER_SPLINE * last + 6 * axis, rows), None, value);
            }
        }
        let equality_rows = row;

        // Eq. (6) on the ZMP of eq. (5), per sample and edge line of the shrunk polygon.
        let gravity = self.settings.gravity;
        let slack_column = PER_SPLINE * self.splines.len();
        for (s, slot) in self.splines.iter().enumerate() {
            let planned = &self.phases[slot.phase];
            let height = planned.phase.cog_height;
            let intervals = (slot.duration / self.settings.sample_interval - 1e-9).ceil().max(1.0) as usize;
            let first_sample = if slot.first_in_phase { 0 } else { 1 };
            for j in first_sample..=intervals {
                let zmp = zmp_row(j as f64 / intervals as f64, slot.duration, height, gravity);
                for edge in planned.shrunk_support.edges() {
                    for (axis, weight) in [edge.p, edge.q].into_iter().enumerate() {
                        if weight != 0.0 {
                            for (k, z) in zmp.iter().enumerate() {
                                if *z != 0.0 {
                                    self.triplets.push((row, PER_SPLINE * s + 6 * axis + k, -weight * z));
                                }
                            }
                        }
                    }
                    if elastic {
                        self.triplets.push((row, slack_column + slot.phase, -1.0));
                    }
                    self.b.push(edge.r);
                    row += 1;
                }
            }
        }
        if elastic {
            for k in 0..self.phases.len() {
                self.triplets.push((row, slack_column + k, -1.0));
                self.b.push(0.0);
                row += 1;
            }
        }
        let inequality_rows = row - equality_rows;
        let columns = slack_column + if elastic { self.phases.len() } else { 0 };
        self.triplets_to_csc(row, columns);
        (equality_rows, inequality_rows)
    }

    /// Counting sort of the triplets by column into `A`'s CSC arrays; the triplets come in
    /// increasing row order, so each column's rows end up sorted, as Clarabel requires.
    fn triplets_to_csc(&mut self, rows: usize, n: usize) {
        let a = &mut self.a;
        a.m = rows;
        a.n = n;
        a.colptr.clear();
        a.colptr.resize(n + 1, 0);
        for &(_, col, _) in &self.triplets {
            a.colptr[col + 1] += 1;
        }
        for c in 0..n {
            a.colptr[c + 1] += a.colptr[c];
        }
        let nnz = self.triplets.len();
        a.rowval.clear();
        a.rowval.resize(nnz, 0);
        a.nzval.clear();
        a.nzval.resize(nnz, 0.0);
        // `next[c]` = where column c's next entry goes; reuse colptr shifted by one column.
        for &(row, col, value) in &self.triplets {
            let slot = a.colptr[col];
            a.rowval[slot] = row;
            a.nzval[slot] = value;
            a.colptr[col] += 1;
        }
        // Each colptr[c] now holds the end of column c = start of column c + 1: shift back.
        for c in (1..=n).rev() {
            a.colptr[c] = a.colptr[c - 1];
        }
        a.colptr[0] = 0;
    }

    /// Re-imposes the equality rows exactly on the interior-point solution, which meets them
    /// only to the solver tolerance: a forward pass sets each spline's first three
    /// coefficients from the initial state or the previous spline's end (eq. 4), and the last
    /// spline's top three from the goal at rest. Returns the largest change (m); the ZMP
    /// moves by a comparable amount.
    fn enforce_equalities(&mut self, initial: &CogState, goal: Point2<f64>) -> f64 {
        let mut largest: f64 = 0.0;
        let mut set = |value: &mut f64, new: f64| {
            largest = largest.max((*value - new).abs());
            *value = new;
        };
        for s in 0..self.splines.len() {
            let duration = self.splines[s].duration;
            for axis in 0..2 {
                // Start state (position, velocity, acceleration) of this spline.
                let (x, v, a) = if s == 0 {
                    (initial.position[axis], initial.velocity[axis], initial.acceleration[axis])
                } else {
                    let previous = &self.alpha[PER_SPLINE * (s - 1) + 6 * axis..][..6];
                    let t = self.splines[s - 1].duration;
                    let dot = |row: [f64; 6]| row.iter().zip(previous).map(|(r, c)| r * c).sum::<f64>();
                    (dot(position_row(1.0)), dot(velocity_row(1.0, t)), dot(acceleration_row(1.0, t)))
                };
                let alpha = &mut self.alpha[PER_SPLINE * s + 6 * axis..][..6];
                set(&mut alpha[0], x);
                set(&mut alpha[1], v * duration);
                set(&mut alpha[2], 0.5 * a * duration * duration);
            }
        }
        let last = self.splines.len() - 1;
        for axis in 0..2 {
            let alpha = &mut self.alpha[PER_SPLINE * last + 6 * axis..][..6];
            // End at rest at the goal: with R_p, R_v, R_a what the first three coefficients
            // leave of x(1), x'(1), x''(1) (derivatives in tau), the top three solve
            // [1 1 1; 3 4 5; 6 12 20] (a3, a4, a5) = (R_p, R_v, R_a).
            let r_p = goal[axis] - (alpha[0] + alpha[1] + alpha[2]);
            let r_v = -(alpha[1] + 2.0 * alpha[2]);
            let r_a = -2.0 * alpha[2];
            set(&mut alpha[3], 10.0 * r_p - 4.0 * r_v + 0.5 * r_a);
            set(&mut alpha[4], -15.0 * r_p + 7.0 * r_v - r_a);
            set(&mut alpha[5], 6.0 * r_p - 3.0 * r_v + 0.5 * r_a);
        }
        largest
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::zmp::phases::{phases_from_footsteps, Footstep, Leg, PhaseOrigin, StepTiming};
    use crate::zmp::quintic::GAUSS_LEGENDRE_8;
    use nalgebra::{DMatrix, DVector, Vector2};

    /// HyQ's nominal stance: feet at (±0.37, ±0.33) m around the body.
    fn hyq_feet() -> [Point2<f64>; 4] {
        [Point2::new(0.37, 0.33), Point2::new(0.37, -0.33), Point2::new(-0.37, 0.33), Point2::new(-0.37, -0.33)]
    }

    /// A crawl of `steps` steps of `length` m in the order RH, RF, LH, LF, and its goal (the
    /// centre of the final feet).
    fn crawl(steps: usize, length: f64, swing: f64) -> (Vec<SupportPhase>, Point2<f64>) {
        let order = [Leg::RH, Leg::RF, Leg::LH, Leg::LF];
        let mut feet = hyq_feet();
        let footsteps: Vec<Footstep> = (0..steps)
            .map(|i| {
                let leg = order[i % 4];
                feet[leg.index()].x += length;
                Footstep { leg, target: feet[leg.index()] }
            })
            .collect();
        let centre = feet.iter().fold(Vector2::zeros(), |sum, f| sum + f.coords) / 4.0;
        let timing = StepTiming { initial_stance: 0.6, swing, final_stance: 0.6 };
        (phases_from_footsteps(hyq_feet(), &footsteps, timing, 0.6), Point2::from(centre))
    }

    /// Smallest eq. (6) margin at the constraint samples themselves.
    fn margin_at_constraint_samples(plan: &CogTrajectory, settings: &ZmpSettings) -> f64 {
        let mut worst = f64::INFINITY;
        for spline in plan.splines() {
            let phase = &plan.phases()[spline.phase];
            let n = (spline.duration / settings.sample_interval - 1e-9).ceil().max(1.0) as usize;
            for j in 0..=n {
                let zmp =
                    spline.state(spline.duration * j as f64 / n as f64).zmp(phase.phase.cog_height, settings.gravity);
                worst = worst.min(phase.shrunk_support.margin(zmp));
            }
        }
        worst
    }

    /// Issue 5's HyQ crawl: 8 steps of 0.15 m, swing order RH, RF, LH, LF, 0.6 s phases, CoG
    /// 0.6 m high, margin 5 cm. Solves; four-leg phases only at the three diagonal switches;
    /// eq. (4) and the boundary states hold to 1e-9; the ZMP stays in the shrunk polygons at
    /// every constraint sample (to the solver tolerance) and on a 1 ms grid (to the
    /// tolerance between samples stated in the module docs).
    #[test]
    fn hyq_crawl_8_steps_is_zmp_stable_and_continuous() {
        let settings = ZmpSettings::default();
        let (phases, goal) = crawl(8, 0.15, 0.6);
        let mut qp = ZmpQp::new(settings).unwrap();
        let initial = CogState::at_rest(Vector2::zeros());
        let plan = qp.solve(&phases, &initial, goal).unwrap();
        let inserted: Vec<_> = plan
            .phases()
            .iter()
            .filter(|p| matches!(p.origin, PhaseOrigin::Inserted { .. }))
            .map(|p| p.origin)
            .collect();
        assert_eq!(
            inserted,
            [3, 5, 7].map(|before| PhaseOrigin::Inserted { before }),
            "four-leg phases at RF -> LH, LF -> RH, RF -> LH"
        );
        let info = *plan.info();
        eprintln!("crawl 8 steps: {info:?}");
        // Eq. (4) and boundary states.
        assert!(plan.continuity_error() < 1e-9, "{}", plan.continuity_error());
        assert!(info.continuity_correction < 1e-6, "the solver itself met eq. (4): {}", info.continuity_correction);
        let start = plan.state(0.0).unwrap();
        assert!((start.position - initial.position).amax() < 1e-12 && start.velocity.amax() < 1e-12);
        let end = plan.state(plan.duration()).unwrap();
        assert!((end.position - goal.coords).amax() < 1e-9, "{:?}", end);
        assert!(end.velocity.amax() < 1e-9 && end.acceleration.amax() < 1e-9, "{end:?}");
        assert_eq!(plan.state(plan.duration() + 1.0).unwrap(), end);
        // Eq. (6) at the constraint samples, and binding somewhere (else the test proves little).
        let at_samples = margin_at_constraint_samples(&plan, &settings);
        assert!(at_samples > -1e-6, "{at_samples}");
        assert!(at_samples < 1e-4, "eq. (6) should be active: {at_samples}");
        // Between samples, on a 1 ms grid.
        let dense = plan.check_zmp(0.001);
        eprintln!("crawl 8 steps: samples {at_samples:.3e}, dense {dense:?}");
        assert!(dense.worst_margin > -DENSE_TOLERANCE, "{dense:?}");
        // Denser samples shrink the excursion between them (measured: 1.0e-5 m at 0.1 s,
        // 9e-7 m at 0.03 s).
        let fine = ZmpSettings { sample_interval: 0.03, ..settings };
        let fine_plan = ZmpQp::new(fine).unwrap().solve(&phases, &initial, goal).unwrap();
        let fine_dense = fine_plan.check_zmp(0.001);
        eprintln!("crawl 8 steps, 30 ms samples: dense {fine_dense:?}");
        assert!(fine_dense.worst_margin > -DENSE_TOLERANCE / 20.0, "{fine_dense:?}");
    }

    /// How far (m) the ZMP may leave the shrunk polygon between the default 0.1 s constraint
    /// samples: 0.1 mm, ten times the excursion measured on the crawls (1.0e-5 m), 0.2 % of
    /// the 5 cm margin.
    const DENSE_TOLERANCE: f64 = 1e-4;

    /// Eq. (7) by hand: one phase in one spline, the six boundary conditions fix the rest-to-
    /// rest quintic `x = Δ (10 tau^3 - 15 tau^4 + 6 tau^5)`, whose `∫ ẍ^2 dt = 120 Δ^2 /
    /// (7 T^3)` (see quintic.rs); with `w = (1, 1.5)`: `J = 120 (Δx^2 + 1.5 Δy^2) / (7 T^3)`.
    #[test]
    fn single_spline_cost_matches_hand_computation() {
        let settings = ZmpSettings { max_spline_duration: 1.0, ..ZmpSettings::default() };
        let phases = [SupportPhase::four_leg(hyq_feet(), 1.0, 0.6)];
        let (dx, dy) = (0.1, -0.08);
        let plan = ZmpQp::new(settings)
            .unwrap()
            .solve(&phases, &CogState::at_rest(Vector2::zeros()), Point2::new(dx, dy))
            .unwrap();
        assert_eq!(plan.splines().len(), 1);
        let expected = 120.0 * (dx * dx + 1.5 * dy * dy) / 7.0;
        assert!((plan.cost() - expected).abs() < 1e-12 * expected.max(1.0), "{} vs {expected}", plan.cost());
        assert_eq!(plan.info().cost, plan.cost());
        let mid = plan.state(0.5).unwrap();
        assert!((mid.position - Vector2::new(dx, dy) * 0.5).amax() < 1e-9, "{mid:?}");
    }

    /// With several splines and no active ZMP constraint, the QP's optimum equals a dense KKT
    /// solve (nalgebra LU) of min eq. (7) subject to the equality rows, built here from the
    /// definition (boundary states and eq. 4 written out with the polynomial's derivatives).
    #[test]
    fn unconstrained_optimum_matches_dense_kkt_reference() {
        let settings = ZmpSettings { max_spline_duration: 0.3, ..ZmpSettings::default() };
        let duration = 1.2;
        let phases = [SupportPhase::four_leg(hyq_feet(), duration, 0.6)];
        let initial = CogState {
            position: Vector2::new(0.02, -0.01),
            velocity: Vector2::new(0.1, 0.05),
            acceleration: Vector2::new(-0.2, 0.1),
        };
        let goal = Point2::new(0.12, 0.04);
        let plan = ZmpQp::new(settings).unwrap().solve(&phases, &initial, goal).unwrap();
        assert!(plan.check_zmp(0.001).worst_margin > 0.05, "the ZMP constraints should be inactive");
        let splines = plan.splines().len();
        assert_eq!(splines, 4);
        let piece = duration / splines as f64;
        // Per axis: unknowns c (paper form, 6 per spline); cost c^T H c; constraints E c = f.
        let n = 6 * splines;
        let mut reference_cost = 0.0;
        for (axis, weight) in [(0, 1.0), (1, 1.5)] {
            let mut h = DMatrix::zeros(n, n);
            for s in 0..splines {
                for j in 2..6 {
                    for k in 2..6 {
                        let power = (j + k - 3) as i32;
                        h[(6 * s + j, 6 * s + k)] =
                            weight * ((j * (j - 1) * k * (k - 1)) as f64) * piece.powi(power) / power as f64;
                    }
                }
            }
            // Derivative `order` of t^k at t.
            let derivative = |k: usize, order: usize, t: f64| -> f64 {
                if k < order {
                    return 0.0;
                }
                let factor: usize = (k - order + 1..=k).product();
                factor as f64 * t.powi((k - order) as i32)
            };
            let rows = 6 + 3 * (splines - 1);
            let mut e = DMatrix::zeros(rows, n);
            let mut f = DVector::zeros(rows);
            let start = [initial.position[axis], initial.velocity[axis], initial.acceleration[axis]];
            for order in 0..3 {
                e[(order, order)] = derivative(order, order, 0.0);
                f[order] = start[order];
                for k in 0..6 {
                    e[(3 + order, 6 * (splines - 1) + k)] = derivative(k, order, piece);
                }
                f[3 + order] = if order == 0 { goal[axis] } else { 0.0 };
                for s in 0..splines - 1 {
                    let r = 6 + 3 * s + order;
                    for k in 0..6 {
                        e[(r, 6 * s + k)] = derivative(k, order, piece);
                        e[(r, 6 * (s + 1) + k)] -= derivative(k, order, 0.0);
                    }
                }
            }
            let mut kkt = DMatrix::zeros(n + rows, n + rows);
            kkt.view_mut((0, 0), (n, n)).copy_from(&(&h * 2.0));
            kkt.view_mut((0, n), (n, rows)).copy_from(&e.transpose());
            kkt.view_mut((n, 0), (rows, n)).copy_from(&e);
            let mut rhs = DVector::zeros(n + rows);
            rhs.rows_mut(n, rows).copy_from(&f);
            let solution = kkt.lu().solve(&rhs).expect("KKT system nonsingular");
            let c = solution.rows(0, n);
            reference_cost += (c.transpose() * &h * c)[(0, 0)];
            for (s, spline) in plan.splines().iter().enumerate() {
                let ours = if axis == 0 { spline.x } else { spline.y };
                for k in 0..6 {
                    let scale = piece.powi(-(k as i32));
                    assert!(
                        (ours.coefficients[k] - c[6 * s + k]).abs() < 1e-6 * scale,
                        "axis {axis} spline {s} c{k}: {} vs {}",
                        ours.coefficients[k],
                        c[6 * s + k]
                    );
                }
            }
        }
        assert!((plan.cost() - reference_cost).abs() < 1e-7 * reference_cost, "{} vs {reference_cost}", plan.cost());
    }

    /// The closed-form cost of a solved crawl equals Gauss-Legendre quadrature of eq. (7).
    #[test]
    fn crawl_cost_matches_quadrature() {
        let (phases, goal) = crawl(4, 0.15, 0.6);
        let plan = ZmpQp::new(ZmpSettings::default())
            .unwrap()
            .solve(&phases, &CogState::at_rest(Vector2::zeros()), goal)
            .unwrap();
        let quadrature: f64 = plan
            .splines()
            .iter()
            .map(|s| {
                GAUSS_LEGENDRE_8
                    .iter()
                    .map(|(node, weight)| {
                        let a = s.state(0.5 * s.duration * (node + 1.0)).acceleration;
                        0.5 * s.duration * weight * (a.x * a.x + 1.5 * a.y * a.y)
                    })
                    .sum::<f64>()
            })
            .sum();
        assert!((plan.cost() - quadrature).abs() < 1e-10 * quadrature, "{} vs {quadrature}", plan.cost());
    }

    /// Different CoG heights per phase: each phase's ZMP (eq. 5 with its own height) stays in
    /// its shrunk polygon, including both sides of every switch.
    #[test]
    fn per_phase_cog_heights() {
        let (mut phases, goal) = crawl(4, 0.15, 0.6);
        for (i, phase) in phases.iter_mut().enumerate() {
            phase.cog_height = 0.5 + 0.03 * i as f64;
        }
        let plan = ZmpQp::new(ZmpSettings::default())
            .unwrap()
            .solve(&phases, &CogState::at_rest(Vector2::zeros()), goal)
            .unwrap();
        let dense = plan.check_zmp(0.001);
        assert!(dense.worst_margin > -DENSE_TOLERANCE, "{dense:?}");
        assert!(plan.continuity_error() < 1e-9);
    }

    /// One ZmpQp re-used for problems of different sizes gives the same plans as fresh ones.
    #[test]
    fn reused_workspace_gives_identical_plans() {
        let mut qp = ZmpQp::new(ZmpSettings::default()).unwrap();
        let initial = CogState::at_rest(Vector2::zeros());
        let (long, long_goal) = crawl(8, 0.15, 0.6);
        let (short, short_goal) = crawl(3, 0.1, 0.7);
        let first = qp.solve(&long, &initial, long_goal).unwrap();
        let short_plan = qp.solve(&short, &initial, short_goal).unwrap();
        let again = qp.solve(&long, &initial, long_goal).unwrap();
        assert_eq!(first.splines(), again.splines());
        let fresh = ZmpQp::new(ZmpSettings::default()).unwrap().solve(&short, &initial, short_goal).unwrap();
        assert_eq!(short_plan.splines(), fresh.splines());
    }

    /// An infeasible plan names the phase. One four-leg phase, a goal too far for its
    /// duration: the elastic slack is the smallest amount the margin must shrink by, checked
    /// by re-solving with the margin just below and just above `d - slack`.
    #[test]
    fn infeasible_plan_names_the_phase_and_the_missing_margin() {
        let settings = ZmpSettings { stability_margin: 0.08, ..ZmpSettings::default() };
        let phases = [SupportPhase::four_leg(hyq_feet(), 0.5, 0.6)];
        let (initial, goal) = (CogState::at_rest(Vector2::zeros()), Point2::new(0.17, 0.0));
        let error = ZmpQp::new(settings).unwrap().solve(&phases, &initial, goal).unwrap_err();
        let ZmpError::Infeasible { index, violation, others, .. } = error.clone() else {
            panic!("expected Infeasible, got {error}");
        };
        eprintln!("{error}");
        assert_eq!((index, others), (0, 0));
        assert!(error.to_string().contains("phase 0 (four-leg support, given phase 0"), "{error}");
        assert!(violation > 1e-3 && violation < 0.08, "{violation}");
        let with_margin = |margin: f64| {
            ZmpQp::new(ZmpSettings { stability_margin: margin, ..settings }).unwrap().solve(&phases, &initial, goal)
        };
        assert!(with_margin(0.08 - violation - 1e-4).is_ok());
        assert!(matches!(with_margin(0.08 - violation + 1e-4), Err(ZmpError::Infeasible { .. })));
    }

    #[test]
    fn boundary_errors_name_the_problem() {
        let mut qp = ZmpQp::new(ZmpSettings::default()).unwrap();
        let phases = [SupportPhase::swing(hyq_feet(), Leg::RH, 0.6, 0.6)];
        // At rest on the diagonal of the RH triangle: outside by the margin.
        let e = qp.solve(&phases, &CogState::at_rest(Vector2::zeros()), Point2::new(0.2, 0.1)).unwrap_err();
        assert!(matches!(e, ZmpError::InitialZmpOutside { distance, .. } if (distance - 0.05).abs() < 1e-12), "{e}");
        let e = qp
            .solve(&phases, &CogState::at_rest(Vector2::new(0.2, 0.1)), Point2::new(-0.3, -0.3))
            .unwrap_err()
            .to_string();
        assert!(e.contains("goal CoG (-0.3000, -0.3000)") && e.contains("swing RH"), "{e}");
        let e = qp.solve(&phases, &CogState::at_rest(Vector2::new(f64::NAN, 0.0)), Point2::origin()).unwrap_err();
        assert!(e.to_string().contains("initial CoG state"), "{e}");
        let e = ZmpQp::new(ZmpSettings { sample_interval: 0.0, ..ZmpSettings::default() }).err().unwrap();
        assert!(e.to_string().contains("`sample_interval`"), "{e}");
        let plan = ZmpQp::new(ZmpSettings::default())
            .unwrap()
            .solve(
                &[SupportPhase::four_leg(hyq_feet(), 0.5, 0.6)],
                &CogState::at_rest(Vector2::zeros()),
                Point2::origin(),
            )
            .unwrap();
        assert!(matches!(plan.state(-0.1), Err(ZmpError::InvalidTime { .. })));
        assert!(matches!(plan.zmp(f64::NAN), Err(ZmpError::InvalidTime { .. })));
    }
}
