//! The SLQ solver on problems with known answers: a linear-quadratic problem (the optimum
//! is one linear solve away, and SLQ must reach it in one full step) and a nonlinear
//! pendulum swing (cost decreasing, convergence, target reached); the same linear-quadratic
//! problem with input bounds against its condensed QP solved by Clarabel.

use legwork::slq::{ControlLimits, KnotDerivatives, Policy, Problem, Slq, SlqSettings, SolutionPolicy, Termination};
use nalgebra::{DMatrix, DVector};

/// `x_{k+1} = A x + B u`, `l = x^T Q x + u^T R u`, `h = x^T H x`, in R^nx.
struct Linear {
    a: DMatrix<f64>,
    b: DMatrix<f64>,
    q: DMatrix<f64>,
    r: DMatrix<f64>,
    h: DMatrix<f64>,
    x0: DVector<f64>,
    n: usize,
    /// `|u_i| <= u_max` (infinite: unbounded).
    u_max: f64,
    /// A state is valid while every coordinate is below this in magnitude (infinite: while
    /// finite).
    valid_below: f64,
}

impl Problem for Linear {
    type State = DVector<f64>;
    type Workspace = ();
    fn nx(&self) -> usize {
        self.a.nrows()
    }
    fn nu(&self) -> usize {
        self.b.ncols()
    }
    fn horizon(&self) -> usize {
        self.n
    }
    fn workspace(&self) {}
    fn initial_state(&self) -> DVector<f64> {
        self.x0.clone()
    }
    fn difference(&self, y: &DVector<f64>, x: &DVector<f64>, dx: &mut DVector<f64>) {
        dx.copy_from(&(x - y));
    }
    fn step(&self, _: &mut (), _: usize, x: &DVector<f64>, u: &DVector<f64>, next: &mut DVector<f64>) -> f64 {
        next.copy_from(&(&self.a * x + &self.b * u));
        (x.transpose() * &self.q * x)[0] + (u.transpose() * &self.r * u)[0]
    }
    fn step_with_derivatives(&self, ws: &mut (), k: usize, x: &DVector<f64>, u: &DVector<f64>, next: &mut DVector<f64>, d: &mut KnotDerivatives) -> f64 {
        d.a.copy_from(&self.a);
        d.b.copy_from(&self.b);
        d.l_x.copy_from(&(&self.q * x * 2.0));
        d.l_u.copy_from(&(&self.r * u * 2.0));
        d.l_xx.copy_from(&(&self.q * 2.0));
        d.l_uu.copy_from(&(&self.r * 2.0));
        d.l_ux.fill(0.0);
        self.step(ws, k, x, u, next)
    }
    fn terminal_cost(&self, _: &mut (), x: &DVector<f64>) -> f64 {
        (x.transpose() * &self.h * x)[0]
    }
    fn terminal_cost_derivatives(&self, ws: &mut (), x: &DVector<f64>, h_x: &mut DVector<f64>, h_xx: &mut DMatrix<f64>) -> f64 {
        h_x.copy_from(&(&self.h * x * 2.0));
        h_xx.copy_from(&(&self.h * 2.0));
        self.terminal_cost(ws, x)
    }
    fn input_bounds(&self, _: usize, lower: &mut DVector<f64>, upper: &mut DVector<f64>) {
        lower.fill(-self.u_max);
        upper.fill(self.u_max);
    }
    fn is_valid(&self, x: &DVector<f64>) -> bool {
        x.iter().all(|v| v.is_finite() && v.abs() < self.valid_below)
    }
}

struct Zero;
impl<P: Problem> Policy<P> for Zero {
    fn control(&self, _: &P, _: usize, _: &P::State, u: &mut DVector<f64>) {
        u.fill(0.0);
    }
}

/// The optimum of the linear problem by condensing: `X = Sx x0 + Su U`, minimise a
/// quadratic in U (normal equations).
fn condensed_optimum(p: &Linear) -> DVector<f64> {
    let (lhs, rhs) = condensed(p);
    lhs.lu().solve(&rhs).unwrap()
}

