//! ipocp on linear-quadratic optimal-control problems: a discrete LQR with an
//! equality-constrained terminal state against its dense KKT solution, and a
//! box-constrained LQ against Clarabel.

use clarabel::algebra::CscMatrix;
use clarabel::solver::{DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT};
use legwork::ipocp::{BarrierUpdate, MuOracle, Problem, Settings, Solver, Stage, StageDims, StageJacobians, StageMultipliers, StageValues, Status};
use nalgebra::{DMatrix, DVector};

/// `l = 1/2 z^T W z + w^T z`, `x+ = F z`, `G z = c`, `lower <= H z <= upper`.
#[derive(Clone)]
struct LqStage {
    dims: StageDims,
    w: DMatrix<f64>,
    wl: DVector<f64>,
    f: DMatrix<f64>,
    g: DMatrix<f64>,
    c: DVector<f64>,
    h: DMatrix<f64>,
    lower: Vec<f64>,
    upper: Vec<f64>,
}

impl Stage for LqStage {
    fn dims(&self) -> StageDims {
        self.dims
    }
    fn inequality_bounds(&self, lower: &mut [f64], upper: &mut [f64]) {
        lower.copy_from_slice(&self.lower);
        upper.copy_from_slice(&self.upper);
    }
    fn evaluate(&self, z: &[f64], out: &mut StageValues) {
        let z = DVector::from_column_slice(z);
        out.cost = 0.5 * z.dot(&(&self.w * &z)) + self.wl.dot(&z);
        out.dynamics.copy_from(&(&self.f * &z));
        out.equalities.copy_from(&(&self.g * &z - &self.c));
        out.inequalities.copy_from(&(&self.h * &z));
    }
    fn jacobians(&self, z: &[f64], out: &mut StageJacobians) {
        let z = DVector::from_column_slice(z);
        out.cost_gradient.copy_from(&(&self.w * &z + &self.wl));
        out.dynamics.copy_from(&self.f);
        out.equalities.copy_from(&self.g);
        out.inequalities.copy_from(&self.h);
    }
    fn lagrangian_hessian(&self, _z: &[f64], m: StageMultipliers<'_>, out: &mut DMatrix<f64>) {
        out.copy_from(&(&self.w * m.cost));
    }
}

const N: usize = 20;
const DT: f64 = 0.1;

/// A double integrator (position, velocity; force input) from (1, 0) to rest at the
/// origin in N steps, cost sum 1/2 (x^T diag(1, 0.1) x + 0.01 u^2); `u_max` bounds |u|.
fn double_integrator(u_max: Option<f64>, v_min: Option<f64>) -> Vec<LqStage> {
    let mut stages = Vec::new();
    for k in 0..=N {
        let last = k == N;
        let (nu, nx_next) = if last { (0, 0) } else { (1, 2) };
        let nz = 2 + nu;
        let mut w = DMatrix::zeros(nz, nz);
        w[(0, 0)] = 1.0;
        w[(1, 1)] = 0.1;
        if !last {
            w[(2, 2)] = 0.01;
        }
        let f = if last { DMatrix::zeros(0, nz) } else { DMatrix::from_row_slice(2, 3, &[1.0, DT, 0.0, 0.0, 1.0, DT]) };
        let (g, c) = if k == 0 {
            (DMatrix::from_row_slice(2, 3, &[1.0, 0.0, 0.0, 0.0, 1.0, 0.0]), DVector::from_vec(vec![1.0, 0.0]))
        } else if last {
            (DMatrix::identity(2, 2), DVector::zeros(2))
        } else {
            (DMatrix::zeros(0, nz), DVector::zeros(0))
        };
        let mut rows: Vec<(Vec<f64>, f64, f64)> = Vec::new();
        if let (Some(um), false) = (u_max, last) {
            rows.push((vec![0.0, 0.0, 1.0], -um, um));
        }
        if let (Some(vm), true) = (v_min, k > 0) {
            let mut r = vec![0.0; nz];
            r[1] = 1.0;
            rows.push((r, vm, f64::INFINITY));
        }
        let h = DMatrix::from_fn(rows.len(), nz, |i, j| rows[i].0[j]);
        stages.push(LqStage {
            dims: StageDims { nx: 2, nu, nx_next, ng: g.nrows(), nh: rows.len() },
            w,
            wl: DVector::zeros(nz),
            f,
            g,
            c,
            h,
            lower: rows.iter().map(|r| r.1).collect(),
            upper: rows.iter().map(|r| r.2).collect(),
        });
    }
    stages
}

fn problem(stages: &[LqStage]) -> Problem {
    Problem::new(stages.iter().map(|s| Box::new(s.clone()) as Box<dyn Stage>).collect()).unwrap()
}

fn zero_guess(stages: &[LqStage]) -> Vec<DVector<f64>> {
    stages.iter().map(|s| DVector::zeros(s.dims.nz())).collect()
}

