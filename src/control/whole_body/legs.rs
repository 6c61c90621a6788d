//! The legs as three-joint chains from the free-flyer base to each foot: foot position and
//! velocity, the foot Jacobian split into its base and leg columns, the bias acceleration
//! `Jd v`, per-leg solves with the 3 x 3 leg Jacobian, and a Newton inverse kinematics.
//!
//! All of it reads the world-frame joint Jacobian and joint placements that
//! [`crate::dynamics::compute_joint_jacobians`] leaves in [`Data`]; nothing allocates.

use super::WholeBodyError;
use crate::dynamics::{compute_joint_jacobians, Data};
use crate::model::{JointKind, Model};
use crate::spatial::Motion;
use nalgebra::{DVector, Matrix3, Matrix3x6, Vector3};

/// Largest joint change of one Newton step (rad): keeps a far target from throwing the
/// leg through a singularity.
const MAX_NEWTON_STEP: f64 = 0.3;

/// `|det J| / (|J_1| |J_2| |J_3|)` (Hadamard ratio, 1 for orthogonal columns) below which a
/// leg Jacobian counts as singular (knee stretched or folded).
const SINGULAR_RATIO: f64 = 1e-3;

/// Damping `mu^2` (m^2) of the least-squares solve used at a singular leg Jacobian.
const SINGULAR_DAMPING: f64 = 1e-4;

/// One leg: the foot frame and the three one-degree-of-freedom joints between it and the
/// base, hip first.
#[derive(Clone, Debug, PartialEq)]
pub struct LegChain {
    /// Index of the foot in `model.feet`.
    pub foot: usize,
    /// The foot frame (centre of the foot sphere).
    pub frame: usize,
    /// The joint the foot frame moves with.
    pub joint: usize,
    /// The foot frame origin in that joint's frame.
    pub point: Vector3<f64>,
    /// Indices of the three joints into `v`, hip to knee.
    pub v_index: [usize; 3],
    /// Their indices into `q`.
    pub q_index: [usize; 3],
    /// Their position limits (rad).
    pub lower: [f64; 3],
    pub upper: [f64; 3],
}

/// Finds every foot's chain and checks the structure the controller relies on: a
/// free-flyer base, exactly three one-degree-of-freedom joints per leg, and every actuated
/// joint in exactly one leg.
pub fn leg_chains(model: &Model) -> Result<Vec<LegChain>, WholeBodyError> {
    let structure = |problem: String| WholeBodyError::Structure { robot: model.name.clone(), problem };
    if !model.has_free_flyer() || model.joints[1].kind != JointKind::FreeFlyer || model.joints[1].idx_v != 0 {
        return Err(structure("the first joint must be a free-flyer base with v[0..6]".into()));
    }
    if model.feet.is_empty() {
        return Err(structure("the robot has no feet".into()));
    }
    let mut owner = vec![None::<usize>; model.nv];
    let mut legs = Vec::with_capacity(model.feet.len());
    for (foot, f) in model.feet.iter().enumerate() {
        let frame = &model.frames[f.frame];
        let mut chain = Vec::new();
        let mut i = frame.parent_joint;
        while i > 1 {
            chain.push(i);
            i = model.joints[i].parent;
        }
        if i != 1 {
            return Err(structure(format!("foot '{}' is not attached to the free-flyer base", f.name)));
        }
        chain.reverse();
        if chain.len() != 3 || chain.iter().any(|&j| model.joints[j].nv != 1) {
            return Err(structure(format!(
                "foot '{}' hangs on {} joints ({}); the leg solver needs three one-degree-of-freedom joints",
                f.name,
                chain.len(),
                chain.iter().map(|&j| model.joints[j].name.as_str()).collect::<Vec<_>>().join(", ")
            )));
        }
        let joint = |k: usize| &model.joints[chain[k]];
        for k in 0..3 {
            let iv = joint(k).idx_v;
            if let Some(other) = owner[iv] {
                return Err(structure(format!("joint '{}' is in the legs of feet {} and {}", joint(k).name, model.feet[other].name, f.name)));
            }
            owner[iv] = Some(foot);
        }
        legs.push(LegChain {
            foot,
            frame: f.frame,
            joint: frame.parent_joint,
            point: frame.placement.translation,
            v_index: [joint(0).idx_v, joint(1).idx_v, joint(2).idx_v],
            q_index: [joint(0).idx_q, joint(1).idx_q, joint(2).idx_q],
            lower: [joint(0).limits.lower[0], joint(1).limits.lower[0], joint(2).limits.lower[0]],
            upper: [joint(0).limits.upper[0], joint(1).limits.upper[0], joint(2).limits.upper[0]],
        });
    }
    if let Some(j) = model.actuated_joints().find(|j| owner[j.idx_v].is_none()) {
        return Err(structure(format!("joint '{}' belongs to no leg; the controller would leave it unactuated", j.name)));
    }
    Ok(legs)
}

