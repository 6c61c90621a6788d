//! The kinematic pieces of the full-body optimization: the legs' joint chains, world points
//! and their Jacobians, the leg inverse kinematics of the initial guess, and the derivative
//! of a point force's generalized force `d (J_p(q)^T lambda) / dq` that the forward
//! dynamics with contact forces needs.
//!
//! Jacobians are in Pinocchio's tangent convention (`shared/fixtures/README.md`): the base
//! columns are the base's local twist, `M' = M exp(delta)`.

use super::FullBodyError;
use crate::dynamics::{compute_joint_jacobians, frame_position, Data};
use crate::model::{JointKind, Model};
use crate::spatial::Motion;
use nalgebra::{DMatrix, DVector, Matrix3, Matrix3xX, Vector3};

/// One leg: its foot, its knee and its three joints.
#[derive(Clone, Debug)]
pub struct Leg {
    /// Frame of the foot (the centre of its sphere).
    pub foot_frame: usize,
    /// The joint whose origin is the knee (the foot frame's parent joint).
    pub knee_joint: usize,
    /// `q` and `v` indices of the leg's joints, hip to knee.
    pub q_index: [usize; 3],
    pub v_index: [usize; 3],
    /// Degrees of freedom from the root to the foot (base first), for the derivatives.
    pub chain: Vec<usize>,
    /// How many of `chain` are the free flyer's (6).
    pub base_dofs: usize,
}

/// The four legs of `model` (order of `model.feet`), each a chain of three one-dof joints
/// below a free-flyer base.
pub fn legs(model: &Model) -> Result<Vec<Leg>, FullBodyError> {
    if model.feet.len() != 4 || !model.has_free_flyer() {
        return Err(FullBodyError::Model(format!("'{}' needs a free-flyer base and 4 feet, it has {} feet", model.name, model.feet.len())));
    }
    let mut out = Vec::with_capacity(4);
    for foot in &model.feet {
        let knee_joint = model.frames[foot.frame].parent_joint;
        let mut joints = Vec::new();
        let mut base = None;
        let mut i = knee_joint;
        while i > 0 {
            let j = &model.joints[i];
            match j.kind {
                JointKind::FreeFlyer => base = Some(i),
                _ if j.nv == 1 => joints.push(i),
                _ => return Err(FullBodyError::Model(format!("foot '{}': joint '{}' is not a one-dof joint", foot.name, j.name))),
            }
            i = j.parent;
        }
        let (Some(base), 3) = (base, joints.len()) else {
            return Err(FullBodyError::Model(format!("foot '{}': expected 3 joints below the free flyer, found {}", foot.name, joints.len())));
        };
        joints.reverse();
        let b = &model.joints[base];
        let mut chain: Vec<usize> = (b.idx_v..b.idx_v + 6).collect();
        chain.extend(joints.iter().map(|&j| model.joints[j].idx_v));
        out.push(Leg {
            foot_frame: foot.frame,
            knee_joint,
            q_index: std::array::from_fn(|a| model.joints[joints[a]].idx_q),
            v_index: std::array::from_fn(|a| model.joints[joints[a]].idx_v),
            chain,
            base_dofs: 6,
        });
    }
    Ok(out)
}

/// World position of a foot (after forward kinematics).
pub fn foot_position(model: &Model, data: &Data, leg: &Leg) -> Vector3<f64> {
    frame_position(model, data, leg.foot_frame)
}

/// World position of a knee (after forward kinematics).
pub fn knee_position(data: &Data, leg: &Leg) -> Vector3<f64> {
    data.o_m_i[leg.knee_joint].translation
}

/// `d p / dq` (3 x nv, world axes) of the world point `p` carried by joint `joint`'s body:
/// column `c` on the chain is `v0_c + w_c x p` (the world Jacobian column at the origin moved
/// to the point). Needs [`compute_joint_jacobians`] first; `out` is overwritten.
pub fn point_jacobian(model: &Model, data: &Data, joint: usize, p: &Vector3<f64>, out: &mut Matrix3xX<f64>) {
    out.as_mut_slice().fill(0.0);
    let mut i = joint;
    while i > 0 {
        let j = &model.joints[i];
        for c in j.idx_v..j.idx_v + j.nv {
            let s = data.jacobian.column(c);
            let v0 = Vector3::new(s[0], s[1], s[2]);
            let w = Vector3::new(s[3], s[4], s[5]);
            out.column_mut(c).copy_from(&(v0 + w.cross(p)));
        }
        i = j.parent;
    }
}

/// Adds `d (J_p(q)^T lambda) / dq` (nv x nv) of a world force `lambda` at the foot of `leg`
/// (world point `p`) to `out`. With the world Jacobian columns `s_i` and the force's wrench
/// at the origin `W = (lambda, p x lambda)`, `Q_i = s_i . W`, and
///
/// ```text
/// dQ_i/dq_j = [j precedes i] (s_j x s_i) . W  +  w_i . ((v0_j + w_j x p) x lambda)
/// ```
///
/// (`d s_i / dq_j = s_j x s_i` for an ancestor `j`, and for every pair of base columns since
/// `Ad(M exp(delta)) e_i = s_i + (Ad(M) delta) x s_i`). Needs [`compute_joint_jacobians`].
pub fn add_point_force_derivative(data: &Data, leg: &Leg, p: &Vector3<f64>, lambda: &Vector3<f64>, out: &mut DMatrix<f64>) {
    let col = |c: usize| Motion::from_slice(&data.jacobian.column(c).as_slice()[..6]);
    let moment = p.cross(lambda);
    for (a, &i) in leg.chain.iter().enumerate() {
        let si = col(i);
        for (b, &j) in leg.chain.iter().enumerate() {
            let sj = col(j);
            let pdot = sj.v + sj.w.cross(p);
            let mut d = si.w.dot(&pdot.cross(lambda));
            if b < a || (a < leg.base_dofs && b < leg.base_dofs) {
                let c = sj.cross(&si);
                d += c.v.dot(lambda) + c.w.dot(&moment);
            }
            out[(i, j)] += d;
        }
    }
}

/// Leg inverse kinematics: the joint angles of `leg` (written into `q`) that put its foot
/// at `target` with the base where `q` has it, by damped Gauss-Newton steps from the
/// angles in `q`, kept within the joint limits. Returns the remaining distance (m).
pub fn leg_inverse_kinematics(model: &Model, data: &mut Data, leg: &Leg, target: &Vector3<f64>, q: &mut DVector<f64>) -> f64 {
    let mut jac = Matrix3xX::zeros(model.nv);
    let mut error = f64::INFINITY;
    for _ in 0..100 {
        compute_joint_jacobians(model, data, q);
        let p = foot_position(model, data, leg);
        let e = target - p;
        error = e.norm();
        if error < 1e-12 {
            break;
        }
        point_jacobian(model, data, leg.knee_joint, &p, &mut jac);
        let j = Matrix3::from_fn(|r, c| jac[(r, leg.v_index[c])]);
        let step = (j.transpose() * j + Matrix3::identity() * 1e-8).try_inverse().map(|m| m * j.transpose() * e).unwrap_or_else(Vector3::zeros);
        for a in 0..3 {
            let jnt = &model.joints[model.joint_of_dof[leg.v_index[a]]];
            let (lo, hi) = (jnt.limits.lower[0], jnt.limits.upper[0]);
            q[leg.q_index[a]] = (q[leg.q_index[a]] + step[a]).clamp(lo, hi);
        }
    }
    error
}
