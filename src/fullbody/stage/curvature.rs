//! The constraints' curvature `sum_i m_i Hess c_i(z)` of a full-body stage by forward
//! differences of the multiplier-weighted constraint gradient `J_c(z)^T m`, the gradient
//! formed without any constraint Jacobian (vector-Jacobian products only).
//!
//! ```text
//! dynamics   dq' = (q (+) dt v') (-) qbar',   v' = v + dt qdd,   qdd = ABA(q, v, tau_gen(q))
//!   lambda_q^T d dq'/dz = a^T Jq [Jd 0 0] + dt a^T Jv dv'/dz          a = Jl^T lambda_q
//!   mu^T dv'/dz, mu = lambda_v + dt Jv^T a:   w = M^-1 mu
//!     dq:    dt Jd^T (d tau_gen/dq - d RNEA/dq)^T w      (Carpentier & Mansard 2018, eq. 21)
//!     v:     mu - dt (d RNEA/dv)^T w
//!     tau:   dt w_j,     lambda_f: dt J_f w
//! feet held  Jd^T J_f^T nu_f;  trunk and legs-apart rows (base frame, leg joints only);
//! box        y_r Jd^T J_p^T grad sd(p)
//! ```
//!
//! The linear rows (initial state, pre-landing joints, final pose, joint angles and
//! velocities, torques, friction pyramid, normal force) add a constant to `J_c^T m`, which
//! cancels in the differences: they are left out. The joint-acceleration rows
//! (`(v'_j - v_j) / dt`) fold into `mu`. One gradient costs an ABA, the RNEA derivatives and
//! a sparse `M` solve, against the full Jacobian pass's ABA derivatives (`M^-1` formed and
//! multiplied) and its `nv x nz` products; forward differences take `nx + 2` gradients
//! (the velocity's `nv` of them without the kinematics) where the central differences of
//! the Jacobians took `2 nx` Jacobian passes.

use super::{add_state_columns, FullBodyStage, Workspace, TRUNK_CORNERS};
use crate::dynamics::{
    aba, compute_joint_jacobians, compute_rnea_derivatives, integrate, integrate_velocity_jacobian, mass_matrix_factor, mass_matrix_factored_solve,
    rnea_derivatives_forward, rnea_derivatives_tr_mul, tangent_jacobian_tr_mul,
};
use crate::fullbody::kinematics::{add_point_force_derivative, foot_position, knee_position, point_jacobian};
use crate::ipocp::StageMultipliers;
use nalgebra::{DMatrix, DVector, Matrix3, Vector3};
use std::sync::atomic::Ordering;

/// Buffers of [`FullBodyStage::add_constraint_curvature_by_gradients`].
pub(super) struct GradientCurvature {
    z: DVector<f64>,
    /// `J_c^T m` at `z` and at `z + h e_j`.
    gradient: DVector<f64>,
    perturbed: DVector<f64>,
    /// Columns `j < nx`: `d (J_c^T m) / d z_j`.
    curvature: DMatrix<f64>,
    /// `a = Jl^T lambda_q`, `mu`, `w = M^-1 mu`, and a scratch vector (all `nv`).
    a: DVector<f64>,
    mu: DVector<f64>,
    w: DVector<f64>,
    t: DVector<f64>,
    /// `w^T d RNEA / dq` and `w^T d RNEA / dv` (with `curvature_rnea_tr_mul`).
    w_dtau_dq: DVector<f64>,
    w_dtau_dv: DVector<f64>,
    /// The kinematic rows' part of `t` and of the gradient, and `d tau_gen / dq`, at the
    /// last configuration evaluated: a velocity perturbation changes the dynamics only.
    t_kinematics: DVector<f64>,
    gradient_kinematics: DVector<f64>,
    dgen_dq: DMatrix<f64>,
    /// The curvature phase `curvature` was formed in, and the Hessians asked for since.
    phase: usize,
    evaluations: usize,
}

impl GradientCurvature {
    fn new(nv: usize, nz: usize, nx: usize) -> Self {
        Self {
            z: DVector::zeros(nz),
            gradient: DVector::zeros(nz),
            perturbed: DVector::zeros(nz),
            curvature: DMatrix::zeros(nz, nx),
            a: DVector::zeros(nv),
            mu: DVector::zeros(nv),
            w: DVector::zeros(nv),
            t: DVector::zeros(nv),
            w_dtau_dq: DVector::zeros(nv),
            w_dtau_dv: DVector::zeros(nv),
            t_kinematics: DVector::zeros(nv),
            gradient_kinematics: DVector::zeros(nz),
            dgen_dq: DMatrix::zeros(nv, nv),
            phase: usize::MAX,
            evaluations: 0,
        }
    }
}

