//! Properties of the dynamics on the URDF models of HyQ and A1, at random states
//! (`random_configuration`, 64 cases per robot and property):
//!
//! * `ABA(q, v, RNEA(q, v, qdd)) = qdd`;
//! * `M(q)` is symmetric positive definite;
//! * `CRBA(q) qdd + nle(q, v) = RNEA(q, v, qdd)`;
//! * `difference(q0, integrate(q0, v)) = v` and `integrate(q0, difference(q0, q1)) = q1`;
//! * without gravity or torque, a free-floating robot conserves its centroidal momentum and
//!   kinetic energy (1 s of Runge-Kutta-Munthe-Kaas 4 with 1 ms steps, to 1e-6 relative);
//! * cross-checks of the algorithms the Pinocchio fixtures do not cover: the CoM Jacobian
//!   against finite differences and the centroidal momentum; the centroidal momentum
//!   against a body-by-body sum; World, Local and LocalWorldAligned frame Jacobians against
//!   each other and finite differences; ABA with external forces against RNEA and `J^T f`.

use legwork::dynamics::*;
use legwork::model::{urdf, Model};
use legwork::spatial::{Force, Motion, SE3, Vector3};
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
    fn aba_after_the_kinematics_is_aba_to_the_bit(seed in any::<u64>()) {
        // The simulator's ABA reuses the placements of its contacts' forward kinematics at
        // the same q: the same acceleration, bit for bit, with external forces.
        for model in robots() {
            let mut rng = Rng::new(seed);
            let mut data = Data::new(model);
            let q = rng.configuration(model);
            let v = rng.vector(model.nv, 2.0);
            let tau = rng.vector(model.nv, 20.0);
            let f_ext: Vec<Force> = (0..model.njoints()).map(|_| {
                let x = rng.vector(6, 30.0);
                Force::new(Vector3::new(x[0], x[1], x[2]), Vector3::new(x[3], x[4], x[5]))
            }).collect();
            let want = aba_with_external_forces(model, &mut data, &q, &v, &tau, &f_ext).clone();
            let mut other = Data::new(model);
            forward_kinematics_velocity(model, &mut other, &q, &v);
            let got = aba_with_external_forces_after_kinematics(model, &mut other, &q, &v, &tau, &f_ext).clone();
            prop_assert!(got == want, "after the kinematics {got}\nwithout {want}");
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

    /// `J^T x` by blocks for the tangent-space Jacobians of `integrate` (a 6 x 6 block on
    /// the base, the identity on the joints) against the dense product, to the bit (its
    /// sums are in the dense product's order).
    #[test]
    fn tangent_jacobian_transpose_product_matches_the_dense_product(seed in any::<u64>()) {
        for model in robots() {
            let mut rng = Rng::new(seed);
            let n = model.nv;
            let v = rng.vector(n, 1.5);
            let (mut jq, mut jv) = (nalgebra::DMatrix::zeros(n, n), nalgebra::DMatrix::zeros(n, n));
            integrate_jacobians(model, &v, &mut jq, &mut jv);
            let alpha = 0.01;
            for j in [&jq, &jv] {
                let xv = rng.vector(n, 3.0);
                for beta in [0.0, 1.0] {
                    let mut want = rng.vector(n, 1.0);
                    let mut got = want.clone();
                    want.gemv_tr(alpha, j, &xv, beta);
                    tangent_jacobian_tr_mul(model, alpha, j, xv.as_slice(), beta, got.as_mut_slice());
                    prop_assert!(got == want, "J^T x differs: {got} vs {want}");
                }
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: CASES, .. ProptestConfig::default() })]

    /// `w^T d RNEA / dq` and `w^T d RNEA / dv` by the weighted backward sweep against the
    /// products with `compute_rnea_derivatives`' matrices (1e-12, relative: the sums are in
    /// another order) and against central differences of `w^T RNEA` (1e-6); the mass matrix
    /// of `rnea_derivatives_forward` to the bit.
    #[test]
    fn weighted_rnea_derivatives_match_the_matrix_products_and_differences(seed in any::<u64>()) {
        for model in robots() {
            let mut rng = Rng::new(seed);
            let n = model.nv;
            let (q, v, a, w) = (rng.configuration(model), rng.vector(n, 2.0), rng.vector(n, 5.0), rng.vector(n, 3.0));
            let mut data = Data::new(model);
            compute_rnea_derivatives(model, &mut data, &q, &v, &a);
            let want_q = data.dtau_dq.tr_mul(&w);
            let want_v = data.dtau_dv.tr_mul(&w);
            let mass_matrix = data.mass_matrix.clone();
            let mut data = Data::new(model);
            rnea_derivatives_forward(model, &mut data, &q, &v, &a, true);
            prop_assert!(data.mass_matrix == mass_matrix, "M differs");
            let (mut got_q, mut got_v) = (DVector::zeros(n), DVector::zeros(n));
            rnea_derivatives_tr_mul(model, &mut data, w.as_slice(), got_q.as_mut_slice(), got_v.as_mut_slice());
            close(&got_q, &want_q, 1e-12)?;
            close(&got_v, &want_v, 1e-12)?;
            let h = 1e-6;
            let mut fd_q = DVector::zeros(n);
            let mut fd_v = DVector::zeros(n);
            for j in 0..n {
                let mut e = DVector::zeros(n);
                e[j] = h;
                let (mut qp, mut qm) = (q.clone(), q.clone());
                integrate(model, &q, &e, &mut qp);
                integrate(model, &q, &(-&e), &mut qm);
                fd_q[j] = (w.dot(rnea(model, &mut data, &qp, &v, &a)) - w.dot(rnea(model, &mut data, &qm, &v, &a))) / (2.0 * h);
                fd_v[j] = (w.dot(rnea(model, &mut data, &q, &(&v + &e), &a)) - w.dot(rnea(model, &mut data, &q, &(&v - &e), &a))) / (2.0 * h);
            }
            close(&got_q, &fd_q, 1e-6)?;
            close(&got_v, &fd_v, 1e-6)?;
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

/// The centroidal momentum computed body by body: `sum_i oMi* (I_i v_i)` moved from the
/// world origin to the centre of mass.
fn centroidal_momentum_by_bodies(model: &Model, data: &mut Data, q: &DVector<f64>, v: &DVector<f64>) -> nalgebra::Vector6<f64> {
    forward_kinematics_velocity(model, data, q, v);
    let mut total = legwork::spatial::Force::zero();
    for i in 1..model.njoints() {
        total += data.o_m_i[i].act_force(&model.inertias[i].mul_motion(&data.v[i]));
    }
    let com = center_of_mass(model, data, q);
    legwork::spatial::Force::new(total.f, total.n - com.cross(&total.f)).to_vector()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: CASES, .. ProptestConfig::default() })]

    #[test]
    fn centre_of_mass_jacobian_and_centroidal_momentum_agree(seed in any::<u64>()) {
        for model in robots() {
            let mut rng = Rng::new(seed);
            let mut data = Data::new(model);
            let q = rng.configuration(model);
            let v = rng.vector(model.nv, 2.0);
            let mass = model.total_mass();
            // d com / dt by central differences along the manifold.
            let eps = 1e-6;
            let (mut qp, mut qm) = (q.clone(), q.clone());
            integrate(model, &q, &(&v * eps), &mut qp);
            integrate(model, &q, &(&v * -eps), &mut qm);
            let dcom = (center_of_mass(model, &mut data, &qp) - center_of_mass(model, &mut data, &qm)) / (2.0 * eps);
            let jc = com_jacobian(model, &mut data, &q).clone();
            let jv = &jc * &v;
            let dcom = DVector::from_column_slice(dcom.as_slice());
            close(&DVector::from_column_slice(jv.as_slice()), &dcom, 1e-7)?;
            // Linear momentum = m dcom/dt; angular momentum about the CoM body by body.
            let h = centroidal_momentum(model, &mut data, &q, &v).to_vector();
            close(&DVector::from_column_slice(&h.as_slice()[..3]), &(DVector::from_column_slice(jv.as_slice()) * mass), 1e-10)?;
            let h_bodies = centroidal_momentum_by_bodies(model, &mut data, &q, &v);
            close(&DVector::from_column_slice(h.as_slice()), &DVector::from_column_slice(h_bodies.as_slice()), 1e-10)?;
        }
    }

    #[test]
    fn frame_jacobians_agree_across_reference_frames(seed in any::<u64>()) {
        for model in robots() {
            let mut rng = Rng::new(seed);
            let mut data = Data::new(model);
            let q = rng.configuration(model);
            let v = rng.vector(model.nv, 2.0);
            compute_joint_jacobians(model, &mut data, &q);
            update_frame_placements(model, &mut data);
            let (mut jw, mut jl, mut jlwa) = (nalgebra::Matrix6xX::zeros(model.nv), nalgebra::Matrix6xX::zeros(model.nv), nalgebra::Matrix6xX::zeros(model.nv));
            for foot in &model.feet {
                frame_jacobian(model, &data, foot.frame, ReferenceFrame::World, &mut jw);
                frame_jacobian(model, &data, foot.frame, ReferenceFrame::Local, &mut jl);
                frame_jacobian(model, &data, foot.frame, ReferenceFrame::LocalWorldAligned, &mut jlwa);
                let m = data.o_m_f[foot.frame];
                let (vw, vl, vlwa) = (Motion::from_slice((&jw * &v).as_slice()), Motion::from_slice((&jl * &v).as_slice()), Motion::from_slice((&jlwa * &v).as_slice()));
                // World spatial velocity = oMf . local twist; LWA = local twist rotated to world axes.
                close(&DVector::from_column_slice(vw.to_vector().as_slice()), &DVector::from_column_slice(m.act(&vl).to_vector().as_slice()), 1e-10)?;
                let rot = Motion::new(m.rotation * vl.v, m.rotation * vl.w);
                close(&DVector::from_column_slice(vlwa.to_vector().as_slice()), &DVector::from_column_slice(rot.to_vector().as_slice()), 1e-10)?;
                // The LWA linear velocity is the time derivative of the foot position.
                let eps = 1e-6;
                let (mut qp, mut qm) = (q.clone(), q.clone());
                integrate(model, &q, &(&v * eps), &mut qp);
                integrate(model, &q, &(&v * -eps), &mut qm);
                let mut d2 = Data::new(model);
                forward_kinematics(model, &mut d2, &qp);
                let pp = frame_placement(model, &mut d2, foot.frame).translation;
                forward_kinematics(model, &mut d2, &qm);
                let pm = frame_placement(model, &mut d2, foot.frame).translation;
                close(&DVector::from_column_slice(vlwa.v.as_slice()), &DVector::from_column_slice(((pp - pm) / (2.0 * eps)).as_slice()), 1e-7)?;
            }
        }
    }

    #[test]
    fn external_forces_in_aba_act_through_the_jacobian_transpose(seed in any::<u64>()) {
        for model in robots() {
            let mut rng = Rng::new(seed);
            let mut data = Data::new(model);
            let q = rng.configuration(model);
            let v = rng.vector(model.nv, 2.0);
            let tau = rng.vector(model.nv, 20.0);
            // A wrench on every body, in its joint's frame.
            let f_ext: Vec<legwork::spatial::Force> = (0..model.njoints())
                .map(|i| if i == 0 { legwork::spatial::Force::zero() } else { legwork::spatial::Force::from_vector(&nalgebra::Vector6::from_iterator(rng.vector(6, 30.0).iter().copied())) })
                .collect();
            let qdd = aba_with_external_forces(model, &mut data, &q, &v, &tau, &f_ext).clone();
            // M qdd + nle = tau + sum_i J_i^T f_i, with J_i the LOCAL Jacobian of joint i's frame.
            let lhs = rnea(model, &mut data, &q, &v, &qdd).clone();
            compute_joint_jacobians(model, &mut data, &q);
            let mut rhs = tau.clone();
            let mut j = nalgebra::Matrix6xX::zeros(model.nv);
            for (i, f) in f_ext.iter().enumerate().skip(1) {
                let frame = model.frames.iter().position(|fr| fr.kind == legwork::model::FrameKind::Joint && fr.parent_joint == i).unwrap();
                frame_jacobian(model, &data, frame, ReferenceFrame::Local, &mut j);
                rhs += j.transpose() * f.to_vector();
            }
            close(&lhs, &rhs, 1e-9)?;
        }
    }
}
