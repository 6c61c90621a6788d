//! One knot of the full-body jump optimization (Nguyen 2022, sec. II-C) as an ipocp stage.
//!
//! ```text
//! x_k = [dq_k (nv), v_k (nv)]      q_k = qbar_k (+) dq_k, the deviation in the tangent space
//!                                  around the initial guess (no singularity at any rotation)
//! u_k = [tau_k (12), lambda_k^s (3 per stance foot, world)]
//! v_{k+1} = v_k + dt ABA(q_k, v_k, S^T tau_k + sum_s J_s(q_k)^T lambda^s)     eq. (3), semi-implicit
//! q_{k+1} = q_k (+) dt v_{k+1},   dq_{k+1} = q_{k+1} (-) qbar_{k+1}            Euler
//! ```
//!
//! Equalities: the initial state at rest (`dq_0 = 0`, `v_0 = 0`), each stance foot at its
//! contact point at the end of every interval it pushes over (`k >= 1`, the lift-off knot
//! included: the foot leaves its point only with no load on it), the pre-landing joint
//! angles over the last `a` knots with zero joint velocity at the first of them (the rest
//! follows from the dynamics), the final base pose. Inequalities: joint angle, velocity and
//! torque limits, the friction pyramid and minimum normal force, knees and feet below the
//! trunk's bottom face (a half-space inside the "outside the trunk's box" region, smooth),
//! the legs apart, and knees, trunk corners and airborne feet clear of the box (signed
//! distance at least the clearance, the foot's radius for a foot).
//!
//! Derivatives: exact first derivatives of the dynamics (ABA derivatives of Carpentier &
//! Mansard 2018 plus the contact forces' `d (J^T lambda) / dq`) and of every constraint;
//! the Hessian is Gauss-Newton (`2 J_r^T W J_r` of the cost residuals; the curvature of the
//! dynamics and constraints, weighted by their multipliers, is left out), or with
//! `FullBodySettings::constraint_curvature_after` that curvature added by forward
//! differences of the multiplier-weighted constraint gradient (`curvature.rs`), or, as a
//! reference, by central differences of the exact constraint Jacobians
//! ([`FullBodyStage::add_constraint_curvature`]).

// Index loops over rows and columns read like the equations they implement.
#![allow(clippy::needless_range_loop)]

use super::kinematics::{add_point_force_derivative, foot_position, knee_position, point_jacobian, Leg};
use super::momentum::{centroidal_momentum_derivatives, MomentumWorkspace};
use super::settings::{BallisticFlight, BoxObstacle, FullBodySettings};
use crate::dynamics::{
    aba, center_of_mass, com_jacobian, compute_aba_derivatives, compute_joint_jacobians, difference, integrate,
    integrate_jacobians, integrate_velocity_jacobian, Data,
};
use crate::ipocp::{Stage, StageDims, StageJacobians, StageMultipliers, StageValues};
use crate::model::Model;
use crate::spatial::skew;
use nalgebra::{DMatrix, DVector, DVectorView, Matrix3, Matrix3xX, Vector3};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

mod curvature;

/// What all knots share.
pub(crate) struct Shared {
    pub model: Model,
    pub legs: Vec<Leg>,
    pub settings: FullBodySettings,
    pub obstacle: Option<BoxObstacle>,
    /// Joint limits in `q[7..]` order: angles, velocities, torques.
    pub joint_lower: Vec<f64>,
    pub joint_upper: Vec<f64>,
    pub velocity_limit: Vec<f64>,
    pub torque_limit: Vec<f64>,
    pub foot_radius: f64,
    /// Add the constraints' curvature to the Hessian (the second phase of
    /// `FullBodySettings::constraint_curvature_after`).
    pub curvature: AtomicBool,
    /// Take that curvature by central differences of the full Jacobians (the reference, `2 nx`
    /// Jacobian passes) instead of forward differences of the multiplier-weighted gradient.
    pub curvature_by_jacobians: AtomicBool,
    /// Counts the curvature phases started: a knot's curvature formed in an earlier one is
    /// not reused (`FullBodySettings::curvature_refresh`).
    pub curvature_phase: AtomicUsize,
}

/// What one knot is.
#[derive(Clone, Debug)]
pub(crate) struct KnotSpec {
    pub knot: usize,
    pub last: bool,
    /// The guess: tangent origin of this knot and of the next.
    pub qbar: DVector<f64>,
    pub qbar_next: Option<DVector<f64>>,
    /// SRB references: CoM and the stance feet's forces.
    pub com_ref: Vector3<f64>,
    pub force_ref: [Vector3<f64>; 4],
    /// Feet pushing over this knot's interval (their forces are controls).
    pub contacts: [bool; 4],
    /// Feet held at a contact point at this knot (pushing over this knot's interval or the one
    /// before it).
    pub pinned: [Option<Vector3<f64>>; 4],
    /// Feet pushing over this knot's interval for the last time (lifting off at the next knot).
    pub lifting: [bool; 4],
    /// Feet that must keep clear of the box at this knot (in the air since before it).
    pub airborne: [bool; 4],
    pub initial: bool,
    pub pre_landing: bool,
    pub pre_landing_first: bool,
    pub is_final: bool,
}

/// Inequality row kinds, in the order a stage stacks them (for the report).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum ConstraintKind {
    JointAngle,
    JointVelocity,
    Torque,
    JointAcceleration,
    FrictionCone,
    MinNormalForce,
    TrunkClearance,
    LegsApart,
    BoxClearance,
}

impl ConstraintKind {
    pub fn name(&self) -> &'static str {
        match self {
            Self::JointAngle => "joint angle",
            Self::JointVelocity => "joint velocity",
            Self::Torque => "torque",
            Self::JointAcceleration => "joint acceleration",
            Self::FrictionCone => "friction cone",
            Self::MinNormalForce => "min normal force",
            Self::TrunkClearance => "trunk clearance",
            Self::LegsApart => "legs apart",
            Self::BoxClearance => "box clearance",
        }
    }
}

