//! `legwork.solve`: the job of `legwork solve` (legwork::job::solve), with the GIL released
//! while it runs and an optional progress callback.

use crate::convert::{from_python, to_python};
use crate::errors::{could_not_finish, input_error, CouldNotFinishError, InputError};
use crate::robot::{path_or_name, Robot};
use crate::trajectory::Trajectory;
use legwork::export::MujocoCheck;
use legwork::job::resources::MemoryLimit;
use legwork::job::solve::{exploration_override, SolveJob};
use legwork::job::{JobError, JobErrorKind};
use legwork::ocp::{Rerun, SolveOptions, TaskSpec};
use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyTuple};
use std::path::PathBuf;
use std::sync::Mutex;

pub(crate) fn job_error(e: JobError) -> PyErr {
    match e.kind {
        JobErrorKind::BadInput => InputError::new_err(e.message),
        JobErrorKind::CouldNotFinish => CouldNotFinishError::new_err(e.message),
    }
}

/// The task: an embedded name or a `.toml` path, or a dict of the task file's tables; with
/// `overrides` (`{"input.weight": 0.1, "waypoint[0].desired.base_position[0]": 1.5}`).
pub(crate) fn load_task(task: &Bound<'_, PyAny>, overrides: Option<&Bound<'_, PyDict>>) -> PyResult<(TaskSpec, String)> {
    let mut pairs = Vec::new();
    if let Some(o) = overrides {
        for (key, value) in o.iter() {
            let path: String = key.extract().map_err(|_| input_error(format!("overrides: keys are paths into the task (str), got {key}")))?;
            let json = from_python(&value, &format!("overrides[{path:?}]"))?;
            let value = toml::Value::try_from(json).map_err(|e| input_error(format!("overrides[{path:?}]: {e}")))?;
            pairs.push((path, value));
        }
    }
    let (text, origin) = if let Ok(dict) = task.cast::<PyDict>() {
        let json = from_python(dict.as_any(), "task")?;
        let text = toml::to_string(&json).map_err(|e| input_error(format!("task (dict): cannot write it as TOML: {e}")))?;
        (text, "task (dict)".to_string())
    } else {
        TaskSpec::text_of(&path_or_name(task, "task")?).map_err(|e| input_error(e.to_string()))?
    };
    let spec = TaskSpec::from_toml_with_overrides(&text, &origin, &pairs).map_err(|e| input_error(e.to_string()))?;
    Ok((spec, origin))
}

/// A progress callback called from the job's threads (the GIL taken for each call): the
/// first exception it raises (or a Ctrl-C) is kept and raised when the job returns, since
/// a job cannot be stopped halfway.
struct Progress {
    callback: Option<Py<PyAny>>,
    error: Mutex<Option<PyErr>>,
}

impl Progress {
    fn new(callback: Option<Py<PyAny>>) -> Self {
        Self { callback, error: Mutex::new(None) }
    }

    fn wanted(&self) -> bool {
        self.callback.is_some()
    }

