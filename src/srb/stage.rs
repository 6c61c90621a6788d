//! One knot of Nguyen 2022's contact-timing problem (sec. II-B, eq. (1)-(2)) as an ipocp
//! stage, with exact first and second derivatives.
//!
//! State `x = [p, pdot, Omega, vec(R), T_1..T_np]` (CoM position and velocity in the world,
//! body angular velocity, rotation body -> world stored column by column, the phase
//! durations as augmented states with `T_{k+1} = T_k`); control `u` = 3 numbers per foot
//! (order LF, RF, LH, RH): its ground force while it is in contact, its position while it
//! swings. The last knot has no control.

// Index loops over rows and columns read like the equations they implement.
#![allow(clippy::needless_range_loop)]

use super::exp_map::{exp_derivatives, hat, ExpMap};
use crate::ipocp::{Stage, StageDims, StageJacobians, StageMultipliers, StageValues};
use nalgebra::{DMatrix, Matrix3, Vector3};
use std::sync::Arc;

pub(crate) const P: usize = 0;
pub(crate) const V: usize = 3;
pub(crate) const W: usize = 6;
pub(crate) const R: usize = 9;
pub(crate) const T: usize = 18;
/// Bound the reference script puts on every unbounded variable (`big = 1e3`).
pub(crate) const BIG: f64 = 1e3;
const GRAVITY: f64 = 9.81;

/// Data shared by all knots.
#[derive(Clone, Debug)]
pub(crate) struct Shared {
    pub mass: f64,
    pub inertia: Matrix3<f64>,
    pub inertia_inv: Matrix3<f64>,
    /// Sphere centres `pbar^s` (body frame, relative to the CoM).
    pub pbar: [Vector3<f64>; 4],
    pub radius: f64,
    pub mu: f64,
    pub eps_omega: f64,
    pub eps_r: f64,
    pub eps_f: f64,
    pub cost_dt: bool,
    pub exp_map: ExpMap,
    pub knots_per_phase: Vec<usize>,
    pub phases: usize,
    /// The bounds of the durations' sum (2j).
    pub t_sum: (f64, f64),
    /// CoM height bounds above the start ground in contact phases (2g) and the ground height.
    pub height: (f64, f64),
    pub ground: f64,
    pub p0: Vector3<f64>,
    pub pg: Vector3<f64>,
    pub rg: Matrix3<f64>,
    /// Feet at the start and at the goal (world).
    pub feet_start: [Vector3<f64>; 4],
    pub feet_goal: [Vector3<f64>; 4],
    /// The start box the airborne legs clear, the legs' tuck points (body frame, relative to
    /// the CoM) and the clearance.
    pub platform: Option<PlatformBox>,
    pub tuck: [Vector3<f64>; 4],
    pub box_clearance: f64,
}

/// The start box as an obstacle: top face at `top`, extent `x`, `y`, down to the ground.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct PlatformBox {
    pub top: f64,
    pub x: [f64; 2],
    pub y: [f64; 2],
}

impl PlatformBox {
    /// Signed distance of `a` from the box (negative inside), its gradient and Hessian.
    /// Outside: the distance to the nearest point, `|e+|` with `e+` the positive part of
    /// the excess over each half-extent; its Hessian is `(P - n n^T) / d` on the `k` excess
    /// axes `P` (zero on a face, the edge's or corner's curvature beyond). Inside: minus
    /// the distance to the nearest face (top or side), gradient out of that face.
    pub fn signed_distance(&self, a: &Vector3<f64>) -> (f64, Vector3<f64>, Matrix3<f64>) {
        let cx = 0.5 * (self.x[0] + self.x[1]);
        let cy = 0.5 * (self.y[0] + self.y[1]);
        let e = Vector3::new((a.x - cx).abs() - 0.5 * (self.x[1] - self.x[0]), (a.y - cy).abs() - 0.5 * (self.y[1] - self.y[0]), a.z - self.top);
        let sign = Vector3::new(if a.x >= cx { 1.0 } else { -1.0 }, if a.y >= cy { 1.0 } else { -1.0 }, 1.0);
        let out = e.map(|v| v.max(0.0));
        let d = out.norm();
        if d > 0.0 {
            let n = out.component_mul(&sign) / d;
            let active = Matrix3::from_diagonal(&e.map(|v| if v > 0.0 { 1.0 } else { 0.0 }));
            return (d, n, (active - n * n.transpose()) / d);
        }
        let axis = e.imax();
        let mut g = Vector3::zeros();
        g[axis] = sign[axis];
        (e[axis], g, Matrix3::zeros())
    }
}

