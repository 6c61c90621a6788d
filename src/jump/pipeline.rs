//! The jump pipeline of Nguyen 2022 (Fig. 2): the contact-timing optimization on the single
//! rigid body (sec. II-B), the full-body trajectory optimization from its result (sec.
//! II-C), the jump and landing controllers in legwork's simulator (sec. III).
//!
//! Each stage reports what it did, or why it did not run ([`StageState`]): the contact timing
//! ([`crate::srb`]), the full-body optimization ([`crate::fullbody`]), the controllers
//! ([`super::control`]) and the robustness trials ([`super::trials`]) are their modules';
//! this file chains them and reads their results into one [`JumpReport`].

use super::control::{run_jump, JumpRun, JumpSettings};
use super::spec::{Jump, StanceConflict};
use super::trials::{run_trials, SuccessCriteria, TrialSettings, TrialsReport};
use crate::control::whole_body::{leg_chains, legs_inverse_kinematics};
use crate::dynamics::Data;
use crate::fullbody::{initial_guess_clear_of, BoxObstacle, FullBodyPlan, FullBodyProblem, FullBodySettings};
use crate::io::{Knot, Trajectory};
use crate::ipocp::{Settings as SolverSettings, Status};
use crate::model::Model;
use crate::srb::{ContactTimingError, ContactTimingProblem, ContactTimingSettings, SrbKnot, SrbParams, SrbParamsError, SrbTrajectory};
use crate::terrain::Terrain;
use nalgebra::{DVector, Rotation3, UnitQuaternion, Vector3};
use serde_json::json;
use std::time::Instant;

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
    /// The solution, knot by knot.
    pub srb: SrbTrajectory,
}

impl ContactTimingStage {
    pub fn solved(&self) -> bool {
        self.status == Status::Solved
    }
    pub fn knots(&self) -> &[SrbKnot] {
        &self.srb.knots
    }
}

/// Whether a stage ran.
#[derive(Clone, Debug, PartialEq)]
pub enum StageState {
    Done,
    Failed(String),
    /// Not run: an earlier stage failed (the reason).
    Skipped(String),
}

impl std::fmt::Display for StageState {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        match self {
            StageState::Done => write!(f, "done"),
            StageState::Failed(reason) => write!(f, "failed: {reason}"),
            StageState::Skipped(reason) => write!(f, "not run: {reason}"),
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
    /// The full-body trajectory optimization did not converge or its plan breaks a limit.
    FullBodyFailed,
    /// The re-run landed upright, away from the target.
    MissedTarget,
    /// The re-run fell (or the controllers could not run).
    Fell,
}

impl Verdict {
    /// `legwork jump`'s exit code, by the convention of every command (`legwork --help`):
    /// 0 landed on target; 1 ran but missed the target (landed off target, or fell); 3 an
    /// optimization failed, so there is no motion to run. Bad input (2) never gets here.
    pub fn exit_code(self) -> u8 {
        match self {
            Verdict::Landed => 0,
            Verdict::MissedTarget | Verdict::Fell => 1,
            Verdict::ContactTimingFailed | Verdict::FullBodyFailed => 3,
        }
    }
    pub fn describe(self) -> &'static str {
        match self {
            Verdict::Landed => "landed on target",
            Verdict::ContactTimingFailed => "the contact-timing optimization failed",
            Verdict::FullBodyFailed => "the full-body trajectory optimization failed",
            Verdict::MissedTarget => "landed, off target or tilted",
            Verdict::Fell => "fell",
        }
    }
}

/// Gauss-Newton iterations of the full-body solve before the constraints' curvature is added
/// (`FullBodySettings::constraint_curvature_after`, then at the first iterate with violation at
/// most 1): lateral, spin_90 and diagonal (25-31 iterations) converge before it, barrel_roll
/// takes 2 curvature iterations (62 in all, 61 with 100); the box jumps' main loop stalls at a
/// large dual infeasibility without the curvature (docs/experiments/jump-box.md). 60 instead
/// of 100: lateral_down 156 -> 138 iterations, double_barrel_roll 131 -> 94, double_backflip
/// 184 -> 125, the five that land still 20/20 (docs/experiments/fb-speed-3.md).
pub const FULL_BODY_GAUSS_NEWTON_ITERATIONS: usize = 60;

