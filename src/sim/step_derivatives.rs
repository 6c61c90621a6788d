//! The exact linearization of one simulator step, `dx_{k+1} = A dx_k + B du_k`, in the
//! tangent space of the state (`dx = [dq; dv]`, `2 nv`), for the SLQ optimizer (Neunert
//! 2017, Alg. 1: "linearize the system dynamics along the trajectory").
//!
//! Forward dynamics with contact: `M(q) a + nle(q, v) = tau + tau_c(q, v)`, with the contact
//! generalized force of the feet `tau_c = sum_i J_i(q)^T lambda_i(p_i(q), pdot_i(q, v))`
//! (Neunert 2017, eq. 6) plus the joint stops' diagonal generalized force `tau_l(q, v)`
//! ([`super::JointLimitParams`]), which enters below as part of `tau_c`. Differentiating the
//! identity `RNEA(q, v, a) = tau + tau_c`:
//!
//! ```text
//! da/dq   = M^-1 (dtau_c/dq - dRNEA/dq)
//! da/dv   = M^-1 (dtau_c/dv - dRNEA/dv)
//! da/dtau = M^-1 S^T
//! ```
//!
//! with RNEA's analytic derivatives (Carpentier & Mansard 2018), the stops' `dtau_l/dq`,
//! `dtau_l/dv` (diagonal, [`super::JointStops::add_derivatives`]), and `dtau_c` from the
//! contact model's derivatives ([`crate::contact::ContactForce`]) and the world-frame joint
//! axes `S_k` (Jacobian columns): for a foot at `p` with force `lambda`, the spatial force at
//! the world origin is `F = (lambda, p x lambda)` and `tau_c[k] = S_k . F` for every degree
//! of freedom `k` supporting the foot, so
//!
//! ```text
//! dtau_c[k]/dq_j = S_k . dF/dq_j + (S_j x S_k) . F        (second term when j supports k)
//! dF/dq_j        = (dlambda_j, dp_j x lambda + p x dlambda_j)
//! dp_j           = S_j.v + S_j.w x p                       (foot Jacobian column)
//! dpdot_j        = dV_j.v + dV_j.w x p + V.w x dp_j,   dV_j = S_j x sum_{k: j supports k} S_k v_k
//! dlambda_j      = dlambda/dp dp_j + dlambda/dpdot dpdot_j
//! dtau_c[k]/dv_j = S_k . (dlambda, p x dlambda),  dlambda = dlambda/dpdot dp_j
//! ```
//!
//! (`S_j x S_k` is the change of axis `k` when `q_j` moves, `dS_k/dq_j`; on the free-flyer
//! base, whose tangent is a body-frame twist, every base axis supports every other.)
//!
//! The semi-implicit Euler step `v' = v + dt a`, `q' = q (+) dt v'` then gives, with the
//! Jacobians of `integrate` at `dt v'` ([`crate::dynamics::integrate_jacobians`]):
//!
//! ```text
//! A = [ Jq + dt^2 Jv a_q    dt Jv (I + dt a_v) ]      B = [ dt^2 Jv a_tau ]
//!     [ dt a_q              I + dt a_v         ]          [ dt a_tau      ]
//! ```
//!
//! The contact anchors are hidden states (as in the paper): held over the step.

use crate::linalg::gemm;
use super::workspace::ContactModelWorkspace;
use crate::dynamics::{compute_joint_jacobians, compute_minverse, compute_rnea_derivatives, integrate_jacobians};
use crate::model::Model;
use crate::spatial::Motion;
use nalgebra::{DMatrix, DVector, Matrix3xX, Vector3};

/// Scratch and results of [`StepDerivatives::step`]; one per thread, beside a
/// [`ContactModelWorkspace`].
pub struct StepDerivatives {
    /// `d x_{k+1} / d x_k` (`2 nv x 2 nv`), tangent space, `[dq; dv]` ordering.
    pub a: DMatrix<f64>,
    /// `d x_{k+1} / d u_k` (`2 nv x nu`), `u` the actuated joints' torques.
    pub b: DMatrix<f64>,
    dtau_c_dq: DMatrix<f64>,
    dtau_c_dv: DMatrix<f64>,
    a_q: DMatrix<f64>,
    a_v: DMatrix<f64>,
    pub(super) jq: DMatrix<f64>,
    pub(super) jv: DMatrix<f64>,
    tmp: DMatrix<f64>,
    b_lower: DMatrix<f64>,
    acc: DVector<f64>,
    chain: Vec<usize>,
    /// Partial sums `sum_{k: j supports k} S_k v_k` along a foot's chain.
    partial_velocity: Vec<Motion>,
    /// Per foot at the last step: `d p / d dq` and `d pdot / d dq` (3 x nv, world frame;
    /// `d pdot / d dv = d p / d dq`), for the anchor linearization and the feasibility rows.
    pub(super) foot_dp_dq: Vec<Matrix3xX<f64>>,
    pub(super) foot_dpdot_dq: Vec<Matrix3xX<f64>>,
    nu: usize,
}

