//! `M^-1` for a six-dof trunk carrying serial limbs of equal length (every quadruped in
//! `shared/robots/`: a free flyer and four three-dof legs), with the tree's shape known at
//! compile time.
//!
//! It is the tree-sparse `M = L^T D L` factorization and `M^-1 = L^-1 D^-1 L^-T` of
//! [`super::aba_derivatives`] (Featherstone 2008, Tables 6.3 and §6.5) written on the
//! shape's dense blocks instead of walking each degree of freedom's branch:
//!
//! ```text
//!       [ T    .    .  ]     T   trunk x trunk (6 x 6, lower triangle)
//!   M = [ B_1  L_1  .  ]     B_c limb c x trunk (N x 6)
//!       [ B_2  .    L_2]     L_c limb c x limb c (N x N, lower triangle); limbs do not couple
//! ```
//!
//! Every entry sees the same floating-point operations in the same order as the general
//! code (the tree's leaves first, the sums from a degree of freedom towards the root), so the
//! two give the same bits (tested); the terms the general code adds as zeros, where one
//! degree of freedom is not on the other's branch, are left out (adding `+-0` to a sum that
//! started at `+0` changes nothing: it is never `-0`).
//!
//! On the same shape, [`neg_minv_times_limb_sparse`] forms the ABA derivatives' `-M^-1 dtau`
//! without `dtau`'s zero blocks between two limbs.

use nalgebra::DMatrix;

/// Degrees of freedom in the trunk (a free flyer).
const TRUNK: usize = 6;

/// The shapes with a compiled path, `(limbs, dofs per limb)`: quadrupeds with three- and
/// four-dof legs, hexapods, bipeds with six-dof legs. Other trees take the general code.
pub(crate) const SHAPES: [(usize, usize); 4] = [(4, 3), (4, 4), (6, 3), (2, 6)];

/// Degrees of freedom of the largest shape in [`SHAPES`] (the stack arrays' length).
const MAX_NV: usize = {
    let (mut most, mut i) = (0, 0);
    while i < SHAPES.len() {
        let nv = TRUNK + SHAPES[i].0 * SHAPES[i].1;
        if nv > most {
            most = nv;
        }
        i += 1;
    }
    most
};

/// The shape [`invert`] handles: degrees of freedom `0..6` a chain (the trunk), then `count`
/// limbs of `len` degrees of freedom each, limb `c` at `6 + c len ..`, each a chain whose
/// first degree of freedom hangs from the trunk's last; `(count, len)` one of [`SHAPES`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct LimbLayout {
    pub count: usize,
    pub len: usize,
}

impl LimbLayout {
    /// The layout of a tree given by each degree of freedom's parent (`usize::MAX` for the
    /// root), or `None` if it is not a trunk with equal serial limbs of one of [`SHAPES`].
    pub fn detect(dof_parent: &[usize]) -> Option<Self> {
        let nv = dof_parent.len();
        if nv <= TRUNK || dof_parent[0] != usize::MAX || (1..TRUNK).any(|k| dof_parent[k] != k - 1) {
            return None;
        }
        let len = (TRUNK + 1..nv).find(|&k| dof_parent[k] == TRUNK - 1).unwrap_or(nv) - TRUNK;
        let count = (nv - TRUNK) / len;
        let chains = (TRUNK..nv).all(|k| dof_parent[k] == if (k - TRUNK) % len == 0 { TRUNK - 1 } else { k - 1 });
        (count * len == nv - TRUNK && chains && SHAPES.contains(&(count, len))).then_some(Self { count, len })
    }
}

/// `M^-1` (full, symmetric) of the `nv x nv` mass matrix `m` with [`LimbLayout`] `layout`,
/// into `out`; the same bits as the general tree-sparse factorization.
pub(crate) fn invert(layout: LimbLayout, m: &DMatrix<f64>, out: &mut DMatrix<f64>) {
    match (layout.count, layout.len) {
        (4, 3) => invert_shape::<4, 3>(m, out),
        (4, 4) => invert_shape::<4, 4>(m, out),
        (6, 3) => invert_shape::<6, 3>(m, out),
        (2, 6) => invert_shape::<2, 6>(m, out),
        shape => unreachable!("LimbLayout::detect admits only {SHAPES:?}, not {shape:?}"),
    }
}