/// The cost as a quadratic in the stacked inputs `U`: `J = U^T L U - 2 r^T U + const`,
/// returned as `(L, r)`.
fn condensed(p: &Linear) -> (DMatrix<f64>, DVector<f64>) {
    let (nx, nu, n) = (p.nx(), p.nu(), p.n);
    // X = [x_0 .. x_N] stacked.
    let mut sx = DMatrix::zeros(nx * (n + 1), nx);
    let mut su = DMatrix::zeros(nx * (n + 1), nu * n);
    let mut ak = DMatrix::identity(nx, nx);
    for k in 0..=n {
        sx.view_mut((k * nx, 0), (nx, nx)).copy_from(&ak);
        for j in 0..k {
            // x_k contains A^{k-1-j} B u_j
            let mut m = DMatrix::identity(nx, nx);
            for _ in 0..(k - 1 - j) {
                m = &p.a * m;
            }
            su.view_mut((k * nx, j * nu), (nx, nu)).copy_from(&(m * &p.b));
        }
        ak = &p.a * ak;
    }
    let mut qbar = DMatrix::zeros(nx * (n + 1), nx * (n + 1));
    for k in 0..n {
        qbar.view_mut((k * nx, k * nx), (nx, nx)).copy_from(&p.q);
    }
    qbar.view_mut((n * nx, n * nx), (nx, nx)).copy_from(&p.h);
    let mut rbar = DMatrix::zeros(nu * n, nu * n);
    for k in 0..n {
        rbar.view_mut((k * nu, k * nu), (nu, nu)).copy_from(&p.r);
    }
    let lhs = su.transpose() * &qbar * &su + rbar;
    let rhs = -(su.transpose() * &qbar * &sx * &p.x0);
    (lhs, rhs)
}

/// The condensed problem with `|u| <= u_max` by Clarabel: `min 1/2 U^T (2 L) U - 2 r^T U`
/// s.t. `[I; -I] U <= [u_max; u_max]`.
fn clarabel_box_optimum(p: &Linear) -> DVector<f64> {
    use clarabel::algebra::CscMatrix;
    use clarabel::solver::{DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT};
    let (lhs, rhs) = condensed(p);
    let m = lhs.nrows();
    let (mut colptr, mut rowval, mut nzval) = (vec![0], Vec::new(), Vec::new());
    for j in 0..m {
        for i in 0..=j {
            rowval.push(i);
            nzval.push(2.0 * lhs[(i, j)]);
        }
        colptr.push(rowval.len());
    }
    let hessian = CscMatrix::new(m, m, colptr, rowval, nzval);
    let constraints = CscMatrix::new(2 * m, m, (0..=m).map(|j| 2 * j).collect(), (0..m).flat_map(|j| [j, m + j]).collect(), (0..m).flat_map(|_| [1.0, -1.0]).collect());
    let q: Vec<f64> = rhs.iter().map(|r| -2.0 * r).collect();
    let b = vec![p.u_max; 2 * m];
    let settings = DefaultSettingsBuilder::default().verbose(false).tol_gap_abs(1e-12).tol_gap_rel(1e-12).tol_feas(1e-12).build().unwrap();
    let mut solver = DefaultSolver::new(&hessian, &q, &constraints, &b, &[SupportedConeT::NonnegativeConeT(2 * m)], settings).unwrap();
    solver.solve();
    assert_eq!(solver.solution.status, SolverStatus::Solved);
    DVector::from_vec(solver.solution.x.clone())
}

/// The double integrator of the test below with the second input's axis.
fn double_integrator(n: usize, u_max: f64) -> Linear {
    let dt = 0.05;
    let a = DMatrix::from_row_slice(4, 4, &[1.0, dt, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, dt, 0.0, 0.0, 0.0, 1.0]);
    let b = DMatrix::from_row_slice(4, 2, &[0.0, 0.0, dt, 0.0, 0.0, 0.0, 0.0, dt]);
    let q = DMatrix::from_row_slice(4, 4, &[1.0, 0.0, 0.3, 0.0, 0.0, 0.1, 0.0, 0.0, 0.3, 0.0, 2.0, 0.0, 0.0, 0.0, 0.0, 0.1]);
    Linear { a, b, q: q.clone(), r: DMatrix::identity(2, 2) * 0.01, h: q * 50.0, x0: DVector::from_row_slice(&[1.0, 0.0, -0.5, 0.3]), n, u_max, valid_below: f64::INFINITY }
}

