//! `A_i X` for one substep's linearization on its structure, for the chain rule over a
//! knot's substeps (`A <- A_i A`, `B <- A_i B + B_i`, [`crate::ocp::KnotLinearization`]).
//!
//! The semi-implicit step of [`StepDerivatives`] (with the anchor rows of
//! [`super::AnchorStepDerivatives`]) has, with `V` the velocity rows of `A_i` (`nv x n`):
//!
//! ```text
//! dv'  = V dx                                  V = [h a_q, I + h a_v, h a_anchor]
//! dq'  = Jq dq + h Jv dv'                      so  (A_i X)_q = Jq X_q + h Jv (V X)
//! da'_f = R_f dx   per foot: zero (off the ground), da_f (sticking: R_f = [0 0 I]), or dense
//! ```
//!
//! `Jq`, `Jv` are the identity but on a free flyer's `6 x 6` block
//! ([`crate::dynamics::integrate_jacobians`]). So `A_i X` costs one `nv x n x m` product
//! (`V X`) and `O(n m)` besides, against the dense `n x n x m`: at HyQ's `n = 48`,
//! `nv = 18` with the anchors, 2.7x fewer multiplications. The result equals the dense
//! product up to round-off.
//!
//! A knot's `A = A_i^k` ([`SubstepProduct::power`]) needs only the velocity rows of each
//! power, `V A_i^j`, new: they follow from the last ones by a product on the right,
//! `V A_i^j = (V A_i^(j-1)) A_i`, and a product with `A_i` on the right is `nv x nv x n`
//! (`A_i`'s rows are `V`'s but for identities and the free flyers' blocks):
//!
//! ```text
//! W A_i = [W_q Jq, 0, 0] + (W_v + h W_q Jv) V + W_a R       (W = [W_q W_v W_a], nv x n)
//! ```
//!
//! so a power costs `nv x nv x n` a substep instead of `nv x n x n` (at HyQ's 48 states
//! 2.7x fewer again).

use crate::linalg::gemm;
use super::{StepDerivatives, ANCHOR_DIM};
use crate::model::{JointKind, Model};
use crate::spatial::Matrix6;
use nalgebra::{DMatrix, DMatrixViewMut, Vector6};

/// How a foot's anchor rows of `A_i` act.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum AnchorRows {
    /// All zero: the foot is off the ground after the substep.
    Zero,
    /// `[0 0 I]`: the anchor is held (a sticking foot).
    Held,
    /// Anything else (touch-down, slip): multiplied densely.
    Dense,
}

/// What [`Self::mul`] needs of one substep's `A_i` ([`Self::capture`]), and its scratch;
/// one per thread.
pub struct SubstepProduct {
    nv: usize,
    /// `h`, the substep's length.
    h: f64,
    /// Per free flyer: its first velocity index, its `Jq` block and `h Jv` block.
    free_flyers: Vec<(usize, Matrix6, Matrix6)>,
    /// `V`, the velocity rows of `A_i` (`nv x n`).
    velocity_rows: DMatrix<f64>,
    anchor_rows: Vec<AnchorRows>,
    /// The anchor rows of `A_i` (`3 nf x n`), kept for the [`AnchorRows::Dense`] feet only.
    dense_anchor_rows: DMatrix<f64>,
    /// `V X`, `nv x m` in the first `nv m` entries.
    vx: Vec<f64>,
    /// [`Self::power`]'s scratch: `W = V A_i^j` and the next one (`nv x n`), `W_v + h W_q Jv`
    /// (`nv x nv`).
    powers_v: DMatrix<f64>,
    powers_v_next: DMatrix<f64>,
    /// The configuration rows of `A_i^j` and the next power's (`nv x n`), without dense
    /// anchor rows.
    powers_q: DMatrix<f64>,
    powers_q_next: DMatrix<f64>,
    right_factor: DMatrix<f64>,
    /// The configuration columns outside every free flyer's block (where `Jq`, `Jv` are
    /// the identity).
    plain_columns: Vec<usize>,
}