/// Forward-difference step of state coordinate `z_j` (about the square root of the
/// machine epsilon, relative).
fn step(z_j: f64) -> f64 {
    1e-7 * (1.0 + z_j.abs())
}

impl FullBodyStage {
    /// Adds `sum_i m_i Hess c_i(z)` of the dynamics, equality and inequality rows to `out`:
    /// column `j < nx` is the forward difference of `J_c(z)^T m` along `z_j`
    /// ([`Self::constraint_gradient`]). As the central differences of the Jacobians it
    /// replaces (`add_constraint_curvature`): the state block symmetrized, the
    /// control-state block the state columns' control rows, the control-control block zero.
    pub(super) fn add_constraint_curvature_by_gradients(&self, z: &[f64], m: &StageMultipliers<'_>, out: &mut DMatrix<f64>) {
        let d = self.dims;
        let (nz, nx) = (d.nz(), d.nx);
        let mut guard = self.gradient_fd.lock().unwrap_or_else(|e| e.into_inner());
        let fd = guard.get_or_insert_with(|| GradientCurvature::new(self.nv(), nz, nx));
        let phase = self.shared.curvature_phase.load(Ordering::Relaxed);
        let refresh = self.shared.settings.curvature_refresh.max(1);
        if fd.phase == phase && fd.evaluations % refresh != 0 {
            fd.evaluations += 1;
            add_state_columns(&fd.curvature, nx, out);
            return;
        }
        (fd.phase, fd.evaluations) = (phase, 1);
        let mut ws_guard = self.ws.lock().unwrap_or_else(|e| e.into_inner());
        let ws = &mut *ws_guard;
        let nv = self.nv();
        fd.z.copy_from_slice(z);
        self.constraint_gradient(ws, fd, m, true);
        std::mem::swap(&mut fd.gradient, &mut fd.perturbed);
        // The configuration's columns, then (the kinematics at z again) the velocity's, which
        // reuse the kinematics and redo the dynamics only.
        for j in 0..nx {
            if j == nv {
                self.constraint_gradient(ws, fd, m, true);
            }
            let h = step(z[j]);
            fd.z[j] = z[j] + h;
            self.constraint_gradient(ws, fd, m, j < nv);
            fd.z[j] = z[j];
            for i in 0..nz {
                fd.curvature[(i, j)] = (fd.perturbed[i] - fd.gradient[i]) / h;
            }
        }
        // (fd.gradient holds the unperturbed gradient: the swap above.)
        add_state_columns(&fd.curvature, nx, out);
    }

