//! Analytic derivatives of inverse dynamics (Carpentier & Mansard 2018, "Analytical
//! derivatives of rigid body dynamics algorithms", RSS, Alg. 1 and §III).
//!
//! Everything is expressed in the world frame ("o" quantities), where the derivative of a
//! joint's Jacobian column with respect to an ancestor's motion is a plain cross product
//! (`d J_j / d q_k = J_k x J_j` for `k` ancestor of `j`). The derivatives are taken in the
//! tangent space of the configuration manifold: `d/dq` means `d/d delta` at `delta = 0` with
//! `q (+) delta`, the base perturbed by a right (local) SE(3) increment, as Pinocchio.

use super::kinematics::{joint_motion, local_placement};
use super::Data;
use crate::model::{JointKind, Model};
use crate::spatial::{skew, Force, InertiaMoments, Matrix3, Motion, Vector3, SE3};
use nalgebra::{DVector, Matrix6xX, Vector6};

/// The inertia variation of Carpentier & Mansard 2018 (eq. (14)-(15)) for a world inertia
/// `Y = [m I, -[h]x; [h]x, I_o]` moving with twist `(v, w)` and momentum `(h_f, h_n) = Y (v, w)`:
///
/// `dY = v x* Y - Y v x + [m -> m x* (h_f, h_n)]`.
///
/// Written out, the commutator `[w]x[h]x - [h]x[w]x = [w x h]x` collapses it to
/// `dY = [[0, -2 [h_f]x], [0, B]]` with `B = [w]x I_o - I_o [w]x - [v]x [h]x - [h]x [v]x - [h_n]x`,
/// so only the vector `t = -2 h_f` and the block `B` are kept.
#[inline]
fn inertia_variation(y: &InertiaMoments, v: &Motion, momentum: &Force) -> (Vector3<f64>, Matrix3<f64>) {
    let w = skew(&v.w);
    let vx = skew(&v.v);
    let hx = skew(&y.first);
    let b = w * y.second - y.second * w - vx * hx - hx * vx - skew(&momentum.n);
    (momentum.f * -2.0, b)
}

