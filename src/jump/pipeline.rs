//! The jump pipeline of Nguyen 2022 (Fig. 2): the contact-timing optimization on the single
//! rigid body (sec. II-B), the full-body trajectory optimization from its result (sec.
//! II-C), the jump and landing controllers in legwork's simulator (sec. III).
//!
//! Each stage reports what it did or why it did not run. A stage this build does not have
//! is [`StageState::Missing`], never replaced by something else: the full-body stage and the
//! controllers come from other modules ([`MISSING_FULL_BODY`], [`MISSING_CONTROLLERS`]).

use super::spec::{Jump, StanceConflict};
use crate::control::whole_body::{leg_chains, legs_inverse_kinematics};
use crate::dynamics::Data;
use crate::io::{Knot, Trajectory};
use crate::ipocp::{Settings as SolverSettings, Status};
use crate::model::Model;
use crate::srb::{ContactTimingError, ContactTimingProblem, ContactTimingSettings, SrbKnot, SrbParams, SrbParamsError};
use crate::terrain::Terrain;
use nalgebra::{DVector, Rotation3, UnitQuaternion, Vector3};
use serde_json::json;
use std::time::Instant;

/// Why the full-body stage does not run in this build.
pub const MISSING_FULL_BODY: &str = "the full-body trajectory optimization (sec. II-C) is not in this build";
/// Why the controllers' re-run does not run in this build.
pub const MISSING_CONTROLLERS: &str = "the jump and landing controllers (sec. III) are not in this build";

/// What went wrong before a stage could report.
#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    #[error("jump '{jump}': the robot is '{robot}', the jump is for '{expected}'")]
    Robot { jump: String, robot: String, expected: String },
    #[error(transparent)]
    Params(#[from] SrbParamsError),
    #[error(transparent)]
    ContactTiming(#[from] ContactTimingError),
    #[error("contact timing: {0}")]
    Solver(String),
    #[error("the robot's legs: {0}")]
    Legs(String),
}

/// The contact-timing optimization's result.
#[derive(Clone, Debug)]
pub struct ContactTimingStage {
    pub status: Status,
    pub iterations: usize,
    pub objective: f64,
    /// Largest constraint violation at the result.
    pub primal_infeasibility: f64,
    /// Phase durations `T_i` (s).
    pub durations: Vec<f64>,
    /// Wall time of the solve (problem set-up excluded), s.
    pub solve_time_s: f64,
    /// Knots per phase `N_i` of the solve.
    pub knots_per_phase: usize,
    pub knots: Vec<SrbKnot>,
}

impl ContactTimingStage {
    pub fn solved(&self) -> bool {
        self.status == Status::Solved
    }
}

/// Whether a stage ran.
#[derive(Clone, Debug, PartialEq)]
pub enum StageState {
    Done,
    Failed(String),
    /// Not in this build (the reason).
    Missing(&'static str),
}

impl std::fmt::Display for StageState {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        match self {
            StageState::Done => write!(f, "done"),
            StageState::Failed(reason) => write!(f, "failed: {reason}"),
            StageState::Missing(reason) => write!(f, "not run: {reason}"),
        }
    }
}

/// The jump's outcome, with `legwork jump`'s exit code.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Verdict {
    /// The re-run met the target (upright, position and yaw within the tolerances).
    Landed,
    /// The contact-timing optimization did not converge.
    ContactTimingFailed,
    /// The full-body trajectory optimization did not converge.
    FullBodyFailed,
    /// The re-run landed upright, away from the target.
    MissedTarget,
    /// The re-run fell.
    Fell,
    /// A stage is not in this build: the jump was planned as far as the build goes.
    Incomplete,
}

impl Verdict {
    /// 0 for a landed jump; 1 is any error before the pipeline runs (bad file, no robot).
    pub fn exit_code(self) -> u8 {
        match self {
            Verdict::Landed => 0,
            Verdict::ContactTimingFailed => 2,
            Verdict::FullBodyFailed => 3,
            Verdict::MissedTarget => 4,
            Verdict::Fell => 5,
            Verdict::Incomplete => 6,
        }
    }
    pub fn describe(self) -> &'static str {
        match self {
            Verdict::Landed => "landed on target",
            Verdict::ContactTimingFailed => "the contact-timing optimization failed",
            Verdict::FullBodyFailed => "the full-body trajectory optimization failed",
            Verdict::MissedTarget => "landed upright, off target",
            Verdict::Fell => "fell",
            Verdict::Incomplete => "planned as far as this build goes (a stage is missing)",
        }
    }
}

/// Everything a jump's run reports.
#[derive(Clone, Debug)]
pub struct JumpReport {
    pub contact_timing: ContactTimingStage,
    pub full_body: StageState,
    pub controllers: StageState,
    /// Start feet off the box and landing feet over it (see [`Jump::stance_conflicts`]).
    pub stance_conflicts: Vec<StanceConflict>,
}

impl JumpReport {
    pub fn verdict(&self) -> Verdict {
        if !self.contact_timing.solved() {
            return Verdict::ContactTimingFailed;
        }
        match (&self.full_body, &self.controllers) {
            (StageState::Failed(_), _) => Verdict::FullBodyFailed,
            (StageState::Missing(_), _) | (_, StageState::Missing(_)) => Verdict::Incomplete,
            (_, StageState::Failed(_)) => Verdict::Fell,
            (StageState::Done, StageState::Done) => Verdict::Landed,
        }
    }