impl StepDerivatives {
    pub fn new(model: &Model) -> Self {
        let nv = model.nv;
        let nu = nv - 6;
        let z = || DMatrix::zeros(nv, nv);
        Self {
            a: DMatrix::zeros(2 * nv, 2 * nv),
            b: DMatrix::zeros(2 * nv, nu),
            dtau_c_dq: z(),
            dtau_c_dv: z(),
            a_q: z(),
            a_v: z(),
            jq: z(),
            jv: z(),
            tmp: z(),
            b_lower: DMatrix::zeros(nv, nu),
            acc: DVector::zeros(nv),
            chain: Vec::with_capacity(nv),
            partial_velocity: vec![Motion::zero(); nv],
            foot_dp_dq: vec![Matrix3xX::zeros(nv); model.feet.len()],
            foot_dpdot_dq: vec![Matrix3xX::zeros(nv); model.feet.len()],
            nu,
        }
    }

    /// Of foot `f` at the start of the last [`Self::step`]: `d p / d dq` and `d pdot / d dq`
    /// (3 x nv, world frame; `d pdot / d dv = d p / d dq`), of every foot, touching the
    /// ground or not.
    pub fn foot_jacobians(&self, f: usize) -> (&Matrix3xX<f64>, &Matrix3xX<f64>) {
        (&self.foot_dp_dq[f], &self.foot_dpdot_dq[f])
    }

    /// One semi-implicit Euler step from `(q, v)` with torques `tau` (`nv`, base entries
    /// zero) and its linearization into [`Self::a`], [`Self::b`]. `q`, `v` and `anchors`
    /// are advanced exactly as [`ContactModelWorkspace::step`] does.
    pub fn step(
        &mut self,
        ws: &mut ContactModelWorkspace<'_>,
        q: &mut DVector<f64>,
        v: &mut DVector<f64>,
        anchors: &mut [Option<Vector3<f64>>],
        tau: &DVector<f64>,
        dt: f64,
    ) {
        let model = ws.model;
        let nv = model.nv;
        ws.evaluate_contacts(q, v, anchors);
        ws.acceleration(q, v, tau, &Vector3::zeros(), 0);
        self.acc.copy_from(&ws.dv[0]);

        // dRNEA/dq, dRNEA/dv at the actual acceleration, and M^-1.
        compute_rnea_derivatives(model, &mut ws.data, q, v, &self.acc);
        self.contact_force_derivatives(ws, q, v);
        ws.stops.add_derivatives(q, v, &mut self.dtau_c_dq, &mut self.dtau_c_dv);
        self.dtau_c_dq -= &ws.data.dtau_dq;
        self.dtau_c_dv -= &ws.data.dtau_dv;
        compute_minverse(model, &mut ws.data, q);
        gemm(&mut self.a_q, 1.0, &ws.data.minv, &self.dtau_c_dq, 0.0);
        gemm(&mut self.a_v, 1.0, &ws.data.minv, &self.dtau_c_dv, 0.0);

        // v' = v + dt a, q' = q (+) dt v' (the simulator's own update), and the Jacobians of
        // that integrate at dt v'.
        ws.advance_semi_implicit(q, v, anchors, dt);
        integrate_jacobians(model, &ws.step_v, &mut self.jq, &mut self.jv);
        let minv = &ws.data.minv;

        // Lower rows: dv' = dt a_q dq + (I + dt a_v) dv + dt a_tau du.
        let (dt2, nu) = (dt * dt, self.nu);
        {
            let mut lower_q = self.a.view_mut((nv, 0), (nv, nv));
            lower_q.copy_from(&self.a_q);
            lower_q *= dt;
        }
        {
            let mut lower_v = self.a.view_mut((nv, nv), (nv, nv));
            lower_v.copy_from(&self.a_v);
            lower_v *= dt;
            for i in 0..nv {
                lower_v[(i, i)] += 1.0;
            }
        }
        // a_tau = M^-1 S^T: the actuated columns of M^-1.
        self.b.view_mut((nv, 0), (nv, nu)).copy_from(&minv.columns(6, nu));
        self.b.view_mut((nv, 0), (nv, nu)).scale_mut(dt);
        // Upper rows: dq' = Jq dq + Jv dt dv'.
        self.tmp.copy_from(&self.jq);
        self.tmp.gemm(dt2, &self.jv, &self.a_q, 1.0);
        self.a.view_mut((0, 0), (nv, nv)).copy_from(&self.tmp);
        self.tmp.copy_from(&self.jv);
        self.tmp.gemm(dt2, &self.jv, &self.a_v, dt);
        self.a.view_mut((0, nv), (nv, nv)).copy_from(&self.tmp);
        self.b_lower.copy_from(&self.b.rows(nv, nv));
        gemm(self.b.view_mut((0, 0), (nv, nu)), dt, &self.jv, &self.b_lower, 0.0);
    }