#[inline]
fn col(m: &Matrix6xX<f64>, k: usize) -> Motion {
    Motion::from_slice(&m.as_slice()[6 * k..6 * k + 6])
}
#[inline]
fn set_col(m: &mut Matrix6xX<f64>, k: usize, x: &Motion) {
    let s = &mut m.as_mut_slice()[6 * k..6 * k + 6];
    s[0] = x.v.x;
    s[1] = x.v.y;
    s[2] = x.v.z;
    s[3] = x.w.x;
    s[4] = x.w.y;
    s[5] = x.w.z;
}
#[inline]
fn set_col_f(m: &mut Matrix6xX<f64>, k: usize, x: &Force) {
    set_col(m, k, &Motion::new(x.f, x.n));
}
#[inline(always)]
fn col6(s: &[f64], k: usize) -> [f64; 6] {
    s[6 * k..6 * k + 6].try_into().expect("6 rows")
}
#[inline(always)]
fn col3(s: &[f64], k: usize) -> [f64; 3] {
    s[3 * k..3 * k + 3].try_into().expect("3 rows")
}
#[inline(always)]
fn dot6(a: &[f64; 6], b: &[f64; 6]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3] + a[4] * b[4] + a[5] * b[5]
}
#[inline(always)]
fn dot3(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The backward pass's two blocks for joint dofs `iv..iv + nvj`, subtree columns up to
/// `sub_end`: its rows and its columns in the strict subtree's rows (see
/// [`compute_rnea_derivatives`]).
#[inline(always)]
#[allow(clippy::type_complexity)]
fn joint_rows_and_columns(
    nv: usize,
    (iv, nvj): (usize, usize),
    sub_end: usize,
    (js, dfda, dytj, dfdq, dfdv): (&[f64], &[f64], &[f64], &[f64], &[f64]),
    (dvdq_s, dadq_s, dadv_s): (&[f64], &[f64], &[f64]),
    (mm, dq, dv): (&mut [f64], &mut [f64], &mut [f64]),
) {
    // Rows of the joint, columns of its subtree: M, dtau/dq, dtau/dv = J_k^T (dF/da, dF/dq, dF/dv)_c
    for c in iv..sub_end {
        let (fa, fq, fv) = (col6(dfda, c), col6(dfdq, c), col6(dfdv, c));
        for k in iv..iv + nvj {
            let jc = col6(js, k);
            mm[k + c * nv] = dot6(&jc, &fa);
            dq[k + c * nv] = dot6(&jc, &fq);
            dv[k + c * nv] = dot6(&jc, &fv);
        }
    }
    // Rows of the strict subtree, columns of the joint:
    //   dtau/dq[r, k] = (dF/da)_r . dA/dq_k + (dY^T J)_r . dV/dq_k   ((dY^T J)_r is angular only)
    for k in iv..iv + nvj {
        let (jc, dvdq, dadq, dadv) = (col6(js, k), col6(dvdq_s, k), col6(dadq_s, k), col6(dadv_s, k));
        let (dvdq_w, jc_w) = ([dvdq[3], dvdq[4], dvdq[5]], [jc[3], jc[4], jc[5]]);
        for r in iv + nvj..sub_end {
            let (fa, yt) = (col6(dfda, r), col3(dytj, r));
            dq[r + k * nv] = dot6(&fa, &dadq) + dot3(&yt, &dvdq_w);
            dv[r + k * nv] = dot6(&fa, &dadv) + dot3(&yt, &jc_w);
        }
    }
}

/// Degrees of freedom of a free flyer: its six rows are summed side by side.
const FREE_FLYER_DOFS: usize = 6;

/// Six values, one per degree of freedom of a six-dof joint, padded to a vector register's
/// eight lanes (the padding is never stored).
type SixLanes = [f64; 8];

/// Lane `k`: `sum_e a[e][k] b[e]` summed from `e = 0` up, each product then a sum: the
/// operations of [`dot6`] (resp. [`dot3`] with `E = 3`) in their order, for six pairs at once,
/// so the same bits.
#[inline(always)]
fn lanes_dot<const E: usize>(a: &[SixLanes; E], b: &[f64; E]) -> SixLanes {
    let mut acc = [0.0; 8];
    for (acc, a) in acc.iter_mut().zip(&a[0]) {
        *acc = a * b[0];
    }
    for (a, b) in a.iter().zip(b).skip(1) {
        for (acc, a) in acc.iter_mut().zip(a) {
            *acc += a * b;
        }
    }
    acc
}

/// Of the six columns `x_k`, `k = first..first + 6`, of a column-major slice with `rows` rows:
/// entry `offset + e` of every column in the lanes of `out[e]`, `e < E`.
#[inline(always)]
fn transpose_six<const E: usize>(x: &[f64], first: usize, rows: usize, offset: usize) -> [SixLanes; E] {
    let mut out = [[0.0; 8]; E];
    for k in 0..FREE_FLYER_DOFS {
        for (e, out) in out.iter_mut().enumerate() {
            out[k] = x[rows * (first + k) + offset + e];
        }
    }
    out
}

/// The backward pass's two blocks for a six-dof joint (the free flyer at the root) at
/// degrees of freedom `iv..iv + 6`, subtree columns up to `sub_end`: its rows
/// (`J_k^T (dF/da, dF/dq, dF/dv)_c`) and its columns in the strict subtree's rows
/// (`(dF/da)_r . dA/dq_k + (dY^T J)_r . dV/dq_k`, likewise with `dA/dv`, `J`), with its six
/// degrees of freedom in the lanes of one sum: the root's block is the largest of the pass
/// (18 x 6 of HyQ's entries per matrix) and the per-entry sums are the scalar loop's.
#[inline(always)]
#[allow(clippy::type_complexity)]
fn free_flyer_rows_and_columns(
    nv: usize,
    iv: usize,
    sub_end: usize,
    (js, dfda, dytj, dfdq, dfdv): (&[f64], &[f64], &[f64], &[f64], &[f64]),
    (dvdq_s, dadq_s, dadv_s): (&[f64], &[f64], &[f64]),
    (mm, dq, dv): (&mut [f64], &mut [f64], &mut [f64]),
) {
    let n = FREE_FLYER_DOFS;
    let jt = transpose_six::<6>(js, iv, 6, 0);
    for c in iv..sub_end {
        let rows = iv + c * nv..iv + c * nv + n;
        mm[rows.clone()].copy_from_slice(&lanes_dot(&jt, &col6(dfda, c))[..n]);
        dq[rows.clone()].copy_from_slice(&lanes_dot(&jt, &col6(dfdq, c))[..n]);
        dv[rows].copy_from_slice(&lanes_dot(&jt, &col6(dfdv, c))[..n]);
    }
    let (dadq_t, dadv_t) = (transpose_six::<6>(dadq_s, iv, 6, 0), transpose_six::<6>(dadv_s, iv, 6, 0));
    let (dvdq_w_t, jc_w_t) = (transpose_six::<3>(dvdq_s, iv, 6, 3), transpose_six::<3>(js, iv, 6, 3));
    for r in iv + n..sub_end {
        let (fa, yt) = (col6(dfda, r), col3(dytj, r));
        let (q6, q3) = (lanes_dot(&dadq_t, &fa), lanes_dot(&dvdq_w_t, &yt));
        let (v6, v3) = (lanes_dot(&dadv_t, &fa), lanes_dot(&jc_w_t, &yt));
        for k in 0..n {
            dq[r + (iv + k) * nv] = q6[k] + q3[k];
            dv[r + (iv + k) * nv] = v6[k] + v3[k];
        }
    }
}

/// Column `k`'s `dF/dq` (without the ancestors' `J x* f`, added where the rows need it) and
/// `dF/dv` of a joint with composite inertia `oYc` and inertia variation `dYc = (t, B)`
/// (`dY x = [t x x_w; B x_w]`; the root's children have no `dV/dq` term):
///
/// ```text
/// dF/dq_k = oYc dA/dq_k + dYc dV/dq_k,   dF/dv_k = oYc dA/dv_k + dYc J_k
/// ```
#[inline(always)]
fn force_derivative_columns(oyc: &InertiaMoments, (t, b): (&Vector3<f64>, &Matrix3<f64>), has_parent: bool, jc: &Motion, dvdq: &Motion, dadq: &Motion, dadv: &Motion) -> (Force, Force) {
    let mut dfdq = oyc.mul_motion(dadq);
    if has_parent {
        dfdq += Force::new(t.cross(&dvdq.w), b * dvdq.w);
    }
    let dfdv = oyc.mul_motion(dadv) + Force::new(t.cross(&jc.w), b * jc.w);
    (dfdq, dfdv)
}

/// The angular half of `dYc^T J_k = [0; -t x J_v + B^T J_w]` (its linear half is zero).
#[inline(always)]
fn dy_transpose_j((t, b): (&Vector3<f64>, &Matrix3<f64>), jc: &Motion) -> Vector3<f64> {
    b.tr_mul(&jc.w) - t.cross(&jc.v)
}

/// Adds joint `i`'s subtree sums (`oYc_i`, `dYc_i`, `f_i`) into its parent's, if any: the
/// composite quantities of the backward pass.
#[inline]
fn add_to_parent(data: &mut Data, i: usize, parent: usize) {
    if parent > 0 {
        let (oyc, t, b, of) = (data.o_y_crb[i], data.do_y_top[i], data.do_y_b[i], data.of[i]);
        data.o_y_crb[parent] += oyc;
        data.do_y_top[parent] += t;
        data.do_y_b[parent] += b;
        data.of[parent] += of;
    }
}

/// Partial derivatives of `tau = RNEA(q, v, a)`: `data.dtau_dq`, `data.dtau_dv`, and
/// `data.mass_matrix` (`= d tau / d a`, full and symmetric); `data.tau` is set too.
///
/// Forward pass, for every joint `i` with parent `p` (world frame, `a^gf = a - g`):
///
/// ```text
/// J_i = oMi S_i,  dJ_i = ov_i x J_i
/// dV/dq_i = ov_p x J_i,  dA/dq_i = oa^gf_p x J_i + ov_p x dV/dq_i,  dA/dv_i = dJ_i + dV/dq_i
/// f_i = oY_i oa^gf_i + ov_i x* oY_i ov_i,  dY_i = ov_i x* oY_i - oY_i ov_i x + [. x* oh_i]
/// ```
///
/// Backward pass (composite quantities of the subtree of `i`, `sub(i)` its columns):
///
/// ```text
/// dtau/da[i, sub]  = J_i^T (oYc_i J_sub)
/// dtau/dq[i, sub]  = J_i^T (dYc_i dV/dq_sub + oYc_i dA/dq_sub)
/// dtau/dq[sub, i]  = (oYc J)_sub^T dA/dq_i + (dYc^T J)_sub^T dV/dq_i   (strict subtree)
/// dtau/dv likewise with dA/dv and J.
/// ```
pub fn compute_rnea_derivatives(model: &Model, data: &mut Data, q: &DVector<f64>, v: &DVector<f64>, a: &DVector<f64>) {
    forward_pass(model, data, q, v, a);
    backward_pass(model, data);
}

/// [`compute_rnea_derivatives`] at `a = qdd` right after `aba_keeping_body_inertias`: the
/// placements, world inertias, velocities and accelerations are ABA's
/// ([`forward_pass_after_aba`]). `data.mass_matrix` has the bits of
/// [`compute_rnea_derivatives`]' (it depends on the placements and inertias only);
/// `dtau/dq`, `dtau/dv` and `tau` agree with it up to round-off.
pub(super) fn compute_rnea_derivatives_after_aba(model: &Model, data: &mut Data) {
    forward_pass_after_aba(model, data);
    backward_pass(model, data);
}

/// The backward pass of [`compute_rnea_derivatives`] (see there) from the forward pass's
/// quantities in `data`.
#[inline(always)]
fn backward_pass(model: &Model, data: &mut Data) {
    let n = model.njoints();
    let nv = model.nv;
    for i in (1..n).rev() {
        let jnt = &model.joints[i];
        let p = jnt.parent;
        let (iv, nvj) = (jnt.idx_v, jnt.nv);
        let sub_end = iv + model.nv_subtree[i];
        let oyc = data.o_y_crb[i];
        let (t, b) = (data.do_y_top[i], data.do_y_b[i]);
        let of = data.of[i];
        for k in iv..iv + nvj {
            let jc = col(&data.jacobian, k);
            data.tau[k] = jc.dot(&of);
            // dF/da = oYc J (the A_g column at the world origin); dY^T J = [0; -t x J_v + B^T J_w]
            set_col_f(&mut data.dfda, k, &oyc.mul_motion(&jc));
            let yt = dy_transpose_j((&t, &b), &jc);
            data.dytj.as_mut_slice()[3 * k..3 * k + 3].copy_from_slice(yt.as_slice());
            let (dfdq, dfdv) = force_derivative_columns(&oyc, (&t, &b), p > 0, &jc, &col(&data.dvdq, k), &col(&data.dadq, k), &col(&data.dadv, k));
            set_col_f(&mut data.dfdq, k, &dfdq);
            set_col_f(&mut data.dfdv, k, &dfdv);
        }
        let (js, dfda, dytj, dfdq, dfdv) =
            (data.jacobian.as_slice(), data.dfda.as_slice(), data.dytj.as_slice(), data.dfdq.as_slice(), data.dfdv.as_slice());
        let (dvdq_s, dadq_s, dadv_s) = (data.dvdq.as_slice(), data.dadq.as_slice(), data.dadv.as_slice());
        let (mm, dq, dv) = (data.mass_matrix.as_mut_slice(), data.dtau_dq.as_mut_slice(), data.dtau_dv.as_mut_slice());
        let (columns, variations, out) = ((js, dfda, dytj, dfdq, dfdv), (dvdq_s, dadq_s, dadv_s), (mm, dq, dv));
        if nvj == FREE_FLYER_DOFS {
            free_flyer_rows_and_columns(nv, iv, sub_end, columns, variations, out);
        } else {
            joint_rows_and_columns(nv, (iv, nvj), sub_end, columns, variations, out);
        }
        // dF/dq += J x* f, for the ancestors' rows
        for k in iv..iv + nvj {
            let add = col(&data.jacobian, k).cross_force(&of);
            let cur = col(&data.dfdq, k);
            set_col(&mut data.dfdq, k, &Motion::new(cur.v + add.f, cur.w + add.n));
        }
        add_to_parent(data, i, p);
    }
    // M: mirror the upper triangle.
    data.mass_matrix.fill_lower_triangle_with_upper_triangle();
}

/// The forward pass of [`compute_rnea_derivatives`]: placements, world velocities and
/// accelerations, the bodies' world inertias `oY_i`, forces `f_i` and inertia variations
/// `dY_i` (not yet summed over the subtrees), and the columns `J`, `dV/dq`, `dA/dq`, `dA/dv`.
fn forward_pass(model: &Model, data: &mut Data, q: &DVector<f64>, v: &DVector<f64>, a: &DVector<f64>) {
    let n = model.njoints();
    let minus_g = -model.gravity;
    for i in 1..n {
        let jnt = &model.joints[i];
        let p = jnt.parent;
        let li = local_placement(model, data, i, q);
        let omi = if p > 0 { data.o_m_i[p] * li } else { li };
        let vj = joint_motion(model, i, v);
        let aj = joint_motion(model, i, a);
        let (vi, ai) = if p > 0 {
            let vi = li.act_inv(&data.v[p]) + vj;
            (vi, li.act_inv(&data.a[p]) + aj + vi.cross(&vj))
        } else {
            (vj, aj + vj.cross(&vj))
        };
        data.li_m_i[i] = li;
        data.o_m_i[i] = omi;
        data.v[i] = vi;
        data.a[i] = ai;
        let oy = data.body_moments[i].transformed(&omi);
        // What follows is `world_forces_and_columns` written out: calling it here measured 2-3 %
        // slower on the stand-alone derivatives (docs/experiments/deriv-aba.md).
        let ov = omi.act(&vi);
        let oa_gf = omi.act(&ai) + minus_g;
        let oh = oy.mul_motion(&ov);
        data.of[i] = oy.mul_motion(&oa_gf) + ov.cross_force(&oh);
        data.o_y_crb[i] = oy;
        data.ov[i] = ov;
        data.oa[i] = oa_gf;
        data.oh[i] = oh;
        let (ov_p, oa_gf_p) = if p > 0 { (data.ov[p], data.oa[p]) } else { (Motion::zero(), minus_g) };
        for k in jnt.idx_v..jnt.idx_v + jnt.nv {
            let s_local = match jnt.kind {
                JointKind::FreeFlyer => {
                    let mut e = Vector6::zeros();
                    e[k - jnt.idx_v] = 1.0;
                    Motion::from_vector(&e)
                }
                kind => kind.subspace(),
            };
            let jc = omi.act(&s_local);
            let dvdq = ov_p.cross(&jc);
            let dadq = oa_gf_p.cross(&jc) + ov_p.cross(&dvdq);
            let dadv = ov.cross(&jc) + dvdq; // dJ + dV/dq
            set_col(&mut data.jacobian, k, &jc);
            set_col(&mut data.dvdq, k, &dvdq);
            set_col(&mut data.dadq, k, &dadq);
            set_col(&mut data.dadv, k, &dadv);
        }
        let (t, b) = inertia_variation(&oy, &ov, &oh);
        data.do_y_top[i] = t;
        data.do_y_b[i] = b;
    }
}

/// The forward pass of [`compute_rnea_derivatives_after_aba`] at ABA's own `qdd`: ABA's
/// pass 1 left the placements, world velocities `ov_i` and bodies' world inertias, its pass 3
/// the world accelerations `oa_i = a_i - g`, so only the forces and the columns remain (as
/// Pinocchio's `computeABADerivatives` reuses its ABA's sweeps). The velocities and
/// accelerations are ABA's world-frame recursions, not the local-frame ones of
/// [`forward_pass`]: equal up to round-off.
fn forward_pass_after_aba(model: &Model, data: &mut Data) {
    let minus_g = -model.gravity;
    for i in 1..model.njoints() {
        let (omi, oy, ov, oa_gf) = (data.o_m_i[i], data.o_y_body[i], data.ov[i], data.oa[i]);
        world_forces_and_columns(model, data, i, &omi, oy, ov, oa_gf, minus_g);
    }
}

/// Of joint `i` with world inertia `oY`, velocity `ov` and acceleration `oa^gf = a - g`:
/// `f_i = oY oa^gf + ov x* oY ov`, `dY_i`, and the columns `J`, `dV/dq`, `dA/dq`, `dA/dv` of
/// its dofs (the parent's `ov`, `oa^gf` already in `data`).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn world_forces_and_columns(model: &Model, data: &mut Data, i: usize, omi: &SE3, oy: InertiaMoments, ov: Motion, oa_gf: Motion, minus_g: Motion) {
    let jnt = &model.joints[i];
    let p = jnt.parent;
    let oh = oy.mul_motion(&ov);
    data.of[i] = oy.mul_motion(&oa_gf) + ov.cross_force(&oh);
    data.o_y_crb[i] = oy;
    data.ov[i] = ov;
    data.oa[i] = oa_gf;
    data.oh[i] = oh;
    let (ov_p, oa_gf_p) = if p > 0 { (data.ov[p], data.oa[p]) } else { (Motion::zero(), minus_g) };
    for k in jnt.idx_v..jnt.idx_v + jnt.nv {
        let s_local = match jnt.kind {
            JointKind::FreeFlyer => {
                let mut e = Vector6::zeros();
                e[k - jnt.idx_v] = 1.0;
                Motion::from_vector(&e)
            }
            kind => kind.subspace(),
        };
        let jc = omi.act(&s_local);
        let dvdq = ov_p.cross(&jc);
        let dadq = oa_gf_p.cross(&jc) + ov_p.cross(&dvdq);
        let dadv = ov.cross(&jc) + dvdq; // dJ + dV/dq
        set_col(&mut data.jacobian, k, &jc);
        set_col(&mut data.dvdq, k, &dvdq);
        set_col(&mut data.dadq, k, &dadq);
        set_col(&mut data.dadv, k, &dadv);
    }
    let (t, b) = inertia_variation(&oy, &ov, &oh);
    data.do_y_top[i] = t;
    data.do_y_b[i] = b;
}

