use crate::model::Model;
use crate::spatial::{Force, InertiaMoments, Matrix3, Matrix6, Motion, Vector6, SE3};
use nalgebra::{DMatrix, DVector, Matrix3xX, Matrix6xX, Vector3};

/// The mutable workspace of the dynamics algorithms: one per thread, built once from a
/// [`Model`] and reused; no algorithm allocates. Build a new `Data` if the model changes.
///
/// Field names follow Pinocchio's `Data` where they have a counterpart.
#[derive(Clone, Debug)]
pub struct Data {
    /// Pose of joint `i` in its parent joint's frame (`liMi`).
    pub li_m_i: Vec<SE3>,
    /// Pose of joint `i` in the world (`oMi`).
    pub o_m_i: Vec<SE3>,
    /// Pose of each frame in the world (`oMf`), after [`super::update_frame_placements`].
    pub o_m_f: Vec<SE3>,
    /// Spatial velocity of each joint, in its own frame.
    pub v: Vec<Motion>,
    /// Spatial acceleration of each joint, in its own frame (gravity included, as Pinocchio).
    pub a: Vec<Motion>,
    /// Spatial force transmitted by each joint, in its own frame.
    pub f: Vec<Force>,
    /// Generalized force, output of RNEA.
    pub tau: DVector<f64>,
    /// Generalized acceleration, output of ABA.
    pub ddq: DVector<f64>,
    /// Non-linear effects `C(q, v) v + g(q)`.
    pub nle: DVector<f64>,
    /// Generalized gravity `g(q)`.
    pub g: DVector<f64>,
    /// Joint-space inertia matrix (full, symmetric), output of CRBA.
    pub mass_matrix: DMatrix<f64>,
    /// Inverse of the joint-space inertia matrix (full, symmetric).
    pub minv: DMatrix<f64>,
    /// Joint Jacobian columns in the world frame (`J`, spatial velocity at the world origin).
    pub jacobian: Matrix6xX<f64>,
    /// Centre of mass of the whole robot in the world.
    pub com: Vector3<f64>,
    /// Jacobian of the centre of mass (3 x nv).
    pub com_jacobian: Matrix3xX<f64>,
    /// Centroidal momentum matrix `A_g` (6 x nv), linear rows first.
    pub centroidal_matrix: Matrix6xX<f64>,
    /// Centroidal momentum `h_g = A_g v`: linear momentum, angular momentum about the CoM.
    pub centroidal_momentum: Force,
    /// Mass of the subtree rooted at each joint.
    pub subtree_mass: Vec<f64>,
    /// Centre of mass of the subtree rooted at each joint, in the world.
    pub subtree_com: Vec<Vector3<f64>>,
    /// `d ddq / dq` in the tangent space (ABA derivatives).
    pub ddq_dq: DMatrix<f64>,
    /// `d ddq / dv`.
    pub ddq_dv: DMatrix<f64>,
    /// `d tau / dq` (RNEA derivatives).
    pub dtau_dq: DMatrix<f64>,
    /// `d tau / dv`.
    pub dtau_dv: DMatrix<f64>,

    // --- cached from the model ---
    /// Body inertias of the model as mass moments about each joint origin.
    pub(crate) body_moments: Vec<InertiaMoments>,
    /// For one-degree-of-freedom revolute joints, `(Rp [a]x, Rp [a]x^2)` with `Rp` the
    /// placement rotation and `a` the axis: then `Rp Exp(a t) = Rp + sin t Rp[a]x + (1 - cos t) Rp[a]x^2`.
    pub(crate) revolute_terms: Vec<(Matrix3<f64>, Matrix3<f64>)>,
    // --- scratch of the algorithms ---
    pub(crate) c: Vec<Motion>,
    pub(crate) y_aba: Vec<Matrix6>,
    pub(crate) p_a: Vec<Force>,
    pub(crate) u_col: Vec<Vector6>,
    pub(crate) d_inv: Vec<f64>,
    pub(crate) u_scalar: Vec<f64>,
    pub(crate) y_crb: Vec<InertiaMoments>,
    pub(crate) o_y_crb: Vec<InertiaMoments>,
    /// Each body's inertia in the world frame, as ABA left it for the ABA derivatives.
    pub(crate) o_y_body: Vec<InertiaMoments>,
    pub(crate) ov: Vec<Motion>,
    /// World-frame spatial acceleration of each joint after [`super::aba`], with gravity as a
    /// fictitious base acceleration `a_0 = -g` (a body in free fall has `oa = 0`).
    pub oa: Vec<Motion>,
    pub(crate) of: Vec<Force>,
    pub(crate) oh: Vec<Force>,
    /// Inertia variation `dY` of Carpentier & Mansard 2018: `[[0, [t]x], [0, B]]`, kept as
    /// the vector `t` and the block `B` (its other blocks are zero).
    pub(crate) do_y_top: Vec<nalgebra::Vector3<f64>>,
    pub(crate) do_y_b: Vec<Matrix3<f64>>,
    pub(crate) o_j: Vec<Motion>,
    pub(crate) dvdq: Matrix6xX<f64>,
    pub(crate) dadq: Matrix6xX<f64>,
    pub(crate) dadv: Matrix6xX<f64>,
    pub(crate) dfdq: Matrix6xX<f64>,
    pub(crate) dfdv: Matrix6xX<f64>,
    pub(crate) dfda: Matrix6xX<f64>,
    /// Angular halves of the columns `dY^T J` (their linear halves are zero).
    pub(crate) dytj: Matrix3xX<f64>,
    pub(crate) tmp_nv: DVector<f64>,
    /// Of [`super::rnea_derivatives_tr_mul`]: `W_i = sum_{k in anc(i)} w_k J_k` (the weights
    /// of the rows of `i` and its ancestors), and the strict subtree's `sum_r w_r (dF/da)_r`
    /// and `sum_r w_r (dY^T J)_r`.
    pub(crate) w_ancestors: Vec<Motion>,
    pub(crate) w_dfda: Vec<Force>,
    pub(crate) w_dytj: Vec<Vector3<f64>>,
    /// `L^T D L` factor of `M` (Featherstone 2008, §6.5).
    pub(crate) ltdl: DMatrix<f64>,
    /// `L^-1`.
    pub(crate) linv: DMatrix<f64>,
    /// Each degree of freedom's branch to the root, itself first, then its parent, ...:
    /// `dof_chains[dof_chain_starts[k]..dof_chain_starts[k + 1]]` (the parent links of
    /// `Model::dof_parent` walked once, not at every use).
    pub(crate) dof_chains: Vec<usize>,
    pub(crate) dof_chain_starts: Vec<usize>,
    /// A column of `M^-1` as it is summed.
    pub(crate) minv_column: Vec<f64>,
    /// The tree's shape if `M^-1` has the specialized path (a trunk with equal serial limbs).
    pub(crate) limb_layout: Option<super::minverse_limbs::LimbLayout>,
}