/// Control limits (Tassa 2014): with `|u| <= 1.5`, which cuts the unconstrained optimum's
/// first 0.4 s (it starts at |u| = 9.6), the box-constrained SLQ reaches the optimum of the
/// constrained QP (Clarabel on the condensed problem) to 1e-6, every input inside the box,
/// and the gain rows of inputs clamped at their bound are zero.
#[test]
fn linear_quadratic_with_input_bounds_reaches_the_constrained_optimum() {
    let p = double_integrator(40, 1.5);
    let unconstrained = condensed_optimum(&p);
    assert!(unconstrained.amax() > 5.0, "the bound must cut the unconstrained optimum: {}", unconstrained.amax());
    let settings = SlqSettings { threads: 2, max_iterations: 50, feedforward_tolerance: 1e-9, relative_cost_tolerance: 0.0, normalized_cost_tolerance: 0.0, control_limits: ControlLimits::BoxQp, ..Default::default() };
    let sol = Slq::new(&p, settings.clone()).unwrap().solve(&Zero, |_| {}).unwrap();
    let exact = clarabel_box_optimum(&p);
    let ours = DVector::from_iterator(80, sol.inputs.iter().flat_map(|u| u.iter().copied()));
    assert!(ours.iter().all(|u| u.abs() <= 1.5), "an input left the box");
    assert!((&ours - &exact).amax() < 1e-6, "SLQ {ours} vs Clarabel {exact} (max difference {})", (&ours - &exact).amax());
    let at_bound: Vec<(usize, usize)> = (0..40).flat_map(|k| (0..2).map(move |i| (k, i))).filter(|&(k, i)| sol.inputs[k][i].abs() == 1.5).collect();
    assert!(at_bound.len() >= 8, "{} inputs at the bound", at_bound.len());
    for (k, i) in at_bound {
        assert!(sol.gains[k].row(i).iter().all(|g| *g == 0.0), "knot {k} input {i} at its bound has gains {}", sol.gains[k].row(i));
    }
    assert!(matches!(sol.termination, Termination::Converged | Termination::CostStalled), "{:?}", sol.termination);
    // The projected rollout keeps every input in the box too, at a cost no lower than the
    // constrained optimum's (and here within 5 % of it).
    let projected = Slq::new(&p, SlqSettings { control_limits: ControlLimits::ProjectedRollout, ..settings }).unwrap().solve(&Zero, |_| {}).unwrap();
    assert!(projected.inputs.iter().all(|u| u.amax() <= 1.5));
    let (best, clamped) = (*sol.cost_history.last().unwrap(), *projected.cost_history.last().unwrap());
    assert!(clamped >= best * (1.0 - 1e-9) && clamped < 1.05 * best, "projected {clamped} against the optimum {best}");
}

/// Bounds the solver cannot use are refused with the knot and the input.
#[test]
fn crossed_input_bounds_are_named() {
    let p = double_integrator(5, -1.0);
    let err = Slq::new(&p, SlqSettings::default()).err().unwrap();
    assert!(err.to_string().contains("knot 0, input 0"), "{err}");
}

#[test]
fn linear_quadratic_optimum_in_one_full_step() {
    // A double integrator per axis, two axes coupled by the cost.
    let dt = 0.05;
    let a = DMatrix::from_row_slice(4, 4, &[1.0, dt, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, dt, 0.0, 0.0, 0.0, 1.0]);
    let b = DMatrix::from_row_slice(4, 2, &[0.0, 0.0, dt, 0.0, 0.0, 0.0, 0.0, dt]);
    let q = DMatrix::from_row_slice(4, 4, &[1.0, 0.0, 0.3, 0.0, 0.0, 0.1, 0.0, 0.0, 0.3, 0.0, 2.0, 0.0, 0.0, 0.0, 0.0, 0.1]);
    let p = Linear { a, b, q: q.clone(), r: DMatrix::identity(2, 2) * 0.01, h: q * 50.0, x0: DVector::from_row_slice(&[1.0, 0.0, -0.5, 0.3]), n: 40, u_max: f64::INFINITY, valid_below: f64::INFINITY };
    let settings = SlqSettings { threads: 2, ..Default::default() };
    let sol = Slq::new(&p, settings).unwrap().solve(&Zero, |_| {}).unwrap();
    assert_eq!(sol.iterations[0].alpha, 1.0, "a linear-quadratic problem takes the full step");
    let exact = condensed_optimum(&p);
    let ours = DVector::from_iterator(80, sol.inputs.iter().flat_map(|u| u.iter().copied()));
    assert!((&ours - &exact).norm() < 1e-8 * (1.0 + exact.norm()), "SLQ {ours} vs exact {exact}");
    assert!(matches!(sol.termination, Termination::Converged), "{:?}", sol.termination);
    assert!(sol.iterations.len() <= 2);
    // The gains are the LQR gains: the feedback law reproduces the optimum from a
    // perturbed start to first order (here exactly, the problem being linear).
    assert_eq!(sol.gains.len(), 40);
    assert!(sol.gains[0].iter().any(|g| g.abs() > 1e-3));
}