    /// Calls the callback with the arguments `args` builds (with the GIL held).
    fn call(&self, args: impl FnOnce(Python<'_>) -> PyResult<Py<PyTuple>>) {
        let Some(callback) = &self.callback else { return };
        Python::attach(|py| {
            if let Err(e) = args(py).and_then(|args| callback.call1(py, args.bind(py))).and_then(|_| py.check_signals()) {
                if let Ok(mut slot) = self.error.lock() {
                    slot.get_or_insert(e);
                }
            }
        });
    }

    /// The job's result, or the callback's exception.
    fn finish<T>(self, result: T) -> PyResult<T> {
        match self.error.into_inner().ok().flatten() {
            Some(e) => Err(e),
            None => Ok(result),
        }
    }
}

/// A robot argument (a `Robot`, a name or a path; `default` when absent) as a model and
/// what it was loaded from.
fn model_of(robot: Option<&Bound<'_, PyAny>>, default: &str, what: &str) -> PyResult<(legwork::model::Model, String)> {
    if let Some(r) = robot.and_then(|r| r.cast::<Robot>().ok()) {
        let r = r.borrow();
        return Ok(((*r.model).clone(), r.spec.clone()));
    }
    let spec = match robot {
        Some(r) => path_or_name(r, "robot")?,
        None => default.to_string(),
    };
    let model = legwork::model::load(&spec).map_err(|e| input_error(format!("{what}: {e}")))?;
    Ok((model, spec))
}

/// The result of [`solve`]: the plan (with its gains), the closed-loop re-runs, the target
/// checks and the solver's figures; the same as the files in `out`.
#[pyclass(name = "SolveResult", module = "legwork", frozen)]
pub struct SolveResult {
    #[pyo3(get)]
    plan: Py<Trajectory>,
    /// The re-runs by name (`"SLQ policy"`, `"tracking ctrl"`, and with `check_mujoco`
    /// `"MuJoCo track"`, `"MuJoCo policy"`): a Trajectory, or the reason it failed (str).
    #[pyo3(get)]
    reruns: Py<PyDict>,
    /// `"met"` or `"missed"`.
    #[pyo3(get)]
    verdict: String,
    /// 0 met, 1 missed (the command line's exit code).
    #[pyo3(get)]
    exit_code: u8,
    /// Normalized cost per SLQ iteration of the last solve (Neunert 2017's Fig. 12).
    #[pyo3(get)]
    cost_history: Py<PyArray1<f64>>,
    /// The plan's cost from the task's own terms (comparable between solves).
    #[pyo3(get)]
    task_cost: f64,
    #[pyo3(get)]
    iterations: usize,
    /// Seconds of solving (every stage and round).
    #[pyo3(get)]
    solve_time: f64,
    /// The output folder.
    #[pyo3(get)]
    out: PathBuf,
}

#[pymethods]
impl SolveResult {
    /// Whether the plan met the task's targets (and both MuJoCo runs, when checked).
    #[getter]
    fn met(&self) -> bool {
        self.verdict == "met"
    }
    /// The summary written to trajectory.json (targets, figures of every run), as a dict.
    #[getter]
    fn summary<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.plan.get().summary(py)
    }
    /// The target checks per run: `{run: [{"what", "required", "value", "met"}, ...] or "failed"}`.
    #[getter]
    fn targets<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.summary(py)?.get_item("target")
    }
    fn __repr__(&self) -> String {
        format!("legwork.SolveResult(verdict={:?}, task_cost={:.4e}, iterations={}, solve_time={:.2} s, out={:?})", self.verdict, self.task_cost, self.iterations, self.solve_time, self.out.display().to_string())
    }
}

