//! The whole-body optimal-control problem of Neunert 2017 for a legged robot: the
//! simulator's discrete contact dynamics ([`crate::sim::ContactModelWorkspace`], one source
//! of truth with simulation), joint torques as inputs, and the cost of eq. (4) with the
//! Gaussian-windowed waypoints of eq. (5):
//!
//! ```text
//! J = xb(t_f)^T H xb(t_f) + sum_k dt [ xb_k^T Q xb_k + ub_k^T R ub_k + W(x_k, t_k) ]
//! W(x, t) = sum_p xh_p^T W_p xh_p sqrt(rho_p / (2 pi)) exp(-rho_p / 2 (t - t_p)^2)
//! ```
//!
//! `xb` is the deviation of the state from the desired state in intuitive coordinates
//! ([`StateDeviation`]): base position in the world, base orientation error
//! `log(R*^T R)` (roll, pitch, yaw about the desired base axes for small errors), joint
//! angles, base linear and angular velocity in the base frame (as the paper's eq. 7), joint
//! velocities. No contact, gait or timing appears anywhere: contacts emerge from the
//! dynamics. Derivatives are Gauss-Newton (`l_xx = 2 dt E^T Q E`, `E = d xb / d dx`, exact).
//!
//! Beyond the paper, a task may add a running cost on joint positions past their limits
//! ([`JointLimitCost`]) and be solved by horizon continuation ([`ContinuationSpec`]: shorter
//! versions of the task first, each warm-starting the next).

mod constraints;
mod continuation;
mod deviation;
mod exploration;
mod limit_cost;
mod metrics;
mod overrides;
mod physical_gains;
mod receding;
mod run;
mod target;
mod task;

pub use constraints::{relaxed_barrier, tangential_demand, FeasibilityConstraints, FeasibilitySettings, FrictionForm, FeasibilitySettingsError, KnotContacts, Violation};
pub use continuation::ContinuationSpec;
pub use deviation::StateDeviation;
pub use exploration::{explore, start_seed, survivors, Exploration, ExplorationSpec, PerturbedStanding, SamplingSpec, StartReport, MAX_STARTS};
pub use limit_cost::{JointLimitCost, JointLimitCostSpec};
pub use metrics::{joint_limit_excess, Feasibility, LimitExcess, MotionMetrics, Snapshot, FRICTION_MARGIN, SLIDE_SPEED};
pub use physical_gains::{physical_gain, PhysicalGainWorkspace};
pub use receding::{CoarseTail, KnotGrid, PlanValue, RecedingHorizon, ReferenceMotion};

pub use run::{solution_trajectory, solve_task, ExplorationReport, Rerun, SingleStartFinal, SlqPolicyController, SolveError, SolveOptions, SolveProgress, StageReport, TaskRun};
pub use target::{all_met, CheckTime, Target, TargetCoordinate, TargetResult, TargetSpec, TargetTime};
pub use task::{fewest_substeps, Coordinate, DesiredSpec, InputSpec, JointValues, JointWeights, TaskError, TaskSpec, WaypointSpec, WeightSpec, EMBEDDED_TASKS};

use crate::control::JointPd;
use crate::model::Model;
use crate::sim::{AnchorStepDerivatives, ContactModelWorkspace, JointLimitParams, StepDerivatives, SubstepProduct, ANCHOR_DIM};
use crate::slq::{KnotDerivatives, Policy, Problem};
use crate::terrain::Terrain;
use nalgebra::{DMatrix, DVector, Vector3};

/// A state of the optimization: configuration, velocity and the contact anchors (hidden
/// states, Neunert 2017 sec. III-B).
#[derive(Debug, PartialEq)]
pub struct RobotState {
    pub q: DVector<f64>,
    pub v: DVector<f64>,
    pub anchors: Vec<Option<Vector3<f64>>>,
}

impl Clone for RobotState {
    fn clone(&self) -> Self {
        Self { q: self.q.clone(), v: self.v.clone(), anchors: self.anchors.clone() }
    }
    /// Copies into the existing buffers (no allocation when the sizes match): the solver's
    /// line search and rollouts reuse their states.
    fn clone_from(&mut self, source: &Self) {
        if self.q.len() == source.q.len() && self.v.len() == source.v.len() {
            self.q.copy_from(&source.q);
            self.v.copy_from(&source.v);
        } else {
            self.q = source.q.clone();
            self.v = source.v.clone();
        }
        self.anchors.clone_from(&source.anchors);
    }
}

/// The robot standing still on `terrain`: the `standing` pose put on the ground and
/// simulated for `seconds` with the standing controller (and the robot's contact model), so
/// that an optimization starts from rest (its first knots do not fall or bounce).
pub fn settled_stance(model: &Model, terrain: &dyn Terrain, seconds: f64) -> Result<RobotState, crate::sim::SimError> {
    use crate::sim::{standing_on_ground, SimConfig, Simulator};
    let q0 = standing_on_ground(model, terrain, 0.0)?;
    let config = SimConfig::default();
    let mut sim = Simulator::new(model, terrain, config.clone(), q0, None)?;
    let mut stand = JointPd::standing(model, config.control_dt).map_err(|source| crate::sim::SimError::Controller { t: 0.0, source })?;
    let steps = (seconds / config.physics_dt).round() as usize;
    for _ in 0..steps {
        sim.step(&mut stand)?;
    }
    let s = sim.state();
    Ok(RobotState { q: s.q.clone(), v: s.v.clone(), anchors: s.anchors.clone() })
}