/// What a knot is.
#[derive(Clone, Debug)]
pub(crate) struct SrbStage {
    pub shared: Arc<Shared>,
    /// Knot index `k` and its phase (of interval `min(k, Nc - 1)`).
    pub knot: usize,
    pub phase: usize,
    pub last: bool,
    /// Feet in contact during this knot's interval (all false on the last knot).
    pub contact: [bool; 4],
    /// `e_R = L vec(R)`, Lee's error `1/2 vee(R_ref^T R - R^T R_ref)` as a linear map.
    pub rot_err: nalgebra::SMatrix<f64, 3, 9>,
    /// `(row in z, lower, upper)` of the simple bounds.
    pub bounds: Vec<(usize, f64, f64)>,
    pub n_general: usize,
    /// Box-clearance rows (the last of the general rows): one per airborne foot.
    pub n_box: usize,
}

fn ridx(a: usize, b: usize) -> usize {
    R + a + 3 * b
}

fn add_pair(h: &mut DMatrix<f64>, i: usize, j: usize, v: f64) {
    if i == j {
        h[(i, i)] += v;
    } else {
        h[(i, j)] += v;
        h[(j, i)] += v;
    }
}

/// `1/2 vee(M - M^T)` of `M = R_ref^T R` as a 3 x 9 map on `vec(R)` (column-major).
pub(crate) fn rotation_error_map(r_ref: &Matrix3<f64>) -> nalgebra::SMatrix<f64, 3, 9> {
    let mut l = nalgebra::SMatrix::<f64, 3, 9>::zeros();
    // M_ab = sum_c Rref_ca R_cb;  d M_ab / d R_cd = Rref_ca delta_bd
    let mut add = |row: usize, a: usize, b: usize, sign: f64| {
        for c in 0..3 {
            l[(row, c + 3 * b)] += 0.5 * sign * r_ref[(c, a)];
        }
    };
    add(0, 2, 1, 1.0);
    add(0, 1, 2, -1.0);
    add(1, 0, 2, 1.0);
    add(1, 2, 0, -1.0);
    add(2, 1, 0, 1.0);
    add(2, 0, 1, -1.0);
    l
}

/// Per row of `d`, up to 9 (index, coefficient) pairs of its Jacobian.
type SphereJacobian = [[(usize, f64); 9]; 3];

/// Quantities of a knot at `z` used by values and derivatives.
struct Point {
    p: Vector3<f64>,
    v: Vector3<f64>,
    w: Vector3<f64>,
    r: Matrix3<f64>,
    dt: f64,
    force: Vector3<f64>,
    torque: Vector3<f64>,
}

impl SrbStage {
    fn nx(&self) -> usize {
        T + self.shared.phases
    }

    fn u_index(&self, foot: usize) -> usize {
        self.nx() + 3 * foot
    }

    fn t_index(&self) -> usize {
        T + self.phase
    }

    fn inv_n(&self) -> f64 {
        1.0 / self.shared.knots_per_phase[self.phase] as f64
    }

    /// Foot position: fixed at the start while in contact, the goal on the last knot, else
    /// the control.
    fn foot(&self, z: &[f64], s: usize) -> Vector3<f64> {
        if self.last {
            self.shared.feet_goal[s]
        } else if self.contact[s] {
            self.shared.feet_start[s]
        } else {
            let i = self.u_index(s);
            Vector3::new(z[i], z[i + 1], z[i + 2])
        }
    }

    fn point(&self, z: &[f64]) -> Point {
        let v3 = |i: usize| Vector3::new(z[i], z[i + 1], z[i + 2]);
        let r = Matrix3::from_fn(|a, b| z[ridx(a, b)]);
        let p = v3(P);
        let (mut force, mut torque) = (Vector3::zeros(), Vector3::zeros());
        if !self.last {
            for s in 0..4 {
                if self.contact[s] {
                    let f = v3(self.u_index(s));
                    force += f;
                    torque += (self.shared.feet_start[s] - p).cross(&f);
                }
            }
        }
        Point { p, v: v3(V), w: v3(W), r, dt: z[self.t_index()] * self.inv_n(), force, torque }
    }

    /// `R^T tau - Omega x I Omega` (eq. 1c without `I^{-1}`).
    fn body_torque(&self, q: &Point) -> Vector3<f64> {
        q.r.transpose() * q.torque - q.w.cross(&(self.shared.inertia * q.w))
    }