/// Optimizes a task with SLQ (Neunert 2017), re-runs it in closed loop, checks its targets and
/// writes the same folder as `legwork solve` (`out`, default `out/<task>`).
#[pyfunction]
#[pyo3(signature = (task, *, robot=None, out=None, threads=0, iterations=None, starts=None, seed=None, check_mujoco=false, overrides=None, progress=None, memory_limit_gb=None, png=false))]
#[allow(clippy::too_many_arguments)]
pub fn solve(
    py: Python<'_>,
    task: &Bound<'_, PyAny>,
    robot: Option<&Bound<'_, PyAny>>,
    out: Option<PathBuf>,
    threads: usize,
    iterations: Option<usize>,
    starts: Option<usize>,
    seed: Option<u64>,
    check_mujoco: bool,
    overrides: Option<&Bound<'_, PyDict>>,
    progress: Option<Py<PyAny>>,
    memory_limit_gb: Option<f64>,
    png: bool,
) -> PyResult<SolveResult> {
    let (spec, origin) = load_task(task, overrides)?;
    let (model, _) = model_of(robot, &spec.robot, &format!("{origin}: robot"))?;
    if let Some(gb) = memory_limit_gb.filter(|gb| !(gb.is_finite() && *gb > 0.0)) {
        return Err(input_error(format!("memory_limit_gb: expected a positive number of gigabytes, got {gb}")));
    }
    let exploration = exploration_override(&spec, starts, seed, "starts").map_err(job_error)?;
    let out = out.unwrap_or_else(|| PathBuf::from("out").join(&spec.name));
    // MuJoCo in this interpreter (the `mujoco` extra), else legwork's own checker venv.
    let mujoco = if check_mujoco {
        let python: PathBuf = py.import("sys")?.getattr("executable")?.extract()?;
        Some(MujocoCheck::with_python(python).or_else(|e| MujocoCheck::locate().map_err(|_| could_not_finish(format!("check_mujoco: {e}; pip install 'legwork[mujoco]'"))))?)
    } else {
        None
    };
    let job = SolveJob {
        spec: &spec,
        origin: &origin,
        model: &model,
        options: SolveOptions { threads, max_iterations: iterations, exploration, value_function: false },
        mujoco: mujoco.as_ref(),
        out: &out,
        memory_limit: MemoryLimit { gb: memory_limit_gb, setting: "memory_limit_gb" },
        png,
    };
    let progress = Progress::new(progress);
    let solved = py
        .detach(|| {
            job.run(|p| {
                if !progress.wanted() {
                    return;
                }
                let log = p.log;
                let time = log.timing.linearization + log.timing.backward_pass + log.timing.line_search;
                progress.call(|py| {
                    let info = PyDict::new(py);
                    info.set_item("iteration", log.iteration)?;
                    info.set_item("cost", log.cost)?;
                    info.set_item("step", log.alpha)?;
                    info.set_item("stage", p.stage)?;
                    info.set_item("time_s", time)?;
                    Ok(PyTuple::new(py, [info])?.unbind())
                });
            })
        })
        .map_err(job_error)?;
    let solved = progress.finish(solved)?;
    let run = &solved.run;
    let reruns = PyDict::new(py);
    let add = |name: &str, rerun: &Rerun| -> PyResult<()> {
        match rerun {
            Rerun::Completed { trajectory, .. } => reruns.set_item(name, Py::new(py, Trajectory::new((**trajectory).clone()))?),
            Rerun::Failed { reason } => reruns.set_item(name, reason),
        }
    };
    add("SLQ policy", &run.policy_rerun)?;
    add("tracking ctrl", &run.tracking_rerun)?;
    if let Some(m) = &solved.mujoco {
        add("MuJoCo track", &m.tracking)?;
        add("MuJoCo policy", &m.policy)?;
    }
    Ok(SolveResult {
        plan: Py::new(py, Trajectory::new(solved.trajectory.clone()))?,
        reruns: reruns.unbind(),
        verdict: solved.verdict.as_str().to_string(),
        exit_code: solved.verdict.exit_code(),
        cost_history: PyArray1::from_slice(py, &run.solution.cost_history).unbind(),
        task_cost: run.task_cost,
        iterations: run.iterations(),
        solve_time: run.solve_time(),
        out,
    })
}

/// The embedded tasks: name -> one-line summary.
#[pyfunction]
pub fn tasks(py: Python<'_>) -> PyResult<Bound<'_, PyList>> {
    let list = PyList::empty(py);
    for (name, _) in legwork::ocp::EMBEDDED_TASKS {
        let spec = TaskSpec::embedded(name).map_err(|e| input_error(e.to_string()))?;
        list.append((name.to_string(), spec.summary.clone()))?;
    }
    Ok(list)
}

/// A task as the dict of its TOML tables (to edit and pass to `solve`).
#[pyfunction]
pub fn task_dict<'py>(py: Python<'py>, task: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
    let (text, origin) = TaskSpec::text_of(&path_or_name(task, "task")?).map_err(|e| input_error(e.to_string()))?;
    let table: toml::Table = toml::from_str(&text).map_err(|e| input_error(format!("{origin}: {e}")))?;
    to_python(py, &serde_json::to_value(table).map_err(|e| input_error(e.to_string()))?)
}

/// Python names of the simulate job's settings, for its messages.
fn keyword(setting: &str) -> String {
    setting.to_string()
}

/// A push: `"X,Y,Z@T:DUR"` as on the command line, or `(fx, fy, fz, start, duration)`.
fn push(item: &Bound<'_, PyAny>, index: usize) -> PyResult<legwork::sim::Push> {
    let text = match item.extract::<String>() {
        Ok(text) => text,
        Err(_) => {
            let (fx, fy, fz, t, d): (f64, f64, f64, f64, f64) = item.extract().map_err(|_| input_error(format!("pushes[{index}]: expected \"X,Y,Z@T:DUR\" or (fx, fy, fz, start, duration), got {item}")))?;
            format!("{fx},{fy},{fz}@{t}:{d}")
        }
    };
    legwork::sim::Push::parse(&text).map_err(|e| input_error(format!("pushes[{index}]: {e}")))
}

