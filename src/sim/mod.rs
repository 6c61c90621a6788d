//! Forward simulation of a robot on a terrain through the smooth contact model.
//!
//! The state is `(q, v)` plus one hidden contact anchor per foot (the point where its
//! contact began, Neunert 2017 sec. III-B). Each physics step:
//!
//! 1. every `control_dt` the [`Controller`] is asked for joint torques, which are then held
//!    (zero-order hold) and clipped to the joints' effort limits;
//! 2. foot positions and velocities from forward kinematics, contact forces from
//!    [`crate::contact::contact_force`] against the [`Terrain`], and any active [`Push`] on
//!    the base, become external forces on the bodies;
//! 3. the joint stops ([`JointLimitParams`]) add their generalized force to the torques
//!    of every joint past a position limit;
//! 4. ABA with those torques and external forces gives `qdd`; the integrator advances `(q, v)`;
//! 5. the anchors are updated ([`crate::contact::update_anchor`]); a non-finite or
//!    exploding state stops the run with [`SimError::Diverged`], naming the step and state.
//!
//! The same [`ContactModelWorkspace::step`] is what a trajectory optimizer can call as its
//! discrete dynamics `x_{k+1} = f(x_k, u_k)`: one source of truth.
//!
//! ```
//! use legwork::{model::embedded, sim::{Simulator, SimConfig}, control::JointPd, terrain::Plane};
//! let model = embedded::load("a1").unwrap();
//! let ground = Plane::flat(0.0);
//! let q0 = legwork::sim::standing_on_ground(&model, &ground, 0.05).unwrap();
//! let mut sim = Simulator::new(&model, &ground, SimConfig::default(), q0, None).unwrap();
//! let mut stand = JointPd::standing(&model, 0.001).unwrap();
//! let run = sim.run(0.5, &mut stand, |_| {}).unwrap();
//! assert!(run.trajectory.knots.len() > 400);
//! ```

mod anchor_states;
pub(crate) mod joint_limits;
mod step_derivatives;
mod substep_product;
mod workspace;

pub use anchor_states::{AnchorStepDerivatives, ANCHOR_DIM};
pub use joint_limits::{JointLimitParams, JointLimitParamsError, JointStops, StopForce};
pub use step_derivatives::StepDerivatives;
pub use substep_product::SubstepProduct;
pub use workspace::{ContactModelWorkspace, FootState};

use crate::contact::{ContactParams, ContactParamsError};
use crate::dynamics::{forward_kinematics, update_frame_placements, Data};
use crate::io::{Knot, Trajectory};
use crate::model::Model;
use crate::terrain::Terrain;
use nalgebra::{DVector, Vector3};
use serde::{Deserialize, Serialize};

/// How `(q, v)` is advanced over one physics step.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Integrator {
    /// `v' = v + dt qdd(q, v)`, `q' = q (+) dt v'` (symplectic Euler; the default).
    #[default]
    SemiImplicitEuler,
    /// Classical Runge-Kutta 4 in the tangent space at the step's start
    /// (`q' = q (+) dt/6 (v1 + 2 v2 + 2 v3 + v4)`), contact anchors held over the step.
    Rk4,
}

/// Simulation settings. Defaults: 2 kHz physics, 1 kHz control, semi-implicit Euler, no
/// joint stops, knots recorded at the control rate. The contact model is the robot's
/// ([`Model::contact`]): one world for the simulator and the optimizer.
#[derive(Clone, Debug, PartialEq)]
pub struct SimConfig {
    /// Physics time step (s).
    pub physics_dt: f64,
    /// Control period (s): a whole multiple of `physics_dt`.
    pub control_dt: f64,
    pub integrator: Integrator,
    /// The joints' mechanical stops at their position limits; `None` (the default) leaves
    /// the joints free. Off by default for now: the terrain walks (Winkler 2015) pass HyQ's
    /// published hip limits by up to 41 deg and fail with the stops on, and so do several
    /// optimized tasks (see BENCHMARKS.md); `legwork solve` and `legwork walk` report how far
    /// a motion went past them.
    pub joint_limits: Option<JointLimitParams>,
    /// Time between recorded knots (s): a whole multiple of `physics_dt`.
    pub record_dt: f64,
    /// Clip joint torques to the model's effort limits (on by default).
    pub enforce_effort_limits: bool,
    /// A speed (m/s or rad/s) above which the state is taken as blown up.
    pub max_speed: f64,
}

