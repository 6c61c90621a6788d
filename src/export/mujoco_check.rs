//! The MuJoCo checker from Rust: writes the MJCF ([`super::mjcf_model`]), the controller's
//! settings (legwork's own gains, so MuJoCo runs the controllers legwork runs) and the
//! reference trajectory into a folder, runs `python/legwork/mujoco_check.py` (compiled into the
//! crate and written beside them) with the Python of the checker's virtual environment,
//! and reads the run back as a legwork [`Trajectory`], whose figures legwork computes with
//! its own [`MotionMetrics`]: one metrics code, not two.
//!
//! The Python is found, in this order, at `$LEGWORK_MUJOCO_PYTHON`, at
//! `$LEGWORK_MUJOCO_VENV/bin/python`, or at `.venv-mujoco/bin/python` in the source tree
//! legwork was built from (`scripts/install-mujoco.sh` makes that one). The crate itself
//! has no MuJoCo dependency.

use super::mjcf::{mjcf_model, MjcfError, MjcfSettings};
use crate::control::{BaseGains, PdGains};
use crate::io::{Trajectory, TrajectoryError};
use crate::model::Model;
use crate::ocp::{MotionMetrics, Rerun};
use crate::terrain::TerrainSpec;
use nalgebra::DVector;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The checker script, as compiled in.
pub const CHECKER_SCRIPT: &str = include_str!("../../python/legwork/mujoco_check.py");
/// The script that installs the checker's environment.
pub const INSTALL_SCRIPT: &str = "scripts/install-mujoco.sh";

/// The controllers of the checker.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CheckController {
    /// Neunert 2017's tracking controller (sec. IV-B, eq. 12), as
    /// [`crate::control::TrackingController`] with its default gains.
    Track,
    /// The exported feedback policy `tau = tau_ff + K [q (-) q*; v - v*]`.
    Policy,
    /// Joint PD to the standing pose ([`crate::control::JointPd::standing`]).
    Stand,
}

impl CheckController {
    pub fn name(&self) -> &'static str {
        match self {
            CheckController::Track => "track",
            CheckController::Policy => "policy",
            CheckController::Stand => "stand",
        }
    }
}

/// Gains of the tracking controller, in legwork's joint order (the checker's `track`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TrackingGains {
    pub joint_kp: Vec<f64>,
    pub joint_kd: Vec<f64>,
    pub base_position_p: [f64; 3],
    pub base_position_d: [f64; 3],
    pub base_orientation_p: [f64; 3],
    pub base_orientation_d: [f64; 3],
}

/// The standing joint PD (the checker's `stand`): gains and target joint angles.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StandingPd {
    pub joint_kp: Vec<f64>,
    pub joint_kd: Vec<f64>,
    pub stand_target: Vec<f64>,
}

/// What the checker's controller needs from legwork.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(untagged)]
pub enum ControllerSettings {
    Track(TrackingGains),
    Stand(StandingPd),
    Policy {},
}

fn joint_entries(model: &Model, x: &DVector<f64>) -> Vec<f64> {
    model.actuated_joints().map(|j| x[j.idx_v]).collect()
}

impl ControllerSettings {
    /// The gains [`crate::control::TrackingController::with_default_gains`] uses on
    /// `reference` at the control period `control_dt`: the joint PD capped for the robot
    /// in flight and 2 Hz base springs, at the reference's first configuration.
    pub fn tracking(model: &Model, reference: &Trajectory, control_dt: f64) -> Result<Self, MujocoCheckError> {
        let q0 = reference.knots.first().map(|k| DVector::from_column_slice(&k.q)).ok_or_else(|| MujocoCheckError::Input("the reference has no knots".into()))?;
        model.check_configuration(&q0).map_err(|e| MujocoCheckError::Input(format!("the reference's first q: {e}")))?;
        let joint = PdGains::from_model(model, &q0, control_dt).capped_for_free_joints(model, &q0, control_dt);
        let base = BaseGains::from_model(model, &q0, 2.0 * std::f64::consts::PI * 2.0);
        Ok(ControllerSettings::Track(TrackingGains {
            joint_kp: joint_entries(model, &joint.kp),
            joint_kd: joint_entries(model, &joint.kd),
            base_position_p: base.position.0.into(),
            base_position_d: base.position.1.into(),
            base_orientation_p: base.orientation.0.into(),
            base_orientation_d: base.orientation.1.into(),
        }))
    }