/// A plan argument: a Trajectory or a trajectory.json path.
fn plan_of(reference: &Bound<'_, PyAny>) -> PyResult<(legwork::io::Trajectory, String)> {
    if let Ok(t) = reference.cast::<Trajectory>() {
        return Ok((t.get().motion.clone(), "reference (Trajectory)".into()));
    }
    let path = path_or_name(reference, "reference")?;
    let plan = legwork::io::Trajectory::load_file(&path).map_err(|e| input_error(e.to_string()))?;
    Ok((plan, path))
}

/// Simulates a robot (`legwork simulate`): the standing PD, or a plan tracked (`"track"`) or
/// replayed with its feedback policy (`"policy"`), with pushes on the base; returns the run
/// (its `summary` has the figures) and writes the command's files to `out` (default
/// `out/simulate`; `write=False`: none).
#[pyfunction]
#[pyo3(signature = (robot=None, *, controller="stand", reference=None, duration=3.0, pushes=None, drop_height=0.0, terrain=None, integrator="euler", physics_rate=2000.0, control_rate=1000.0, record_rate=None, out=None, write=true, progress=None, memory_limit_gb=None, png=false))]
#[allow(clippy::too_many_arguments)]
pub fn simulate(
    py: Python<'_>,
    robot: Option<&Bound<'_, PyAny>>,
    controller: &str,
    reference: Option<&Bound<'_, PyAny>>,
    duration: f64,
    pushes: Option<&Bound<'_, PyAny>>,
    drop_height: f64,
    terrain: Option<PathBuf>,
    integrator: &str,
    physics_rate: f64,
    control_rate: f64,
    record_rate: Option<f64>,
    out: Option<PathBuf>,
    write: bool,
    progress: Option<Py<PyAny>>,
    memory_limit_gb: Option<f64>,
    png: bool,
) -> PyResult<Trajectory> {
    let out = write.then(|| out.unwrap_or_else(|| PathBuf::from("out/simulate")));
    use legwork::job::simulate::{SimController, SimulateJob};
    let (model, spec) = model_of(robot, "hyq", "robot")?;
    let scenario = format!("legwork.simulate({spec:?}, controller={controller:?}, duration={duration})");
    let (controller, origin) = match (controller, reference) {
        ("stand", None) => (SimController::Stand, String::new()),
        ("stand", Some(_)) => return Err(input_error("reference: is for controller=\"track\" or \"policy\"".into())),
        ("track" | "policy", None) => return Err(input_error(format!("controller={controller:?} needs reference= (a Trajectory or a trajectory.json path)"))),
        ("track", Some(r)) => plan_of(r).map(|(p, o)| (SimController::Track(p), o))?,
        ("policy", Some(r)) => plan_of(r).map(|(p, o)| (SimController::Policy(p), o))?,
        (other, _) => return Err(input_error(format!("controller: expected \"stand\", \"track\" or \"policy\", got {other:?}"))),
    };
    let pushes = match pushes {
        None => Vec::new(),
        Some(list) => list.try_iter()?.enumerate().map(|(i, item)| push(&item?, i)).collect::<PyResult<Vec<_>>>()?,
    };
    let height_map = match &terrain {
        Some(path) => Some(legwork::terrain::HeightMap::load_file(path).map_err(|e| input_error(e.to_string()))?),
        None => None,
    };
    let integrator = match integrator {
        "euler" => legwork::sim::Integrator::SemiImplicitEuler,
        "rk4" => legwork::sim::Integrator::Rk4,
        other => return Err(input_error(format!("integrator: expected \"euler\" or \"rk4\", got {other:?}"))),
    };
    let job = SimulateJob {
        model: &model,
        controller,
        reference_origin: origin,
        terrain: height_map.as_ref().map(|m| m as &dyn legwork::terrain::Terrain),
        duration,
        pushes,
        drop_height,
        integrator,
        physics_rate,
        control_rate,
        record_rate,
        scenario,
        memory_limit: MemoryLimit { gb: memory_limit_gb, setting: "memory_limit_gb" },
        png,
        setting: keyword,
    };
    job.check().map_err(job_error)?;
    let progress = Progress::new(progress);
    let done = py
        .detach(|| {
            // At most a hundred calls a run, the last at 1.
            let mut last = 0.0;
            let done = job.run(out.as_deref(), |fraction| {
                if fraction - last >= 0.01 {
                    last = fraction;
                    progress.call(|py| Ok(PyTuple::new(py, [fraction])?.unbind()));
                }
            });
            if done.is_ok() {
                progress.call(|py| Ok(PyTuple::new(py, [1.0])?.unbind()));
            }
            done
        })
        .map_err(job_error)?;
    let done = progress.finish(done)?;
    Ok(Trajectory::new(done.trajectory))
}