impl Default for SimConfig {
    fn default() -> Self {
        Self {
            physics_dt: 0.0005,
            control_dt: 0.001,
            integrator: Integrator::SemiImplicitEuler,
            joint_limits: None,
            record_dt: 0.001,
            enforce_effort_limits: true,
            max_speed: 200.0,
        }
    }
}

impl SimConfig {
    /// Physics steps per control period and per recorded knot, for a robot whose contact
    /// model is `contact` (the physics step may not exceed its stable step).
    pub fn ratios(&self, contact: &ContactParams) -> Result<(usize, usize), SimError> {
        let ratio = |field: &'static str, value: f64| -> Result<usize, SimError> {
            if !(value > 0.0 && value.is_finite()) {
                return Err(SimError::Config { field, problem: format!("expected a positive time in seconds, got {value}") });
            }
            let r = value / self.physics_dt;
            if (r - r.round()).abs() > 1e-6 || r.round() < 1.0 {
                return Err(SimError::Config {
                    field,
                    problem: format!("{value} s is not a whole multiple of physics_dt = {} s", self.physics_dt),
                });
            }
            Ok(r.round() as usize)
        };
        if !(self.physics_dt > 0.0 && self.physics_dt.is_finite()) {
            return Err(SimError::Config { field: "physics_dt", problem: format!("expected a positive time in seconds, got {}", self.physics_dt) });
        }
        if self.max_speed.is_nan() || self.max_speed <= 0.0 {
            return Err(SimError::Config { field: "max_speed", problem: format!("expected a positive speed, got {}", self.max_speed) });
        }
        contact.validate()?;
        if self.physics_dt > contact.max_step * (1.0 + 1e-9) {
            return Err(SimError::Config {
                field: "physics_dt",
                problem: format!("{} s is longer than the robot's contact model allows ({} s, `contact.max_step`): use a physics rate of at least {} Hz", self.physics_dt, contact.max_step, (1.0 / contact.max_step).round()),
            });
        }
        if let Some(stops) = &self.joint_limits {
            stops.validate()?;
        }
        Ok((ratio("control_dt", self.control_dt)?, ratio("record_dt", self.record_dt)?))
    }
}

/// A force on the base, world frame, applied at the base origin from `start` for
/// `duration` seconds (`--push X,Y,Z@T:DUR` on the command line).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Push {
    pub force: Vector3<f64>,
    pub start: f64,
    pub duration: f64,
}

impl Push {
    /// Parses `X,Y,Z@T:DUR` (newtons, seconds), e.g. `0,50,0@1.0:0.2`.
    pub fn parse(text: &str) -> Result<Self, String> {
        let expected = "expected X,Y,Z@T:DUR (force in N, world frame; start and duration in s), e.g. 0,50,0@1:0.2";
        let (force, timing) = text.split_once('@').ok_or_else(|| format!("push '{text}': {expected}"))?;
        let (start, duration) = timing.split_once(':').ok_or_else(|| format!("push '{text}': {expected}"))?;
        let numbers: Result<Vec<f64>, _> = force.split(',').map(|s| s.trim().parse::<f64>()).collect();
        let f = match numbers {
            Ok(v) if v.len() == 3 => v,
            _ => return Err(format!("push '{text}': force '{force}': {expected}")),
        };
        let number = |s: &str, what: &str| -> Result<f64, String> {
            s.trim().parse::<f64>().map_err(|_| format!("push '{text}': {what} '{s}' is not a number; {expected}"))
        };
        let push = Push { force: Vector3::new(f[0], f[1], f[2]), start: number(start, "start")?, duration: number(duration, "duration")? };
        if push.force.iter().any(|x| !x.is_finite()) || !push.start.is_finite() || !push.duration.is_finite() || push.duration <= 0.0 {
            return Err(format!("push '{text}': force and start must be finite and the duration positive"));
        }
        Ok(push)
    }

