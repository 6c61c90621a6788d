//! Feedback gains a robot can use: the SLQ gains on the physical state alone.
//!
//! With anchor states the optimizer's state is `x = (q, v, a)`: the configuration, the
//! velocity and, per foot in contact, the anchor `a_f` of its tangential contact spring
//! (Neunert 2017, eq. 10: the point where contact began). Its gains act on
//! `dx = [q (-) q*; v - v*; a - a*]`, but an anchor exists only inside the contact model:
//! neither another simulator nor a robot can measure it. The anchors are eliminated by what
//! they are physically. A foot that sticks stays on its anchor up to the stretch of its
//! tangential spring, `|F_t| / (k_t s(p_n))` (about 2 mm per 100 N for the calibrated
//! contact, [`crate::contact::ContactParams`]), so an anchor's deviation is the deviation
//! of the foot's contact point, projected on the ground's tangent plane:
//!
//! ```text
//! a_f - a_f* = P_f (c_f(q) - c_f(q*)) = P_f J_f (q (-) q*) + O(|dq|^2),   P_f = I - n_f n_f^T
//! ```
//!
//! with `c_f = p_f - r n_f` the contact point and `J_f` the foot's world-aligned linear
//! Jacobian. Substituted into `u = u* + K_q dq + K_v dv + sum_f K_a,f da_f`:
//!
//! ```text
//! K_phys = [ K_q + sum_{f in contact} K_a,f P_f J_f(q*),  K_v ]        (nu x 2 nv)
//! ```
//!
//! which is what `trajectory.json` exports: `tau = tau_ff + K_phys [q (-) q*; v - v*]`. A
//! foot off the ground at the knot has no anchor and its columns are zero already.

use crate::dynamics::{compute_joint_jacobians, frame_jacobian, Data, ReferenceFrame};
use crate::model::Model;
use crate::sim::ANCHOR_DIM;
use crate::terrain::Terrain;
use nalgebra::{DMatrix, DVector, Matrix3, Matrix6xX, Vector3};

/// Workspace for [`physical_gain`]: the kinematics and the foot Jacobian.
pub struct PhysicalGainWorkspace {
    data: Data,
    jacobian: Matrix6xX<f64>,
    projected: DMatrix<f64>,
}

impl PhysicalGainWorkspace {
    pub fn new(model: &Model) -> Self {
        Self { data: Data::new(model), jacobian: Matrix6xX::zeros(model.nv), projected: DMatrix::zeros(ANCHOR_DIM, model.nv) }
    }
}

/// The gain on the physical state `[q (-) q*; v - v*]` (`nu x 2 nv`, into `out`) equivalent
/// to the optimizer's `gain` on `[dq; dv; da]` at the planned configuration `q_star`, whose
/// feet with an anchor are those of `anchors` (module documentation).
///
/// A gain without anchor columns (`2 nv` wide) is copied.
pub fn physical_gain(model: &Model, terrain: &dyn Terrain, ws: &mut PhysicalGainWorkspace, q_star: &DVector<f64>, anchors: &[Option<Vector3<f64>>], gain: &DMatrix<f64>, out: &mut DMatrix<f64>) {
    let nv = model.nv;
    out.copy_from(&gain.columns(0, 2 * nv));
    if gain.ncols() == 2 * nv || anchors.iter().all(Option::is_none) {
        return;
    }
    compute_joint_jacobians(model, &mut ws.data, q_star);
    for (f, anchor) in anchors.iter().enumerate() {
        let Some(anchor) = anchor else { continue };
        frame_jacobian(model, &ws.data, model.feet[f].frame, ReferenceFrame::LocalWorldAligned, &mut ws.jacobian);
        let n = terrain.normal(anchor.x, anchor.y);
        let tangent = Matrix3::identity() - n * n.transpose();
        // P_f J_f: the tangential motion of the contact point (c = p - r n moves as p).
        ws.projected.gemm(1.0, &tangent, &ws.jacobian.fixed_rows::<3>(0), 0.0);
        let k_anchor = gain.columns(2 * nv + ANCHOR_DIM * f, ANCHOR_DIM);
        out.columns_mut(0, nv).gemm(1.0, &k_anchor, &ws.projected, 1.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dynamics::{forward_kinematics, frame_position, integrate};
    use crate::model::embedded;
    use crate::terrain::Plane;

    /// For a small configuration change `dq`, the exported gain's action equals the
    /// optimizer gain's action on `[dq; 0; da]` with `da` the tangential move of the contact
    /// points (to first order: central differences), and a gain without anchors is unchanged.
    #[test]
    fn the_anchor_columns_act_through_the_feet() {
        let model = embedded::load("hyq").unwrap();
        let ground = Plane::new(0.02, Vector3::new(0.1, -0.05, 1.0)).unwrap();
        let q = model.reference_configuration("standing").unwrap().clone();
        let nv = model.nv;
        let nu = nv - 6;
        let nx = 2 * nv + ANCHOR_DIM * model.feet.len();
        let gain = DMatrix::from_fn(nu, nx, |i, j| ((i * 31 + j * 17) % 13) as f64 - 6.0);
        // LF and RH feet in contact (anchors anywhere on the plane; only their normals matter).
        let anchors = vec![Some(Vector3::new(0.4, 0.3, 0.0)), None, None, Some(Vector3::new(-0.4, -0.3, 0.0))];
        let mut ws = PhysicalGainWorkspace::new(&model);
        let mut k = DMatrix::zeros(nu, 2 * nv);
        physical_gain(&model, &ground, &mut ws, &q, &anchors, &gain, &mut k);

        let dq = DVector::from_fn(nv, |i, _| 1e-5 * (((i * 7) % 5) as f64 - 2.0));
        // Central differences: the contact points at q (+) dq and q (-) dq.
        let (mut q_plus, mut q_minus) = (q.clone(), q.clone());
        integrate(&model, &q, &dq, &mut q_plus);
        integrate(&model, &q, &(-&dq), &mut q_minus);
        let mut data = Data::new(&model);
        let mut dx = DVector::zeros(nx);
        dx.rows_mut(0, nv).copy_from(&dq);
        for (f, a) in anchors.iter().enumerate() {
            let Some(a) = a else { continue };
            forward_kinematics(&model, &mut data, &q_minus);
            let p1 = frame_position(&model, &data, model.feet[f].frame);
            forward_kinematics(&model, &mut data, &q_plus);
            let p2 = frame_position(&model, &data, model.feet[f].frame);
            let n = ground.normal(a.x, a.y);
            let da = (Matrix3::identity() - n * n.transpose()) * (p2 - p1) * 0.5;
            dx.fixed_rows_mut::<3>(2 * nv + 3 * f).copy_from(&da);
        }
        let mut dphys = DVector::zeros(2 * nv);
        dphys.rows_mut(0, nv).copy_from(&dq);
        let (with_anchors, exported) = (&gain * &dx, &k * &dphys);
        assert!((&with_anchors - &exported).norm() < 1e-8 * with_anchors.norm(), "{with_anchors} vs {exported}");
        // The velocity columns are the optimizer's.
        assert_eq!(k.columns(nv, nv), gain.columns(nv, nv));
        // No anchors: the (q, v) columns as they are.
        physical_gain(&model, &ground, &mut ws, &q, &[None; 4], &gain, &mut k);
        assert_eq!(k, gain.columns(0, 2 * nv));
    }
}