    /// `fd.perturbed = J_c(fd.z)^T m` up to a constant (the linear rows left out): the
    /// multiplier-weighted gradient of the rows with curvature, no Jacobian formed.
    /// `kinematics` false: the configuration part of `fd.z` is the last call's (only `v`
    /// moved), whose kinematics (`Jd`, the feet's Jacobians, the kinematic rows' part,
    /// `d tau_gen / dq`) are reused.
    fn constraint_gradient(&self, ws: &mut Workspace, fd: &mut GradientCurvature, m: &StageMultipliers<'_>, kinematics: bool) {
        let sh = &self.shared;
        let s = &sh.settings;
        let model = &sh.model;
        let nv = model.nv;
        let nj = nv - 6;
        let spec = &self.spec;
        let z = fd.z.as_slice();
        let g = &mut fd.perturbed;
        ws.v.copy_from_slice(&z[nv..2 * nv]);
        // Inequalities: the linear rows first, then the acceleration rows (if any), then the
        // trunk clearance, legs apart and box clearance.
        let y = m.inequalities;
        let mut first_nonlinear_row = 2 * nj;
        let mut acceleration_rows = None;
        if !spec.last {
            first_nonlinear_row += nj;
            if s.max_joint_acceleration.is_finite() {
                acceleration_rows = Some(first_nonlinear_row);
                first_nonlinear_row += nj;
            }
            first_nonlinear_row += 5 * spec.contacts.iter().filter(|&&c| c).count();
        }
        // `t` accumulates the world-tangent gradient `d/dq` (before `Jd^T`).
        let t = &mut fd.t;
        if kinematics {
            ws.dq.copy_from_slice(&z[..nv]);
            integrate(model, &spec.qbar, &ws.dq, &mut ws.q);
            // d q / d dq: Jr(dq) on the base, identity on the joints.
            integrate_velocity_jacobian(model, &ws.dq, &mut ws.jd);
            compute_joint_jacobians(model, &mut ws.data, &ws.q);
            let feet: [Vector3<f64>; 4] = std::array::from_fn(|f| foot_position(model, &ws.data, &sh.legs[f]));
            let knees: [Vector3<f64>; 4] = std::array::from_fn(|f| knee_position(&ws.data, &sh.legs[f]));
            let base = ws.data.o_m_i[1];
            for f in 0..4 {
                point_jacobian(model, &ws.data, sh.legs[f].knee_joint, &feet[f], &mut ws.feet_jac[f]);
                point_jacobian(model, &ws.data, sh.legs[f].knee_joint, &knees[f], &mut ws.knee_jac[f]);
            }
            g.as_mut_slice().fill(0.0);
            t.as_mut_slice().fill(0.0);
            // Equalities: the held feet (the others are linear).
            if !spec.initial {
                let mut r = 0;
                for f in 0..4 {
                    if spec.pinned[f].is_some() {
                        let nu = Vector3::new(m.equalities[r], m.equalities[r + 1], m.equalities[r + 2]);
                        t.gemv_tr(1.0, &ws.feet_jac[f], &nu, 1.0);
                        r += 3;
                    }
                }
            }
            let mut r = first_nonlinear_row;
            let rt: Matrix3<f64> = base.rotation.transpose();
            // d (p_b)_axis / d q_leg = (R^T d p / d q_leg)_axis, onto the leg's joint columns.
            let add_base_row = |g: &mut DVector<f64>, weight: f64, jac: &nalgebra::Matrix3xX<f64>, f: usize, axis: usize| {
                for c in sh.legs[f].v_index {
                    g[c] += weight * (0..3).map(|b| rt[(axis, b)] * jac[(b, c)]).sum::<f64>();
                }
            };
            for f in 0..4 {
                add_base_row(g, y[r], &ws.knee_jac[f], f, 2);
                add_base_row(g, y[r + 1], &ws.feet_jac[f], f, 2);
                r += 2;
            }
            for (jacs, row) in [(&ws.feet_jac, r), (&ws.knee_jac, r + 4)] {
                for (k, (fa, fb, axis)) in [(0, 1, 1), (2, 3, 1), (0, 2, 0), (1, 3, 0)].into_iter().enumerate() {
                    add_base_row(g, y[row + k], &jacs[fa], fa, axis);
                    add_base_row(g, -y[row + k], &jacs[fb], fb, axis);
                }
            }
            r += 8;
            if let Some(b) = &sh.obstacle {
                let add_point = |t: &mut DVector<f64>, weight: f64, p: &Vector3<f64>, jac: &nalgebra::Matrix3xX<f64>| {
                    let grad = b.signed_distance(p).1 * weight;
                    t.gemv_tr(1.0, jac, &grad, 1.0);
                };
                for f in 0..4 {
                    add_point(t, y[r], &knees[f], &ws.knee_jac[f]);
                    r += 1;
                }
                for c in 0..8 {
                    let corner = base.act_point(&s.trunk_half_extents.component_mul(&Vector3::from(TRUNK_CORNERS[c])));
                    point_jacobian(model, &ws.data, 1, &corner, &mut ws.point_jac);
                    add_point(t, y[r], &corner, &ws.point_jac);
                    r += 1;
                }
                for f in 0..4 {
                    if spec.airborne[f] {
                        add_point(t, y[r], &feet[f], &ws.feet_jac[f]);
                        r += 1;
                    }
                }
            }
            fd.t_kinematics.copy_from(t);
            fd.gradient_kinematics.copy_from(g);
            fd.dgen_dq.as_mut_slice().fill(0.0);
            for f in 0..4 {
                if let Some(l) = self.force(z, f) {
                    add_point_force_derivative(&ws.data, &sh.legs[f], &feet[f], &l, &mut fd.dgen_dq);
                }
            }
        } else {
            t.copy_from(&fd.t_kinematics);
            g.copy_from(&fd.gradient_kinematics);
        }
        if !spec.last {
            let dt = s.dt;
            // qdd = ABA(q, v, S^T tau + sum_f J_f^T lambda_f) and d tau_gen / dq.
            ws.tau.as_mut_slice().fill(0.0);
            ws.tau.as_mut_slice()[6..].copy_from_slice(&z[2 * nv..2 * nv + nj]);
            ws.dgen_dq.copy_from(&fd.dgen_dq);
            for f in 0..4 {
                if let Some(l) = self.force(z, f) {
                    ws.tau.gemv_tr(1.0, &ws.feet_jac[f], &l, 1.0);
                }
            }
            aba(model, &mut ws.data, &ws.q, &ws.v, &ws.tau);
            let qdd = std::mem::replace(&mut ws.data.ddq, DVector::zeros(0));
            // Only `w^T d RNEA / d(q, v)` is used below, `w = M^-1 mu` needing `M` first: with
            // `curvature_rnea_tr_mul` the forward pass and `M` now, the weighted backward sweep
            // once `w` is known; otherwise both derivative matrices (and `M`) now.
            let weighted_sweep = s.curvature_rnea_tr_mul;
            if weighted_sweep {
                rnea_derivatives_forward(model, &mut ws.data, &ws.q, &ws.v, &qdd, kinematics);
            } else {
                compute_rnea_derivatives(model, &mut ws.data, &ws.q, &ws.v, &qdd);
            }
            // The step q' = q (+) dt v' and dq' = q' (-) qbar'.
            ws.data.ddq = qdd;
            ws.semi_implicit_step(model, dt, spec.qbar_next.as_ref().expect("a stage with dynamics has a next knot"));
            // a = Jl^T lambda_q: the dq' rows through q; mu = lambda_v + dt Jv^T a (+ the
            // acceleration rows' y / dt).
            // (Jl, Jq, Jv, Jd: a 6 x 6 block on the base, the identity on the joints.)
            tangent_jacobian_tr_mul(model, 1.0, &ws.jl, &m.dynamics[..nv], 0.0, fd.a.as_mut_slice());
            tangent_jacobian_tr_mul(model, 1.0, &ws.jq_step, fd.a.as_slice(), 1.0, t.as_mut_slice());
            fd.mu.copy_from_slice(&m.dynamics[nv..2 * nv]);
            tangent_jacobian_tr_mul(model, dt, &ws.jv_step, fd.a.as_slice(), 1.0, fd.mu.as_mut_slice());
            if let Some(r0) = acceleration_rows {
                for j in 0..nj {
                    fd.mu[6 + j] += y[r0 + j] / dt;
                }
            }
            fd.w.copy_from(&fd.mu);
            // M depends on q only: a velocity perturbation reuses the configuration's factor.
            if kinematics {
                mass_matrix_factor(model, &mut ws.data);
            }
            mass_matrix_factored_solve(model, &ws.data, fd.w.as_mut_slice());
            // mu^T dv'/dz, column blocks dq (through t), v, tau, lambda.
            let mut gv = g.rows_mut(nv, nv);
            gv += &fd.mu;
            if weighted_sweep {
                rnea_derivatives_tr_mul(model, &mut ws.data, fd.w.as_slice(), fd.w_dtau_dq.as_mut_slice(), fd.w_dtau_dv.as_mut_slice());
                t.gemv_tr(dt, &ws.dgen_dq, &fd.w, 1.0);
                t.axpy(-dt, &fd.w_dtau_dq, 1.0);
                gv.axpy(-dt, &fd.w_dtau_dv, 1.0);
            } else {
                ws.dgen_dq -= &ws.data.dtau_dq;
                t.gemv_tr(dt, &ws.dgen_dq, &fd.w, 1.0);
                gv.gemv_tr(-dt, &ws.data.dtau_dv, &fd.w, 1.0);
            }
            for j in 0..nj {
                g[2 * nv + j] += dt * fd.w[6 + j];
            }
            for f in 0..4 {
                if let Some(i) = self.force_index(f) {
                    let jw = &ws.feet_jac[f] * &fd.w;
                    for a in 0..3 {
                        g[i + a] += dt * jw[a];
                    }
                }
            }
        }
        // The tangent gradient through d q / d dq.
        tangent_jacobian_tr_mul(model, 1.0, &ws.jd, t.as_slice(), 1.0, &mut g.as_mut_slice()[..nv]);
    }
}