    /// The push acts at time `t` (s): `start <= t < start + duration`.
    pub fn active(&self, t: f64) -> bool {
        t >= self.start && t < self.start + self.duration
    }
}

/// The simulated state: configuration, velocity, contact anchors, time.
#[derive(Clone, Debug, PartialEq)]
pub struct SimState {
    pub t: f64,
    pub q: DVector<f64>,
    pub v: DVector<f64>,
    /// Per foot: the contact point when its current contact began (`None`: no contact).
    pub anchors: Vec<Option<Vector3<f64>>>,
}

/// Computes joint torques from the state, every control period.
pub trait Controller {
    /// Short name for reports (`stand`, `track`).
    fn name(&self) -> &str;
    /// Writes the generalized torques (`nv` entries; the six base entries are ignored, the
    /// base is not actuated) for `state`.
    fn compute(&mut self, model: &Model, state: &SimState, tau: &mut DVector<f64>) -> Result<(), ControlError>;
}

/// What [`controller_torques`] applied.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AppliedTorques {
    /// Some torque was clipped to its joint's effort limit.
    pub saturated: bool,
    /// The largest absolute joint torque applied (N m).
    pub max_torque: f64,
}

/// The torques a robot's joints apply under `controller` at `state`, into `tau` (`nv`
/// entries): the base's six zeroed (it is not actuated), a non-finite torque an error
/// naming the joint, each torque clipped to its joint's effort limit when
/// `enforce_effort_limits`. Every plant ([`Plant`]) applies a controller through it.
pub fn controller_torques(model: &Model, controller: &mut dyn Controller, state: &SimState, tau: &mut DVector<f64>, enforce_effort_limits: bool) -> Result<AppliedTorques, SimError> {
    controller.compute(model, state, tau).map_err(|source| SimError::Controller { t: state.t, source })?;
    let mut applied = AppliedTorques { saturated: false, max_torque: 0.0 };
    for j in &model.joints[1..] {
        for k in 0..j.nv {
            let i = j.idx_v + k;
            if j.kind == crate::model::JointKind::FreeFlyer {
                tau[i] = 0.0;
                continue;
            }
            if !tau[i].is_finite() {
                return Err(SimError::Controller { t: state.t, source: ControlError { controller: controller.name().into(), problem: format!("torque of joint '{}' is {}", j.name, tau[i]) } });
            }
            let limit = j.limits.effort[k];
            if enforce_effort_limits && limit.is_finite() && tau[i].abs() > limit {
                tau[i] = tau[i].clamp(-limit, limit);
                applied.saturated = true;
            }
            applied.max_torque = applied.max_torque.max(tau[i].abs());
        }
    }
    Ok(applied)
}

/// A physics that a controller steps one physics step at a time, recording the motion as
/// it goes: legwork's [`Simulator`], or another simulator behind a pipe
/// ([`crate::export::MujocoPlant`]). A receding-horizon controller's closed loop
/// ([`crate::mpc::run_closed_loop`]) runs on either.
pub trait Plant {
    /// The measured state; its contact anchors are legwork's contact model's (a plant that
    /// has none estimates them from the measured feet).
    fn state(&self) -> &SimState;
    /// The physics step (s).
    fn physics_dt(&self) -> f64;
    /// Time between recorded knots (s).
    fn record_dt(&self) -> f64;
    /// One physics step (the controller asked at control instants), recording the knot of
    /// the step's start on the recording grid.
    fn step_recorded(&mut self, controller: &mut dyn Controller, trajectory: &mut Trajectory) -> Result<(), SimError>;
    /// Appends the current state to `trajectory` if it falls on the recording grid.
    fn record_final(&mut self, trajectory: &mut Trajectory) -> Result<(), SimError>;
}