/// A quadratic cost on the deviation from a desired state, `xb^T diag(weights) xb`, plus
/// foot position targets `sum_f (p_f - p_f*)^T diag(w_f) (p_f - p_f*)`.
#[derive(Clone, Debug, PartialEq)]
pub struct StateCost {
    /// The desired configuration (`nq`) and velocity (`nv`).
    pub q: DVector<f64>,
    pub v: DVector<f64>,
    /// Diagonal weights on the deviation coordinates (`2 nv`, see [`StateDeviation`]).
    pub weights: DVector<f64>,
    /// Targets for feet (world positions of the foot-sphere centres).
    pub feet: Vec<FootTarget>,
}

/// A desired world position of a foot (index into `Model::feet`), weighted per axis.
#[derive(Clone, Debug, PartialEq)]
pub struct FootTarget {
    /// Index into `Model::feet`.
    pub foot: usize,
    pub position: Vector3<f64>,
    pub weights: Vector3<f64>,
}

/// A waypoint of eq. (5): a state cost active around `time`, with a Gaussian window of
/// precision `rho` (1/s^2; its standard deviation is `1/sqrt(rho)`).
#[derive(Clone, Debug, PartialEq)]
pub struct Waypoint {
    pub time: f64,
    pub rho: f64,
    pub cost: StateCost,
}

impl Waypoint {
    /// The window `sqrt(rho / 2 pi) exp(-rho / 2 (t - t_p)^2)` (integrates to one over time).
    pub fn window(&self, t: f64) -> f64 {
        (self.rho / (2.0 * std::f64::consts::PI)).sqrt() * (-0.5 * self.rho * (t - self.time).powi(2)).exp()
    }
}

/// The problem: robot (with its contact model, [`Model::contact`]), terrain, horizon, costs.
pub struct WholeBodyProblem<'a> {
    pub model: &'a Model,
    pub terrain: &'a dyn Terrain,
    /// The joints' mechanical stops ([`crate::sim::SimConfig::joint_limits`]; `None`: off),
    /// in the dynamics and their linearization as in the simulator.
    pub joint_limits: Option<JointLimitParams>,
    /// Time between knots (s): the input is held over it (zero-order hold).
    pub dt: f64,
    /// Integration steps per knot interval: the dynamics integrate `substeps` steps of
    /// `dt / substeps` with the knot's input held, as the simulator does with its physics
    /// step inside a control period. `dt / substeps` may not exceed the contact model's
    /// stable step (`model.contact.max_step`).
    pub substeps: usize,
    /// Number of transitions (a receding window's most: it may use fewer,
    /// [`Self::active_knots`]).
    pub knots: usize,
    /// A receding window's coarser knots after its first ones (`None`: every knot `dt`;
    /// [`Self::knot_dt`], [`Self::knot_time`]).
    pub tail: Option<CoarseTail>,
    pub initial: RobotState,
    /// `Q` with the desired state of the running cost.
    pub running: StateCost,
    /// `H` with the desired final state.
    pub terminal: StateCost,
    /// `R` (diagonal, `nv - 6`) and the desired torques.
    pub input_weights: DVector<f64>,
    pub input_desired: DVector<f64>,
    /// Joint effort limits (N m, `nv - 6`; infinite = none): the box of the inputs
    /// ([`Problem::input_bounds`]), so that SLQ's backward pass and rollouts keep every
    /// knot's torques within them (Tassa 2014's control limits). The simulator clips torques
    /// to them, and so do the optimizer's dynamics (one source of truth), which only matters
    /// for an input handed in from outside the box: it acts as the limit, its column of `B`
    /// zero.
    pub effort_limits: DVector<f64>,
    pub waypoints: Vec<Waypoint>,
    /// A running cost on joint positions outside their limits (`None`: none).
    pub joint_limit_cost: Option<JointLimitCost>,
    /// The feasibility constraints on every knot's state (friction with a margin,
    /// penetration, joint limits and speeds, [`FeasibilityConstraints`]). Every task file's
    /// problem has them; `None` only for problems built in code.
    pub feasibility: Option<FeasibilityConstraints>,
    /// Linearize with the contact anchors as states (`dx = [dq; dv; da]`, three coordinates
    /// per foot, [`crate::sim::AnchorStepDerivatives`]) rather than as hidden states held
    /// over each step.
    pub anchor_states: bool,
    /// How a knot of several substeps is linearized ([`KnotLinearization`]).
    pub linearization: KnotLinearization,
    /// The problem as a receding-horizon controller's window (`None`: a plan from `t = 0`):
    /// knot times from the window's start, the final cost at the task's end, a reference
    /// motion's tracking cost ([`RecedingHorizon`]).
    pub receding: Option<RecedingHorizon>,
}

/// How [`WholeBodyProblem`] linearizes a knot integrated in several substeps.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum KnotLinearization {
    /// Every substep's exact `A_i`, `B_i`, chained: `A = A_n .. A_1`, `B = sum_i A_n .. A_{i+1} B_i`
    /// (the plans').
    #[default]
    EverySubstep,
    /// The first substep's `A_1`, `B_1` held over the knot (`A = A_1^n`,
    /// `B = sum_i A_1^i B_1`): one derivative evaluation per knot instead of `n`, for a
    /// receding horizon's coarse knots ([`crate::mpc`]); the states are still integrated
    /// exactly, only the local model is frozen at the knot's start.
    FirstSubstep,
}

