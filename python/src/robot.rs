//! `legwork.Robot`: a model (immutable, shared) and its dynamics workspace (Pinocchio's
//! Model/Data split), with the dynamics algorithms on numpy arrays.
//!
//! Each call copies its inputs into vectors the robot keeps (a few dozen floats: no
//! allocation) and returns a new array, or writes into `out=` when given one.

use crate::errors::{input_error, InputError};
use legwork::dynamics::{self, Data, ReferenceFrame};
use legwork::model::Model;
use nalgebra::{DMatrix, DVector, Matrix6xX};
use numpy::{AllowTypeChange, PyArray1, PyArray2, PyArrayLike1, PyArrayMethods, PyReadonlyArray1, PyUntypedArrayMethods, ToPyArray};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::sync::Arc;

/// A robot: an embedded name (`"hyq"`, `"a1"`), a URDF file or a legwork description
/// (`.toml`), with its dynamics workspace.
#[pyclass(name = "Robot", module = "legwork")]
pub struct Robot {
    pub(crate) model: Arc<Model>,
    /// What the robot was loaded from (the argument of the constructor).
    pub(crate) spec: String,
    data: Data,
    q: DVector<f64>,
    v: DVector<f64>,
    w: DVector<f64>,
    jacobian: Matrix6xX<f64>,
}

impl Robot {
    pub(crate) fn from_model(model: Model, spec: String) -> Self {
        let data = Data::new(&model);
        let (nq, nv) = (model.nq, model.nv);
        Self { jacobian: Matrix6xX::zeros(nv), model: Arc::new(model), spec, data, q: DVector::zeros(nq), v: DVector::zeros(nv), w: DVector::zeros(nv) }
    }

    /// Copies `array` into `into`, checking its length (the robot's `dimension`, "nq" or
    /// "nv") and that every value is finite. Allocates only for an error's message.
    fn read(what: &str, array: &PyReadonlyArray1<f64>, into: &mut DVector<f64>, dimension: &str, robot: &str) -> PyResult<()> {
        let n = into.len();
        let got = array.len();
        if got != n {
            return Err(input_error(format!("{what}: expected {n} values (the robot's {dimension} for {robot}), got {got}")));
        }
        match array.as_slice() {
            Ok(values) => into.as_mut_slice().copy_from_slice(values),
            Err(_) => {
                for (i, x) in array.as_array().iter().enumerate() {
                    into[i] = *x;
                }
            }
        }
        if let Some(i) = into.iter().position(|x| !x.is_finite()) {
            return Err(input_error(format!("{what}: element {i} is not finite ({})", into[i])));
        }
        Ok(())
    }

    fn read_q(&mut self, what: &str, q: &PyReadonlyArray1<f64>) -> PyResult<()> {
        Self::read(what, q, &mut self.q, "nq", &self.model.name)?;
        // The quaternion of a free-flyer base must be a rotation: refuse one far from unit.
        if self.model.has_free_flyer() {
            let norm = self.q.rows(3, 4).norm();
            if (norm - 1.0).abs() > 1e-3 {
                return Err(input_error(format!("{what}: the base quaternion q[3:7] (x, y, z, w) has norm {norm:.6}, expected 1")));
            }
        }
        Ok(())
    }

    fn read_v(&mut self, what: &str, v: &PyReadonlyArray1<f64>) -> PyResult<()> {
        Self::read(what, v, &mut self.v, "nv", &self.model.name)
    }

    fn read_w(&mut self, what: &str, w: &PyReadonlyArray1<f64>) -> PyResult<()> {
        Self::read(what, w, &mut self.w, "nv", &self.model.name)
    }

    fn frame_index(&self, frame: &Bound<'_, PyAny>) -> PyResult<usize> {
        if let Ok(name) = frame.extract::<String>() {
            return self.model.frame_id(&name).map_err(|e| input_error(format!("frame: {e}; the robot's frames are in Robot.frame_names")));
        }
        let index: usize = frame.extract().map_err(|_| input_error("frame: expected a frame name (str) or index (int)".to_string()))?;
        if index >= self.model.frames.len() {
            return Err(input_error(format!("frame: index {index} out of range ({} frames)", self.model.frames.len())));
        }
        Ok(index)
    }

