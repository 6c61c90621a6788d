//! One trial of Winkler 2015's pipeline in the simulator (Fig. 2 and Fig. 6): HyQ stands at
//! the scenario's start, builds its terrain map from noisy height samples, plans body
//! actions (ARA*), footsteps and the ZMP body trajectory, and walks with the virtual-model
//! and inverse-dynamics controller at 1 kHz; it re-plans (sec. III-D) when the map shows the
//! world changed or the CoG strays from the plan, at the next phase boundary.
//!
//! A trial succeeds when the base ends within `goal_tolerance` of the goal with no fall and
//! no foot ever touching an unsupported region (a gap, the pit between stepping stones).

use super::motion::{GaitParams, MotionPlan, Posture};
use super::scenario::ScenarioSpec;
use crate::control::{MotionSource, WholeBodyController, WholeBodyReference, WholeBodyStats};
use crate::dynamics::{base_orientation, center_of_mass, Data};
use crate::io::Trajectory;
use crate::model::Model;
use crate::plan::body::{BodyPlanner, BodyPlannerConfig, BodyPose};
use crate::plan::footstep::{plan_footsteps, FootstepParams};
use crate::plan::search::SearchLimits;
use crate::sim::{lift_onto_ground, standing_on_ground, ControlError, SimConfig, Simulator};
use crate::terrain::{Terrain, TerrainMap, TerrainMapConfig};
use crate::zmp::{CogState, ZmpQp, ZmpSettings};
use nalgebra::{DVector, UnitQuaternion, Vector2, Vector3};
use rand::{rngs::Xoshiro256PlusPlus, RngExt, SeedableRng};
use std::time::{Duration, Instant};

/// Everything a trial is tuned by (defaults for HyQ in [`WalkConfig::hyq`]).
#[derive(Clone, Debug)]
pub struct WalkConfig {
    pub gait: GaitParams,
    pub zmp: ZmpSettings,
    pub footsteps: FootstepParams,
    pub body: BodyPlannerConfig,
    /// Wall-clock budget of one body-action search (ARA* returns its best plan by then).
    pub planning_budget: Duration,
    /// Time between two sensor sweeps of the map (s).
    pub sensor_period: f64,
    /// The terrain map (its origin and size are the scenario world's, its noise the trial's).
    pub map: TerrainMapConfig,
    /// Reset map cells in one sweep that count as a change of the world (a lone reset is
    /// sensor noise beyond the map's k-sigma test; a placed pallet resets hundreds).
    pub min_changed_cells: usize,
    /// Horizontal CoG error that triggers a re-plan (m).
    pub replan_deviation: f64,
    /// Standing still under the controller before the first plan (s): ten sensor sweeps
    /// average the map's noise down before footholds are chosen on it.
    pub settle_time: f64,
    /// Base position error at the end that counts as reaching the goal (m).
    pub goal_tolerance: f64,
    /// Roll or pitch beyond which the robot has fallen (rad).
    pub fall_tilt: f64,
    /// Base height above the terrain below it under which the robot has fallen (m).
    pub fall_height: f64,
    /// Time between recorded knots (s).
    pub record_dt: f64,
}