/// What one thread needs: the contact dynamics, its linearization and cost scratch.
pub struct WholeBodyWorkspace<'a> {
    dynamics: ContactModelWorkspace<'a>,
    derivatives: StepDerivatives,
    anchor_derivatives: AnchorStepDerivatives,
    deviation: StateDeviation,
    tau: DVector<f64>,
    /// Scratch of the chain rule over substeps: the anchors before a substep, its `A_i`,
    /// `B_i`, and the products.
    anchors_before: Vec<Option<Vector3<f64>>>,
    step_a: DMatrix<f64>,
    step_b: DMatrix<f64>,
    chain_tmp_a: DMatrix<f64>,
    /// `A_1 X` on the first substep's structure ([`KnotLinearization::FirstSubstep`]).
    substep_product: SubstepProduct,
    /// The first substep's `B_1` ([`KnotLinearization::FirstSubstep`]; its `A_1` is kept
    /// by `substep_product`).
    frozen_b: DMatrix<f64>,
    e: DVector<f64>,
    we: DVector<f64>,
    jac: DMatrix<f64>,
    kinematics: crate::dynamics::Data,
    frame_jac: nalgebra::Matrix6xX<f64>,
    /// A constraint's gradient row (`nx`).
    constraint_row: DVector<f64>,
    /// A receding window's terminal deviation from the plan and `P dx` (`nx`).
    value_dx: DVector<f64>,
    value_pdx: DVector<f64>,
    /// The terminal state's copy that a linearized step from it advances (its contacts and
    /// foot Jacobians are the terminal constraints').
    terminal_scratch: RobotState,
}

impl<'a> WholeBodyProblem<'a> {
    /// [`Problem::step_with_derivatives`] at knot `k`; with `integrate_exactly` false and
    /// [`KnotLinearization::FirstSubstep`], `next` is the state after the first substep only.
    #[allow(clippy::too_many_arguments)]
    fn knot_derivatives(&self, ws: &mut WholeBodyWorkspace<'a>, k: usize, x: &RobotState, u: &DVector<f64>, next: &mut RobotState, d: &mut KnotDerivatives, integrate_exactly: bool) -> f64 {
        self.torques(ws, u);
        next.q.copy_from(&x.q);
        next.v.copy_from(&x.v);
        next.anchors.clone_from(&x.anchors);
        // Zeroed as slices (a memset): nalgebra's `fill` walks a matrix with its strided
        // iterator, a few percent of the linearization at 48 x 48.
        d.l_x.as_mut_slice().fill(0.0);
        d.l_xx.as_mut_slice().fill(0.0);
        d.l_ux.as_mut_slice().fill(0.0);
        let mut cost = 0.0;
        // Each substep's A_i, B_i (the anchor-extended ones with anchor states), chained
        // with the input held: A <- A_i A, B <- A_i B + B_i.
        let (dt, substeps) = (self.knot_dt(k), self.knot_substeps(k));
        let h = dt / substeps as f64;
        let frozen = self.linearization == KnotLinearization::FirstSubstep;
        for substep in 0..substeps {
            if frozen && substep > 0 {
                // The model the first substep's: B <- A_1 B + B_1 on A_1's structure
                // ([`SubstepProduct`]: 2.7x fewer multiplications than dense at HyQ's 48
                // states; A = A_1^n after the loop); the state exactly, if asked for.
                if integrate_exactly {
                    ws.dynamics.step(&mut next.q, &mut next.v, &mut next.anchors, &ws.tau, h);
                }
                ws.substep_product.mul(&d.b, &mut ws.step_b);
                ws.step_b += &ws.frozen_b;
                std::mem::swap(&mut d.b, &mut ws.step_b);
                continue;
            }
            ws.anchors_before.clone_from(&next.anchors);
            ws.derivatives.step(&mut ws.dynamics, &mut next.q, &mut next.v, &mut next.anchors, &ws.tau, h);
            // The first substep evaluated the contacts and foot Jacobians at x.
            if let (0, Some(constraints)) = (substep, &self.feasibility) {
                let at = KnotContacts { q: &x.q, v: &x.v, anchors: &x.anchors, params: ws.dynamics.params(), feet: ws.dynamics.feet() };
                cost += constraints.add_derivatives(k, dt, at, &ws.derivatives, self.anchor_states, &mut ws.constraint_row, (&mut d.l_x, &mut d.l_xx));
            }
            let (a, b) = if substep == 0 { (&mut d.a, &mut d.b) } else { (&mut ws.step_a, &mut ws.step_b) };
            if self.anchor_states {
                ws.anchor_derivatives.linearize(&ws.derivatives, &ws.dynamics, &ws.anchors_before, h, a);
                b.as_mut_slice().fill(0.0);
                b.view_mut((0, 0), (2 * self.model.nv, self.nu_())).copy_from(&ws.derivatives.b);
            } else {
                a.copy_from(&ws.derivatives.a);
                b.copy_from(&ws.derivatives.b);
            }
            if frozen && substeps > 1 {
                ws.frozen_b.copy_from(&d.b);
                ws.substep_product.capture(&ws.derivatives, &d.a, h);
            }
            if substep > 0 {
                // The products land in scratch of the same shapes, which then trades its
                // buffer with the knot's (no copy, no allocation). Dense: the plans' one
                // product a knot (two substeps), kept to the bit as their tests measured them.
                ws.chain_tmp_a.gemm(1.0, &ws.step_a, &d.a, 0.0);
                std::mem::swap(&mut d.a, &mut ws.chain_tmp_a);
                ws.step_b.gemm(1.0, &ws.step_a, &d.b, 1.0);
                std::mem::swap(&mut d.b, &mut ws.step_b);
            }
        }
        if frozen && substeps > 1 {
            ws.substep_product.power(substeps, &mut d.a, &mut ws.chain_tmp_a);
        }
        // A clipped input does not move the state.
        for (i, (u, limit)) in u.iter().zip(self.effort_limits.iter()).enumerate() {
            if u.abs() > *limit {
                d.b.column_mut(i).fill(0.0);
            }
        }
        let t = self.knot_time(k);
        cost += self.add_state_cost_derivatives(ws, &self.running, dt, x, &mut d.l_x, &mut d.l_xx);
        cost += self.add_receding_cost_derivatives(ws, k, x, &mut d.l_x, &mut d.l_xx);
        for w in &self.waypoints {
            let scale = dt * w.window(t);
            if scale > 1e-12 * dt {
                cost += self.add_state_cost_derivatives(ws, &w.cost, scale, x, &mut d.l_x, &mut d.l_xx);
            }
        }
        if let Some(limits) = &self.joint_limit_cost {
            cost += limits.add_derivatives(dt, &x.q, &mut d.l_x, &mut d.l_xx);
        }
        d.l_uu.as_mut_slice().fill(0.0);
        for i in 0..self.nu_() {
            let r = self.input_weights[i];
            let du = u[i] - self.input_desired[i];
            d.l_u[i] = 2.0 * dt * r * du;
            d.l_uu[(i, i)] = 2.0 * dt * r;
            cost += dt * r * du * du;
        }
        cost + self.reference_input_cost(k, u, Some((&mut d.l_u, &mut d.l_uu)))
    }

