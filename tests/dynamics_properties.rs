//! Properties of the dynamics on the URDF models of HyQ and A1, at random states
//! (`random_configuration`, 64 cases per robot and property):
//!
//! * `ABA(q, v, RNEA(q, v, qdd)) = qdd`;
//! * `M(q)` is symmetric positive definite;
//! * `CRBA(q) qdd + nle(q, v) = RNEA(q, v, qdd)`;
//! * `difference(q0, integrate(q0, v)) = v` and `integrate(q0, difference(q0, q1)) = q1`;
//! * without gravity or torque, a free-floating robot conserves its centroidal momentum and
//!   kinetic energy (1 s of Runge-Kutta-Munthe-Kaas 4 with 1 ms steps, to 1e-6 relative).

use legwork::dynamics::*;
use legwork::model::{urdf, Model};
use legwork::spatial::{Motion, SE3};
use nalgebra::DVector;
use proptest::prelude::*;
use std::sync::OnceLock;

fn shared(rel: &str) -> String {
    format!("{}/../shared/{rel}", env!("CARGO_MANIFEST_DIR"))
}

fn hyq() -> &'static Model {
    static M: OnceLock<Model> = OnceLock::new();
    M.get_or_init(|| urdf::load_file(shared("robots/hyq/hyq_no_sensors.urdf")).unwrap())
}
fn a1() -> &'static Model {
    static M: OnceLock<Model> = OnceLock::new();
    M.get_or_init(|| urdf::load_file(shared("robots/a1/a1.urdf")).unwrap())
}
/// Both robots: every property runs on each at every case.
fn robots() -> [&'static Model; 2] {
    [hyq(), a1()]
}

/// A small deterministic generator (xorshift64*), seeded by proptest.
struct Rng(u64);
impl Rng {
    fn new(seed: u64) -> Self {
        Self(seed | 1)
    }
    /// U(0, 1).
    fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    }
    /// U(-a, a) in every component.
    fn vector(&mut self, n: usize, a: f64) -> DVector<f64> {
        DVector::from_fn(n, |_, _| a * (2.0 * self.uniform() - 1.0))
    }
    fn configuration(&mut self, model: &Model) -> DVector<f64> {
        random_configuration(model, &mut || self.uniform())
    }
}

/// `|got - want| <= tol * max(1, |want|)`.
fn close(got: &DVector<f64>, want: &DVector<f64>, tol: f64) -> Result<(), TestCaseError> {
    let err = (got - want).norm();
    let scale = want.norm().max(1.0);
    prop_assert!(
        err <= tol * scale,
        "error {err:.3e} > {tol:.0e} * {scale:.3e}\n got {got}\nwant {want}"
    );
    Ok(())
}

fn base_pose(q: &DVector<f64>) -> SE3 {
    joint_transform(&legwork::model::JointKind::FreeFlyer, &q.as_slice()[..7])
}

const CASES: u32 = 64;

proptest! {
    #![proptest_config(ProptestConfig { cases: CASES, .. ProptestConfig::default() })]

    #[test]
    fn aba_inverts_rnea(seed in any::<u64>()) {
        for model in robots() {
            let mut rng = Rng::new(seed);
            let mut data = Data::new(model);
            let q = rng.configuration(model);
            let v = rng.vector(model.nv, 2.0);
            let qdd = rng.vector(model.nv, 10.0);
            let tau = rnea(model, &mut data, &q, &v, &qdd).clone();
            let back = aba(model, &mut data, &q, &v, &tau).clone();
            close(&back, &qdd, 1e-9)?;
        }
    }

    #[test]
    fn mass_matrix_is_symmetric_positive_definite(seed in any::<u64>()) {
        for model in robots() {
            let mut rng = Rng::new(seed);
            let mut data = Data::new(model);
            let q = rng.configuration(model);
            let m = crba(model, &mut data, &q).clone();
            let asym = (&m - m.transpose()).norm();
            prop_assert!(asym <= 1e-12 * m.norm(), "asymmetry {asym:.3e}");
            let eig = nalgebra::SymmetricEigen::new(m.clone()).eigenvalues;
            prop_assert!(eig.min() > 0.0, "eigenvalues {eig}");
            prop_assert!(m.clone().cholesky().is_some());
            // The base block is the composite inertia of the whole robot: its mass is the total mass.
            prop_assert!((m[(0, 0)] - model.total_mass()).abs() < 1e-12 * model.total_mass());
        }
    }

    #[test]
    fn crba_and_nonlinear_effects_give_rnea(seed in any::<u64>()) {
        for model in robots() {
            let mut rng = Rng::new(seed);
            let mut data = Data::new(model);
            let q = rng.configuration(model);
            let v = rng.vector(model.nv, 2.0);
            let qdd = rng.vector(model.nv, 10.0);
            let m = crba(model, &mut data, &q).clone();
            let nle = nonlinear_effects(model, &mut data, &q, &v).clone();
            let tau = rnea(model, &mut data, &q, &v, &qdd).clone();
            close(&(m * &qdd + nle), &tau, 1e-10)?;
        }
    }

    #[test]
    fn integrate_and_difference_are_inverse(seed in any::<u64>()) {
        for model in robots() {
            let mut rng = Rng::new(seed);
            let q0 = rng.configuration(model);
            // Base rotations below pi, so that the logarithm is unique.
            let v = rng.vector(model.nv, 1.5);
            let mut q1 = q0.clone();
            integrate(model, &q0, &v, &mut q1);
            let mut v_back = DVector::zeros(model.nv);
            difference(model, &q0, &q1, &mut v_back);
            close(&v_back, &v, 1e-10)?;
            prop_assert!((q1.rows(3, 4).norm() - 1.0).abs() < 1e-12);
            // And the other way round, between two random configurations.
            let q2 = rng.configuration(model);
            let mut d = DVector::zeros(model.nv);
            difference(model, &q0, &q2, &mut d);
            let mut q3 = q0.clone();
            integrate(model, &q0, &d, &mut q3);
            let (m2, m3) = (base_pose(&q2), base_pose(&q3));
            prop_assert!((m2.rotation - m3.rotation).norm() < 1e-9, "{} vs {}", m2.rotation, m3.rotation);
            prop_assert!((m2.translation - m3.translation).norm() < 1e-9);
            close(&q3.rows(7, model.nq - 7).into_owned(), &q2.rows(7, model.nq - 7).into_owned(), 1e-12)?;
            // The difference of a configuration with itself is zero.
            difference(model, &q2, &q2, &mut d);
            prop_assert!(d.norm() < 1e-12);
        }
    }
}