impl WalkConfig {
    /// HyQ's walk: 0.25 s swings on level ground (longer where the foot climbs, 0.05 s longer
    /// next to forbidden ground), 0.15 s four-leg phases, a 10 cm step height, a 5 cm ZMP
    /// margin, the nominal stance of the standing pose.
    pub fn hyq(model: &Model) -> Result<Self, crate::plan::body::BodyPlanError> {
        let foot_radius = model.feet.first().map(|f| f.radius).unwrap_or(0.02);
        let stance = crate::plan::body::NominalStance::from_model(model)?.feet.map(|f| [f.x, f.y]);
        Ok(Self {
            gait: GaitParams {
                swing_duration: 0.25,
                swing_time_per_height: 1.4,
                careful_swing_extra: 0.05,
                initial_stance: 0.2,
                final_stance: 0.6,
                step_height: 0.10,
                clearance: 0.05,
                cog_height: 0.55,
                stance_length: 0.5 * (stance[0][0] + stance[1][0] - stance[2][0] - stance[3][0]),
                stance_width: 0.5 * (stance[0][1] + stance[2][1] - stance[1][1] - stance[3][1]),
                foot_radius,
                touchdown_depth: 0.02,
            },
            // ZMP constraints every 30 ms: between the samples the ZMP then stays within about
            // 0.5 mm of the shrunk polygon (50 ms let it out by 1.3 mm on these 0.25 s swings,
            // 0.1 s by 11 mm on 0.3 s ones).
            zmp: ZmpSettings { four_leg_duration: 0.15, sample_interval: 0.03, ..ZmpSettings::default() },
            footsteps: FootstepParams::hyq(stance),
            // The body planner asks for a usable cell as far from each nominal foothold as
            // the footstep planner searches (12 cm, not its default 8 cm): with 8 cm, a start
            // yawed a few degrees had no lattice path across the 35 cm gap.
            body: BodyPlannerConfig { foothold_radius: FootstepParams::hyq(stance).search_half_width, ..BodyPlannerConfig::default() },
            planning_budget: Duration::from_millis(100),
            sensor_period: 0.1,
            // The scanning depth camera sees the scene to about 4 m; the cost features over
            // 3 x 3 cells (12 cm) so that a 16 cm stepping stone keeps footholds inside its
            // forbidden lip.
            map: TerrainMapConfig {
                sensor: crate::terrain::SensorConfig { range: 4.0, ..Default::default() },
                cost: crate::terrain::CostParams { window_radius_cells: 1, ..Default::default() },
                ..TerrainMapConfig::default()
            },
            min_changed_cells: 8,
            replan_deviation: 0.08,
            settle_time: 1.0,
            goal_tolerance: 0.1,
            fall_tilt: 40f64.to_radians(),
            fall_height: 0.25,
            record_dt: 0.01,
        })
    }
}

/// The randomized part of a trial (the benchmark's "start offset +- 5 cm, yaw +- 5 deg, map
/// noise").
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrialSetup {
    pub seed: u64,
    /// Offset of the start pose: x, y (m), yaw (rad).
    pub start_offset: [f64; 3],
    /// Standard deviation of the map's height samples (m).
    pub map_noise: f64,
}

impl TrialSetup {
    /// The nominal trial: no offset, 1 cm map noise.
    pub fn nominal(seed: u64) -> Self {
        Self { seed, start_offset: [0.0; 3], map_noise: 0.01 }
    }

    /// A random trial: offsets uniform in +-5 cm and +-5 deg, map noise uniform in 0.5-2 cm.
    pub fn random(seed: u64) -> Self {
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed ^ 0x5eed_1e55);
        let mut uniform = |half: f64| half * (2.0 * rng.random::<f64>() - 1.0);
        let start_offset = [uniform(0.05), uniform(0.05), uniform(5f64.to_radians())];
        let map_noise = 0.0125 + uniform(0.0075);
        Self { seed, start_offset, map_noise }
    }
}

/// Why a plan was made.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlanReason {
    Start,
    WorldChanged,
    Deviation,
    GoalNotReached,
}

impl PlanReason {
    pub fn name(&self) -> &'static str {
        match self {
            PlanReason::Start => "start",
            PlanReason::WorldChanged => "world changed",
            PlanReason::Deviation => "deviation",
            PlanReason::GoalNotReached => "goal not reached",
        }
    }
}

/// One plan of a trial and what it cost to make.
#[derive(Clone, Debug)]
pub struct PlanRecord {
    pub t: f64,
    pub reason: PlanReason,
    /// Body-action search (ARA*): time to its first solution and in all, its bound.
    pub body_first_ms: f64,
    pub body_ms: f64,
    pub epsilon: f64,
    pub actions: usize,
    pub footstep_ms: f64,
    pub zmp_ms: f64,
    pub total_ms: f64,
    pub steps: usize,
    /// Smallest distance of the ZMP inside its shrunk support polygon over a 1 ms grid (m;
    /// negative = outside).
    pub zmp_min_margin: f64,
    pub plan: MotionPlan,
}