    fn nu_(&self) -> usize {
        self.model.nv - 6
    }

    /// `scale (xb^T W xb + foot terms)` (no derivatives).
    fn state_cost(&self, ws: &mut WholeBodyWorkspace<'a>, cost: &StateCost, scale: f64, x: &RobotState) -> f64 {
        self.deviation_cost(ws, (&cost.q, &cost.v), &cost.weights, &cost.feet, scale, x)
    }

    /// `scale (xb^T diag(weights) xb + foot terms)`, `xb` the deviation from `desired`.
    fn deviation_cost(&self, ws: &mut WholeBodyWorkspace<'a>, desired: (&DVector<f64>, &DVector<f64>), weights: &DVector<f64>, feet: &[FootTarget], scale: f64, x: &RobotState) -> f64 {
        ws.deviation.evaluate(self.model, (&x.q, &x.v), desired, &mut ws.e, None);
        let mut c = ws.e.iter().zip(weights.iter()).map(|(e, w)| w * e * e).sum::<f64>();
        if !feet.is_empty() {
            crate::dynamics::forward_kinematics(self.model, &mut ws.kinematics, &x.q);
            for target in feet {
                let e = self.foot_position(ws, target.foot) - target.position;
                c += e.component_mul(&target.weights).dot(&e);
            }
        }
        scale * c
    }

    /// World position of foot `f` after forward kinematics in `ws.kinematics`.
    fn foot_position(&self, ws: &WholeBodyWorkspace<'a>, f: usize) -> Vector3<f64> {
        crate::dynamics::frame_position(self.model, &ws.kinematics, self.model.feet[f].frame)
    }

    /// Adds the foot terms' Gauss-Newton derivatives: `e = p_f - p*`, `J` the foot's
    /// world-aligned linear Jacobian (`d p_f / d dq`): `l_x += 2 s J^T W e`,
    /// `l_xx += 2 s J^T W J` (configuration block).
    fn add_foot_cost_derivatives(&self, ws: &mut WholeBodyWorkspace<'a>, feet: &[FootTarget], scale: f64, x: &RobotState, l_x: &mut DVector<f64>, l_xx: &mut DMatrix<f64>) -> f64 {
        if feet.is_empty() {
            return 0.0;
        }
        let nv = self.model.nv;
        crate::dynamics::compute_joint_jacobians(self.model, &mut ws.kinematics, &x.q);
        let mut c = 0.0;
        for target in feet {
            let e = self.foot_position(ws, target.foot) - target.position;
            c += e.component_mul(&target.weights).dot(&e);
            crate::dynamics::frame_jacobian(self.model, &ws.kinematics, self.model.feet[target.foot].frame, crate::dynamics::ReferenceFrame::LocalWorldAligned, &mut ws.frame_jac);
            let jac = ws.frame_jac.fixed_rows::<3>(0);
            let we = e.component_mul(&target.weights);
            l_x.rows_mut(0, nv).gemv_tr(2.0 * scale, &jac, &we, 1.0);
            for (r, w) in target.weights.iter().enumerate() {
                let row = jac.row(r);
                l_xx.view_mut((0, 0), (nv, nv)).ger(2.0 * scale * w, &row.transpose(), &row.transpose(), 1.0);
            }
        }
        scale * c
    }

    /// Adds `scale xb^T W xb` and its Gauss-Newton derivatives to `(l_x, l_xx)`.
    fn add_state_cost_derivatives(&self, ws: &mut WholeBodyWorkspace<'a>, cost: &StateCost, scale: f64, x: &RobotState, l_x: &mut DVector<f64>, l_xx: &mut DMatrix<f64>) -> f64 {
        self.add_deviation_cost_derivatives(ws, (&cost.q, &cost.v), &cost.weights, &cost.feet, scale, x, l_x, l_xx)
    }