impl SubstepProduct {
    /// For `model`'s steps with `feet` anchor blocks (0 without anchor states), the state
    /// `n = 2 nv + 3 feet`, and products with up to `n` columns.
    pub fn new(model: &Model, feet: usize) -> Self {
        let (nv, n) = (model.nv, 2 * model.nv + ANCHOR_DIM * feet);
        let flyers = model.joints.iter().filter(|j| j.kind == JointKind::FreeFlyer).map(|j| j.idx_v).collect::<Vec<_>>();
        let plain_columns = (0..nv).filter(|c| !flyers.iter().any(|iv| (*iv..iv + 6).contains(c))).collect();
        let free_flyers = model.joints.iter().filter(|j| j.kind == JointKind::FreeFlyer).map(|j| (j.idx_v, Matrix6::identity(), Matrix6::identity())).collect();
        Self {
            nv,
            h: 0.0,
            free_flyers,
            velocity_rows: DMatrix::zeros(nv, n),
            anchor_rows: vec![AnchorRows::Dense; feet],
            dense_anchor_rows: DMatrix::zeros(ANCHOR_DIM * feet, n),
            vx: vec![0.0; nv * n],
            powers_v: DMatrix::zeros(nv, n),
            powers_v_next: DMatrix::zeros(nv, n),
            powers_q: DMatrix::zeros(nv, n),
            powers_q_next: DMatrix::zeros(nv, n),
            right_factor: DMatrix::zeros(nv, nv),
            plain_columns,
        }
    }

    /// Keeps what [`Self::mul`] needs of `a_i`, the linearization of the substep of length
    /// `h` that `step` took last (its `Jq`, `Jv`), with `a_i`'s anchor rows (if any) as
    /// [`super::AnchorStepDerivatives::linearize`] wrote them.
    pub fn capture(&mut self, step: &StepDerivatives, a_i: &DMatrix<f64>, h: f64) {
        let nv = self.nv;
        self.h = h;
        for (iv, jq, h_jv) in &mut self.free_flyers {
            jq.copy_from(&step.jq.fixed_view::<6, 6>(*iv, *iv));
            h_jv.copy_from(&step.jv.fixed_view::<6, 6>(*iv, *iv));
            *h_jv *= h;
        }
        self.velocity_rows.copy_from(&a_i.rows(nv, nv));
        let n = a_i.ncols();
        debug_assert_eq!(n, self.velocity_rows.ncols(), "A_i's size is the state's of SubstepProduct::new");
        for (f, kind) in self.anchor_rows.iter_mut().enumerate() {
            let r0 = 2 * self.nv + ANCHOR_DIM * f;
            let rows = a_i.rows(r0, ANCHOR_DIM);
            let (mut zero, mut held) = (true, true);
            for c in 0..n {
                for r in 0..ANCHOR_DIM {
                    let value = rows[(r, c)];
                    zero &= value == 0.0;
                    held &= value == if c == r0 + r { 1.0 } else { 0.0 };
                }
            }
            *kind = if zero {
                AnchorRows::Zero
            } else if held {
                AnchorRows::Held
            } else {
                self.dense_anchor_rows.rows_mut(ANCHOR_DIM * f, ANCHOR_DIM).copy_from(&rows);
                AnchorRows::Dense
            };
        }
    }

    /// `out = A_i X` for the `a_i` of the last [`Self::capture`] (`X` and `out` `n x m`,
    /// `m <= n`).
    pub fn mul(&mut self, x: &DMatrix<f64>, out: &mut DMatrix<f64>) {
        let (nv, m) = (self.nv, x.ncols());
        // V X, the velocity rows: the one product of the size of the state.
        gemm(DMatrixViewMut::from_slice(&mut self.vx[..nv * m], nv, m), 1.0, &self.velocity_rows, x, 0.0);
        self.assemble(x, &self.vx[..nv * m], out);
    }