/// A foot touching ground it must not stand on.
#[derive(Clone, Debug, PartialEq)]
pub struct BadFoothold {
    pub t: f64,
    pub leg: &'static str,
    pub position: [f64; 3],
    pub surface: String,
}

/// Where a swing ended against where it was planned to (foot-sphere centres, world).
#[derive(Clone, Debug, PartialEq)]
pub struct Touchdown {
    pub t: f64,
    pub leg: &'static str,
    pub planned: [f64; 3],
    pub actual: [f64; 3],
    pub in_contact: bool,
    /// How far the foot moved horizontally between this touchdown and its next lift-off (m);
    /// `None` if the trial ended first.
    pub stance_slip: Option<f64>,
}

/// The result of a trial.
#[derive(Clone, Debug)]
pub struct TrialOutcome {
    pub scenario: String,
    pub setup: TrialSetup,
    pub success: bool,
    /// Why it failed (`None` on success).
    pub failure: Option<String>,
    /// Final base position error to the goal (m) and yaw error (rad).
    pub goal_error: f64,
    pub yaw_error: f64,
    /// Time from the first plan to the end of the last (or to the failure) (s), and, for a
    /// successful trial, the average forward speed over it (start-to-goal distance over
    /// that time, m/s; 0 for a failed trial).
    pub walking_time: f64,
    pub speed: f64,
    pub plans: Vec<PlanRecord>,
    pub map_updates: usize,
    /// Longest map update (sample, fuse, local cost) (ms).
    pub max_map_update_ms: f64,
    pub bad_footholds: Vec<BadFoothold>,
    /// Every swing's end, planned against actual foot position.
    pub touchdowns: Vec<Touchdown>,
    /// The largest horizontal distance a foot moved while in stance, from the end of one
    /// swing to the start of its next (m).
    pub max_stance_slip: f64,
    /// The whole-body controller's counts over the trial (clipped torque ticks, force
    /// redistributions, ...).
    pub controller: WholeBodyStats,
    pub trajectory: Trajectory,
    /// The map at the end (for drawing).
    pub map: TerrainMap,
}

#[derive(Debug, thiserror::Error)]
pub enum WalkError {
    #[error("scenario {scenario}: {problem}")]
    Setup { scenario: String, problem: String },
}

/// The controller's source: the current plan, or holding a pose.
struct PlanSource {
    plan: Option<MotionPlan>,
    hold: WholeBodyReference,
}

impl MotionSource for PlanSource {
    fn sample(&mut self, t: f64, reference: &mut WholeBodyReference) -> Result<(), ControlError> {
        match &self.plan {
            Some(plan) => plan.reference(t, reference),
            None => reference.clone_from(&self.hold),
        }
        Ok(())
    }
}

/// HyQ's standing configuration at `pose` on `terrain`, the feet just touching.
fn standing_at(model: &Model, terrain: &dyn Terrain, pose: BodyPose) -> Result<DVector<f64>, crate::sim::SimError> {
    // The checks of `standing_on_ground` (a free flyer, feet); its lift happens at the pose.
    standing_on_ground(model, terrain, 0.0)?;
    let mut q = model.reference_configuration("standing").cloned().unwrap_or_else(|| model.neutral());
    let base = model.joints[1].idx_q;
    q[base] = pose.x;
    q[base + 1] = pose.y;
    let r = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), pose.yaw) * base_orientation(q.as_slice());
    let c = r.quaternion().coords; // (x, y, z, w)
    for k in 0..4 {
        q[base + 3 + k] = c[k];
    }
    lift_onto_ground(model, terrain, &mut q, 0.0);
    Ok(q)
}

