//! The landing controller's QP on the single rigid body (Nguyen 2022, sec. III, extending
//! the Cheetah 3 landing QP of their ref. \[4\]): ground reaction forces of the feet in
//! contact that best produce the wrench of a PD on the CoM position and the base
//! orientation, inside the friction cones and the normal force bounds.
//!
//! ```text
//! pdd* = K_p,x (p^d - p) + K_d,x (pd^d - pd)
//! wd*  = K_p,R log(R^d R^T) + K_d,R (w^d - w)                     (world axes)
//! b    = [m (pdd* - g);  R I_b R^T wd*]
//! A    = [I_3 ... I_3;  [p_f,1 - p]x ... [p_f,4 - p]x]            (eq. 1a-1b)
//!
//! min_f  1/2 (A f - b)^T S (A f - b) + alpha/2 |f|^2
//! s.t.   |t_k . f_s| <= mu n . f_s   (k = 1, 2)                  friction pyramid
//!        f_min <= n . f_s <= f_max                               feet in contact
//!        |J_s^T f_s| <= tau_max                                  the leg's motors
//! ```
//!
//! The last row is the motors' limit on the force: the leg pushes the ground with `-f_s`
//! by `tau = -J_s^T f_s` (`J_s` the 3 x 3 leg Jacobian, world axes), so a force the knee
//! cannot give is not asked for (the simulator would clip the torque and the wrench would
//! be lost where the QP did not choose it).
//!
//! A foot not in contact (Remark 2: zero normal force until it touches) keeps its three
//! variables, but its columns of `A` are zero and its bounds `0 <= n . f <= f_max`: the
//! regularization alone drives its force to zero. The sparsity of `P` (the dense upper
//! triangle) and of the constraint matrix (one 6 x 3 block per foot) is therefore the same
//! at every tick: both are built once, and each solve overwrites their values in clarabel's
//! solver (no presolve, no zero dropping, so the data updates are allowed).

use super::JumpControlError;
use crate::spatial::{log3, skew};
use clarabel::algebra::CscMatrix;
use clarabel::solver::{DefaultSettings, DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT};
use nalgebra::{Matrix3, Vector3, Vector6};

/// Constraint rows per foot: four friction faces, the two normal force bounds, the upper
/// and lower limit of each of the leg's three motors.
const ROWS_PER_FOOT: usize = 12;

/// Gains, weights and limits of the landing QP.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LandingQpSettings {
    /// `K_p,x` (1/s^2) and `K_d,x` (1/s) of the CoM, world axes. Defaults 100 and 20
    /// (critically damped at 10 rad/s).
    pub position_kp: Vector3<f64>,
    pub position_kd: Vector3<f64>,
    /// `K_p,R` (1/s^2) and `K_d,R` (1/s) of the orientation. Defaults 150 and 24.5
    /// (critically damped at 12.2 rad/s).
    pub orientation_kp: Vector3<f64>,
    pub orientation_kd: Vector3<f64>,
    /// `S`, the weight of each row of the wrench residual `[F; M]` (1/N^2, 1/(N m)^2).
    /// Default `[1, 1, 1, 25, 25, 25]`: a moment error over the A1's 0.2 m half stance
    /// counts like the force that causes it.
    pub wrench_weight: Vector6<f64>,
    /// `alpha` (1/N^2). Default 1e-4: the tie-break towards small forces.
    pub regularization: f64,
    /// `mu` of the pyramid. Default 0.6: the simulator's ground has 0.8; the margin keeps
    /// the feet from sliding where the pyramid's corners exceed the circular cone.
    pub friction_coefficient: f64,
    /// Normal force bounds of a foot in contact (N). Defaults 0 and 200 N (about what an
    /// A1 leg's 33.5 N m knee gives at a 0.17 m lever).
    pub normal_force_min: f64,
    pub normal_force_max: f64,
}

impl Default for LandingQpSettings {
    fn default() -> Self {
        Self {
            position_kp: Vector3::repeat(100.0),
            position_kd: Vector3::repeat(20.0),
            orientation_kp: Vector3::repeat(150.0),
            orientation_kd: Vector3::repeat(24.5),
            wrench_weight: Vector6::new(1.0, 1.0, 1.0, 25.0, 25.0, 25.0),
            regularization: 1e-4,
            friction_coefficient: 0.6,
            normal_force_min: 0.0,
            normal_force_max: 200.0,
        }
    }
}