/// Buffers of one stage's evaluations.
struct Workspace {
    data: Data,
    dq: DVector<f64>,
    v: DVector<f64>,
    q: DVector<f64>,
    q_next: DVector<f64>,
    v_next: DVector<f64>,
    tau: DVector<f64>,
    step: DVector<f64>,
    dq_next: DVector<f64>,
    /// `d q / d dq` (`Jr(dq)` on the base), and the integrate / difference Jacobians of the step.
    jd: DMatrix<f64>,
    jq_step: DMatrix<f64>,
    jv_step: DMatrix<f64>,
    jl: DMatrix<f64>,
    /// `d qdd / dq` (tangent), `d v' / dz`, `d dq' / dz`.
    dqdd_dq: DMatrix<f64>,
    dgen_dq: DMatrix<f64>,
    dv_dz: DMatrix<f64>,
    dq_next_dz: DMatrix<f64>,
    point_jac: Matrix3xX<f64>,
    force_map: Matrix3xX<f64>,
    feet_jac: [Matrix3xX<f64>; 4],
    knee_jac: [Matrix3xX<f64>; 4],
    corner_jac: [Matrix3xX<f64>; 8],
    com_jac: Matrix3xX<f64>,
    /// The `z` the Jacobian pass took `com_jac` (`J_c Jd`) at: the Gauss-Newton Hessian at
    /// the same `z` reuses it.
    com_jac_z: DVector<f64>,
    row: DVector<f64>,
    /// `d qdd_j / dz` (the joints' rows of `d v' / dz` over `dt`) and the `z` it was taken
    /// at: the Gauss-Newton term of the acceleration cost reuses the Jacobian pass's.
    acceleration_jac: DMatrix<f64>,
    acceleration_z: DVector<f64>,
    /// The centroidal momentum of the ballistic flight rows, their residual
    /// `h_G(x_{k+1}) - h_G(x_k) - dt [m g; 0]` and its Jacobian (at `acceleration_z`).
    momentum: MomentumWorkspace,
    momentum_residual: nalgebra::Vector6<f64>,
    momentum_jac: DMatrix<f64>,
}

impl Workspace {
    /// The semi-implicit step from `(q, v)` with `qdd = data.ddq` and its Jacobians:
    /// `v' = v + dt qdd`, `q' = q (+) dt v'`, `dq' = q' (-) qbar'`; `Jq`, `Jv` of the
    /// integration `q (+) dt v'`, and `Jl = d dq' / d q'`: `Jr(dq')^-1`, of which only the
    /// base block differs from the identity.
    fn semi_implicit_step(&mut self, model: &Model, dt: f64, qbar_next: &DVector<f64>) {
        self.v_next.copy_from(&self.v);
        self.v_next.axpy(dt, &self.data.ddq, 1.0);
        self.step.copy_from(&self.v_next);
        self.step *= dt;
        integrate(model, &self.q, &self.step, &mut self.q_next);
        difference(model, qbar_next, &self.q_next, &mut self.dq_next);
        integrate_jacobians(model, &self.step, &mut self.jq_step, &mut self.jv_step);
        integrate_velocity_jacobian(model, &self.dq_next, &mut self.jl);
        let base_block = self.jl.fixed_view::<6, 6>(0, 0).into_owned();
        let inverse = base_block.try_inverse().unwrap_or_else(|| nalgebra::Matrix6::from_element(f64::NAN));
        self.jl.fixed_view_mut::<6, 6>(0, 0).copy_from(&inverse);
    }
}

pub(crate) struct FullBodyStage {
    pub shared: Arc<Shared>,
    pub spec: KnotSpec,
    dims: StageDims,
    ws: Mutex<Workspace>,
    /// Buffers of the constraint curvature by differences (allocated on first use).
    fd: Mutex<Option<CurvatureWorkspace>>,
    /// Buffers of the constraint curvature by differences of the gradient (allocated on first use).
    gradient_fd: Mutex<Option<curvature::GradientCurvature>>,
}

/// Buffers of [`FullBodyStage::add_constraint_curvature`].
struct CurvatureWorkspace {
    z: DVector<f64>,
    jacobians: StageJacobians,
    plus: DVector<f64>,
    minus: DVector<f64>,
    curvature: DMatrix<f64>,
}

const TRUNK_CORNERS: [[f64; 3]; 8] = [
    [1.0, 1.0, 1.0],
    [1.0, 1.0, -1.0],
    [1.0, -1.0, 1.0],
    [1.0, -1.0, -1.0],
    [-1.0, 1.0, 1.0],
    [-1.0, 1.0, -1.0],
    [-1.0, -1.0, 1.0],
    [-1.0, -1.0, -1.0],
];

impl FullBodyStage {
    pub fn new(shared: Arc<Shared>, spec: KnotSpec) -> Self {
        let nv = shared.model.nv;
        let nc = spec.contacts.iter().filter(|&&c| c).count();
        let (nu, nx_next) = if spec.last { (0, 0) } else { (nv - 6 + 3 * nc, 2 * nv) };
        let ng = if spec.initial { 2 * nv } else { 3 * spec.pinned.iter().filter(|p| p.is_some()).count() }
            + if spec.pre_landing { nv - 6 } else { 0 }
            + if spec.pre_landing_first { nv - 6 } else { 0 }
            + if spec.is_final { 6 } else { 0 }
            + if Self::has_momentum_rows(&shared, &spec) { shared.settings.ballistic_flight.rows() } else { 0 };
        let nh = Self::kinds_of(&shared, &spec).len();
        let model = &shared.model;
        let ws = Workspace {
            data: Data::new(model),
            dq: DVector::zeros(nv),
            v: DVector::zeros(nv),
            q: DVector::zeros(model.nq),
            q_next: DVector::zeros(model.nq),
            v_next: DVector::zeros(nv),
            tau: DVector::zeros(nv),
            step: DVector::zeros(nv),
            dq_next: DVector::zeros(nv),
            jd: DMatrix::zeros(nv, nv),
            jq_step: DMatrix::zeros(nv, nv),
            jv_step: DMatrix::zeros(nv, nv),
            jl: DMatrix::zeros(nv, nv),
            dqdd_dq: DMatrix::zeros(nv, nv),
            dgen_dq: DMatrix::zeros(nv, nv),
            dv_dz: DMatrix::zeros(nv, 2 * nv + nu),
            dq_next_dz: DMatrix::zeros(nv, 2 * nv + nu),
            point_jac: Matrix3xX::zeros(nv),
            force_map: Matrix3xX::zeros(nv),
            feet_jac: std::array::from_fn(|_| Matrix3xX::zeros(nv)),
            knee_jac: std::array::from_fn(|_| Matrix3xX::zeros(nv)),
            corner_jac: std::array::from_fn(|_| Matrix3xX::zeros(nv)),
            com_jac: Matrix3xX::zeros(nv),
            com_jac_z: DVector::from_element(2 * nv + nu, f64::NAN),
            row: DVector::zeros(nv),
            acceleration_jac: DMatrix::zeros(nv - 6, 2 * nv + nu),
            acceleration_z: DVector::from_element(2 * nv + nu, f64::NAN),
            momentum: MomentumWorkspace::new(model),
            momentum_residual: nalgebra::Vector6::zeros(),
            momentum_jac: DMatrix::zeros(6, 2 * nv + nu),
        };
        Self { dims: StageDims { nx: 2 * nv, nu, nx_next, ng, nh }, shared, spec, ws: Mutex::new(ws), fd: Mutex::new(None), gradient_fd: Mutex::new(None) }
    }