/// A torque-driven pendulum, `theta'' = -g/l sin(theta) - c theta' + u / (m l^2)`,
/// explicit Euler, state (theta, theta'); cost drives theta to `target`.
struct Pendulum {
    n: usize,
    dt: f64,
    target: f64,
}

impl Pendulum {
    fn f(&self, x: &DVector<f64>, u: f64) -> DVector<f64> {
        let acc = -9.81 * x[0].sin() - 0.1 * x[1] + u;
        DVector::from_row_slice(&[x[0] + self.dt * x[1], x[1] + self.dt * acc])
    }
}

impl Problem for Pendulum {
    type State = DVector<f64>;
    type Workspace = ();
    fn nx(&self) -> usize {
        2
    }
    fn nu(&self) -> usize {
        1
    }
    fn horizon(&self) -> usize {
        self.n
    }
    fn workspace(&self) {}
    fn initial_state(&self) -> DVector<f64> {
        DVector::zeros(2)
    }
    fn difference(&self, y: &DVector<f64>, x: &DVector<f64>, dx: &mut DVector<f64>) {
        dx.copy_from(&(x - y));
    }
    fn step(&self, _: &mut (), _: usize, x: &DVector<f64>, u: &DVector<f64>, next: &mut DVector<f64>) -> f64 {
        next.copy_from(&self.f(x, u[0]));
        self.dt * (0.1 * (x[0] - self.target).powi(2) + 0.01 * x[1] * x[1] + 0.001 * u[0] * u[0])
    }
    fn step_with_derivatives(&self, ws: &mut (), k: usize, x: &DVector<f64>, u: &DVector<f64>, next: &mut DVector<f64>, d: &mut KnotDerivatives) -> f64 {
        d.a.copy_from(&DMatrix::from_row_slice(2, 2, &[1.0, self.dt, -self.dt * 9.81 * x[0].cos(), 1.0 - self.dt * 0.1]));
        d.b.copy_from(&DMatrix::from_row_slice(2, 1, &[0.0, self.dt]));
        d.l_x.copy_from(&DVector::from_row_slice(&[self.dt * 0.2 * (x[0] - self.target), self.dt * 0.02 * x[1]]));
        d.l_u[0] = self.dt * 0.002 * u[0];
        d.l_xx.copy_from(&DMatrix::from_row_slice(2, 2, &[self.dt * 0.2, 0.0, 0.0, self.dt * 0.02]));
        d.l_uu[(0, 0)] = self.dt * 0.002;
        d.l_ux.fill(0.0);
        self.step(ws, k, x, u, next)
    }
    fn terminal_cost(&self, _: &mut (), x: &DVector<f64>) -> f64 {
        10.0 * (x[0] - self.target).powi(2) + x[1] * x[1]
    }
    fn terminal_cost_derivatives(&self, ws: &mut (), x: &DVector<f64>, h_x: &mut DVector<f64>, h_xx: &mut DMatrix<f64>) -> f64 {
        h_x.copy_from(&DVector::from_row_slice(&[20.0 * (x[0] - self.target), 2.0 * x[1]]));
        h_xx.copy_from(&DMatrix::from_row_slice(2, 2, &[20.0, 0.0, 0.0, 2.0]));
        self.terminal_cost(ws, x)
    }
    fn is_valid(&self, x: &DVector<f64>) -> bool {
        x.iter().all(|v| v.is_finite() && v.abs() < 1e3)
    }
}

/// A PD that holds the pendulum down: the "initial stable control law".
struct HoldDown;
impl Policy<Pendulum> for HoldDown {
    fn control(&self, _: &Pendulum, _: usize, x: &DVector<f64>, u: &mut DVector<f64>) {
        u[0] = -5.0 * x[0] - 1.0 * x[1];
    }
}

