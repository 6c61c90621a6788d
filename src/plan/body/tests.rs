//! Body planner tests on terrain fields given as closures: closed-form costs on flat ground,
//! a detour, a gap strip, the cost terms one by one, and ARA* against A* on the lattice.

use super::*;
use crate::model::{embedded, info::RobotInfo};
use crate::plan::search::{a_star, Edge, SearchSpace};
use std::collections::HashSet;

/// A terrain cost field from two closures; cost 1 (unknown) outside `x_range` x `y_range`.
struct FnField<C, H> {
    cost: C,
    height: H,
    x_range: [f64; 2],
    y_range: [f64; 2],
}

impl<C: Fn(f64, f64) -> f64, H: Fn(f64, f64) -> f64> TerrainCostField for FnField<C, H> {
    fn cost(&self, x: f64, y: f64) -> f64 {
        if x < self.x_range[0] || x > self.x_range[1] || y < self.y_range[0] || y > self.y_range[1] {
            1.0
        } else {
            (self.cost)(x, y)
        }
    }
    fn height(&self, x: f64, y: f64) -> f64 {
        (self.height)(x, y)
    }
    fn resolution(&self) -> f64 {
        0.04
    }
}

const AREA_X: [f64; 2] = [-1.0, 4.0];
const AREA_Y: [f64; 2] = [-2.0, 2.0];

fn field(cost: impl Fn(f64, f64) -> f64, height: impl Fn(f64, f64) -> f64) -> impl TerrainCostField {
    FnField { cost, height, x_range: AREA_X, y_range: AREA_Y }
}

fn flat() -> impl TerrainCostField {
    field(|_, _| 0.0, |_, _| 0.0)
}

fn hyq_planner(config: BodyPlannerConfig) -> BodyPlanner {
    let model = embedded::load("hyq").unwrap();
    BodyPlanner::for_model(&model, config).unwrap()
}

fn pose(x: f64, y: f64, yaw_degrees: f64) -> BodyPose {
    BodyPose { x, y, yaw: yaw_degrees.to_radians() }
}

fn primitive_index(planner: &BodyPlanner, name: &str) -> usize {
    planner.config().primitives.iter().position(|p| p.name == name).unwrap()
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-9 * (1.0 + a.abs().max(b.abs()))
}

/// Consecutive poses are joined by the steps, the steps' totals add up to the plan's cost,
/// the last pose is in the goal region, and no chosen foothold is forbidden.
fn assert_consistent(planner: &BodyPlanner, plan: &BodyPlan, goal: BodyPose) {
    assert_eq!(plan.poses.len(), plan.steps.len() + 1);
    let mut total = 0.0;
    for (i, step) in plan.steps.iter().enumerate() {
        assert_eq!((step.from, step.to), (plan.poses[i], plan.poses[i + 1]));
        let c = &step.cost;
        let w = &planner.config().weights;
        let weighted =
            w.terrain * c.terrain + w.difficulty * c.difficulty + w.swing_collision * c.swing_collision + w.orientation * c.orientation;
        assert!(close(c.total, weighted));
        assert_eq!(c.difficulty, planner.config().primitives[step.primitive].difficulty);
        assert!(step.footholds.iter().all(|f| f.cost < 1.0));
        total += c.total;
    }
    assert!(close(total, plan.cost), "{total} vs {}", plan.cost);
    let last = plan.poses.last().unwrap();
    assert!((last.x - goal.x).hypot(last.y - goal.y) <= planner.config().goal_position_tolerance + 1e-12);
    assert!(wrap_angle(last.yaw - goal.yaw).abs() <= planner.config().goal_yaw_tolerance + 1e-12);
}