    /// The standing PD of [`crate::control::JointPd::standing`] at `control_dt`.
    pub fn standing(model: &Model, control_dt: f64) -> Result<Self, MujocoCheckError> {
        let pd = crate::control::JointPd::standing(model, control_dt).map_err(|e| MujocoCheckError::Input(e.to_string()))?;
        let target = pd.target();
        Ok(ControllerSettings::Stand(StandingPd {
            joint_kp: joint_entries(model, &pd.gains().kp),
            joint_kd: joint_entries(model, &pd.gains().kd),
            stand_target: model.actuated_joints().map(|j| target[j.idx_q]).collect(),
        }))
    }
}

/// Why the MuJoCo check could not run.
#[derive(Debug, thiserror::Error)]
pub enum MujocoCheckError {
    #[error("the MuJoCo checker's Python environment is missing: no {path} ({why}); run `bash {INSTALL_SCRIPT}` in the legwork source tree, or point LEGWORK_MUJOCO_PYTHON at a Python with mujoco==4.0.0 and numpy")]
    MissingEnvironment { path: String, why: String },
    #[error("{path}: {error}")]
    Io { path: String, error: std::io::Error },
    #[error(transparent)]
    Mjcf(#[from] MjcfError),
    #[error(transparent)]
    Trajectory(#[from] TrajectoryError),
    #[error("{0}")]
    Input(String),
    #[error("the MuJoCo checker ({command}) failed with {status}:\n{stderr}")]
    Checker { command: String, status: String, stderr: String },
}

/// One run of the checker: what to replay, with which controller, where to write it.
pub struct CheckRun<'a> {
    /// The MJCF (from [`mjcf_model`]).
    pub mjcf: &'a Path,
    /// The reference trajectory.json; the run starts at its first knot.
    pub reference: &'a Path,
    pub controller: CheckController,
    pub settings: &'a ControllerSettings,
    /// Where the run is written (a trajectory.json).
    pub output: &'a Path,
    /// Seconds to run; `None`: the reference's own duration.
    pub duration: Option<f64>,
    /// Time between recorded knots (s).
    pub record_dt: f64,
}

/// A located checker: the Python to run it with.
#[derive(Clone, Debug)]
pub struct MujocoCheck {
    python: PathBuf,
}

impl MujocoCheck {
    /// Finds the checker's Python (see the module docs) and checks that it imports mujoco.
    pub fn locate() -> Result<Self, MujocoCheckError> {
        let python = if let Some(p) = std::env::var_os("LEGWORK_MUJOCO_PYTHON") {
            PathBuf::from(p)
        } else if let Some(v) = std::env::var_os("LEGWORK_MUJOCO_VENV") {
            PathBuf::from(v).join("bin").join("python")
        } else {
            Path::new(env!("CARGO_MANIFEST_DIR")).join(".venv-mujoco").join("bin").join("python")
        };
        Self::with_python(python)
    }

    /// The checker run by `python` (an interpreter that imports mujoco and numpy: the
    /// Python package's own, `sys.executable`).
    pub fn with_python(python: PathBuf) -> Result<Self, MujocoCheckError> {
        let missing = |why: String| MujocoCheckError::MissingEnvironment { path: python.display().to_string(), why };
        if !python.is_file() {
            return Err(missing("no such file".into()));
        }
        let probe = Command::new(&python).args(["-c", "import mujoco, numpy; print(mujoco.__version__)"]).output().map_err(|e| missing(e.to_string()))?;
        if !probe.status.success() {
            return Err(missing(format!("it cannot import mujoco and numpy: {}", String::from_utf8_lossy(&probe.stderr).trim())));
        }
        Ok(Self { python })
    }

    /// The checker's Python.
    pub fn python(&self) -> &Path {
        &self.python
    }

