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
pub fn crba<'d>(model: &Model, data: &'d mut Data, q: &DVector<f64>) -> &'d DMatrix<f64> {
    let n = model.njoints();
    for i in 1..n {
        let li = local_placement(model, i, q);
        let p = model.joints[i].parent;
        data.o_m_i[i] = if p > 0 { &data.o_m_i[p] * &li } else { li };
        data.li_m_i[i] = li;
        data.y_crb[i] = model.inertias[i];
    }
    let m = &mut data.mass_matrix;
    for i in (1..n).rev() {
        let j = &model.joints[i];
        let ic = data.y_crb[i];
        match j.kind {
            JointKind::FreeFlyer => {
                // S = I6 and the root has no parent: M_bb = IC (6x6).
                let y = ic.matrix();
                m.view_mut((j.idx_v, j.idx_v), (6, 6)).copy_from(&y);
            }
            JointKind::Universe => {}
            kind => {
                let k = j.idx_v;
                let s = kind.subspace();
                let mut f: Force = ic.mul_motion(&s);
                m[(k, k)] = s.dot(&f);
                let mut jj = i;
                while model.joints[jj].parent > 0 {
                    f = data.li_m_i[jj].act_force(&f);
                    jj = model.joints[jj].parent;
                    let pj = &model.joints[jj];
                    match pj.kind {
                        JointKind::FreeFlyer => {
                            let fv = f.to_vector();
                            for r in 0..6 {
                                m[(pj.idx_v + r, k)] = fv[r];
                                m[(k, pj.idx_v + r)] = fv[r];
                            }
                        }
                        pk => {
                            let x = pk.subspace().dot(&f);
                            m[(pj.idx_v, k)] = x;
                            m[(k, pj.idx_v)] = x;
                        }
                    }
                }
            }
        }
        if j.parent > 0 {
            let lumped = data.y_crb[j.parent] + ic.transformed(&data.li_m_i[i]);
            data.y_crb[j.parent] = lumped;
        }
    }
    &data.mass_matrix
}