/// The planar pose of the base in `q`.
fn body_pose(q: &DVector<f64>) -> BodyPose {
    let r = base_orientation(q.as_slice());
    let (_, _, yaw) = r.euler_angles();
    BodyPose { x: q[0], y: q[1], yaw }
}

/// The posture (CoG height, roll, pitch, yaw) of a reference, for continuity across plans.
fn posture_of(reference: &WholeBodyReference) -> Posture {
    let (roll, pitch, yaw) = reference.body.orientation.euler_angles();
    Posture { cog_z: reference.body.cog_position.z, roll, pitch, yaw }
}

/// Smallest margin of the ZMP inside the shrunk support polygons over a 1 ms grid.
fn zmp_margin(plan: &MotionPlan, gravity: f64) -> f64 {
    let mut worst = f64::INFINITY;
    let duration = plan.duration();
    let n = (duration / 0.001).ceil() as usize;
    for i in 0..=n {
        let t = (i as f64 * 0.001).min(duration);
        let Ok(k) = plan.cog.phase_index(t) else { continue };
        let phase = &plan.cog.phases()[k];
        if let Ok(state) = plan.cog.state(t) {
            let zmp = state.zmp(phase.phase.cog_height, gravity);
            worst = worst.min(phase.shrunk_support.margin(zmp));
        }
    }
    worst
}

