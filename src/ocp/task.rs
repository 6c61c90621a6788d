//! Task files: what a user asks of the robot, in the terms of Neunert 2017 (desired states,
//! weights per coordinate group, waypoints) and nothing else: no contacts, gaits or timings.
//!
//! ```toml
//! name = "squat_jump"
//! summary = "jump to a 0.8 m apex and land in the default stance"
//! robot = "hyq"
//! duration = 1.5            # s
//! dt = 0.002                # s: knot spacing (the input is held over it)
//! substeps = 2              # integration steps per knot (optional; also the SLQ policy re-run's physics step, dt / substeps;
//!                           # default: the fewest that keep dt / substeps within the robot's contact.max_step)
//! iterations = 40           # SLQ iteration limit (optional)
//! flat_cost_tolerance = 1e-3 # stop when 5 iterations lower the cost by less than this fraction of the initial cost (optional; 0 = never)
//!
//! [joint_limits]            # optional: stops at the joints' position limits (JointLimitParams fields; empty = defaults)
//! stiffness = 5000.0
//!
//! [joint_limit_cost]        # optional: a running cost w sum r^2 on joint positions r rad outside [lower + margin, upper - margin]
//! weight = 1e4
//! margin = 0.05             # rad (0 if absent)
//!
//! [continuation]            # optional: solve shorter horizons first (see legwork::ocp::ContinuationSpec)
//! horizons = [0.5, 1.0]     # s
//! iterations = 4            # per stage, counted in the task's limit
//! progress_exponent = 1.6   # a stage's base goal: start + (goal - start) (T_s / T)^e
//!
//! [exploration]             # optional: solve from many perturbed initial laws, keep the best (see legwork::ocp::ExplorationSpec)
//! starts = 8                # the unperturbed standing PD is start 0
//! seed = 0
//! screen_iterations = 10    # per start and round; the kept start's count in the task's limit
//! rounds = 1                # successive halving: the cheaper half of the starts goes on each round
//!
//! [desired]                 # the desired state of the running and final costs
//! base_position = [0.0, 0.0, "start"]   # m, world; "start" = the initial state's value
//! base_rpy = [0.0, 0.0, 0.0]            # rad
//! joints = "stance"                     # "stance", or { "*_hfe_joint" = 0.9, lf_kfe_joint = -1.6 }
//! # base_linear_velocity, base_angular_velocity (base frame), joint_velocities: zero if absent
//!
//! [running]                 # Q: weights per coordinate group (absent = 0)
//! base_position = [0.0, 0.0, 10.0]
//! base_orientation = [50.0, 50.0, 50.0]
//! joint_position = 1.0      # one number, or { "*_kfe_joint" = 2.0, ... }
//! base_linear_velocity = [0.1, 0.1, 0.1]
//! base_angular_velocity = [0.1, 0.1, 0.1]
//! joint_velocity = 0.01
//!
//! [final]                   # H: the same keys
//! base_position = [1000.0, 1000.0, 1000.0]
//!
//! [input]
//! weight = 1e-4             # R (diagonal)
//!
//! [[waypoint]]              # eq. (5): any number of these
//! time = 0.6                # s
//! rho = 400.0               # 1/s^2: window exp(-rho/2 (t - time)^2)
//! desired = { base_position = [0.0, 0.0, 0.8] }
//! weights = { base_position = [0.0, 0.0, 2000.0] }
//!
//! [[target]]                # what counts as done (any number; see legwork::ocp::Target)
//! at = "apex"
//! base_position = ["any", "any", 0.8]
//! position_tolerance = 0.01
//! ```
//!
//! Every field is checked; unknown fields, a joint name the robot does not have, a NaN or a
//! negative weight are errors naming the file and the field. A task says nothing of how the
//! world behaves: the contact model belongs to the robot (its description's `[contact]`
//! section, [`crate::model::Model::contact`]), and a `[contact]` section here is an error.

use super::{RobotState, StateCost, Waypoint, WholeBodyProblem};
use crate::model::Model;
use crate::terrain::Terrain;
use nalgebra::{DVector, UnitQuaternion};
use serde::Deserialize;
use std::collections::BTreeMap;