#[test]
fn pendulum_swings_to_its_target_and_the_cost_decreases() {
    let p = Pendulum { n: 300, dt: 0.01, target: 2.5 };
    let mut seen = Vec::new();
    let sol = Slq::new(&p, SlqSettings { threads: 2, max_iterations: 100, ..Default::default() })
        .unwrap()
        .solve(&HoldDown, |log| seen.push(log.cost))
        .unwrap();
    assert!(sol.cost_history.windows(2).all(|w| w[1] < w[0]), "cost must decrease: {:?}", sol.cost_history);
    assert!(sol.cost_history.last().unwrap() < &(0.1 * sol.cost_history[0]));
    let last = sol.states.last().unwrap();
    assert!((last[0] - p.target).abs() < 0.05, "final angle {} (target {})", last[0], p.target);
    assert!(matches!(sol.termination, Termination::Converged | Termination::CostStalled), "{:?}", sol.termination);
    assert_eq!(seen.len(), sol.iterations.len());
    for log in &sol.iterations {
        assert!(log.timing.linearization >= 0.0 && log.timing.backward_pass >= 0.0 && log.timing.line_search >= 0.0);
    }
    // Re-running the returned policy from the start reproduces the returned states.
    let mut x = p.initial_state();
    for (k, u) in sol.inputs.iter().enumerate() {
        let mut next = x.clone();
        p.step(&mut (), k, &x, u, &mut next);
        x = next;
    }
    assert!((&x - last).norm() < 1e-12);
}

#[test]
fn the_overlapped_backward_pass_gives_the_same_iterates_to_the_bit() {
    // SlqSettings::overlap_backward_pass reorders who linearizes which knot and when the
    // pass reads it, not the arithmetic: on 2 and 3 threads the iterates, gains and costs
    // equal those of the separate linearization and pass (and of one thread) exactly.
    let p = Pendulum { n: 300, dt: 0.01, target: 2.5 };
    let solve = |threads: usize, overlap: bool| Slq::new(&p, SlqSettings { threads, max_iterations: 30, overlap_backward_pass: overlap, ..Default::default() }).unwrap().solve(&HoldDown, |_| {}).unwrap();
    let reference = solve(1, false);
    assert!(reference.iterations.len() > 3, "{} iterations", reference.iterations.len());
    for (threads, overlap) in [(2, true), (3, true), (2, false)] {
        let other = solve(threads, overlap);
        assert_eq!(other.cost_history, reference.cost_history, "{threads} threads, overlap {overlap}");
        assert_eq!(other.states, reference.states, "{threads} threads, overlap {overlap}");
        assert_eq!(other.inputs, reference.inputs, "{threads} threads, overlap {overlap}");
        assert_eq!(other.gains, reference.gains, "{threads} threads, overlap {overlap}");
        assert_eq!(other.termination, reference.termination);
    }
}

#[test]
fn a_diverging_initial_policy_is_reported() {
    struct Explode;
    impl Policy<Pendulum> for Explode {
        fn control(&self, _: &Pendulum, _: usize, x: &DVector<f64>, u: &mut DVector<f64>) {
            u[0] = 1e4 * (1.0 + x[1].abs());
        }
    }
    let p = Pendulum { n: 300, dt: 0.01, target: 1.0 };
    let err = Slq::new(&p, SlqSettings::default()).unwrap().solve(&Explode, |_| {}).unwrap_err();
    assert!(err.to_string().contains("initial rollout"), "{err}");
    let bad = SlqSettings { alpha_divisor: 1.0, ..Default::default() };
    assert!(Slq::new(&p, bad).err().unwrap().to_string().contains("alpha_divisor"));
    let bad = SlqSettings { short_step: 0.1, short_step_regularization_growth: 0.5, ..Default::default() };
    assert!(Slq::new(&p, bad).err().unwrap().to_string().contains("short_step"));
}