impl Data {
    /// A workspace sized for `model`.
    pub fn new(model: &Model) -> Self {
        let n = model.njoints();
        let nv = model.nv;
        let (dof_chains, dof_chain_starts) = dof_chains(&model.dof_parent);
        Self {
            li_m_i: vec![SE3::identity(); n],
            o_m_i: vec![SE3::identity(); n],
            o_m_f: vec![SE3::identity(); model.frames.len()],
            v: vec![Motion::zero(); n],
            a: vec![Motion::zero(); n],
            f: vec![Force::zero(); n],
            tau: DVector::zeros(nv),
            ddq: DVector::zeros(nv),
            nle: DVector::zeros(nv),
            g: DVector::zeros(nv),
            mass_matrix: DMatrix::zeros(nv, nv),
            minv: DMatrix::zeros(nv, nv),
            jacobian: Matrix6xX::zeros(nv),
            com: Vector3::zeros(),
            com_jacobian: Matrix3xX::zeros(nv),
            centroidal_matrix: Matrix6xX::zeros(nv),
            centroidal_momentum: Force::zero(),
            subtree_mass: vec![0.0; n],
            subtree_com: vec![Vector3::zeros(); n],
            ddq_dq: DMatrix::zeros(nv, nv),
            ddq_dv: DMatrix::zeros(nv, nv),
            dtau_dq: DMatrix::zeros(nv, nv),
            dtau_dv: DMatrix::zeros(nv, nv),
            body_moments: model.inertias.iter().map(InertiaMoments::from_inertia).collect(),
            revolute_terms: model
                .joints
                .iter()
                .map(|j| match j.kind {
                    crate::model::JointKind::Revolute { axis } => {
                        let a = crate::spatial::skew(&axis);
                        (j.placement.rotation * a, j.placement.rotation * a * a)
                    }
                    _ => (Matrix3::zeros(), Matrix3::zeros()),
                })
                .collect(),
            c: vec![Motion::zero(); n],
            y_aba: vec![Matrix6::zeros(); n],
            p_a: vec![Force::zero(); n],
            u_col: vec![Vector6::zeros(); n],
            d_inv: vec![0.0; n],
            u_scalar: vec![0.0; n],
            y_crb: vec![InertiaMoments::zero(); n],
            o_y_crb: vec![InertiaMoments::zero(); n],
            o_y_body: vec![InertiaMoments::zero(); n],
            ov: vec![Motion::zero(); n],
            oa: vec![Motion::zero(); n],
            of: vec![Force::zero(); n],
            oh: vec![Force::zero(); n],
            do_y_top: vec![nalgebra::Vector3::zeros(); n],
            do_y_b: vec![Matrix3::zeros(); n],
            o_j: vec![Motion::zero(); n],
            dvdq: Matrix6xX::zeros(nv),
            dadq: Matrix6xX::zeros(nv),
            dadv: Matrix6xX::zeros(nv),
            dfdq: Matrix6xX::zeros(nv),
            dfdv: Matrix6xX::zeros(nv),
            dfda: Matrix6xX::zeros(nv),
            dytj: Matrix3xX::zeros(nv),
            tmp_nv: DVector::zeros(nv),
            w_ancestors: vec![Motion::zero(); n],
            w_dfda: vec![Force::zero(); n],
            w_dytj: vec![Vector3::zeros(); n],
            ltdl: DMatrix::zeros(nv, nv),
            linv: DMatrix::zeros(nv, nv),
            dof_chains,
            dof_chain_starts,
            minv_column: vec![0.0; nv],
            limb_layout: super::minverse_limbs::LimbLayout::detect(&model.dof_parent),
        }
    }
}

/// Each degree of freedom's branch to the root, itself first (`Data::dof_chains` and
/// `Data::dof_chain_starts`), from each one's parent (`usize::MAX` for the root).
pub(super) fn dof_chains(dof_parent: &[usize]) -> (Vec<usize>, Vec<usize>) {
    let nv = dof_parent.len();
    let (mut chains, mut starts) = (Vec::new(), vec![0]);
    for k in 0..nv {
        let mut j = k;
        while j < nv {
            chains.push(j);
            j = dof_parent[j];
        }
        starts.push(chains.len());
    }
    (chains, starts)
}