/// A number, or the keyword `"start"` (the initial state's value).
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(untagged)]
pub enum Coordinate {
    Value(f64),
    Keyword(String),
}

/// `"stance"` or a table `joint name (with an optional '*' wildcard) = value`.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(untagged)]
pub enum JointValues {
    Keyword(String),
    Table(BTreeMap<String, f64>),
}

/// One number for every joint, or a table by name pattern.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(untagged)]
pub enum JointWeights {
    All(f64),
    Table(BTreeMap<String, f64>),
}

/// A desired state in intuitive terms; absent fields keep the defaults (see module docs).
#[derive(Clone, Debug, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DesiredSpec {
    pub base_position: Option<[Coordinate; 3]>,
    pub base_rpy: Option<[Coordinate; 3]>,
    pub joints: Option<JointValues>,
    pub base_linear_velocity: Option<[f64; 3]>,
    pub base_angular_velocity: Option<[f64; 3]>,
    pub joint_velocities: Option<f64>,
    /// Foot positions (world, m) by foot name; `"start"` = the foot's initial coordinate.
    pub feet: Option<BTreeMap<String, [Coordinate; 3]>>,
}

/// Weights per coordinate group; absent = 0.
#[derive(Clone, Debug, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WeightSpec {
    pub base_position: Option<[f64; 3]>,
    pub base_orientation: Option<[f64; 3]>,
    pub joint_position: Option<JointWeights>,
    pub base_linear_velocity: Option<[f64; 3]>,
    pub base_angular_velocity: Option<[f64; 3]>,
    pub joint_velocity: Option<JointWeights>,
    /// Weights on foot positions (x, y, z) by foot name; a weighted foot without a desired
    /// position is held where it started.
    pub feet: Option<BTreeMap<String, [f64; 3]>>,
}

#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InputSpec {
    /// `R`, the same for every joint.
    pub weight: f64,
}

#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WaypointSpec {
    pub time: f64,
    pub rho: f64,
    #[serde(default)]
    pub desired: DesiredSpec,
    pub weights: WeightSpec,
}

/// A task file.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TaskSpec {
    pub name: String,
    pub summary: String,
    pub robot: String,
    pub duration: f64,
    pub dt: f64,
    /// Integration steps per knot interval (1): the dynamics, and the simulator's physics in
    /// the SLQ policy re-run, step `dt / substeps`.
    #[serde(default)]
    pub substeps: Option<usize>,
    #[serde(default)]
    pub iterations: Option<usize>,
    /// Overrides [`crate::slq::SlqSettings::normalized_cost_tolerance`] (1e-3; 0 turns the
    /// test off): a task whose initial cost is dominated by one early, large correction
    /// (standing up) makes its later progress look flat.
    #[serde(default)]
    pub flat_cost_tolerance: Option<f64>,
    /// Not allowed: read only to say where contact parameters go.
    #[serde(default)]
    contact: Option<toml::Value>,
    /// The joints' mechanical stops at their position limits, in the dynamics and both
    /// re-runs (absent: none, as [`crate::sim::SimConfig`]'s default).
    #[serde(default)]
    pub joint_limits: Option<crate::sim::JointLimitParams>,
    /// A running cost on joint positions outside their limits (absent: none).
    #[serde(default)]
    pub joint_limit_cost: Option<super::JointLimitCostSpec>,
    /// Solve shorter horizons first (absent: the full horizon from the standing PD only).
    #[serde(default)]
    pub continuation: Option<super::ContinuationSpec>,
    /// Solve the first problem from many perturbed initial control laws and keep the best
    /// (absent: the standing PD alone; see [`super::ExplorationSpec`]).
    #[serde(default)]
    pub exploration: Option<super::ExplorationSpec>,
    #[serde(default)]
    pub desired: DesiredSpec,
    pub running: WeightSpec,
    #[serde(rename = "final")]
    pub terminal: WeightSpec,
    pub input: InputSpec,
    #[serde(default, rename = "waypoint")]
    pub waypoints: Vec<WaypointSpec>,
    /// What counts as done (`[[target]]`, see [`super::Target`]); absent: no target, and
    /// `legwork solve` says so.
    #[serde(default, rename = "target")]
    pub targets: Vec<super::TargetSpec>,
}

