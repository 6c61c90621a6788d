//! Composite-rigid-body algorithm: the joint-space inertia matrix `M(q)`.

use super::kinematics::local_placement;
use super::Data;
use crate::model::{JointKind, Model};
use crate::spatial::{Force, InertiaMoments};
use nalgebra::{DMatrix, DVector};

/// `S^T f` for a one-degree-of-freedom joint: `a . n` (revolute) or `a . f` (prismatic).
#[inline(always)]
fn subspace_dot(kind: &JointKind, f: &Force) -> f64 {
    match kind {
        JointKind::Revolute { axis } => axis.dot(&f.n),
        JointKind::Prismatic { axis } => axis.dot(&f.f),
        _ => 0.0,
    }
}

/// `IC S` for a one-degree-of-freedom joint, without the zero half of `S`:
/// revolute `S = (0, a)`: `(a x h, I_o a)`; prismatic `S = (a, 0)`: `(m a, h x a)`.
#[inline(always)]
fn composite_times_subspace(kind: &JointKind, ic: &InertiaMoments) -> Force {
    match kind {
        JointKind::Revolute { axis } => Force { f: axis.cross(&ic.first), n: ic.second * axis },
        JointKind::Prismatic { axis } => Force { f: axis * ic.mass, n: ic.first.cross(axis) },
        _ => Force::zero(),
    }
}

/// Joint-space inertia matrix (Featherstone 2008, Table 6.2), full and symmetric, into
/// `data.mass_matrix`:
///
/// ```text
/// IC_i = I_i + sum over children c of  iXc* IC_c cXi
/// F = IC_i S_i,  M_ii = S_i^T F;  up the tree: F = pXj* F,  M_ji = M_ij^T = S_j^T F
/// ```
///
/// Composite inertias are kept as mass moments about the joint origin, so lumping a child
/// into its parent is a transform and a sum.
pub fn crba<'d>(model: &Model, data: &'d mut Data, q: &DVector<f64>) -> &'d DMatrix<f64> {
    let n = model.njoints();
    let nv = model.nv;
    for i in 1..n {
        data.li_m_i[i] = local_placement(model, data, i, q);
        data.y_crb[i] = data.body_moments[i];
    }
    let m = data.mass_matrix.as_mut_slice(); // column-major: (r, c) at r + c * nv
    for i in (1..n).rev() {
        let j = &model.joints[i];
        let ic = data.y_crb[i];
        match j.kind {
            JointKind::FreeFlyer => {
                // S = I6 and the root has no parent: M_bb = IC (6x6).
                let y = ic.matrix();
                for c in 0..6 {
                    let col = (j.idx_v + c) * nv + j.idx_v;
                    m[col..col + 6].copy_from_slice(y.column(c).as_slice());
                }
            }
            JointKind::Universe => {}
            kind => {
                let k = j.idx_v;
                let mut f = composite_times_subspace(&kind, &ic);
                m[k + k * nv] = subspace_dot(&kind, &f);
                let mut jj = i;
                while model.joints[jj].parent > 0 {
                    f = data.li_m_i[jj].act_force(&f);
                    jj = model.joints[jj].parent;
                    let pj = &model.joints[jj];
                    match pj.kind {
                        JointKind::FreeFlyer => {
                            let fv = [f.f.x, f.f.y, f.f.z, f.n.x, f.n.y, f.n.z];
                            let col = k * nv + pj.idx_v;
                            m[col..col + 6].copy_from_slice(&fv);
                            for (r, x) in fv.iter().enumerate() {
                                m[k + (pj.idx_v + r) * nv] = *x;
                            }
                        }
                        pk => {
                            let x = subspace_dot(&pk, &f);
                            m[pj.idx_v + k * nv] = x;
                            m[k + pj.idx_v * nv] = x;
                        }
                    }
                }
            }
        }
        if j.parent > 0 {
            let lumped = ic.transformed(&data.li_m_i[i]);
            data.y_crb[j.parent] += lumped;
        }
    }
    &data.mass_matrix
}