#[test]
fn hyq_stance_is_the_standing_pose_feet_in_the_body_frame() {
    let model = embedded::load("hyq").unwrap();
    let stance = NominalStance::from_model(&model).unwrap();
    // The model info computes the same feet through frame placements; HyQ stands at the
    // origin with an identity orientation, so world x, y are body x, y.
    let standing = RobotInfo::of(&model).standing.unwrap();
    for (k, foot) in standing.feet.iter().enumerate() {
        assert!((stance.feet[k].x - foot.world.x).abs() < 1e-12 && (stance.feet[k].y - foot.world.y).abs() < 1e-12);
    }
    // LF, RF, LH, RH: front positive x, left positive y; HyQ's +-0.3708, +-0.3241 m.
    let signs = [(1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)];
    for (foot, (sx, sy)) in stance.feet.iter().zip(signs) {
        assert!((foot.x - sx * 0.3708).abs() < 1e-4 && (foot.y - sy * 0.3241).abs() < 1e-4, "{foot:?}");
    }
    assert!(NominalStance::new([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [3.0, 0.0]]).is_err());
    assert!(NominalStance::new([[f64::NAN, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]]).is_err());
}

#[test]
fn straight_path_on_flat_ground_has_the_closed_form_cost() {
    let mut planner = hyq_planner(BodyPlannerConfig::default());
    let (start, goal) = (pose(0.0, 0.0, 0.0), pose(2.0, 0.0, 0.0));
    // 2 m within 5 cm on flat ground, where only the difficulty c_a counts: the cheapest
    // multiset of the straight primitives (long stride 0.44 m / 1.2, stride 0.36 / 1.1,
    // forward_long 0.28 / 1.15, forward 0.24 / 1.0, forward_short 0.12 / 0.6) whose lengths
    // add up to 1.95-2.05 m, by enumeration.
    // `per_step` is what every action pays besides its difficulty.
    let straight = [(0.44, 1.2), (0.36, 1.1), (0.28, 1.15), (0.24, 1.0), (0.12, 0.6)];
    let config = BodyPlannerConfig::default();
    for (dx, difficulty) in straight {
        assert!(config.primitives.iter().any(|p| p.dx == dx && p.dy == 0.0 && p.dyaw == 0.0 && p.difficulty == difficulty), "({dx}, {difficulty}) is not a primitive");
    }
    // Every multiset with at most 2.05 m in total: counts `n[i]` of `straight[i]`.
    fn cheapest_from(straight: &[(f64, f64)], length: f64, cost: f64, per_step: f64) -> f64 {
        let mut best = if (length - 2.0).abs() <= 0.05 + 1e-9 { cost } else { f64::INFINITY };
        if let Some((&(dx, c), rest)) = straight.split_first() {
            best = best.min(cheapest_from(rest, length, cost, per_step));
            let mut k = 1.0;
            while length + k * dx <= 2.05 + 1e-9 {
                best = best.min(cheapest_from(rest, length + k * dx, cost + k * (c + per_step), per_step));
                k += 1.0;
            }
        }
        best
    }
    let cheapest_with = |per_step: f64| cheapest_from(&straight, 0.0, 0.0, per_step);
    let cheapest = cheapest_with(0.0);
    let plans = planner.plan(&flat(), start, goal, &SearchLimits::none()).unwrap();
    let best = plans.best();
    assert!(close(best.cost, cheapest), "{} vs {cheapest}", best.cost);
    assert_eq!(best.bound, 1.0);
    assert_consistent(&planner, best, goal);
    assert!(best.poses.iter().all(|p| p.y == 0.0 && p.yaw == 0.0));
    assert!(best.steps.iter().all(|s| (s.cost.terrain, s.cost.swing_collision, s.cost.orientation) == (0.0, 0.0, 0.0)));
    let optimal = planner.plan_optimal(&flat(), start, goal, &SearchLimits::none()).unwrap();
    assert!(close(optimal.cost, cheapest));

    // Uniform terrain cost 0.25: every step also pays w_t * 0.25 = 1 (fewer, longer steps win).
    let uniform = field(|_, _| 0.25, |_, _| 0.0);
    let plans = planner.plan(&uniform, start, goal, &SearchLimits::none()).unwrap();
    assert!(close(plans.best().cost, cheapest_with(4.0 * 0.25)), "{}", plans.best().cost);
}

