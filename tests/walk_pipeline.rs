//! Winkler 2015's pipeline end to end: map, ARA* body plan, footsteps, ZMP body trajectory,
//! and execution with the virtual-model / inverse-dynamics controller in the simulator.

use legwork::model::embedded;
use legwork::plan::body::{BodyPlanner, BodyPose};
use legwork::plan::footstep::plan_footsteps;
use legwork::plan::search::SearchLimits;
use legwork::terrain::{TerrainMap, TerrainMapConfig};
use legwork::walk::scenario::ScenarioSpec;
use legwork::walk::trial::{run_trial, TrialSetup, WalkConfig};
use nalgebra::Vector3;
use rand::{rngs::Xoshiro256PlusPlus, SeedableRng};

/// One metre of flat ground: HyQ stands, maps, plans and crawls to the goal; every swing
/// lands within 2 cm of its foothold and the ZMP of the plan stays inside the support
/// polygons shrunk by the margin (to 1 mm, checked every millisecond).
#[test]
fn hyq_crawls_one_metre_to_its_goal() {
    let scenario = ScenarioSpec::from_toml(
        r#"
name = "short"
summary = "one metre ahead"
start = [0.0, 0.0, 0.0]
goal = [1.0, 0.0, 0.0]
time_limit = 20.0
[world]
origin = [-1.0, -1.5]
size = [3.5, 3.0]
"#,
        "test",
    )
    .unwrap();
    let model = embedded::load("hyq").unwrap();
    let config = WalkConfig::hyq(&model).unwrap();
    let out = run_trial(&model, &scenario, &config, TrialSetup::nominal(7), |_, _| {}).unwrap();
    assert!(out.success, "{:?}", out.failure);
    assert!(out.goal_error < config.goal_tolerance, "{}", out.goal_error);
    assert!(out.bad_footholds.is_empty());
    assert!(!out.plans.is_empty() && out.walking_time > 1.0);
    assert!(out.speed > 0.05, "{} m/s", out.speed);
    assert!(out.touchdowns.len() >= 8, "{} swings", out.touchdowns.len());
    for d in &out.touchdowns {
        let error = ((d.planned[0] - d.actual[0]).powi(2) + (d.planned[1] - d.actual[1]).powi(2)).sqrt();
        assert!(error < 0.02, "{d:?}");
        // The swing aims below the mapped surface, so the foot is on the ground when its
        // stance begins. Between touchdown and lift-off a foot moves by the tangential
        // compliance of the contact (about 1 cm) and, for a hind foot that its diagonal front
        // leg's swing unloads, by a short hop (3.6 cm here at most; 7.5 cm before the forces
        // were clipped into the friction cones and kept from pulling).
        assert!(d.in_contact, "{d:?}");
        assert!(d.stance_slip.is_none_or(|s| s < 0.05), "{d:?}");
    }
    for p in &out.plans {
        assert!(p.zmp_min_margin > -1e-3, "ZMP {} m outside the shrunk polygon", -p.zmp_min_margin);
        assert!(p.plan.cog.continuity_error() < 1e-9);
    }
    // The trajectory file records the walk.
    let last = out.trajectory.knots.last().unwrap();
    assert!((last.q[0] - 1.0).abs() < config.goal_tolerance);
}

/// The 35 cm gap seen through the noisy on-board map: the body plan crosses it and no
/// planned foothold comes within a foot radius of it.
#[test]
fn footholds_across_the_gap_stay_off_it() {
    let scenario = ScenarioSpec::embedded("gap").unwrap();
    let model = embedded::load("hyq").unwrap();
    let config = WalkConfig::hyq(&model).unwrap();
    let world = scenario.world_at(0.0);
    let w = &scenario.world;
    let mut map = TerrainMap::new(TerrainMapConfig { origin: w.origin, size: w.size, ..config.map }).unwrap();
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(3);
    for _ in 0..10 {
        map.observe(&world, [0.0, 0.0], 0.0, &mut rng).unwrap();
    }
    let mut planner = BodyPlanner::for_model(&model, config.body.clone()).unwrap();
    let plan = planner.plan(&map, BodyPose { x: 0.0, y: 0.0, yaw: 0.0 }, BodyPose { x: 3.0, y: 0.0, yaw: 0.0 }, &SearchLimits::none()).unwrap();
    let best = plan.best();
    assert_eq!(best.epsilon, 1.0, "ran to the optimum");
    let stance = config.footsteps.nominal;
    let feet: [Vector3<f64>; 4] = std::array::from_fn(|l| Vector3::new(stance[l][0], stance[l][1], 0.0));
    let steps = plan_footsteps(&map, &config.footsteps, feet, &best.poses).unwrap();
    let gap = w.blocks.iter().find(|b| !b.support).unwrap();
    let radius = model.feet[0].radius;
    let mut crossed = [false; 4];
    for s in &steps {
        assert!(s.to.x < gap.x[0] - radius || s.to.x > gap.x[1] + radius, "{s:?}");
        if s.from.x < gap.x[0] && s.to.x > gap.x[1] {
            crossed[s.leg] = true;
        }
    }
    assert_eq!(crossed, [true; 4], "every foot steps over the gap");
}