/// A task file that cannot be used; names the file and the field.
#[derive(Debug, thiserror::Error)]
pub enum TaskError {
    #[error("{path}: cannot read the task: {error}")]
    Io { path: String, error: std::io::Error },
    #[error("{origin}: {message}")]
    Parse { origin: String, message: String },
    #[error("{origin}: field `{field}`: {problem}")]
    Invalid { origin: String, field: String, problem: String },
    #[error("no embedded task named '{name}' (embedded tasks: {known})")]
    UnknownTask { name: String, known: String },
}

/// The longest knot interval a task may ask for (s).
pub const MAX_DT: f64 = 0.02;

/// The embedded tasks (Neunert 2017, sec. V), as `(name, TOML text)`.
pub const EMBEDDED_TASKS: &[(&str, &str)] = &[
    ("gallop", include_str!("../../tasks/gallop.toml")),
    ("trot", include_str!("../../tasks/trot.toml")),
    ("squat_jump", include_str!("../../tasks/squat_jump.toml")),
    ("rearing", include_str!("../../tasks/rearing.toml")),
    ("diagonal_balance", include_str!("../../tasks/diagonal_balance.toml")),
    ("pallet_push", include_str!("../../tasks/pallet_push.toml")),
    ("sidestep", include_str!("../../tasks/sidestep.toml")),
    ("turn", include_str!("../../tasks/turn.toml")),
    ("humanoid_walk", include_str!("../../tasks/humanoid_walk.toml")),
];

/// The TOML text of the embedded task `name`.
pub(super) fn embedded_text(name: &str) -> Result<&'static str, TaskError> {
    EMBEDDED_TASKS.iter().find(|(n, _)| *n == name).map(|(_, text)| *text).ok_or_else(|| TaskError::UnknownTask {
        name: name.into(),
        known: EMBEDDED_TASKS.iter().map(|(n, _)| *n).collect::<Vec<_>>().join(", "),
    })
}

/// The text of a task file; the error names it.
pub(super) fn read_task_file(path: &std::path::Path) -> Result<String, TaskError> {
    std::fs::read_to_string(path).map_err(|error| TaskError::Io { path: path.display().to_string(), error })
}

/// The fewest integration steps that keep a knot of `dt` seconds in steps of at most
/// `max_step` (the robot's `contact.max_step`): a task's default `substeps`, and a receding
/// window's ([`crate::mpc::MpcSettings::substeps`]).
pub fn fewest_substeps(dt: f64, max_step: f64) -> usize {
    ((dt / max_step) * (1.0 - 1e-9)).ceil().max(1.0) as usize
}

impl TaskSpec {
    /// Parses TOML text; `origin` (a path or `embedded task NAME`) goes into errors.
    pub fn from_toml(text: &str, origin: &str) -> Result<Self, TaskError> {
        let spec: TaskSpec = toml::from_str(text).map_err(|e| TaskError::Parse { origin: origin.into(), message: e.to_string() })?;
        spec.check_numbers(origin)?;
        Ok(spec)
    }

    /// Reads a task file.
    pub fn load_file(path: impl AsRef<std::path::Path>) -> Result<Self, TaskError> {
        let name = path.as_ref().display().to_string();
        Self::from_toml(&read_task_file(path.as_ref())?, &name)
    }

    /// An embedded task by name.
    pub fn embedded(name: &str) -> Result<Self, TaskError> {
        Self::from_toml(embedded_text(name)?, &format!("embedded task {name}"))
    }

    /// The task's own robot (`robot = "..."`: an embedded name or a file), loaded; an error
    /// names the task and the field.
    pub fn load_robot(&self, origin: &str) -> Result<Model, TaskError> {
        crate::model::load(&self.robot).map_err(|e| TaskError::Invalid { origin: origin.into(), field: "robot".into(), problem: e.to_string() })
    }