    /// [`Self::deviation_cost`], adding its Gauss-Newton derivatives to `(l_x, l_xx)`.
    #[allow(clippy::too_many_arguments)]
    fn add_deviation_cost_derivatives(&self, ws: &mut WholeBodyWorkspace<'a>, desired: (&DVector<f64>, &DVector<f64>), weights: &DVector<f64>, feet: &[FootTarget], scale: f64, x: &RobotState, l_x: &mut DVector<f64>, l_xx: &mut DMatrix<f64>) -> f64 {
        ws.deviation.evaluate(self.model, (&x.q, &x.v), desired, &mut ws.e, Some(&mut ws.jac));
        // l_x += 2 s E^T W e, l_xx += 2 s E^T W E, using E's structure (StateDeviation):
        // identity except the 3x3 blocks of the base position (R) and orientation (Jr^-1).
        for i in 0..ws.e.len() {
            ws.we[i] = weights[i] * ws.e[i];
        }
        for block in [0usize, 3] {
            let jb = ws.jac.fixed_view::<3, 3>(block, block).into_owned();
            let web = nalgebra::Vector3::new(ws.we[block], ws.we[block + 1], ws.we[block + 2]);
            let w = nalgebra::Matrix3::from_diagonal(&nalgebra::Vector3::new(weights[block], weights[block + 1], weights[block + 2]));
            let g = jb.transpose() * web * (2.0 * scale);
            let h = jb.transpose() * w * jb * (2.0 * scale);
            for r in 0..3 {
                l_x[block + r] += g[r];
                for c in 0..3 {
                    l_xx[(block + r, block + c)] += h[(r, c)];
                }
            }
        }
        for i in 6..ws.e.len() {
            l_x[i] += 2.0 * scale * ws.we[i];
            l_xx[(i, i)] += 2.0 * scale * weights[i];
        }
        scale * ws.e.dot(&ws.we) + self.add_foot_cost_derivatives(ws, feet, scale, x, l_x, l_xx)
    }

    /// Where the knots fall ([`KnotGrid`]; a receding window's coarse tail as of its
    /// current start, [`CoarseTail::at_start`]).
    pub fn grid(&self) -> KnotGrid {
        KnotGrid { dt: self.dt, knots: self.active_knots(), tail: self.current_tail() }
    }

    /// The window's knots now ([`crate::slq::Problem::horizon`]): `knots`, but a receding
    /// window that ends at the task's end ([`RecedingHorizon::ends_at_task_end`], uniform
    /// knots) keeps only those up to the knot nearest it, down to its shortest length: the
    /// task's final cost `H` then ends the window, as it ends the plan, and no knot is spent
    /// on a motion after the task that the closed loop never runs. It only shrinks as the
    /// window moves on (a solver allocates for the knots it starts with).
    pub fn active_knots(&self) -> usize {
        let (Some(r), None) = (&self.receding, self.tail) else { return self.knots };
        let Some(shortest) = r.ends_at_task_end else { return self.knots };
        let to_end = ((r.final_time - r.start()).max(shortest) / self.dt).round();
        if to_end >= self.knots as f64 {
            self.knots
        } else {
            to_end.max(1.0) as usize
        }
    }

    /// The coarse tail as of the window's current start (the start read only if there is
    /// a tail: the plans' knots ask this on every step).
    fn current_tail(&self) -> Option<CoarseTail> {
        self.tail.map(|tail| tail.at_start(self.dt, self.receding.as_ref().map_or(0.0, RecedingHorizon::start)))
    }

    /// The length of knot `k`'s interval (s): `dt`, or the coarse tail's.
    pub fn knot_dt(&self, k: usize) -> f64 {
        self.grid().dt_of(k)
    }

    /// Integration steps of knot `k` (each `knot_dt(k) / knot_substeps(k)`).
    pub fn knot_substeps(&self, k: usize) -> usize {
        match self.current_tail() {
            Some(tail) if k >= tail.from => tail.substeps,
            _ => self.substeps,
        }
    }

    /// The absolute time of knot `k` (s): `k dt` (with a coarse tail, its knots' spacing
    /// after `tail.from`), from the window's start in a receding horizon.
    pub fn knot_time(&self, k: usize) -> f64 {
        self.receding.as_ref().map_or(0.0, RecedingHorizon::start) + self.grid().offset(k)
    }

    /// The knot whose state carries the task's final cost `H` (the last, but in a receding
    /// horizon the one at the task's end, if the window reaches it).
    fn final_knot(&self) -> Option<usize> {
        match &self.receding {
            None => Some(self.knots),
            Some(r) => r.final_knot(&self.grid()),
        }
    }

    /// The receding horizon's terms at knot `k` (`k = N`: the terminal ones): the task's
    /// final cost if it falls on `k`, and the reference motion's tracking cost.
    fn receding_cost(&self, ws: &mut WholeBodyWorkspace<'a>, k: usize, x: &RobotState) -> f64 {
        let Some(r) = &self.receding else { return 0.0 };
        let n = self.active_knots();
        let mut cost = 0.0;
        if k < n && self.final_knot() == Some(k) {
            cost += self.state_cost(ws, &self.terminal, 1.0, x);
        }
        let (weights, scale) = if k < n { (&r.reference.weights, self.knot_dt(k)) } else { (&r.reference.terminal_weights, 1.0) };
        cost += self.deviation_cost(ws, r.reference.at(self.knot_time(k)), weights, &[], scale, x);
        if k == n && self.ends_on_plan_value() {
            cost += self.plan_value(ws, x, None);
        }
        cost
    }

    /// Whether a receding window ends on the plan's value function. The value stands for the
    /// plan's cost from the window's end to the task's end, its final cost `H` included
    /// (past the plan's end, its last knot's value: `l_{N-1} + H`). Once the window reaches
    /// the task's end, `H` is in the window at [`Self::final_knot`], and the value would
    /// count it a second time: the window then ends on `H` alone, as the plan does. A window
    /// without the task's final cost (`--no-task-costs`) keeps the value, `H`'s only trace.
    fn ends_on_plan_value(&self) -> bool {
        let has_final_cost = self.terminal.weights.iter().any(|&w| w != 0.0) || !self.terminal.feet.is_empty();
        self.final_knot().is_none() || !has_final_cost
    }

