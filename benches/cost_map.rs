//! Terrain map and cost map update speed (Winkler 2015 sec. III-A; issue 5's target: a cost
//! map update within 50 ms). The map is the default one (8 m x 4 m at 4 cm: 200 x 100
//! cells), the sensor a 2.5 m disk with 1 cm noise, the robot at (0.5, 0) in front of a
//! 1.2 x 0.8 x 0.15 m pallet, the map warmed up by ten sweeps.
//!
//! Run: `cargo bench --bench cost_map`. Cases:
//! * `observe_2.5m`: one sweep: sample, fuse, recompute the cost locally (what the robot
//!   does at every map update);
//! * `observe_obstacle_appears`: one sweep in which the world changed since the last one
//!   (the pallet alternately appears and disappears: 600 cells reset every sweep);
//! * `local_cost_recompute_2.5m`: the local cost recompute of one sweep alone;
//! * `full_cost_recompute`: every cell's cost, for comparison.

use criterion::{criterion_group, criterion_main, Criterion};
use legwork::terrain::{HeightMap, TerrainMap, TerrainMapConfig};
use rand::rngs::Xoshiro256PlusPlus;
use rand::SeedableRng;
use std::time::Duration;

fn worlds() -> (HeightMap, HeightMap) {
    let flat = HeightMap::flat([-2.0, -3.0], 0.04, 301, 151, 0.0);
    let mut pallet = flat.clone();
    pallet.set_rect([1.0, 2.2], [-0.4, 0.4], 0.15);
    (flat, pallet)
}

fn cost_map_update(c: &mut Criterion) {
    let (flat, pallet) = worlds();
    let robot = [0.5, 0.0];
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(7);
    let mut map = TerrainMap::new(TerrainMapConfig::default()).expect("default configuration");
    let mut sweep = None;
    for _ in 0..10 {
        sweep = Some(map.observe(&pallet, robot, 0.0, &mut rng).expect("sweep"));
    }
    let sweep = sweep.expect("ten sweeps");
    let observed = sweep.observed.expect("the sweep sees the map");
    println!(
        "one sweep: {} cells observed, {} cells' cost recomputed of {} x {}",
        sweep.observed_cells,
        sweep.cost_region.map_or(0, |r| r.cell_count()),
        map.size().0,
        map.size().1
    );

    let mut group = c.benchmark_group("cost_map");
    group.warm_up_time(Duration::from_millis(500)).measurement_time(Duration::from_secs(3)).sample_size(30);
    group.bench_function("observe_2.5m", |b| b.iter(|| map.observe(&pallet, robot, 0.0, &mut rng).expect("sweep")));
    let mut worlds = [&flat, &pallet].into_iter().cycle();
    group.bench_function("observe_obstacle_appears", |b| {
        b.iter(|| {
            let update = map.observe(worlds.next().expect("cycle"), robot, 0.0, &mut rng).expect("sweep");
            assert!(update.reset_cells >= 600, "the pallet's cells are reset: {update:?}");
            update
        })
    });
    group.bench_function("local_cost_recompute_2.5m", |b| b.iter(|| map.recompute_costs_around(observed)));
    group.bench_function("full_cost_recompute", |b| b.iter(|| map.recompute_all_costs()));
    group.finish();
}

criterion_group!(benches, cost_map_update);
criterion_main!(benches);