/// The full body's stall rule (`FullBodySettings::curvature_on_stall`): the curvature also
/// before [`FULL_BODY_GAUSS_NEWTON_ITERATIONS`] once the violation is at most 1 and has not
/// reached a new low for this many Gauss-Newton iterations. 5 (10 in brackets; measured on
/// all seven, idle, docs/experiments/fb-speed-3.md): barrel_roll 33 iterations (62),
/// double_barrel_roll 63 (94), double_backflip 89 (94); lateral, lateral_down, spin_90 and
/// diagonal do not stall so; the five that land still land 20/20 in legwork and MuJoCo.
pub const FULL_BODY_STALL_ITERATIONS: usize = 5;

/// The curvature phase forms the constraints' curvature every this many iterations and
/// reuses it in between (`FullBodySettings::curvature_refresh`; a curvature iteration costs
/// ~5 Gauss-Newton ones). 2 (1, 3 in brackets; interleaved, idle AMD EPYC, full-body seconds,
/// docs/experiments/fb-curvature-lag.md): lateral_down 0.73-0.77 (0.88-1.11, 0.83-0.95),
/// barrel_roll 0.42-0.44 (0.50-0.63, 0.37-0.38), double_barrel_roll 1.68-1.70 (1.83-2.05,
/// 1.40-1.55), double_backflip 2.52-2.64 (3.30-3.54, 2.03-2.06); 3 took lateral_down 98 ->
/// 118 iterations. The same optima (lateral_down's and barrel_roll's costs to 7 digits) and
/// landings.
pub const FULL_BODY_CURVATURE_REFRESH: usize = 2;

/// Options of [`run`] beyond the jump file.
#[derive(Clone, Debug)]
pub struct PipelineOptions {
    pub contact_timing: ContactTimingSettings,
    /// The contact timing's solver settings (the full body's are in `full_body`).
    pub contact_timing_solver: SolverSettings,
    pub full_body: FullBodySettings,
    pub controllers: JumpSettings,
    pub criteria: SuccessCriteria,
    /// Robustness trials after the nominal re-run (0: none).
    pub trials: usize,
}

impl PipelineOptions {
    /// The jump file's contact-timing settings, the full body's defaults with the constraint
    /// curvature after [`FULL_BODY_GAUSS_NEWTON_ITERATIONS`] (formed every
    /// [`FULL_BODY_CURVATURE_REFRESH`] iterations), airborne feet kept
    /// `clearance` (1 cm) beyond their radius from the box, and the jump file's
    /// `[full_body]` settings (the lift-off force bound, the airborne feet's margin), every
    /// other setting its default.
    pub fn of(jump: &Jump) -> Self {
        Self {
            contact_timing: jump.contact_timing.clone(),
            contact_timing_solver: ContactTimingProblem::solver_settings(),
            full_body: {
                let defaults = FullBodySettings::default();
                FullBodySettings {
                    constraint_curvature_after: Some(FULL_BODY_GAUSS_NEWTON_ITERATIONS),
                    curvature_on_stall: Some(FULL_BODY_STALL_ITERATIONS),
                    curvature_refresh: FULL_BODY_CURVATURE_REFRESH,
                    airborne_foot_margin: jump.full_body.airborne_foot_margin.unwrap_or(defaults.clearance),
                    lift_off_normal_force: jump.full_body.lift_off_normal_force.unwrap_or(defaults.lift_off_normal_force),
                    ..defaults
                }
            },
            controllers: JumpSettings::default(),
            criteria: SuccessCriteria::default(),
            trials: 0,
        }
    }
}

/// Everything a jump's run reports.
#[derive(Clone, Debug)]
pub struct JumpReport {
    pub contact_timing: ContactTimingStage,
    pub full_body: StageState,
    pub full_body_plan: Option<FullBodyPlan>,
    pub controllers: StageState,
    /// The nominal re-run in legwork's simulator and whether it met the criteria.
    pub rerun: Option<JumpRun>,
    pub landed: Option<bool>,
    pub trials: Option<TrialsReport>,
    /// Start feet off the box and landing feet over it (see [`Jump::stance_conflicts`]).
    pub stance_conflicts: Vec<StanceConflict>,
}

