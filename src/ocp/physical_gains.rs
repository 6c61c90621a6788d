//! Feedback gains a robot can use: the SLQ gains on the physical state alone, with the
//! stance feet as constraints.
//!
//! With anchor states the optimizer's state is `x = (q, v, a)`: the configuration, the
//! velocity and, per foot in contact, the anchor `a_f` of its tangential contact spring
//! (Neunert 2017, eq. 10). Its gains act on `dx = [q (-) q*; v - v*; a - a*]` in a world
//! whose ground is a spring: a stance foot's own motion stretches that spring, and the
//! optimizer's answer to it counts on the spring's force. Measured on the nine plans
//! (docs/experiments/policy-mujoco.md), the gain of a stance leg on its own joints is a
//! *negative* stiffness (an eigenvalue with positive real part) at 23-99 % of the stance
//! knots (diagonal_balance 95 %, median +447 N m/rad, with almost no damping): harmless
//! while the soft ground holds the foot, a runaway of that leg as soon as a foot loses its
//! load in a stiff, unilateral contact (MuJoCo, a robot).
//!
//! On a robot a loaded foot does not move; the deviations the gains may answer are those
//! that keep the stance feet planted, `J_c dq = 0` (`J_c` stacks the stance feet's linear
//! Jacobians at `q*`), and on those the anchors stay where they are (`da = 0`). The measured
//! deviation is projected on that set by moving the stance legs' own joints (the joints
//! `C` on the paths from the stance feet to the base):
//!
//! ```text
//! dq_planted = N dq,   N = I - E_C J_c,C^+ J_c          (J_c N = 0; N = I on the base and swing legs)
//! K_phys     = [ K_q N,  K_v N - K_d (I - N) ]           (nu x 2 nv; K_d = diag(kd), actuated rows)
//! ```
//!
//! with `J_c,C` the columns `C` of `J_c`, `^+` the pseudo-inverse (the inverse of each 3 x 3
//! leg Jacobian on a quadruped) and `E_C` the embedding of those columns. On every motion
//! with the stance feet planted, `K_phys` acts as the optimizer's gain does; the anchor
//! columns drop out (`a - a* = P J_c N dq = 0`). A stance foot's own motion, `(I - N) dq`,
//! which a stiff ground does not let happen while the foot is loaded, gets no position
//! feedback and the joint damping `kd` of legwork's joint PD for a free joint
//! ([`crate::control::PdGains::capped_for_free_joints`], HyQ 30 / 30 / 22 N m s/rad at
//! 1 kHz): a foot that loses its load is slowed, not thrown away, and the feedforward (a
//! stance torque, pressing the foot down) puts it back. Without that damping the policy
//! does not hold a pushed plan in legwork's own soft contact, where pushed feet do unload
//! (measured, docs/experiments/policy-mujoco.md). A foot off the ground at the knot (no
//! anchor) keeps its leg's gains as the optimizer computed them.
//!
//! This is what `trajectory.json` exports: `tau = tau_ff + K_phys [q (-) q*; v - v*]`.

use crate::control::PdGains;
use crate::dynamics::{compute_joint_jacobians, frame_jacobian, Data, ReferenceFrame};
use crate::model::{JointKind, Model};
use nalgebra::{DMatrix, DVector, Matrix6xX, Vector3};

/// Singular values of the stance legs' Jacobian below this fraction of the largest are
/// treated as zero in its pseudo-inverse (a leg stretched to a singularity keeps the
/// directions it can still move in).
const PSEUDO_INVERSE_RELATIVE_TOLERANCE: f64 = 1e-9;