    /// A receding window's terminal cost from the plan's value function,
    /// `p_j^T dx + 1/2 dx^T P_j dx` with `dx = x (-) x_j` ([`PlanValue`]), and with
    /// `derivatives` its gradient `p_j + P_j dx` and Hessian `P_j` added (`d dx / d x` taken
    /// as the identity, as the solver's own tangent-space model does).
    fn plan_value(&self, ws: &mut WholeBodyWorkspace<'a>, x: &RobotState, derivatives: Option<(&mut DVector<f64>, &mut DMatrix<f64>)>) -> f64 {
        let Some(plan) = self.receding.as_ref().and_then(|r| r.value.as_ref()) else { return 0.0 };
        let n = self.active_knots();
        let j = plan.knot_at(self.knot_time(n));
        let (p_mat, p_vec) = (&plan.value.hessians[j], &plan.value.gradients[j]);
        if p_vec.len() != ws.value_dx.len() {
            return 0.0;
        }
        self.difference(&plan.states[j], x, &mut ws.value_dx);
        ws.value_pdx.gemv(1.0, p_mat, &ws.value_dx, 0.0);
        let cost = p_vec.dot(&ws.value_dx) + 0.5 * ws.value_dx.dot(&ws.value_pdx);
        if let Some((h_x, h_xx)) = derivatives {
            *h_x += p_vec;
            *h_x += &ws.value_pdx;
            *h_xx += p_mat;
        }
        cost
    }

    /// [`Self::receding_cost`] with its derivatives added to `(l_x, l_xx)`.
    fn add_receding_cost_derivatives(&self, ws: &mut WholeBodyWorkspace<'a>, k: usize, x: &RobotState, l_x: &mut DVector<f64>, l_xx: &mut DMatrix<f64>) -> f64 {
        let Some(r) = &self.receding else { return 0.0 };
        let n = self.active_knots();
        let mut cost = 0.0;
        if k < n && self.final_knot() == Some(k) {
            cost += self.add_state_cost_derivatives(ws, &self.terminal, 1.0, x, l_x, l_xx);
        }
        let (weights, scale) = if k < n { (&r.reference.weights, self.knot_dt(k)) } else { (&r.reference.terminal_weights, 1.0) };
        cost += self.add_deviation_cost_derivatives(ws, r.reference.at(self.knot_time(k)), weights, &[], scale, x, l_x, l_xx);
        if k == n && self.ends_on_plan_value() {
            cost += self.plan_value(ws, x, Some((l_x, l_xx)));
        }
        cost
    }

    fn running_cost(&self, ws: &mut WholeBodyWorkspace<'a>, k: usize, x: &RobotState, u: &DVector<f64>) -> f64 {
        let (t, dt) = (self.knot_time(k), self.knot_dt(k));
        let mut cost = self.state_cost(ws, &self.running, dt, x) + self.receding_cost(ws, k, x);
        for w in &self.waypoints {
            cost += self.state_cost(ws, &w.cost, dt * w.window(t), x);
        }
        if let Some(limits) = &self.joint_limit_cost {
            cost += limits.cost(dt, &x.q);
        }
        cost + dt * u.iter().zip(&self.input_desired).zip(&self.input_weights).map(|((u, d), r)| r * (u - d) * (u - d)).sum::<f64>() + self.reference_input_cost(k, u, None)
    }

    /// A receding horizon's `dt w_u |u - u_ref(t_k)|^2`, with its gradient and Hessian
    /// added to `derivatives = (l_u, l_uu)` if given.
    fn reference_input_cost(&self, k: usize, u: &DVector<f64>, derivatives: Option<(&mut DVector<f64>, &mut DMatrix<f64>)>) -> f64 {
        let Some(r) = self.receding.as_ref().filter(|r| r.reference.input_weight > 0.0 && !r.reference.tau.is_empty()) else { return 0.0 };
        let w = self.knot_dt(k) * r.reference.input_weight;
        let reference = r.reference.torque_at(self.knot_time(k));
        let cost = w * u.iter().zip(reference.iter()).map(|(u, d)| (u - d) * (u - d)).sum::<f64>();
        if let Some((l_u, l_uu)) = derivatives {
            for i in 0..u.len() {
                l_u[i] += 2.0 * w * (u[i] - reference[i]);
                l_uu[(i, i)] += 2.0 * w;
            }
        }
        cost
    }

    /// `tau = [0; clamp(u, -limit, limit)]`, as the simulator applies it.
    fn torques(&self, ws: &mut WholeBodyWorkspace<'a>, u: &DVector<f64>) {
        ws.tau.fill(0.0);
        for (i, (u, limit)) in u.iter().zip(self.effort_limits.iter()).enumerate() {
            ws.tau[6 + i] = u.clamp(-limit, *limit);
        }
    }
}

