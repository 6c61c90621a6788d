//! Whole-body execution controller (Winkler 2015, sec. V): time of one control tick on HyQ
//! (virtual model, leg accelerations, RNEA, contact-force pseudo-inverse, leg inverse
//! kinematics, joint PD), against the 1 ms budget of 1 kHz control.
//!
//! Run: `cargo bench --bench whole_body_control`. One criterion iteration = one tick
//! (sampling the motion source included), at a settled standing state: four feet in
//! stance, and LF in swing on three; and the redistribution of clipped forces inside the
//! friction cones alone (it runs only in ticks that clip).

use criterion::{criterion_group, criterion_main, Criterion};
use legwork::control::{
    clip_to_friction_cones, contact_forces, DistributionProblem, FootKinematics, FootMotion, FrictionConeDistribution, LegMotion, WholeBodyController, WholeBodyGains,
    WholeBodyReference,
};
use legwork::dynamics::{forward_kinematics, frame_position, Data};
use legwork::model::embedded;
use legwork::sim::{standing_on_ground, SimConfig, Simulator};
use legwork::terrain::Plane;
use nalgebra::{Matrix3, Matrix3x6, Vector3, Vector6};
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

    // The redistribution inside the friction cones, alone: HyQ's feet under a level base,
    // RH in swing, a roll and pitch moment the three others cannot give within their cones
    // (the clipped pseudo-inverse start, as in a tick that clips).
    let feet: Vec<FootKinematics> = [(0.37, 0.33), (0.37, -0.33), (-0.37, 0.33), (-0.37, -0.33)]
        .iter()
        .map(|&(x, y)| {
            let r = Vector3::new(x, y, -0.55);
            let mut base_jacobian = Matrix3x6::zeros();
            base_jacobian.fixed_view_mut::<3, 3>(0, 0).copy_from(&Matrix3::identity());
            base_jacobian.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-r.cross_matrix()));
            FootKinematics { position: r, base_jacobian, ..Default::default() }
        })
        .collect();
    let base_rows = Vector6::new(0.0, 0.0, 830.0, -250.0, -150.0, 0.0);
    let stance = [true, true, true, false];
    let gains = WholeBodyGains::from_model(&model, &q0, 0.001);
    let (settings, mu) = (gains.cone_distribution.expect("default redistribution"), gains.friction_coefficient.expect("default cones"));
    let problem = DistributionProblem { base_rows: &base_rows, feet: &feet, stance: &stance, mu, tangential_weight: gains.tangential_force_weight };
    let mut start = vec![Vector3::zeros(); 4];
    contact_forces(&base_rows, &feet, &stance, gains.tangential_force_weight, &mut start);
    assert!(clip_to_friction_cones(&mut start, &stance, mu) > 0, "the case needs no redistribution");
    let mut distribution = FrictionConeDistribution::new(4);
    let mut forces = start.clone();
    let info = distribution.solve(&settings, &problem, &mut forces);
    eprintln!("redistribution: {} iterations, converged {}", info.iterations, info.converged);
    group.bench_function("cone_redistribution_three_feet", |b| {
        b.iter(|| {
            forces.copy_from_slice(&start);
            distribution.solve(&settings, black_box(&problem), &mut forces)
        })
    });
    group.finish();
}

criterion_group!(benches, control_tick);
criterion_main!(benches);
