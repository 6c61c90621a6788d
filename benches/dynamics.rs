//! Criterion benchmarks of the rigid-body algorithms, shaped like Pinocchio's C++ timing
//! harness (`shared/anchors/pinocchio_bench.cpp`) so the two can be read side by side:
//! the same URDF models (HyQ and A1 from `../shared/robots`, loaded with a free flyer), 64
//! random states cycled call by call (base position in [-1, 1]^3, orientation uniform on
//! SO(3), joints uniform within their limits clipped to [-pi, pi]; `v`, `tau`, `a` uniform in
//! [-1, 1]), one call per iteration.
//!
//! Without `../shared` (a bare clone) the embedded robots are timed instead.
//!
//! Run: `cargo bench --bench dynamics` (portable x86-64 code) or, like Pinocchio's
//! `-march=native` build, `RUSTFLAGS="-C target-cpu=native" cargo bench --bench dynamics`.
//! `benches/compare_pinocchio.py` turns the results into the table of `BENCHMARKS.md`.

use criterion::{criterion_group, criterion_main, Criterion};
use legwork::dynamics::*;
use legwork::model::{embedded, urdf, Model};
use nalgebra::{DVector, Matrix6xX};
use std::hint::black_box;
use std::time::Duration;

/// xorshift64*: a small deterministic generator, U(0, 1).
struct Rng(u64);
impl Rng {
    fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    }
}

struct State {
    q: DVector<f64>,
    v: DVector<f64>,
    tau: DVector<f64>,
    a: DVector<f64>,
}

fn robot(name: &str, urdf_rel: &str) -> (Model, &'static str) {
    let path = format!("{}/../shared/robots/{urdf_rel}", env!("CARGO_MANIFEST_DIR"));
    match urdf::load_file(&path) {
        Ok(m) => (m, "urdf"),
        Err(_) => (embedded::load(name).expect("embedded robot"), "embedded"),
    }
}

fn states(model: &Model, n: usize) -> Vec<State> {
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    (0..n)
        .map(|_| {
            let q = random_configuration(model, &mut || rng.uniform());
            let mut sym = |_: usize, _: usize| 2.0 * rng.uniform() - 1.0;
            let v = DVector::from_fn(model.nv, &mut sym);
            let tau = DVector::from_fn(model.nv, &mut sym);
            let a = DVector::from_fn(model.nv, &mut sym);
            State { q, v, tau, a }
        })
        .collect()
}

fn bench_robot(c: &mut Criterion, name: &str, urdf_rel: &str) {
    let (model, source) = robot(name, urdf_rel);
    let states = states(&model, 64);
    let mut data = Data::new(&model);
    let feet: Vec<usize> = model.feet.iter().map(|f| f.frame).collect();
    assert_eq!(feet.len(), 4, "{name}: four feet expected");
    let mut jac = Matrix6xX::zeros(model.nv);
    let mut group = c.benchmark_group(format!("{name}_{source}"));
    group.warm_up_time(Duration::from_millis(500)).measurement_time(Duration::from_secs(2)).sample_size(40);
    let m = &model;
    let mut k = 0usize;
    let mut next = move || {
        k = (k + 1) & 63;
        k
    };
    group.bench_function("aba", |b| b.iter(|| { let s = &states[next()]; black_box(aba(m, &mut data, &s.q, &s.v, &s.tau)[7]) }));
    group.bench_function("rnea", |b| b.iter(|| { let s = &states[next()]; black_box(rnea(m, &mut data, &s.q, &s.v, &s.a)[7]) }));
    group.bench_function("crba", |b| b.iter(|| { let s = &states[next()]; black_box(crba(m, &mut data, &s.q)[(7, 3)]) }));
    group.bench_function("nonLinearEffects", |b| b.iter(|| { let s = &states[next()]; black_box(nonlinear_effects(m, &mut data, &s.q, &s.v)[7]) }));
    group.bench_function("computeMinverse", |b| b.iter(|| { let s = &states[next()]; black_box(compute_minverse(m, &mut data, &s.q)[(7, 3)]) }));
    group.bench_function("fk_updateFramePlacements", |b| {
        b.iter(|| {
            let s = &states[next()];
            forward_kinematics(m, &mut data, &s.q);
            update_frame_placements(m, &mut data);
            black_box(data.o_m_f[feet[0]].translation.x)
        })
    });
    group.bench_function("computeJointJacobians", |b| {
        b.iter(|| {
            let s = &states[next()];
            compute_joint_jacobians(m, &mut data, &s.q);
            black_box(data.jacobian[(1, 7)])
        })
    });
    group.bench_function("feet_jacobians_lwa", |b| {
        b.iter(|| {
            let s = &states[next()];
            compute_joint_jacobians(m, &mut data, &s.q);
            let mut acc = 0.0;
            for &f in &feet {
                frame_jacobian(m, &data, f, ReferenceFrame::LocalWorldAligned, &mut jac);
                acc += jac[(1, 7)];
            }
            black_box(acc)
        })
    });
    group.bench_function("centerOfMass", |b| b.iter(|| { let s = &states[next()]; black_box(center_of_mass(m, &mut data, &s.q).x) }));
    group.bench_function("computeABADerivatives", |b| {
        b.iter(|| {
            let s = &states[next()];
            compute_aba_derivatives(m, &mut data, &s.q, &s.v, &s.tau);
            black_box(data.ddq_dq[(3, 7)])
        })
    });
    group.bench_function("computeRNEADerivatives", |b| {
        b.iter(|| {
            let s = &states[next()];
            compute_rnea_derivatives(m, &mut data, &s.q, &s.v, &s.a);
            black_box(data.dtau_dq[(3, 7)])
        })
    });
    group.finish();
}

fn dynamics(c: &mut Criterion) {
    bench_robot(c, "hyq", "hyq/hyq_no_sensors.urdf");
    bench_robot(c, "a1", "a1/a1.urdf");
}

criterion_group!(benches, dynamics);
criterion_main!(benches);