#[test]
fn turning_in_place_takes_four_twenty_degree_turns() {
    let mut planner = hyq_planner(BodyPlannerConfig::default());
    let goal = pose(0.0, 0.0, 90.0);
    let plan = planner.plan_optimal(&flat(), pose(0.0, 0.0, 0.0), goal, &SearchLimits::none()).unwrap();
    // 80 deg is within 10 deg of the goal: four turns of 20 deg (c_a = 1 each).
    assert!(close(plan.cost, 4.0), "{}", plan.cost);
    assert_eq!(plan.steps.len(), 4);
    assert!(plan.poses.iter().all(|p| p.x == 0.0 && p.y == 0.0));
    assert_consistent(&planner, &plan, goal);
}

#[test]
fn lattice_is_anchored_at_the_start_pose() {
    let mut planner = hyq_planner(BodyPlannerConfig::default());
    let start = pose(0.013, -0.027, 33.0);
    let goal = pose(0.013 + 0.96 * 33f64.to_radians().cos(), -0.027 + 0.96 * 33f64.to_radians().sin(), 33.0);
    let plan = planner.plan_optimal(&flat(), start, goal, &SearchLimits::none()).unwrap();
    assert_eq!(plan.poses[0], start);
    assert_consistent(&planner, &plan, goal);
    for p in &plan.poses {
        let (i, j) = ((p.x - start.x) / 0.04, (p.y - start.y) / 0.04);
        assert!((i - i.round()).abs() < 1e-9 && (j - j.round()).abs() < 1e-9);
        let k = wrap_angle(p.yaw - start.yaw) / 10f64.to_radians();
        assert!((k - k.round()).abs() < 1e-9);
    }
}

#[test]
fn terrain_term_is_the_mean_of_the_n_best_cells_per_leg() {
    let mut planner = hyq_planner(BodyPlannerConfig::default());
    let forward = primitive_index(&planner, "forward");
    let start = pose(0.0, 0.0, 0.0);
    let stance = *planner.stance();
    // Cost 0 on the nominal footholds after one forward step, 0.5 elsewhere: each leg's four
    // best cells are 0, 0.5, 0.5, 0.5.
    let nominal: Vec<(f64, f64)> = stance.feet.iter().map(|f| (f.x + 0.24, f.y)).collect();
    let spots = field(move |x, y| if nominal.iter().any(|&(nx, ny)| (x - nx).hypot(y - ny) < 0.01) { 0.0 } else { 0.5 }, |_, _| 0.0);
    let cost = planner.action_cost(&spots, start, forward).unwrap();
    assert!(close(cost.terrain, 0.375), "{}", cost.terrain);
    assert!(close(cost.total, 1.0 + 4.0 * 0.375));
    let terrain = planner.stance_terrain(&spots, pose(0.24, 0.0, 0.0)).unwrap();
    for (k, f) in terrain.footholds.iter().enumerate() {
        assert!(close(f.x, stance.feet[k].x + 0.24) && close(f.y, stance.feet[k].y) && f.cost == 0.0);
    }
    // n = 1: only the best cell counts.
    let mut one = hyq_planner(BodyPlannerConfig { best_cells: 1, ..Default::default() });
    assert_eq!(one.action_cost(&spots, start, forward).unwrap().terrain, 0.0);
    // A leg whose whole window is forbidden: no foothold, the action is infeasible.
    let hole = field(|x, y| if (x - 0.6108).hypot(y - 0.3241) < 0.1 { 1.0 } else { 0.0 }, |_, _| 0.0);
    assert!(matches!(planner.action_cost(&hole, start, forward), Err(BodyPlanError::NoFoothold { leg: "LF", .. })));
}

