//! Whole-body execution controller (Winkler 2015, sec. V): time of one control tick on HyQ
//! (virtual model, leg accelerations, RNEA, contact-force pseudo-inverse, leg inverse
//! kinematics, joint PD), against the 1 ms budget of 1 kHz control.
//!
//! Run: `cargo bench --bench whole_body_control`. One criterion iteration = one tick
//! (sampling the motion source included), at a settled standing state: four feet in
//! stance, and LF in swing on three.

use criterion::{criterion_group, criterion_main, Criterion};
use legwork::control::{FootMotion, LegMotion, WholeBodyController, WholeBodyReference};
use legwork::dynamics::{forward_kinematics, frame_position, Data};
use legwork::model::embedded;
use legwork::sim::{standing_on_ground, SimConfig, Simulator};
use legwork::terrain::Plane;
use nalgebra::Vector3;
use std::hint::black_box;
use std::time::Duration;

fn control_tick(c: &mut Criterion) {
    let model = embedded::load("hyq").expect("embedded HyQ");
    let ground = Plane::flat(0.0);
    let q0 = standing_on_ground(&model, &ground, 0.0).expect("standing pose");
    let hold = WholeBodyReference::holding(&model, &q0);
    // Settle for a second under the controller, then time ticks at that state.
    let mut sim = Simulator::new(&model, &ground, SimConfig::default(), q0.clone(), None).expect("simulator");
    let hold_source = {
        let hold = hold.clone();
        move |_: f64, r: &mut WholeBodyReference| r.clone_from(&hold)
    };
    let mut controller = WholeBodyController::with_default_gains(&model, hold_source, 0.001).expect("controller");
    for _ in 0..2000 {
        sim.step(&mut controller).expect("settling");
    }
    assert!(sim.feet().iter().all(|f| f.contact.normal_force > 0.0), "not standing on four feet");
    let (q, v) = (sim.state().q.clone(), sim.state().v.clone());
    let mut tau = nalgebra::DVector::zeros(model.nv);

    let mut group = c.benchmark_group("whole_body_control");
    group.warm_up_time(Duration::from_millis(500)).measurement_time(Duration::from_secs(3)).sample_size(40);
    group.bench_function("hyq_tick_four_stance", |b| b.iter(|| controller.compute_torques(&model, 1.0, black_box(&q), black_box(&v), &mut tau).expect("tick")));

    let mut data = Data::new(&model);
    forward_kinematics(&model, &mut data, &q);
    let lf = frame_position(&model, &data, model.feet[0].frame) + Vector3::new(0.02, 0.0, 0.03);
    let mut swing = hold.clone();
    swing.legs[0] = LegMotion::Swing(FootMotion { position: lf, velocity: Vector3::new(0.2, 0.0, 0.1), acceleration: Vector3::new(0.0, 0.0, -1.0) });
    let mut controller =
        WholeBodyController::with_default_gains(&model, move |_: f64, r: &mut WholeBodyReference| r.clone_from(&swing), 0.001).expect("controller");
    group.bench_function("hyq_tick_lf_swing", |b| b.iter(|| controller.compute_torques(&model, 1.0, black_box(&q), black_box(&v), &mut tau).expect("tick")));
    group.finish();
}

criterion_group!(benches, control_tick);
criterion_main!(benches);
