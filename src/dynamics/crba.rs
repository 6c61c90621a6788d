//! Composite-rigid-body algorithm: the joint-space inertia matrix `M(q)`.

use super::kinematics::local_placement;
use super::Data;
use crate::model::{JointKind, Model};
use crate::spatial::Force;
use nalgebra::{DMatrix, DVector};

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
        let li = local_placement(model, i, q);
        let p = model.joints[i].parent;
        data.o_m_i[i] = if p > 0 { &data.o_m_i[p] * &li } else { li };
        data.li_m_i[i] = li;
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
                    for r in 0..6 {
                        m[(j.idx_v + r) + (j.idx_v + c) * nv] = y[(r, c)];
                    }
                }
            }
            JointKind::Universe => {}
            kind => {
                let k = j.idx_v;
                let s = kind.subspace();
                let mut f: Force = ic.mul_motion(&s);
                m[k + k * nv] = s.dot(&f);
                let mut jj = i;
                while model.joints[jj].parent > 0 {
                    f = data.li_m_i[jj].act_force(&f);
                    jj = model.joints[jj].parent;
                    let pj = &model.joints[jj];
                    match pj.kind {
                        JointKind::FreeFlyer => {
                            let fv = f.to_vector();
                            for r in 0..6 {
                                m[(pj.idx_v + r) + k * nv] = fv[r];
                                m[k + (pj.idx_v + r) * nv] = fv[r];
                            }
                        }
                        pk => {
                            let x = pk.subspace().dot(&f);
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