/// `out = -M^-1 B` for an `nv x nv` matrix `B` whose blocks between two different limbs are
/// zero (`B[limb a, limb b] = 0` for `a != b`), as `d tau / dq` and `d tau / dv` of RNEA are
/// on such a tree (`d tau_i / d q_j = 0` unless one of `i`, `j` is on the other's branch:
/// Carpentier & Mansard 2018, §III): a limb's columns take only the trunk's rows and their
/// own limb's,
///
/// ```text
/// out[:, trunk]  = -M^-1 B[:, trunk]
/// out[:, limb c] = -M^-1[:, trunk] B[trunk, limb c] - M^-1[:, limb c] B[limb c, limb c]
/// ```
///
/// (on HyQ 6 x 18 + 12 x 9 of the 18 x 18 products per row, two thirds). `minv` is `M^-1`
/// (full); the columns are summed a few at a time in registers, each `M^-1` column loaded
/// once per block.
pub(crate) fn neg_minv_times_limb_sparse(layout: LimbLayout, minv: &DMatrix<f64>, b: &DMatrix<f64>, out: &mut DMatrix<f64>) {
    let nv = TRUNK + layout.count * layout.len;
    assert!(minv.shape() == (nv, nv) && b.shape() == (nv, nv) && out.shape() == (nv, nv));
    let (minv, b, out) = (minv.as_slice(), b.as_slice(), out.as_mut_slice());
    match (layout.count, layout.len) {
        (4, 3) => neg_minv_times_limb_sparse_shape::<4, 3, 18>(minv, b, out),
        (4, 4) => neg_minv_times_limb_sparse_shape::<4, 4, 22>(minv, b, out),
        (6, 3) => neg_minv_times_limb_sparse_shape::<6, 3, 24>(minv, b, out),
        (2, 6) => neg_minv_times_limb_sparse_shape::<2, 6, 18>(minv, b, out),
        shape => unreachable!("LimbLayout::detect admits only {SHAPES:?}, not {shape:?}"),
    }
}

/// [`neg_minv_times_limb_sparse`] for `COUNT` limbs of `N` dofs, `NV = 6 + COUNT N`.
#[inline(always)]
fn neg_minv_times_limb_sparse_shape<const COUNT: usize, const N: usize, const NV: usize>(minv: &[f64], b: &[f64], out: &mut [f64]) {
    assert!(NV == TRUNK + COUNT * N);
    for first in [0, TRUNK / 2] {
        neg_product_columns::<NV, { TRUNK / 2 }>(minv, b, out, first, 0..NV);
    }
    for c in 0..COUNT {
        let first = TRUNK + c * N;
        neg_product_columns::<NV, N>(minv, b, out, first, (0..TRUNK).chain(first..first + N));
    }
}

/// `out[:, j] = -sum_{k in rows} M^-1[:, k] B[k, j]` for the `W` columns `j` from `first`
/// (column-major `NV x NV` slices), summed side by side: `W` independent sums per row keep
/// the multiply-add unit busy where one column's sum would wait on its previous term.
#[inline(always)]
fn neg_product_columns<const NV: usize, const W: usize>(minv: &[f64], b: &[f64], out: &mut [f64], first: usize, rows: impl Iterator<Item = usize>) {
    let b = &b[first * NV..(first + W) * NV];
    let mut acc = [[0.0; NV]; W];
    for k in rows {
        let minv_k: &[f64; NV] = minv[k * NV..(k + 1) * NV].try_into().expect("NV rows");
        for (w, acc) in acc.iter_mut().enumerate() {
            let b_kj = b[k + w * NV];
            for (acc, m) in acc.iter_mut().zip(minv_k) {
                *acc = multiply_add(*m, b_kj, *acc);
            }
        }
    }
    for (out, acc) in out[first * NV..(first + W) * NV].chunks_exact_mut(NV).zip(&acc) {
        for (o, acc) in out.iter_mut().zip(acc) {
            *o = -acc;
        }
    }
}

/// `a b + c`, fused where the CPU the build targets has FMA (one rounding, one instruction)
/// and a product and a sum where it has not (`f64::mul_add` would be a libm call there).
#[inline(always)]
fn multiply_add(a: f64, b: f64, c: f64) -> f64 {
    if cfg!(target_feature = "fma") {
        a.mul_add(b, c)
    } else {
        a * b + c
    }
}

/// Trunk rows padded to a vector register's eight lanes (the padding stays zero; entries
/// above the diagonal hold whatever the full-row updates leave and are never read).
const LANES: usize = 8;
type TrunkRow = [f64; LANES];

/// A limb's blocks: `l[p][q]` (`q <= p`) and `b[p][t]` as in the module's picture; they hold
/// `M`, then the factor `L` (`D` on the diagonal), then `L^-1` (unit diagonal).
#[derive(Clone, Copy)]
struct Limb<const N: usize> {
    l: [[f64; N]; N],
    b: [TrunkRow; N],
}