/// The first half of [`rnea_derivatives_tr_mul`]: the forward pass of
/// [`compute_rnea_derivatives`] at `(q, v, a)` and the composite quantities `oYc_i`, `dYc_i`,
/// `f_i` summed over each subtree (the same sums in the same order); with `mass_matrix`,
/// also `data.mass_matrix` (`M[k, sub] = J_k^T oYc J_sub`, mirrored), to the bit the one
/// [`compute_rnea_derivatives`] forms.
pub fn rnea_derivatives_forward(model: &Model, data: &mut Data, q: &DVector<f64>, v: &DVector<f64>, a: &DVector<f64>, mass_matrix: bool) {
    forward_pass(model, data, q, v, a);
    let nv = model.nv;
    for i in (1..model.njoints()).rev() {
        let jnt = &model.joints[i];
        let p = jnt.parent;
        if mass_matrix {
            let (iv, nvj) = (jnt.idx_v, jnt.nv);
            let oyc = data.o_y_crb[i];
            for k in iv..iv + nvj {
                set_col_f(&mut data.dfda, k, &oyc.mul_motion(&col(&data.jacobian, k)));
            }
            let (js, dfda, mm) = (data.jacobian.as_slice(), data.dfda.as_slice(), data.mass_matrix.as_mut_slice());
            for c in iv..iv + model.nv_subtree[i] {
                let fa = col6(dfda, c);
                for k in iv..iv + nvj {
                    mm[k + c * nv] = dot6(&col6(js, k), &fa);
                }
            }
        }
        add_to_parent(data, i, p);
    }
    if mass_matrix {
        data.mass_matrix.fill_lower_triangle_with_upper_triangle();
    }
}