impl Plant for Simulator<'_> {
    fn state(&self) -> &SimState {
        Simulator::state(self)
    }
    fn physics_dt(&self) -> f64 {
        self.config.physics_dt
    }
    fn record_dt(&self) -> f64 {
        self.config.record_dt
    }
    fn step_recorded(&mut self, controller: &mut dyn Controller, trajectory: &mut Trajectory) -> Result<(), SimError> {
        Simulator::step_recorded(self, controller, trajectory)
    }
    fn record_final(&mut self, trajectory: &mut Trajectory) -> Result<(), SimError> {
        Simulator::record_final(self, trajectory);
        Ok(())
    }
}

/// A controller that cannot produce torques.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{controller}: {problem}")]
pub struct ControlError {
    pub controller: String,
    pub problem: String,
}

/// Why a simulation stopped or could not start.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    #[error("simulation setting `{field}`: {problem}")]
    Config { field: &'static str, problem: String },
    #[error(transparent)]
    Contact(#[from] ContactParamsError),
    #[error(transparent)]
    JointLimits(#[from] JointLimitParamsError),
    #[error("initial state: {0}")]
    InitialState(String),
    #[error("simulation diverged at step {step} (t = {t:.4} s): {reason}\n  q = {q:?}\n  v = {v:?}")]
    Diverged { step: u64, t: f64, reason: String, q: Vec<f64>, v: Vec<f64> },
    #[error("at t = {t:.4} s: {source}")]
    Controller { t: f64, source: ControlError },
    /// Another simulator behind a pipe failed (not the motion: the process, its files).
    #[error("{simulator}: {problem}")]
    External { simulator: String, problem: String },
}

/// What a run reports besides its trajectory.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RunStats {
    pub steps: u64,
    /// Largest penetration of any foot (m).
    pub max_penetration: f64,
    /// Largest absolute joint torque applied (N m).
    pub max_torque: f64,
    /// Largest ratio |F_t| / F_n over feet in contact (at most the friction coefficient).
    pub max_friction_ratio: f64,
    /// Physics steps in which some foot slipped (friction cone saturated).
    pub slipping_steps: u64,
    /// Control periods in which some torque was clipped to its effort limit.
    pub saturated_controls: u64,
    /// Wall-clock time of the run (s).
    pub wall_time: f64,
}

/// A finished run: the recorded trajectory and the figures.
#[derive(Clone, Debug)]
pub struct Run {
    pub trajectory: Trajectory,
    pub stats: RunStats,
}

/// The configuration `standing` of `model` (or its neutral configuration) moved up so that
/// the lowest foot sphere touches `terrain`, then `drop_height` higher.
pub fn standing_on_ground(model: &Model, terrain: &dyn Terrain, drop_height: f64) -> Result<DVector<f64>, SimError> {
    if !model.has_free_flyer() {
        return Err(SimError::InitialState(format!("robot '{}' has no free-flyer base to stand on the ground", model.name)));
    }
    if model.feet.is_empty() {
        return Err(SimError::InitialState(format!("robot '{}' has no feet", model.name)));
    }
    if !drop_height.is_finite() || drop_height < 0.0 {
        return Err(SimError::InitialState(format!("drop height must be a finite number >= 0 m, got {drop_height}")));
    }
    let mut q = model.reference_configuration("standing").cloned().unwrap_or_else(|| model.neutral());
    lift_onto_ground(model, terrain, &mut q, drop_height);
    Ok(q)
}

/// Moves the free-flyer base of `q` up or down so that the lowest foot sphere touches
/// `terrain`, then `drop_height` higher (the model must have a free flyer and feet, as
/// [`standing_on_ground`] checks).
pub fn lift_onto_ground(model: &Model, terrain: &dyn Terrain, q: &mut DVector<f64>, drop_height: f64) {
    let mut data = Data::new(model);
    forward_kinematics(model, &mut data, q);
    update_frame_placements(model, &mut data);
    // Height the base must rise by for the deepest foot sphere to just touch.
    let rise = model
        .feet
        .iter()
        .map(|f| {
            let p = data.o_m_f[f.frame].translation;
            let (h, n) = terrain.surface(p.x, p.y);
            f.radius / n.z - (p.z - h)
        })
        .fold(f64::NEG_INFINITY, f64::max);
    let iz = model.joints[1].idx_q + 2;
    q[iz] += rise + drop_height;
}

/// Runs a robot on a terrain with a controller; see the module documentation.
pub struct Simulator<'a> {
    model: &'a Model,
    config: SimConfig,
    workspace: ContactModelWorkspace<'a>,
    state: SimState,
    tau: DVector<f64>,
    pushes: Vec<Push>,
    control_every: usize,
    record_every: usize,
    step: u64,
    stats: RunStats,
    /// The physics step at which the controller was last called (so that `run` can call it
    /// for the first knot without calling it twice).
    last_control_step: Option<u64>,
}

