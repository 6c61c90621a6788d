//! The deviation of a state from a desired state in the coordinates people write weights
//! in, and its Jacobian with respect to the tangent-space state.

use crate::dynamics::base_orientation;
use crate::model::{JointKind, Model};
use crate::spatial::{jlog3, log3};
use nalgebra::{DMatrix, DVector, Matrix3, Vector3};

/// `xb = [p - p*; log(R*^T R); q_J - q_J*; v_B - v_B*; w_B - w_B*; qd_J - qd_J*]` (`2 nv`):
/// base position error in the world frame (m), base orientation error as a rotation vector
/// in the desired base frame (rad; roll, pitch, yaw deviations for small errors), joint
/// angle errors in the model's joint order, then the velocity errors with the base twist
/// in the base frame (Neunert 2017, eq. 7).
///
/// With the tangent-space state `dx = [dq; dv]` (`q (+) dq` a body-frame twist on the base),
/// its Jacobian `E = d xb / d dx` is block diagonal: `R` (base position), `Jr^-1(log(R*^T R))`
/// (orientation), and identities.
pub struct StateDeviation {
    nv: usize,
}

fn base_rotation(q: &DVector<f64>) -> Matrix3<f64> {
    base_orientation(q.as_slice()).to_rotation_matrix().into_inner()
}

impl StateDeviation {
    /// For a model with a free-flyer base first (checked by the problem's builder).
    pub fn new(model: &Model) -> Self {
        debug_assert!(model.joints.get(1).map(|j| j.kind == JointKind::FreeFlyer).unwrap_or(false));
        Self { nv: model.nv }
    }

    /// `xb` into `e`; with `jac`, also `E` (overwritten).
    /// `state` and `desired` are `(q, v)` pairs.
    pub fn evaluate(&self, model: &Model, state: (&DVector<f64>, &DVector<f64>), desired: (&DVector<f64>, &DVector<f64>), e: &mut DVector<f64>, jac: Option<&mut DMatrix<f64>>) {
        let ((q, v), (q_des, v_des)) = (state, desired);
        let nv = self.nv;
        let r = base_rotation(q);
        let r_des = base_rotation(q_des);
        let orientation = log3(&(r_des.transpose() * r));
        for i in 0..3 {
            e[i] = q[i] - q_des[i];
            e[3 + i] = orientation[i];
        }
        for j in model.joints.iter().skip(2) {
            for k in 0..j.nv {
                e[j.idx_v + k] = q[j.idx_q + k] - q_des[j.idx_q + k];
            }
        }
        for i in 0..nv {
            e[nv + i] = v[i] - v_des[i];
        }
        if let Some(jac) = jac {
            jac.as_mut_slice().fill(0.0);
            jac.fixed_view_mut::<3, 3>(0, 0).copy_from(&r);
            jac.fixed_view_mut::<3, 3>(3, 3).copy_from(&jlog3(&Vector3::new(orientation[0], orientation[1], orientation[2])));
            for i in 6..2 * nv {
                jac[(i, i)] = 1.0;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dynamics::integrate;
    use crate::model::embedded;
    use nalgebra::UnitQuaternion;

    #[test]
    fn jacobian_matches_finite_differences() {
        let model = embedded::load("a1").unwrap();
        let nv = model.nv;
        let mut q = model.reference_configuration("standing").unwrap().clone();
        let mut q_des = q.clone();
        // Rotate both bases and move the desired one, so that every block is non-trivial.
        let quat = UnitQuaternion::from_euler_angles(0.3, -0.2, 0.9);
        let quat_des = UnitQuaternion::from_euler_angles(0.1, 0.25, -0.4);
        for (target, qu) in [(&mut q, quat), (&mut q_des, quat_des)] {
            target[3] = qu.i;
            target[4] = qu.j;
            target[5] = qu.k;
            target[6] = qu.w;
        }
        q_des[0] += 0.3;
        q_des[8] += 0.2;
        let v = DVector::from_fn(nv, |i, _| 0.1 * i as f64 - 0.5);
        let v_des = DVector::from_fn(nv, |i, _| 0.05 * i as f64);
        let dev = StateDeviation::new(&model);
        let mut e0 = DVector::zeros(2 * nv);
        let mut jac = DMatrix::zeros(2 * nv, 2 * nv);
        dev.evaluate(&model, (&q, &v), (&q_des, &v_des), &mut e0, Some(&mut jac));
        let h = 1e-6;
        let mut qp = q.clone();
        let mut qm = q.clone();
        let (mut ep, mut em) = (DVector::zeros(2 * nv), DVector::zeros(2 * nv));
        for k in 0..2 * nv {
            let mut dq = DVector::zeros(nv);
            let (mut vp, mut vm) = (v.clone(), v.clone());
            if k < nv {
                dq[k] = h;
                integrate(&model, &q, &dq, &mut qp);
                integrate(&model, &q, &(-&dq), &mut qm);
            } else {
                qp.copy_from(&q);
                qm.copy_from(&q);
                vp[k - nv] += h;
                vm[k - nv] -= h;
            }
            dev.evaluate(&model, (&qp, &vp), (&q_des, &v_des), &mut ep, None);
            dev.evaluate(&model, (&qm, &vm), (&q_des, &v_des), &mut em, None);
            let col = (&ep - &em) / (2.0 * h);
            assert!((col - jac.column(k)).norm() < 1e-7, "column {k}");
        }
    }
}