#[test]
fn orientation_term_is_the_tilt_of_the_footprint_plane() {
    let mut planner = hyq_planner(BodyPlannerConfig::default());
    let forward = primitive_index(&planner, "forward");
    // On a plane z = 0.1 x + 0.05 y the fit through any four footholds is the plane itself.
    let ramp = field(|_, _| 0.0, |x, y| 0.1 * x + 0.05 * y);
    for yaw in [0.0, 30.0, 90.0, -135.0] {
        let cost = planner.action_cost(&ramp, pose(0.3, -0.2, yaw), forward).unwrap();
        let tilt = 0.1f64.hypot(0.05).atan();
        assert!(close(cost.orientation, tilt / 20f64.to_radians()), "yaw {yaw}: {}", cost.orientation);
        // The swings run along the plane: nothing rises above both ends.
        assert_eq!(cost.swing_collision, 0.0);
    }
}

#[test]
fn swing_collision_term_is_the_rise_over_a_bar() {
    let mut planner = hyq_planner(BodyPlannerConfig::default());
    let forward = primitive_index(&planner, "forward");
    // A bar 0.2 m high across x in [0.48, 0.52): the front feet swing from x = 0.3708 to
    // 0.6108 over it (and land out of its reach), the hind feet stay behind it.
    let bar = field(|_, _| 0.0, |x, _| if (0.48..0.52).contains(&x) { 0.2 } else { 0.0 });
    let cost = planner.action_cost(&bar, pose(0.0, 0.0, 0.0), forward).unwrap();
    assert!(close(cost.swing_collision, 0.2 / 0.1), "{}", cost.swing_collision);
    assert!(close(cost.total, 1.0 + 2.0 * 2.0));
    // Unknown ground under the swing.
    let unknown = field(|_, _| 0.0, |x, _| if (0.48..0.52).contains(&x) { f64::NAN } else { 0.0 });
    assert_eq!(planner.action_cost(&unknown, pose(0.0, 0.0, 0.0), forward), Err(BodyPlanError::UnknownSwingGround { primitive: forward }));
}

/// A forbidden block across the straight line from the start to the goal.
fn block_field() -> impl TerrainCostField {
    field(|x, y| if (0.9..1.5).contains(&x) && (-0.7..0.7).contains(&y) { 1.0 } else { 0.0 }, |_, _| 0.0)
}

#[test]
fn detour_around_a_forbidden_block_and_ara_star_against_a_star() {
    let mut planner = hyq_planner(BodyPlannerConfig::default());
    let (start, goal) = (pose(0.0, 0.0, 0.0), pose(2.6, 0.0, 0.0));
    let optimal = planner.plan_optimal(&block_field(), start, goal, &SearchLimits::none()).unwrap();
    assert_consistent(&planner, &optimal, goal);
    let anytime = planner.plan(&block_field(), start, goal, &SearchLimits::none()).unwrap();
    assert_eq!(anytime.stop, AraStop::Converged);
    let first = &anytime.plans[0];
    assert_eq!(first.epsilon, 3.0);
    assert!(first.bound <= 3.0 && first.cost <= first.bound * optimal.cost + 1e-9, "first {} bound {}", first.cost, first.bound);
    for plan in &anytime.plans {
        assert!(plan.cost <= plan.bound * optimal.cost + 1e-9);
        assert_consistent(&planner, plan, goal);
    }
    let last = anytime.plans.last().unwrap();
    assert_eq!(last.bound, 1.0);
    assert!(close(last.cost, optimal.cost), "ARA* {} vs A* {}", last.cost, optimal.cost);
    // The body goes around the block, and no foothold is on it.
    let best = anytime.best();
    assert!(best.poses.iter().any(|p| p.y.abs() > 0.7), "{:?}", best.poses);
    for step in &best.steps {
        for f in &step.footholds {
            assert!(!((0.9..1.5).contains(&f.x) && (-0.7..0.7).contains(&f.y)), "{f:?}");
        }
    }
    let straight = planner.plan_optimal(&flat(), start, goal, &SearchLimits::none()).unwrap();
    assert!(optimal.cost > straight.cost + 1.0, "detour {} vs straight {}", optimal.cost, straight.cost);
}

