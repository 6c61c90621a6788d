//! Operations on the configuration manifold `R^3 x SO(3) x R^n` (SE(3) base).

use crate::model::{JointKind, Model};
use crate::spatial::{exp6, jexp6, log6, Matrix6, Motion, SE3};
use nalgebra::{DMatrix, DVector, Quaternion, UnitQuaternion, Vector3};

/// Orientation of the free-flyer base in a configuration `q` whose first joint is the free
/// flyer: `q[3..7]` is its quaternion `(x, y, z, w)` (legwork's and Pinocchio's order).
#[inline]
pub fn base_orientation(q: &[f64]) -> UnitQuaternion<f64> {
    UnitQuaternion::from_quaternion(Quaternion::new(q[6], q[3], q[4], q[5]))
}

fn base_pose(q: &[f64]) -> SE3 {
    super::kinematics::joint_transform(&JointKind::FreeFlyer, q)
}

/// `q_out = q (+) v`: the configuration reached by following velocity `v` for unit time.
/// Base: `M_out = M exp6(v_base)` (local twist); other joints: `q + v`.
pub fn integrate(model: &Model, q: &DVector<f64>, v: &DVector<f64>, q_out: &mut DVector<f64>) {
    for j in model.joints.iter().skip(1) {
        let (iq, iv) = (j.idx_q, j.idx_v);
        match j.kind {
            JointKind::FreeFlyer => {
                let qs = &q.as_slice()[iq..iq + 7];
                let m = base_pose(qs);
                let step = exp6(&Motion::from_slice(&v.as_slice()[iv..iv + 6]));
                let t = m.translation + m.rotation * step.translation;
                let q0 = Quaternion::new(qs[6], qs[3], qs[4], qs[5]);
                let dq = UnitQuaternion::from_rotation_matrix(&nalgebra::Rotation3::from_matrix_unchecked(step.rotation));
                let mut qn = q0 * dq.into_inner();
                qn /= qn.norm();
                let out = &mut q_out.as_mut_slice()[iq..iq + 7];
                out[0] = t.x;
                out[1] = t.y;
                out[2] = t.z;
                out[3] = qn.i;
                out[4] = qn.j;
                out[5] = qn.k;
                out[6] = qn.w;
            }
            JointKind::Universe => {}
            _ => q_out[iq] = q[iq] + v[iv],
        }
    }
}

/// Jacobians of `q' = integrate(q, v)` in the tangent spaces (Pinocchio's `dIntegrate`):
/// `dq' = Jq dq + Jv dv`. Joints: identities. Free-flyer (`M' = M Exp(v)`, Sola et al. 2018,
/// eq. 170-171): `Jq = Ad(Exp(v))^-1`, `Jv = Jr(v)` ([`crate::spatial::jexp6`]).
/// `jq` and `jv` are `nv x nv`, overwritten.
pub fn integrate_jacobians(model: &Model, v: &DVector<f64>, jq: &mut DMatrix<f64>, jv: &mut DMatrix<f64>) {
    fill_joint_blocks(model, v, jq, |step| exp6(step).inverse().action_matrix());
    fill_joint_blocks(model, v, jv, jexp6);
}

/// The velocity Jacobian `Jv = d integrate(q, v) / dv` of [`integrate_jacobians`] alone
/// (the same values; `Jq` not formed): the identity on the joints, `Jr(v)` on a free flyer.
pub fn integrate_velocity_jacobian(model: &Model, v: &DVector<f64>, jv: &mut DMatrix<f64>) {
    fill_joint_blocks(model, v, jv, jexp6);
}

/// Overwrites `out` (`nv x nv`) with a block-diagonal tangent Jacobian: the identity on the
/// joints, `free_flyer(v_base)` on a free flyer's `6 x 6` block.
fn fill_joint_blocks(model: &Model, v: &DVector<f64>, out: &mut DMatrix<f64>, free_flyer: impl Fn(&Motion) -> Matrix6) {
    out.as_mut_slice().fill(0.0);
    for j in model.joints.iter().skip(1) {
        let iv = j.idx_v;
        match j.kind {
            JointKind::FreeFlyer => {
                let step = Motion::from_slice(&v.as_slice()[iv..iv + 6]);
                out.fixed_view_mut::<6, 6>(iv, iv).copy_from(&free_flyer(&step));
            }
            JointKind::Universe => {}
            _ => {
                for k in iv..iv + j.nv {
                    out[(k, k)] = 1.0;
                }
            }
        }
    }
}

