//! Feasibility restoration (Wächter & Biegler 2006, sec. 3.3), stage-wise.
//!
//! When the filter line search cannot find an acceptable step from a point whose
//! constraints are violated, IPOPT minimizes the violation instead (eq. 30):
//!
//! ```text
//! min  rho sum(p + n) + zeta/2 |D_R (z - z_R)|^2
//! s.t. c(z) - p + n = 0,   p, n >= 0,   the original bounds
//! ```
//!
//! with `z_R` the point where the line search failed, `zeta = sqrt(mu)`,
//! `D_R = diag(min(1, 1/|z_R,i|))`, solved by the same interior-point algorithm, and returns
//! to the main loop as soon as the original filter accepts the point and the violation has
//! dropped to `kappa_resto theta(z_R)` (IPOPT's `required_infeasibility_reduction`).
//!
//! Here every constraint row belongs to one stage (the dynamics defect `f_k(z_k) - x_{k+1}`
//! to stage `k`), so the elastic pair `(p, n)` of a row is a stage-local variable: the
//! restoration problem is again a stage-wise problem for the Riccati recursion,
//!
//! ```text
//! stage k < N:  x_k,  u_k^R = [u_k; p_k; n_k]           x_{k+1} = f_k(z_k) - p_k^f + n_k^f
//! stage N:      x_N^R = [x_N; p_N; n_N]                 (p_N, n_N carried as controls of stage N-1)
//!               g_k(z_k) - p_k^g + n_k^g = 0
//!               lower <= h_k(z_k) - p_k^h + n_k^h <= upper,   p_k, n_k >= 0
//! ```
//!
//! (the last stage has no control, so its elastics enter as states set by stage `N - 1`; a
//! one-stage problem, an NLP, has them as states directly). Inequality rows get an elastic
//! pair only where `h` is outside its bounds at `z_R`: the others stay satisfied during the
//! restoration, which keeps the controls few (the restoration's feasible set is then smaller
//! than IPOPT's, but contains the original one).

// Index loops over rows and columns read like the equations they implement.
#![allow(clippy::needless_range_loop)]

use super::filter::Filter;
use super::iterate::{Duals, Iterate, Status, Timings};
use super::problem::Problem;
use super::settings::{BarrierUpdate, Settings};
use super::solver::{barrier, violation_1, Solver};
use super::stage::{Stage, StageDims, StageJacobians, StageMultipliers, StageValues};
use nalgebra::{DMatrix, DVector};
use std::sync::{Arc, Mutex};

/// How one restoration ended.
pub(super) struct Restoration {
    /// The restored point (primal, slacks, bound multipliers of the original problem; the
    /// constraint multipliers zero), if the filter accepted one.
    pub iterate: Option<Iterate>,
    pub iterations: usize,
    pub timings: Timings,
}

/// Where a stage's elastic variables sit in its restoration variable `z^R`.
#[derive(Clone, Debug)]
struct ElasticLayout {
    /// The original stage's sizes.
    inner: StageDims,
    /// Inequality rows with an elastic pair.
    elastic_rows: Vec<usize>,
    /// Elastic rows: `nx_next + ng + elastic_rows.len()`; `p` at `offset..offset + m`, `n`
    /// at `offset + m..offset + 2 m` with `offset = inner.nz()`.
    m: usize,
    /// Elastics of the last stage carried by this stage's controls (stage `N - 1` only):
    /// `2 m_N` entries after its own.
    carry: usize,
    last: bool,
}

impl ElasticLayout {
    fn offset(&self) -> usize {
        self.inner.nz()
    }

    fn dims(&self) -> StageDims {
        let d = self.inner;
        if self.last {
            StageDims { nx: d.nx + 2 * self.m, nu: 0, nx_next: 0, ng: d.ng, nh: d.nh + 2 * self.m }
        } else {
            StageDims { nx: d.nx, nu: d.nu + 2 * self.m + self.carry, nx_next: d.nx_next + self.carry, ng: d.ng, nh: d.nh + 2 * self.m }
        }
    }
}