/// Velocity and bias acceleration (the acceleration at `vd = 0`, without gravity) of every
/// joint in its own frame (Featherstone 2008, Table 5.1, forward pass with `qdd = 0`):
///
/// ```text
/// v_i = iXp v_p + S_i qd_i,     a_i = iXp a_p + v_i x (S_i qd_i)
/// ```
///
/// Needs the local placements `data.li_m_i` of the same `q` (forward kinematics).
pub fn velocities_and_bias(model: &Model, data: &Data, v: &DVector<f64>, velocity: &mut [Motion], bias: &mut [Motion]) {
    velocity[0] = Motion::zero();
    bias[0] = Motion::zero();
    for i in 1..model.njoints() {
        let j = &model.joints[i];
        let vj = match j.kind {
            JointKind::FreeFlyer => Motion::from_slice(&v.as_slice()[j.idx_v..j.idx_v + 6]),
            JointKind::Universe => Motion::zero(),
            k => k.subspace() * v[j.idx_v],
        };
        let li = &data.li_m_i[i];
        let (vp, ap) = if j.parent > 0 { (li.act_inv(&velocity[j.parent]), li.act_inv(&bias[j.parent])) } else { (Motion::zero(), Motion::zero()) };
        velocity[i] = vp + vj;
        bias[i] = ap + velocity[i].cross(&vj);
    }
}

/// One foot at the current state, world frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FootKinematics {
    pub position: Vector3<f64>,
    pub velocity: Vector3<f64>,
    /// `Jd v`: the foot's (classical) acceleration when `vd = 0`.
    pub bias_acceleration: Vector3<f64>,
    /// Columns of the foot Jacobian for the base, `v[0..6]`.
    pub base_jacobian: Matrix3x6<f64>,
    /// Columns for the leg's own joints, in [`LegChain::v_index`] order; the Jacobian is
    /// zero for every other joint.
    pub leg_jacobian: Matrix3<f64>,
}

impl Default for FootKinematics {
    fn default() -> Self {
        Self {
            position: Vector3::zeros(),
            velocity: Vector3::zeros(),
            bias_acceleration: Vector3::zeros(),
            base_jacobian: Matrix3x6::zeros(),
            leg_jacobian: Matrix3::zeros(),
        }
    }
}

impl FootKinematics {
    /// `J v` restricted to the base and the leg: the foot velocity the Jacobian predicts.
    pub fn jacobian_times(&self, leg: &LegChain, v: &DVector<f64>) -> Vector3<f64> {
        let vb = v.fixed_rows::<6>(0);
        self.base_jacobian * vb + self.leg_jacobian * Vector3::new(v[leg.v_index[0]], v[leg.v_index[1]], v[leg.v_index[2]])
    }
}

/// Foot position `p` (world) of `leg` after forward kinematics.
#[inline]
pub fn foot_position(data: &Data, leg: &LegChain) -> Vector3<f64> {
    data.o_m_i[leg.joint].act_point(&leg.point)
}

/// The linear velocity of the world point `p` moved by the Jacobian column `c` (a world
/// spatial velocity at the world origin): `v0 + w x p`.
#[inline]
fn point_column(data: &Data, c: usize, p: &Vector3<f64>) -> Vector3<f64> {
    let col = data.jacobian.column(c);
    Vector3::new(col[0], col[1], col[2]) + Vector3::new(col[3], col[4], col[5]).cross(p)
}

/// The leg's 3 x 3 Jacobian at foot position `p` (after [`compute_joint_jacobians`]).
#[inline]
pub fn leg_jacobian(data: &Data, leg: &LegChain, p: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::from_columns(&[point_column(data, leg.v_index[0], p), point_column(data, leg.v_index[1], p), point_column(data, leg.v_index[2], p)])
}

