//! Criterion benchmarks of the body action planner (Winkler 2015 sec. III-B) on HyQ: ARA*
//! to a goal 5 m ahead on a 4 cm terrain cost field with obstacles (issue 5 target: first
//! solution and re-planning at 10 Hz or faster, <= 100 ms).
//!
//! The field (7 m x 4 m, 175 x 100 cells, seeded): small noise costs (0 to 0.05) everywhere,
//! a forbidden block across the straight line (x 1.0-1.6 m, y -0.8-0.5 m), a forbidden gap
//! strip 0.2 m wide across the whole width at x = 2.4 m, a rough patch (x 3.2-4.2 m, costs
//! 0.2-0.9 with 5 % forbidden cells) and a raised box 0.15 m high (x 4.4-4.7 m, y 0.3-1.0 m).
//!
//! Run: `cargo bench --bench plan`. Timed:
//! * `first_solution_eps3`: ARA* stopped after its first run (epsilon 3);
//! * `replan_eps3`: the same from the plan's third pose (the robot two actions on);
//! * `anytime_to_eps1`: the whole schedule 3, 2.5, 2, 1.5, 1 (the last run proves optimality);
//! * `a_star`: plain A*, the reference.

use criterion::{criterion_group, criterion_main, Criterion};
use legwork::model::embedded;
use legwork::plan::body::{BodyPlanner, BodyPlannerConfig, BodyPose};
use legwork::plan::search::{AraStarConfig, SearchLimits};
use legwork::plan::TerrainCostField;
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

/// A cost map on a regular grid (cell `(i, j)` covers `[x0 + i r, x0 + (i + 1) r) x ...`);
/// outside it cost 1, height 0.
struct GridField {
    origin: [f64; 2],
    resolution: f64,
    columns: usize,
    rows: usize,
    cost: Vec<f64>,
    height: Vec<f64>,
}

impl GridField {
    /// The cell holding `(x, y)`. Truncation instead of `floor` (an out-of-line libm call on
    /// baseline x86-64), after the check that the offsets are non-negative.
    fn cell(&self, x: f64, y: f64) -> Option<usize> {
        let (u, v) = ((x - self.origin[0]) / self.resolution, (y - self.origin[1]) / self.resolution);
        if !(u >= 0.0 && v >= 0.0) {
            return None;
        }
        let (i, j) = (u as usize, v as usize);
        (i < self.columns && j < self.rows).then(|| j * self.columns + i)
    }

    fn cells_in(&self, x: [f64; 2], y: [f64; 2]) -> Vec<usize> {
        let mut out = Vec::new();
        for j in 0..self.rows {
            for i in 0..self.columns {
                let (cx, cy) = (self.origin[0] + (i as f64 + 0.5) * self.resolution, self.origin[1] + (j as f64 + 0.5) * self.resolution);
                if (x[0]..x[1]).contains(&cx) && (y[0]..y[1]).contains(&cy) {
                    out.push(j * self.columns + i);
                }
            }
        }
        out
    }

    fn obstacle_course() -> Self {
        let (columns, rows) = (175, 100);
        let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
        let mut field = GridField {
            origin: [-1.0, -2.0],
            resolution: 0.04,
            columns,
            rows,
            cost: (0..columns * rows).map(|_| 0.05 * rng.uniform()).collect(),
            height: vec![0.0; columns * rows],
        };
        for c in field.cells_in([1.0, 1.6], [-0.8, 0.5]) {
            field.cost[c] = 1.0;
        }
        for c in field.cells_in([2.4, 2.6], [-2.0, 2.0]) {
            field.cost[c] = 1.0;
        }
        for c in field.cells_in([3.2, 4.2], [-2.0, 2.0]) {
            field.cost[c] = if rng.uniform() < 0.05 { 1.0 } else { 0.2 + 0.7 * rng.uniform() };
        }
        for c in field.cells_in([4.4, 4.7], [0.3, 1.0]) {
            field.height[c] = 0.15;
        }
        field
    }
}

impl TerrainCostField for GridField {
    fn cost(&self, x: f64, y: f64) -> f64 {
        self.cell(x, y).map_or(1.0, |c| self.cost[c])
    }
    fn height(&self, x: f64, y: f64) -> f64 {
        self.cell(x, y).map_or(0.0, |c| self.height[c])
    }
    fn resolution(&self) -> f64 {
        self.resolution
    }
    fn cost_and_height(&self, x: f64, y: f64) -> (f64, f64) {
        self.cell(x, y).map_or((1.0, 0.0), |c| (self.cost[c], self.height[c]))
    }
}

fn planner(search: AraStarConfig) -> BodyPlanner {
    let model = embedded::load("hyq").expect("embedded HyQ");
    BodyPlanner::for_model(&model, BodyPlannerConfig { search, ..Default::default() }).expect("default settings are valid")
}

fn bench_plan(c: &mut Criterion) {
    let field = GridField::obstacle_course();
    let start = BodyPose { x: 0.0, y: 0.0, yaw: 0.0 };
    let goal = BodyPose { x: 5.0, y: 0.0, yaw: 0.0 };
    let limits = SearchLimits::none();
    let first_only = AraStarConfig { initial_epsilon: 3.0, epsilon_step: 0.5, final_epsilon: 3.0 };
    let mut first = planner(first_only);
    let mut anytime = planner(AraStarConfig::default());

    // One untimed run of each, for the report.
    let plans = anytime.plan(&field, start, goal, &limits).expect("a plan exists");
    for p in &plans.plans {
        eprintln!(
            "ARA* epsilon {:.1}: bound {:.3}, cost {:.2}, {} steps, {} expansions, {:.1} ms",
            p.epsilon,
            p.bound,
            p.cost,
            p.steps.len(),
            p.expansions,
            p.elapsed.as_secs_f64() * 1e3
        );
    }
    let replan_start = plans.plans[0].poses[2];
    let optimal = anytime.plan_optimal(&field, start, goal, &limits).expect("a plan exists");
    eprintln!("A*: cost {:.2}, {} expansions, {:.1} ms", optimal.cost, optimal.expansions, optimal.elapsed.as_secs_f64() * 1e3);

    let mut group = c.benchmark_group("body_planner_5m");
    group.warm_up_time(Duration::from_secs(1)).measurement_time(Duration::from_secs(5)).sample_size(20);
    group.bench_function("first_solution_eps3", |b| b.iter(|| black_box(first.plan(&field, start, goal, &limits).expect("plan"))));
    group.bench_function("replan_eps3", |b| b.iter(|| black_box(first.plan(&field, replan_start, goal, &limits).expect("plan"))));
    group.bench_function("anytime_to_eps1", |b| b.iter(|| black_box(anytime.plan(&field, start, goal, &limits).expect("plan"))));
    group.bench_function("a_star", |b| b.iter(|| black_box(anytime.plan_optimal(&field, start, goal, &limits).expect("plan"))));
    group.finish();
}

criterion_group!(benches, bench_plan);
criterion_main!(benches);