/// Scratch of the wrapped stage's evaluations.
struct Scratch {
    values: StageValues,
    jac: StageJacobians,
    hess: DMatrix<f64>,
}

/// A stage of the restoration problem: the original stage with elastic rows, the l1 penalty
/// and the proximity term as its cost.
struct ElasticStage {
    inner: Arc<dyn Stage>,
    layout: ElasticLayout,
    lower: Vec<f64>,
    upper: Vec<f64>,
    rho: f64,
    zeta: f64,
    /// `z_R` (original variables) and `D_R^2`.
    reference: DVector<f64>,
    scaling: DVector<f64>,
    scratch: Mutex<Scratch>,
}

impl ElasticStage {
    fn scratch(&self) -> std::sync::MutexGuard<'_, Scratch> {
        self.scratch.lock().unwrap_or_else(|e| e.into_inner())
    }
}

impl Stage for ElasticStage {
    fn dims(&self) -> StageDims {
        self.layout.dims()
    }

    fn inequality_bounds(&self, lower: &mut [f64], upper: &mut [f64]) {
        let nh = self.layout.inner.nh;
        lower[..nh].copy_from_slice(&self.lower);
        upper[..nh].copy_from_slice(&self.upper);
        for i in nh..lower.len() {
            lower[i] = 0.0;
            upper[i] = f64::INFINITY;
        }
    }

    fn evaluate(&self, z: &[f64], out: &mut StageValues) {
        let l = &self.layout;
        let d = l.inner;
        let (o, m) = (l.offset(), l.m);
        let mut guard = self.scratch();
        let v = &mut guard.values;
        self.inner.evaluate(&z[..d.nz()], v);
        // rho sum(p + n) + zeta/2 |D_R (z - z_R)|^2 (eq. 30).
        let mut cost = 0.0;
        for i in 0..d.nz() {
            let e = z[i] - self.reference[i];
            cost += 0.5 * self.zeta * self.scaling[i] * e * e;
        }
        for r in 0..2 * m {
            cost += self.rho * z[o + r];
        }
        out.cost = cost;
        let elastic = |r: usize| -z[o + r] + z[o + m + r];
        for r in 0..d.nx_next {
            out.dynamics[r] = v.dynamics[r] + elastic(r);
        }
        for j in 0..l.carry {
            out.dynamics[d.nx_next + j] = z[o + 2 * m + j];
        }
        for i in 0..d.ng {
            out.equalities[i] = v.equalities[i] + elastic(d.nx_next + i);
        }
        out.inequalities.rows_mut(0, d.nh).copy_from(&v.inequalities);
        for (e, &i) in l.elastic_rows.iter().enumerate() {
            out.inequalities[i] += elastic(d.nx_next + d.ng + e);
        }
        for r in 0..2 * m {
            out.inequalities[d.nh + r] = z[o + r];
        }
    }

    fn jacobians(&self, z: &[f64], out: &mut StageJacobians) {
        let l = &self.layout;
        let d = l.inner;
        let (o, m, nz) = (l.offset(), l.m, d.nz());
        let mut guard = self.scratch();
        let jac = &mut guard.jac;
        self.inner.jacobians(&z[..nz], jac);
        out.cost_gradient.fill(0.0);
        for i in 0..nz {
            out.cost_gradient[i] = self.zeta * self.scaling[i] * (z[i] - self.reference[i]);
        }
        for r in 0..2 * m {
            out.cost_gradient[o + r] = self.rho;
        }
        out.dynamics.fill(0.0);
        out.dynamics.view_mut((0, 0), (d.nx_next, nz)).copy_from(&jac.dynamics);
        for r in 0..d.nx_next {
            out.dynamics[(r, o + r)] = -1.0;
            out.dynamics[(r, o + m + r)] = 1.0;
        }
        for j in 0..l.carry {
            out.dynamics[(d.nx_next + j, o + 2 * m + j)] = 1.0;
        }
        out.equalities.fill(0.0);
        out.equalities.view_mut((0, 0), (d.ng, nz)).copy_from(&jac.equalities);
        for i in 0..d.ng {
            out.equalities[(i, o + d.nx_next + i)] = -1.0;
            out.equalities[(i, o + m + d.nx_next + i)] = 1.0;
        }
        out.inequalities.fill(0.0);
        out.inequalities.view_mut((0, 0), (d.nh, nz)).copy_from(&jac.inequalities);
        for (e, &i) in l.elastic_rows.iter().enumerate() {
            let r = d.nx_next + d.ng + e;
            out.inequalities[(i, o + r)] = -1.0;
            out.inequalities[(i, o + m + r)] = 1.0;
        }
        for r in 0..2 * m {
            out.inequalities[(d.nh + r, o + r)] = 1.0;
        }
    }

