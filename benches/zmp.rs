//! ZMP CoG-trajectory QP (Winkler 2015, sec. IV) per plan: HyQ crawls of 8, 20 and 52 steps
//! of 0.15 m (swing order RH, RF, LH, LF, 0.6 s phases, CoG 0.6 m high, margin 5 cm), with
//! ZMP samples every 0.1 s (the default) and every 0.05 s (the walk's `WalkConfig::hyq`,
//! whose plans cover the whole path: 24-52 steps), one `ZmpQp` re-used across solves as a
//! planner would. Issue 5's target: a plan within 5 ms.
//!
//! Run: `cargo bench --bench zmp`. One iteration = one `ZmpQp::solve`: four-leg phase
//! insertion, QP assembly, Clarabel (setup and solve), the check of the left-out rows (and
//! any further rounds), and the conversion to splines.

use criterion::{criterion_group, criterion_main, Criterion};
use legwork::zmp::{phases_from_footsteps, CogState, Footstep, Leg, StepTiming, SupportPhase, ZmpQp, ZmpSettings};
use nalgebra::{Point2, Vector2};
use std::time::Duration;

/// The support phases of a crawl of `steps` steps from HyQ's nominal stance, and its goal.
fn crawl(steps: usize) -> (Vec<SupportPhase>, Point2<f64>) {
    let start = [[0.37, 0.33], [0.37, -0.33], [-0.37, 0.33], [-0.37, -0.33]].map(|[x, y]| Point2::new(x, y));
    let order = [Leg::RH, Leg::RF, Leg::LH, Leg::LF];
    let mut feet = start;
    let footsteps: Vec<Footstep> = (0..steps)
        .map(|i| {
            let leg = order[i % 4];
            feet[leg.index()].x += 0.15;
            Footstep { leg, target: feet[leg.index()] }
        })
        .collect();
    let goal = Point2::from(feet.iter().fold(Vector2::zeros(), |sum, f| sum + f.coords) / 4.0);
    let timing = StepTiming { initial_stance: 0.6, swing: 0.6, final_stance: 0.6 };
    (phases_from_footsteps(start, &footsteps, timing, 0.6), goal)
}

fn zmp_qp(c: &mut Criterion) {
    let mut group = c.benchmark_group("zmp_qp");
    group.warm_up_time(Duration::from_millis(500)).measurement_time(Duration::from_secs(3)).sample_size(30);
    let initial = CogState::at_rest(Vector2::zeros());
    for (steps, sample_interval) in [(8, 0.1), (20, 0.1), (52, 0.1), (8, 0.05), (20, 0.05), (52, 0.05)] {
        let (phases, goal) = crawl(steps);
        let settings = ZmpSettings { sample_interval, ..ZmpSettings::default() };
        let mut qp = ZmpQp::new(settings).expect("settings");
        let plan = qp.solve(&phases, &initial, goal).expect("the crawl is feasible");
        let info = plan.info();
        let check = plan.check_zmp(0.001);
        eprintln!(
            "crawl {steps} steps, samples every {sample_interval} s: {} phases, {} splines, {} variables, {} of {} eq. (6) rows \
             in the QP, {} round(s), {} iterations, Clarabel {:.2} ms, cost {:.12e}, worst ZMP margin on a 1 ms grid {:.2e} m",
            info.phases,
            info.splines,
            info.variables,
            info.inequality_constraints,
            info.zmp_constraints,
            info.rounds,
            info.iterations,
            info.solver_seconds * 1e3,
            info.cost,
            check.worst_margin
        );
        group.bench_function(format!("crawl_{steps}_steps_sample_{sample_interval}"), |b| {
            b.iter(|| qp.solve(&phases, &initial, goal).expect("feasible"))
        });
    }
    group.finish();
}

criterion_group!(benches, zmp_qp);
criterion_main!(benches);