    /// MuJoCo's version as the checker's Python reports it.
    pub fn version(&self) -> Result<String, MujocoCheckError> {
        let out = Command::new(&self.python).args(["-c", "import mujoco; print(mujoco.__version__)"]).output().map_err(|error| MujocoCheckError::Io { path: self.python.display().to_string(), error })?;
        Ok(String::from_utf8_lossy(&out.stdout).trim().to_string())
    }

    /// The checker's `torques`: `controller`'s joint torques (legwork's joint order, before
    /// the effort clip) on `reference` at each state `(t, q, v)` (legwork's conventions).
    pub fn torques(&self, folder: &Path, mjcf: &Path, reference: &Path, controller: CheckController, settings: &ControllerSettings, states: &[(f64, DVector<f64>, DVector<f64>)]) -> Result<Vec<Vec<f64>>, MujocoCheckError> {
        let settings_path = folder.join(format!("controller_{}.json", controller.name()));
        write(&settings_path, &serde_json::to_string_pretty(settings).map_err(|e| MujocoCheckError::Input(e.to_string()))?)?;
        let input = serde_json::json!({ "states": states.iter().map(|(t, q, v)| serde_json::json!({ "t": t, "q": q.as_slice(), "v": v.as_slice() })).collect::<Vec<_>>() });
        let (input_path, output_path) = (folder.join("torques_in.json"), folder.join("torques_out.json"));
        write(&input_path, &input.to_string())?;
        let args: [&std::ffi::OsStr; 13] = ["torques".as_ref(), "--mjcf".as_ref(), mjcf.as_os_str(), "--reference".as_ref(), reference.as_os_str(), "--controller".as_ref(), controller.name().as_ref(), "--settings".as_ref(), settings_path.as_os_str(), "--input".as_ref(), input_path.as_os_str(), "--output".as_ref(), output_path.as_os_str()];
        self.call(folder, &args)?;
        let text = std::fs::read_to_string(&output_path).map_err(|error| MujocoCheckError::Io { path: output_path.display().to_string(), error })?;
        let value: serde_json::Value = serde_json::from_str(&text).map_err(|e| MujocoCheckError::Input(format!("{}: {e}", output_path.display())))?;
        serde_json::from_value(value["torques"].clone()).map_err(|e| MujocoCheckError::Input(format!("{}: {e}", output_path.display())))
    }

    /// Writes the checker script into `folder` and runs it with `args`.
    fn call(&self, folder: &Path, args: &[&std::ffi::OsStr]) -> Result<(), MujocoCheckError> {
        let script = folder.join("mujoco_check.py");
        write(&script, CHECKER_SCRIPT)?;
        let out = Command::new(&self.python).arg(&script).args(args).output().map_err(|error| MujocoCheckError::Io { path: self.python.display().to_string(), error })?;
        if !out.status.success() {
            let command = format!("{} {} {}", self.python.display(), script.display(), args.iter().map(|a| a.to_string_lossy()).collect::<Vec<_>>().join(" "));
            return Err(MujocoCheckError::Checker { command, status: out.status.to_string(), stderr: String::from_utf8_lossy(&out.stderr).into_owned() });
        }
        Ok(())
    }

    /// Runs `run.controller` in MuJoCo on `run.mjcf` from `run.reference`'s first knot;
    /// returns the run and, if MuJoCo flagged it as unstable, why (the run up to there is
    /// kept).
    pub fn run(&self, folder: &Path, run: &CheckRun) -> Result<(Trajectory, Option<String>), MujocoCheckError> {
        let settings_path = folder.join(format!("controller_{}.json", run.controller.name()));
        write(&settings_path, &serde_json::to_string_pretty(run.settings).map_err(|e| MujocoCheckError::Input(e.to_string()))?)?;
        let duration = run.duration.map(|d| d.to_string());
        let record_dt = run.record_dt.to_string();
        let mut args: Vec<&std::ffi::OsStr> = vec!["run".as_ref(), "--mjcf".as_ref(), run.mjcf.as_os_str(), "--reference".as_ref(), run.reference.as_os_str(), "--controller".as_ref(), run.controller.name().as_ref()];
        args.extend::<[&std::ffi::OsStr; 6]>(["--settings".as_ref(), settings_path.as_os_str(), "--output".as_ref(), run.output.as_os_str(), "--record-dt".as_ref(), record_dt.as_ref()]);
        if let Some(d) = &duration {
            args.extend::<[&std::ffi::OsStr; 2]>(["--duration".as_ref(), d.as_ref()]);
        }
        self.call(folder, &args)?;
        let traj = Trajectory::load_file(run.output)?;
        let failed = traj.summary.get("mujoco_failed").and_then(|f| f.as_str()).map(String::from);
        Ok((traj, failed))
    }