/// A gap strip of forbidden cells across the path, x in [1.0, 1.16): narrower than a step
/// (0.24 m) but wider than a foothold window's radius.
fn gap_field() -> impl TerrainCostField {
    field(|x, _| if (1.0..1.16).contains(&x) { 1.0 } else { 0.0 }, |_, _| 0.0)
}

#[test]
fn crossing_a_gap_strip_keeps_the_footholds_off_the_gap() {
    let mut planner = hyq_planner(BodyPlannerConfig::default());
    let (start, goal) = (pose(0.0, 0.0, 0.0), pose(2.4, 0.0, 0.0));
    let forward = primitive_index(&planner, "forward");
    // Walking straight on with full steps would put the front feet at x = 0.3708 + 0.72 =
    // 1.0908, in the gap, with one usable cell in their windows: c_t_bar > 0.
    let naive = planner.action_cost(&gap_field(), pose(0.48, 0.0, 0.0), forward).unwrap();
    assert!(naive.terrain > 0.3, "{naive:?}");

    let plans = planner.plan(&gap_field(), start, goal, &SearchLimits::none()).unwrap();
    let best = plans.best();
    assert_consistent(&planner, best, goal);
    // Every leg crosses: all four chosen footholds end beyond the gap.
    assert!(best.steps.last().unwrap().footholds.iter().all(|f| f.x >= 1.16));
    for step in &best.steps {
        for f in &step.footholds {
            assert!(!(1.0..1.16).contains(&f.x), "foothold in the gap: {f:?}");
        }
        // The plan places the legs where their n best cells are all off the gap.
        assert_eq!(step.cost.terrain, 0.0, "{step:?}");
    }
    let optimal = planner.plan_optimal(&gap_field(), start, goal, &SearchLimits::none()).unwrap();
    assert!(close(best.cost, optimal.cost));
}

#[test]
fn heuristic_is_consistent_and_admissible_on_the_lattice() {
    let mut planner = hyq_planner(BodyPlannerConfig::default());
    let (start, goal) = (pose(0.0, 0.0, 0.0), pose(2.6, 0.0, 0.0));
    let checked = planner
        .query(&block_field(), start, goal, |space, start_key, workspace| {
            // Every state within a few actions of the start: h(s) <= c(s, s') + h(s').
            let mut frontier = vec![start_key];
            let mut seen: HashSet<LatticeKey> = frontier.iter().copied().collect();
            let mut out: Vec<Edge<LatticeKey, usize>> = Vec::new();
            let mut edges = 0;
            for _depth in 0..4 {
                let mut next = Vec::new();
                for s in frontier {
                    out.clear();
                    space.successors(&s, &mut out);
                    for e in &out {
                        assert!(space.heuristic(&s) <= e.cost + space.heuristic(&e.to) + 1e-12, "{s:?} -> {e:?}");
                        edges += 1;
                        if seen.insert(e.to) {
                            next.push(e.to);
                        }
                    }
                }
                frontier = next;
            }
            let optimal = a_star(space, start_key, &SearchLimits::none(), workspace)?;
            assert!(space.heuristic(&start_key) <= optimal.cost);
            for &s in optimal.states.iter().rev() {
                assert!(space.heuristic(&s) <= optimal.cost);
            }
            Ok(edges)
        })
        .unwrap();
    assert!(checked > 10_000, "{checked}");
}

