//! Joint and frame Jacobians.

use super::kinematics::forward_kinematics;
use super::Data;
use crate::model::{JointKind, Model};
use crate::spatial::skew;
use nalgebra::{DVector, Matrix6xX};

/// The frame in which a frame Jacobian expresses velocities (Pinocchio's `ReferenceFrame`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReferenceFrame {
    /// Spatial velocity at the world origin, world axes.
    World,
    /// Twist of the frame in its own axes.
    Local,
    /// Linear velocity of the frame origin and angular velocity, both in world axes.
    LocalWorldAligned,
}

/// World-frame joint Jacobian columns `J[:, idx_v(i)] = oMi . S_i`, into `data.jacobian`,
/// after forward kinematics.
pub fn compute_joint_jacobians(model: &Model, data: &mut Data, q: &DVector<f64>) {
    forward_kinematics(model, data, q);
    for i in 1..model.njoints() {
        let j = &model.joints[i];
        let o = &data.o_m_i[i];
        match j.kind {
            JointKind::FreeFlyer => {
                let x = o.action_matrix();
                data.jacobian.columns_mut(j.idx_v, 6).copy_from(&x);
            }
            JointKind::Universe => {}
            k => {
                let col = o.act(&k.subspace()).to_vector();
                data.jacobian.column_mut(j.idx_v).copy_from(&col);
            }
        }
    }
}

/// Jacobian of `frame` (6 x nv, linear rows first) in `reference`, written into `out`
/// (zeroed first). Needs [`compute_joint_jacobians`] first.
///
/// With `LocalWorldAligned`, `[d p_frame/dt; w_world] = J v`.
pub fn frame_jacobian(model: &Model, data: &Data, frame: usize, reference: ReferenceFrame, out: &mut Matrix6xX<f64>) {
    out.as_mut_slice().fill(0.0);
    let fr = &model.frames[frame];
    let o_m_f = data.o_m_i[fr.parent_joint] * fr.placement;
    let p = o_m_f.translation;
    let rt = o_m_f.rotation.transpose();
    let mut i = fr.parent_joint;
    while i > 0 {
        let j = &model.joints[i];
        for c in j.idx_v..j.idx_v + j.nv {
            let col = data.jacobian.column(c);
            let v0 = nalgebra::Vector3::new(col[0], col[1], col[2]);
            let w = nalgebra::Vector3::new(col[3], col[4], col[5]);
            let (lin, ang) = match reference {
                ReferenceFrame::World => (v0, w),
                // velocity of the frame origin: v0 + w x p
                ReferenceFrame::LocalWorldAligned => (v0 + w.cross(&p), w),
                ReferenceFrame::Local => (rt * (v0 + w.cross(&p)), rt * w),
            };
            let mut oc = out.column_mut(c);
            oc[0] = lin.x;
            oc[1] = lin.y;
            oc[2] = lin.z;
            oc[3] = ang.x;
            oc[4] = ang.y;
            oc[5] = ang.z;
        }
        i = j.parent;
    }
    let _ = skew;
}