impl LandingQpSettings {
    pub fn validate(&self) -> Result<(), JumpControlError> {
        let nonneg = |x: &f64| x.is_finite() && *x >= 0.0;
        let check = |ok: bool, field: &'static str, expected: &str| if ok { Ok(()) } else { Err(JumpControlError::Setting { field, expected: expected.into() }) };
        check(self.position_kp.iter().chain(self.position_kd.iter()).all(nonneg), "landing.qp.position_kp/kd", "finite, non-negative gains")?;
        check(self.orientation_kp.iter().chain(self.orientation_kd.iter()).all(nonneg), "landing.qp.orientation_kp/kd", "finite, non-negative gains")?;
        check(self.wrench_weight.iter().all(|w| w.is_finite() && *w > 0.0), "landing.qp.wrench_weight", "finite, positive weights")?;
        check(self.regularization.is_finite() && self.regularization > 0.0, "landing.qp.regularization", "a finite, positive number")?;
        check(self.friction_coefficient.is_finite() && self.friction_coefficient > 0.0, "landing.qp.friction_coefficient", "a finite, positive number")?;
        check(nonneg(&self.normal_force_min) && self.normal_force_max.is_finite() && self.normal_force_max > self.normal_force_min, "landing.qp.normal_force_min/max", "0 <= min < max, finite (N)")
    }
}

/// The single rigid body measured: CoM, orientation, their velocities (world).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SrbState {
    pub com: Vector3<f64>,
    pub rotation: Matrix3<f64>,
    pub com_velocity: Vector3<f64>,
    pub angular_velocity: Vector3<f64>,
}

/// The pose the landing returns to, with zero velocity.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SrbTarget {
    pub com: Vector3<f64>,
    pub rotation: Matrix3<f64>,
}

/// One foot as the QP sees it (world frame).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QpFoot {
    pub position: Vector3<f64>,
    /// Unit surface normal under the foot.
    pub normal: Vector3<f64>,
    pub in_contact: bool,
    /// The leg Jacobian `d p_foot / d q_leg` (world axes, hip to knee columns).
    pub leg_jacobian: Matrix3<f64>,
    /// The leg's motor limits (N m), hip to knee.
    pub torque_limit: Vector3<f64>,
}

/// What one solve did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LandingQpInfo {
    pub iterations: u32,
    /// `|A f - b|` of the solution, unweighted: the part of the wrench the feet cannot give.
    pub wrench_residual: f64,
}

/// The landing QP of four feet with its solver, set up once.
pub struct LandingQp {
    settings: LandingQpSettings,
    mass: f64,
    inertia_body: Matrix3<f64>,
    gravity: Vector3<f64>,
    feet: usize,
    solver: DefaultSolver<f64>,
    p_values: Vec<f64>,
    q: Vec<f64>,
    a_values: Vec<f64>,
    b: Vec<f64>,
    /// The wrench map `A` (6 x 3 per foot) and the desired wrench `b` of the last solve.
    wrench_map: Vec<[Vector6<f64>; 3]>,
    wrench: Vector6<f64>,
    forces: Vec<Vector3<f64>>,
}