    fn lagrangian_hessian(&self, z: &[f64], multipliers: StageMultipliers<'_>, out: &mut DMatrix<f64>) {
        // The elastic rows are linear in (p, n): the constraints' curvature is the original
        // stage's with the same multipliers; the cost's is the proximity term's alone (a
        // Gauss-Newton stage returns its cost's curvature whatever the weights, scaled by
        // the cost weight, here 0).
        let d = self.layout.inner;
        let nz = d.nz();
        let mut guard = self.scratch();
        let hess = &mut guard.hess;
        let m = StageMultipliers {
            cost: 0.0,
            dynamics: &multipliers.dynamics[..d.nx_next],
            equalities: multipliers.equalities,
            inequalities: &multipliers.inequalities[..d.nh],
        };
        self.inner.lagrangian_hessian(&z[..nz], m, hess);
        out.fill(0.0);
        out.view_mut((0, 0), (nz, nz)).copy_from(hess);
        for i in 0..nz {
            out[(i, i)] += self.zeta * self.scaling[i];
        }
    }
}

/// IPOPT's closed-form start of the elastic pair of a residual `c` (eq. 33): the minimizer
/// of `rho (p + n) - mu (ln p + ln n)` subject to `p - n = c`.
fn elastic_start(c: f64, rho: f64, mu: f64) -> (f64, f64) {
    let a = (mu - rho * c) / (2.0 * rho);
    let n = a + (a * a + mu * c / (2.0 * rho)).sqrt();
    (c + n, n)
}