    /// A vector result: written into `out` (a float64 array of the right length, returned
    /// as it is), or a new array.
    fn vector_out<'py>(py: Python<'py>, values: &DVector<f64>, out: Option<Bound<'py, PyArray1<f64>>>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let Some(out) = out else { return Ok(PyArray1::from_slice(py, values.as_slice())) };
        {
            let mut writable = out.try_readwrite().map_err(|e| input_error(format!("out: {e}")))?;
            let slice = writable.as_slice_mut().map_err(|_| input_error("out: expected a contiguous array".to_string()))?;
            if slice.len() != values.len() {
                return Err(input_error(format!("out: expected an array of {} values, got {}", values.len(), slice.len())));
            }
            slice.copy_from_slice(values.as_slice());
        }
        Ok(out)
    }
}

/// Three matrices (derivatives: with respect to q, v, and the third argument).
type Matrices3<'py> = (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray2<f64>>, Bound<'py, PyArray2<f64>>);
/// A rotation and a position.
type Placement<'py> = (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray1<f64>>);

fn matrix<'py>(py: Python<'py>, m: &DMatrix<f64>) -> Bound<'py, PyArray2<f64>> {
    // nalgebra is column-major; a numpy array from the transposed rows keeps the indices.
    numpy::ndarray::Array2::from_shape_fn((m.nrows(), m.ncols()), |(i, j)| m[(i, j)]).to_pyarray(py)
}

fn matrix6x<'py>(py: Python<'py>, m: &Matrix6xX<f64>) -> Bound<'py, PyArray2<f64>> {
    numpy::ndarray::Array2::from_shape_fn((6, m.ncols()), |(i, j)| m[(i, j)]).to_pyarray(py)
}

#[pymethods]
impl Robot {
    /// Loads a robot: an embedded name (`legwork.robots()`), a `.urdf` file (the
    /// `standing` pose from an SRDF beside it) or a legwork description (`.toml`).
    #[new]
    fn new(robot: &Bound<'_, PyAny>) -> PyResult<Self> {
        let spec = path_or_name(robot, "robot")?;
        let model = legwork::model::load(&spec).map_err(|e| InputError::new_err(e.to_string()))?;
        Ok(Self::from_model(model, spec))
    }

    /// Pickles as its constructor's argument (Ray and multiprocessing ship robots by name).
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<(Bound<'py, PyAny>, (String,))> {
        Ok((slf.get_type().into_any(), (slf.borrow().spec.clone(),)))
    }

    fn __repr__(&self) -> String {
        format!("legwork.Robot({:?}: nq={}, nv={}, {:.3} kg, {} feet)", self.model.name, self.model.nq, self.model.nv, self.model.total_mass(), self.model.feet.len())
    }