    /// The kind of every inequality row, in order.
    pub fn kinds_of(shared: &Shared, spec: &KnotSpec) -> Vec<ConstraintKind> {
        use ConstraintKind::*;
        let nc = spec.contacts.iter().filter(|&&c| c).count();
        let nj = shared.model.nv - 6;
        let mut k = vec![JointAngle; nj];
        k.extend(std::iter::repeat_n(JointVelocity, nj));
        if !spec.last {
            k.extend(std::iter::repeat_n(Torque, nj));
            if shared.settings.max_joint_acceleration.is_finite() {
                k.extend(std::iter::repeat_n(JointAcceleration, nj));
            }
            for _ in 0..nc {
                k.extend([FrictionCone; 4]);
                k.push(MinNormalForce);
            }
        }
        k.extend([TrunkClearance; 8]);
        k.extend([LegsApart; 8]);
        if shared.obstacle.is_some() {
            k.extend([BoxClearance; 12]);
            k.extend(std::iter::repeat_n(BoxClearance, spec.airborne.iter().filter(|&&a| a).count()));
        }
        k
    }

    /// The interval from this knot is a flight the momentum rows hold over
    /// (`FullBodySettings::ballistic_flight`): no foot pushes and the joints are free (before
    /// the pre-landing window, whose held joints leave the step no freedom).
    pub fn is_ballistic(spec: &KnotSpec) -> bool {
        !spec.last && !spec.pre_landing && spec.contacts.iter().all(|&c| !c)
    }

    /// The interval has the momentum balance's equality rows: a ballistic flight, or with
    /// `momentum_balance_in_stance` a stance interval.
    fn has_momentum_rows(shared: &Shared, spec: &KnotSpec) -> bool {
        let s = &shared.settings;
        s.ballistic_flight != BallisticFlight::Off
            && (Self::is_ballistic(spec) || (s.momentum_balance_in_stance && !spec.last && spec.contacts.iter().any(|&c| c)))
    }

    fn nv(&self) -> usize {
        self.shared.model.nv
    }

    /// Index in `z` of the force of stance foot `f` (None if `f` does not push).
    fn force_index(&self, f: usize) -> Option<usize> {
        if self.spec.last || !self.spec.contacts[f] {
            return None;
        }
        let before = self.spec.contacts[..f].iter().filter(|&&c| c).count();
        Some(2 * self.nv() + self.nv() - 6 + 3 * before)
    }

    fn force(&self, z: &[f64], f: usize) -> Option<Vector3<f64>> {
        self.force_index(f).map(|i| Vector3::new(z[i], z[i + 1], z[i + 2]))
    }
}

impl Stage for FullBodyStage {
    fn dims(&self) -> StageDims {
        self.dims
    }

    fn inequality_bounds(&self, lower: &mut [f64], upper: &mut [f64]) {
        let sh = &self.shared;
        let s = &sh.settings;
        let nj = sh.model.nv - 6;
        let mut r = 0;
        for j in 0..nj {
            (lower[r], upper[r]) = (sh.joint_lower[j], sh.joint_upper[j]);
            r += 1;
        }
        for j in 0..nj {
            (lower[r], upper[r]) = (-sh.velocity_limit[j], sh.velocity_limit[j]);
            r += 1;
        }
        if !self.spec.last {
            for j in 0..nj {
                (lower[r], upper[r]) = (-sh.torque_limit[j], sh.torque_limit[j]);
                r += 1;
            }
            if s.max_joint_acceleration.is_finite() {
                for _ in 0..nj {
                    (lower[r], upper[r]) = (-s.max_joint_acceleration, s.max_joint_acceleration);
                    r += 1;
                }
            }
            for f in (0..4).filter(|&f| self.spec.contacts[f]) {
                for _ in 0..4 {
                    (lower[r], upper[r]) = (f64::NEG_INFINITY, 0.0);
                    r += 1;
                }
                let max_normal_force = if self.spec.lifting[f] { s.lift_off_normal_force } else { f64::INFINITY };
                (lower[r], upper[r]) = (s.min_normal_force, max_normal_force);
                r += 1;
            }
        }
        for _ in 0..8 {
            (lower[r], upper[r]) = (f64::NEG_INFINITY, -(s.trunk_half_extents.z + s.clearance));
            r += 1;
        }
        for pair in 0..8 {
            let d = if pair % 4 < 2 { s.legs_apart_y } else { s.legs_apart_x };
            (lower[r], upper[r]) = (d, f64::INFINITY);
            r += 1;
        }
        if sh.obstacle.is_some() {
            for _ in 0..12 {
                (lower[r], upper[r]) = (s.clearance, f64::INFINITY);
                r += 1;
            }
            for f in 0..4 {
                if self.spec.airborne[f] {
                    (lower[r], upper[r]) = (sh.foot_radius + s.airborne_foot_margin, f64::INFINITY);
                    r += 1;
                }
            }
        }
    }