    /// `a <- A_i^k` for `a = A_i` of the last [`Self::capture`] (`k >= 1`; `scratch` of
    /// `a`'s shape), by the velocity rows' recursion of the module docs: each power
    /// `A_i^(j+1) = A_i A_i^j` has the velocity rows `W_j = V A_i^j = W_(j-1) A_i`, the
    /// configuration rows `Jq (A_i^j)_q + h Jv W_j` and the anchor rows `R A_i^j`. Equals
    /// `k - 1` products [`Self::mul`] up to round-off.
    ///
    /// Without a foot's dense anchor rows only the last power is needed whole: of the others,
    /// the configuration rows are kept apart (`nv x n`, the velocity rows are already), and
    /// `a`'s anchor rows are already the last power's (a held anchor's rows of every power are
    /// `A_i`'s; a forgotten one's, zero, are written again), so `a` is written once, at the
    /// end. The same operations on every entry as through the whole powers.
    pub fn power(&mut self, k: usize, a: &mut DMatrix<f64>, scratch: &mut DMatrix<f64>) {
        let (nv, n) = (self.nv, a.nrows());
        let whole_powers = self.anchor_rows.contains(&AnchorRows::Dense);
        self.powers_v.copy_from(&self.velocity_rows);
        if !whole_powers {
            self.powers_q.copy_from(&a.rows(0, nv));
        }
        for _ in 1..k {
            self.right_mul_velocity_rows();
            std::mem::swap(&mut self.powers_v, &mut self.powers_v_next);
            if whole_powers {
                self.assemble(a, self.powers_v.as_slice(), scratch);
                std::mem::swap(a, scratch);
            } else {
                // Out of `self` for the call (an empty matrix left in its place: no allocation).
                let mut next = std::mem::take(&mut self.powers_q_next);
                self.configuration_rows(self.powers_q.as_slice(), nv, self.powers_v.as_slice(), next.as_mut_slice(), nv);
                self.powers_q_next = std::mem::replace(&mut self.powers_q, next);
            }
        }
        if whole_powers {
            return;
        }
        for (c, ac) in a.as_mut_slice().chunks_exact_mut(n).enumerate() {
            ac[..nv].copy_from_slice(&self.powers_q.as_slice()[c * nv..(c + 1) * nv]);
            ac[nv..2 * nv].copy_from_slice(&self.powers_v.as_slice()[c * nv..(c + 1) * nv]);
            // A forgotten anchor's rows as `assemble` writes them (`A_i`'s may hold -0).
            for (f, kind) in self.anchor_rows.iter().enumerate() {
                if *kind == AnchorRows::Zero {
                    let r0 = 2 * nv + ANCHOR_DIM * f;
                    ac[r0..r0 + ANCHOR_DIM].fill(0.0);
                }
            }
        }
    }

    /// The configuration rows of `A_i X`, `dq' = Jq X_q + h Jv (V X)` (the identity on the
    /// joints, the free flyers' blocks over it), column by column: `X`'s column `c` starts at
    /// `c ldx` in `x`, `out`'s at `c ldo`, `V X` in `vx` (`nv x m`).
    fn configuration_rows(&self, x: &[f64], ldx: usize, vx: &[f64], out: &mut [f64], ldo: usize) {
        let (nv, h) = (self.nv, self.h);
        for (c, vc) in vx.chunks_exact(nv).enumerate() {
            let (xc, oc) = (&x[c * ldx..c * ldx + nv], &mut out[c * ldo..c * ldo + nv]);
            for ((o, xi), vi) in oc.iter_mut().zip(xc).zip(vc) {
                *o = xi + h * vi;
            }
            for (iv, jq, h_jv) in &self.free_flyers {
                let block = jq * Vector6::from_column_slice(&xc[*iv..iv + 6]) + h_jv * Vector6::from_column_slice(&vc[*iv..iv + 6]);
                oc[*iv..iv + 6].copy_from_slice(block.as_slice());
            }
        }
    }