/// Workspace for [`physical_gain`]: the kinematics, the foot Jacobian, each foot's leg and
/// the joint damping of a stance foot's own motion. Sized once: on a robot whose feet end
/// disjoint legs of three joints each (a quadruped), [`physical_gain`] allocates nothing
/// (the MPC's controller calls it in the control loop, [`crate::mpc::MpcFeedback`]).
pub struct PhysicalGainWorkspace {
    data: Data,
    jacobian: Matrix6xX<f64>,
    /// Per foot, the velocity indices of the joints between the foot and the base.
    legs: Vec<Vec<usize>>,
    /// Every leg has three joints and no joint is on two feet's legs: `J_c,C` is block
    /// diagonal with 3 x 3 blocks, its pseudo-inverse taken block by block.
    three_joint_legs: bool,
    /// `kd` per velocity index (the base entries unused).
    damping: DVector<f64>,
    projector: DMatrix<f64>,
    /// Per stance foot: its linear Jacobian `J_f` (3 x nv) and, on three-joint legs, the
    /// SVD of its leg's block `J_f,C_f`.
    foot_jacobians: Vec<nalgebra::Matrix3xX<f64>>,
    leg_blocks: Vec<nalgebra::SVD<f64, nalgebra::U3, nalgebra::U3>>,
}

impl PhysicalGainWorkspace {
    /// With the damping `joint_pd.kd` on a stance foot's own motion (module documentation).
    pub fn new(model: &Model, joint_pd: &PdGains) -> Self {
        let legs: Vec<Vec<usize>> = model.feet.iter().map(|foot| leg_dofs(model, model.frames[foot.frame].parent_joint)).collect();
        let mut all: Vec<usize> = legs.iter().flatten().copied().collect();
        let joints = all.len();
        all.sort_unstable();
        all.dedup();
        let three_joint_legs = all.len() == joints && legs.iter().all(|l| l.len() == 3);
        let feet = model.feet.len();
        let zero_svd = nalgebra::Matrix3::<f64>::identity().svd(true, true);
        Self {
            data: Data::new(model),
            jacobian: Matrix6xX::zeros(model.nv),
            legs,
            three_joint_legs,
            damping: joint_pd.kd.clone(),
            projector: DMatrix::identity(model.nv, model.nv),
            foot_jacobians: vec![nalgebra::Matrix3xX::zeros(model.nv); feet],
            leg_blocks: vec![zero_svd; feet],
        }
    }

    /// With the damping of the policy `trajectory.json` exports: legwork's joint PD for a free
    /// joint ([`PdGains::capped_for_free_joints`]) around `q0` at the simulator's control rate
    /// (legwork's simulator and the MuJoCo check run the policy at 1 kHz).
    pub fn for_exported_policy(model: &Model, q0: &DVector<f64>) -> Self {
        let control_dt = crate::sim::SimConfig::default().control_dt;
        Self::new(model, &PdGains::from_model(model, q0, control_dt).capped_for_free_joints(model, q0, control_dt))
    }

    /// `N` of the last [`physical_gain`] call (`nv x nv`): the projection of a configuration
    /// deviation on the motions that keep its stance feet planted.
    pub fn planted_projector(&self) -> &DMatrix<f64> {
        &self.projector
    }
}

/// The velocity indices of the joints on the path from `joint` to the root, free flyer
/// excluded (a foot's leg).
fn leg_dofs(model: &Model, joint: usize) -> Vec<usize> {
    let mut dofs = Vec::new();
    let mut j = joint;
    while j > 0 {
        let joint = &model.joints[j];
        if joint.kind != JointKind::FreeFlyer {
            dofs.extend(joint.idx_v..joint.idx_v + joint.nv);
        }
        j = joint.parent;
    }
    dofs.sort_unstable();
    dofs
}