    /// The task's targets, resolved for `model`; names the file and field of a bad one.
    pub fn target(&self, model: &Model, origin: &str) -> Result<super::Target, TaskError> {
        super::Target::resolve(&self.targets, model, self.duration, origin)
    }

    /// Number of knots.
    pub fn knots(&self) -> usize {
        (self.duration / self.dt).round() as usize
    }

    /// The memory a solve of this task needs, estimated (bytes): 12 MB plus 64 KB per knot
    /// (the SLQ linearizations, gains and rollouts, the re-runs). Measured as the peak
    /// resident size of `legwork solve` on HyQ: 35 MB at 500 knots, 116 MB at 2000, 226 MB at
    /// 4000 (55 KB per knot), the gallop's 1500 knots with its continuation 106 MB (2026-12-03).
    pub fn estimated_memory_bytes(&self) -> f64 {
        12e6 + 64e3 * (self.duration / self.dt)
    }

    /// `Err(what the screening does not fit in)` if `exploration`'s screening (the kept
    /// start's `screen_iterations x rounds`) leaves no iteration of `limit` after it: it must
    /// fit in the first continuation stage's iterations, or be fewer than `limit`.
    pub fn exploration_budget(&self, exploration: &super::ExplorationSpec, limit: usize) -> Result<(), String> {
        let screening = exploration.screen_iterations * exploration.rounds;
        match &self.continuation {
            Some(c) if screening > c.iterations => Err(format!("the first continuation stage's {} iterations", c.iterations)),
            None if screening >= limit => Err(format!("fewer than the iteration limit of {limit}")),
            _ => Ok(()),
        }
    }

    /// As [`Self::estimated_memory_bytes`] for a solve that explores with `exploration` on
    /// `threads` threads: 12 MB plus, per knot, 72 KB for each of `1 + threads` solvers (the
    /// starts side by side, then the kept and the single start's final) and 8 KB for each
    /// solution the halving keeps (half the starts). Measured (2026-12-03, 2 threads): trot,
    /// 4000 knots, 16 starts x 3 rounds: 1.11 GB (estimate 1.13); humanoid_walk, 1500 knots,
    /// 16 x 3: 0.42 GB (estimate 0.43).
    pub fn estimated_memory_bytes_exploring(&self, exploration: Option<&super::ExplorationSpec>, threads: usize) -> f64 {
        let Some(e) = exploration.filter(|e| e.starts > 1 || e.sampling.is_some()) else { return self.estimated_memory_bytes() };
        let starts = e.starts + e.sampling.as_ref().map_or(0, |s| s.starts);
        let kept = if e.rounds > 1 { super::survivors(starts, 1) } else { 1 };
        let solvers = 1 + threads.max(1).min(starts.max(1));
        12e6 + (72e3 * solvers as f64 + 8e3 * kept as f64) * (self.duration / self.dt)
    }