impl LandingQp {
    /// The QP of a body of `mass` (kg) and `inertia_body` (kg m^2, base axes, about the
    /// CoM) under `gravity` (world, m/s^2) on `feet` feet.
    pub fn new(settings: LandingQpSettings, mass: f64, inertia_body: Matrix3<f64>, gravity: Vector3<f64>, feet: usize) -> Result<Self, JumpControlError> {
        settings.validate()?;
        if !(mass.is_finite() && mass > 0.0) || inertia_body.iter().any(|x| !x.is_finite()) || gravity.iter().any(|x| !x.is_finite()) || feet == 0 {
            return Err(JumpControlError::Setting { field: "landing QP body", expected: "a positive mass, finite inertia and gravity, at least one foot".into() });
        }
        let n = 3 * feet;
        let m = ROWS_PER_FOOT * feet;
        // P: the dense upper triangle, column by column.
        // P: the dense upper triangle, column by column (identity values for the setup;
        // each solve overwrites them).
        let (mut colptr, mut rowval, mut p0) = (vec![0], vec![], vec![]);
        for j in 0..n {
            for i in 0..=j {
                rowval.push(i);
                p0.push(if i == j { 1.0 } else { 0.0 });
            }
            colptr.push(rowval.len());
        }
        let p_values = vec![0.0; rowval.len()];
        let p = CscMatrix::new(n, n, colptr, rowval, p0);
        // Constraints: the 6 x 3 block of each foot, column-major.
        let (mut colptr, mut rowval) = (vec![0], vec![]);
        for j in 0..n {
            let foot = j / 3;
            rowval.extend(ROWS_PER_FOOT * foot..ROWS_PER_FOOT * (foot + 1));
            colptr.push(rowval.len());
        }
        let a_values = vec![0.0; rowval.len()];
        let mut a = CscMatrix::new(m, n, colptr, rowval, a_values.clone());
        let mut b = vec![0.0; m];
        let standing = QpFoot { position: Vector3::zeros(), normal: Vector3::z(), in_contact: true, leg_jacobian: Matrix3::identity(), torque_limit: Vector3::repeat(1.0) };
        fill_constraints(&settings, &vec![standing; feet], &mut a.nzval, &mut b);
        let cones = [SupportedConeT::NonnegativeConeT(m)];
        let solver = DefaultSolver::new(&p, &vec![0.0; n], &a, &b, &cones, solver_settings()?).map_err(|e| JumpControlError::Qp(format!("setup: {e}")))?;
        if !solver.is_data_update_allowed() {
            return Err(JumpControlError::Qp("clarabel does not allow data updates with these settings".into()));
        }
        Ok(Self {
            settings,
            mass,
            inertia_body,
            gravity,
            feet,
            solver,
            p_values,
            q: vec![0.0; n],
            a_values,
            b,
            wrench_map: vec![[Vector6::zeros(); 3]; feet],
            wrench: Vector6::zeros(),
            forces: vec![Vector3::zeros(); feet],
        })
    }

    pub fn settings(&self) -> &LandingQpSettings {
        &self.settings
    }

    /// The desired wrench `b = [m (pdd* - g); R I_b R^T wd*]` of the PD (world, about the CoM).
    pub fn desired_wrench(&self, state: &SrbState, target: &SrbTarget) -> Vector6<f64> {
        let s = &self.settings;
        let pdd = s.position_kp.component_mul(&(target.com - state.com)) - s.position_kd.component_mul(&state.com_velocity);
        let orientation_error = log3(&(target.rotation * state.rotation.transpose()));
        let wd = s.orientation_kp.component_mul(&orientation_error) - s.orientation_kd.component_mul(&state.angular_velocity);
        let force = self.mass * (pdd - self.gravity);
        let moment = state.rotation * self.inertia_body * state.rotation.transpose() * wd;
        Vector6::new(force.x, force.y, force.z, moment.x, moment.y, moment.z)
    }

