//! `legwork._legwork`: the compiled half of the `legwork` Python package (pyo3). The
//! package's `__init__.py` re-exports it with the pure-Python parts (MuJoCo helpers, sweeps).

use pyo3::prelude::*;

mod checks;
mod convert;
mod errors;
mod jobs;
mod robot;
mod trajectory;

#[pymodule]
fn _legwork(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("LegworkError", py.get_type::<errors::LegworkError>())?;
    m.add("InputError", py.get_type::<errors::InputError>())?;
    m.add("CouldNotFinishError", py.get_type::<errors::CouldNotFinishError>())?;
    m.add_class::<robot::Robot>()?;
    m.add_class::<trajectory::Trajectory>()?;
    m.add_class::<jobs::SolveResult>()?;
    m.add_class::<jobs::WalkResult>()?;
    m.add_class::<jobs::JumpResult>()?;
    m.add_function(wrap_pyfunction!(robots, m)?)?;
    m.add_function(wrap_pyfunction!(jobs::solve, m)?)?;
    m.add_function(wrap_pyfunction!(jobs::tasks, m)?)?;
    m.add_function(wrap_pyfunction!(jobs::simulate, m)?)?;
    m.add_function(wrap_pyfunction!(jobs::walk, m)?)?;
    m.add_function(wrap_pyfunction!(jobs::jump, m)?)?;
    m.add_function(wrap_pyfunction!(jobs::jumps, m)?)?;
    m.add_function(wrap_pyfunction!(jobs::task_dict, m)?)?;
    m.add_function(wrap_pyfunction!(checks::figures, m)?)?;
    m.add_function(wrap_pyfunction!(checks::check_targets, m)?)?;
    m.add_function(wrap_pyfunction!(checks::mjcf, m)?)?;
    m.add_function(wrap_pyfunction!(checks::mujoco_replay, m)?)?;
    m.add_function(wrap_pyfunction!(checks::mujoco_check, m)?)?;
    Ok(())
}

/// The embedded robots: name -> one-line summary.
#[pyfunction]
fn robots() -> PyResult<Vec<(String, String)>> {
    legwork::model::embedded::names().iter().map(|n| Ok((n.to_string(), legwork::model::embedded::summary(n).map_err(|e| errors::input_error(e.to_string()))?))).collect()
}