/// A warm start from a solution reproduces that solution on its own problem (the first
/// rollout costs what the solution's last iterate did); on a longer horizon its knots get
/// the solution's `u_k + K_k (x - x_k)` and the knots after them the fallback policy.
#[test]
fn a_solution_warm_starts_the_same_and_a_longer_horizon() {
    let short = Pendulum { n: 150, dt: 0.01, target: 2.5 };
    let settings = SlqSettings { threads: 2, max_iterations: 30, ..Default::default() };
    let sol = Slq::new(&short, settings.clone()).unwrap().solve(&HoldDown, |_| {}).unwrap();
    let again = Slq::new(&short, SlqSettings { max_iterations: 1, ..settings }).unwrap().solve(&SolutionPolicy::new(&short, &sol, &HoldDown), |_| {}).unwrap();
    let best = *sol.cost_history.last().unwrap();
    assert!((again.cost_history[0] - best).abs() <= 1e-12 * best, "{} against {best}", again.cost_history[0]);

    let long = Pendulum { n: 300, dt: 0.01, target: 2.5 };
    let policy = SolutionPolicy::new(&long, &sol, &HoldDown);
    let mut u = DVector::zeros(1);
    // On the solution's knots: its input on its state, plus its gain times the deviation.
    let k = 100;
    policy.control(&long, k, &sol.states[k], &mut u);
    assert_eq!(u[0], sol.inputs[k][0]);
    let off = &sol.states[k] + DVector::from_row_slice(&[0.1, -0.2]);
    policy.control(&long, k, &off, &mut u);
    let expected = sol.inputs[k][0] + (&sol.gains[k] * DVector::from_row_slice(&[0.1, -0.2]))[0];
    assert!((u[0] - expected).abs() < 1e-12);
    // After them, the hold-down PD: -5 theta - theta'.
    policy.control(&long, 200, &DVector::from_row_slice(&[2.5, 0.0]), &mut u);
    assert_eq!(u[0], -12.5);
}

/// A receding window on the double integrator whose state weight changes along absolute
/// time: knot `k` of the window is absolute knot `k + offset` (moved on by the test, as an
/// MPC moves its window). Counts the knots it linearizes.
struct Window {
    linear: Linear,
    offset: std::sync::atomic::AtomicUsize,
    linearized: std::sync::atomic::AtomicUsize,
    /// What [`Problem::same_model_piece`] answers for any two states (false: a kept model
    /// never serves).
    one_piece: bool,
    /// [`Problem::last_used_knot`] (`None`: the last knot): a window that runs past its
    /// task's end.
    last_used: Option<usize>,
}

impl Window {
    /// `Q_k = Q (1 + 0.3 ((k + offset) mod 7))`.
    fn q(&self, k: usize) -> DMatrix<f64> {
        let absolute = k + self.offset.load(std::sync::atomic::Ordering::Relaxed);
        &self.linear.q * (1.0 + 0.3 * (absolute % 7) as f64)
    }
}

impl Problem for Window {
    type State = DVector<f64>;
    type Workspace = ();
    fn nx(&self) -> usize {
        self.linear.nx()
    }
    fn nu(&self) -> usize {
        self.linear.nu()
    }
    fn horizon(&self) -> usize {
        self.linear.n
    }
    fn workspace(&self) {}
    fn initial_state(&self) -> DVector<f64> {
        self.linear.x0.clone()
    }
    fn difference(&self, y: &DVector<f64>, x: &DVector<f64>, dx: &mut DVector<f64>) {
        dx.copy_from(&(x - y));
    }
    fn step(&self, _: &mut (), k: usize, x: &DVector<f64>, u: &DVector<f64>, next: &mut DVector<f64>) -> f64 {
        next.copy_from(&(&self.linear.a * x + &self.linear.b * u));
        (x.transpose() * self.q(k) * x)[0] + (u.transpose() * &self.linear.r * u)[0]
    }
    fn step_with_derivatives(&self, ws: &mut (), k: usize, x: &DVector<f64>, u: &DVector<f64>, next: &mut DVector<f64>, d: &mut KnotDerivatives) -> f64 {
        self.linearized.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let q = self.q(k);
        d.a.copy_from(&self.linear.a);
        d.b.copy_from(&self.linear.b);
        d.l_x.copy_from(&(&q * x * 2.0));
        d.l_u.copy_from(&(&self.linear.r * u * 2.0));
        d.l_xx.copy_from(&(&q * 2.0));
        d.l_uu.copy_from(&(&self.linear.r * 2.0));
        d.l_ux.fill(0.0);
        self.step(ws, k, x, u, next)
    }
    fn terminal_cost(&self, ws: &mut (), x: &DVector<f64>) -> f64 {
        self.linear.terminal_cost(ws, x)
    }
    fn terminal_cost_derivatives(&self, ws: &mut (), x: &DVector<f64>, h_x: &mut DVector<f64>, h_xx: &mut DMatrix<f64>) -> f64 {
        self.linear.terminal_cost_derivatives(ws, x, h_x, h_xx)
    }
    fn is_valid(&self, x: &DVector<f64>) -> bool {
        self.linear.is_valid(x)
    }
    fn same_model_piece(&self, _: &DVector<f64>, _: &DVector<f64>) -> bool {
        self.one_piece
    }
    fn input_bounds(&self, k: usize, lower: &mut DVector<f64>, upper: &mut DVector<f64>) {
        self.linear.input_bounds(k, lower, upper)
    }
    fn last_used_knot(&self) -> usize {
        self.last_used.unwrap_or(self.linear.n)
    }
}