impl WholeBodyProblem<'_> {
    /// Whether the last state `x_N` carries the feasibility constraints.
    fn terminal_constrained(&self) -> bool {
        self.feasibility.as_ref().is_some_and(|c| c.settings.terminal_knot)
    }

    /// `f(k, q, v, anchors, feet)` at every constrained knot state of `states` (`x_0 ..
    /// x_{N-1}`, and `x_N` with [`FeasibilitySettings::terminal_knot`]), with the contacts
    /// evaluated there.
    fn for_each_knot_contact(&self, states: &[RobotState], mut f: impl FnMut(usize, &RobotState, &crate::contact::ContactParams, &[crate::sim::FootState])) {
        let mut ws = ContactModelWorkspace::new(self.model, self.terrain).with_joint_limits(self.joint_limits);
        let n = self.active_knots();
        for (k, x) in states.iter().enumerate().take(n + usize::from(self.terminal_constrained())) {
            ws.evaluate_contacts(&x.q, &x.v, &x.anchors);
            f(k, x, ws.params(), ws.feet());
        }
    }

    /// The largest violation of each feasibility constraint along `states` (`None` without
    /// the constraints).
    pub fn constraint_violation(&self, states: &[RobotState]) -> Option<Violation> {
        let constraints = self.feasibility.as_ref()?;
        let mut worst = Violation::default();
        self.for_each_knot_contact(states, |k, x, params, feet| constraints.violation(k, KnotContacts { q: &x.q, v: &x.v, anchors: &x.anchors, params, feet }, &mut worst));
        Some(worst)
    }

    /// The augmented Lagrangian's outer update of every multiplier at `states`
    /// ([`FeasibilityConstraints::update_multipliers`]).
    pub fn update_multipliers(&mut self, states: &[RobotState]) {
        let Some(mut constraints) = self.feasibility.take() else { return };
        self.for_each_knot_contact(states, |k, x, params, feet| constraints.update_multipliers(k, KnotContacts { q: &x.q, v: &x.v, anchors: &x.anchors, params, feet }));
        constraints.decrease_barrier();
        self.feasibility = Some(constraints);
    }

    /// The augmented-Lagrangian update between two rounds on the same horizon: the
    /// multipliers at `states` ([`Self::update_multipliers`]), then the penalties grown
    /// ([`FeasibilityConstraints::grow_penalties`]).
    pub fn next_outer_round(&mut self, states: &[RobotState]) {
        self.update_multipliers(states);
        if let Some(constraints) = self.feasibility.as_mut() {
            constraints.grow_penalties();
        }
    }
}

impl<'a> Problem for WholeBodyProblem<'a> {
    type State = RobotState;
    type Workspace = WholeBodyWorkspace<'a>;