/// The result of [`walk`]: the run, the trial's report (the numbers of summary.json) and the verdict.
#[pyclass(name = "WalkResult", module = "legwork", frozen)]
pub struct WalkResult {
    #[pyo3(get)]
    trajectory: Py<Trajectory>,
    /// `"met"` (the goal reached) or `"missed"`.
    #[pyo3(get)]
    verdict: String,
    /// The trial in numbers (goal error, walking time, speed, plans and their timings, ...).
    #[pyo3(get)]
    report: Py<PyAny>,
    #[pyo3(get)]
    out: Option<PathBuf>,
}

#[pymethods]
impl WalkResult {
    #[getter]
    fn met(&self) -> bool {
        self.verdict == "met"
    }
    fn __repr__(&self) -> String {
        format!("legwork.WalkResult(verdict={:?}, out={})", self.verdict, repr_path(&self.out))
    }
}

/// One trial of Winkler 2015's terrain pipeline (`legwork walk`): an embedded scenario
/// (`flat`, `pallet`, `two_pallets`, `gap`, `stepping_stones`, `pallet_appears`) or a
/// scenario file; `random=True` randomizes it as `legwork bench terrain` does (trial `seed`).
/// Writes the command's files to `out` (default `out/walk-<scenario>`; `write=False`: none).
#[pyfunction]
#[pyo3(signature = (scenario, *, seed=1, random=false, out=None, write=true, progress=None, png=false))]
#[allow(clippy::too_many_arguments)]
pub fn walk(py: Python<'_>, scenario: &Bound<'_, PyAny>, seed: u64, random: bool, out: Option<PathBuf>, write: bool, progress: Option<Py<PyAny>>, png: bool) -> PyResult<WalkResult> {
    use legwork::walk::trial::TrialSetup;
    let spec = legwork::walk::ScenarioSpec::resolve(&path_or_name(scenario, "scenario")?).map_err(|e| input_error(e.to_string()))?;
    let model = legwork::model::load(&spec.robot).map_err(|e| input_error(format!("scenario {}: robot: {e}", spec.name)))?;
    let setup = if random { TrialSetup::random(seed) } else { TrialSetup::nominal(seed) };
    let out = write.then(|| out.unwrap_or_else(|| PathBuf::from("out").join(format!("walk-{}", spec.name))));
    let progress = Progress::new(progress);
    let walked = py.detach(|| legwork::job::walk::walk(&model, &spec, setup, out.as_deref(), png, |t, what| progress.call(|py| Ok((t, what).into_pyobject(py)?.unbind())))).map_err(job_error)?;
    let walked = progress.finish(walked)?;
    let report = to_python(py, &serde_json::to_value(&walked.report).map_err(|e| could_not_finish(e.to_string()))?)?.unbind();
    Ok(WalkResult { trajectory: Py::new(py, Trajectory::new(walked.trajectory))?, verdict: walked.verdict.as_str().to_string(), report, out })
}

/// The result of [`jump`]: the plans, the controllers' run and the report.
#[pyclass(name = "JumpResult", module = "legwork", frozen)]
pub struct JumpResult {
    /// `"landed"`, `"contact timing failed"`, `"full body failed"`, `"missed target"` or `"fell"`.
    #[pyo3(get)]
    verdict: String,
    /// 0 landed on target, 1 missed or fell, 3 an optimization failed (the command's).
    #[pyo3(get)]
    exit_code: u8,
    /// The optimal phase durations (s) of the contact timing (Nguyen 2022 eq. 1-2).
    #[pyo3(get)]
    phase_durations: Vec<f64>,
    /// The full-body plan (10 ms knots), if the full-body optimization ran.
    #[pyo3(get)]
    plan: Option<Py<Trajectory>>,
    /// The jump and landing controllers' run in legwork's simulator, if it ran.
    #[pyo3(get)]
    rerun: Option<Py<Trajectory>>,
    /// The report (`trajectory.json`'s summary): each stage, the landing errors, the trials.
    #[pyo3(get)]
    summary: Py<PyAny>,
    #[pyo3(get)]
    out: Option<PathBuf>,
}