/// `row -= a x` on all lanes.
#[inline(always)]
fn sub_scaled(row: &mut TrunkRow, a: f64, x: &TrunkRow) {
    for (r, x) in row.iter_mut().zip(x) {
        *r -= a * x;
    }
}

/// `acc += a x` on all lanes.
#[inline(always)]
fn add_scaled(acc: &mut TrunkRow, a: f64, x: &TrunkRow) {
    for (r, x) in acc.iter_mut().zip(x) {
        *r += a * x;
    }
}

/// [`invert`] for `COUNT` limbs of `N` degrees of freedom. (The loops keep the
/// factorization's indices, as in the equations.)
#[allow(clippy::needless_range_loop)]
#[inline(always)]
fn invert_shape<const COUNT: usize, const N: usize>(m: &DMatrix<f64>, out: &mut DMatrix<f64>) {
    let nv = TRUNK + COUNT * N;
    assert!(nv <= MAX_NV && m.shape() == (nv, nv) && out.shape() == (nv, nv));
    let start = |c: usize| TRUNK + c * N;
    let m = m.as_slice();
    let mut t = [[0.0; LANES]; TRUNK];
    let mut limbs = [Limb::<N> { l: [[0.0; N]; N], b: [[0.0; LANES]; N] }; COUNT];
    for (j, column) in m.chunks_exact(nv).take(TRUNK).enumerate() {
        for i in j..TRUNK {
            t[i][j] = column[i];
        }
        for (c, limb) in limbs.iter_mut().enumerate() {
            for p in 0..N {
                limb.b[p][j] = column[start(c) + p];
            }
        }
    }
    for (c, limb) in limbs.iter_mut().enumerate() {
        for q in 0..N {
            let column = &m[(start(c) + q) * nv..(start(c) + q + 1) * nv];
            for p in q..N {
                limb.l[p][q] = column[start(c) + p];
            }
        }
    }

    // M = L^T D L, from the leaves up (Featherstone 2008, Table 6.3). Eliminating dof k:
    //   a_i = H_ki / H_kk,  H_ij -= a_i H_kj  (i, j on k's branch, j towards the root),  H_ki = a_i
    // A limb's own blocks see only its own eliminations, so the limbs go side by side; the
    // trunk's block takes their updates afterwards, in the same order (the last limb's first).
    let mut h_trunk = [[[0.0; LANES]; N]; COUNT];
    for p in (0..N).rev() {
        for (limb, h_trunk) in limbs.iter_mut().zip(h_trunk.iter_mut()) {
            let d = limb.l[p][p];
            let mut a_limb = [0.0; N];
            for q in 0..p {
                a_limb[q] = limb.l[p][q] / d;
            }
            let mut a_trunk = [0.0; LANES];
            for (a, h) in a_trunk.iter_mut().zip(&limb.b[p]).take(TRUNK) {
                *a = h / d;
            }
            h_trunk[p] = limb.b[p];
            for i in 0..p {
                for j in 0..=i {
                    limb.l[i][j] -= a_limb[i] * limb.l[p][j];
                }
                sub_scaled(&mut limb.b[i], a_limb[i], &h_trunk[p]);
            }
            limb.l[p][..p].copy_from_slice(&a_limb[..p]);
            limb.b[p] = a_trunk;
        }
    }
    for (limb, h_trunk) in limbs.iter().zip(&h_trunk).rev() {
        for p in (0..N).rev() {
            for (i, row) in t.iter_mut().enumerate() {
                for j in 0..=i {
                    row[j] -= limb.b[p][i] * h_trunk[p][j];
                }
            }
        }
    }
    for k in (0..TRUNK).rev() {
        let d = t[k][k];
        let mut a = [0.0; TRUNK];
        for i in 0..k {
            a[i] = t[k][i] / d;
        }
        let h = t[k];
        for i in 0..k {
            for j in 0..=i {
                t[i][j] -= a[i] * h[j];
            }
        }
        t[k][..k].copy_from_slice(&a[..k]);
    }

    // D^-1
    let mut d_trunk = [0.0; TRUNK];
    for k in 0..TRUNK {
        d_trunk[k] = 1.0 / t[k][k];
    }
    let mut d_limbs = [[0.0; N]; COUNT];
    for (d, limb) in d_limbs.iter_mut().zip(limbs.iter()) {
        for p in 0..N {
            d[p] = 1.0 / limb.l[p][p];
        }
    }

    // L^-1, in place of L: L^-1[i, j] = -sum_{k from i's parent down to j} L[i, k] L^-1[k, j].
    // The trunk's is kept with zeros above the diagonal so the limbs' rows sum over all of
    // its columns at once (the extra terms are zeros added to a non-zero sum, or to +0).
    let mut t_inv = [[0.0; LANES]; TRUNK];
    for i in 0..TRUNK {
        t_inv[i][i] = 1.0;
        for j in 0..i {
            let mut acc = 0.0;
            for k in (j..i).rev() {
                acc += t[i][k] * t_inv[k][j];
            }
            t_inv[i][j] = -acc;
        }
    }
    let factors = limbs;
    for p in 0..N {
        for (limb, factor) in limbs.iter_mut().zip(&factors) {
            let (l, b) = (&factor.l, &factor.b);
            // the limb's columns (unit diagonal)
            for q in 0..p {
                let mut acc = 0.0;
                for k in (q..p).rev() {
                    acc += l[p][k] * limb.l[k][q];
                }
                limb.l[p][q] = -acc;
            }
            limb.l[p][p] = 1.0;
            // the trunk's columns: the branch runs through the limb, then the trunk
            let mut acc = [0.0; LANES];
            for k in (0..p).rev() {
                add_scaled(&mut acc, l[p][k], &limb.b[k]);
            }
            for k in (0..TRUNK).rev() {
                add_scaled(&mut acc, b[p][k], &t_inv[k]);
            }
            for (x, acc) in limb.b[p].iter_mut().zip(&acc) {
                *x = -acc;
            }
        }
    }

    // M^-1[a, b] = sum_{k on both branches, from b towards the root} (L^-1[a, k] L^-1[b, k]) D^-1_k,
    // a whole column b at a time from the trunk's columns of L^-1, `rows[k][a] = L^-1[a, k]`:
    // an entry above the diagonal gets the terms of its mirror image, after zeros.
    let mut rows = [[0.0; MAX_NV]; TRUNK];
    for (k, row) in rows.iter_mut().enumerate() {
        for (a, t_inv_a) in t_inv.iter().enumerate() {
            row[a] = t_inv_a[k];
        }
        for (c, limb) in limbs.iter().enumerate() {
            for p in 0..N {
                row[start(c) + p] = limb.b[p][k];
            }
        }
    }
    let out = out.as_mut_slice();
    let add_trunk_terms = |column: &mut [f64; MAX_NV], l_b: &TrunkRow, last: usize| {
        for k in (0..=last).rev() {
            let (l_bk, d_k) = (l_b[k], d_trunk[k]);
            for (acc, l_ak) in column[..nv].iter_mut().zip(&rows[k][..nv]) {
                *acc += l_ak * l_bk * d_k;
            }
        }
    };
    for (b, l_b) in t_inv.iter().enumerate() {
        let mut column = [0.0; MAX_NV];
        add_trunk_terms(&mut column, l_b, b);
        out[b * nv..(b + 1) * nv].copy_from_slice(&column[..nv]);
    }
    // a limb's columns side by side (independent sums)
    for (c, limb) in limbs.iter().enumerate() {
        let mut columns = [[0.0; MAX_NV]; N];
        for (q, column) in columns.iter_mut().enumerate() {
            for p in 0..N {
                let mut acc = 0.0;
                for k in (0..=q).rev() {
                    acc += limb.l[p][k] * limb.l[q][k] * d_limbs[c][k];
                }
                column[start(c) + p] = acc;
            }
        }
        for k in (0..TRUNK).rev() {
            for (column, l_b) in columns.iter_mut().zip(&limb.b) {
                let (l_bk, d_k) = (l_b[k], d_trunk[k]);
                for (acc, l_ak) in column[..nv].iter_mut().zip(&rows[k][..nv]) {
                    *acc += l_ak * l_bk * d_k;
                }
            }
        }
        for (q, column) in columns.iter().enumerate() {
            let b = start(c) + q;
            out[b * nv..(b + 1) * nv].copy_from_slice(&column[..nv]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dynamics::aba_derivatives::{ltdl_in_place, minv_from_ltdl};
    use crate::dynamics::data::dof_chains;
    use crate::dynamics::uniform_from;

    const R: usize = usize::MAX;

    /// Each degree of freedom's parent for a trunk and `count` limbs of `len`.
    fn limbs(count: usize, len: usize) -> Vec<usize> {
        let mut parents = vec![R, 0, 1, 2, 3, 4];
        for _ in 0..count {
            for p in 0..len {
                let k = parents.len();
                parents.push(if p == 0 { TRUNK - 1 } else { k - 1 });
            }
        }
        parents
    }

    #[test]
    fn detects_the_compiled_shapes_only() {
        for (count, len) in SHAPES {
            assert!(TRUNK + count * len <= MAX_NV);
            assert_eq!(LimbLayout::detect(&limbs(count, len)), Some(LimbLayout { count, len }));
        }
        assert_eq!(LimbLayout::detect(&limbs(2, 2)), None, "a shape without a compiled path");
        assert_eq!(LimbLayout::detect(&[R, 0, 1, 2]), None, "no six-dof trunk");
        assert_eq!(LimbLayout::detect(&[R, 0, 1, 2, 3, 4, 5, 6, 6, 5, 9, 10, 5, 12, 13, 5, 15, 16]), None, "a limb that branches");
        let mut unequal = limbs(4, 3);
        unequal[8] = 5;
        assert_eq!(LimbLayout::detect(&unequal), None, "limbs of unequal length");
        let mut rooted = limbs(4, 3);
        rooted[6] = R;
        assert_eq!(LimbLayout::detect(&rooted), None, "a limb not on the trunk");
    }

    /// The product on the limbs' zero blocks against a dense one, every compiled shape,
    /// random `M^-1` and random `B` with zero blocks between limbs.
    #[test]
    fn limb_sparse_product_matches_the_dense_product() {
        let mut uniform_01 = uniform_from(17);
        let mut uniform = move || uniform_01() - 0.5;
        for (count, len) in SHAPES {
            let nv = TRUNK + count * len;
            let limb = |k: usize| (k >= TRUNK).then(|| (k - TRUNK) / len);
            let layout = LimbLayout { count, len };
            let minv = DMatrix::from_fn(nv, nv, |_, _| uniform());
            let b = DMatrix::from_fn(nv, nv, |i, j| match (limb(i), limb(j)) {
                (Some(a), Some(c)) if a != c => 0.0,
                _ => uniform(),
            });
            let mut out = DMatrix::from_element(nv, nv, f64::NAN);
            neg_minv_times_limb_sparse(layout, &minv, &b, &mut out);
            let dense = -(&minv * &b);
            let err = (&out - &dense).amax();
            assert!(err <= 1e-14 * nv as f64, "{count} x {len}: off by {err:.2e}");
        }
    }

    /// On random mass matrices with each shape's sparsity (`M = U^T E U`, `U` unit upper
    /// triangular with the tree's branch pattern), the same bits as the general code.
    #[test]
    fn every_shape_matches_the_general_factorization_to_the_bit() {
        let mut uniform = uniform_from(7);
        for (count, len) in SHAPES {
            let parents = limbs(count, len);
            let nv = parents.len();
            let layout = LimbLayout::detect(&parents).unwrap();
            let (chains, starts) = dof_chains(&parents);
            for _ in 0..10 {
                // u[(k, i)] for i on k's branch; M[(i, j)] = sum_k u[(k, i)] e_k u[(k, j)]
                let mut u = DMatrix::<f64>::zeros(nv, nv);
                for k in 0..nv {
                    for &i in &chains[starts[k]..starts[k + 1]] {
                        u[(k, i)] = if i == k { 1.0 } else { 2.0 * uniform() - 1.0 };
                    }
                }
                let e = nalgebra::DVector::from_fn(nv, |_, _| 0.1 + 10.0 * uniform());
                let m = u.transpose() * DMatrix::from_diagonal(&e) * &u;
                let mut fast = DMatrix::zeros(nv, nv);
                invert(layout, &m, &mut fast);
                let mut h = m.clone();
                ltdl_in_place(h.as_mut_slice(), nv, (&chains, &starts));
                let (mut linv, mut d_inv, mut column, mut general) = (DMatrix::zeros(nv, nv), vec![0.0; nv], vec![0.0; nv], DMatrix::zeros(nv, nv));
                minv_from_ltdl(h.as_slice(), nv, (&chains, &starts), linv.as_mut_slice(), &mut d_inv, &mut column, general.as_mut_slice());
                for (k, (x, y)) in fast.iter().zip(general.iter()).enumerate() {
                    assert_eq!(x.to_bits(), y.to_bits(), "{count} x {len}: entry {k}: {x:e} against {y:e}");
                }
                assert!((&fast * &m - DMatrix::identity(nv, nv)).amax() < 1e-8, "{count} x {len}: not an inverse");
            }
        }
    }
}
