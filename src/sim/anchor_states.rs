//! The contact anchors as states of the step's linearization.
//!
//! [`StepDerivatives`] linearizes `(q, v) -> (q', v')` with the tangential-spring anchors
//! held (Neunert 2017 treats them as hidden states). Here the state is extended by the
//! anchors, three world coordinates per foot (`dx = [dq; dv; da_1 .. da_nf]`), with the
//! derivatives of [`crate::contact::anchor_derivatives`]:
//!
//! ```text
//! columns of a_f:  dv' = dt M^-1 J_f^T dF_f/da_f,   dq' = dt Jv dv'
//! rows of a_f':    da_f' = (da'/dp J_f + da'/dpdot dpdot_f/dq) dq + da'/dpdot J_f dv + da'/da da_f
//! ```
//!
//! (`J_f = d p_f / d dq`, the foot's world-frame point Jacobian; `dpdot_f / d v = J_f`.) A
//! foot with no anchor before the step has zero columns (the force does not depend on an
//! anchor it does not have); a foot off the ground after it has zero rows. With the anchors
//! in the state, moving a foot before it lands moves the anchor planted under it, which the
//! held-anchor linearization cannot see.

use crate::linalg::{copy_block, gemv};
use super::{ContactModelWorkspace, StepDerivatives};
use crate::contact::anchor_derivatives;
use nalgebra::{DMatrix, DVector, Vector3};

/// Anchor coordinates per foot in the extended state.
pub const ANCHOR_DIM: usize = 3;

/// Scratch for [`AnchorStepDerivatives::linearize`]; one per thread.
pub struct AnchorStepDerivatives {
    force_column: DVector<f64>,
    acceleration_column: DVector<f64>,
}

impl AnchorStepDerivatives {
    pub fn new(nv: usize) -> Self {
        Self { force_column: DVector::zeros(nv), acceleration_column: DVector::zeros(nv) }
    }

    /// After `step.step(ws, ..)` from anchors `anchors_before`, writes the extended
    /// linearization into `a` (`(2 nv + 3 nf)` square): `step.a` in its `(q, v)` block, the
    /// anchor rows and columns around it. `B` has no anchor rows (the anchor update reads
    /// the contact at the step's start, before the torques act).
    pub fn linearize(&mut self, step: &StepDerivatives, ws: &ContactModelWorkspace<'_>, anchors_before: &[Option<Vector3<f64>>], dt: f64, a: &mut DMatrix<f64>) {
        let model = ws.model;
        let nv = model.nv;
        let nx = 2 * nv;
        // Every entry is written below but the anchor columns of a foot without an anchor
        // and the anchor rows' blocks of the other feet: zero the anchor columns only (the
        // last columns, contiguous in column-major storage).
        let first_anchor_entry = nx * a.nrows();
        a.as_mut_slice()[first_anchor_entry..].fill(0.0);
        copy_block(a, (0, 0), &step.a);
        let minv = &ws.data.minv;
        for (f, foot) in ws.feet.iter().enumerate() {
            let d = anchor_derivatives(&ws.params, &foot.contact, &foot.velocity, &foot.normal, anchors_before[f].as_ref());
            let jp = &step.foot_dp_dq[f];
            let col = nx + ANCHOR_DIM * f;
            // Columns: the force's dependence on the anchor.
            for c in 0..ANCHOR_DIM {
                let df = d.force.column(c);
                if df.iter().all(|x| *x == 0.0) {
                    continue;
                }
                self.force_column.gemv_tr(1.0, jp, &df, 0.0);
                gemv(&mut self.acceleration_column, dt, minv, &self.force_column, 0.0);
                a.view_mut((nv, col + c), (nv, 1)).copy_from(&self.acceleration_column);
                gemv(&mut self.force_column, dt, &step.jv, &self.acceleration_column, 0.0);
                a.view_mut((0, col + c), (nv, 1)).copy_from(&self.force_column);
            }
            // Rows: the anchor after the step.
            let dpdot_dq = &step.foot_dpdot_dq[f];
            let mut rows_q = a.view_mut((col, 0), (ANCHOR_DIM, nv));
            rows_q.gemm(1.0, &d.next_d_position, jp, 0.0);
            rows_q.gemm(1.0, &d.next_d_velocity, dpdot_dq, 1.0);
            a.view_mut((col, nv), (ANCHOR_DIM, nv)).gemm(1.0, &d.next_d_velocity, jp, 0.0);
            a.view_mut((col, col), (ANCHOR_DIM, ANCHOR_DIM)).copy_from(&d.next_d_anchor);
        }
    }
}