#[pymethods]
impl JumpResult {
    #[getter]
    fn met(&self) -> bool {
        self.exit_code == 0
    }
    fn __repr__(&self) -> String {
        format!("legwork.JumpResult(verdict={:?}, out={})", self.verdict, repr_path(&self.out))
    }
}

/// Nguyen 2022's 3D jump (`legwork jump`): an embedded jump (`legwork.jumps()`) or a jump
/// file; contact timing, full-body optimization, jump and landing controllers in legwork's
/// simulator, `trials` robustness trials. Writes the command's files to `out` (default
/// `out/jump/<jump>`; `write=False`: none). `progress(stage, done)` sees each stage.
#[pyfunction]
#[pyo3(signature = (jump, *, knots=None, trials=0, threads=0, out=None, write=true, progress=None, png=false))]
#[allow(clippy::too_many_arguments)]
pub fn jump(py: Python<'_>, jump: &Bound<'_, PyAny>, knots: Option<usize>, trials: usize, threads: usize, out: Option<PathBuf>, write: bool, progress: Option<Py<PyAny>>, png: bool) -> PyResult<JumpResult> {
    use legwork::jump::{Jump, PipelineOptions, Verdict as JumpVerdict};
    let spec = Jump::load(&path_or_name(jump, "jump")?).map_err(|e| input_error(e.to_string()))?;
    let model = legwork::model::load(&spec.robot).map_err(|e| input_error(format!("jump {}: robot: {e}", spec.name)))?;
    if trials > 1000 {
        return Err(input_error(format!("trials: expected at most 1000 (the paper runs 20), got {trials}")));
    }
    let settings = legwork::job::jump::settings_of(&spec, knots, "knots").map_err(job_error)?;
    let out = write.then(|| out.unwrap_or_else(|| PathBuf::from("out").join("jump").join(&spec.name)));
    let mut options = PipelineOptions { contact_timing: settings, trials, ..PipelineOptions::of(&spec) };
    let progress = Progress::new(progress);
    let (report, _) = py
        .detach(|| legwork::job::jump::jump(&spec, &model, &mut options, threads, out.as_deref(), png, |stage, done| progress.call(|py| Ok((legwork::job::jump::stage_name(stage), done).into_pyobject(py)?.unbind()))))
        .map_err(job_error)?;
    let report = progress.finish(report)?;
    let verdict = report.verdict();
    let name = match verdict {
        JumpVerdict::Landed => "landed",
        JumpVerdict::ContactTimingFailed => "contact timing failed",
        JumpVerdict::FullBodyFailed => "full body failed",
        JumpVerdict::MissedTarget => "missed target",
        JumpVerdict::Fell => "fell",
    };
    let traj = |t: &legwork::io::Trajectory| Py::new(py, Trajectory::new(t.clone()));
    Ok(JumpResult {
        verdict: name.to_string(),
        exit_code: verdict.exit_code(),
        phase_durations: report.contact_timing.durations.clone(),
        plan: report.full_body_plan.as_ref().map(|p| traj(&p.trajectory)).transpose()?,
        rerun: report.rerun.as_ref().map(|r| traj(&r.trajectory)).transpose()?,
        summary: to_python(py, &serde_json::Value::Object(report.summary(&spec)))?.unbind(),
        out,
    })
}

/// The embedded jumps: name -> one-line summary.
#[pyfunction]
pub fn jumps() -> PyResult<Vec<(String, String)>> {
    legwork::jump::EMBEDDED_JUMPS
        .iter()
        .map(|(name, _, _)| Ok((name.to_string(), legwork::jump::Jump::embedded(name).map_err(|e| input_error(e.to_string()))?.summary.clone())))
        .collect()
}

/// A folder as Python prints it: `'out/x'` or `None`.
fn repr_path(path: &Option<PathBuf>) -> String {
    path.as_ref().map_or("None".into(), |p| format!("{:?}", p.display().to_string()))
}