    fn check_numbers(&self, origin: &str) -> Result<(), TaskError> {
        let bad = |field: String, problem: String| Err(TaskError::Invalid { origin: origin.into(), field, problem });
        if !(self.duration.is_finite() && self.duration > 0.0) {
            return bad("duration".into(), format!("expected a positive number of seconds, got {}", self.duration));
        }
        if !(self.dt.is_finite() && self.dt > 0.0 && self.dt <= self.duration) {
            return bad("dt".into(), format!("expected a positive time step no longer than the duration, got {}", self.dt));
        }
        // SLQ holds the input over a knot interval; through contact, the standing PD that
        // starts the optimization diverges for holds from about 10-30 ms on HyQ, and Neunert
        // 2017's tasks use 1-4 ms.
        if self.dt > MAX_DT {
            return bad("dt".into(), format!("expected at most {MAX_DT} s (the input is held over dt; legwork's tasks use 0.002 s, and from about 0.01 s the standing PD that starts the optimization no longer keeps the robot up), got {}", self.dt));
        }
        if self.substeps == Some(0) {
            return bad("substeps".into(), "expected at least 1".into());
        }
        if self.iterations == Some(0) {
            return bad("iterations".into(), "expected at least 1".into());
        }
        if let Some(t) = self.flat_cost_tolerance {
            if !(t.is_finite() && (0.0..1.0).contains(&t)) {
                return bad("flat_cost_tolerance".into(), format!("expected a fraction in [0, 1), got {t}"));
            }
        }
        if self.contact.is_some() {
            return bad("contact".into(), "a task may not set the contact model: contact parameters belong to the robot (the `[contact]` section of its description, legwork::model::description), so that the optimizer, the simulator and the MuJoCo check share one world; remove this section".into());
        }
        if let Some(j) = &self.joint_limits {
            j.validate().map_err(|e| TaskError::Invalid { origin: origin.into(), field: format!("joint_limits.{}", e.field), problem: format!("expected {}, got {}", e.expected, e.value) })?;
        }
        if let Some(c) = &self.joint_limit_cost {
            if !(c.weight.is_finite() && c.weight >= 0.0) {
                return bad("joint_limit_cost.weight".into(), format!("expected a finite number >= 0, got {}", c.weight));
            }
            if !(c.margin.is_finite() && c.margin >= 0.0) {
                return bad("joint_limit_cost.margin".into(), format!("expected a finite angle >= 0 (rad), got {}", c.margin));
            }
        }
        if let Some(e) = &self.exploration {
            e.validate().map_err(|(field, problem)| TaskError::Invalid { origin: origin.into(), field: format!("exploration.{field}"), problem })?;
            let limit = self.iterations.unwrap_or(crate::slq::SlqSettings::default().max_iterations);
            if let Err(budget) = self.exploration_budget(e, limit) {
                return bad("exploration.screen_iterations".into(), format!("expected screen_iterations x rounds to fit in {budget}, got {} x {}", e.screen_iterations, e.rounds));
            }
        }
        if let Some(c) = &self.continuation {
            c.check(self.duration, self.dt).map_err(|(field, problem)| TaskError::Invalid { origin: origin.into(), field: format!("continuation.{field}"), problem })?;
            let limit = self.iterations.unwrap_or(crate::slq::SlqSettings::default().max_iterations);
            if c.stage_iterations() >= limit {
                return bad("continuation.iterations".into(), format!("expected fewer than the task's {limit} iterations over the {} stages, got {} each", c.horizons.len(), c.iterations));
            }
        }
        if !(self.input.weight.is_finite() && self.input.weight >= 0.0) {
            return bad("input.weight".into(), format!("expected a finite number >= 0, got {}", self.input.weight));
        }
        check_weights(&self.running, "running", origin)?;
        check_weights(&self.terminal, "final", origin)?;
        for (i, w) in self.waypoints.iter().enumerate() {
            if !(w.time.is_finite() && w.time >= 0.0 && w.time <= self.duration) {
                return bad(format!("waypoint[{i}].time"), format!("expected a time within [0, duration = {}] s, got {}", self.duration, w.time));
            }
            if !(w.rho.is_finite() && w.rho > 0.0) {
                return bad(format!("waypoint[{i}].rho"), format!("expected a positive precision (1/s^2), got {}", w.rho));
            }
            check_weights(&w.weights, &format!("waypoint[{i}].weights"), origin)?;
        }
        Ok(())
    }

    /// Integration steps per knot interval: the task's `substeps`, checked against the
    /// robot's stable contact step, or the fewest that keep `dt / substeps` within it.
    pub fn substeps(&self, model: &Model, origin: &str) -> Result<usize, TaskError> {
        let max_step = model.contact.max_step;
        let fewest = fewest_substeps(self.dt, max_step);
        match self.substeps {
            None => Ok(fewest),
            Some(n) if n >= fewest => Ok(n),
            Some(n) => Err(TaskError::Invalid {
                origin: origin.into(),
                field: "substeps".into(),
                problem: format!("{n} steps of {} s each: the robot's contact model is stable only up to {max_step} s steps (contact.max_step); use at least {fewest}, or leave `substeps` out", self.dt / n as f64),
            }),
        }
    }

