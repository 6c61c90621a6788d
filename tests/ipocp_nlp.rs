//! ipocp on Hock-Schittkowski problems (Hock & Schittkowski 1981, "Test Examples for
//! Nonlinear Programming Codes"), each a one-stage problem, against the published optima.

use legwork::ipocp::{nlp_problem, BarrierUpdate, MuOracle, Nlp, Settings, Solver, Status};
use nalgebra::{DMatrix, DVector};

const INF: f64 = f64::INFINITY;

/// A problem given by closed-form functions: objective, equalities and inequalities with
/// their exact derivatives; simple bounds on `x` are appended as inequality rows.
struct Hs {
    n: usize,
    ng: usize,
    /// General inequality rows and their bounds.
    nh_general: usize,
    general_bounds: Vec<(f64, f64)>,
    /// Bounds on x (appended after the general rows, only the finite ones).
    x_bounds: Vec<(usize, f64, f64)>,
    f: fn(&[f64]) -> f64,
    grad: fn(&[f64], &mut [f64]),
    hess_f: fn(&[f64], &mut DMatrix<f64>, f64),
    /// Constraints c = [g; h_general], Jacobian rows, and Hessian of sum w_i c_i added to H.
    c: fn(&[f64], &mut [f64]),
    jac: fn(&[f64], &mut DMatrix<f64>),
    hess_c: fn(&[f64], &[f64], &mut DMatrix<f64>),
}

impl Nlp for Hs {
    fn sizes(&self) -> (usize, usize, usize) {
        (self.n, self.ng, self.nh_general + self.x_bounds.len())
    }
    fn inequality_bounds(&self, lower: &mut [f64], upper: &mut [f64]) {
        for (i, &(l, u)) in self.general_bounds.iter().enumerate() {
            lower[i] = l;
            upper[i] = u;
        }
        for (j, &(_, l, u)) in self.x_bounds.iter().enumerate() {
            lower[self.nh_general + j] = l;
            upper[self.nh_general + j] = u;
        }
    }
    fn evaluate(&self, x: &[f64], g: &mut [f64], h: &mut [f64]) -> f64 {
        let mut c = vec![0.0; self.ng + self.nh_general];
        (self.c)(x, &mut c);
        g.copy_from_slice(&c[..self.ng]);
        h[..self.nh_general].copy_from_slice(&c[self.ng..]);
        for (j, &(i, _, _)) in self.x_bounds.iter().enumerate() {
            h[self.nh_general + j] = x[i];
        }
        (self.f)(x)
    }
    fn jacobians(&self, x: &[f64], grad: &mut [f64], jg: &mut DMatrix<f64>, jh: &mut DMatrix<f64>) {
        (self.grad)(x, grad);
        let mut j = DMatrix::zeros(self.ng + self.nh_general, self.n);
        (self.jac)(x, &mut j);
        jg.copy_from(&j.rows(0, self.ng));
        jh.fill(0.0);
        jh.rows_mut(0, self.nh_general).copy_from(&j.rows(self.ng, self.nh_general));
        for (r, &(i, _, _)) in self.x_bounds.iter().enumerate() {
            jh[(self.nh_general + r, i)] = 1.0;
        }
    }
    fn lagrangian_hessian(&self, x: &[f64], sigma: f64, nu: &[f64], y: &[f64], out: &mut DMatrix<f64>) {
        out.fill(0.0);
        (self.hess_f)(x, out, sigma);
        let mut w = nu.to_vec();
        w.extend_from_slice(&y[..self.nh_general]);
        (self.hess_c)(x, &w, out);
    }
}

fn solve(p: Hs, x0: &[f64]) -> legwork::ipocp::SolveResult {
    let problem = nlp_problem(p).unwrap();
    let mut solver = Solver::new(&problem, Settings::default()).unwrap();
    solver.solve(&problem, &[DVector::from_column_slice(x0)]).unwrap()
}