    /// Jacobian of `a = R^T tau - Omega x I Omega` into rows `row..row+3` of `jac`, scaled.
    fn body_torque_jacobian(&self, q: &Point, jac: &mut DMatrix<f64>, row: usize, scale: f64) {
        let sh = &self.shared;
        let dw = hat(&(sh.inertia * q.w)) - hat(&q.w) * sh.inertia;
        for i in 0..3 {
            for j in 0..3 {
                jac[(row + i, W + j)] += scale * dw[(i, j)];
            }
        }
        // d a_d / d R_cd' = delta_dd' tau_c
        for c in 0..3 {
            for d in 0..3 {
                jac[(row + d, ridx(c, d))] += scale * q.torque[c];
            }
        }
        let dp = q.r.transpose() * hat(&q.force);
        for i in 0..3 {
            for j in 0..3 {
                jac[(row + i, P + j)] += scale * dp[(i, j)];
            }
        }
        for s in 0..4 {
            if self.contact[s] && !self.last {
                let df = q.r.transpose() * hat(&(sh.feet_start[s] - q.p));
                let u = self.u_index(s);
                for i in 0..3 {
                    for j in 0..3 {
                        jac[(row + i, u + j)] += scale * df[(i, j)];
                    }
                }
            }
        }
    }

    /// Hessian of `scale * mu^T a` (a as above) into `h`; with `t_scale`, also the cross
    /// terms with `T` of `(T / N) mu^T a` (`t_scale = 1/N`).
    fn body_torque_hessian(&self, q: &Point, mu: &Vector3<f64>, scale: f64, t_scale: Option<f64>, h: &mut DMatrix<f64>) {
        let sh = &self.shared;
        let rho = q.r * mu;
        let hw = hat(mu) * sh.inertia - sh.inertia * hat(mu);
        for i in 0..3 {
            for j in 0..3 {
                h[(W + i, W + j)] += scale * hw[(i, j)];
            }
        }
        let hf = hat(&q.force);
        let hr = hat(&rho);
        for c in 0..3 {
            for d in 0..3 {
                for j in 0..3 {
                    add_pair(h, ridx(c, d), P + j, scale * mu[d] * hf[(c, j)]);
                }
            }
        }
        for s in 0..4 {
            if !self.contact[s] || self.last {
                continue;
            }
            let u = self.u_index(s);
            let lever = hat(&(sh.feet_start[s] - q.p));
            for c in 0..3 {
                for d in 0..3 {
                    for l in 0..3 {
                        add_pair(h, ridx(c, d), u + l, scale * mu[d] * lever[(c, l)]);
                    }
                }
            }
            for j in 0..3 {
                for l in 0..3 {
                    add_pair(h, P + j, u + l, scale * hr[(j, l)]);
                }
            }
        }
        if let Some(ts) = t_scale {
            let ti = self.t_index();
            // gradient of mu^T a
            let iw = sh.inertia * q.w;
            let g_w = mu.cross(&iw) + sh.inertia * q.w.cross(mu);
            for j in 0..3 {
                add_pair(h, ti, W + j, ts * g_w[j]);
            }
            for c in 0..3 {
                for d in 0..3 {
                    add_pair(h, ti, ridx(c, d), ts * mu[d] * q.torque[c]);
                }
            }
            let g_p = rho.cross(&q.force);
            for j in 0..3 {
                add_pair(h, ti, P + j, ts * g_p[j]);
            }
            for s in 0..4 {
                if self.contact[s] && !self.last {
                    let g_f = rho.cross(&(sh.feet_start[s] - q.p));
                    let u = self.u_index(s);
                    for l in 0..3 {
                        add_pair(h, ti, u + l, ts * g_f[l]);
                    }
                }
            }
        }
    }

    /// `q = eps_W |Omega|^2 + eps_R |e_R|^2 + eps_f sum |f|^2` and the weight `w` (dt or 1).
    fn cost_terms(&self, z: &[f64], q: &Point) -> (f64, f64) {
        let sh = &self.shared;
        let r9 = nalgebra::SVector::<f64, 9>::from_column_slice(&z[R..R + 9]);
        let e = self.rot_err * r9;
        let mut c = sh.eps_omega * q.w.norm_squared() + sh.eps_r * e.norm_squared();
        if !self.last {
            for s in 0..4 {
                if self.contact[s] {
                    let u = self.u_index(s);
                    c += sh.eps_f * (z[u] * z[u] + z[u + 1] * z[u + 1] + z[u + 2] * z[u + 2]);
                }
            }
        }
        let w = if sh.cost_dt { q.dt } else { 1.0 };
        (c, w)
    }