#[test]
fn forbidden_start_or_goal_and_unreachable_goal_are_errors() {
    let mut planner = hyq_planner(BodyPlannerConfig::default());
    let limits = SearchLimits::none();
    let outside = pose(10.0, 0.0, 0.0);
    assert!(matches!(planner.plan(&flat(), outside, pose(0.0, 0.0, 0.0), &limits), Err(BodyPlanError::StartForbidden { .. })));
    assert!(matches!(planner.plan(&flat(), pose(0.0, 0.0, 0.0), outside, &limits), Err(BodyPlanError::GoalForbidden { .. })));
    // The goal stands on an island (Chebyshev distance 0.5 m around (2, 0)) cut off by a
    // moat 1 m wide, longer than the footprint (0.74 m) plus two foothold windows: no pose
    // has feet on both sides.
    let island = FnField {
        cost: |x: f64, y: f64| {
            let d = (x - 2.0).abs().max(y.abs());
            if d > 0.5 && d < 1.5 {
                1.0
            } else {
                0.0
            }
        },
        height: |_, _| 0.0,
        x_range: [-0.8, 3.6],
        y_range: [-1.0, 1.0],
    };
    let err = planner.plan(&island, pose(0.0, 0.0, 0.0), pose(2.0, 0.0, 0.0), &limits).unwrap_err();
    assert!(matches!(err, BodyPlanError::NoPath { .. }), "{err}");
    let err = planner.plan(&flat(), pose(0.0, 0.0, 0.0), pose(2.0, 0.0, 0.0), &SearchLimits::expansions(3)).unwrap_err();
    assert_eq!(err, BodyPlanError::NoPlanWithinLimits { limit: Limit::Expansions, expansions: 3 });
    let err = planner.plan(&flat(), pose(f64::NAN, 0.0, 0.0), pose(2.0, 0.0, 0.0), &limits).unwrap_err();
    assert!(matches!(err, BodyPlanError::InvalidPose { which: "start", field: "x", .. }));
}

#[test]
fn invalid_settings_name_the_field() {
    let model = embedded::load("hyq").unwrap();
    let try_config = |config: BodyPlannerConfig| match BodyPlanner::for_model(&model, config) {
        Err(BodyPlanError::InvalidConfig { field, .. }) => field,
        Err(other) => panic!("{other}"),
        Ok(_) => panic!("accepted"),
    };
    let mut bad_turn = hyq_crawl_primitives();
    let turn = bad_turn.iter().position(|p| p.name == "turn_left").unwrap();
    bad_turn[turn].dyaw = 15f64.to_radians();
    assert_eq!(try_config(BodyPlannerConfig { primitives: bad_turn, ..Default::default() }), format!("primitives[{turn}] (turn_left).dyaw"));
    let mut tiny = hyq_crawl_primitives();
    let short = tiny.iter().position(|p| p.name == "forward_short").unwrap();
    tiny[short].dx = 0.0;
    assert_eq!(try_config(BodyPlannerConfig { primitives: tiny, ..Default::default() }), format!("primitives[{short}] (forward_short)"));
    let mut between_cells = hyq_crawl_primitives();
    between_cells[short].dx = 0.42;
    assert_eq!(try_config(BodyPlannerConfig { primitives: between_cells, ..Default::default() }), format!("primitives[{short}] (forward_short).dx"));
    let turns_only = hyq_crawl_primitives().into_iter().filter(|p| p.dx == 0.0 && p.dy == 0.0).collect();
    assert_eq!(try_config(BodyPlannerConfig { primitives: turns_only, ..Default::default() }), "primitives");
    let weights = ActionCostWeights { difficulty: 0.0, ..Default::default() };
    assert_eq!(try_config(BodyPlannerConfig { weights, ..Default::default() }), "weights.difficulty");
    assert_eq!(try_config(BodyPlannerConfig { best_cells: 0, ..Default::default() }), "best_cells");
    assert_eq!(try_config(BodyPlannerConfig { goal_position_tolerance: 0.01, ..Default::default() }), "goal_position_tolerance");
    assert_eq!(try_config(BodyPlannerConfig { cell_size: f64::NAN, ..Default::default() }), "cell_size");
    let search = AraStarConfig { final_epsilon: 0.5, ..Default::default() };
    assert_eq!(try_config(BodyPlannerConfig { search, ..Default::default() }), "search.final_epsilon");
}