    fn evaluate(&self, z: &[f64], out: &mut StageValues) {
        let sh = &self.shared;
        let s = &sh.settings;
        let model = &sh.model;
        let nv = model.nv;
        let nj = nv - 6;
        let spec = &self.spec;
        let mut guard = self.ws.lock().unwrap_or_else(|e| e.into_inner());
        let ws = &mut *guard;
        ws.dq.copy_from_slice(&z[..nv]);
        integrate(model, &spec.qbar, &ws.dq, &mut ws.q);
        let v = &z[nv..2 * nv];
        let com = center_of_mass(model, &mut ws.data, &ws.q);
        // Cost (eq. 4, with the references of sec. II-C2).
        let sq = |a: &[f64]| a.iter().map(|x| x * x).sum::<f64>();
        let mut cost = s.w_com * (com - spec.com_ref).norm_squared()
            + s.w_base_position * sq(&z[..3])
            + s.w_base_orientation * sq(&z[3..6])
            + s.w_joint * sq(&z[6..nv])
            + s.w_velocity * sq(v);
        if !spec.last {
            cost += s.w_torque * sq(&z[2 * nv..2 * nv + nj]);
            for f in 0..4 {
                if let Some(l) = self.force(z, f) {
                    cost += s.w_force * (l - spec.force_ref[f]).norm_squared();
                }
            }
        }
        out.cost = cost;
        // Points of the constraints at q_k (forward kinematics done by the CoM).
        let feet: [Vector3<f64>; 4] = std::array::from_fn(|f| foot_position(model, &ws.data, &sh.legs[f]));
        let knees: [Vector3<f64>; 4] = std::array::from_fn(|f| knee_position(&ws.data, &sh.legs[f]));
        let base = ws.data.o_m_i[1];
        if !spec.last {
            // Dynamics (3): generalized forces of the torques and the stance feet's forces.
            ws.tau.as_mut_slice().fill(0.0);
            ws.tau.as_mut_slice()[6..].copy_from_slice(&z[2 * nv..2 * nv + nj]);
            compute_joint_jacobians(model, &mut ws.data, &ws.q);
            for f in 0..4 {
                if let Some(l) = self.force(z, f) {
                    point_jacobian(model, &ws.data, sh.legs[f].knee_joint, &feet[f], &mut ws.point_jac);
                    ws.tau.gemv_tr(1.0, &ws.point_jac, &l, 1.0);
                }
            }
            ws.v.copy_from_slice(v);
            aba(model, &mut ws.data, &ws.q, &ws.v, &ws.tau);
            out.cost += s.w_acceleration * sq(&ws.data.ddq.as_slice()[6..]);
            ws.v_next.copy_from(&ws.v);
            ws.v_next.axpy(s.dt, &ws.data.ddq, 1.0);
            ws.step.copy_from(&ws.v_next);
            ws.step *= s.dt;
            integrate(model, &ws.q, &ws.step, &mut ws.q_next);
            difference(model, spec.qbar_next.as_ref().expect("a stage with dynamics has a next knot"), &ws.q_next, &mut ws.dq_next);
            out.dynamics.rows_mut(0, nv).copy_from(&ws.dq_next);
            out.dynamics.rows_mut(nv, nv).copy_from(&ws.v_next);
        }
        // Equalities.
        let g = &mut out.equalities;
        let mut r = 0;
        if spec.initial {
            g.rows_mut(0, 2 * nv).copy_from_slice(&z[..2 * nv]);
            r = 2 * nv;
        } else {
            for f in 0..4 {
                if let Some(anchor) = spec.pinned[f] {
                    g.rows_mut(r, 3).copy_from(&(feet[f] - anchor));
                    r += 3;
                }
            }
        }
        if spec.pre_landing {
            g.rows_mut(r, nj).copy_from_slice(&z[6..nv]);
            r += nj;
        }
        if spec.pre_landing_first {
            g.rows_mut(r, nj).copy_from_slice(&z[nv + 6..2 * nv]);
            r += nj;
        }
        if spec.is_final {
            g.rows_mut(r, 6).copy_from_slice(&z[..6]);
            r += 6;
        }
        let flight_penalty = s.w_flight_momentum > 0.0 && Self::is_ballistic(spec);
        if Self::has_momentum_rows(sh, spec) || flight_penalty {
            Self::flight_momentum(model, s.dt, ws, false);
            // Stance: less the feet's impulse, their forces applied at q_k.
            for f in 0..4 {
                if let Some(l) = self.force(z, f) {
                    let lin = l * s.dt;
                    let ang = (feet[f] - com).cross(&l) * s.dt;
                    for i in 0..3 {
                        ws.momentum_residual[i] -= lin[i];
                        ws.momentum_residual[3 + i] -= ang[i];
                    }
                }
            }
            if flight_penalty {
                out.cost += s.w_flight_momentum * ws.momentum_residual.norm_squared();
            }
            if Self::has_momentum_rows(sh, spec) {
                let rows = s.ballistic_flight.rows();
                g.rows_mut(r, rows).copy_from(&ws.momentum_residual.rows(6 - rows, rows));
            }
        }
        // Inequalities.
        let h = &mut out.inequalities;
        let mut r = 0;
        for j in 0..nj {
            h[r] = ws.q[7 + j];
            r += 1;
        }
        for j in 0..nj {
            h[r] = v[6 + j];
            r += 1;
        }
        if !spec.last {
            for j in 0..nj {
                h[r] = z[2 * nv + j];
                r += 1;
            }
            if s.max_joint_acceleration.is_finite() {
                // ws.data.ddq: the ABA of the dynamics above.
                for j in 0..nj {
                    h[r] = ws.data.ddq[6 + j];
                    r += 1;
                }
            }
            for f in 0..4 {
                if let Some(l) = self.force(z, f) {
                    h[r] = l.x - s.mu * l.z;
                    h[r + 1] = -l.x - s.mu * l.z;
                    h[r + 2] = l.y - s.mu * l.z;
                    h[r + 3] = -l.y - s.mu * l.z;
                    h[r + 4] = l.z;
                    r += 5;
                }
            }
        }
        let in_base = |p: &Vector3<f64>| base.rotation.transpose() * (p - base.translation);
        for f in 0..4 {
            h[r] = in_base(&knees[f]).z;
            h[r + 1] = in_base(&feet[f]).z;
            r += 2;
        }
        for (points, row) in [(&feet, r), (&knees, r + 4)] {
            let pb: [Vector3<f64>; 4] = std::array::from_fn(|f| in_base(&points[f]));
            // LF-RF, LH-RH in y; LF-LH, RF-RH in x (order LF, RF, LH, RH).
            h[row] = pb[0].y - pb[1].y;
            h[row + 1] = pb[2].y - pb[3].y;
            h[row + 2] = pb[0].x - pb[2].x;
            h[row + 3] = pb[1].x - pb[3].x;
        }
        r += 8;
        if let Some(b) = &sh.obstacle {
            for f in 0..4 {
                h[r] = b.signed_distance(&knees[f]).0;
                r += 1;
            }
            for c in TRUNK_CORNERS {
                let p = base.act_point(&s.trunk_half_extents.component_mul(&Vector3::from(c)));
                h[r] = b.signed_distance(&p).0;
                r += 1;
            }
            for f in 0..4 {
                if spec.airborne[f] {
                    h[r] = b.signed_distance(&feet[f]).0;
                    r += 1;
                }
            }
        }
    }