impl<'a> Simulator<'a> {
    /// A simulator at `q0` (checked: length, finiteness, unit quaternion) with velocity
    /// `v0` (zero if `None`).
    pub fn new(model: &'a Model, terrain: &'a dyn Terrain, config: SimConfig, q0: DVector<f64>, v0: Option<DVector<f64>>) -> Result<Self, SimError> {
        let (control_every, record_every) = config.ratios(&model.contact)?;
        model.check_configuration(&q0).map_err(|e| SimError::InitialState(e.to_string()))?;
        let v0 = v0.unwrap_or_else(|| DVector::zeros(model.nv));
        model.check_tangent("initial velocity", &v0).map_err(|e| SimError::InitialState(e.to_string()))?;
        let workspace = ContactModelWorkspace::new(model, terrain).with_joint_limits(config.joint_limits);
        Ok(Self {
            model,
            state: SimState { t: 0.0, q: q0, v: v0, anchors: vec![None; model.feet.len()] },
            tau: DVector::zeros(model.nv),
            pushes: Vec::new(),
            control_every,
            record_every,
            step: 0,
            stats: RunStats::default(),
            last_control_step: None,
            workspace,
            config,
        })
    }

    /// Sets the hidden contact anchors (one per foot, as in [`SimState::anchors`]): a run
    /// that continues a state of the optimizer, which carries them, starts from the same
    /// state, tangential spring pre-loads included.
    pub fn set_contact_anchors(&mut self, anchors: &[Option<Vector3<f64>>]) -> Result<(), SimError> {
        if anchors.len() != self.model.feet.len() {
            return Err(SimError::InitialState(format!("expected {} contact anchors (one per foot), got {}", self.model.feet.len(), anchors.len())));
        }
        if let Some(k) = anchors.iter().position(|a| a.is_some_and(|a| a.iter().any(|x| !x.is_finite()))) {
            return Err(SimError::InitialState(format!("contact anchor of foot {k} is not finite")));
        }
        self.state.anchors.clone_from_slice(anchors);
        Ok(())
    }

