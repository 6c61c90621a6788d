//! The ZMP QP of Winkler 2015, sec. IV: a spline of quintics (eq. 3), continuous in
//! position, velocity and acceleration at the spline junctions (eq. 4), from the initial
//! state to rest at the goal, minimizing the squared CoG acceleration (eq. 7) subject to the
//! cart-table ZMP (eq. 5) inside the shrunk support polygon (eq. 6) at sample times. Solved
//! with Clarabel (the paper used QuadProg++).
//!
//! Unknowns. Each phase of the plan is cut into `ceil(duration / max_spline_duration)`
//! splines of equal duration. Rather than the splines' coefficients tied together by the
//! equality rows of eq. (4), the unknowns are the CoG states at the junctions between
//! splines, and each spline is the quintic Hermite interpolant of the states at its two ends
//! ([`super::quintic::HERMITE_BASIS`]): neighbouring splines share their junction state, so
//! eq. (4) holds by construction, exactly, and the QP has no equality rows. The first and
//! last junctions are not unknowns: the initial state and the goal at rest are constants,
//! moved to the right-hand side. Half as many unknowns as coefficients (6 per junction
//! against 12 per spline), and the KKT matrix stays banded (a spline couples two
//! neighbouring junctions).
//!
//! Layout. Junction `j` (`1 ..= splines - 1`, between spline `j - 1` and spline `j`) owns
//! unknowns `6 (j - 1) .. 6 j`: `(x, T_r ẋ, T_r^2 ẍ)` then the same for `y`, with `T_r` the
//! `max_spline_duration`, so that all unknowns are lengths of similar size, as the
//! interior-point solver prefers. In Clarabel's form `A x + s = b`, all rows are eq. (6) in
//! a nonnegative cone: for an edge line `p x + q y + r >= 0` at a sample,
//! `-(p x_zmp + q y_zmp) <= r`, the ZMP's dependence on the fixed end states moved into `b`.
//!
//! Lazy rows. Most edges of most support polygons are never approached: on the HyQ crawls,
//! the ZMP comes within 1 cm of only a quarter of the eq. (6) rows (the diagonal edge of
//! each swing triangle) and stays more than 10 cm from all others. The QP is therefore first
//! solved with the edges the ZMP is predicted to approach (an edge whose line is nearer to
//! the centre of the previous or the next phase's shrunk polygon than half the distance to
//! its own phase's centre: the ZMP travels between them), then every left-out row is
//! checked at the solution; edges with a violated row join the QP, which is solved again,
//! until no row is violated. The result is the optimum of the full QP: the optimum of a
//! relaxation that meets all the rows left out is feasible for the full problem, hence its
//! optimum. (A prediction that misses costs one more solve, never a different answer.)
//!
//! ZMP samples: every spline is sampled at `ceil(T / sample_interval)` equal steps, its end
//! included; the first spline of each phase also at its start, so each phase's closed time
//! interval is constrained, both sides of a phase switch included.

use super::phases::{insert_four_leg_phases_into, PlannedPhase, SupportPhase};
use super::quintic::{hermite_row, hermite_squared_acceleration_gram, normalized_from_hermite, zmp_row, Quintic};
use super::trajectory::{CogSpline, CogState, CogTrajectory, SolveInfo};
use super::ZmpError;
use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettings, DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT,
};
use nalgebra::Point2;

/// Unknowns per junction: the state (position, velocity, acceleration) of x, then of y.
const PER_JUNCTION: usize = 6;

/// Price per metre of slack in the elastic QP that names an infeasible phase: large against
/// eq. (7)'s cost of a plan (order 1 m²/s³), so that the slacks are as small as possible.
const ELASTIC_PENALTY: f64 = 1e4;

/// Slacks above this (m) count as a phase that needs one.
const ELASTIC_SLACK_REPORTED: f64 = 1e-6;

/// Eq. (6) rows left out of the QP (see "Lazy rows" in the module docs) count as violated at
/// its solution below this (m): about Clarabel's own feasibility on the rows it has.
const VIOLATION_TOLERANCE: f64 = 1e-9;