    /// Gradient of `q` (sizes of `z`).
    fn cost_gradient_q(&self, z: &[f64], q: &Point, g: &mut [f64]) {
        let sh = &self.shared;
        g.iter_mut().for_each(|v| *v = 0.0);
        for j in 0..3 {
            g[W + j] = 2.0 * sh.eps_omega * q.w[j];
        }
        let r9 = nalgebra::SVector::<f64, 9>::from_column_slice(&z[R..R + 9]);
        let gr = self.rot_err.transpose() * (self.rot_err * r9) * (2.0 * sh.eps_r);
        for j in 0..9 {
            g[R + j] = gr[j];
        }
        if !self.last {
            for s in 0..4 {
                if self.contact[s] {
                    let u = self.u_index(s);
                    for j in 0..3 {
                        g[u + j] = 2.0 * sh.eps_f * z[u + j];
                    }
                }
            }
        }
    }

    /// The airborne feet whose tuck points have a box-clearance row, in row order.
    fn box_feet(&self) -> impl Iterator<Item = usize> + '_ {
        (0..4).filter(move |&f| self.n_box > 0 && !self.contact[f])
    }

    /// Tuck point of leg `s` in the world, `a = p + R t^s` (linear in `p` and `vec(R)`).
    fn tuck_point(&self, q: &Point, s: usize) -> Vector3<f64> {
        q.p + q.r * self.shared.tuck[s]
    }

    /// Gradient in `z` of `n^T a` for the tuck point `a = p + R t^s`: `n` on `p`, `n_a t_b`
    /// on `R_ab`.
    fn add_point_row(&self, s: usize, n: &Vector3<f64>, mut put: impl FnMut(usize, f64)) {
        let t = self.shared.tuck[s];
        for a in 0..3 {
            put(P + a, n[a]);
            for b in 0..3 {
                put(ridx(a, b), n[a] * t[b]);
            }
        }
    }

    /// Sphere row of foot `s` (2d): `d = R^T (p_f - p) - pbar`, value `|d|^2`; the sparse
    /// Jacobian of `d`: per row `a`, up to 9 (index, coefficient) pairs, `count` used.
    fn sphere(&self, z: &[f64], q: &Point, s: usize) -> (Vector3<f64>, SphereJacobian, usize) {
        let pf = self.foot(z, s);
        let delta = pf - q.p;
        let d = q.r.transpose() * delta - self.shared.pbar[s];
        let variable = !self.last && !self.contact[s];
        let mut rows = [[(0usize, 0.0f64); 9]; 3];
        let count = if variable { 9 } else { 6 };
        for (a, row) in rows.iter_mut().enumerate() {
            for c in 0..3 {
                row[c] = (ridx(c, a), delta[c]);
                row[3 + c] = (P + c, -q.r[(c, a)]);
                if variable {
                    row[6 + c] = (self.u_index(s) + c, q.r[(c, a)]);
                }
            }
        }
        (d, rows, count)
    }
}

impl Stage for SrbStage {
    fn dims(&self) -> StageDims {
        let nx = self.nx();
        let (nu, nx_next) = if self.last { (0, 0) } else { (12, nx) };
        let ng = if self.knot == 0 { 21 } else if self.last { 6 } else { 0 };
        StageDims { nx, nu, nx_next, ng, nh: self.n_general + self.bounds.len() }
    }

    fn inequality_bounds(&self, lower: &mut [f64], upper: &mut [f64]) {
        let sh = &self.shared;
        let mut row = 0;
        if !self.last {
            for s in 0..4 {
                if self.contact[s] {
                    for _ in 0..4 {
                        lower[row] = f64::NEG_INFINITY;
                        upper[row] = 0.0;
                        row += 1;
                    }
                }
            }
        }
        for _ in 0..4 {
            lower[row] = f64::NEG_INFINITY;
            upper[row] = sh.radius * sh.radius;
            row += 1;
        }
        if !self.last && self.contact.iter().any(|&c| c) {
            lower[row] = sh.height.0;
            upper[row] = sh.height.1;
            row += 1;
        }
        if self.knot == 0 {
            lower[row] = sh.t_sum.0;
            upper[row] = sh.t_sum.1;
            row += 1;
        }
        if self.last {
            lower[row] = 2.9;
            upper[row] = f64::INFINITY;
            row += 1;
        }
        for _ in 0..self.n_box {
            lower[row] = sh.box_clearance;
            upper[row] = f64::INFINITY;
            row += 1;
        }
        debug_assert_eq!(row, self.n_general);
        for (i, &(_, lo, up)) in self.bounds.iter().enumerate() {
            lower[row + i] = lo;
            upper[row + i] = up;
        }
    }