    /// The optimal-control problem for `model` on `terrain` from `initial`.
    pub fn problem<'a>(&self, model: &'a Model, terrain: &'a dyn Terrain, initial: RobotState, origin: &str) -> Result<WholeBodyProblem<'a>, TaskError> {
        let stance = model.reference_configuration("standing").cloned().unwrap_or_else(|| model.neutral());
        let running_desired = desired_state(&self.desired, model, &initial, &stance, origin, "desired")?;
        let running = StateCost {
            q: running_desired.0.clone(),
            v: running_desired.1.clone(),
            weights: weights(&self.running, model, origin, "running")?,
            feet: foot_targets(&self.desired, &self.running, model, &initial, origin, "running")?,
        };
        let terminal = StateCost {
            q: running_desired.0,
            v: running_desired.1,
            weights: weights(&self.terminal, model, origin, "final")?,
            feet: foot_targets(&self.desired, &self.terminal, model, &initial, origin, "final")?,
        };
        let mut waypoints = Vec::new();
        for (i, w) in self.waypoints.iter().enumerate() {
            // A waypoint's desired state starts from the task's desired state.
            let merged = merge(&self.desired, &w.desired);
            let (q, v) = desired_state(&merged, model, &initial, &stance, origin, &format!("waypoint[{i}].desired"))?;
            let section = format!("waypoint[{i}]");
            let cost = StateCost { q, v, weights: weights(&w.weights, model, origin, &format!("{section}.weights"))?, feet: foot_targets(&merged, &w.weights, model, &initial, origin, &section)? };
            waypoints.push(Waypoint { time: w.time, rho: w.rho, cost });
        }
        let nu = model.nv - 6;
        Ok(WholeBodyProblem {
            model,
            terrain,
            joint_limits: self.joint_limits,
            dt: self.dt,
            substeps: self.substeps(model, origin)?,
            knots: self.knots(),
            tail: None,
            initial,
            running,
            terminal,
            input_weights: DVector::from_element(nu, self.input.weight),
            input_desired: DVector::zeros(nu),
            effort_limits: DVector::from_iterator(nu, model.actuated_joints().map(|j| j.limits.effort[0])),
            waypoints,
            joint_limit_cost: self.joint_limit_cost.map(|spec| super::JointLimitCost::new(model, spec)),
            // Every task gets the feasibility constraints (issue 16): no task field turns them off.
            feasibility: Some(super::FeasibilityConstraints::new(model, self.knots(), super::FeasibilitySettings::default()).map_err(|e| TaskError::Invalid { origin: origin.into(), field: format!("(feasibility constraints) {}", e.field), problem: e.to_string() })?),
            // The anchors as states of the linearization: the held-anchor model mispredicts
            // every touch-down and slip (see `crate::sim::AnchorStepDerivatives`).
            anchor_states: true,
            linearization: super::KnotLinearization::EverySubstep,
            receding: None,
        })
    }
}

/// A waypoint's desired state: its own fields over the task's.
fn merge(base: &DesiredSpec, over: &DesiredSpec) -> DesiredSpec {
    DesiredSpec {
        base_position: over.base_position.clone().or_else(|| base.base_position.clone()),
        base_rpy: over.base_rpy.clone().or_else(|| base.base_rpy.clone()),
        joints: over.joints.clone().or_else(|| base.joints.clone()),
        base_linear_velocity: over.base_linear_velocity.or(base.base_linear_velocity),
        base_angular_velocity: over.base_angular_velocity.or(base.base_angular_velocity),
        joint_velocities: over.joint_velocities.or(base.joint_velocities),
        feet: over.feet.clone().or_else(|| base.feet.clone()),
    }
}