/// A plan of a single spline has no unknown (both end states are given): its ZMP samples
/// are checked directly, and count as inside up to this distance (m), Clarabel's own
/// feasibility tolerance being of this order.
const FIXED_PLAN_TOLERANCE: f64 = 1e-9;
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

/// One spline of the layout: spline `s` runs from junction `s` to junction `s + 1`.
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
    /// Clarabel's settings for the plan (see [`ZmpQp::new`]) and for the elastic re-solve.
    solver_settings: DefaultSettings<f64>,
    elastic_solver_settings: DefaultSettings<f64>,
    phases: Vec<PlannedPhase>,
    splines: Vec<SplineSlot>,
    /// Per spline, the Gram matrix of eq. (7) over its two end states in unknown units (see
    /// the module docs): `∫ ẍ^2 dt = u^T K u` for either axis.
    grams: Vec<[[f64; 6]; 6]>,
    /// The given first and last junction states per axis, in unknown units: initial state,
    /// goal at rest.
    fixed_start: [[f64; 3]; 2],
    fixed_end: [[f64; 3]; 2],
    /// Triplets of `A`, generated in increasing row order.
    triplets: Vec<(usize, usize, f64)>,
    a: CscMatrix<f64>,
    p: CscMatrix<f64>,
    q: Vec<f64>,
    b: Vec<f64>,
    /// Solution: junction states, then (elastic mode) slacks.
    solution: Vec<f64>,
    /// Index of phase k's first edge in `candidate_edges`.
    edge_offsets: Vec<usize>,
    /// Per phase and edge of its shrunk polygon: are its eq. (6) rows in the QP?
    candidate_edges: Vec<bool>,
}

/// Outcome of one Clarabel run.
enum Run {
    Solved { iterations: u32, seconds: f64, inequality_rows: usize, reduced_accuracy: bool },
    Infeasible,
}

