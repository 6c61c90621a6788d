//! `legwork.Trajectory`: a motion (legwork's `trajectory.json`) as numpy arrays.

use crate::convert::to_python;
use crate::errors::{could_not_finish, input_error};
use legwork::io::Trajectory as Motion;
use numpy::ndarray::{Array2, Array3};
use numpy::{PyArray1, PyArray2, PyArray3, ToPyArray};
use pyo3::prelude::*;

/// A motion: knots of time, state, torques, ground forces and contact flags, the feedback
/// gains where the plan has them, metadata and summary. Arrays are built on each access
/// (keep the one you use in a loop).
#[pyclass(name = "Trajectory", module = "legwork", frozen)]
pub struct Trajectory {
    pub(crate) motion: Motion,
}

impl Trajectory {
    pub(crate) fn new(motion: Motion) -> Self {
        Self { motion }
    }

    fn rows<'py>(&self, py: Python<'py>, width: usize, row: impl Fn(&legwork::io::Knot) -> &[f64]) -> Bound<'py, PyArray2<f64>> {
        let knots = &self.motion.knots;
        Array2::from_shape_fn((knots.len(), width), |(k, j)| row(&knots[k]).get(j).copied().unwrap_or(f64::NAN)).to_pyarray(py)
    }
}

#[pymethods]
impl Trajectory {
    /// Reads a `trajectory.json` (every field checked; errors name the file and the field).
    #[staticmethod]
    fn load(path: std::path::PathBuf) -> PyResult<Self> {
        Motion::load_file(&path).map(Self::new).map_err(|e| input_error(e.to_string()))
    }

    /// Writes it as `trajectory.json` (legwork's format; `legwork simulate --reference` reads it).
    fn save(&self, path: std::path::PathBuf) -> PyResult<()> {
        self.motion.save_file(&path).map_err(|e| could_not_finish(e.to_string()))
    }

    fn __len__(&self) -> usize {
        self.motion.knots.len()
    }

    fn __repr__(&self) -> String {
        let duration = self.motion.knots.last().map_or(0.0, |k| k.t) - self.motion.knots.first().map_or(0.0, |k| k.t);
        format!("legwork.Trajectory({}: {} knots, {:.3} s)", self.motion.metadata.robot, self.motion.knots.len(), duration)
    }

    /// Knot times (s), shape (K,).
    #[getter]
    fn t<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_iter(py, self.motion.knots.iter().map(|k| k.t))
    }
    /// Configurations, shape (K, nq): `[p, quat (x, y, z, w), joints]`.
    #[getter]
    fn q<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let n = self.motion.knots.first().map_or(0, |k| k.q.len());
        self.rows(py, n, |k| &k.q)
    }
    /// Velocities, shape (K, nv): `[v_B, w_B (base frame), joints]`.
    #[getter]
    fn v<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let n = self.motion.knots.first().map_or(0, |k| k.v.len());
        self.rows(py, n, |k| &k.v)
    }
    /// Joint torques (N m), shape (K, nu), `joint_names`' order.
    #[getter]
    fn tau<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let n = self.motion.knots.first().map_or(0, |k| k.tau.len());
        self.rows(py, n, |k| &k.tau)
    }
    /// Force of the ground on each foot (N, world frame), shape (K, feet, 3).
    #[getter]
    fn contact_force<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray3<f64>> {
        let knots = &self.motion.knots;
        let feet = knots.first().map_or(0, |k| k.contact_force.len());
        Array3::from_shape_fn((knots.len(), feet, 3), |(k, f, j)| knots[k].contact_force.get(f).map_or(f64::NAN, |c| c[j])).to_pyarray(py)
    }
    /// Which feet touch the ground: the contact schedule, shape (K, feet), bool.
    #[getter]
    fn in_contact<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<bool>> {
        let knots = &self.motion.knots;
        let feet = knots.first().map_or(0, |k| k.in_contact.len());
        Array2::from_shape_fn((knots.len(), feet), |(k, f)| knots[k].in_contact.get(f).copied().unwrap_or(false)).to_pyarray(py)
    }
    /// The feedback gains `K` of `tau = tau_ff + K [q (-) q*; v - v*]`, shape (K, nu, 2 nv),
    /// or None for a motion without them (a simulation).
    #[getter]
    fn gains<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray3<f64>>> {
        let knots = &self.motion.knots;
        let first = knots.iter().find_map(|k| k.feedback_gain.as_ref())?;
        let (rows, cols) = (first.len(), first.first().map_or(0, Vec::len));
        Some(Array3::from_shape_fn((knots.len(), rows, cols), |(k, i, j)| knots[k].feedback_gain.as_ref().and_then(|g| g.get(i)).and_then(|r| r.get(j)).copied().unwrap_or(0.0)).to_pyarray(py))
    }
    #[getter]
    fn joint_names(&self) -> Vec<String> {
        self.motion.metadata.joint_names.clone()
    }
    #[getter]
    fn foot_names(&self) -> Vec<String> {
        self.motion.metadata.foot_names.clone()
    }
    #[getter]
    fn robot(&self) -> String {
        self.motion.metadata.robot.clone()
    }
    /// The metadata (robot, names, dt, units, terrain, initial contact anchors), as a dict.
    #[getter]
    fn metadata<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_python(py, &serde_json::to_value(&self.motion.metadata).map_err(|e| could_not_finish(e.to_string()))?)
    }
    /// The figures of the run that made it (verdict, target checks, task figures), as a dict.
    #[getter]
    pub(crate) fn summary<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_python(py, &serde_json::Value::Object(self.motion.summary.clone()))
    }
}