    fn jacobians(&self, z: &[f64], out: &mut StageJacobians) {
        let sh = &self.shared;
        let s = &sh.settings;
        let model = &sh.model;
        let nv = model.nv;
        let nj = nv - 6;
        let nz = self.dims.nz();
        let spec = &self.spec;
        let mut guard = self.ws.lock().unwrap_or_else(|e| e.into_inner());
        let ws = &mut *guard;
        ws.dq.copy_from_slice(&z[..nv]);
        integrate(model, &spec.qbar, &ws.dq, &mut ws.q);
        // d q / d dq: Jr(dq) on the base, identity on the joints.
        integrate_velocity_jacobian(model, &ws.dq, &mut ws.jd);
        ws.v.copy_from_slice(&z[nv..2 * nv]);
        out.dynamics.as_mut_slice().fill(0.0);
        out.equalities.as_mut_slice().fill(0.0);
        out.inequalities.as_mut_slice().fill(0.0);
        out.cost_gradient.as_mut_slice().fill(0.0);
        // Kinematics at q_k: world Jacobians, CoM and its Jacobian, the feet's Jacobians.
        let jc = com_jacobian(model, &mut ws.data, &ws.q);
        ws.com_jac.gemm(1.0, jc, &ws.jd, 0.0);
        ws.com_jac_z.copy_from_slice(z);
        let com = ws.data.com;
        let feet: [Vector3<f64>; 4] = std::array::from_fn(|f| foot_position(model, &ws.data, &sh.legs[f]));
        let knees: [Vector3<f64>; 4] = std::array::from_fn(|f| knee_position(&ws.data, &sh.legs[f]));
        let base = ws.data.o_m_i[1];
        for f in 0..4 {
            point_jacobian(model, &ws.data, sh.legs[f].knee_joint, &feet[f], &mut ws.point_jac);
            ws.feet_jac[f].copy_from(&ws.point_jac);
        }
        // (Before the dynamics' derivatives, which reuse the world Jacobians' buffer.)
        for f in 0..4 {
            point_jacobian(model, &ws.data, sh.legs[f].knee_joint, &knees[f], &mut ws.knee_jac[f]);
        }
        let corners: [Vector3<f64>; 8] = std::array::from_fn(|c| base.act_point(&s.trunk_half_extents.component_mul(&Vector3::from(TRUNK_CORNERS[c]))));
        if sh.obstacle.is_some() {
            for c in 0..8 {
                point_jacobian(model, &ws.data, 1, &corners[c], &mut ws.corner_jac[c]);
            }
        }
        // Cost gradient.
        let com_error = (com - spec.com_ref) * (2.0 * s.w_com);
        for i in 0..nv {
            let gc = ws.com_jac.column(i).dot(&com_error);
            let w = if i < 3 {
                s.w_base_position
            } else if i < 6 {
                s.w_base_orientation
            } else {
                s.w_joint
            };
            out.cost_gradient[i] = gc + 2.0 * w * z[i];
            out.cost_gradient[nv + i] = 2.0 * s.w_velocity * z[nv + i];
        }
        if !spec.last {
            for j in 0..nj {
                out.cost_gradient[2 * nv + j] = 2.0 * s.w_torque * z[2 * nv + j];
            }
            for f in 0..4 {
                if let (Some(i), Some(l)) = (self.force_index(f), self.force(z, f)) {
                    for a in 0..3 {
                        out.cost_gradient[i + a] = 2.0 * s.w_force * (l[a] - spec.force_ref[f][a]);
                    }
                }
            }
        }
        if !spec.last {
            // Dynamics: qdd = ABA(q, v, tau_gen(q)),  d qdd/dq = -M^-1 dRNEA/dq + M^-1 d tau_gen/dq.
            ws.tau.as_mut_slice().fill(0.0);
            ws.tau.as_mut_slice()[6..].copy_from_slice(&z[2 * nv..2 * nv + nj]);
            ws.dgen_dq.as_mut_slice().fill(0.0);
            for f in 0..4 {
                if let Some(l) = self.force(z, f) {
                    ws.tau.gemv_tr(1.0, &ws.feet_jac[f], &l, 1.0);
                    add_point_force_derivative(&ws.data, &sh.legs[f], &feet[f], &l, &mut ws.dgen_dq);
                }
            }
            compute_aba_derivatives(model, &mut ws.data, &ws.q, &ws.v, &ws.tau);
            ws.dqdd_dq.copy_from(&ws.data.ddq_dq);
            ws.dqdd_dq.gemm(1.0, &ws.data.minv, &ws.dgen_dq, 1.0);
            // v' = v + dt qdd: d v'/dz.
            let dt = s.dt;
            ws.dv_dz.as_mut_slice().fill(0.0);
            ws.dv_dz.columns_mut(0, nv).gemm(dt, &ws.dqdd_dq, &ws.jd, 0.0);
            for c in 0..nv {
                for r in 0..nv {
                    ws.dv_dz[(r, nv + c)] = dt * ws.data.ddq_dv[(r, c)] + if r == c { 1.0 } else { 0.0 };
                }
            }
            for j in 0..nj {
                for r in 0..nv {
                    ws.dv_dz[(r, 2 * nv + j)] = dt * ws.data.minv[(r, 6 + j)];
                }
            }
            for f in 0..4 {
                if let Some(i) = self.force_index(f) {
                    // M^-1 J^T = (J M^-1)^T, M^-1 symmetric.
                    ws.force_map.gemm(dt, &ws.feet_jac[f], &ws.data.minv, 0.0);
                    for a in 0..3 {
                        for r in 0..nv {
                            ws.dv_dz[(r, i + a)] = ws.force_map[(a, r)];
                        }
                    }
                }
            }
            ws.semi_implicit_step(model, dt, spec.qbar_next.as_ref().expect("a stage with dynamics has a next knot"));
            // dq' = (q (+) dt v') (-) qbar': d/dz = Jl (Jq [Jd 0 0] + dt Jv dv'/dz).
            ws.dq_next_dz.gemm(dt, &ws.jv_step, &ws.dv_dz, 0.0);
            ws.dq_next_dz.columns_mut(0, nv).gemm(1.0, &ws.jq_step, &ws.jd, 1.0);
            out.dynamics.rows_mut(0, nv).gemm(1.0, &ws.jl, &ws.dq_next_dz, 0.0);
            out.dynamics.rows_mut(nv, nv).copy_from(&ws.dv_dz);
            // Joint accelerations qdd_j = (v'_j - v_j) / dt: their Jacobian, the cost's gradient
            // 2 w J^T qdd_j (ws.data.ddq: the ABA of compute_aba_derivatives).
            ws.acceleration_jac.copy_from(&ws.dv_dz.rows(6, nj));
            for j in 0..nj {
                ws.acceleration_jac[(j, nv + 6 + j)] -= 1.0;
            }
            ws.acceleration_jac /= dt;
            ws.acceleration_z.copy_from_slice(z);
            if s.w_acceleration > 0.0 {
                let qdd = ws.data.ddq.rows(6, nj);
                out.cost_gradient.gemv_tr(2.0 * s.w_acceleration, &ws.acceleration_jac, &qdd, 1.0);
            }
        }
        // Equalities.
        let g = &mut out.equalities;
        let mut r = 0;
        if spec.initial {
            for i in 0..2 * nv {
                g[(i, i)] = 1.0;
            }
            r = 2 * nv;
        } else {
            for f in 0..4 {
                if spec.pinned[f].is_some() {
                    g.view_mut((r, 0), (3, nv)).gemm(1.0, &ws.feet_jac[f], &ws.jd, 0.0);
                    r += 3;
                }
            }
        }
        if spec.pre_landing {
            for j in 0..nj {
                g[(r + j, 6 + j)] = 1.0;
            }
            r += nj;
        }
        if spec.pre_landing_first {
            for j in 0..nj {
                g[(r + j, nv + 6 + j)] = 1.0;
            }
            r += nj;
        }
        if spec.is_final {
            for i in 0..6 {
                g[(r + i, i)] = 1.0;
            }
            r += 6;
        }
        let flight_penalty = s.w_flight_momentum > 0.0 && Self::is_ballistic(spec);
        if Self::has_momentum_rows(sh, spec) || flight_penalty {
            Self::flight_momentum(model, s.dt, ws, true);
            // Stance: less the feet's impulse dt [lambda; (p_f - c) x lambda] at q_k, whose
            // derivatives are dt [I; [p_f - c]x] in lambda and
            // -dt [lambda]x (J_f - J_c) Jd in dq.
            for f in 0..4 {
                if let (Some(i), Some(l)) = (self.force_index(f), self.force(z, f)) {
                    let arm = feet[f] - com;
                    let (arm_x, l_x) = (skew(&arm), skew(&l));
                    let lin = l * s.dt;
                    let ang = arm.cross(&l) * s.dt;
                    for a in 0..3 {
                        ws.momentum_residual[a] -= lin[a];
                        ws.momentum_residual[3 + a] -= ang[a];
                        ws.momentum_jac[(a, i + a)] -= s.dt;
                        for b in 0..3 {
                            ws.momentum_jac[(3 + a, i + b)] -= s.dt * arm_x[(a, b)];
                        }
                    }
                    // d (p_f - c) / d dq = (J_f - J_c) Jd (ws.com_jac has its Jd), column by column.
                    for c in 0..nv {
                        let d_arm: Vector3<f64> = (0..nv).map(|m| ws.feet_jac[f].column(m) * ws.jd[(m, c)]).sum::<Vector3<f64>>() - ws.com_jac.column(c);
                        let d_ang = -(l_x * d_arm) * s.dt;
                        for a in 0..3 {
                            ws.momentum_jac[(3 + a, c)] -= d_ang[a];
                        }
                    }
                }
            }
            if Self::has_momentum_rows(sh, spec) {
                let rows = s.ballistic_flight.rows();
                g.rows_mut(r, rows).copy_from(&ws.momentum_jac.rows(6 - rows, rows));
            }
            if flight_penalty {
                out.cost_gradient.gemv_tr(2.0 * s.w_flight_momentum, &ws.momentum_jac, &ws.momentum_residual, 1.0);
            }
        }
        // Inequalities.
        let h = &mut out.inequalities;
        let mut r = 0;
        for j in 0..nj {
            h[(r, 6 + j)] = 1.0;
            r += 1;
        }
        for j in 0..nj {
            h[(r, nv + 6 + j)] = 1.0;
            r += 1;
        }
        if !spec.last {
            for j in 0..nj {
                h[(r, 2 * nv + j)] = 1.0;
                r += 1;
            }
            if s.max_joint_acceleration.is_finite() {
                h.rows_mut(r, nj).copy_from(&ws.acceleration_jac);
                r += nj;
            }
            for f in 0..4 {
                if let Some(i) = self.force_index(f) {
                    for (row, (cx, cy)) in [(1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0)].into_iter().enumerate() {
                        h[(r + row, i)] = cx;
                        h[(r + row, i + 1)] = cy;
                        h[(r + row, i + 2)] = -s.mu;
                    }
                    h[(r + 4, i + 2)] = 1.0;
                    r += 5;
                }
            }
        }
        // Base-frame coordinates p_b = R^T (p - t) move with the leg's joints only:
        // d p_b / d q_leg = R^T d p / d q_leg.
        let rt: Matrix3<f64> = base.rotation.transpose();
        let base_rows = |jac: &Matrix3xX<f64>, f: usize, axis: usize| -> [(usize, f64); 3] {
            std::array::from_fn(|a| {
                let c = sh.legs[f].v_index[a];
                (c, (0..3).map(|b| rt[(axis, b)] * jac[(b, c)]).sum())
            })
        };
        for f in 0..4 {
            for (c, d) in base_rows(&ws.knee_jac[f], f, 2) {
                h[(r, c)] = d;
            }
            for (c, d) in base_rows(&ws.feet_jac[f], f, 2) {
                h[(r + 1, c)] = d;
            }
            r += 2;
        }
        for (jacs, row) in [(&ws.feet_jac, r), (&ws.knee_jac, r + 4)] {
            for (k, (fa, fb, axis)) in [(0, 1, 1), (2, 3, 1), (0, 2, 0), (1, 3, 0)].into_iter().enumerate() {
                for (c, d) in base_rows(&jacs[fa], fa, axis) {
                    h[(row + k, c)] += d;
                }
                for (c, d) in base_rows(&jacs[fb], fb, axis) {
                    h[(row + k, c)] -= d;
                }
            }
        }
        r += 8;
        if let Some(b) = &sh.obstacle {
            let (jd, row) = (&ws.jd, &mut ws.row);
            let mut row_of = |h: &mut DMatrix<f64>, r: usize, p: &Vector3<f64>, jac: &Matrix3xX<f64>| {
                // d sd / d dq = grad^T (d p / dq) Jd, Jd = Jr(dq) on the base block and the
                // identity on the joints (`integrate_jacobians`): the joints' columns are
                // `grad^T d p / dq` itself, only the base's take the product (the same sums as
                // the full product, whose other terms are zeros).
                let grad = b.signed_distance(p).1;
                row.gemv_tr(1.0, jac, &grad, 0.0);
                for c in 0..6 {
                    h[(r, c)] = (0..6).map(|i| row[i] * jd[(i, c)]).sum();
                }
                for c in 6..nv {
                    h[(r, c)] = row[c];
                }
            };
            for f in 0..4 {
                row_of(h, r, &knees[f], &ws.knee_jac[f]);
                r += 1;
            }
            for c in 0..8 {
                row_of(h, r, &corners[c], &ws.corner_jac[c]);
                r += 1;
            }
            for f in 0..4 {
                if spec.airborne[f] {
                    row_of(h, r, &feet[f], &ws.feet_jac[f]);
                    r += 1;
                }
            }
        }
        debug_assert_eq!(out.cost_gradient.len(), nz);
    }