/// The stacked QP `min 1/2 z^T P z s.t. A_eq z = b_eq, H z in [lo, up]` of the stages.
struct Stacked {
    p: DMatrix<f64>,
    a_eq: DMatrix<f64>,
    b_eq: DVector<f64>,
    h: DMatrix<f64>,
    lo: Vec<f64>,
    up: Vec<f64>,
    offsets: Vec<usize>,
}

fn stack(stages: &[LqStage]) -> Stacked {
    let mut offsets = vec![0];
    for s in stages {
        offsets.push(offsets.last().unwrap() + s.dims.nz());
    }
    let n = *offsets.last().unwrap();
    let neq: usize = stages.iter().map(|s| s.dims.nx_next + s.dims.ng).sum();
    let nh: usize = stages.iter().map(|s| s.dims.nh).sum();
    let mut p = DMatrix::zeros(n, n);
    let mut a_eq = DMatrix::zeros(neq, n);
    let mut b_eq = DVector::zeros(neq);
    let mut h = DMatrix::zeros(nh, n);
    let (mut lo, mut up) = (Vec::new(), Vec::new());
    let (mut r, mut rh) = (0, 0);
    for (k, s) in stages.iter().enumerate() {
        let o = offsets[k];
        let nz = s.dims.nz();
        p.view_mut((o, o), (nz, nz)).copy_from(&s.w);
        for i in 0..s.dims.nx_next {
            for j in 0..nz {
                a_eq[(r, o + j)] = s.f[(i, j)];
            }
            a_eq[(r, offsets[k + 1] + i)] = -1.0;
            r += 1;
        }
        for i in 0..s.dims.ng {
            for j in 0..nz {
                a_eq[(r, o + j)] = s.g[(i, j)];
            }
            b_eq[r] = s.c[i];
            r += 1;
        }
        for i in 0..s.dims.nh {
            for j in 0..nz {
                h[(rh, o + j)] = s.h[(i, j)];
            }
            lo.push(s.lower[i]);
            up.push(s.upper[i]);
            rh += 1;
        }
    }
    Stacked { p, a_eq, b_eq, h, lo, up, offsets }
}

#[test]
fn lqr_with_terminal_state_matches_the_dense_kkt_solution() {
    let stages = double_integrator(None, None);
    let pb = problem(&stages);
    let mut solver = Solver::new(&pb, Settings::default()).unwrap();
    let r = solver.solve(&pb, &zero_guess(&stages)).unwrap();
    assert_eq!(r.status, Status::Solved);
    // An equality-constrained QP: Newton's first step is the solution.
    assert!(r.iterations <= 2, "{} iterations", r.iterations);
    // Dense KKT [P A^T; A 0] [z; y] = [0; b].
    let st = stack(&stages);
    let (n, m) = (st.p.nrows(), st.a_eq.nrows());
    let mut kkt = DMatrix::zeros(n + m, n + m);
    kkt.view_mut((0, 0), (n, n)).copy_from(&st.p);
    kkt.view_mut((n, 0), (m, n)).copy_from(&st.a_eq);
    kkt.view_mut((0, n), (n, m)).copy_from(&st.a_eq.transpose());
    let mut rhs = DVector::zeros(n + m);
    rhs.rows_mut(n, m).copy_from(&st.b_eq);
    let sol = kkt.lu().solve(&rhs).unwrap();
    let z = sol.rows(0, n);
    let cost = 0.5 * z.dot(&(&st.p * z));
    assert!((r.objective - cost).abs() < 1e-10 * cost.max(1.0), "{} vs {cost}", r.objective);
    for (k, zk) in r.last.primal.iter().enumerate() {
        for i in 0..zk.len() {
            assert!((zk[i] - z[st.offsets[k] + i]).abs() < 1e-9, "stage {k}");
        }
    }
    assert!(r.last.primal[N].amax() < 1e-10, "terminal state {}", r.last.primal[N]);
}