fn check_weights(w: &WeightSpec, section: &str, origin: &str) -> Result<(), TaskError> {
    let bad = |field: &str, value: f64| Err(TaskError::Invalid { origin: origin.into(), field: format!("{section}.{field}"), problem: format!("expected finite weights >= 0, got {value}") });
    for (field, values) in [("base_position", w.base_position), ("base_orientation", w.base_orientation), ("base_linear_velocity", w.base_linear_velocity), ("base_angular_velocity", w.base_angular_velocity)] {
        if let Some(v) = values {
            if let Some(x) = v.iter().find(|x| !(x.is_finite() && **x >= 0.0)) {
                return bad(field, *x);
            }
        }
    }
    for (field, values) in [("joint_position", &w.joint_position), ("joint_velocity", &w.joint_velocity)] {
        let numbers: Vec<f64> = match values {
            Some(JointWeights::All(x)) => vec![*x],
            Some(JointWeights::Table(t)) => t.values().copied().collect(),
            None => vec![],
        };
        if let Some(x) = numbers.iter().find(|x| !(x.is_finite() && **x >= 0.0)) {
            return bad(field, *x);
        }
    }
    Ok(())
}

/// `pattern` with at most one `*` matches `name`.
fn matches(pattern: &str, name: &str) -> bool {
    match pattern.split_once('*') {
        None => pattern == name,
        Some((pre, post)) => name.len() >= pre.len() + post.len() && name.starts_with(pre) && name.ends_with(post),
    }
}

/// Applies a name-pattern table to `out` (indexed by `index(joint)`); every pattern must
/// match some joint.
fn apply_table(table: &BTreeMap<String, f64>, model: &Model, origin: &str, field: &str, mut set: impl FnMut(&crate::model::Joint, f64)) -> Result<(), TaskError> {
    for (pattern, value) in table {
        if !value.is_finite() {
            return Err(TaskError::Invalid { origin: origin.into(), field: format!("{field}.{pattern}"), problem: format!("expected a finite number, got {value}") });
        }
        let mut any = false;
        for j in model.actuated_joints().filter(|j| matches(pattern, &j.name)) {
            set(j, *value);
            any = true;
        }
        if !any {
            let names: Vec<&str> = model.actuated_joints().map(|j| j.name.as_str()).collect();
            return Err(TaskError::Invalid {
                origin: origin.into(),
                field: format!("{field}.{pattern}"),
                problem: format!("matches no joint of robot '{}' (its joints: {})", model.name, names.join(", ")),
            });
        }
    }
    Ok(())
}

fn coordinate(c: &Coordinate, start: f64, origin: &str, field: String) -> Result<f64, TaskError> {
    match c {
        Coordinate::Value(x) if x.is_finite() => Ok(*x),
        Coordinate::Keyword(k) if k == "start" => Ok(start),
        other => Err(TaskError::Invalid { origin: origin.into(), field, problem: format!("expected a finite number or \"start\", got {other:?}") }),
    }
}

/// The desired `(q, v)` of a spec.
fn desired_state(spec: &DesiredSpec, model: &Model, initial: &RobotState, stance: &DVector<f64>, origin: &str, section: &str) -> Result<(DVector<f64>, DVector<f64>), TaskError> {
    let mut q = stance.clone();
    let start = &initial.q;
    for i in 0..3 {
        q[i] = match &spec.base_position {
            Some(p) => coordinate(&p[i], start[i], origin, format!("{section}.base_position[{i}]"))?,
            None => start[i],
        };
    }
    let start_rpy = crate::dynamics::base_orientation(start.as_slice()).euler_angles();
    let start_rpy = [start_rpy.0, start_rpy.1, start_rpy.2];
    let mut rpy = [0.0; 3];
    if let Some(r) = &spec.base_rpy {
        for i in 0..3 {
            rpy[i] = coordinate(&r[i], start_rpy[i], origin, format!("{section}.base_rpy[{i}]"))?;
        }
    }
    let quat = UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]);
    q[3] = quat.i;
    q[4] = quat.j;
    q[5] = quat.k;
    q[6] = quat.w;
    match &spec.joints {
        None => {}
        Some(JointValues::Keyword(k)) if k == "stance" => {}
        Some(JointValues::Keyword(k)) if k == "start" => {
            for j in model.actuated_joints() {
                q[j.idx_q] = start[j.idx_q];
            }
        }
        Some(JointValues::Keyword(k)) => {
            return Err(TaskError::Invalid { origin: origin.into(), field: format!("{section}.joints"), problem: format!("expected \"stance\", \"start\" or a table of joint angles, got \"{k}\"") });
        }
        Some(JointValues::Table(t)) => apply_table(t, model, origin, &format!("{section}.joints"), |j, x| q[j.idx_q] = x)?,
    }
    let mut v = DVector::zeros(model.nv);
    for (offset, values) in [(0, spec.base_linear_velocity), (3, spec.base_angular_velocity)] {
        if let Some(x) = values {
            for i in 0..3 {
                v[offset + i] = x[i];
            }
        }
    }
    if let Some(x) = spec.joint_velocities {
        for j in model.actuated_joints() {
            v[j.idx_v] = x;
        }
    }
    if !v.iter().all(|x| x.is_finite()) {
        return Err(TaskError::Invalid { origin: origin.into(), field: format!("{section}.velocities"), problem: "expected finite numbers".into() });
    }
    Ok((q, v))
}