#[test]
fn real_time_iterations_that_keep_the_knots_models_take_the_same_steps_on_a_quadratic_problem() {
    // ModelReuse: a kept model has its gradient moved to the new trajectory by its Hessian,
    // which on a quadratic cost is the new gradient, and it moves with its knot when the
    // window moves (the weights here change along absolute time). So over ticks that move
    // the window and start from a disturbed state, a solver that keeps nearly every model
    // takes the same steps as one that linearizes every knot (to round-off), while it
    // linearizes only the knots its settings name: the first `fresh_head`, the new one and
    // its turn of the rest. A knot whose state left its model's piece
    // (Problem::same_model_piece) is linearized anew.
    use legwork::slq::ModelReuse;
    use std::sync::atomic::Ordering;
    let n = 40;
    for threads in [1, 2] {
        let run = |reuse: Option<ModelReuse>, one_piece: bool| {
            let window = Window { linear: double_integrator(n, f64::INFINITY), offset: 0.into(), linearized: 0.into(), one_piece, last_used: None };
            let mut slq = Slq::new(&window, SlqSettings { threads, ..Default::default() }).unwrap();
            let mut x0 = window.linear.x0.clone();
            slq.start_from(&x0, &Zero).unwrap();
            slq.real_time_iteration(&x0, None).unwrap();
            slq.set_model_reuse(reuse).unwrap();
            let mut per_tick = Vec::new();
            let mut ticks = Vec::new();
            for tick in 0..12 {
                window.offset.fetch_add(1, Ordering::Relaxed);
                slq.shift(1, &Zero);
                // The measured state: where the solution said, pushed a little.
                x0.copy_from(&slq.states()[0]);
                x0[1] += 0.05 * (tick as f64 * 1.3).sin();
                let before = window.linearized.load(Ordering::Relaxed);
                let it = slq.real_time_iteration(&x0, None).unwrap();
                per_tick.push(window.linearized.load(Ordering::Relaxed) - before);
                ticks.push((it.cost, slq.inputs().to_vec(), slq.gains().to_vec()));
            }
            (ticks, per_tick)
        };
        let (fresh, fresh_count) = run(None, true);
        let (head, period) = (3, 5);
        let reuse = Some(ModelReuse { fresh_head: head, refresh_period: period });
        let (kept, kept_count) = run(reuse, true);
        // A problem whose states never share a model piece gets every knot linearized.
        let (pieces, pieces_count) = run(reuse, false);
        assert!(pieces_count.iter().all(|&c| c == n), "{pieces_count:?}");
        assert_eq!(pieces, fresh, "{threads} threads: every knot linearized, the same steps to the bit");
        assert!(fresh_count.iter().all(|&c| c == n), "{fresh_count:?}");
        // Per tick: the head, the new last knot and every period-th of the rest (7 or 8 of
        // 40 here; the first tick after turning it on linearizes every knot).
        assert_eq!(kept_count[0], n, "{kept_count:?}");
        for &c in &kept_count[1..] {
            assert!((head + (n - head - 1) / period..=head + 1 + (n - head).div_ceil(period)).contains(&c), "{threads} threads: {kept_count:?}");
        }
        for (tick, ((cost_f, inputs_f, gains_f), (cost_k, inputs_k, gains_k))) in fresh.iter().zip(&kept).enumerate() {
            assert!((cost_f - cost_k).abs() <= 1e-9 * cost_f.abs(), "tick {tick}: cost {cost_f} vs {cost_k}");
            for k in 0..n {
                assert!((&inputs_f[k] - &inputs_k[k]).amax() <= 1e-8 * (1.0 + inputs_f[k].amax()), "tick {tick} knot {k}: {} vs {}", inputs_f[k], inputs_k[k]);
                assert!((&gains_f[k] - &gains_k[k]).amax() <= 1e-8 * (1.0 + gains_f[k].amax()), "tick {tick} knot {k} gains");
            }
        }
    }
}