/// Clarabel's solution of the stacked QP (bounds as two one-sided rows each).
fn clarabel_solution(st: &Stacked) -> (Vec<f64>, f64) {
    let n = st.p.nrows();
    let csc = |m: &DMatrix<f64>, upper_only: bool| {
        let (mut colptr, mut rowval, mut nzval) = (vec![0], Vec::new(), Vec::new());
        for j in 0..m.ncols() {
            for i in 0..m.nrows() {
                if m[(i, j)] != 0.0 && (!upper_only || i <= j) {
                    rowval.push(i);
                    nzval.push(m[(i, j)]);
                }
            }
            colptr.push(rowval.len());
        }
        CscMatrix::new(m.nrows(), m.ncols(), colptr, rowval, nzval)
    };
    let mut rows: Vec<DVector<f64>> = Vec::new();
    let mut b = Vec::new();
    for i in 0..st.a_eq.nrows() {
        rows.push(st.a_eq.row(i).transpose());
        b.push(st.b_eq[i]);
    }
    let neq = rows.len();
    for i in 0..st.h.nrows() {
        if st.up[i].is_finite() {
            rows.push(st.h.row(i).transpose());
            b.push(st.up[i]);
        }
        if st.lo[i].is_finite() {
            rows.push(-st.h.row(i).transpose());
            b.push(-st.lo[i]);
        }
    }
    let a = DMatrix::from_fn(rows.len(), n, |i, j| rows[i][j]);
    let cones = [SupportedConeT::ZeroConeT(neq), SupportedConeT::NonnegativeConeT(rows.len() - neq)];
    let settings = DefaultSettingsBuilder::default().verbose(false).tol_gap_abs(1e-12).tol_gap_rel(1e-12).tol_feas(1e-12).build().unwrap();
    let q = vec![0.0; n];
    let mut solver = DefaultSolver::new(&csc(&st.p, true), &q, &csc(&a, false), &b, &cones, settings).unwrap();
    solver.solve();
    assert!(matches!(solver.solution.status, SolverStatus::Solved), "{:?}", solver.solution.status);
    (solver.solution.x.clone(), solver.solution.obj_val)
}

#[test]
fn box_constrained_lq_matches_clarabel() {
    // |u| <= 2 and v >= -0.6 are both active on the optimal path (the unconstrained one
    // pushes with -7.9 and reaches v = -1.1).
    let stages = double_integrator(Some(2.0), Some(-0.6));
    let pb = problem(&stages);
    let st = stack(&stages);
    let (x, obj) = clarabel_solution(&st);
    // The monotone barrier update and the adaptive ones (Nocedal, Wächter & Waltz 2009).
    for barrier_update in [BarrierUpdate::Monotone, BarrierUpdate::Adaptive(MuOracle::QualityFunction), BarrierUpdate::Adaptive(MuOracle::Probing), BarrierUpdate::Adaptive(MuOracle::Loqo)] {
        // The control weight is 0.01: at the default tolerance (1e-8 on the gradient) u is
        // known to ~1e-6 only; 1e-10 makes the 1e-6 comparison below meaningful.
        let mut solver = Solver::new(&pb, Settings { tolerance: 1e-10, barrier_update, ..Settings::default() }).unwrap();
        let r = solver.solve(&pb, &zero_guess(&stages)).unwrap();
        assert_eq!(r.status, Status::Solved, "{barrier_update:?}");
        assert!((r.objective - obj).abs() < 1e-7 * obj.abs().max(1.0), "{barrier_update:?}: {} vs {obj}", r.objective);
        let mut active = 0;
        for (k, zk) in r.last.primal.iter().enumerate() {
            for i in 0..zk.len() {
                assert!((zk[i] - x[st.offsets[k] + i]).abs() < 1e-6, "{barrier_update:?}: stage {k} entry {i}: {} vs {}", zk[i], x[st.offsets[k] + i]);
            }
            if k < N && (zk[2].abs() - 2.0).abs() < 1e-6 {
                active += 1;
            }
            if k > 0 && (zk[1] + 0.6).abs() < 1e-6 {
                active += 1;
            }
        }
        assert!(active >= 3, "{barrier_update:?}: {active} active bounds");
    }
}

#[test]
fn unconstrained_lq_pushes_through_the_boxes_of_the_constrained_test() {
    // The premise of the box test: without bounds the path leaves them.
    let stages = double_integrator(None, None);
    let pb = problem(&stages);
    let mut solver = Solver::new(&pb, Settings::default()).unwrap();
    let r = solver.solve(&pb, &zero_guess(&stages)).unwrap();
    let umax = r.last.primal[..N].iter().map(|z| z[2].abs()).fold(0.0, f64::max);
    let vmin = r.last.primal.iter().map(|z| z[1]).fold(f64::INFINITY, f64::min);
    assert!(umax > 2.5 && vmin < -0.7, "umax {umax} vmin {vmin}");
}

#[test]
fn parallel_stage_evaluation_takes_the_same_steps() {
    // The stages are evaluated independently: on rayon's threads the iterates are the same
    // to the last bit.
    let stages = double_integrator(Some(2.0), Some(-0.6));
    let pb = problem(&stages);
    let serial = Solver::new(&pb, Settings::default()).unwrap().solve(&pb, &zero_guess(&stages)).unwrap();
    let parallel = Solver::new(&pb, Settings { parallel: true, ..Settings::default() }).unwrap().solve(&pb, &zero_guess(&stages)).unwrap();
    assert_eq!(parallel.status, Status::Solved);
    assert_eq!(parallel.iterations, serial.iterations);
    assert_eq!(parallel.last.primal, serial.last.primal);
}
