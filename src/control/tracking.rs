//! The tracking controller of Neunert 2017, sec. IV-B: the planned feedforward torques, a
//! joint-space PD on the planned joint positions and velocities, and a task-space PD on the
//! base pose (eq. 12) whose wrench is distributed to the stance feet of the planned contact
//! schedule and mapped to joint torques by `J_c^T`.

use super::interpolation::{interpolate_state, knot_bracket, KnotBracket};
use super::joint_pd::PdGains;
use crate::dynamics::{base_orientation, compute_joint_jacobians, crba, frame_jacobian, frame_position, Data, ReferenceFrame};
use crate::io::Trajectory;
use crate::model::Model;
use crate::sim::{ControlError, Controller, SimState};
use crate::spatial::{log3, skew};
use nalgebra::{DMatrix, DVector, Matrix3, Matrix6, Matrix6xX, Vector3, Vector6};

/// Gains of the task-space base PD (eq. 12), world frame, diagonal.
#[derive(Clone, Debug, PartialEq)]
pub struct BaseGains {
    /// Position stiffness `P_x` (N/m) and damping `D_x` (N s/m).
    pub position: (Vector3<f64>, Vector3<f64>),
    /// Orientation stiffness (N m/rad) and damping (N m s/rad).
    pub orientation: (Vector3<f64>, Vector3<f64>),
}

impl BaseGains {
    /// Critically damped base "virtual springs" (Neunert 2017 cite Pratt's virtual model
    /// control \[14\]) at natural frequency `omega` (rad/s), from the robot's mass and its
    /// rotational inertia about the base in `q_ref`: `P = m w^2`, `D = 2 m w`
    /// (likewise with the inertia's diagonal for orientation).
    pub fn from_model(model: &Model, q_ref: &DVector<f64>, omega: f64) -> Self {
        let mut data = Data::new(model);
        let m = crba(model, &mut data, q_ref);
        let mass = m[(0, 0)];
        let inertia = Vector3::new(m[(3, 3)], m[(4, 4)], m[(5, 5)]);
        Self {
            position: (Vector3::repeat(mass * omega * omega), Vector3::repeat(2.0 * mass * omega)),
            orientation: (inertia * omega * omega, inertia * 2.0 * omega),
        }
    }
}

/// The reference as vectors, converted once from the trajectory file.
struct Reference {
    t: Vec<f64>,
    q: Vec<DVector<f64>>,
    v: Vec<DVector<f64>>,
    tau: Vec<DVector<f64>>,
    stance: Vec<Vec<bool>>,
}

/// Neunert 2017, sec. IV-B:
///
/// ```text
/// tau   = tau_ff + Kp (q*_J - q_J) + Kd (qd*_J - qd_J) + tau_fb
/// F_cog = P_x (x* - x) + D_x (xd* - xd)                      eq. (12), and likewise
/// T     = P_o log(R* R^T) + D_o (w* - w)                     for the orientation
/// f     = G^T (G G^T + eps I)^-1 [F; T],   G = [I ..; [p_i - x]x ..] over the stance feet
/// tau_fb = - sum_i J_i^T f_i                                 (the legs push the ground with -f_i)
/// ```
///
/// No gravity compensation is added: the feedforward torques already hold the robot up.
/// Fewer than three stance feet make `G G^T` singular; the small `eps` (1e-8 of its trace)
/// then gives the least-squares wrench the feet can produce.
pub struct TrackingController {
    reference: Reference,
    joint_gains: PdGains,
    base_gains: BaseGains,
    data: Data,
    jac: Matrix6xX<f64>,
    grasp: DMatrix<f64>,
    forces: DVector<f64>,
    q_ref: DVector<f64>,
    v_ref: DVector<f64>,
    tau_ff: DVector<f64>,
    dq: DVector<f64>,
    stance: Vec<bool>,
}