/// The foot Jacobian's six base columns at foot position `p` (after [`compute_joint_jacobians`]).
#[inline]
pub fn base_jacobian(data: &Data, p: &Vector3<f64>) -> Matrix3x6<f64> {
    let mut jb = Matrix3x6::zeros();
    for c in 0..6 {
        jb.set_column(c, &point_column(data, c, p));
    }
    jb
}

/// Everything about one foot at the state: after [`compute_joint_jacobians`] at `q` and
/// [`velocities_and_bias`] at `(q, v)`. The foot's velocity and bias acceleration, in the
/// parent joint's frame and rotated to the world:
///
/// ```text
/// v_p = v.lin + v.ang x p,      a_p = a.lin + a.ang x p + v.ang x v_p
/// ```
pub fn foot_kinematics(data: &Data, leg: &LegChain, velocity: &[Motion], bias: &[Motion], out: &mut FootKinematics) {
    let p = foot_position(data, leg);
    let r = &data.o_m_i[leg.joint].rotation;
    let (vel, acc) = (&velocity[leg.joint], &bias[leg.joint]);
    let v_local = vel.v + vel.w.cross(&leg.point);
    let a_local = acc.v + acc.w.cross(&leg.point) + vel.w.cross(&v_local);
    out.position = p;
    out.velocity = r * v_local;
    out.bias_acceleration = r * a_local;
    out.base_jacobian = base_jacobian(data, &p);
    out.leg_jacobian = leg_jacobian(data, leg, &p);
}

/// Solves `J x = b` for a leg Jacobian: exactly (LU) when well conditioned, by damped least
/// squares `x = J^T (J J^T + mu^2 I)^-1 b` near a singularity. Returns `x` and whether the
/// damped solve was used.
pub fn solve_leg(j: &Matrix3<f64>, b: &Vector3<f64>) -> (Vector3<f64>, bool) {
    let scale = j.column(0).norm() * j.column(1).norm() * j.column(2).norm();
    let det = j.determinant();
    if scale > 0.0 && det.abs() > SINGULAR_RATIO * scale {
        if let Some(x) = j.lu().solve(b) {
            return (x, false);
        }
    }
    let jjt = j * j.transpose() + Matrix3::identity() * SINGULAR_DAMPING;
    let y = jjt.cholesky().map(|c| c.solve(b)).unwrap_or_else(Vector3::zeros);
    (j.transpose() * y, true)
}

/// Newton inverse kinematics of all legs at once, the base held where `q` puts it:
/// `q_leg += J_leg^-1 (p* - p(q))` ([`solve_leg`]), each step at most 0.3 rad, the joints
/// clamped to their limits, until every foot is within `tolerance` (m) of its target or
/// `max_iterations` steps were taken. `q` is the warm start (the previous solution) and
/// receives the result; `data` is left with the kinematics and Jacobian of the result.
/// Returns the largest remaining foot error (m): non-zero for an unreachable target.
///
/// Newton rather than HyQ's closed form so that any three-joint leg (A1's offset hips too)
/// works; warm-started from the last tick it converges in one or two steps.
pub fn legs_inverse_kinematics(
    model: &Model,
    data: &mut Data,
    legs: &[LegChain],
    targets: &[Vector3<f64>],
    q: &mut DVector<f64>,
    tolerance: f64,
    max_iterations: usize,
) -> f64 {
    let mut iteration = 0;
    loop {
        compute_joint_jacobians(model, data, q);
        let residual = legs.iter().map(|leg| (targets[leg.foot] - foot_position(data, leg)).norm()).fold(0.0, f64::max);
        if residual <= tolerance || iteration == max_iterations {
            return residual;
        }
        iteration += 1;
        for leg in legs {
            let p = foot_position(data, leg);
            let (mut dq, _) = solve_leg(&leg_jacobian(data, leg, &p), &(targets[leg.foot] - p));
            let step = dq.amax();
            if step > MAX_NEWTON_STEP {
                dq *= MAX_NEWTON_STEP / step;
            }
            for k in 0..3 {
                let iq = leg.q_index[k];
                q[iq] = (q[iq] + dq[k]).clamp(leg.lower[k], leg.upper[k]);
            }
        }
    }
}