fn hs071() -> Hs {
    Hs {
        n: 4,
        ng: 1,
        nh_general: 1,
        general_bounds: vec![(25.0, INF)],
        x_bounds: (0..4).map(|i| (i, 1.0, 5.0)).collect(),
        f: |x| x[0] * x[3] * (x[0] + x[1] + x[2]) + x[2],
        grad: |x, g| {
            g[0] = x[3] * (2.0 * x[0] + x[1] + x[2]);
            g[1] = x[0] * x[3];
            g[2] = x[0] * x[3] + 1.0;
            g[3] = x[0] * (x[0] + x[1] + x[2]);
        },
        hess_f: |x, h, s| {
            let mut a = DMatrix::zeros(4, 4);
            a[(0, 0)] = 2.0 * x[3];
            a[(0, 1)] = x[3];
            a[(0, 2)] = x[3];
            a[(0, 3)] = 2.0 * x[0] + x[1] + x[2];
            a[(1, 3)] = x[0];
            a[(2, 3)] = x[0];
            let a = &a + a.transpose() - DMatrix::from_diagonal(&a.diagonal());
            *h += a * s;
        },
        c: |x, c| {
            c[0] = x.iter().map(|v| v * v).sum::<f64>() - 40.0;
            c[1] = x[0] * x[1] * x[2] * x[3];
        },
        jac: |x, j| {
            for i in 0..4 {
                j[(0, i)] = 2.0 * x[i];
            }
            j[(1, 0)] = x[1] * x[2] * x[3];
            j[(1, 1)] = x[0] * x[2] * x[3];
            j[(1, 2)] = x[0] * x[1] * x[3];
            j[(1, 3)] = x[0] * x[1] * x[2];
        },
        hess_c: |x, w, h| {
            for i in 0..4 {
                h[(i, i)] += 2.0 * w[0];
            }
            for i in 0..4 {
                for k in 0..4 {
                    if i != k {
                        let p: f64 = (0..4).filter(|&l| l != i && l != k).map(|l| x[l]).product();
                        h[(i, k)] += w[1] * p;
                    }
                }
            }
        },
    }
}

#[test]
fn hs071_reaches_the_published_optimum() {
    let r = solve(hs071(), &[1.0, 5.0, 5.0, 1.0]);
    assert_eq!(r.status, Status::Solved);
    assert!((r.objective - 17.014_017_3).abs() < 1e-6, "{}", r.objective);
    let x = &r.last.primal[0];
    let expected = [1.0, 4.742_999_64, 3.821_149_98, 1.379_408_29];
    for i in 0..4 {
        assert!((x[i] - expected[i]).abs() < 1e-6, "x = {x}");
    }
    // IPOPT takes 8 iterations on HS071 from this start.
    assert!(r.iterations <= 15, "{} iterations", r.iterations);
}

/// The adaptive barrier updates (Nocedal, Wächter & Waltz 2009) reach HS071's optimum too.
#[test]
fn hs071_with_the_adaptive_barrier_updates() {
    for oracle in [MuOracle::Probing, MuOracle::QualityFunction, MuOracle::Loqo] {
        let problem = nlp_problem(hs071()).unwrap();
        let mut solver = Solver::new(&problem, Settings { barrier_update: BarrierUpdate::Adaptive(oracle), ..Settings::default() }).unwrap();
        let r = solver.solve(&problem, &[DVector::from_column_slice(&[1.0, 5.0, 5.0, 1.0])]).unwrap();
        assert_eq!(r.status, Status::Solved, "{oracle:?}");
        assert!((r.objective - 17.014_017_3).abs() < 1e-6, "{oracle:?}: {}", r.objective);
        let x = &r.last.primal[0];
        let expected = [1.0, 4.742_999_64, 3.821_149_98, 1.379_408_29];
        for i in 0..4 {
            assert!((x[i] - expected[i]).abs() < 1e-6, "{oracle:?}: x = {x}");
        }
        assert!(r.iterations <= 15, "{oracle:?}: {} iterations", r.iterations);
    }
}