/// `y <- alpha J^T x + beta y` for a tangent-space Jacobian `J` of the configuration
/// manifold ([`integrate_jacobians`], or a product or inverse of such blocks): a `6 x 6`
/// block on each free flyer, the identity on the other joints. Only the blocks are
/// multiplied; the dense product's other terms are zeros. `beta = 0` ignores `y`. (The
/// dense `J X` products are left to the matrix kernel: for 18 x 18 times 18 x 60 its
/// vectorized product measured cheaper than the blocks plus an element-wise copy.)
pub fn tangent_jacobian_tr_mul(model: &Model, alpha: f64, j: &DMatrix<f64>, x: &[f64], beta: f64, y: &mut [f64]) {
    for jnt in model.joints.iter().skip(1) {
        let iv = jnt.idx_v;
        match jnt.kind {
            JointKind::FreeFlyer => {
                for c in iv..iv + 6 {
                    let p: [f64; 6] = std::array::from_fn(|i| j[(iv + i, c)] * x[iv + i]);
                    // The dense product's order (nalgebra's dot, 8 accumulators, on a base block
                    // at the top of a vector of at least 8): the same bits as the dense product.
                    let dot = if iv == 0 && x.len() >= 8 { (p[0] + p[4]) + (p[1] + p[5]) + p[2] + p[3] } else { p.iter().sum() };
                    y[c] = if beta == 0.0 { alpha * dot } else { alpha * dot + beta * y[c] };
                }
            }
            JointKind::Universe => {}
            _ => {
                for k in iv..iv + jnt.nv {
                    y[k] = if beta == 0.0 { alpha * x[k] } else { alpha * x[k] + beta * y[k] };
                }
            }
        }
    }
}

/// `v = q1 (-) q0`, the velocity with `integrate(q0, v) = q1`.
/// Base: `log6(M0^-1 M1)`; other joints: `q1 - q0`.
pub fn difference(model: &Model, q0: &DVector<f64>, q1: &DVector<f64>, v_out: &mut DVector<f64>) {
    difference_into(model, q0, q1, v_out.as_mut_slice());
}

/// [`difference`] into a slice of length `nv` (for example the top half of a state
/// tangent `[dq; dv]`).
pub fn difference_into(model: &Model, q0: &DVector<f64>, q1: &DVector<f64>, v_out: &mut [f64]) {
    for j in model.joints.iter().skip(1) {
        let (iq, iv) = (j.idx_q, j.idx_v);
        match j.kind {
            JointKind::FreeFlyer => {
                let m0 = base_pose(&q0.as_slice()[iq..iq + 7]);
                let m1 = base_pose(&q1.as_slice()[iq..iq + 7]);
                let tw = log6(&m0.inv_mul(&m1)).to_vector();
                v_out[iv..iv + 6].copy_from_slice(tw.as_slice());
            }
            JointKind::Universe => {}
            _ => v_out[iv] = q1[iq] - q0[iq],
        }
    }
}

/// A random configuration: base position uniform in `[-1, 1]^3`, orientation uniform on
/// SO(3), joints uniform within their limits (clipped to `[-pi, pi]` where unbounded).
/// `uniform` returns samples of U(0, 1).
pub fn random_configuration(model: &Model, uniform: &mut impl FnMut() -> f64) -> DVector<f64> {
    let mut q = model.neutral();
    for j in model.joints.iter().skip(1) {
        let iq = j.idx_q;
        match j.kind {
            JointKind::FreeFlyer => {
                for k in 0..3 {
                    q[iq + k] = 2.0 * uniform() - 1.0;
                }
                // Shoemake's uniform random quaternion.
                let (u1, u2, u3) = (uniform(), uniform(), uniform());
                let tau = std::f64::consts::TAU;
                let (a, b) = ((1.0 - u1).sqrt(), u1.sqrt());
                let quat = [a * (tau * u2).sin(), a * (tau * u2).cos(), b * (tau * u3).sin(), b * (tau * u3).cos()];
                q.as_mut_slice()[iq + 3..iq + 7].copy_from_slice(&quat);
            }
            JointKind::Universe => {}
            _ => {
                let pi = std::f64::consts::PI;
                let lo = j.limits.lower[0].max(-pi);
                let hi = j.limits.upper[0].min(pi);
                q[iq] = lo + (hi - lo) * uniform();
            }
        }
    }
    let _ = Vector3::<f64>::zeros;
    q
}