impl TrackingController {
    /// Tracks `reference` (checked against `model`) with the given gains.
    pub fn new(model: &Model, reference: &Trajectory, joint_gains: PdGains, base_gains: BaseGains) -> Result<Self, ControlError> {
        let err = |problem: String| ControlError { controller: "tracking".into(), problem };
        reference.check_against(model, "reference trajectory").map_err(|e| err(e.to_string()))?;
        reference.validate("reference trajectory").map_err(|e| err(e.to_string()))?;
        if joint_gains.kp.len() != model.nv || joint_gains.kd.len() != model.nv {
            return Err(err(format!("joint gains need {} entries (nv)", model.nv)));
        }
        let nj = model.nv - 6;
        let mut r = Reference { t: vec![], q: vec![], v: vec![], tau: vec![], stance: vec![] };
        for k in &reference.knots {
            r.t.push(k.t);
            r.q.push(DVector::from_column_slice(&k.q));
            r.v.push(DVector::from_column_slice(&k.v));
            let mut tau = DVector::zeros(model.nv);
            tau.rows_mut(6, nj).copy_from_slice(&k.tau);
            r.tau.push(tau);
            r.stance.push(k.in_contact.clone());
        }
        let nfeet = model.feet.len();
        Ok(Self {
            reference: r,
            joint_gains,
            base_gains,
            data: Data::new(model),
            jac: Matrix6xX::zeros(model.nv),
            grasp: DMatrix::zeros(6, 3 * nfeet),
            forces: DVector::zeros(3 * nfeet),
            q_ref: DVector::zeros(model.nq),
            v_ref: DVector::zeros(model.nv),
            tau_ff: DVector::zeros(model.nv),
            dq: DVector::zeros(model.nv),
            stance: vec![false; nfeet],
        })
    }

    /// Default gains: joint PD from [`PdGains::from_model`] with its dampers capped for the
    /// robot in flight ([`PdGains::capped_for_free_joints`]) and base springs at 2 Hz, all
    /// at the reference's first configuration, for the control period `control_dt` (s).
    pub fn with_default_gains(model: &Model, reference: &Trajectory, control_dt: f64) -> Result<Self, ControlError> {
        let q0 = reference
            .knots
            .first()
            .map(|k| DVector::from_column_slice(&k.q))
            .ok_or_else(|| ControlError { controller: "tracking".into(), problem: "the reference has no knots".into() })?;
        if q0.len() != model.nq {
            return Err(ControlError { controller: "tracking".into(), problem: format!("reference q has {} entries, robot nq = {}", q0.len(), model.nq) });
        }
        // The plans fly (jumps, bounding hops): the joint dampers are capped for the robot
        // in flight, where the standing controller's cap lets a free leg chatter.
        let joint = PdGains::from_model(model, &q0, control_dt).capped_for_free_joints(model, &q0, control_dt);
        let base = BaseGains::from_model(model, &q0, 2.0 * std::f64::consts::PI * 2.0);
        Self::new(model, reference, joint, base)
    }

    /// Interpolates the reference at `t` (held at its ends): `q* = q_k (+) s (q_k+1 (-) q_k)`,
    /// `v*`, `tau_ff` linear, the stance of the nearer knot.
    fn sample(&mut self, model: &Model, t: f64) {
        let r = &self.reference;
        let (k, s) = match knot_bracket(&r.t, t) {
            KnotBracket::Hold(k) => {
                self.q_ref.copy_from(&r.q[k]);
                self.v_ref.copy_from(&r.v[k]);
                self.tau_ff.copy_from(&r.tau[k]);
                self.stance.copy_from_slice(&r.stance[k]);
                return;
            }
            KnotBracket::Between(k, s) => (k, s),
        };
        interpolate_state(model, (&r.q[k], &r.v[k]), (&r.q[k + 1], &r.v[k + 1]), s, &mut self.dq, &mut self.q_ref, &mut self.v_ref);
        self.tau_ff.copy_from(&r.tau[k]);
        self.tau_ff.axpy(s, &r.tau[k + 1], 1.0 - s);
        self.stance.copy_from_slice(&r.stance[if s < 0.5 { k } else { k + 1 }]);
    }