impl JumpReport {
    pub fn verdict(&self) -> Verdict {
        if !self.contact_timing.solved() {
            return Verdict::ContactTimingFailed;
        }
        if self.full_body != StageState::Done {
            return Verdict::FullBodyFailed;
        }
        match (&self.rerun, self.landed) {
            (Some(_), Some(true)) => Verdict::Landed,
            (Some(run), Some(false)) if !run.fell => Verdict::MissedTarget,
            _ => Verdict::Fell,
        }
    }

    /// The figures of the run as JSON (the trajectory file's summary).
    pub fn summary(&self, jump: &Jump) -> serde_json::Map<String, serde_json::Value> {
        let ct = &self.contact_timing;
        let full_body = self.full_body_plan.as_ref().map(|p| {
            json!({
                "status": format!("{:?}", p.report.status),
                "iterations": p.report.iterations,
                "cost": p.report.objective,
                "constraint_violation": p.report.primal_infeasibility,
                "solve_time_s": p.report.time.as_secs_f64(),
                "evaluation_time_s": p.report.evaluation_time.as_secs_f64(),
                "kkt_time_s": p.report.kkt_time.as_secs_f64(),
                "phase_durations_s": p.phase_durations,
                "knots": p.trajectory.knots.len(),
                "limits_met": p.limits.all_met(1e-6),
                "binding_limits": p.limits.binding(1e-3),
                "pre_landing_joints": p.pre_landing_joints,
            })
        });
        let rerun = self.rerun.as_ref().map(|r| {
            json!({
                "landed_on_target": self.landed,
                "lift_off_s": r.lift_off,
                "touch_down_s": r.touch_down,
                "landing_switch_s": r.switch,
                "position_error_m": r.position_error,
                "yaw_error_deg": r.yaw_error.to_degrees(),
                "roll_deg": r.roll.to_degrees(),
                "pitch_deg": r.pitch.to_degrees(),
                "fell": r.fell,
                "failure": r.failure,
                "max_torque_nm": r.max_torque,
                "saturated_controls": r.saturated_controls,
            })
        });
        let trials = self.trials.as_ref().map(|t| {
            json!({
                "trials": t.outcomes.len(),
                "successes": t.successes(),
                "success_rate": t.success_rate(),
                "position_errors_m": t.outcomes.iter().map(|o| o.run.position_error).collect::<Vec<_>>(),
            })
        });
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
            "full_body_stage": self.full_body.to_string(),
            "full_body": full_body,
            "controllers_stage": self.controllers.to_string(),
            "rerun": rerun,
            "trials": trials,
            "stance_conflicts": self.stance_conflicts.iter().map(|c| c.to_string()).collect::<Vec<_>>(),
            "paper": jump.paper,
        });
        match value {
            serde_json::Value::Object(map) => map,
            _ => serde_json::Map::new(),
        }
    }
}

/// Solves the contact-timing problem of `jump` (sec. II-B) for the body `params`.
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
        srb: SrbTrajectory::from_solution(&problem, &result.last.primal).map_err(|e| PipelineError::Solver(e.to_string()))?,
    })
}

/// The jump's box as the full-body optimization's obstacle: its extent, the top lowered by
/// the foot radius (the optimizer's foot points are the spheres' centres, `top` bounds them
/// from below over the box).
pub fn box_obstacle(jump: &Jump, foot_radius: f64) -> Option<BoxObstacle> {
    jump.platform.as_ref().map(|p| BoxObstacle { top: p.height - foot_radius, x: p.x, y: p.y })
}

/// The full-body stage (sec. II-C): the contact-timing solution resampled at `dt`, the
/// initial guess, the solve; `Err` says why there is no plan.
pub fn plan_full_body(model: &Model, jump: &Jump, srb: &SrbTrajectory, settings: &FullBodySettings) -> Result<FullBodyPlan, String> {
    let radius = model.feet.iter().map(|f| f.radius).fold(0.0, f64::max);
    let srb = srb.resample(settings.dt).map_err(|e| e.to_string())?;
    let obstacle = box_obstacle(jump, radius);
    let guess = initial_guess_clear_of(model, &srb, settings.pre_landing_knots, obstacle.as_ref()).map_err(|e| e.to_string())?;
    let problem = FullBodyProblem::new(model, &srb, &guess, settings, obstacle).map_err(|e| e.to_string())?;
    problem.solve().map_err(|e| e.to_string())
}