/// Runs one trial of `scenario` with `model` (HyQ).
pub fn run_trial(model: &Model, scenario: &ScenarioSpec, config: &WalkConfig, setup: TrialSetup, mut on_progress: impl FnMut(f64, &str)) -> Result<TrialOutcome, WalkError> {
    let setup_error = |problem: String| WalkError::Setup { scenario: scenario.name.clone(), problem };
    // The physics holds every block from the start (a foot reaching a block before the block
    // appears is an error, checked below); the map's sensor sees `world_at(t)`, so a block
    // shows up on the map when it appears.
    let world = scenario.world_at(f64::INFINITY);
    let start = BodyPose { x: scenario.start[0] + setup.start_offset[0], y: scenario.start[1] + setup.start_offset[1], yaw: scenario.start[2] + setup.start_offset[2] };
    let goal = BodyPose { x: scenario.goal[0], y: scenario.goal[1], yaw: scenario.goal[2] };
    let q0 = standing_at(model, &scenario.world_at(0.0), start).map_err(|e| setup_error(e.to_string()))?;
    let sim_config = SimConfig { record_dt: config.record_dt, ..SimConfig::default() };
    let mut sim = Simulator::new(model, &world, sim_config.clone(), q0.clone(), None).map_err(|e| setup_error(e.to_string()))?;
    let control_dt = sim_config.control_dt;
    let hold = WholeBodyReference::holding(model, &q0);
    let mut controller = WholeBodyController::with_default_gains(model, PlanSource { plan: None, hold }, control_dt).map_err(|e| setup_error(e.to_string()))?;

    let w = &scenario.world;
    let map_config = TerrainMapConfig {
        origin: w.origin,
        size: w.size,
        sensor: crate::terrain::SensorConfig { noise_sigma: setup.map_noise, ..config.map.sensor },
        ..config.map
    };
    let mut map = TerrainMap::new(map_config).map_err(|e| setup_error(e.to_string()))?;
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(setup.seed);
    let mut planner = BodyPlanner::for_model(model, config.body.clone()).map_err(|e| setup_error(e.to_string()))?;
    let mut qp = ZmpQp::new(config.zmp).map_err(|e| setup_error(e.to_string()))?;

    let mut data = Data::new(model);
    let cog_offset_body = {
        let q = &q0;
        let c = center_of_mass(model, &mut data, q);
        let r = base_orientation(q.as_slice());
        r.inverse() * (c - Vector3::new(q[0], q[1], q[2]))
    };

    let mut trajectory = Trajectory::new(model, format!("walk {}", scenario.name), config.record_dt, world.spec());
    let mut plans: Vec<PlanRecord> = Vec::new();
    let mut bad_footholds = Vec::new();
    let mut touchdowns = Vec::new();
    let mut swinging: Option<(usize, nalgebra::Point3<f64>)> = None;
    let mut landed: [Option<Vector2<f64>>; 4] = [None; 4];
    let mut max_stance_slip: f64 = 0.0;
    let mut map_updates = 0;
    let mut max_map_update_ms: f64 = 0.0;
    let mut next_sensor = 0.0;
    let mut next_record = 0.0;
    let mut replan: Option<PlanReason> = Some(PlanReason::Start);
    let mut last_phase: Option<usize> = None;
    let mut failure: Option<String> = None;
    let mut walk_start: Option<f64> = None;
    let mut walk_end: Option<f64> = None;
    let mut goal_attempts = 0;

    loop {
        let t = sim.state().t;
        if t > scenario.time_limit {
            failure = Some(format!("time limit of {} s reached", scenario.time_limit));
            break;
        }
        if t >= next_record - 1e-9 {
            trajectory.knots.push(sim.knot());
            next_record += config.record_dt;
        }
        // Sensor sweep.
        if t >= next_sensor - 1e-9 {
            let pose = body_pose(&sim.state().q);
            let seen = scenario.world_at(t);
            let started = Instant::now();
            let update = map.observe(&seen, [pose.x, pose.y], pose.yaw, &mut rng).map_err(|e| setup_error(e.to_string()))?;
            max_map_update_ms = max_map_update_ms.max(started.elapsed().as_secs_f64() * 1e3);
            map_updates += 1;
            if update.world_changed() && update.reset_cells >= config.min_changed_cells && plans.last().is_some() && replan.is_none() {
                replan = Some(PlanReason::WorldChanged);
            }
            next_sensor += config.sensor_period;
        }
        // Deviation from the plan.
        if let (Some(plan), None) = (&controller.source().plan, replan) {
            let planned = plan.cog_state(t).position;
            let actual = center_of_mass(model, &mut data, &sim.state().q);
            if (actual.xy() - planned).norm() > config.replan_deviation {
                replan = Some(PlanReason::Deviation);
            }
        }
        // Plan at the start (after settling) and at phase boundaries when asked to.
        let phase = controller.source().plan.as_ref().map(|p| p.phase_at(t));
        let at_boundary = phase != last_phase || controller.source().plan.as_ref().is_some_and(|p| t >= p.end_time());
        let settled = t >= config.settle_time;
        if let (Some(reason), true, true) = (replan, settled, at_boundary || controller.source().plan.is_none()) {
            let in_swing = controller.source().plan.as_ref().and_then(|p| p.swing_at(t)).is_some();
            if !in_swing {
                on_progress(t, &format!("planning ({})", reason.name()));
                match make_plan(model, &sim, &map, &mut planner, &mut qp, config, controller.source().plan.as_ref(), controller.reference(), t, goal, cog_offset_body, reason) {
                    Ok(record) => {
                        if walk_start.is_none() {
                            walk_start = Some(t);
                        }
                        controller.source_mut().plan = Some(record.plan.clone());
                        plans.push(record);
                        replan = None;
                    }
                    Err(problem) => {
                        failure = Some(format!("plan at t = {t:.2} s ({}): {problem}", reason.name()));
                        break;
                    }
                }
            }
        }
        last_phase = controller.source().plan.as_ref().map(|p| p.phase_at(t));
        // The end of a swing: where the foot is against where it was to land.
        let now_swinging = controller.source().plan.as_ref().and_then(|p| p.swing_at(t)).map(|s| (s.leg, s.trajectory.state(f64::INFINITY).0));
        if let Some((leg, planned)) = swinging {
            if now_swinging.is_none_or(|(l, p)| l != leg || p != planned) {
                let foot = &sim.feet()[leg];
                touchdowns.push(Touchdown { t, leg: crate::model::description::LEG_ORDER[leg], planned: planned.coords.into(), actual: foot.position.into(), in_contact: foot.contact.normal_force > 0.0, stance_slip: None });
                landed[leg] = Some(foot.position.xy());
            }
        }
        if let Some((leg, _)) = now_swinging {
            if swinging.is_none_or(|(l, _)| l != leg) {
                if let Some(p) = landed[leg].take() {
                    let slip = (sim.feet()[leg].position.xy() - p).norm();
                    max_stance_slip = max_stance_slip.max(slip);
                    let name = crate::model::description::LEG_ORDER[leg];
                    if let Some(touchdown) = touchdowns.iter_mut().rev().find(|d| d.leg == name) {
                        touchdown.stance_slip = Some(slip);
                    }
                }
            }
        }
        swinging = now_swinging;

        // The end of a plan: at the goal, or plan again.
        if let Some(plan) = &controller.source().plan {
            if t >= plan.end_time() && replan.is_none() {
                let pose = body_pose(&sim.state().q);
                let error = ((pose.x - goal.x).powi(2) + (pose.y - goal.y).powi(2)).sqrt();
                if error <= config.goal_tolerance {
                    walk_end = Some(plan.end_time());
                    break;
                }
                goal_attempts += 1;
                if goal_attempts > 3 {
                    failure = Some(format!("the base stopped {error:.3} m from the goal after {goal_attempts} plans ending there"));
                    break;
                }
                replan = Some(PlanReason::GoalNotReached);
            }
        }

        if let Err(e) = sim.step(&mut controller) {
            failure = Some(format!("simulation stopped at t = {t:.3} s: {e}"));
            break;
        }
        // Falls and feet on unsupported ground.
        let q = &sim.state().q;
        let r = base_orientation(q.as_slice());
        let (roll, pitch, _) = r.euler_angles();
        let ground = world.height(q[0], q[1]);
        if roll.abs() > config.fall_tilt || pitch.abs() > config.fall_tilt || q[2] - ground < config.fall_height {
            failure = Some(format!("fell at t = {:.2} s (roll {:.0} deg, pitch {:.0} deg, base {:.2} m above the ground)", sim.state().t, roll.to_degrees(), pitch.to_degrees(), q[2] - ground));
            break;
        }
        for (leg, foot) in sim.feet().iter().enumerate() {
            if foot.contact.normal_force > 0.0 && !scenario.supports(sim.state().t, foot.position.x, foot.position.y) {
                let name = crate::model::description::LEG_ORDER[leg];
                if bad_footholds.iter().all(|b: &BadFoothold| b.leg != name || (sim.state().t - b.t) > 0.1) {
                    bad_footholds.push(BadFoothold { t: sim.state().t, leg: name, position: foot.position.into(), surface: scenario.surface_name(sim.state().t, foot.position.x, foot.position.y) });
                }
            }
        }
        if !bad_footholds.is_empty() {
            let b = &bad_footholds[0];
            failure = Some(format!("{} touched {} at ({:.2}, {:.2}) at t = {:.2} s", b.leg, b.surface, b.position[0], b.position[1], b.t));
            break;
        }
        // No foot on a block before it appears.
        for b in scenario.world.blocks.iter().filter(|b| b.appears_at.is_some_and(|a| a > sim.state().t)) {
            for foot in sim.feet() {
                if foot.position.x >= b.x[0] && foot.position.x <= b.x[1] && foot.position.y >= b.y[0] && foot.position.y <= b.y[1] {
                    return Err(setup_error(format!("a foot reached block '{}' before it appears at {} s", b.name.clone().unwrap_or_default(), b.appears_at.unwrap_or(0.0))));
                }
            }
        }
    }
    if trajectory.knots.last().is_none_or(|k| k.t < sim.state().t) {
        trajectory.knots.push(sim.knot());
    }
    let pose = body_pose(&sim.state().q);
    let goal_error = ((pose.x - goal.x).powi(2) + (pose.y - goal.y).powi(2)).sqrt();
    let yaw_error = crate::plan::body::wrap_angle(pose.yaw - goal.yaw).abs();
    let walking_time = match (walk_start, walk_end) {
        (Some(a), Some(b)) => b - a,
        (Some(a), None) => sim.state().t - a,
        _ => 0.0,
    };
    let distance = ((goal.x - start.x).powi(2) + (goal.y - start.y).powi(2)).sqrt();
    let success = failure.is_none() && goal_error <= config.goal_tolerance;
    Ok(TrialOutcome {
        scenario: scenario.name.clone(),
        setup,
        success,
        failure,
        goal_error,
        yaw_error,
        walking_time,
        speed: if success && walking_time > 0.0 { distance / walking_time } else { 0.0 },
        plans,
        map_updates,
        max_map_update_ms,
        bad_footholds,
        touchdowns,
        max_stance_slip,
        controller: controller.stats().clone(),
        trajectory,
        map,
    })
}