    fn evaluate(&self, z: &[f64], out: &mut StageValues) {
        let sh = &self.shared;
        let q = self.point(z);
        let (c, w) = self.cost_terms(z, &q);
        out.cost = w * c;
        if !self.last {
            // (2h): forward Euler of (1a)-(1b); (2i): the SO(3) step.
            let g = Vector3::new(0.0, 0.0, -GRAVITY);
            let pn = q.p + q.v * q.dt;
            let vn = q.v + (q.force / sh.mass + g) * q.dt;
            let wn = q.w + sh.inertia_inv * self.body_torque(&q) * q.dt;
            let rn = q.r * super::exp_map::exp(sh.exp_map, &(q.w * q.dt));
            let f = &mut out.dynamics;
            for j in 0..3 {
                f[P + j] = pn[j];
                f[V + j] = vn[j];
                f[W + j] = wn[j];
            }
            for a in 0..3 {
                for b in 0..3 {
                    f[ridx(a, b)] = rn[(a, b)];
                }
            }
            for i in 0..sh.phases {
                f[T + i] = z[T + i];
            }
        }
        if self.knot == 0 {
            // (2a)(2b): initial state, and zero net body torque (Omegadot_0 = 0).
            let g = &mut out.equalities;
            for j in 0..3 {
                g[j] = q.p[j] - sh.p0[j];
                g[3 + j] = q.v[j];
                g[6 + j] = q.w[j];
            }
            for a in 0..3 {
                for b in 0..3 {
                    g[9 + a + 3 * b] = q.r[(a, b)] - if a == b { 1.0 } else { 0.0 };
                }
            }
            let a = self.body_torque(&q);
            for j in 0..3 {
                g[18 + j] = a[j];
            }
        } else if self.last {
            // (2c): final position, and skew(R_g^T R_N) = 0.
            let g = &mut out.equalities;
            let m = sh.rg.transpose() * q.r;
            for j in 0..3 {
                g[j] = q.p[j] - sh.pg[j];
            }
            g[3] = m[(2, 1)] - m[(1, 2)];
            g[4] = m[(0, 2)] - m[(2, 0)];
            g[5] = m[(1, 0)] - m[(0, 1)];
        }
        let h = &mut out.inequalities;
        let mut row = 0;
        if !self.last {
            for s in 0..4 {
                if self.contact[s] {
                    // (2e) |f_x| <= mu f_z, |f_y| <= mu f_z
                    let u = self.u_index(s);
                    let (fx, fy, fz) = (z[u], z[u + 1], z[u + 2]);
                    h[row] = fx - sh.mu * fz;
                    h[row + 1] = -fx - sh.mu * fz;
                    h[row + 2] = fy - sh.mu * fz;
                    h[row + 3] = -fy - sh.mu * fz;
                    row += 4;
                }
            }
        }
        for s in 0..4 {
            let (d, _, _) = self.sphere(z, &q, s);
            h[row] = d.norm_squared(); // (2d)
            row += 1;
        }
        if !self.last && self.contact.iter().any(|&c| c) {
            h[row] = q.p[2] - sh.ground; // (2g)
            row += 1;
        }
        if self.knot == 0 {
            h[row] = (0..sh.phases).map(|i| z[T + i]).sum(); // (2j)
            row += 1;
        }
        if self.last {
            h[row] = (sh.rg.transpose() * q.r).trace();
            row += 1;
        }
        if let Some(b) = &sh.platform {
            for s in self.box_feet() {
                h[row] = b.signed_distance(&self.tuck_point(&q, s)).0; // airborne legs clear the box
                row += 1;
            }
        }
        for (i, &(idx, _, _)) in self.bounds.iter().enumerate() {
            h[row + i] = z[idx];
        }
    }