    /// `out = A_i X` from `X` and its velocity rows `V X` (`vx`, `nv x m` column-major).
    /// Column by column (column-major): dq' = Jq X_q + h Jv (V X) (the identity on the
    /// joints, the free flyers' blocks over it), dv' = V X, the held anchors copied, the
    /// forgotten ones zero, the others `R_f X`.
    fn assemble(&self, x: &DMatrix<f64>, vx: &[f64], out: &mut DMatrix<f64>) {
        let (nv, n) = (self.nv, x.nrows());
        let m = x.ncols();
        let xs = x.as_slice();
        self.configuration_rows(xs, n, &vx[..nv * m], out.as_mut_slice(), n);
        for (c, oc) in out.as_mut_slice().chunks_exact_mut(n).enumerate() {
            let (xc, vc) = (&xs[c * n..(c + 1) * n], &vx[c * nv..(c + 1) * nv]);
            oc[nv..2 * nv].copy_from_slice(vc);
            for (f, kind) in self.anchor_rows.iter().enumerate() {
                let r0 = 2 * nv + ANCHOR_DIM * f;
                match kind {
                    AnchorRows::Zero => oc[r0..r0 + ANCHOR_DIM].fill(0.0),
                    AnchorRows::Held => oc[r0..r0 + ANCHOR_DIM].copy_from_slice(&xc[r0..r0 + ANCHOR_DIM]),
                    AnchorRows::Dense => {}
                }
            }
        }
        for (f, kind) in self.anchor_rows.iter().enumerate() {
            if *kind == AnchorRows::Dense {
                let r0 = 2 * nv + ANCHOR_DIM * f;
                out.rows_mut(r0, ANCHOR_DIM).gemm(1.0, &self.dense_anchor_rows.rows(ANCHOR_DIM * f, ANCHOR_DIM), x, 0.0);
            }
        }
    }

    /// `powers_v_next = W A_i` for `W` in `powers_v` (module docs):
    /// `[W_q Jq, 0, 0] + (W_v + h W_q Jv) V + W_a R`.
    fn right_mul_velocity_rows(&mut self) {
        let (nv, h) = (self.nv, self.h);
        let w = &self.powers_v;
        // W_v + h W_q Jv (Jv the identity but on the free flyers' blocks).
        self.right_factor.copy_from(&w.columns(nv, nv));
        for (iv, _, h_jv) in &self.free_flyers {
            gemm(self.right_factor.columns_mut(*iv, 6), 1.0, w.columns(*iv, 6), h_jv, 1.0);
        }
        for &c in &self.plain_columns {
            self.right_factor.column_mut(c).axpy(h, &w.column(c), 1.0);
        }
        let out = &mut self.powers_v_next;
        gemm(&mut *out, 1.0, &self.right_factor, &self.velocity_rows, 0.0);
        // + W_q Jq on the configuration columns.
        for &c in &self.plain_columns {
            out.column_mut(c).axpy(1.0, &w.column(c), 1.0);
        }
        for (iv, jq, _) in &self.free_flyers {
            gemm(out.columns_mut(*iv, 6), 1.0, w.columns(*iv, 6), jq, 1.0);
        }
        // + W_a R: a held anchor's rows pass it through, a forgotten one's are zero.
        for (f, kind) in self.anchor_rows.iter().enumerate() {
            let r0 = 2 * nv + ANCHOR_DIM * f;
            match kind {
                AnchorRows::Zero => {}
                AnchorRows::Held => {
                    let mut block = out.columns_mut(r0, ANCHOR_DIM);
                    block += &w.columns(r0, ANCHOR_DIM);
                }
                AnchorRows::Dense => out.gemm(1.0, &w.columns(r0, ANCHOR_DIM), &self.dense_anchor_rows.rows(ANCHOR_DIM * f, ANCHOR_DIM), 1.0),
            }
        }
    }
}