/// The gain on the physical state `[q (-) q*; v - v*]` (`nu x 2 nv`, into `out`) from the
/// optimizer's `gain` on `[dq; dv]` or `[dq; dv; da]` at the planned configuration
/// `q_star`, whose stance feet are those with an anchor in `anchors` (module
/// documentation: `K_phys = [K_q N, K_v N - K_d (I - N)]`).
pub fn physical_gain(model: &Model, ws: &mut PhysicalGainWorkspace, q_star: &DVector<f64>, anchors: &[Option<Vector3<f64>>], gain: &DMatrix<f64>, out: &mut DMatrix<f64>) {
    let nv = model.nv;
    ws.projector.fill_with_identity();
    if anchors.iter().all(Option::is_none) {
        out.copy_from(&gain.columns(0, 2 * nv));
        return;
    }
    // J_f per stance foot (3 x nv).
    compute_joint_jacobians(model, &mut ws.data, q_star);
    for (f, _) in anchors.iter().enumerate().filter(|(_, a)| a.is_some()) {
        frame_jacobian(model, &ws.data, model.feet[f].frame, ReferenceFrame::LocalWorldAligned, &mut ws.jacobian);
        ws.foot_jacobians[f].copy_from(&ws.jacobian.fixed_rows::<3>(0));
    }
    // N = I - E_C J_c,C^+ J_c, row by row of the stance legs' joints C.
    if ws.three_joint_legs {
        subtract_blockwise_correction(ws, anchors);
    } else {
        subtract_correction(model, ws, anchors);
    }
    // K_phys = [K_q N, K_v N - K_d (I - N)]; the anchor columns act on da = 0.
    // Column by column: a matrix-matrix product this size goes through matrixmultiply,
    // which allocates its packing buffers.
    for c in 0..nv {
        out.column_mut(c).gemv(1.0, &gain.columns(0, nv), &ws.projector.column(c), 0.0);
        out.column_mut(nv + c).gemv(1.0, &gain.columns(nv, nv), &ws.projector.column(c), 0.0);
    }
    // Row dof - 6 of K_d (I - N) = kd_dof (E_C J_c,C^+ J_c)[dof, :] = kd_dof (I - N)[dof, :],
    // zero off the stance legs' joints.
    for dof in 6..nv {
        let kd = ws.damping[dof];
        for c in 0..nv {
            let identity = if c == dof { 1.0 } else { 0.0 };
            out[(dof - 6, nv + c)] -= kd * (identity - ws.projector[(dof, c)]);
        }
    }
}

/// `N -= E_C J_c,C^+ J_c` when the stance legs are disjoint and of three joints: `J_c,C` is
/// block diagonal, `J_c,C^+ = diag(J_f,C_f^+)` (its singular values are the blocks', the
/// tolerance relative to the largest of them all), no allocation.
fn subtract_blockwise_correction(ws: &mut PhysicalGainWorkspace, anchors: &[Option<Vector3<f64>>]) {
    let mut largest = 0.0_f64;
    for (f, _) in anchors.iter().enumerate().filter(|(_, a)| a.is_some()) {
        let leg = &ws.legs[f];
        let block = nalgebra::Matrix3::from_fn(|r, c| ws.foot_jacobians[f][(r, leg[c])]);
        ws.leg_blocks[f] = block.svd(true, true);
        largest = largest.max(ws.leg_blocks[f].singular_values.max());
    }
    let tolerance = PSEUDO_INVERSE_RELATIVE_TOLERANCE * largest;
    for (f, _) in anchors.iter().enumerate().filter(|(_, a)| a.is_some()) {
        // The SVD was computed with both factors, so the pseudo-inverse exists.
        let Ok(pseudo_inverse) = ws.leg_blocks[f].pseudo_inverse(tolerance) else { unreachable!("SVD computed with U and V^T") };
        // Column c of J_f,C_f^+ J_f onto the leg's rows of N.
        for c in 0..ws.projector.ncols() {
            let column = pseudo_inverse * ws.foot_jacobians[f].fixed_view::<3, 1>(0, c);
            for (i, &dof) in ws.legs[f].iter().enumerate() {
                ws.projector[(dof, c)] -= column[i];
            }
        }
    }
}