    /// The checker's `inspect`: MuJoCo's sizes, and at each `(q, v, a)` (legwork's
    /// conventions) the feet, mass matrix and inverse dynamics in legwork's coordinates;
    /// and the ground's height under each of `ground_points` (`ground_heights`).
    pub fn inspect(&self, folder: &Path, model: &Model, mjcf: &Path, states: &[(DVector<f64>, DVector<f64>, DVector<f64>)], ground_points: &[[f64; 2]]) -> Result<serde_json::Value, MujocoCheckError> {
        let input = serde_json::json!({
            "ground_points": ground_points,
            "joint_names": model.actuated_joint_names(),
            "foot_names": model.feet.iter().map(|f| f.name.as_str()).collect::<Vec<_>>(),
            "states": states.iter().map(|(q, v, a)| serde_json::json!({ "q": q.as_slice(), "v": v.as_slice(), "a": a.as_slice() })).collect::<Vec<_>>(),
        });
        let (input_path, output_path) = (folder.join("inspect_in.json"), folder.join("inspect_out.json"));
        write(&input_path, &input.to_string())?;
        self.call(folder, &["inspect".as_ref(), "--mjcf".as_ref(), mjcf.as_os_str(), "--input".as_ref(), input_path.as_os_str(), "--output".as_ref(), output_path.as_os_str()])?;
        let text = std::fs::read_to_string(&output_path).map_err(|error| MujocoCheckError::Io { path: output_path.display().to_string(), error })?;
        serde_json::from_str(&text).map_err(|e| MujocoCheckError::Input(format!("{}: {e}", output_path.display())))
    }
}

fn write(path: &Path, text: &str) -> Result<(), MujocoCheckError> {
    std::fs::write(path, text).map_err(|error| MujocoCheckError::Io { path: path.display().to_string(), error })
}

/// The two MuJoCo re-runs of a plan.
pub struct MujocoReruns {
    /// MuJoCo with the tracking controller.
    pub tracking: Rerun,
    /// MuJoCo with the exported feedback policy.
    pub policy: Rerun,
    /// MuJoCo's version.
    pub version: String,
}

/// Checks `plan` (a motion of `model` on `terrain`, saved or not) in MuJoCo with both
/// controllers; writes `model.xml`, the controllers' settings and `mujoco_track.json` /
/// `mujoco_policy.json` into `folder`. The friction coefficient is the robot's contact
/// model's ([`Model::contact`]).
pub fn check_plan_in_mujoco(check: &MujocoCheck, model: &Model, plan: &Trajectory, terrain: &TerrainSpec, folder: &Path) -> Result<MujocoReruns, MujocoCheckError> {
    plan.check_against(model, "the plan")?;
    std::fs::create_dir_all(folder).map_err(|error| MujocoCheckError::Io { path: folder.display().to_string(), error })?;
    let settings = MjcfSettings::default();
    let mjcf_path = folder.join("model.xml");
    write(&mjcf_path, &mjcf_model(model, terrain, &settings)?)?;
    let reference = folder.join("reference.json");
    plan.save_file(&reference)?;
    let control_dt = settings.timestep;
    let rerun = |controller: CheckController, settings: ControllerSettings| -> Result<Rerun, MujocoCheckError> {
        let output = folder.join(format!("mujoco_{}.json", controller.name()));
        let (trajectory, failed) = check.run(folder, &CheckRun { mjcf: &mjcf_path, reference: &reference, controller, settings: &settings, output: &output, duration: None, record_dt: control_dt })?;
        Ok(match failed {
            Some(reason) => Rerun::Failed { reason },
            None => {
                trajectory.check_against(model, &output.display().to_string())?;
                let metrics = MotionMetrics::of(model, &trajectory, model.contact.friction);
                Rerun::Completed { trajectory: Box::new(trajectory), metrics: Box::new(metrics) }
            }
        })
    };
    let tracking = rerun(CheckController::Track, ControllerSettings::tracking(model, plan, control_dt)?)?;
    let policy = rerun(CheckController::Policy, ControllerSettings::Policy {})?;
    Ok(MujocoReruns { tracking, policy, version: check.version()? })
}

/// Replays `plan` in MuJoCo with one controller (tracking or the exported policy) for
/// `duration` seconds (default: the plan's); writes `model.xml`, `reference.json`, the
/// controller's settings and `mujoco_<controller>.json` into `folder`. Returns the run and,
/// if MuJoCo flagged it as unstable, why.
pub fn replay_in_mujoco(check: &MujocoCheck, model: &Model, plan: &Trajectory, controller: CheckController, duration: Option<f64>, folder: &Path) -> Result<(Trajectory, Option<String>), MujocoCheckError> {
    plan.check_against(model, "the plan")?;
    std::fs::create_dir_all(folder).map_err(|error| MujocoCheckError::Io { path: folder.display().to_string(), error })?;
    let settings = MjcfSettings::default();
    let mjcf_path = folder.join("model.xml");
    write(&mjcf_path, &mjcf_model(model, &plan.metadata.terrain, &settings)?)?;
    let reference = folder.join("reference.json");
    plan.save_file(&reference)?;
    let controller_settings = match controller {
        CheckController::Track => ControllerSettings::tracking(model, plan, settings.timestep)?,
        CheckController::Policy => ControllerSettings::Policy {},
        CheckController::Stand => ControllerSettings::standing(model, settings.timestep)?,
    };
    let output = folder.join(format!("mujoco_{}.json", controller.name()));
    check.run(folder, &CheckRun { mjcf: &mjcf_path, reference: &reference, controller, settings: &controller_settings, output: &output, duration, record_dt: settings.timestep })
}

/// HyQ (or any robot) dropped from `drop_height` (m, feet above flat ground, standing
/// pose) in MuJoCo under the standing joint PD of `legwork simulate --controller stand`
/// (its gains at MuJoCo's 1 ms control period), for `duration` seconds; writes
/// `model.xml`, `controller_stand.json` and `mujoco_stand.json` into `folder`.
pub fn stand_in_mujoco(check: &MujocoCheck, model: &Model, drop_height: f64, duration: f64, folder: &Path) -> Result<(Trajectory, Option<String>), MujocoCheckError> {
    std::fs::create_dir_all(folder).map_err(|error| MujocoCheckError::Io { path: folder.display().to_string(), error })?;
    let settings = MjcfSettings::default();
    let terrain = TerrainSpec::flat();
    let mjcf_path = folder.join("model.xml");
    write(&mjcf_path, &mjcf_model(model, &terrain, &settings)?)?;
    let ground = terrain.build("flat ground").map_err(|e| MujocoCheckError::Input(e.to_string()))?;
    let q0 = crate::sim::standing_on_ground(model, ground.as_ref(), drop_height).map_err(|e| MujocoCheckError::Input(e.to_string()))?;
    let mut start = Trajectory::new(model, format!("drop from {drop_height} m"), settings.timestep, terrain);
    let nfeet = model.feet.len();
    start.knots.push(crate::io::Knot { t: 0.0, q: q0.iter().copied().collect(), v: vec![0.0; model.nv], tau: vec![0.0; model.nv - 6], contact_force: vec![[0.0; 3]; nfeet], in_contact: vec![false; nfeet], feedback_gain: None });
    let reference = folder.join("start.json");
    start.save_file(&reference)?;
    let output = folder.join("mujoco_stand.json");
    let stand = ControllerSettings::standing(model, settings.timestep)?;
    check.run(folder, &CheckRun { mjcf: &mjcf_path, reference: &reference, controller: CheckController::Stand, settings: &stand, output: &output, duration: Some(duration), record_dt: settings.timestep })
}
