//! Task figures and target checks of any motion, and the MuJoCo checker (legwork::export)
//! run by a given Python interpreter: the compiled half of `legwork.mujoco`.

use crate::convert::{from_python, to_python};
use crate::errors::{could_not_finish, input_error};
use crate::jobs::load_task;
use crate::robot::Robot;
use crate::trajectory::Trajectory;
use legwork::export::{check_plan_in_mujoco, mjcf_model, replay_in_mujoco, CheckController, MjcfSettings, MujocoCheck};
use legwork::ocp::{MotionMetrics, Rerun};
use legwork::terrain::TerrainSpec;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;

/// The task figures of a motion (legwork's `MotionMetrics`: final pose, apex, flight time,
/// lift-offs and slide per foot, contact correlations, feasibility), as a dict.
#[pyfunction]
pub fn figures<'py>(py: Python<'py>, trajectory: &Trajectory, robot: &Robot) -> PyResult<Bound<'py, PyAny>> {
    let model = &robot.model;
    trajectory.motion.check_against(model, "trajectory").map_err(|e| input_error(e.to_string()))?;
    let metrics = MotionMetrics::of(model, &trajectory.motion, model.contact.friction);
    to_python(py, &serde_json::to_value(&metrics).map_err(|e| could_not_finish(e.to_string()))?)
}

/// A task's `[[target]]` checks on a motion at `tolerance_scale` times the tolerances (the
/// re-runs are checked at 2): a list of `{"what", "required", "value", "met"}`.
#[pyfunction]
#[pyo3(signature = (task, trajectory, robot, tolerance_scale=1.0, overrides=None))]
pub fn check_targets<'py>(py: Python<'py>, task: &Bound<'py, PyAny>, trajectory: &Trajectory, robot: &Robot, tolerance_scale: f64, overrides: Option<&Bound<'py, PyDict>>) -> PyResult<Bound<'py, PyAny>> {
    if !(tolerance_scale.is_finite() && tolerance_scale > 0.0) {
        return Err(input_error(format!("tolerance_scale: expected a positive number, got {tolerance_scale}")));
    }
    let (spec, origin) = load_task(task, overrides)?;
    let model = &robot.model;
    trajectory.motion.check_against(model, "trajectory").map_err(|e| input_error(e.to_string()))?;
    let target = spec.target(model, &origin).map_err(|e| input_error(e.to_string()))?;
    to_python(py, &serde_json::to_value(target.check(model, &trajectory.motion, tolerance_scale)).map_err(|e| could_not_finish(e.to_string()))?)
}

fn terrain_spec(terrain: Option<&Bound<'_, PyAny>>) -> PyResult<TerrainSpec> {
    match terrain {
        None => Ok(TerrainSpec::flat()),
        Some(t) => serde_json::from_value(from_python(t, "terrain")?).map_err(|e| input_error(format!("terrain: {e} (a trajectory's metadata[\"terrain\"], e.g. {{\"plane\": {{\"elevation\": 0.0, \"normal\": [0, 0, 1]}}}})"))),
    }
}

/// The MJCF (MuJoCo XML) of a robot on a terrain (flat ground by default, or a
/// trajectory's `metadata["terrain"]`): legwork's own model, contact and ground.
#[pyfunction]
#[pyo3(signature = (robot, terrain=None))]
pub fn mjcf(robot: &Robot, terrain: Option<&Bound<'_, PyAny>>) -> PyResult<String> {
    mjcf_model(&robot.model, &terrain_spec(terrain)?, &MjcfSettings::default()).map_err(|e| input_error(e.to_string()))
}

fn checker(python: PathBuf) -> PyResult<MujocoCheck> {
    MujocoCheck::with_python(python).map_err(|e| could_not_finish(e.to_string()))
}

/// Replays `plan` in MuJoCo with `controller` (`"track"`, `"policy"` or `"stand"`) run by
/// the interpreter `python`; files go to `folder`. Returns (run, why MuJoCo stopped or None).
#[pyfunction]
#[pyo3(signature = (plan, robot, python, folder, controller="track", duration=None))]
pub fn mujoco_replay(py: Python<'_>, plan: &Trajectory, robot: &Robot, python: PathBuf, folder: PathBuf, controller: &str, duration: Option<f64>) -> PyResult<(Trajectory, Option<String>)> {
    let controller = match controller {
        "track" => CheckController::Track,
        "policy" => CheckController::Policy,
        "stand" => CheckController::Stand,
        other => return Err(input_error(format!("controller: expected \"track\", \"policy\" or \"stand\", got {other:?}"))),
    };
    if let Some(d) = duration.filter(|d| !(d.is_finite() && *d > 0.0)) {
        return Err(input_error(format!("duration: expected a positive time in s, got {d}")));
    }
    let check = checker(python)?;
    let model = &robot.model;
    let (run, failed) = py.detach(|| replay_in_mujoco(&check, model, &plan.motion, controller, duration, &folder)).map_err(|e| could_not_finish(e.to_string()))?;
    Ok((Trajectory::new(run), failed))
}

/// Both MuJoCo re-runs of `plan` (`legwork solve --check mujoco`): `{"version": ...,
/// "MuJoCo track": Trajectory or reason, "MuJoCo policy": ...}`.
#[pyfunction]
pub fn mujoco_check<'py>(py: Python<'py>, plan: &Trajectory, robot: &Robot, python: PathBuf, folder: PathBuf) -> PyResult<Bound<'py, PyDict>> {
    let check = checker(python)?;
    let model = &robot.model;
    let reruns = py.detach(|| check_plan_in_mujoco(&check, model, &plan.motion, &plan.motion.metadata.terrain, &folder)).map_err(|e| could_not_finish(e.to_string()))?;
    let out = PyDict::new(py);
    out.set_item("version", &reruns.version)?;
    for (name, rerun) in [("MuJoCo track", reruns.tracking), ("MuJoCo policy", reruns.policy)] {
        match rerun {
            Rerun::Completed { trajectory, .. } => out.set_item(name, Py::new(py, Trajectory::new(*trajectory))?)?,
            Rerun::Failed { reason } => out.set_item(name, reason)?,
        }
    }
    Ok(out)
}
