//! One knot of a receding-horizon window (issue 21): HyQ standing on four feet, sidestep's
//! costs, a 5 ms knot of five 1 ms substeps, the contact anchors as states (48 x 48 `A`),
//! linearized as `legwork mpc` does (the first substep's model held over the knot) and as
//! the plans do (every substep's).
//!
//! Run: `cargo bench --bench mpc_knot`. One criterion iteration = one knot's
//! `linearize_knot`, the backward pass's call (`A`, `B`, the cost's derivatives).

use criterion::{criterion_group, criterion_main, Criterion};
use legwork::model::embedded;
use legwork::ocp::{settled_stance, KnotLinearization, TaskSpec};
use legwork::slq::{KnotDerivatives, Problem};
use legwork::terrain::Plane;
use nalgebra::DVector;
use std::hint::black_box;
use std::time::Duration;

fn knot_linearization(c: &mut Criterion) {
    let model = embedded::load("hyq").expect("embedded robot");
    let ground = Plane::flat(0.0);
    let settled = settled_stance(&model, &ground, 0.5).expect("settled stance");
    let spec = TaskSpec::embedded("sidestep").expect("embedded task");
    let mut problem = spec.problem(&model, &ground, settled.clone(), "sidestep").expect("problem");
    problem.anchor_states = true;
    problem.dt = 0.005;
    problem.substeps = 5;
    let (nx, nu) = (problem.nx(), problem.nu());
    assert!(settled.anchors.iter().all(|a| a.is_some()), "not standing on four feet");
    let u = DVector::zeros(nu);
    let mut group = c.benchmark_group("mpc_knot");
    group.warm_up_time(Duration::from_millis(500)).measurement_time(Duration::from_secs(3)).sample_size(40);
    for (name, linearization) in [("first_substep", KnotLinearization::FirstSubstep), ("every_substep", KnotLinearization::EverySubstep)] {
        problem.linearization = linearization;
        let mut ws = problem.workspace();
        let mut d = KnotDerivatives::zeros(nx, nu);
        let mut next = settled.clone();
        group.bench_function(format!("hyq_5ms_{name}"), |b| b.iter(|| black_box(problem.linearize_knot(&mut ws, 0, &settled, &u, &mut next, &mut d))));
    }
    group.finish();
}

criterion_group!(benches, knot_linearization);
criterion_main!(benches);