/// `dexp^-1` of the free-flyer part: the rate of the exponential coordinates `theta` of
/// `M = M0 exp(theta)` for a body twist `v` is `v + [theta, v] / 2 + [theta, [theta, v]] / 12`
/// (truncated after the terms RKMK4 needs); the joints are Euclidean.
fn dexpinv(theta: &DVector<f64>, v: &DVector<f64>) -> DVector<f64> {
    let mut out = v.clone();
    let t = Motion::from_slice(&theta.as_slice()[..6]);
    let m = Motion::from_slice(&v.as_slice()[..6]);
    let tm = t.cross(&m);
    let r = m + tm * 0.5 + t.cross(&tm) * (1.0 / 12.0);
    out.as_mut_slice()[..6].copy_from_slice(r.to_vector().as_slice());
    out
}

/// One Runge-Kutta-Munthe-Kaas 4 step of `(q, v)` under `qdd = ABA(q, v, 0)`.
fn rkmk4_step(model: &Model, data: &mut Data, q: &mut DVector<f64>, v: &mut DVector<f64>, h: f64) {
    let zero = DVector::zeros(model.nv);
    let mut qs = q.clone();
    // Stage i: theta_i = h * sum a_ij K_j, state (q (+) theta_i, v + h * sum a_ij A_j).
    let stage = |model: &Model, data: &mut Data, qs: &mut DVector<f64>, theta: &DVector<f64>, vi: &DVector<f64>| {
        integrate(model, q, theta, qs);
        let a = aba(model, data, qs, vi, &zero).clone();
        (dexpinv(theta, vi), a)
    };
    let zero_theta = DVector::zeros(model.nv);
    let (k1, a1) = stage(model, data, &mut qs, &zero_theta, v);
    let (k2, a2) = stage(model, data, &mut qs, &(&k1 * (h / 2.0)), &(&*v + &a1 * (h / 2.0)));
    let (k3, a3) = stage(model, data, &mut qs, &(&k2 * (h / 2.0)), &(&*v + &a2 * (h / 2.0)));
    let (k4, a4) = stage(model, data, &mut qs, &(&k3 * h), &(&*v + &a3 * h));
    let theta = (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (h / 6.0);
    *v += (a1 + a2 * 2.0 + a3 * 2.0 + a4) * (h / 6.0);
    integrate(model, &q.clone(), &theta, q);
}

fn kinetic_energy(model: &Model, data: &mut Data, q: &DVector<f64>, v: &DVector<f64>) -> f64 {
    let m = crba(model, data, q);
    0.5 * v.dot(&(m * v))
}

proptest! {
    #![proptest_config(ProptestConfig { cases: CASES, .. ProptestConfig::default() })]

    #[test]
    fn free_floating_robot_conserves_momentum_and_energy(seed in any::<u64>()) {
        for model in robots() {
            let mut model = model.clone();
            model.gravity = Motion::zero();
            let mut data = Data::new(&model);
            let mut rng = Rng::new(seed);
            let mut q = rng.configuration(&model);
            let mut v = rng.vector(model.nv, 1.0);
            let h0 = centroidal_momentum(&model, &mut data, &q, &v).to_vector();
            let e0 = kinetic_energy(&model, &mut data, &q, &v);
            let (h, steps) = (1e-3, 1000);
            for _ in 0..steps {
                rkmk4_step(&model, &mut data, &mut q, &mut v, h);
            }
            let h1 = centroidal_momentum(&model, &mut data, &q, &v).to_vector();
            let e1 = kinetic_energy(&model, &mut data, &q, &v);
            let dh = (h1 - h0).norm() / h0.norm().max(1.0);
            let de = (e1 - e0).abs() / e0.max(1.0);
            prop_assert!(dh < 1e-6, "{}: momentum drift {dh:.3e}: {h0} -> {h1}", model.name);
            prop_assert!(de < 1e-6, "{}: energy drift {de:.3e}: {e0} -> {e1}", model.name);
        }
    }
}