    /// The figures of the run as JSON (the trajectory file's summary).
    pub fn summary(&self, jump: &Jump) -> serde_json::Map<String, serde_json::Value> {
        let ct = &self.contact_timing;
        let value = json!({
            "jump": jump.name,
            "origin": jump.origin,
            "verdict": format!("{:?}", self.verdict()),
            "exit_code": self.verdict().exit_code(),
            "contact_timing": {
                "status": format!("{:?}", ct.status),
                "iterations": ct.iterations,
                "cost": ct.objective,
                "constraint_violation": ct.primal_infeasibility,
                "phase_durations_s": ct.durations,
                "phase_durations_10ms": ct.durations.iter().map(|t| (t * 1000.0).round() / 10.0).collect::<Vec<_>>(),
                "solve_time_s": ct.solve_time_s,
                "knots_per_phase": ct.knots_per_phase,
            },
            "full_body": self.full_body.to_string(),
            "controllers": self.controllers.to_string(),
            "stance_conflicts": self.stance_conflicts.iter().map(|c| c.to_string()).collect::<Vec<_>>(),
            "paper": jump.paper,
        });
        match value {
            serde_json::Value::Object(map) => map,
            _ => serde_json::Map::new(),
        }
    }
}

/// Solves the contact-timing problem of `jump` (sec. II-B) for the body `params` with the
/// jump's settings.
pub fn plan_contact_timing(jump: &Jump, params: &SrbParams, settings: &ContactTimingSettings, solver: SolverSettings) -> Result<ContactTimingStage, PipelineError> {
    let problem = ContactTimingProblem::new(&jump.srb(), params, settings)?;
    let mut solver = problem.solver(solver).map_err(|e| PipelineError::Solver(e.to_string()))?;
    let started = Instant::now();
    let result = problem.solve(&mut solver).map_err(|e| PipelineError::Solver(e.to_string()))?;
    let solve_time_s = started.elapsed().as_secs_f64();
    Ok(ContactTimingStage {
        status: result.status.clone(),
        iterations: result.iterations,
        objective: result.objective,
        primal_infeasibility: result.primal_infeasibility,
        durations: problem.durations(&result.last.primal),
        solve_time_s,
        knots_per_phase: settings.knots_per_phase,
        knots: problem.trajectory(&result.last.primal),
    })
}

/// Stages of [`run`], for progress reports.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    ContactTiming,
    FullBody,
    Controllers,
}

/// Runs the pipeline on `model` (the jump's robot) as far as this build goes; `progress`
/// hears when each stage starts (`false`) and ends (`true`).
pub fn run(jump: &Jump, model: &Model, settings: &ContactTimingSettings, mut progress: impl FnMut(Stage, bool)) -> Result<JumpReport, PipelineError> {
    if model.name != jump.robot {
        return Err(PipelineError::Robot { jump: jump.name.clone(), robot: model.name.clone(), expected: jump.robot.clone() });
    }
    let params = SrbParams::from_model(model, "standing")?;
    let radius = model.feet.iter().map(|f| f.radius).fold(0.0, f64::max);
    progress(Stage::ContactTiming, false);
    let contact_timing = plan_contact_timing(jump, &params, settings, SolverSettings::default())?;
    progress(Stage::ContactTiming, true);
    Ok(JumpReport {
        contact_timing,
        full_body: StageState::Missing(MISSING_FULL_BODY),
        controllers: StageState::Missing(MISSING_CONTROLLERS),
        stance_conflicts: jump.stance_conflicts(&params, radius),
    })
}

/// The single-rigid-body plan as a trajectory of the robot: the base where the body's CoM
/// and rotation put it (`base = p - R c`, `c` the CoM in the base frame of the standing
/// pose), the legs by inverse kinematics to the plan's feet (the SRB's nominal foot points,
/// the foot frames), the plan's ground forces. The SRB plan has no joint torques: `tau` is
/// zero and the summary says so.
pub fn srb_plan_trajectory(model: &Model, jump: &Jump, params: &SrbParams, knots: &[SrbKnot]) -> Result<Trajectory, PipelineError> {
    let legs = leg_chains(model).map_err(|e| PipelineError::Legs(e.to_string()))?;
    let mut q = model.reference_configuration("standing").ok_or_else(|| PipelineError::Legs(format!("robot '{}' has no standing configuration", model.name)))?.clone();
    let mut data = Data::new(model);
    let terrain = jump.terrain();
    let dt = knots.get(1).map_or(0.01, |k| k.t - knots[0].t);
    let mut traj = Trajectory::new(model, format!("jump {}: contact-timing plan (single rigid body; legs by inverse kinematics to its feet)", jump.name), dt, terrain.spec());
    let nj = model.nv - 6;
    for (k, knot) in knots.iter().enumerate() {
        let rotation = Rotation3::from_matrix(&knot.rotation);
        let quat = UnitQuaternion::from_rotation_matrix(&rotation);
        let base = knot.position - rotation * params.com_in_base;
        q.rows_mut(0, 3).copy_from(&base);
        q.rows_mut(3, 4).copy_from_slice(&[quat.i, quat.j, quat.k, quat.w]);
        let targets: Vec<Vector3<f64>> = knot.feet.to_vec();
        legs_inverse_kinematics(model, &mut data, &legs, &targets, &mut q, 1e-6, 20);
        let mut v = DVector::zeros(model.nv);
        v.rows_mut(0, 3).copy_from(&(rotation.transpose() * knot.velocity));
        v.rows_mut(3, 3).copy_from(&knot.angular_velocity);
        // Knots of a zero-length phase share their time: keep the times increasing.
        let t = if k > 0 { knot.t.max(traj.knots[k - 1].t + 1e-9) } else { knot.t };
        traj.knots.push(Knot {
            t,
            q: q.as_slice().to_vec(),
            v: v.as_slice().to_vec(),
            tau: vec![0.0; nj],
            contact_force: knot.forces.iter().map(|f| [f.x, f.y, f.z]).collect(),
            in_contact: knot.in_contact.to_vec(),
            feedback_gain: None,
        });
    }
    Ok(traj)
}