/// Foot targets: every foot with weights, at its desired position (or where it started).
fn foot_targets(desired: &DesiredSpec, w: &WeightSpec, model: &Model, initial: &RobotState, origin: &str, section: &str) -> Result<Vec<super::FootTarget>, TaskError> {
    let mut data = crate::dynamics::Data::new(model);
    crate::dynamics::forward_kinematics(model, &mut data, &initial.q);
    let foot_index = |name: &str, field: String| {
        model.feet.iter().position(|f| f.name == name).ok_or_else(|| TaskError::Invalid {
            origin: origin.into(),
            field,
            problem: format!("robot '{}' has no foot '{name}' (its feet: {})", model.name, model.feet.iter().map(|f| f.name.as_str()).collect::<Vec<_>>().join(", ")),
        })
    };
    if let Some(d) = &desired.feet {
        for name in d.keys() {
            foot_index(name, format!("{section}.desired.feet.{name}"))?;
        }
    }
    let mut targets = Vec::new();
    for (name, weights) in w.feet.iter().flatten() {
        let field = format!("{section}.weights.feet.{name}");
        let foot = foot_index(name, field.clone())?;
        if let Some(x) = weights.iter().find(|x| !(x.is_finite() && **x >= 0.0)) {
            return Err(TaskError::Invalid { origin: origin.into(), field, problem: format!("expected finite weights >= 0, got {x}") });
        }
        let start = crate::dynamics::frame_position(model, &data, model.feet[foot].frame);
        let mut position = start;
        if let Some(coords) = desired.feet.as_ref().and_then(|d| d.get(name)) {
            for i in 0..3 {
                position[i] = coordinate(&coords[i], start[i], origin, format!("{section}.desired.feet.{name}[{i}]"))?;
            }
        }
        targets.push(super::FootTarget { foot, position, weights: nalgebra::Vector3::from(*weights) });
    }
    Ok(targets)
}

/// The diagonal weights of a spec (`2 nv`, in [`super::StateDeviation`]'s order).
fn weights(spec: &WeightSpec, model: &Model, origin: &str, section: &str) -> Result<DVector<f64>, TaskError> {
    let nv = model.nv;
    let mut w = DVector::zeros(2 * nv);
    for (offset, values) in [(0, spec.base_position), (3, spec.base_orientation), (nv, spec.base_linear_velocity), (nv + 3, spec.base_angular_velocity)] {
        if let Some(x) = values {
            for i in 0..3 {
                w[offset + i] = x[i];
            }
        }
    }
    for (offset, values, field) in [(0, &spec.joint_position, "joint_position"), (nv, &spec.joint_velocity, "joint_velocity")] {
        match values {
            None => {}
            Some(JointWeights::All(x)) => {
                for j in model.actuated_joints() {
                    w[offset + j.idx_v] = *x;
                }
            }
            Some(JointWeights::Table(t)) => apply_table(t, model, origin, &format!("{section}.{field}"), |j, x| w[offset + j.idx_v] = x)?,
        }
    }
    Ok(w)
}