/// Body actions, footsteps and ZMP trajectory from the robot's state at `t`.
#[allow(clippy::too_many_arguments)]
fn make_plan(
    model: &Model,
    sim: &Simulator<'_>,
    map: &TerrainMap,
    planner: &mut BodyPlanner,
    qp: &mut ZmpQp,
    config: &WalkConfig,
    previous: Option<&MotionPlan>,
    reference: &WholeBodyReference,
    t: f64,
    goal: BodyPose,
    cog_offset_body: Vector3<f64>,
    reason: PlanReason,
) -> Result<PlanRecord, String> {
    let started = Instant::now();
    let q = &sim.state().q;
    let pose = body_pose(q);
    // Body actions (ARA*, anytime within the budget).
    let limits = SearchLimits::time(config.planning_budget);
    let t0 = Instant::now();
    let anytime = planner.plan(map, pose, goal, &limits).map_err(|e| e.to_string())?;
    let body_ms = t0.elapsed().as_secs_f64() * 1e3;
    let body_first_ms = anytime.plans[0].elapsed.as_secs_f64() * 1e3;
    let best = anytime.best();
    let path: Vec<BodyPose> = best.poses.iter().map(|p| BodyPose { x: p.x, y: p.y, yaw: p.yaw }).collect();
    // Footsteps from where the feet are.
    let radius = config.gait.foot_radius;
    let feet: [Vector3<f64>; 4] = std::array::from_fn(|leg| {
        let p = sim.feet()[leg].position;
        Vector3::new(p.x, p.y, p.z - radius)
    });
    let t1 = Instant::now();
    let footsteps = plan_footsteps(map, &config.footsteps, feet, &path).map_err(|e| e.to_string())?;
    let footstep_ms = t1.elapsed().as_secs_f64() * 1e3;
    // ZMP body trajectory from the CoG state of the previous plan (continuity) or at rest.
    let mut data = Data::new(model);
    let cog_now = center_of_mass(model, &mut data, q);
    let cog_start = match previous {
        Some(p) => p.cog_state(t),
        None => CogState::at_rest(cog_now.xy()),
    };
    let posture = posture_of(reference);
    let end = path.last().copied().unwrap_or(pose);
    let (s, c) = end.yaw.sin_cos();
    let goal_cog = Vector2::new(end.x + c * cog_offset_body.x - s * cog_offset_body.y, end.y + s * cog_offset_body.x + c * cog_offset_body.y);
    let t2 = Instant::now();
    let plan = MotionPlan::build(map, qp, &config.gait, t, feet, &cog_start, posture, footsteps, goal_cog).map_err(|e| e.to_string())?;
    let zmp_ms = t2.elapsed().as_secs_f64() * 1e3;
    let zmp_min_margin = zmp_margin(&plan, config.zmp.gravity);
    Ok(PlanRecord {
        t,
        reason,
        body_first_ms,
        body_ms,
        epsilon: best.epsilon,
        actions: best.steps.len(),
        footstep_ms,
        zmp_ms,
        total_ms: started.elapsed().as_secs_f64() * 1e3,
        steps: plan.footsteps.len(),
        zmp_min_margin,
        plan,
    })
}