    /// A simulator in the world a plan was made in, as its file records it: started at the
    /// plan's first state with its contact anchors (`metadata.initial_anchors`, so the
    /// tangential springs carry the plan's pre-load), and with the plan's joint stops
    /// (`metadata.joint_stops`, replacing `config.joint_limits`). The terrain is the caller's:
    /// build it from `plan.metadata.terrain` to replay on the plan's ground. `legwork solve`'s
    /// re-runs and `legwork simulate --controller track` both start here, so they agree.
    pub fn from_plan(model: &'a Model, terrain: &'a dyn Terrain, plan: &crate::io::Trajectory, config: SimConfig) -> Result<Self, SimError> {
        let first = plan.knots.first().ok_or_else(|| SimError::InitialState("the plan has no knots".into()))?;
        let config = SimConfig { joint_limits: plan.metadata.joint_stops, ..config };
        let mut sim = Self::new(model, terrain, config, DVector::from_column_slice(&first.q), Some(DVector::from_column_slice(&first.v)))?;
        if let Some(anchors) = &plan.metadata.initial_anchors {
            let anchors: Vec<Option<Vector3<f64>>> = anchors.iter().map(|a| a.map(Vector3::from)).collect();
            sim.set_contact_anchors(&anchors)?;
        }
        Ok(sim)
    }

    /// Adds a push on the base.
    pub fn add_push(&mut self, push: Push) {
        self.pushes.push(push);
    }

    pub fn state(&self) -> &SimState {
        &self.state
    }

    /// Torques applied over the current control period (`nv`, base entries zero).
    pub fn applied_torque(&self) -> &DVector<f64> {
        &self.tau
    }

    /// Per-foot contact results of the last physics step.
    pub fn feet(&self) -> &[FootState] {
        self.workspace.feet()
    }

    pub fn stats(&self) -> &RunStats {
        &self.stats
    }

    /// One physics step (and a controller call at control instants).
    pub fn step(&mut self, controller: &mut dyn Controller) -> Result<(), SimError> {
        self.step_recording(controller, None)
    }

    /// The step; with `record`, the knot of the state at the step's start (its contacts,
    /// the torques applied from it) is appended before integrating.
    fn step_recording(&mut self, controller: &mut dyn Controller, record: Option<&mut Trajectory>) -> Result<(), SimError> {
        if self.step % self.control_every as u64 == 0 && self.last_control_step != Some(self.step) {
            self.control(controller)?;
        }
        let push: Vector3<f64> = self.pushes.iter().filter(|p| p.active(self.state.t)).map(|p| p.force).sum();
        let dt = self.config.physics_dt;
        self.workspace.evaluate_contacts(&self.state.q, &self.state.v, &self.state.anchors);
        if let Some(trajectory) = record {
            trajectory.knots.push(self.knot());
        }
        let state = &mut self.state;
        match self.config.integrator {
            Integrator::SemiImplicitEuler => {
                self.workspace.integrate_semi_implicit(&mut state.q, &mut state.v, &mut state.anchors, &self.tau, &push, dt)
            }
            Integrator::Rk4 => self.workspace.integrate_rk4(&mut state.q, &mut state.v, &mut state.anchors, &self.tau, &push, dt),
        }
        state.t += dt;
        self.step += 1;
        self.check_state()?;
        let mut slipping = false;
        for f in self.workspace.feet() {
            self.stats.max_penetration = self.stats.max_penetration.max(f.contact.penetration);
            if f.contact.normal_force > 1e-9 {
                let n = f.normal;
                let ft = (f.contact.force - n * n.dot(&f.contact.force)).norm();
                self.stats.max_friction_ratio = self.stats.max_friction_ratio.max(ft / f.contact.normal_force);
            }
            slipping |= f.contact.slipping;
        }
        self.stats.slipping_steps += slipping as u64;
        self.stats.steps = self.step;
        Ok(())
    }

    fn control(&mut self, controller: &mut dyn Controller) -> Result<(), SimError> {
        self.last_control_step = Some(self.step);
        let applied = controller_torques(self.model, controller, &self.state, &mut self.tau, self.config.enforce_effort_limits)?;
        self.stats.max_torque = self.stats.max_torque.max(applied.max_torque);
        self.stats.saturated_controls += applied.saturated as u64;
        Ok(())
    }