    /// Gauss-Newton: `2 J_r^T W J_r` of the cost's residuals (CoM, base and joint deviation,
    /// velocities, torques, forces); the multipliers are not used.
    fn lagrangian_hessian(&self, z: &[f64], multipliers: StageMultipliers<'_>, out: &mut DMatrix<f64>) {
        let sh = &self.shared;
        let s = &sh.settings;
        let model = &sh.model;
        let nv = model.nv;
        let nj = nv - 6;
        let w = multipliers.cost;
        let with_acceleration = s.w_acceleration > 0.0 && !self.spec.last;
        let with_momentum = s.w_flight_momentum > 0.0 && Self::is_ballistic(&self.spec);
        if with_acceleration || with_momentum {
            let cached = self.ws.lock().unwrap_or_else(|e| e.into_inner()).acceleration_z.as_slice() == z;
            if !cached {
                // ipocp asks for the Hessian right after the Jacobians at the same z; anything
                // else takes this (allocating) detour.
                self.jacobians(z, &mut StageJacobians::zeros(self.dims));
            }
        }
        let mut guard = self.ws.lock().unwrap_or_else(|e| e.into_inner());
        let ws = &mut *guard;
        // ipocp asks for the Hessian right after the Jacobians at the same z, whose pass left
        // `J_c Jd` (the same operations) in `ws.com_jac`.
        if ws.com_jac_z.as_slice() != z {
            ws.dq.copy_from_slice(&z[..nv]);
            integrate(model, &self.spec.qbar, &ws.dq, &mut ws.q);
            integrate_velocity_jacobian(model, &ws.dq, &mut ws.jd);
            let jc = com_jacobian(model, &mut ws.data, &ws.q);
            ws.com_jac.gemm(1.0, jc, &ws.jd, 0.0);
            ws.com_jac_z.copy_from_slice(z);
        }
        out.as_mut_slice().fill(0.0);
        out.view_mut((0, 0), (nv, nv)).gemm_tr(2.0 * s.w_com * w, &ws.com_jac, &ws.com_jac, 0.0);
        for i in 0..nv {
            let wd = if i < 3 {
                s.w_base_position
            } else if i < 6 {
                s.w_base_orientation
            } else {
                s.w_joint
            };
            out[(i, i)] += 2.0 * wd * w;
            out[(nv + i, nv + i)] += 2.0 * s.w_velocity * w;
        }
        if !self.spec.last {
            for j in 0..nj {
                out[(2 * nv + j, 2 * nv + j)] += 2.0 * s.w_torque * w;
            }
            for f in 0..4 {
                if let Some(i) = self.force_index(f) {
                    for a in 0..3 {
                        out[(i + a, i + a)] += 2.0 * s.w_force * w;
                    }
                }
            }
        }
        if with_acceleration {
            out.gemm_tr(2.0 * s.w_acceleration * w, &ws.acceleration_jac, &ws.acceleration_jac, 1.0);
        }
        if with_momentum {
            out.gemm_tr(2.0 * s.w_flight_momentum * w, &ws.momentum_jac, &ws.momentum_jac, 1.0);
        }
        drop(guard);
        if sh.curvature.load(Ordering::Relaxed) {
            // The gradient form knows the dynamics, feet, trunk, legs-apart and box rows; the
            // momentum balance's rows (`ballistic_flight`) have curvature it does not form, so
            // their stages take the general differences of the full Jacobians.
            if sh.curvature_by_jacobians.load(Ordering::Relaxed) || Self::has_momentum_rows(sh, &self.spec) {
                self.add_constraint_curvature(z, &multipliers, out);
            } else {
                self.add_constraint_curvature_by_gradients(z, &multipliers, out);
            }
        }
    }
}