#[test]
fn hs035_quadratic_with_a_linear_inequality() {
    let p = Hs {
        n: 3,
        ng: 0,
        nh_general: 1,
        general_bounds: vec![(-INF, 3.0)],
        x_bounds: (0..3).map(|i| (i, 0.0, INF)).collect(),
        f: |x| 9.0 - 8.0 * x[0] - 6.0 * x[1] - 4.0 * x[2] + 2.0 * x[0] * x[0] + 2.0 * x[1] * x[1] + x[2] * x[2] + 2.0 * x[0] * x[1] + 2.0 * x[0] * x[2],
        grad: |x, g| {
            g[0] = -8.0 + 4.0 * x[0] + 2.0 * x[1] + 2.0 * x[2];
            g[1] = -6.0 + 4.0 * x[1] + 2.0 * x[0];
            g[2] = -4.0 + 2.0 * x[2] + 2.0 * x[0];
        },
        hess_f: |_, h, s| {
            *h += DMatrix::from_row_slice(3, 3, &[4.0, 2.0, 2.0, 2.0, 4.0, 0.0, 2.0, 0.0, 2.0]) * s;
        },
        c: |x, c| c[0] = x[0] + x[1] + 2.0 * x[2],
        jac: |_, j| j.row_mut(0).copy_from_slice(&[1.0, 1.0, 2.0]),
        hess_c: |_, _, _| {},
    };
    let r = solve(p, &[0.5, 0.5, 0.5]);
    assert_eq!(r.status, Status::Solved);
    assert!((r.objective - 1.0 / 9.0).abs() < 1e-7, "{}", r.objective);
    let x = &r.last.primal[0];
    for (xi, e) in x.iter().zip([4.0 / 3.0, 7.0 / 9.0, 4.0 / 9.0]) {
        assert!((xi - e).abs() < 1e-6, "x = {x}");
    }
}

#[test]
fn hs040_nonlinear_equalities_only() {
    let p = Hs {
        n: 4,
        ng: 3,
        nh_general: 0,
        general_bounds: vec![],
        x_bounds: vec![],
        f: |x| -x[0] * x[1] * x[2] * x[3],
        grad: |x, g| {
            g[0] = -x[1] * x[2] * x[3];
            g[1] = -x[0] * x[2] * x[3];
            g[2] = -x[0] * x[1] * x[3];
            g[3] = -x[0] * x[1] * x[2];
        },
        hess_f: |x, h, s| {
            for i in 0..4 {
                for k in 0..4 {
                    if i != k {
                        let p: f64 = (0..4).filter(|&l| l != i && l != k).map(|l| x[l]).product();
                        h[(i, k)] -= s * p;
                    }
                }
            }
        },
        c: |x, c| {
            c[0] = x[0].powi(3) + x[1] * x[1] - 1.0;
            c[1] = x[0] * x[0] * x[3] - x[2];
            c[2] = x[3] * x[3] - x[1];
        },
        jac: |x, j| {
            j.fill(0.0);
            j[(0, 0)] = 3.0 * x[0] * x[0];
            j[(0, 1)] = 2.0 * x[1];
            j[(1, 0)] = 2.0 * x[0] * x[3];
            j[(1, 3)] = x[0] * x[0];
            j[(1, 2)] = -1.0;
            j[(2, 3)] = 2.0 * x[3];
            j[(2, 1)] = -1.0;
        },
        hess_c: |x, w, h| {
            h[(0, 0)] += w[0] * 6.0 * x[0] + w[1] * 2.0 * x[3];
            h[(1, 1)] += w[0] * 2.0;
            h[(0, 3)] += w[1] * 2.0 * x[0];
            h[(3, 0)] += w[1] * 2.0 * x[0];
            h[(3, 3)] += w[2] * 2.0;
        },
    };
    let r = solve(p, &[0.8, 0.8, 0.8, 0.8]);
    assert_eq!(r.status, Status::Solved);
    assert!((r.objective + 0.25).abs() < 1e-8, "{}", r.objective);
    let x = &r.last.primal[0];
    let e = [2f64.powf(-1.0 / 3.0), 2f64.powf(-0.5), 2f64.powf(-11.0 / 12.0), 2f64.powf(-0.25)];
    for i in 0..4 {
        assert!((x[i] - e[i]).abs() < 1e-6, "x = {x}");
    }
}