    fn nx(&self) -> usize {
        2 * self.model.nv + if self.anchor_states { ANCHOR_DIM * self.model.feet.len() } else { 0 }
    }
    fn nu(&self) -> usize {
        self.nu_()
    }
    fn horizon(&self) -> usize {
        self.active_knots()
    }
    fn workspace(&self) -> WholeBodyWorkspace<'a> {
        let (model, nv) = (self.model, self.model.nv);
        WholeBodyWorkspace {
            dynamics: ContactModelWorkspace::new(model, self.terrain).with_joint_limits(self.joint_limits),
            derivatives: StepDerivatives::new(model),
            anchor_derivatives: AnchorStepDerivatives::new(nv),
            deviation: StateDeviation::new(model),
            tau: DVector::zeros(nv),
            anchors_before: vec![None; model.feet.len()],
            step_a: DMatrix::zeros(self.nx(), self.nx()),
            step_b: DMatrix::zeros(self.nx(), self.nu()),
            chain_tmp_a: DMatrix::zeros(self.nx(), self.nx()),
            substep_product: SubstepProduct::new(model, if self.anchor_states { model.feet.len() } else { 0 }),
            frozen_b: DMatrix::zeros(self.nx(), self.nu()),
            e: DVector::zeros(2 * nv),
            we: DVector::zeros(2 * nv),
            jac: DMatrix::zeros(2 * nv, 2 * nv),
            kinematics: crate::dynamics::Data::new(model),
            frame_jac: nalgebra::Matrix6xX::zeros(nv),
            constraint_row: DVector::zeros(self.nx()),
            value_dx: DVector::zeros(self.nx()),
            value_pdx: DVector::zeros(self.nx()),
            terminal_scratch: self.initial.clone(),
        }
    }
    fn initial_state(&self) -> RobotState {
        self.initial.clone()
    }
    /// `dx = [q_x (-) q_y; v_x - v_y]`, and with anchor states `a_x - a_y` per foot (zero
    /// where either has no anchor: a foot off the ground has no anchor to deviate).
    fn difference(&self, y: &RobotState, x: &RobotState, dx: &mut DVector<f64>) {
        let nv = self.model.nv;
        crate::dynamics::difference_into(self.model, &y.q, &x.q, &mut dx.as_mut_slice()[..nv]);
        for i in 0..nv {
            dx[nv + i] = x.v[i] - y.v[i];
        }
        if self.anchor_states {
            for (f, (ay, ax)) in y.anchors.iter().zip(&x.anchors).enumerate() {
                let d = match (ay, ax) {
                    (Some(ay), Some(ax)) => ax - ay,
                    _ => Vector3::zeros(),
                };
                dx.fixed_rows_mut::<3>(2 * nv + ANCHOR_DIM * f).copy_from(&d);
            }
        }
    }
    fn step(&self, ws: &mut WholeBodyWorkspace<'a>, k: usize, x: &RobotState, u: &DVector<f64>, next: &mut RobotState) -> f64 {
        let mut cost = self.running_cost(ws, k, x, u);
        self.torques(ws, u);
        next.q.copy_from(&x.q);
        next.v.copy_from(&x.v);
        next.anchors.clone_from(&x.anchors);
        let (dt, substeps) = (self.knot_dt(k), self.knot_substeps(k));
        let h = dt / substeps as f64;
        for substep in 0..substeps {
            ws.dynamics.step(&mut next.q, &mut next.v, &mut next.anchors, &ws.tau, h);
            // The first substep evaluated the contacts at x: the constraints' forces.
            if let (0, Some(constraints)) = (substep, &self.feasibility) {
                let at = KnotContacts { q: &x.q, v: &x.v, anchors: &x.anchors, params: ws.dynamics.params(), feet: ws.dynamics.feet() };
                cost += constraints.cost(k, dt, at);
            }
        }
        cost
    }
    fn step_with_derivatives(&self, ws: &mut WholeBodyWorkspace<'a>, k: usize, x: &RobotState, u: &DVector<f64>, next: &mut RobotState, d: &mut KnotDerivatives) -> f64 {
        self.knot_derivatives(ws, k, x, u, next, d, true)
    }
    /// With [`KnotLinearization::FirstSubstep`], the knot's later substeps are not
    /// integrated (the model is the first substep's; the rollout has the next state):
    /// four of a 5 ms knot's five dynamics evaluations saved.
    fn linearize_knot(&self, ws: &mut WholeBodyWorkspace<'a>, k: usize, x: &RobotState, u: &DVector<f64>, scratch: &mut RobotState, d: &mut KnotDerivatives) -> f64 {
        self.knot_derivatives(ws, k, x, u, scratch, d, false)
    }
    /// `h(x_N)`, and with [`FeasibilitySettings::terminal_knot`] the feasibility terms of
    /// `x_N` as of any knot (`dt psi`): the plan's last state is a knot of the motion, and
    /// without them the terminal cost is cheapest met by a last stamp and drag of the feet
    /// (docs/experiments/feasible-slq-3.md, turn).
    fn terminal_cost(&self, ws: &mut WholeBodyWorkspace<'a>, x: &RobotState) -> f64 {
        let n = self.active_knots();
        let mut cost = if self.final_knot() == Some(n) { self.state_cost(ws, &self.terminal, 1.0, x) } else { 0.0 };
        cost += self.receding_cost(ws, n, x);
        if let Some(constraints) = self.feasibility.as_ref().filter(|c| c.settings.terminal_knot) {
            ws.dynamics.evaluate_contacts(&x.q, &x.v, &x.anchors);
            let at = KnotContacts { q: &x.q, v: &x.v, anchors: &x.anchors, params: ws.dynamics.params(), feet: ws.dynamics.feet() };
            cost += constraints.cost(n, self.knot_dt(n.saturating_sub(1)), at);
        }
        cost
    }
    fn terminal_cost_derivatives(&self, ws: &mut WholeBodyWorkspace<'a>, x: &RobotState, h_x: &mut DVector<f64>, h_xx: &mut DMatrix<f64>) -> f64 {
        let n = self.active_knots();
        h_x.fill(0.0);
        h_xx.fill(0.0);
        let mut cost = 0.0;
        if let Some(constraints) = self.feasibility.as_ref().filter(|c| c.settings.terminal_knot) {
            // One linearized step from x_N (torques zero: they move neither the contacts nor
            // the foot Jacobians at x_N) evaluates both there, as a running knot's first
            // substep does.
            ws.terminal_scratch.clone_from(x);
            ws.tau.fill(0.0);
            let s = &mut ws.terminal_scratch;
            ws.derivatives.step(&mut ws.dynamics, &mut s.q, &mut s.v, &mut s.anchors, &ws.tau, self.dt / self.substeps as f64);
            let dt = self.knot_dt(n.saturating_sub(1));
            let at = KnotContacts { q: &x.q, v: &x.v, anchors: &x.anchors, params: ws.dynamics.params(), feet: ws.dynamics.feet() };
            cost += constraints.add_derivatives(n, dt, at, &ws.derivatives, self.anchor_states, &mut ws.constraint_row, (h_x, h_xx));
        }
        if self.final_knot() == Some(n) {
            cost += self.add_state_cost_derivatives(ws, &self.terminal, 1.0, x, h_x, h_xx);
        }
        cost + self.add_receding_cost_derivatives(ws, n, x, h_x, h_xx)
    }
    /// `-effort <= u <= effort`, the joints' effort limits.
    fn input_bounds(&self, _k: usize, lower: &mut DVector<f64>, upper: &mut DVector<f64>) {
        for (i, limit) in self.effort_limits.iter().enumerate() {
            lower[i] = -limit;
            upper[i] = *limit;
        }
    }
    fn is_valid(&self, x: &RobotState) -> bool {
        x.q.iter().all(|v| v.is_finite()) && x.v.iter().all(|v| v.is_finite() && v.abs() < 200.0)
    }

    /// The knot at the task's end in a window that reaches it (the closed loop ends there;
    /// the knots after it only carry the final state on), else the last.
    fn last_used_knot(&self) -> usize {
        let n = self.active_knots();
        self.final_knot().unwrap_or(n)
    }

    /// The same feet anchored (in contact) in both states: a foot that landed or lifted
    /// changes the knot's dynamics and its contact costs' derivatives.
    fn same_model_piece(&self, y: &RobotState, x: &RobotState) -> bool {
        y.anchors.iter().zip(&x.anchors).all(|(a, b)| a.is_some() == b.is_some())
    }
}

/// The initial stable control law of Neunert 2017 (sec. V): joint PD around the default
/// stance, no feedforward.
pub struct PdPolicy<'a>(pub &'a JointPd);

impl<'a> Policy<WholeBodyProblem<'a>> for PdPolicy<'_> {
    fn control(&self, problem: &WholeBodyProblem<'a>, _k: usize, x: &RobotState, u: &mut DVector<f64>) {
        self.0.actuated_torques(problem.model, &x.q, &x.v, u);
    }
}
