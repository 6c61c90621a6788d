//! Jump and landing controllers (Nguyen 2022, sec. III): time of one 1 kHz control tick on
//! the A1, against the 1 ms budget. One criterion iteration = one `compute` call at a
//! settled standing state: the jumping controller (eq. 5: reference interpolation, leg
//! kinematics, Cartesian and joint PD), and the landing controller (single-rigid-body QP
//! on four feet in contact, clarabel, plus `J^T f` and joint PD).
//!
//! Run: `cargo bench --bench jump_control`.

use criterion::{criterion_group, criterion_main, Criterion};
use legwork::jump::control::{check_references, JumpController, JumpGains, JumpReference, LandingSettings, LegExtension, PosingTolerance};
use legwork::model::embedded;
use legwork::sim::{Controller, SimConfig, SimState, Simulator};
use legwork::terrain::Plane;
use nalgebra::DVector;
use std::hint::black_box;
use std::time::Duration;

fn control_tick(c: &mut Criterion) {
    let model = embedded::load("a1").expect("embedded A1");
    let ground = Plane::flat(0.0);
    let trajectory = check_references::standing_reference(&model, &ground, 1.0).expect("standing reference");
    let reference = JumpReference::new(&model, &trajectory, PosingTolerance::default()).expect("reference");
    let q0 = DVector::from_column_slice(&trajectory.knots[0].q);
    let mut sim = Simulator::new(&model, &ground, SimConfig::default(), q0, None).expect("simulator");
    let mut landing = JumpController::new(&model, reference.clone(), JumpGains::default(), LandingSettings::default(), LegExtension::default()).expect("controller");
    for _ in 0..1000 {
        landing.sense(sim.feet());
        sim.step(&mut landing).expect("settling");
    }
    assert_eq!(landing.switch().in_contact(), &[true; 4], "not standing on four feet");
    let state: SimState = sim.state().clone();
    let mut tau = DVector::zeros(model.nv);
    c.bench_function("jump_control/landing_qp_tick_4_feet", |b| {
        b.iter(|| {
            landing.compute(&model, black_box(&state), &mut tau).expect("tick");
            black_box(&tau);
        })
    });
    let pre = reference.pre_landing().clone();
    let late = reference.with_posing(1.0, &pre).expect("posing");
    let mut jumping = JumpController::new(&model, late, JumpGains::default(), LandingSettings::default(), LegExtension::default()).expect("controller");
    jumping.sense(sim.feet());
    let mut state = state;
    state.t = 0.4567;
    c.bench_function("jump_control/jump_tracking_tick_eq5", |b| {
        b.iter(|| {
            jumping.compute(&model, black_box(&state), &mut tau).expect("tick");
            black_box(&tau);
        })
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().measurement_time(Duration::from_secs(3)).warm_up_time(Duration::from_secs(1));
    targets = control_tick
}
criterion_main!(benches);