impl FullBodyStage {
    /// The ballistic flight's momentum balance over this interval (after the dynamics of
    /// `evaluate` or `jacobians` set `q, v, q', v'`, and for the Jacobian `Jd`, `d q'/dz`
    /// in the tangent at `q'` and `d v'/dz`):
    /// `r = h_G(q', v') - h_G(q, v) - dt [m g; 0]` into `ws.momentum_residual`, and with
    /// `jacobian` `d r / dz = [dh/dq' A_G'] [d q'/dz; d v'/dz] - [dh/dq Jd, A_G, 0]` into
    /// `ws.momentum_jac`.
    fn flight_momentum(model: &Model, dt: f64, ws: &mut Workspace, jacobian: bool) {
        let nv = model.nv;
        let m = &mut ws.momentum;
        let h = centroidal_momentum_derivatives(model, m, &ws.q, &ws.v, jacobian);
        if jacobian {
            ws.momentum_jac.as_mut_slice().fill(0.0);
            ws.momentum_jac.columns_mut(0, nv).gemm(-1.0, &m.dh_dq, &ws.jd, 0.0);
            for c in 0..nv {
                for i in 0..6 {
                    ws.momentum_jac[(i, nv + c)] = -m.a_g[(i, c)];
                }
            }
        }
        let h_next = centroidal_momentum_derivatives(model, m, &ws.q_next, &ws.v_next, jacobian);
        if jacobian {
            ws.momentum_jac.gemm(1.0, &m.dh_dq, &ws.dq_next_dz, 1.0);
            ws.momentum_jac.gemm(1.0, &m.a_g, &ws.dv_dz, 1.0);
        }
        let impulse = model.gravity.v * (m.mass * dt);
        for i in 0..3 {
            ws.momentum_residual[i] = h_next[i] - h[i] - impulse[i];
            ws.momentum_residual[3 + i] = h_next[3 + i] - h[3 + i];
        }
    }