    fn check_state(&self) -> Result<(), SimError> {
        let s = &self.state;
        let reason = if let Some(i) = s.q.iter().position(|x| !x.is_finite()) {
            Some(format!("q[{i}] is {}", s.q[i]))
        } else if let Some(i) = s.v.iter().position(|x| !x.is_finite()) {
            Some(format!("v[{i}] is {}", s.v[i]))
        } else {
            s.v.iter()
                .position(|x| x.abs() > self.config.max_speed)
                .map(|i| format!("|v[{i}]| = {:.3e} exceeds max_speed = {}", s.v[i].abs(), self.config.max_speed))
        };
        match reason {
            None => Ok(()),
            Some(reason) => Err(SimError::Diverged { step: self.step, t: s.t, reason, q: s.q.iter().copied().collect(), v: s.v.iter().copied().collect() }),
        }
    }

    /// The current state as a trajectory knot: the torques applied over the current control
    /// period (actuated joints) and the contacts of the last evaluation.
    pub fn knot(&self) -> Knot {
        let nj = self.model.nv - 6;
        Knot {
            t: self.state.t,
            q: self.state.q.iter().copied().collect(),
            v: self.state.v.iter().copied().collect(),
            tau: self.tau.rows(6, nj).iter().copied().collect(),
            contact_force: self.workspace.feet().iter().map(|f| f.contact.force.into()).collect(),
            in_contact: self.workspace.feet().iter().map(|f| f.contact.normal_force > 0.0).collect(),
            feedback_gain: None,
        }
    }

    /// One physics step, as [`Self::step`], recording into `trajectory` the knot of the
    /// state at the step's start when the step count is a multiple of the recording ratio
    /// (`record_dt / physics_dt`): a loop that interleaves the simulator with other work
    /// (a receding-horizon controller's ticks) records as [`Self::run`] does.
    pub fn step_recorded(&mut self, controller: &mut dyn Controller, trajectory: &mut Trajectory) -> Result<(), SimError> {
        let record = self.step % self.record_every as u64 == 0;
        self.step_recording(controller, if record { Some(trajectory) } else { None })
    }

    /// Appends the current state (its contacts evaluated, the torques of the last control
    /// period) to `trajectory` if it falls on the recording grid: the end of a recorded run.
    pub fn record_final(&mut self, trajectory: &mut Trajectory) {
        self.workspace.evaluate_contacts(&self.state.q, &self.state.v, &self.state.anchors);
        if self.step % self.record_every as u64 == 0 {
            trajectory.knots.push(self.knot());
        }
    }

    /// The simulator's settings.
    pub fn config(&self) -> &SimConfig {
        &self.config
    }

    /// Runs for `duration` seconds, recording a knot every `record_dt` (and the initial
    /// state); `on_progress` receives the fraction done about a hundred times.
    pub fn run(&mut self, duration: f64, controller: &mut dyn Controller, mut on_progress: impl FnMut(f64)) -> Result<Run, SimError> {
        if !(duration > 0.0 && duration.is_finite()) {
            return Err(SimError::Config { field: "duration", problem: format!("expected a positive number of seconds, got {duration}") });
        }
        let steps = (duration / self.config.physics_dt).round() as u64;
        let mut trajectory = Trajectory::new(self.model, format!("simulate {}", controller.name()), self.config.record_dt, self.workspace.terrain().spec());
        let start = std::time::Instant::now();
        let progress_every = (steps / 100).max(1);
        let first = self.step;
        for k in 0..steps {
            let record = (self.step - first) % self.record_every as u64 == 0;
            self.step_recording(controller, if record { Some(&mut trajectory) } else { None })?;
            if k % progress_every == 0 {
                on_progress(k as f64 / steps as f64);
            }
        }
        // The final state, with its contacts and the torques of the last control period.
        self.workspace.evaluate_contacts(&self.state.q, &self.state.v, &self.state.anchors);
        if (self.step - first) % self.record_every as u64 == 0 {
            trajectory.knots.push(self.knot());
        }
        self.stats.wall_time += start.elapsed().as_secs_f64();
        Ok(Run { trajectory, stats: self.stats.clone() })
    }
}