impl ZmpQp {
    /// Clarabel's settings, measured on HyQ crawls of 8 to 52 steps (benches/zmp.rs):
    ///
    /// * no equilibration: the unknowns are lengths of similar size already (module docs),
    ///   and Ruiz scaling made the interior-point iterations slower to converge (52 steps,
    ///   samples every 0.05 s: 15 iterations against 10), and at tighter tolerances stall at
    ///   reduced accuracy (cost 0.6 % off);
    /// * no static regularization and no iterative refinement: `P` is positive definite
    ///   over the junction states (the Gram matrices' null space, straight-line motion, is
    ///   removed by the given first and last states), so the KKT matrix is quasi-definite as
    ///   it is; refinement took 45 % of the run time. Dynamic regularization stays on as the
    ///   guard against a tiny pivot;
    /// * duality-gap tolerances 1e-9 (default 1e-8): at 1e-8 eq. (7) came out up to 7e-7
    ///   relative above the optimum, at 1e-9 within 2e-7, for one more iteration.
    ///
    /// The elastic re-solve, whose slack columns have no quadratic term, keeps Clarabel's
    /// defaults.
    pub fn new(settings: ZmpSettings) -> Result<Self, ZmpError> {
        settings.validate()?;
        let setup_error = |e: clarabel::solver::DefaultSettingsBuilderError| ZmpError::SolverSetup(e.to_string());
        let solver_settings = DefaultSettingsBuilder::default()
            .verbose(false)
            .equilibrate_enable(false)
            .static_regularization_enable(false)
            .iterative_refinement_enable(false)
            .tol_gap_abs(1e-9)
            .tol_gap_rel(1e-9)
            .build()
            .map_err(setup_error)?;
        let elastic_solver_settings = DefaultSettingsBuilder::default().verbose(false).build().map_err(setup_error)?;
        let empty = || CscMatrix::new(0, 0, vec![0], Vec::new(), Vec::new());
        Ok(Self {
            settings,
            solver_settings,
            elastic_solver_settings,
            phases: Vec::new(),
            splines: Vec::new(),
            grams: Vec::new(),
            fixed_start: [[0.0; 3]; 2],
            fixed_end: [[0.0; 3]; 2],
            triplets: Vec::new(),
            a: empty(),
            p: empty(),
            q: Vec::new(),
            b: Vec::new(),
            solution: Vec::new(),
            edge_offsets: Vec::new(),
            candidate_edges: Vec::new(),
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
        let reference = s.max_spline_duration;
        for axis in 0..2 {
            self.fixed_start[axis] = [
                initial.position[axis],
                initial.velocity[axis] * reference,
                initial.acceleration[axis] * reference * reference,
            ];
            self.fixed_end[axis] = [goal[axis], 0.0, 0.0];
        }

        self.layout_splines();
        let zmp_constraints = self.predict_candidate_edges(initial.zmp(self.phases[0].phase.cog_height, s.gravity), goal);
        let (mut iterations, mut seconds, mut rounds) = (0, 0.0, 0);
        loop {
            rounds += 1;
            let run = self.run(false)?;
            if let Run::Solved { iterations: round_iterations, seconds: round_seconds, .. } = run {
                iterations += round_iterations;
                seconds += round_seconds;
            }
            match run {
                Run::Solved { .. } if self.admit_violated_edges() => continue,
                Run::Solved { inequality_rows, reduced_accuracy, .. } => {
                    return Ok(self.trajectory(SolveInfo {
                        phases: self.phases.len(),
                        splines: self.splines.len(),
                        variables: self.junction_unknowns(),
                        inequality_constraints: inequality_rows,
                        zmp_constraints,
                        rounds,
                        iterations,
                        reduced_accuracy,
                        solver_seconds: seconds,
                        cost: 0.0,
                    }))
                }
                // The relaxation is infeasible, so is the full problem.
                Run::Infeasible => return Err(self.diagnose_infeasibility()?),
            }
        }
    }

    /// The plan from the solved junction states.
    fn trajectory(&self, info: SolveInfo) -> CogTrajectory {
        let s = &self.settings;
        let splines = (0..self.splines.len())
            .map(|index| {
                let slot = &self.splines[index];
                let [x, y] = [0, 1].map(|axis| {
                    let alpha = normalized_from_hermite(&self.boundary_values(index, axis));
                    Quintic::from_normalized(&alpha, slot.duration)
                });
                CogSpline { start_time: slot.start_time, duration: slot.duration, phase: slot.phase, x, y }
            })
            .collect();
        let mut trajectory =
            CogTrajectory { splines, phases: self.phases.clone(), gravity: s.gravity, weights: [s.weight_x, s.weight_y], info };
        trajectory.info.cost = trajectory.cost();
        trajectory
    }

    /// The edges whose rows start in the QP (see "Lazy rows" in the module docs): per phase,
    /// those whose line has the centre (vertex centroid) of the previous or next phase's
    /// shrunk polygon (the initial ZMP, the goal at the ends) nearer than half its own
    /// centre. Returns the number of eq. (6) rows of the full problem.
    fn predict_candidate_edges(&mut self, initial_zmp: Point2<f64>, goal: Point2<f64>) -> usize {
        self.edge_offsets.clear();
        self.candidate_edges.clear();
        let last = self.phases.len() - 1;
        for (k, planned) in self.phases.iter().enumerate() {
            self.edge_offsets.push(self.candidate_edges.len());
            let centre = |k: usize| self.phases[k].shrunk_support.vertex_centroid();
            let previous = if k == 0 { initial_zmp } else { centre(k - 1) };
            let next = if k == last { goal } else { centre(k + 1) };
            let own = centre(k);
            for edge in planned.shrunk_support.edges() {
                let neighbours = edge.value(previous).min(edge.value(next));
                self.candidate_edges.push(neighbours < 0.5 * edge.value(own));
            }
        }
        self.edge_offsets.push(self.candidate_edges.len());
        self.splines
            .iter()
            .map(|slot| {
                let (first, intervals) = self.sample_range(slot);
                (intervals + 1 - first) * (self.edge_offsets[slot.phase + 1] - self.edge_offsets[slot.phase])
            })
            .sum()
    }

    /// Checks every eq. (6) row left out of the QP at its solution; the edges with a row
    /// violated by more than `VIOLATION_TOLERANCE` join the QP. Returns whether any did.
    fn admit_violated_edges(&mut self) -> bool {
        let gravity = self.settings.gravity;
        let mut admitted = false;
        for (s, slot) in self.splines.iter().enumerate() {
            let planned = &self.phases[slot.phase];
            let offset = self.edge_offsets[slot.phase];
            if self.candidate_edges[offset..self.edge_offsets[slot.phase + 1]].iter().all(|&c| c) {
                continue;
            }
            let [x, y] = [0, 1].map(|axis| self.boundary_values(s, axis));
            let (first, intervals) = self.sample_range(slot);
            for j in first..=intervals {
                let zmp = hermite_row(&zmp_row(j as f64 / intervals as f64, slot.duration, planned.phase.cog_height, gravity));
                let dot = |h: &[f64; 6]| zmp.iter().zip(h).map(|(z, v)| z * v).sum::<f64>();
                let point = Point2::new(dot(&x), dot(&y));
                for (e, edge) in planned.shrunk_support.edges().enumerate() {
                    if !self.candidate_edges[offset + e] && edge.value(point) < -VIOLATION_TOLERANCE {
                        self.candidate_edges[offset + e] = true;
                        admitted = true;
                    }
                }
            }
        }
        admitted
    }

    /// The ZMP samples of a spline: `j / intervals` of its duration for `j` in
    /// `first ..= intervals` (module docs).
    fn sample_range(&self, slot: &SplineSlot) -> (usize, usize) {
        let intervals = (slot.duration / self.settings.sample_interval - 1e-9).ceil().max(1.0) as usize;
        (usize::from(!slot.first_in_phase), intervals)
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
    fn diagnose_infeasibility(&mut self) -> Result<ZmpError, ZmpError> {
        match self.run(true)? {
            Run::Solved { .. } => {
                let slacks = &self.solution[self.junction_unknowns()..];
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

    /// Number of junction-state unknowns: 6 per junction between two splines.
    fn junction_unknowns(&self) -> usize {
        PER_JUNCTION * (self.splines.len() - 1)
    }

    /// First unknown of junction `j`'s state, or `None` for the given first and last states.
    fn junction_column(&self, j: usize) -> Option<usize> {
        (j >= 1 && j < self.splines.len()).then(|| PER_JUNCTION * (j - 1))
    }

    /// State of junction `j` along `axis` in unknown units: given, or solved.
    fn junction_state(&self, j: usize, axis: usize) -> [f64; 3] {
        match self.junction_column(j) {
            Some(column) => std::array::from_fn(|c| self.solution[column + 3 * axis + c]),
            None => self.given_state(j, axis),
        }
    }

    /// State of the first or last junction along `axis`: the initial state, the goal at rest.
    fn given_state(&self, j: usize, axis: usize) -> [f64; 3] {
        if j == 0 {
            self.fixed_start[axis]
        } else {
            self.fixed_end[axis]
        }
    }

    /// Factors from unknown units `(x, T_r ẋ, T_r^2 ẍ)` at both ends of spline `s` to its
    /// Hermite boundary values `(x, T ẋ, T^2 ẍ)` (see [`super::quintic::HERMITE_BASIS`]).
    fn hermite_scale(&self, s: usize) -> [f64; 6] {
        let ratio = self.splines[s].duration / self.settings.max_spline_duration;
        let [one, v, a] = [1.0, ratio, ratio * ratio];
        [one, v, a, one, v, a]
    }

    /// The Hermite boundary values of spline `s` along `axis`, from the solved junctions.
    fn boundary_values(&self, s: usize, axis: usize) -> [f64; 6] {
        let (start, end) = (self.junction_state(s, axis), self.junction_state(s + 1, axis));
        let scale = self.hermite_scale(s);
        std::array::from_fn(|i| scale[i] * if i < 3 { start[i] } else { end[i - 3] })
    }

    /// Assembles the QP over the laid-out splines (the candidate edges' rows of eq. 6; elastic:
    /// all rows, with one slack per phase) and runs Clarabel; the solution goes to
    /// `self.solution` (junction states, then slacks).
    fn run(&mut self, elastic: bool) -> Result<Run, ZmpError> {
        let slacks = if elastic { self.phases.len() } else { 0 };
        self.assemble_cost(slacks);
        let inequality_rows = self.assemble_constraints(elastic);
        if self.p.n == 0 {
            // One spline, both end states given: nothing to optimize, only eq. (6) to check.
            self.solution.clear();
            let inside = self.b.iter().all(|&r| r >= -FIXED_PLAN_TOLERANCE);
            return Ok(if inside {
                Run::Solved { iterations: 0, seconds: 0.0, inequality_rows, reduced_accuracy: false }
            } else {
                Run::Infeasible
            });
        }
        let cones = [SupportedConeT::NonnegativeConeT(inequality_rows)];
        let solver_settings = if elastic { &self.elastic_solver_settings } else { &self.solver_settings };
        let mut solver = DefaultSolver::new(&self.p, &self.q, &self.a, &self.b, &cones, solver_settings.clone())
            .map_err(|e| ZmpError::SolverSetup(e.to_string()))?;
        solver.solve();
        let solution = &solver.solution;
        match solution.status {
            SolverStatus::Solved | SolverStatus::AlmostSolved => {
                self.solution.clear();
                self.solution.extend_from_slice(&solution.x);
                Ok(Run::Solved {
                    iterations: solution.iterations,
                    seconds: solution.solve_time,
                    inequality_rows,
                    reduced_accuracy: solution.status == SolverStatus::AlmostSolved,
                })
            }
            SolverStatus::PrimalInfeasible | SolverStatus::AlmostPrimalInfeasible => Ok(Run::Infeasible),
            status => Err(ZmpError::Solver { status: format!("{status:?}"), iterations: solution.iterations }),
        }
    }

    /// Cuts the phases into splines and computes each spline's Gram matrix in unknown units.
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
        self.grams.clear();
        for s in 0..self.splines.len() {
            let gram = hermite_squared_acceleration_gram(self.splines[s].duration);
            let scale = self.hermite_scale(s);
            self.grams.push(std::array::from_fn(|i| std::array::from_fn(|j| scale[i] * gram[i][j] * scale[j])));
        }
    }

    /// `P` of Clarabel's `x^T P x / 2 + q^T x` (upper triangle, CSC) and `q`: eq. (7) is
    /// `sum_s sum_axis w_axis u^T K_s u` over each spline's two end states `u`; the unknown
    /// part gives `P` (`2 w K`), its products with the given first and last states give `q`,
    /// the given part alone a constant left out. Junction `j` is the end of spline `j - 1`
    /// and the start of spline `j`: its own block adds both, its coupling to junction
    /// `j - 1` comes from spline `j - 1`. Built column by column. `slacks` extra columns
    /// (elastic mode) have no quadratic term and the linear price `ELASTIC_PENALTY`.
    fn assemble_cost(&mut self, slacks: usize) {
        let unknowns = self.junction_unknowns();
        let n = unknowns + slacks;
        let p = &mut self.p;
        p.m = n;
        p.n = n;
        p.colptr.clear();
        p.rowval.clear();
        p.nzval.clear();
        p.colptr.push(0);
        self.q.clear();
        self.q.resize(unknowns, 0.0);
        self.q.resize(n, ELASTIC_PENALTY);
        let weights = [self.settings.weight_x, self.settings.weight_y];
        let last = self.splines.len();
        for j in 1..last {
            let (before, after) = (&self.grams[j - 1], &self.grams[j]);
            let column = PER_JUNCTION * (j - 1);
            for (axis, weight) in weights.iter().enumerate() {
                for k in 0..3 {
                    // Coupling to the previous junction (its start-end block of spline j - 1).
                    if j >= 2 {
                        for (c, row) in before.iter().take(3).enumerate() {
                            p.rowval.push(column - PER_JUNCTION + 3 * axis + c);
                            p.nzval.push(2.0 * weight * row[3 + k]);
                        }
                    }
                    for c in 0..=k {
                        p.rowval.push(column + 3 * axis + c);
                        p.nzval.push(2.0 * weight * (before[3 + c][3 + k] + after[c][k]));
                    }
                    p.colptr.push(p.rowval.len());
                    // The given neighbours' share of the cross terms.
                    let q = &mut self.q[column + 3 * axis + k];
                    if j == 1 {
                        let start = &self.fixed_start[axis];
                        *q += 2.0 * weight * (0..3).map(|c| before[c][3 + k] * start[c]).sum::<f64>();
                    }
                    if j + 1 == last {
                        let end = &self.fixed_end[axis];
                        *q += 2.0 * weight * (0..3).map(|c| after[k][3 + c] * end[c]).sum::<f64>();
                    }
                }
            }
        }
        for _ in 0..slacks {
            p.colptr.push(p.rowval.len());
        }
    }

    /// Rows of `A` and `b`: eq. (6) at every sample for the candidate edges, the ZMP written
    /// over the end states of its spline, the given ones moved to `b`. Elastic mode: all
    /// edges, and each row of phase k gets `- sigma_k` (its line moved out by the slack),
    /// and rows `-sigma_k <= 0` follow. Returns the row count.
    fn assemble_constraints(&mut self, elastic: bool) -> usize {
        self.triplets.clear();
        self.b.clear();
        let mut row = 0;
        let gravity = self.settings.gravity;
        let unknowns = self.junction_unknowns();
        for (s, slot) in self.splines.iter().enumerate() {
            let planned = &self.phases[slot.phase];
            let height = planned.phase.cog_height;
            let scale = self.hermite_scale(s);
            let ends = [s, s + 1].map(|j| (self.junction_column(j), [0, 1].map(|axis| self.given_state(j, axis))));
            let (first_sample, intervals) = self.sample_range(slot);
            let candidates = &self.candidate_edges[self.edge_offsets[slot.phase]..self.edge_offsets[slot.phase + 1]];
            for j in first_sample..=intervals {
                // ZMP (eq. 5) = zmp · u over the spline's end states in unknown units.
                let hermite = hermite_row(&zmp_row(j as f64 / intervals as f64, slot.duration, height, gravity));
                let zmp: [f64; 6] = std::array::from_fn(|i| hermite[i] * scale[i]);
                for (edge, _) in planned.shrunk_support.edges().zip(candidates).filter(|(_, &c)| c || elastic) {
                    let mut bound = edge.r;
                    for (side, (column, given)) in ends.iter().enumerate() {
                        for (axis, weight) in [edge.p, edge.q].into_iter().enumerate() {
                            if weight == 0.0 {
                                continue;
                            }
                            let zmp = &zmp[3 * side..3 * side + 3];
                            match column {
                                Some(column) => {
                                    for (c, z) in zmp.iter().enumerate() {
                                        if *z != 0.0 {
                                            self.triplets.push((row, column + 3 * axis + c, -weight * z));
                                        }
                                    }
                                }
                                None => bound += weight * zmp.iter().zip(&given[axis]).map(|(z, u)| z * u).sum::<f64>(),
                            }
                        }
                    }
                    if elastic {
                        self.triplets.push((row, unknowns + slot.phase, -1.0));
                    }
                    self.b.push(bound);
                    row += 1;
                }
            }
        }
        if elastic {
            for k in 0..self.phases.len() {
                self.triplets.push((row, unknowns + k, -1.0));
                self.b.push(0.0);
                row += 1;
            }
        }
        let columns = unknowns + if elastic { self.phases.len() } else { 0 };
        self.triplets_to_csc(row, columns);
        row
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
        // Eq. (4) and boundary states: by construction, up to rounding (measured 1e-13).
        assert!(plan.continuity_error() < 1e-11, "{}", plan.continuity_error());
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

    /// The junction-state QP reaches the optimum of the coefficient form with the equality
    /// rows of eq. (4) (`coefficient_qp`, the former formulation): on crawls where eq. (6)
    /// is active, with a moving initial state and per-phase CoG heights, eq. (7) agrees to
    /// 1e-6 relative and the CoG and ZMP paths to 2e-5 m on a 1 ms grid. (Eq. 7 is flat
    /// along slow deformations of the path: within Clarabel's gap tolerances, the two
    /// solutions differ by up to 4e-6 m in the ZMP, measured.)
    #[test]
    fn optimum_matches_coefficient_form() {
        let moving = CogState {
            position: Vector2::new(0.01, -0.005),
            velocity: Vector2::new(0.05, 0.02),
            acceleration: Vector2::new(0.1, -0.05),
        };
        for (steps, sample_interval, initial, heights) in [
            (8, 0.1, CogState::at_rest(Vector2::zeros()), false),
            (12, 0.05, CogState::at_rest(Vector2::zeros()), false),
            (6, 0.1, moving, true),
        ] {
            let settings = ZmpSettings { sample_interval, ..ZmpSettings::default() };
            let (mut phases, goal) = crawl(steps, 0.15, 0.6);
            if heights {
                for (i, phase) in phases.iter_mut().enumerate() {
                    phase.cog_height = 0.55 + 0.02 * i as f64;
                }
            }
            let plan = ZmpQp::new(settings).unwrap().solve(&phases, &initial, goal).unwrap();
            let reference = crate::zmp::coefficient_qp::solve(plan.phases(), &settings, &initial, goal).unwrap();
            let reference =
                CogTrajectory { splines: reference, phases: plan.phases().to_vec(), gravity: 9.81, weights: [1.0, 1.5], info: plan.info };
            assert!(plan.check_zmp(0.1).worst_margin < 1e-4, "eq. (6) should be active");
            let relative = (plan.cost() - reference.cost()).abs() / reference.cost();
            let (mut position, mut zmp) = (0.0_f64, 0.0_f64);
            for i in 0..=(plan.duration() / 0.001) as usize {
                let t = i as f64 * 0.001;
                position = position.max((plan.state(t).unwrap().position - reference.state(t).unwrap().position).amax());
                zmp = zmp.max((plan.zmp(t).unwrap() - reference.zmp(t).unwrap()).amax());
            }
            eprintln!(
                "{steps} steps, samples {sample_interval} s: cost {:.12} vs {:.12} (relative {relative:.1e}), CoG {position:.1e} m, ZMP {zmp:.1e} m",
                plan.cost(),
                reference.cost()
            );
            assert!(relative < 1e-6 && position < 2e-5 && zmp < 2e-5, "{steps} steps: {relative} {position} {zmp}");
        }
    }

    /// A left-out row that the solution violates joins the QP. One four-leg phase of 0.5 s,
    /// from rest at the centre to rest at 0.15 m forward: the goal is farther from the front
    /// edge (0.17 m) than half the centre's distance (0.16 m), so the first QP has no row of
    /// that edge, yet the braking at the end pushes the ZMP (eq. 5) past it; the second
    /// round includes it, and the result is the coefficient form's optimum with every row.
    #[test]
    fn violated_left_out_rows_join_the_qp() {
        let settings = ZmpSettings::default();
        let phases = [SupportPhase::four_leg(hyq_feet(), 0.5, 0.6)];
        let (initial, goal) = (CogState::at_rest(Vector2::zeros()), Point2::new(0.15, 0.0));
        let plan = ZmpQp::new(settings).unwrap().solve(&phases, &initial, goal).unwrap();
        let info = *plan.info();
        eprintln!("{info:?}");
        assert_eq!(info.rounds, 2);
        assert_eq!((info.inequality_constraints, info.zmp_constraints), (7, 28), "the front edge's 7 samples of 4 edges' 28");
        let at_samples = margin_at_constraint_samples(&plan, &settings);
        assert!(at_samples > -1e-6 && at_samples < 1e-6, "the front edge is active: {at_samples}");
        let reference = crate::zmp::coefficient_qp::solve(plan.phases(), &settings, &initial, goal).unwrap();
        let reference =
            CogTrajectory { splines: reference, phases: plan.phases().to_vec(), gravity: 9.81, weights: [1.0, 1.5], info };
        assert!((plan.cost() - reference.cost()).abs() < 1e-6 * reference.cost(), "{} vs {}", plan.cost(), reference.cost());
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