    /// `dtau_c/dq` and `dtau_c/dv` into `self.dtau_c_dq`, `self.dtau_c_dv` (see the module
    /// documentation), from the feet of the last contact evaluation.
    fn contact_force_derivatives(&mut self, ws: &mut ContactModelWorkspace<'_>, q: &DVector<f64>, v: &DVector<f64>) {
        let model = ws.model;
        self.dtau_c_dq.as_mut_slice().fill(0.0);
        self.dtau_c_dv.as_mut_slice().fill(0.0);
        compute_joint_jacobians(model, &mut ws.data, q);
        let axis = |k: usize, jac: &nalgebra::Matrix6xX<f64>| {
            let c = jac.column(k);
            Motion::new(Vector3::new(c[0], c[1], c[2]), Vector3::new(c[3], c[4], c[5]))
        };
        for (i, foot) in model.feet.iter().enumerate() {
            let state = &ws.feet[i];
            self.foot_dp_dq[i].as_mut_slice().fill(0.0);
            self.foot_dpdot_dq[i].as_mut_slice().fill(0.0);
            // Every foot's Jacobians (the feasibility layer's landing rows act on a foot
            // above the ground); only a touching foot adds to tau_c (one touching with no
            // force, leaving fast, adds nothing but its anchor still follows it).
            let touching = state.contact.penetration > 0.0;
            let lambda = state.contact.force;
            let p = state.position;
            let (dl_dp, dl_dv) = (state.contact.d_position, state.contact.d_velocity);
            let force_at_origin = crate::spatial::Force::new(lambda, p.cross(&lambda));
            // The degrees of freedom supporting the foot, leaf first.
            let joint = &model.joints[model.frames[foot.frame].parent_joint];
            self.chain.clear();
            let mut k = joint.idx_v + joint.nv - 1;
            loop {
                self.chain.push(k);
                match model.dof_parent[k] {
                    usize::MAX => break,
                    parent => k = parent,
                }
            }
            // Partial sums of S_k v_k from the leaf; the base's six axes share the total.
            let jac = &ws.data.jacobian;
            let mut sum = Motion::zero();
            for &k in &self.chain {
                let s = axis(k, jac);
                sum = Motion::new(sum.v + s.v * v[k], sum.w + s.w * v[k]);
                self.partial_velocity[k] = sum;
            }
            let body_velocity = sum;
            let is_base = |k: usize| model.joints[model.joint_of_dof[k]].nv == 6;
            for (j_pos, &j) in self.chain.iter().enumerate() {
                let s_j = axis(j, jac);
                let w_j = if is_base(j) { body_velocity } else { self.partial_velocity[j] };
                let dp = s_j.v + s_j.w.cross(&p);
                let dv_body = s_j.cross(&w_j);
                let dpdot = dv_body.v + dv_body.w.cross(&p) + body_velocity.w.cross(&dp);
                self.foot_dp_dq[i].set_column(j, &dp);
                self.foot_dpdot_dq[i].set_column(j, &dpdot);
                if !touching {
                    continue;
                }
                let dlambda = dl_dp * dp + dl_dv * dpdot;
                let df = crate::spatial::Force::new(dlambda, dp.cross(&lambda) + p.cross(&dlambda));
                let dlambda_v = dl_dv * dp;
                let df_v = crate::spatial::Force::new(dlambda_v, p.cross(&dlambda_v));
                // j supports k: k is leafward of j in the chain (the chain lists leaf first,
                // so at or before j's position), or both are base axes.
                for (pos, &k) in self.chain.iter().enumerate() {
                    let s_k = axis(k, jac);
                    let mut dq = s_k.dot(&df);
                    if pos <= j_pos || (is_base(j) && is_base(k)) {
                        dq += s_j.cross(&s_k).dot(&force_at_origin);
                    }
                    self.dtau_c_dq[(k, j)] += dq;
                    self.dtau_c_dv[(k, j)] += s_k.dot(&df_v);
                }
            }
        }
    }
}