/// `N -= E_C J_c,C^+ J_c` on any robot (legs that share joints, or of other lengths): the
/// stacked Jacobian's pseudo-inverse (allocates).
fn subtract_correction(model: &Model, ws: &mut PhysicalGainWorkspace, anchors: &[Option<Vector3<f64>>]) {
    let stance: Vec<usize> = anchors.iter().enumerate().filter_map(|(f, a)| a.map(|_| f)).collect();
    let mut constraint = DMatrix::zeros(3 * stance.len(), model.nv);
    let mut legs: Vec<usize> = Vec::new();
    for (row, &f) in stance.iter().enumerate() {
        constraint.rows_mut(3 * row, 3).copy_from(&ws.foot_jacobians[f]);
        legs.extend(&ws.legs[f]);
    }
    legs.sort_unstable();
    legs.dedup();
    let constraint_legs = DMatrix::from_fn(constraint.nrows(), legs.len(), |r, c| constraint[(r, legs[c])]);
    let svd = constraint_legs.svd(true, true);
    let tolerance = PSEUDO_INVERSE_RELATIVE_TOLERANCE * svd.singular_values.max();
    // The SVD was computed with both factors, so the pseudo-inverse exists.
    let Ok(pseudo_inverse) = svd.pseudo_inverse(tolerance) else { unreachable!("SVD computed with U and V^T") };
    let correction = pseudo_inverse * &constraint;
    for (i, &dof) in legs.iter().enumerate() {
        for c in 0..model.nv {
            ws.projector[(dof, c)] -= correction[(i, c)];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dynamics::{forward_kinematics, frame_position, integrate};
    use crate::model::embedded;
    use crate::sim::ANCHOR_DIM;

    fn bent_stance(model: &Model) -> DVector<f64> {
        let mut q = model.reference_configuration("standing").unwrap().clone();
        for i in 7..model.nq {
            q[i] += 0.05 * ((i % 5) as f64 - 2.0);
        }
        q
    }

    /// The exported gain on a deviation that keeps the stance feet planted (checked by
    /// central differences of their positions) is the optimizer's on it with `da = 0`; a
    /// stance leg's own joints get no gain; a swing leg keeps the optimizer's; no stance
    /// feet, the gain as it is.
    #[test]
    fn the_gain_acts_on_the_motions_that_keep_the_stance_feet_planted() {
        let model = embedded::load("hyq").unwrap();
        let q = bent_stance(&model);
        let nv = model.nv;
        let nu = nv - 6;
        let nx = 2 * nv + ANCHOR_DIM * model.feet.len();
        let gain = DMatrix::from_fn(nu, nx, |i, j| ((i * 31 + j * 17) % 13) as f64 - 6.0);
        // LF, RF and RH in contact, LH in the air.
        let anchors = vec![Some(Vector3::zeros()), Some(Vector3::zeros()), None, Some(Vector3::zeros())];
        let pd = PdGains::from_model(&model, &q, 0.001);
        let mut ws = PhysicalGainWorkspace::new(&model, &pd);
        let mut k = DMatrix::zeros(nu, 2 * nv);
        physical_gain(&model, &mut ws, &q, &anchors, &gain, &mut k);
        let n = ws.planted_projector().clone();

        // A deviation of the base and of every joint, projected: the stance feet stay.
        let dq = DVector::from_fn(nv, |i, _| 1e-5 * (((i * 7) % 5) as f64 - 2.0 + 0.3));
        let planted = &n * &dq;
        let (mut q_plus, mut q_minus) = (q.clone(), q.clone());
        integrate(&model, &q, &planted, &mut q_plus);
        integrate(&model, &q, &(-&planted), &mut q_minus);
        let mut data = Data::new(&model);
        for (f, a) in anchors.iter().enumerate() {
            forward_kinematics(&model, &mut data, &q_plus);
            let p2 = frame_position(&model, &data, model.feet[f].frame);
            forward_kinematics(&model, &mut data, &q_minus);
            let p1 = frame_position(&model, &data, model.feet[f].frame);
            let moved = (p2 - p1).norm() * 0.5;
            if a.is_some() {
                assert!(moved < 1e-9, "stance foot {f} moves {moved:e} m under a planted deviation");
            } else {
                assert!(moved > 1e-6, "the swing foot {f} moves with the base ({moved:e} m)");
            }
        }
        // On a planted deviation and velocity, the exported gain is the optimizer's with
        // da = 0.
        let dv = &n * DVector::from_fn(nv, |i, _| 0.1 * (((i * 3) % 7) as f64 - 3.0));
        let mut dx = DVector::zeros(nx);
        dx.rows_mut(0, nv).copy_from(&planted);
        dx.rows_mut(nv, nv).copy_from(&dv);
        let mut dphys = DVector::zeros(2 * nv);
        dphys.rows_mut(0, nv).copy_from(&planted);
        dphys.rows_mut(nv, nv).copy_from(&dv);
        let (optimizer, exported) = (&gain * &dx, &k * &dphys);
        assert!((&optimizer - &exported).norm() < 1e-9 * optimizer.norm(), "{optimizer} vs {exported}");
        // A stance leg's own joints (LF: velocity indices 6..9) get no position gain and the
        // joint PD's damping on their own velocity; the swing leg's (LH: 12..15) keep the
        // optimizer's.
        for dof in 6..9 {
            assert!(k.column(dof).norm() < 1e-9 * gain.norm());
            for row in 0..nu {
                let expected = if row + 6 == dof { -pd.kd[dof] } else { 0.0 };
                assert!((k[(row, nv + dof)] - expected).abs() < 1e-9 * gain.norm(), "K[{row}, v{dof}] = {} vs {expected}", k[(row, nv + dof)]);
            }
        }
        for dof in 12..15 {
            assert_eq!(k.column(dof), gain.column(dof));
            assert_eq!(k.column(nv + dof), gain.column(nv + dof));
        }
        // No stance feet: the (q, v) columns as they are.
        physical_gain(&model, &mut ws, &q, &[None; 4], &gain, &mut k);
        assert_eq!(k, gain.columns(0, 2 * nv));
    }

    /// On a quadruped the pseudo-inverse is taken leg by leg (no allocation); it is the
    /// stacked Jacobian's, to rounding, on every set of stance feet.
    #[test]
    fn the_leg_by_leg_pseudo_inverse_is_the_stacked_one() {
        let model = embedded::load("hyq").unwrap();
        let q = bent_stance(&model);
        let nv = model.nv;
        let nx = 2 * nv + ANCHOR_DIM * model.feet.len();
        let gain = DMatrix::from_fn(nv - 6, nx, |i, j| ((i * 31 + j * 17) % 13) as f64 - 6.0);
        let pd = PdGains::from_model(&model, &q, 0.001);
        let mut ws = PhysicalGainWorkspace::new(&model, &pd);
        assert!(ws.three_joint_legs);
        let (mut blockwise, mut stacked) = (DMatrix::zeros(nv - 6, 2 * nv), DMatrix::zeros(nv - 6, 2 * nv));
        for stance in 1..16_usize {
            let anchors: Vec<_> = (0..4).map(|f| (stance >> f & 1 == 1).then(Vector3::zeros)).collect();
            ws.three_joint_legs = true;
            physical_gain(&model, &mut ws, &q, &anchors, &gain, &mut blockwise);
            ws.three_joint_legs = false;
            physical_gain(&model, &mut ws, &q, &anchors, &gain, &mut stacked);
            assert!((&blockwise - &stacked).norm() < 1e-12 * gain.norm(), "stance feet {stance:04b}: {}", (&blockwise - &stacked).norm());
            assert!((&blockwise - gain.columns(0, 2 * nv)).norm() > 1.0, "stance feet {stance:04b}: the projection acts");
        }
    }

    #[test]
    fn a_foot_s_leg_is_the_joints_between_it_and_the_base() {
        let model = embedded::load("hyq").unwrap();
        let ws = PhysicalGainWorkspace::new(&model, &PdGains::from_model(&model, &model.neutral(), 0.001));
        assert_eq!(ws.legs, vec![vec![6, 7, 8], vec![9, 10, 11], vec![12, 13, 14], vec![15, 16, 17]]);
    }
}