    /// The base wrench of eq. (12), world frame, about the base origin.
    fn base_wrench(&self, q: &DVector<f64>, v: &DVector<f64>) -> Vector6<f64> {
        let pose = |q: &DVector<f64>| {
            let r = base_orientation(q.as_slice()).to_rotation_matrix().into_inner();
            (Vector3::new(q[0], q[1], q[2]), r)
        };
        let (x, r) = pose(q);
        let (x_ref, r_ref) = pose(&self.q_ref);
        let xd = r * Vector3::new(v[0], v[1], v[2]);
        let w = r * Vector3::new(v[3], v[4], v[5]);
        let xd_ref = r_ref * Vector3::new(self.v_ref[0], self.v_ref[1], self.v_ref[2]);
        let w_ref = r_ref * Vector3::new(self.v_ref[3], self.v_ref[4], self.v_ref[5]);
        let (px, dx) = &self.base_gains.position;
        let (po, d_o) = &self.base_gains.orientation;
        let force = px.component_mul(&(x_ref - x)) + dx.component_mul(&(xd_ref - xd));
        let torque = po.component_mul(&log3(&(r_ref * r.transpose()))) + d_o.component_mul(&(w_ref - w));
        Vector6::new(force.x, force.y, force.z, torque.x, torque.y, torque.z)
    }
}

impl Controller for TrackingController {
    fn name(&self) -> &str {
        "track"
    }

    fn compute(&mut self, model: &Model, state: &SimState, tau: &mut DVector<f64>) -> Result<(), ControlError> {
        self.sample(model, state.t);
        let (q, v) = (&state.q, &state.v);
        // Feedforward and joint PD.
        for j in model.actuated_joints() {
            let (iq, iv) = (j.idx_q, j.idx_v);
            tau[iv] = self.tau_ff[iv] + self.joint_gains.kp[iv] * (self.q_ref[iq] - q[iq]) + self.joint_gains.kd[iv] * (self.v_ref[iv] - v[iv]);
        }
        if !self.stance.iter().any(|&s| s) {
            return Ok(());
        }
        // Task-space base PD, distributed to the stance feet: f = G^T (G G^T + eps I)^-1 W.
        let wrench = self.base_wrench(q, v);
        compute_joint_jacobians(model, &mut self.data, q);
        let base = Vector3::new(q[0], q[1], q[2]);
        self.grasp.fill(0.0);
        for (i, foot) in model.feet.iter().enumerate() {
            if !self.stance[i] {
                continue;
            }
            let p = frame_position(model, &self.data, foot.frame);
            self.grasp.fixed_view_mut::<3, 3>(0, 3 * i).copy_from(&Matrix3::identity());
            self.grasp.fixed_view_mut::<3, 3>(3, 3 * i).copy_from(&skew(&(p - base)));
        }
        let mut ggt: Matrix6<f64> = Matrix6::zeros();
        for c in 0..self.grasp.ncols() {
            let col = self.grasp.fixed_view::<6, 1>(0, c);
            ggt += col * col.transpose();
        }
        let eps = 1e-8 * ggt.trace();
        for d in 0..6 {
            ggt[(d, d)] += eps;
        }
        let y = ggt.cholesky().map(|c| c.solve(&wrench)).unwrap_or_else(Vector6::zeros);
        self.forces.gemv_tr(1.0, &self.grasp, &y, 0.0);
        // tau_fb = -J_c^T f over the stance feet's linear (world-aligned) rows.
        for (i, foot) in model.feet.iter().enumerate() {
            if !self.stance[i] {
                continue;
            }
            frame_jacobian(model, &self.data, foot.frame, ReferenceFrame::LocalWorldAligned, &mut self.jac);
            let f = Vector3::new(self.forces[3 * i], self.forces[3 * i + 1], self.forces[3 * i + 2]);
            for c in 6..model.nv {
                let col = self.jac.column(c);
                tau[c] -= col[0] * f.x + col[1] * f.y + col[2] * f.z;
            }
        }
        Ok(())
    }
}
