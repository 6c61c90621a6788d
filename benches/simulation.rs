//! Simulation speed: physics steps per second of the contact simulator with the standing
//! controller, robots standing on flat ground with four feet in contact (issue 3's target:
//! at least 150,000 steps/s for HyQ at 2 kHz physics and 1 kHz control, one core).
//!
//! Run: `cargo bench --bench simulation`. One criterion iteration = one physics step
//! (every second one also calls the controller, as at 1 kHz control / 2 kHz physics).

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use legwork::control::JointPd;
use legwork::model::embedded;
use legwork::sim::{standing_on_ground, SimConfig, Simulator};
use legwork::terrain::Plane;
use std::time::Duration;

fn standing_step(c: &mut Criterion) {
    let ground = Plane::flat(0.0);
    let mut group = c.benchmark_group("simulate_stand");
    group.warm_up_time(Duration::from_millis(500)).measurement_time(Duration::from_secs(3)).sample_size(40);
    group.throughput(Throughput::Elements(1));
    for name in ["hyq", "a1"] {
        let model = embedded::load(name).expect("embedded robot");
        let q0 = standing_on_ground(&model, &ground, 0.0).expect("standing pose");
        let mut sim = Simulator::new(&model, &ground, SimConfig::default(), q0, None).expect("simulator");
        let mut stand = JointPd::standing(&model, 0.001).expect("standing controller");
        // Settle for a second, then check the premise: four feet in contact.
        for _ in 0..2000 {
            sim.step(&mut stand).expect("settling");
        }
        assert!(sim.feet().iter().all(|f| f.contact.normal_force > 0.0), "{name}: not standing on four feet");
        group.bench_function(format!("{name}_physics_step"), |b| b.iter(|| sim.step(&mut stand).expect("step")));
        assert!(sim.feet().iter().all(|f| f.contact.normal_force > 0.0), "{name}: fell during the benchmark");
    }
    group.finish();
}

criterion_group!(benches, standing_step);
criterion_main!(benches);