/// Stages of [`run`], for progress reports.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    ContactTiming,
    FullBody,
    Controllers,
    Trials,
}

/// Runs the pipeline on `model` (the jump's robot); `progress` hears when each stage starts
/// (`false`) and ends (`true`).
pub fn run(jump: &Jump, model: &Model, options: &PipelineOptions, mut progress: impl FnMut(Stage, bool)) -> Result<JumpReport, PipelineError> {
    if model.name != jump.robot {
        return Err(PipelineError::Robot { jump: jump.name.clone(), robot: model.name.clone(), expected: jump.robot.clone() });
    }
    let params = SrbParams::from_model(model, "standing")?;
    let radius = model.feet.iter().map(|f| f.radius).fold(0.0, f64::max);
    let terrain = jump.terrain();
    progress(Stage::ContactTiming, false);
    let contact_timing = plan_contact_timing(jump, &params, &options.contact_timing, options.contact_timing_solver.clone())?;
    progress(Stage::ContactTiming, true);
    let mut report = JumpReport {
        full_body: StageState::Skipped("the contact timing did not converge".into()),
        full_body_plan: None,
        controllers: StageState::Skipped("no full-body plan".into()),
        rerun: None,
        landed: None,
        trials: None,
        stance_conflicts: jump.stance_conflicts(&params, radius),
        contact_timing,
    };
    if !report.contact_timing.solved() {
        return Ok(report);
    }
    progress(Stage::FullBody, false);
    match plan_full_body(model, jump, &report.contact_timing.srb, &options.full_body) {
        Ok(plan) => {
            report.full_body = if plan.report.status != Status::Solved {
                StageState::Failed(format!("{:?} after {} iterations", plan.report.status, plan.report.iterations))
            } else if !plan.limits.all_met(1e-6) {
                StageState::Failed(format!("the plan breaks a limit: {}", plan.limits))
            } else {
                StageState::Done
            };
            report.full_body_plan = Some(plan);
        }
        Err(reason) => report.full_body = StageState::Failed(reason),
    }
    progress(Stage::FullBody, true);
    let Some(plan) = report.full_body_plan.as_ref().filter(|_| report.full_body == StageState::Done) else {
        return Ok(report);
    };
    progress(Stage::Controllers, false);
    match run_jump(model, &terrain, &plan.trajectory, &options.controllers) {
        Ok(run) => {
            report.landed = Some(options.criteria.met_by(&run));
            report.controllers = StageState::Done;
            report.rerun = Some(run);
        }
        Err(e) => report.controllers = StageState::Failed(e.to_string()),
    }
    progress(Stage::Controllers, true);
    if options.trials > 0 && report.rerun.is_some() {
        progress(Stage::Trials, false);
        let settings = TrialSettings { trials: options.trials, criteria: options.criteria, ..TrialSettings::default() };
        report.trials = run_trials(model, &terrain, &plan.trajectory, &options.controllers, &settings).ok();
        progress(Stage::Trials, true);
    }
    Ok(report)
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
        let base = knot.com - rotation * params.com_in_base;
        q.rows_mut(0, 3).copy_from(&base);
        q.rows_mut(3, 4).copy_from_slice(&[quat.i, quat.j, quat.k, quat.w]);
        let targets: Vec<Vector3<f64>> = knot.feet.to_vec();
        legs_inverse_kinematics(model, &mut data, &legs, &targets, &mut q, 1e-6, 20);
        let mut v = DVector::zeros(model.nv);
        v.rows_mut(0, 3).copy_from(&(rotation.transpose() * knot.com_velocity));
        v.rows_mut(3, 3).copy_from(&knot.omega);
        // Knots of a zero-length phase share their time: keep the times increasing.
        let t = if k > 0 { knot.t.max(traj.knots[k - 1].t + 1e-9) } else { knot.t };
        traj.knots.push(Knot {
            t,
            q: q.as_slice().to_vec(),
            v: v.as_slice().to_vec(),
            tau: vec![0.0; nj],
            contact_force: knot.forces.iter().map(|f| [f.x, f.y, f.z]).collect(),
            in_contact: knot.contacts.to_vec(),
            feedback_gain: None,
        });
    }
    Ok(traj)
}