    /// Solves for the ground reaction forces on the robot (world, one per foot; zero for
    /// the feet not in contact).
    pub fn solve(&mut self, state: &SrbState, target: &SrbTarget, feet: &[QpFoot]) -> Result<(&[Vector3<f64>], LandingQpInfo), JumpControlError> {
        if feet.len() != self.feet {
            return Err(JumpControlError::Qp(format!("expected {} feet, got {}", self.feet, feet.len())));
        }
        self.wrench = self.desired_wrench(state, target);
        // A: [I; [p_f - p]x] per foot in contact, zero columns otherwise.
        for (foot, map) in feet.iter().zip(self.wrench_map.iter_mut()) {
            let lever = skew(&(foot.position - state.com));
            for (c, column) in map.iter_mut().enumerate() {
                *column = if foot.in_contact {
                    let l = lever.column(c);
                    Vector6::new(if c == 0 { 1.0 } else { 0.0 }, if c == 1 { 1.0 } else { 0.0 }, if c == 2 { 1.0 } else { 0.0 }, l[0], l[1], l[2])
                } else {
                    Vector6::zeros()
                };
            }
        }
        // P = A^T S A + alpha I (upper triangle), q = -A^T S b.
        let s = &self.settings;
        let weight = &s.wrench_weight;
        let column = |j: usize| &self.wrench_map[j / 3][j % 3];
        let mut k = 0;
        for j in 0..3 * self.feet {
            let aj = column(j).component_mul(weight);
            for i in 0..=j {
                self.p_values[k] = aj.dot(column(i)) + if i == j { s.regularization } else { 0.0 };
                k += 1;
            }
            self.q[j] = -aj.dot(&self.wrench);
        }
        fill_constraints(s, feet, &mut self.a_values, &mut self.b);
        let update = |e: clarabel::solver::DataUpdateError| JumpControlError::Qp(format!("data update: {e}"));
        self.solver.update_P(&self.p_values).map_err(update)?;
        self.solver.update_q(&self.q).map_err(update)?;
        self.solver.update_A(&self.a_values).map_err(update)?;
        self.solver.update_b(&self.b).map_err(update)?;
        self.solver.solve();
        let solution = &self.solver.solution;
        if !matches!(solution.status, SolverStatus::Solved | SolverStatus::AlmostSolved) {
            return Err(JumpControlError::Qp(format!("clarabel: {:?} after {} iterations", solution.status, solution.iterations)));
        }
        let mut produced = Vector6::zeros();
        for (f, foot) in feet.iter().enumerate() {
            self.forces[f] = if foot.in_contact { Vector3::new(solution.x[3 * f], solution.x[3 * f + 1], solution.x[3 * f + 2]) } else { Vector3::zeros() };
            for c in 0..3 {
                produced += self.wrench_map[f][c] * self.forces[f][c];
            }
        }
        let info = LandingQpInfo { iterations: solution.iterations, wrench_residual: (produced - self.wrench).norm() };
        Ok((&self.forces, info))
    }
}

/// The friction pyramid, normal bounds and motor limits of every foot, `A_c f <= b_c`, into
/// the values of the constraint matrix (column-major 12 x 3 blocks) and `b`.
fn fill_constraints(s: &LandingQpSettings, feet: &[QpFoot], a_values: &mut [f64], b: &mut [f64]) {
    let mu = s.friction_coefficient;
    for (f, foot) in feet.iter().enumerate() {
        let n = foot.normal;
        let (t1, t2) = tangents(&n);
        let j = &foot.leg_jacobian;
        let (j0, j1, j2) = (j.column(0).into_owned(), j.column(1).into_owned(), j.column(2).into_owned());
        let rows = [t1 - mu * n, -t1 - mu * n, t2 - mu * n, -t2 - mu * n, -n, n, j0, -j0, j1, -j1, j2, -j2];
        for c in 0..3 {
            for (r, row) in rows.iter().enumerate() {
                a_values[(3 * f + c) * ROWS_PER_FOOT + r] = row[c];
            }
        }
        let r0 = ROWS_PER_FOOT * f;
        b[r0..r0 + 4].fill(0.0);
        b[r0 + 4] = if foot.in_contact { -s.normal_force_min } else { 0.0 };
        b[r0 + 5] = s.normal_force_max;
        for k in 0..3 {
            b[r0 + 6 + 2 * k] = foot.torque_limit[k];
            b[r0 + 7 + 2 * k] = foot.torque_limit[k];
        }
    }
}

/// Two unit tangents completing the unit normal `n` to a right-handed frame.
fn tangents(n: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let helper = if n.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() };
    let t2 = n.cross(&helper).normalize();
    (t2.cross(n), t2)
}

fn solver_settings() -> Result<DefaultSettings<f64>, JumpControlError> {
    DefaultSettingsBuilder::default()
        .verbose(false)
        .presolve_enable(false)
        .input_sparse_dropzeros(false)
        .equilibrate_enable(false)
        .max_iter(50)
        .build()
        .map_err(|e| JumpControlError::Qp(format!("settings: {e}")))
}