#[test]
fn hs076_quadratic_with_three_linear_inequalities() {
    let p = Hs {
        n: 4,
        ng: 0,
        nh_general: 3,
        general_bounds: vec![(-INF, 5.0), (-INF, 4.0), (1.5, INF)],
        x_bounds: (0..4).map(|i| (i, 0.0, INF)).collect(),
        f: |x| {
            x[0] * x[0] + 0.5 * x[1] * x[1] + x[2] * x[2] + 0.5 * x[3] * x[3] - x[0] * x[2] + x[2] * x[3] - x[0] - 3.0 * x[1] + x[2] - x[3]
        },
        grad: |x, g| {
            g[0] = 2.0 * x[0] - x[2] - 1.0;
            g[1] = x[1] - 3.0;
            g[2] = 2.0 * x[2] - x[0] + x[3] + 1.0;
            g[3] = x[3] + x[2] - 1.0;
        },
        hess_f: |_, h, s| {
            *h += DMatrix::from_row_slice(4, 4, &[2.0, 0.0, -1.0, 0.0, 0.0, 1.0, 0.0, 0.0, -1.0, 0.0, 2.0, 1.0, 0.0, 0.0, 1.0, 1.0]) * s;
        },
        c: |x, c| {
            c[0] = x[0] + 2.0 * x[1] + x[2] + x[3];
            c[1] = 3.0 * x[0] + x[1] + 2.0 * x[2] - x[3];
            c[2] = x[1] + 4.0 * x[2];
        },
        jac: |_, j| {
            j.copy_from(&DMatrix::from_row_slice(3, 4, &[1.0, 2.0, 1.0, 1.0, 3.0, 1.0, 2.0, -1.0, 0.0, 1.0, 4.0, 0.0]));
        },
        hess_c: |_, _, _| {},
    };
    let r = solve(p, &[0.5; 4]);
    assert_eq!(r.status, Status::Solved);
    assert!((r.objective + 4.681_818_181).abs() < 1e-7, "{}", r.objective);
    let x = &r.last.primal[0];
    for (xi, e) in x.iter().zip([0.272_727_3, 2.090_909, 0.0, 0.545_454_5]) {
        assert!((xi - e).abs() < 1e-6, "x = {x}");
    }
}

#[test]
fn hs015_rosenbrock_with_nonconvex_constraints() {
    let p = Hs {
        n: 2,
        ng: 0,
        nh_general: 2,
        general_bounds: vec![(1.0, INF), (0.0, INF)],
        x_bounds: vec![(0, -INF, 0.5)],
        f: |x| 100.0 * (x[1] - x[0] * x[0]).powi(2) + (1.0 - x[0]).powi(2),
        grad: |x, g| {
            g[0] = -400.0 * x[0] * (x[1] - x[0] * x[0]) - 2.0 * (1.0 - x[0]);
            g[1] = 200.0 * (x[1] - x[0] * x[0]);
        },
        hess_f: |x, h, s| {
            h[(0, 0)] += s * (1200.0 * x[0] * x[0] - 400.0 * x[1] + 2.0);
            h[(0, 1)] += s * (-400.0 * x[0]);
            h[(1, 0)] += s * (-400.0 * x[0]);
            h[(1, 1)] += s * 200.0;
        },
        c: |x, c| {
            c[0] = x[0] * x[1];
            c[1] = x[0] + x[1] * x[1];
        },
        jac: |x, j| {
            j.copy_from(&DMatrix::from_row_slice(2, 2, &[x[1], x[0], 1.0, 2.0 * x[1]]));
        },
        hess_c: |_, w, h| {
            h[(0, 1)] += w[0];
            h[(1, 0)] += w[0];
            h[(1, 1)] += 2.0 * w[1];
        },
    };
    let r = solve(p, &[-2.0, 1.0]);
    assert_eq!(r.status, Status::Solved);
    assert!((r.objective - 306.5).abs() < 1e-6, "{}", r.objective);
    let x = &r.last.primal[0];
    assert!((x[0] - 0.5).abs() < 1e-7 && (x[1] - 2.0).abs() < 1e-6, "x = {x}");
}