/// `w^T d tau / dq` and `w^T d tau / dv` of `tau = RNEA(q, v, a)` at the point of the last
/// [`rnea_derivatives_forward`], without forming the two `nv x nv` matrices (the weighted
/// sums of the rows of [`compute_rnea_derivatives`]' backward pass, `O(nv)` instead of
/// `O(nv d)`). Of column `c` of joint `i` (parent `p`), its rows are those of `i` and its
/// ancestors (`J_k^T dF/dq_c`, with `J_c x* f_i` added for the ancestors' rows) and those of
/// the strict subtree (`(dF/da)_r . dA/dq_c + (dY^T J)_r . dV/dq_c`):
///
/// ```text
/// W_i = W_p + sum_{k in i} w_k J_k                       (forward)
/// S_i = sum_{r in sub(i) \ i} w_r (dF/da)_r,   T_i = sum_{r in sub(i) \ i} w_r (dY^T J)_r   (backward)
/// (w^T dtau/dq)_c = W_i . dF/dq_c + W_p . (J_c x* f_i) + S_i . dA/dq_c + T_i . (dV/dq_c)_w
/// (w^T dtau/dv)_c = W_i . dF/dv_c + S_i . dA/dv_c + T_i . (J_c)_w
/// ```
pub fn rnea_derivatives_tr_mul(model: &Model, data: &mut Data, w: &[f64], w_dtau_dq: &mut [f64], w_dtau_dv: &mut [f64]) {
    let n = model.njoints();
    for i in 1..n {
        let jnt = &model.joints[i];
        let mut wi = if jnt.parent > 0 { data.w_ancestors[jnt.parent] } else { Motion::zero() };
        for (k, &w_k) in w.iter().enumerate().skip(jnt.idx_v).take(jnt.nv) {
            wi += col(&data.jacobian, k) * w_k;
        }
        data.w_ancestors[i] = wi;
        data.w_dfda[i] = Force::zero();
        data.w_dytj[i] = Vector3::zeros();
    }
    for i in (1..n).rev() {
        let jnt = &model.joints[i];
        let p = jnt.parent;
        let (oyc, t, b, of) = (data.o_y_crb[i], data.do_y_top[i], data.do_y_b[i], data.of[i]);
        let wi = data.w_ancestors[i];
        let wp = if p > 0 { data.w_ancestors[p] } else { Motion::zero() };
        let (s_sub, t_sub) = (data.w_dfda[i], data.w_dytj[i]);
        let (mut s_own, mut t_own) = (Force::zero(), Vector3::zeros());
        for k in jnt.idx_v..jnt.idx_v + jnt.nv {
            let (jc, dvdq, dadq, dadv) = (col(&data.jacobian, k), col(&data.dvdq, k), col(&data.dadq, k), col(&data.dadv, k));
            let (dfdq, dfdv) = force_derivative_columns(&oyc, (&t, &b), p > 0, &jc, &dvdq, &dadq, &dadv);
            w_dtau_dq[k] = wi.dot(&dfdq) + wp.dot(&jc.cross_force(&of)) + dadq.dot(&s_sub) + t_sub.dot(&dvdq.w);
            w_dtau_dv[k] = wi.dot(&dfdv) + dadv.dot(&s_sub) + t_sub.dot(&jc.w);
            s_own += oyc.mul_motion(&jc) * w[k];
            t_own += dy_transpose_j((&t, &b), &jc) * w[k];
        }
        let (s_i, t_i) = (s_sub + s_own, t_sub + t_own);
        if p > 0 {
            data.w_dfda[p] += s_i;
            data.w_dytj[p] += t_i;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The free flyer's lanes give the scalar loop's bits (random columns, HyQ's sizes: the
    /// root's six dofs and a subtree of 18 columns).
    #[test]
    fn free_flyer_lanes_match_the_scalar_loop_to_the_bit() {
        let (nv, iv, nvj) = (18, 0, 6);
        let mut uniform_01 = crate::dynamics::uniform_from(23);
        let mut uniform = move || uniform_01() - 0.5;
        let mut columns = |rows: usize| (0..rows * nv).map(|_| uniform()).collect::<Vec<f64>>();
        let (js, dfda, dytj, dfdq, dfdv) = (columns(6), columns(6), columns(3), columns(6), columns(6));
        let (dvdq, dadq, dadv) = (columns(6), columns(6), columns(6));
        let mut lanes = (vec![0.0; nv * nv], vec![0.0; nv * nv], vec![0.0; nv * nv]);
        let mut scalar = lanes.clone();
        let inputs = ((&js[..], &dfda[..], &dytj[..], &dfdq[..], &dfdv[..]), (&dvdq[..], &dadq[..], &dadv[..]));
        free_flyer_rows_and_columns(nv, iv, nv, inputs.0, inputs.1, (&mut lanes.0, &mut lanes.1, &mut lanes.2));
        joint_rows_and_columns(nv, (iv, nvj), nv, inputs.0, inputs.1, (&mut scalar.0, &mut scalar.1, &mut scalar.2));
        for (name, x, y) in [("M", &lanes.0, &scalar.0), ("dtau/dq", &lanes.1, &scalar.1), ("dtau/dv", &lanes.2, &scalar.2)] {
            assert!(x.iter().zip(y).all(|(x, y)| x.to_bits() == y.to_bits()), "{name} differs");
            assert!(x.iter().any(|x| *x != 0.0), "{name} not written");
        }
    }
}