    fn jacobians(&self, z: &[f64], out: &mut StageJacobians) {
        let sh = &self.shared;
        let q = self.point(z);
        let nz = z.len();
        let inv_n = self.inv_n();
        let ti = self.t_index();
        // Cost: w q with w = T_i / N (cost_dt).
        let (c, w) = self.cost_terms(z, &q);
        self.cost_gradient_q(z, &q, out.cost_gradient.as_mut_slice());
        out.cost_gradient *= w;
        if sh.cost_dt {
            out.cost_gradient[ti] += inv_n * c;
        }
        if !self.last {
            let f = &mut out.dynamics;
            f.as_mut_slice().fill(0.0);
            for j in 0..3 {
                f[(P + j, P + j)] = 1.0;
                f[(P + j, V + j)] = q.dt;
                f[(P + j, ti)] = q.v[j] * inv_n;
                f[(V + j, V + j)] = 1.0;
            }
            let g = Vector3::new(0.0, 0.0, -GRAVITY);
            let acc = q.force / sh.mass + g;
            for j in 0..3 {
                f[(V + j, ti)] = acc[j] * inv_n;
            }
            for s in 0..4 {
                if self.contact[s] {
                    let u = self.u_index(s);
                    for j in 0..3 {
                        f[(V + j, u + j)] = q.dt / sh.mass;
                    }
                }
            }
            // Omega+ = Omega + dt I^-1 a: da/dz into the (zero) rows, then dt I^-1 applied
            // column by column, then the identity and the T column.
            self.body_torque_jacobian(&q, f, W, 1.0);
            for j in 0..nz {
                let col = sh.inertia_inv * Vector3::new(f[(W, j)], f[(W + 1, j)], f[(W + 2, j)]) * q.dt;
                for i in 0..3 {
                    f[(W + i, j)] = col[i];
                }
            }
            let a = sh.inertia_inv * self.body_torque(&q);
            for i in 0..3 {
                f[(W + i, W + i)] += 1.0;
                f[(W + i, ti)] += a[i] * inv_n;
            }
            // R+ = R E(dt Omega)
            let omega = q.w * q.dt;
            let ed = exp_derivatives(sh.exp_map, &omega);
            let e = ed.value;
            for a in 0..3 {
                for b in 0..3 {
                    let row = ridx(a, b);
                    // d (R E)_ab / d R_ad' = E_d'b
                    for d in 0..3 {
                        f[(row, ridx(a, d))] += e[(d, b)];
                    }
                    let mut dt_t = 0.0;
                    for j in 0..3 {
                        let re = (q.r * ed.first[j])[(a, b)];
                        f[(row, W + j)] += q.dt * re;
                        dt_t += q.w[j] * re;
                    }
                    f[(row, ti)] += inv_n * dt_t;
                }
            }
            for i in 0..sh.phases {
                f[(T + i, T + i)] = 1.0;
            }
        }
        let g = &mut out.equalities;
        g.as_mut_slice().fill(0.0);
        if self.knot == 0 {
            for j in 0..9 {
                g[(j, j)] = 1.0;
            }
            for j in 0..9 {
                g[(9 + j, R + j)] = 1.0;
            }
            self.body_torque_jacobian(&q, g, 18, 1.0);
        } else if self.last {
            for j in 0..3 {
                g[(j, P + j)] = 1.0;
            }
            // vee(M - M^T) with M = Rg^T R: twice Lee's error map of R_ref = R_g.
            let l = rotation_error_map(&sh.rg);
            for i in 0..3 {
                for j in 0..9 {
                    g[(3 + i, R + j)] = 2.0 * l[(i, j)];
                }
            }
        }
        let h = &mut out.inequalities;
        h.as_mut_slice().fill(0.0);
        let mut row = 0;
        if !self.last {
            for s in 0..4 {
                if self.contact[s] {
                    let u = self.u_index(s);
                    h[(row, u)] = 1.0;
                    h[(row + 1, u)] = -1.0;
                    h[(row + 2, u + 1)] = 1.0;
                    h[(row + 3, u + 1)] = -1.0;
                    for r in 0..4 {
                        h[(row + r, u + 2)] = -sh.mu;
                    }
                    row += 4;
                }
            }
        }
        for s in 0..4 {
            let (d, rows, count) = self.sphere(z, &q, s);
            for a in 0..3 {
                for &(idx, c) in &rows[a][..count] {
                    h[(row, idx)] += 2.0 * d[a] * c;
                }
            }
            row += 1;
        }
        if !self.last && self.contact.iter().any(|&c| c) {
            h[(row, P + 2)] = 1.0;
            row += 1;
        }
        if self.knot == 0 {
            for i in 0..sh.phases {
                h[(row, T + i)] = 1.0;
            }
            row += 1;
        }
        if self.last {
            for a in 0..3 {
                for b in 0..3 {
                    h[(row, ridx(a, b))] = sh.rg[(a, b)];
                }
            }
            row += 1;
        }
        if let Some(b) = &sh.platform {
            for s in self.box_feet() {
                let (_, n, _) = b.signed_distance(&self.tuck_point(&q, s));
                self.add_point_row(s, &n, |j, v| h[(row, j)] += v);
                row += 1;
            }
        }
        for (i, &(idx, _, _)) in self.bounds.iter().enumerate() {
            h[(row + i, idx)] = 1.0;
        }
    }