/// x' = 1.2 x over `n` knots, the input clipped at 1e-9 (it cannot hold the state), valid
/// below 1e4.
fn unstable(n: usize) -> Linear {
    Linear {
        a: DMatrix::from_element(1, 1, 1.2),
        b: DMatrix::from_element(1, 1, 1.0),
        q: DMatrix::identity(1, 1),
        r: DMatrix::identity(1, 1),
        h: DMatrix::identity(1, 1),
        x0: DVector::from_element(1, 1.0),
        n,
        u_max: 1e-9,
        valid_below: 1e4,
    }
}

/// A real-time iteration whose every trial leaves the valid states (an MPC window whose
/// rollouts spin a free leg past the speed limit) keeps the trial that went furthest if it
/// held for a quarter of the window, its later states held at its last valid one, and says
/// so (`held_after`, cost infinite); one whose trials all fail sooner is an error.
#[test]
fn a_window_whose_every_trial_leaves_the_valid_states_is_held_after_a_quarter() {
    use legwork::slq::RealTimeIterationError;
    let n = 40;
    let p = unstable(n);
    for threads in [1, 2] {
        let mut slq = Slq::new(&p, SlqSettings { threads, ..Default::default() }).unwrap();
        // From 1: 1.2^40 ~ 1470, valid to the end; a priced trajectory.
        slq.start_from(&p.x0, &Zero).unwrap();
        let it = slq.real_time_iteration(&p.x0, None).unwrap();
        assert!(it.cost.is_finite() && it.held_after.is_none(), "{threads} threads: {} {:?}", it.cost, it.held_after);
        // From 100: 100 * 1.2^k passes 1e4 at k = 26, so the step from knot 25 leaves the
        // valid states: held after knot 25.
        let x = DVector::from_element(1, 100.0);
        let it = slq.real_time_iteration(&x, None).unwrap();
        assert_eq!(it.held_after, Some(25), "{threads} threads");
        assert_eq!(it.cost, f64::INFINITY);
        let states = slq.states();
        assert!(states[25][0] < 1e4 && states[25][0] > 1e4 / 1.2, "{}", states[25][0]);
        assert!(states[26..].iter().all(|s| s == &states[25]), "{threads} threads: the states after knot 25 held at its");
        // From 5000: invalid at knot 4, before a quarter of the window (10): no trajectory.
        let err = slq.real_time_iteration(&DVector::from_element(1, 5000.0), None).unwrap_err();
        assert_eq!(err, RealTimeIterationError::NoValidTrial);
    }
}

/// A window past its task's end (the closed loop stops at the end, the robot never runs the
/// later knots; [`Window::last_used`]) keeps a trial that stayed valid up to the task's last used knot, though that
/// is less than a quarter of the window; one that left the valid states before it is still
/// an error.
#[test]
fn a_window_past_the_tasks_end_is_held_after_the_end() {
    use legwork::slq::RealTimeIterationError;
    // From 2500 the state passes 1e4 at knot 8 (2500 * 1.2^8 ~ 10750), so every trial
    // leaves the valid states after knot 7, under a quarter of the 40 knots.
    let x = DVector::from_element(1, 2500.0);
    for threads in [1, 2] {
        for (last_used, held) in [(40, None), (8, None), (7, Some(7)), (3, Some(7))] {
            let p = Window { linear: unstable(40), offset: 0.into(), linearized: 0.into(), one_piece: true, last_used: Some(last_used) };
            let mut slq = Slq::new(&p, SlqSettings { threads, ..Default::default() }).unwrap();
            slq.start_from(&p.linear.x0, &Zero).unwrap();
            slq.real_time_iteration(&p.linear.x0, None).unwrap();
            match (slq.real_time_iteration(&x, None), held) {
                (Ok(it), Some(k)) => {
                    assert_eq!(it.held_after, Some(k), "{threads} threads, task's end at knot {last_used}");
                    assert_eq!(it.cost, f64::INFINITY);
                    let states = slq.states();
                    assert!(states[k + 1..].iter().all(|s| s == &states[k]), "the states after knot {k} held at its");
                }
                (Err(e), None) => assert_eq!(e, RealTimeIterationError::NoValidTrial),
                (result, expected) => panic!("{threads} threads, task's end at knot {last_used}: {:?}, expected held after {expected:?}", result.map(|it| it.held_after)),
            }
        }
    }
}