/// The restoration phase from `it`, where the line search failed with barrier parameter
/// `mu`. The filter is augmented by `it`'s `(theta, phi)` (Algorithm A, step A-9), and the
/// restored point must be acceptable to it.
pub(super) fn restore(problem: &Problem, it: &Iterate, mu: f64, settings: &Settings, filter: &mut Filter) -> Restoration {
    let n_stages = problem.len();
    let dims = problem.dims();
    let rho = settings.restoration_penalty;
    // Residuals at z_R.
    let mut values: Vec<StageValues> = dims.iter().map(|&d| StageValues::zeros(d)).collect();
    let (mut theta_r, mut phi_r) = (0.0, 0.0);
    for k in 0..n_stages {
        problem.stage(k).evaluate(it.primal[k].as_slice(), &mut values[k]);
        let (lo, up) = problem.bounds(k);
        theta_r += violation_1(&values[k], it.primal.get(k + 1), dims[k].nx_next, &it.slack[k]);
        phi_r += values[k].cost + barrier(&it.slack[k], lo, up, mu);
    }
    filter.add((1.0 - settings.gamma_theta) * theta_r, phi_r - settings.gamma_phi * theta_r);

    // Elastic layout and residuals c_k (dynamics defects, g, h - s of the rows outside
    // their bounds).
    let mut layouts = Vec::with_capacity(n_stages);
    let mut residuals: Vec<Vec<f64>> = Vec::with_capacity(n_stages);
    let mut largest_residual: f64 = 0.0;
    for k in 0..n_stages {
        let d = dims[k];
        let (lo, up) = problem.bounds(k);
        let v = &values[k];
        let elastic_rows: Vec<usize> = (0..d.nh).filter(|&i| v.inequalities[i] <= lo[i] || v.inequalities[i] >= up[i]).collect();
        let mut c = Vec::with_capacity(d.nx_next + d.ng + elastic_rows.len());
        c.extend((0..d.nx_next).map(|i| v.dynamics[i] - it.primal[k + 1][i]));
        c.extend(v.equalities.iter().copied());
        c.extend(elastic_rows.iter().map(|&i| v.inequalities[i] - it.slack[k][i]));
        largest_residual = c.iter().fold(largest_residual, |a, x| a.max(x.abs()));
        layouts.push(ElasticLayout { inner: d, m: c.len(), elastic_rows, carry: 0, last: k + 1 == n_stages });
        residuals.push(c);
    }
    if n_stages > 1 {
        layouts[n_stages - 2].carry = 2 * layouts[n_stages - 1].m;
    }
    let mu_r = mu.max(largest_residual);
    let zeta = mu.sqrt();

    // Starting point of the restoration problem and its bound multipliers.
    let mut elastics: Vec<(Vec<f64>, Vec<f64>)> = residuals.iter().map(|c| c.iter().map(|&ci| elastic_start(ci, rho, mu_r)).unzip()).collect();
    let mut primal = Vec::with_capacity(n_stages);
    let mut stages: Vec<Box<dyn Stage>> = Vec::with_capacity(n_stages);
    let mut duals = Duals {
        dynamics_multiplier: Vec::new(),
        equality_multiplier: Vec::new(),
        inequality_multiplier: Vec::new(),
        lower_bound_multiplier: Vec::new(),
        upper_bound_multiplier: Vec::new(),
    };
    for k in 0..n_stages {
        let l = &layouts[k];
        let rd = l.dims();
        let d = l.inner;
        let (p, n) = &elastics[k];
        let mut z = DVector::zeros(rd.nz());
        z.rows_mut(0, d.nz()).copy_from(&it.primal[k]);
        z.rows_mut(l.offset(), l.m).copy_from_slice(p);
        z.rows_mut(l.offset() + l.m, l.m).copy_from_slice(n);
        if l.carry > 0 {
            let (pn, nn) = &elastics[k + 1];
            z.rows_mut(l.offset() + 2 * l.m, pn.len()).copy_from_slice(pn);
            z.rows_mut(l.offset() + 2 * l.m + pn.len(), nn.len()).copy_from_slice(nn);
        }
        primal.push(z);
        let mut zl = DVector::zeros(rd.nh);
        let mut zu = DVector::zeros(rd.nh);
        for i in 0..d.nh {
            zl[i] = it.lower_bound_multiplier[k][i].min(rho);
            zu[i] = it.upper_bound_multiplier[k][i].min(rho);
        }
        for r in 0..l.m {
            zl[d.nh + r] = mu_r / p[r];
            zl[d.nh + l.m + r] = mu_r / n[r];
        }
        duals.dynamics_multiplier.push(DVector::zeros(rd.nx_next));
        duals.equality_multiplier.push(DVector::zeros(rd.ng));
        duals.inequality_multiplier.push(DVector::zeros(rd.nh));
        duals.lower_bound_multiplier.push(zl);
        duals.upper_bound_multiplier.push(zu);
        let (lo, up) = problem.bounds(k);
        let reference = it.primal[k].clone();
        let scaling = reference.map(|r| 1.0f64.min(1.0 / r.abs()).powi(2));
        stages.push(Box::new(ElasticStage {
            inner: problem.stage_shared(k),
            layout: l.clone(),
            lower: lo.to_vec(),
            upper: up.to_vec(),
            rho,
            zeta,
            reference,
            scaling,
            scratch: Mutex::new(Scratch { values: StageValues::zeros(d), jac: StageJacobians::zeros(d), hess: DMatrix::zeros(d.nz(), d.nz()) }),
        }));
    }
    elastics.clear();
    let failed = |iterations, timings| Restoration { iterate: None, iterations, timings };
    let Ok(resto) = Problem::new(stages) else {
        return failed(0, Timings::default());
    };
    let sub_settings = Settings {
        // The restoration problem starts from the original problem's `mu` (sec. 3.3).
        barrier_update: BarrierUpdate::Monotone,
        mu_init: mu_r,
        least_squares_multipliers: false,
        max_iterations: settings.restoration_max_iterations,
        restoration: false,
        ..settings.clone()
    };
    let Ok(mut solver) = Solver::new(&resto, sub_settings) else {
        return failed(0, Timings::default());
    };

    // Return as soon as the original problem's filter accepts the point and the violation
    // has dropped enough (IPOPT's restoration convergence check).
    let mut accepted = false;
    // The original slacks and next states of a restoration iterate (buffers: the test runs
    // once per restoration iteration).
    let mut slacks: Vec<DVector<f64>> = dims.iter().map(|d| DVector::zeros(d.nh)).collect();
    let mut nexts: Vec<DVector<f64>> = dims.iter().map(|d| DVector::zeros(d.nx_next)).collect();
    let mut exit = |_: usize, r: &Iterate, _: f64| -> bool {
        let (mut theta, mut phi) = (0.0, 0.0);
        for k in 0..n_stages {
            let d = dims[k];
            let (lo, up) = problem.bounds(k);
            problem.stage(k).evaluate(&r.primal[k].as_slice()[..d.nz()], &mut values[k]);
            slacks[k].copy_from(&r.slack[k].rows(0, d.nh));
            let next = if k + 1 < n_stages {
                nexts[k].copy_from(&r.primal[k + 1].rows(0, d.nx_next));
                Some(&nexts[k])
            } else {
                None
            };
            theta += violation_1(&values[k], next, d.nx_next, &slacks[k]);
            phi += values[k].cost + barrier(&slacks[k], lo, up, mu);
        }
        accepted = theta <= settings.restoration_reduction * theta_r && filter.acceptable(theta, phi);
        accepted
    };
    let Ok(result) = solver.solve_with_exit(&resto, &primal, Some(&duals), Some(&mut exit)) else {
        return failed(0, Timings::default());
    };
    if !(accepted && result.status == Status::Solved) {
        return failed(result.iterations, result.timings);
    }
    // Back to the original variables.
    let r = &result.last;
    let mut restored = it.clone();
    for k in 0..n_stages {
        let d = dims[k];
        restored.primal[k].copy_from(&r.primal[k].rows(0, d.nz()));
        restored.slack[k].copy_from(&r.slack[k].rows(0, d.nh));
        restored.lower_bound_multiplier[k].copy_from(&r.lower_bound_multiplier[k].rows(0, d.nh));
        restored.upper_bound_multiplier[k].copy_from(&r.upper_bound_multiplier[k].rows(0, d.nh));
        restored.dynamics_multiplier[k].fill(0.0);
        restored.equality_multiplier[k].fill(0.0);
        restored.inequality_multiplier[k].fill(0.0);
    }
    Restoration { iterate: Some(restored), iterations: result.iterations, timings: result.timings }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn elastic_start_solves_its_barrier_problem() {
        // p - n = c and rho - mu/p = 0 = rho - mu/n shifted by the same multiplier:
        // rho - mu/p + y = 0, rho - mu/n - y = 0  =>  2 rho = mu/p + mu/n.
        for &(c, rho, mu) in &[(0.3, 1e3, 0.1), (-2.0, 1e3, 1e-2), (0.0, 10.0, 1.0), (5.0, 1e3, 5.0)] {
            let (p, n) = elastic_start(c, rho, mu);
            assert!(p > 0.0 && n > 0.0);
            assert!((p - n - c).abs() < 1e-12 * (1.0 + c.abs()));
            assert!((mu / p + mu / n - 2.0 * rho).abs() < 1e-8 * rho, "{c} {rho} {mu}: {p} {n}");
        }
    }
}