    fn lagrangian_hessian(&self, z: &[f64], m: StageMultipliers<'_>, out: &mut DMatrix<f64>) {
        let sh = &self.shared;
        let q = self.point(z);
        out.as_mut_slice().fill(0.0);
        let inv_n = self.inv_n();
        let ti = self.t_index();
        // Cost: w q, w = T/N: w Hess(q) + (1/N)(e_T grad q^T + grad q e_T^T).
        let (_, w) = self.cost_terms(z, &q);
        let sw = m.cost * w;
        for j in 0..3 {
            out[(W + j, W + j)] += sw * 2.0 * sh.eps_omega;
        }
        let ltl = self.rot_err.transpose() * self.rot_err * (2.0 * sh.eps_r);
        for i in 0..9 {
            for j in 0..9 {
                out[(R + i, R + j)] += sw * ltl[(i, j)];
            }
        }
        if !self.last {
            for s in 0..4 {
                if self.contact[s] {
                    let u = self.u_index(s);
                    for j in 0..3 {
                        out[(u + j, u + j)] += sw * 2.0 * sh.eps_f;
                    }
                }
            }
        }
        if sh.cost_dt {
            // (1/N)(e_T grad q^T + grad q e_T^T), grad q as in `cost_gradient_q`.
            let c = m.cost * inv_n;
            for j in 0..3 {
                add_pair(out, ti, W + j, c * 2.0 * sh.eps_omega * q.w[j]);
            }
            let r9 = nalgebra::SVector::<f64, 9>::from_column_slice(&z[R..R + 9]);
            let gr = self.rot_err.transpose() * (self.rot_err * r9) * (2.0 * sh.eps_r);
            for j in 0..9 {
                add_pair(out, ti, R + j, c * gr[j]);
            }
            if !self.last {
                for s in 0..4 {
                    if self.contact[s] {
                        let u = self.u_index(s);
                        for j in 0..3 {
                            add_pair(out, ti, u + j, c * 2.0 * sh.eps_f * z[u + j]);
                        }
                    }
                }
            }
        }
        if !self.last {
            let lam = m.dynamics;
            // p+ = p + (T/N) v; v+ = v + (T/N)(F/m + g)
            for j in 0..3 {
                add_pair(out, ti, V + j, lam[P + j] * inv_n);
            }
            for s in 0..4 {
                if self.contact[s] {
                    let u = self.u_index(s);
                    for j in 0..3 {
                        add_pair(out, ti, u + j, lam[V + j] * inv_n / sh.mass);
                    }
                }
            }
            // Omega+ = Omega + (T/N) I^-1 a: lambda_W^T I^-1 a = mu^T a with mu = I^-1 lambda_W.
            let mu = sh.inertia_inv * Vector3::new(lam[W], lam[W + 1], lam[W + 2]);
            self.body_torque_hessian(&q, &mu, q.dt, Some(inv_n), out);
            // R+ = R E(omega), omega = (T/N) Omega: <Lambda, R E> = <R^T Lambda, E>.
            let big_l = Matrix3::from_fn(|a, b| lam[ridx(a, b)]);
            let mm = q.r.transpose() * big_l;
            let ed = exp_derivatives(sh.exp_map, &(q.w * q.dt));
            let inner = |a: &Matrix3<f64>, b: &Matrix3<f64>| a.component_mul(b).sum();
            let gamma: [f64; 3] = std::array::from_fn(|j| inner(&mm, &ed.first[j]));
            let big_g = Matrix3::from_fn(|i, j| inner(&mm, &ed.second[i][j]));
            for j in 0..3 {
                let le = big_l * ed.first[j].transpose();
                for c in 0..3 {
                    for d in 0..3 {
                        add_pair(out, ridx(c, d), W + j, q.dt * le[(c, d)]);
                        add_pair(out, ridx(c, d), ti, inv_n * q.w[j] * le[(c, d)]);
                    }
                }
            }
            for i in 0..3 {
                for j in 0..3 {
                    out[(W + i, W + j)] += q.dt * q.dt * big_g[(i, j)];
                }
            }
            let gw = big_g * q.w;
            for j in 0..3 {
                add_pair(out, W + j, ti, inv_n * gamma[j] + q.dt * inv_n * gw[j]);
            }
            out[(ti, ti)] += inv_n * inv_n * q.w.dot(&gw);
        }
        if self.knot == 0 {
            let nu = m.equalities;
            let mu = Vector3::new(nu[18], nu[19], nu[20]);
            self.body_torque_hessian(&q, &mu, 1.0, None, out);
        }
        // Sphere rows: Hess |d|^2 = 2 (J_d^T J_d + sum_a d_a Hess d_a).
        let y = m.inequalities;
        let first_row = if self.last { 0 } else { 4 * self.contact.iter().filter(|&&c| c).count() };
        for s in 0..4 {
            let ys = y[first_row + s];
            if ys == 0.0 {
                continue;
            }
            let (d, rows, count) = self.sphere(z, &q, s);
            for a in 0..3 {
                for &(i, ci) in &rows[a][..count] {
                    for &(j, cj) in &rows[a][..count] {
                        out[(i, j)] += 2.0 * ys * ci * cj;
                    }
                }
                // d_a = sum_c R_ca (pf_c - p_c) - pbar_a
                for c in 0..3 {
                    add_pair(out, ridx(c, a), P + c, -2.0 * ys * d[a]);
                    if !self.last && !self.contact[s] {
                        add_pair(out, ridx(c, a), self.u_index(s) + c, 2.0 * ys * d[a]);
                    }
                }
            }
        }
        // Box rows: the tuck point is linear in z, so the row's Hessian is J_a^T H_d J_a.
        if let Some(b) = &sh.platform {
            let first_box = self.n_general - self.n_box;
            for (i, s) in self.box_feet().enumerate() {
                let ys = y[first_box + i];
                if ys == 0.0 {
                    continue;
                }
                let (_, _, hd) = b.signed_distance(&self.tuck_point(&q, s));
                if hd.iter().all(|&v| v == 0.0) {
                    continue;
                }
                // Column c of H_d pulled back: J_a^T H_d e_c, then row by row.
                let mut cols = [[(0usize, 0.0f64); 12]; 3];
                for c in 0..3 {
                    let mut n = 0;
                    self.add_point_row(s, &hd.column(c).into_owned(), |j, v| {
                        cols[c][n] = (j, v);
                        n += 1;
                    });
                }
                // J_a's row c: e_c on p, t_b on R_cb.
                let mut jrow = [[(0usize, 0.0f64); 12]; 3];
                for c in 0..3 {
                    let mut e = Vector3::zeros();
                    e[c] = 1.0;
                    let mut n = 0;
                    self.add_point_row(s, &e, |j, v| {
                        jrow[c][n] = (j, v);
                        n += 1;
                    });
                }
                for c in 0..3 {
                    for &(i, vi) in &jrow[c] {
                        if vi == 0.0 {
                            continue;
                        }
                        for &(j, vj) in &cols[c] {
                            out[(i, j)] += ys * vi * vj;
                        }
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::PlatformBox;
    use nalgebra::Vector3;

    /// Gradient and Hessian of the signed distance against central differences on a face,
    /// an edge and a corner region outside the box, and inside it.
    #[test]
    fn box_signed_distance_derivatives_match_central_differences() {
        let b = PlatformBox { top: 0.3, x: [-0.5, 0.5], y: [-0.5, 0.147] };
        let h = 1e-6;
        for a in [Vector3::new(0.1, 0.2, 0.25), Vector3::new(0.1, 0.2, 0.36), Vector3::new(0.6, 0.2, 0.36), Vector3::new(0.1, 0.0, 0.2)] {
            let (d, g, hd) = b.signed_distance(&a);
            for i in 0..3 {
                let mut e = Vector3::zeros();
                e[i] = h;
                let (dp, gp, _) = b.signed_distance(&(a + e));
                let (dm, gm, _) = b.signed_distance(&(a - e));
                assert!(((dp - dm) / (2.0 * h) - g[i]).abs() < 1e-6, "{a:?}: gradient {i}");
                let col = (gp - gm) / (2.0 * h);
                assert!((col - hd.column(i)).amax() < 1e-5, "{a:?}: Hessian column {i}: {col:?} vs {:?}", hd.column(i));
            }
            assert!(d.is_finite());
        }
        // Beyond the +y edge and above the top: 3 cm from the edge along the diagonal.
        let (d, _, _) = b.signed_distance(&Vector3::new(0.0, 0.147 + 0.03, 0.3 + 0.04));
        assert!((d - 0.05).abs() < 1e-12);
    }
}