    #[getter]
    fn name(&self) -> &str {
        &self.model.name
    }
    /// Dimension of the configuration `q = [p, quat (x, y, z, w), joints]`.
    #[getter]
    fn nq(&self) -> usize {
        self.model.nq
    }
    /// Dimension of the velocity `v = [v_B, w_B (base frame), joints]`.
    #[getter]
    fn nv(&self) -> usize {
        self.model.nv
    }
    #[getter]
    fn total_mass(&self) -> f64 {
        self.model.total_mass()
    }
    /// The actuated joints, in the order of `q[7:]`, `v[6:]` and the torques.
    #[getter]
    fn joint_names(&self) -> Vec<String> {
        self.model.actuated_joint_names().into_iter().map(String::from).collect()
    }
    #[getter]
    fn foot_names(&self) -> Vec<String> {
        self.model.feet.iter().map(|f| f.name.clone()).collect()
    }
    #[getter]
    fn frame_names(&self) -> Vec<String> {
        self.model.frames.iter().map(|f| f.name.clone()).collect()
    }
    /// The feet's sphere radii (m), in the order of `foot_names`.
    #[getter]
    fn foot_radii<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_iter(py, self.model.feet.iter().map(|f| f.radius))
    }
    /// Per actuated joint: lower and upper position limits (rad), speed (rad/s) and effort (N m).
    #[getter]
    fn joint_limits<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        let joints: Vec<_> = self.model.actuated_joints().collect();
        for (key, pick) in [("lower", 0usize), ("upper", 1), ("velocity", 2), ("effort", 3)] {
            let values = joints.iter().flat_map(|j| {
                let l = &j.limits;
                match pick {
                    0 => l.lower.clone(),
                    1 => l.upper.clone(),
                    2 => l.velocity.clone(),
                    _ => l.effort.clone(),
                }
            });
            d.set_item(key, PyArray1::from_iter(py, values))?;
        }
        Ok(d)
    }
    /// The ground contact the robot carries (Neunert 2017's smooth model; the MJCF export's
    /// friction): stiffness, damping, friction coefficient and the rest.
    #[getter]
    fn contact<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        crate::convert::to_python(py, &serde_json::to_value(&self.model.contact).map_err(|e| input_error(e.to_string()))?)
    }
    /// The standing configuration (the `standing` reference pose).
    #[getter]
    fn standing<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let q = self.model.reference_configuration("standing").ok_or_else(|| input_error(format!("{}: no 'standing' reference configuration", self.model.name)))?;
        Ok(PyArray1::from_slice(py, q.as_slice()))
    }
    /// The neutral configuration (identity base, joints at zero or the middle of their range).
    fn neutral<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, self.model.neutral().as_slice())
    }

    /// Forward dynamics, the articulated-body algorithm: `ddq = ABA(q, v, tau)`.
    #[pyo3(signature = (q, v, tau, out=None))]
    fn aba<'py>(&mut self, py: Python<'py>, q: PyArrayLike1<'py, f64, AllowTypeChange>, v: PyArrayLike1<'py, f64, AllowTypeChange>, tau: PyArrayLike1<'py, f64, AllowTypeChange>, out: Option<Bound<'py, PyArray1<f64>>>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        self.read_q("aba: q", &q)?;
        self.read_v("aba: v", &v)?;
        self.read_w("aba: tau", &tau)?;
        let ddq = dynamics::aba(&self.model, &mut self.data, &self.q, &self.v, &self.w);
        Self::vector_out(py, ddq, out)
    }

    /// Benchmark helper: seconds per call of `aba` in Rust alone (`calls` calls on the
    /// robot's own workspace, no Python in between), the baseline of the call overhead.
    fn _time_aba(&mut self, q: PyArrayLike1<'_, f64, AllowTypeChange>, v: PyArrayLike1<'_, f64, AllowTypeChange>, tau: PyArrayLike1<'_, f64, AllowTypeChange>, calls: usize) -> PyResult<f64> {
        self.read_q("_time_aba: q", &q)?;
        self.read_v("_time_aba: v", &v)?;
        self.read_w("_time_aba: tau", &tau)?;
        let started = std::time::Instant::now();
        for _ in 0..calls {
            std::hint::black_box(dynamics::aba(&self.model, &mut self.data, std::hint::black_box(&self.q), &self.v, &self.w));
        }
        Ok(started.elapsed().as_secs_f64() / calls.max(1) as f64)
    }

    /// Inverse dynamics, the recursive Newton-Euler algorithm: `tau = RNEA(q, v, a)`.
    #[pyo3(signature = (q, v, a, out=None))]
    fn rnea<'py>(&mut self, py: Python<'py>, q: PyArrayLike1<'py, f64, AllowTypeChange>, v: PyArrayLike1<'py, f64, AllowTypeChange>, a: PyArrayLike1<'py, f64, AllowTypeChange>, out: Option<Bound<'py, PyArray1<f64>>>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        self.read_q("rnea: q", &q)?;
        self.read_v("rnea: v", &v)?;
        self.read_w("rnea: a", &a)?;
        let tau = dynamics::rnea(&self.model, &mut self.data, &self.q, &self.v, &self.w);
        Self::vector_out(py, tau, out)
    }

    /// The joint-space inertia matrix `M(q)` (composite rigid-body algorithm), full and symmetric.
    fn crba<'py>(&mut self, py: Python<'py>, q: PyArrayLike1<'py, f64, AllowTypeChange>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        self.read_q("crba: q", &q)?;
        Ok(matrix(py, dynamics::crba(&self.model, &mut self.data, &self.q)))
    }

    /// `M(q)^-1`, full and symmetric.
    fn minverse<'py>(&mut self, py: Python<'py>, q: PyArrayLike1<'py, f64, AllowTypeChange>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        self.read_q("minverse: q", &q)?;
        Ok(matrix(py, dynamics::compute_minverse(&self.model, &mut self.data, &self.q)))
    }

    /// Coriolis, centrifugal and gravity terms `h(q, v) = RNEA(q, v, 0)`.
    fn nonlinear_effects<'py>(&mut self, py: Python<'py>, q: PyArrayLike1<'py, f64, AllowTypeChange>, v: PyArrayLike1<'py, f64, AllowTypeChange>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        self.read_q("nonlinear_effects: q", &q)?;
        self.read_v("nonlinear_effects: v", &v)?;
        Ok(PyArray1::from_slice(py, dynamics::nonlinear_effects(&self.model, &mut self.data, &self.q, &self.v).as_slice()))
    }

    /// Generalized gravity `g(q) = RNEA(q, 0, 0)`.
    fn gravity<'py>(&mut self, py: Python<'py>, q: PyArrayLike1<'py, f64, AllowTypeChange>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        self.read_q("gravity: q", &q)?;
        Ok(PyArray1::from_slice(py, dynamics::generalized_gravity(&self.model, &mut self.data, &self.q).as_slice()))
    }

    /// Partial derivatives of forward dynamics: `(d ddq/dq, d ddq/dv, d ddq/dtau = M^-1)`,
    /// derivatives in the tangent space (Pinocchio's `computeABADerivatives`).
    fn aba_derivatives<'py>(&mut self, py: Python<'py>, q: PyArrayLike1<'py, f64, AllowTypeChange>, v: PyArrayLike1<'py, f64, AllowTypeChange>, tau: PyArrayLike1<'py, f64, AllowTypeChange>) -> PyResult<Matrices3<'py>> {
        self.read_q("aba_derivatives: q", &q)?;
        self.read_v("aba_derivatives: v", &v)?;
        self.read_w("aba_derivatives: tau", &tau)?;
        dynamics::compute_aba_derivatives(&self.model, &mut self.data, &self.q, &self.v, &self.w);
        Ok((matrix(py, &self.data.ddq_dq), matrix(py, &self.data.ddq_dv), matrix(py, &self.data.minv)))
    }

    /// Partial derivatives of inverse dynamics: `(d tau/dq, d tau/dv, d tau/da = M)`
    /// (Pinocchio's `computeRNEADerivatives`).
    fn rnea_derivatives<'py>(&mut self, py: Python<'py>, q: PyArrayLike1<'py, f64, AllowTypeChange>, v: PyArrayLike1<'py, f64, AllowTypeChange>, a: PyArrayLike1<'py, f64, AllowTypeChange>) -> PyResult<Matrices3<'py>> {
        self.read_q("rnea_derivatives: q", &q)?;
        self.read_v("rnea_derivatives: v", &v)?;
        self.read_w("rnea_derivatives: a", &a)?;
        dynamics::compute_rnea_derivatives(&self.model, &mut self.data, &self.q, &self.v, &self.w);
        Ok((matrix(py, &self.data.dtau_dq), matrix(py, &self.data.dtau_dv), matrix(py, &self.data.mass_matrix)))
    }

    /// A frame's placement in the world at `q`: `(R, p)`, the 3 x 3 rotation and the
    /// position (m). `frame` is a name (`Robot.frame_names`, the feet among them) or index.
    fn frame_placement<'py>(&mut self, py: Python<'py>, q: PyArrayLike1<'py, f64, AllowTypeChange>, frame: &Bound<'py, PyAny>) -> PyResult<Placement<'py>> {
        let frame = self.frame_index(frame)?;
        self.read_q("frame_placement: q", &q)?;
        dynamics::forward_kinematics(&self.model, &mut self.data, &self.q);
        let m = dynamics::frame_placement(&self.model, &mut self.data, frame);
        let r = numpy::ndarray::Array2::from_shape_fn((3, 3), |(i, j)| m.rotation[(i, j)]);
        Ok((r.to_pyarray(py), PyArray1::from_slice(py, m.translation.as_slice())))
    }

    /// The world positions of the feet at `q`, one row per foot (`foot_names`' order).
    fn foot_positions<'py>(&mut self, py: Python<'py>, q: PyArrayLike1<'py, f64, AllowTypeChange>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        self.read_q("foot_positions: q", &q)?;
        dynamics::forward_kinematics(&self.model, &mut self.data, &self.q);
        dynamics::update_frame_placements(&self.model, &mut self.data);
        let feet: Vec<_> = self.model.feet.iter().map(|f| dynamics::frame_position(&self.model, &self.data, f.frame)).collect();
        Ok(numpy::ndarray::Array2::from_shape_fn((feet.len(), 3), |(i, j)| feet[i][j]).to_pyarray(py))
    }

    /// A frame's 6 x nv Jacobian at `q` (linear rows first), in `reference`:
    /// `"local_world_aligned"` (default), `"local"` or `"world"` (Pinocchio's `ReferenceFrame`).
    #[pyo3(signature = (q, frame, reference="local_world_aligned"))]
    fn frame_jacobian<'py>(&mut self, py: Python<'py>, q: PyArrayLike1<'py, f64, AllowTypeChange>, frame: &Bound<'py, PyAny>, reference: &str) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let frame = self.frame_index(frame)?;
        let reference = match reference {
            "local_world_aligned" => ReferenceFrame::LocalWorldAligned,
            "local" => ReferenceFrame::Local,
            "world" => ReferenceFrame::World,
            other => return Err(input_error(format!("reference: expected \"local_world_aligned\", \"local\" or \"world\", got {other:?}"))),
        };
        self.read_q("frame_jacobian: q", &q)?;
        dynamics::compute_joint_jacobians(&self.model, &mut self.data, &self.q);
        dynamics::update_frame_placements(&self.model, &mut self.data);
        dynamics::frame_jacobian(&self.model, &self.data, frame, reference, &mut self.jacobian);
        Ok(matrix6x(py, &self.jacobian))
    }

    /// The centre of mass at `q` (world, m).
    fn center_of_mass<'py>(&mut self, py: Python<'py>, q: PyArrayLike1<'py, f64, AllowTypeChange>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        self.read_q("center_of_mass: q", &q)?;
        Ok(PyArray1::from_slice(py, dynamics::center_of_mass(&self.model, &mut self.data, &self.q).as_slice()))
    }

    /// The centroidal momentum at `(q, v)`: `[linear; angular]` about the centre of mass, world axes.
    fn centroidal_momentum<'py>(&mut self, py: Python<'py>, q: PyArrayLike1<'py, f64, AllowTypeChange>, v: PyArrayLike1<'py, f64, AllowTypeChange>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        self.read_q("centroidal_momentum: q", &q)?;
        self.read_v("centroidal_momentum: v", &v)?;
        let h = dynamics::centroidal_momentum(&self.model, &mut self.data, &self.q, &self.v);
        Ok(PyArray1::from_iter(py, h.f.iter().chain(h.n.iter()).copied()))
    }

    /// `q (+) v`: the configuration reached by following `v` for unit time (the base on SE(3)).
    fn integrate<'py>(&mut self, py: Python<'py>, q: PyArrayLike1<'py, f64, AllowTypeChange>, v: PyArrayLike1<'py, f64, AllowTypeChange>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        self.read_q("integrate: q", &q)?;
        self.read_v("integrate: v", &v)?;
        let mut out = DVector::zeros(self.model.nq);
        dynamics::integrate(&self.model, &self.q, &self.v, &mut out);
        Ok(PyArray1::from_slice(py, out.as_slice()))
    }

    /// `q1 (-) q0`: the velocity that takes `q0` to `q1` in unit time.
    fn difference<'py>(&mut self, py: Python<'py>, q0: PyArrayLike1<'py, f64, AllowTypeChange>, q1: PyArrayLike1<'py, f64, AllowTypeChange>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        self.read_q("difference: q0", &q0)?;
        let q0 = self.q.clone();
        self.read_q("difference: q1", &q1)?;
        let mut out = DVector::zeros(self.model.nv);
        dynamics::difference(&self.model, &q0, &self.q, &mut out);
        Ok(PyArray1::from_slice(py, out.as_slice()))
    }
}

/// A robot argument: a name (str) or an `os.PathLike`.
pub(crate) fn path_or_name(ob: &Bound<'_, PyAny>, what: &str) -> PyResult<String> {
    if let Ok(s) = ob.extract::<String>() {
        return Ok(s);
    }
    if let Ok(p) = ob.extract::<std::path::PathBuf>() {
        return Ok(p.display().to_string());
    }
    Err(input_error(format!("{what}: expected a name (str) or a path (str or os.PathLike)")))
}