    /// Adds `sum_i m_i Hess c_i(z)` of the dynamics, equality and inequality rows: column `j`
    /// is the central difference of `J_c(z)^T m` along `z_j` (step `1e-6 (1 + |z_j|)`). Only
    /// the state columns are differenced: every row is linear in the controls (the torques
    /// and contact forces enter the dynamics through `ABA(q, v, S^T tau + J^T lambda)`, linear
    /// in its force argument, and the torque, friction and force rows are linear), so the
    /// control-control block is zero and the control-state block is the transpose of the
    /// state columns' control rows. The state block is symmetrized. `2 nx` Jacobian
    /// evaluations per call.
    fn add_constraint_curvature(&self, z: &[f64], m: &StageMultipliers<'_>, out: &mut DMatrix<f64>) {
        let d = self.dims;
        let nz = d.nz();
        let mut guard = self.fd.lock().unwrap_or_else(|e| e.into_inner());
        let fd = guard.get_or_insert_with(|| CurvatureWorkspace {
            z: DVector::zeros(nz),
            jacobians: StageJacobians::zeros(d),
            plus: DVector::zeros(nz),
            minus: DVector::zeros(nz),
            curvature: DMatrix::zeros(nz, nz),
        });
        let lam = DVectorView::from_slice(m.dynamics, d.nx_next);
        let nu = DVectorView::from_slice(m.equalities, d.ng);
        let y = DVectorView::from_slice(m.inequalities, d.nh);
        fd.z.copy_from_slice(z);
        let nx = d.nx;
        for j in 0..nx {
            let h = 1e-6 * (1.0 + z[j].abs());
            for (sign, side) in [(1.0, 0), (-1.0, 1)] {
                fd.z[j] = z[j] + sign * h;
                self.jacobians(fd.z.as_slice(), &mut fd.jacobians);
                let g = if side == 0 { &mut fd.plus } else { &mut fd.minus };
                g.gemv_tr(1.0, &fd.jacobians.dynamics, &lam, 0.0);
                g.gemv_tr(1.0, &fd.jacobians.equalities, &nu, 1.0);
                g.gemv_tr(1.0, &fd.jacobians.inequalities, &y, 1.0);
            }
            fd.z[j] = z[j];
            for i in 0..nz {
                fd.curvature[(i, j)] = (fd.plus[i] - fd.minus[i]) / (2.0 * h);
            }
        }
        add_state_columns(&fd.curvature, nx, out);
    }
}

/// Adds the state columns `C[:, ..nx]` of a curvature by differences to the Hessian `out`:
/// the state block symmetrized, the control-state block `C[nx.., ..nx]` and its transpose;
/// the control-control block stays (every row is linear in the controls).
fn add_state_columns(curvature: &DMatrix<f64>, nx: usize, out: &mut DMatrix<f64>) {
    let nz = out.nrows();
    for j in 0..nx {
        for i in 0..nx {
            out[(i, j)] += 0.5 * (curvature[(i, j)] + curvature[(j, i)]);
        }
        for i in nx..nz {
            out[(i, j)] += curvature[(i, j)];
            out[(j, i)] += curvature[(i, j)];
        }
    }
}