#[test]
fn hs021_bounds_and_one_linear_inequality() {
    let p = Hs {
        n: 2,
        ng: 0,
        nh_general: 1,
        general_bounds: vec![(10.0, INF)],
        x_bounds: vec![(0, 2.0, 50.0), (1, -50.0, 50.0)],
        f: |x| 0.01 * x[0] * x[0] + x[1] * x[1] - 100.0,
        grad: |x, g| {
            g[0] = 0.02 * x[0];
            g[1] = 2.0 * x[1];
        },
        hess_f: |_, h, s| {
            h[(0, 0)] += 0.02 * s;
            h[(1, 1)] += 2.0 * s;
        },
        c: |x, c| c[0] = 10.0 * x[0] - x[1],
        jac: |_, j| j.row_mut(0).copy_from_slice(&[10.0, -1.0]),
        hess_c: |_, _, _| {},
    };
    let r = solve(p, &[-1.0, -1.0]);
    assert_eq!(r.status, Status::Solved);
    assert!((r.objective + 99.96).abs() < 1e-7, "{}", r.objective);
    let x = &r.last.primal[0];
    assert!((x[0] - 2.0).abs() < 1e-6 && x[1].abs() < 1e-6, "x = {x}");
}

#[test]
fn iteration_limit_keeps_the_best_iterate() {
    let problem = nlp_problem(hs071()).unwrap();
    let settings = Settings { max_iterations: 3, ..Settings::default() };
    let mut solver = Solver::new(&problem, settings).unwrap();
    let r = solver.solve(&problem, &[DVector::from_column_slice(&[1.0, 5.0, 5.0, 1.0])]).unwrap();
    assert_eq!(r.status, Status::MaxIterations);
    assert_eq!(r.iterations, 3);
    // The best iterate is the one with the smallest optimality error seen, and it is kept.
    assert!(r.best_optimality_error <= r.optimality_error);
    assert!(r.best_optimality_error.is_finite() && r.best_iteration <= 3);
    assert_eq!(r.best.primal[0].len(), 4);
    // Restarting from the best iterate (primal and duals) converges to the optimum.
    let duals = legwork::ipocp::Duals {
        dynamics_multiplier: r.best.dynamics_multiplier.clone(),
        equality_multiplier: r.best.equality_multiplier.clone(),
        inequality_multiplier: r.best.inequality_multiplier.clone(),
        lower_bound_multiplier: r.best.lower_bound_multiplier.clone(),
        upper_bound_multiplier: r.best.upper_bound_multiplier.clone(),
    };
    let mut solver = Solver::new(&problem, Settings { mu_init: 1e-3, ..Settings::default() }).unwrap();
    let warm = solver.solve_warm(&problem, &r.best.primal, Some(&duals)).unwrap();
    assert_eq!(warm.status, Status::Solved);
    assert!((warm.objective - 17.014_017_3).abs() < 1e-6);
}

#[test]
fn infeasible_problem_is_reported() {
    // min x1^2 + x2^2  s.t.  x1^2 + x2^2 + 1 = 0: no real point satisfies the constraint.
    let p = Hs {
        n: 2,
        ng: 1,
        nh_general: 0,
        general_bounds: vec![],
        x_bounds: vec![],
        f: |x| x[0] * x[0] + x[1] * x[1],
        grad: |x, g| {
            g[0] = 2.0 * x[0];
            g[1] = 2.0 * x[1];
        },
        hess_f: |_, h, s| {
            h[(0, 0)] += 2.0 * s;
            h[(1, 1)] += 2.0 * s;
        },
        c: |x, c| c[0] = x[0] * x[0] + x[1] * x[1] + 1.0,
        jac: |x, j| j.row_mut(0).copy_from_slice(&[2.0 * x[0], 2.0 * x[1]]),
        hess_c: |_, w, h| {
            h[(0, 0)] += 2.0 * w[0];
            h[(1, 1)] += 2.0 * w[0];
        },
    };
    let r = solve(p, &[1.0, 0.5]);
    assert_eq!(r.status, Status::LocallyInfeasible, "{:?} after {} iterations", r.status, r.iterations);
    // The violation cannot go below 1 (its value at x = 0).
    assert!(r.primal_infeasibility >= 1.0 - 1e-12);
    assert!(r.iterations < 100);
}
