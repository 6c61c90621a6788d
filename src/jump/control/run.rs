//! A whole jump in legwork's simulator: take-off and flight under eq. (5), the switch, the
//! landing QP, then `settle_time` more seconds, and what it measured against the target.

use super::controller::{JumpController, JumpControllerStats, LandingSettings, LegExtension};
use super::reference::{JumpReference, JumpTarget, PosingTolerance};
use super::tracking::JumpGains;
use super::JumpControlError;
use crate::dynamics::base_orientation;
use crate::io::Trajectory;
use crate::model::Model;
use crate::sim::{SimConfig, SimError, Simulator};
use crate::terrain::Terrain;
use nalgebra::{DVector, Vector2};

/// When a robot counts as fallen (checked at every physics step from touch-down on).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FallCriteria {
    /// The base origin below this height above the ground under it (m). Default 0.1 m (the
    /// A1 stands at 0.26 m; its trunk is 0.11 m thick).
    pub min_base_height: f64,
    /// Roll or pitch beyond this (rad). Default 60 deg.
    pub max_tilt: f64,
}

impl Default for FallCriteria {
    fn default() -> Self {
        Self { min_base_height: 0.1, max_tilt: 60f64.to_radians() }
    }
}

/// Everything [`run_jump`] needs besides the robot, the ground and the reference.
#[derive(Clone, Debug, PartialEq)]
pub struct JumpSettings {
    pub jump_gains: JumpGains,
    pub landing: LandingSettings,
    pub extension: LegExtension,
    pub posing_tolerance: PosingTolerance,
    /// How early each lifting leg ends its push: `None` (the default), by the time its foot
    /// needs to rise out of the ground its last push pressed in, at
    /// `lift_off_retraction_speed` ([`JumpReference::with_lift_off_release`]); `Some(lead)`,
    /// the same lead for every lifting leg ([`JumpReference::with_lift_off_lead`], s).
    pub lift_off_lead: Option<f64>,
    /// `v_r` of [`JumpReference::with_lift_off_release`] (2.3 m/s): measured, not derived.
    /// barrel_roll's last push (260 N per foot, ~8 mm into legwork's A1 contact) lands
    /// with a constant lead of 3 or 4 ms, not 0 or 5 ms (docs/experiments/jump-flip.md);
    /// 2.3 m/s gives it 3.7 ms, and lateral_down's 20 N push 0.3 ms (it lands 20/20 without
    /// a lead and 11/20 with 4 ms).
    pub lift_off_retraction_speed: f64,
    /// The simulator: default [`SimConfig::default`] (2 kHz physics, 1 kHz control, the
    /// motors' effort limits enforced).
    pub sim: SimConfig,
    /// Simulated time after touch-down (s). Default 1 s (the paper's "one second after").
    pub settle_time: f64,
    /// How long after the reference's last knot the robot may still be in the air (s)
    /// before the run stops as "never landed". Default 1 s.
    pub max_late_landing: f64,
    /// Time between the recorded knots (s), a multiple of the physics step. Default 10 ms.
    pub record_dt: f64,
    pub fall: FallCriteria,
}

impl JumpSettings {
    /// The controllers' reference of `trajectory`, with the lift-off lead of these settings
    /// (the release time of `model`'s contact, or the constant lead).
    pub fn reference(&self, model: &Model, trajectory: &Trajectory) -> Result<JumpReference, JumpControlError> {
        let reference = JumpReference::new(model, trajectory, self.posing_tolerance)?;
        match self.lift_off_lead {
            Some(lead) => reference.with_lift_off_lead(lead),
            None => reference.with_lift_off_release(model.contact.normal_stiffness, self.lift_off_retraction_speed),
        }
    }
}

impl Default for JumpSettings {
    fn default() -> Self {
        Self {
            jump_gains: JumpGains::default(),
            landing: LandingSettings::default(),
            extension: LegExtension::default(),
            posing_tolerance: PosingTolerance::default(),
            lift_off_lead: None,
            lift_off_retraction_speed: 2.3,
            sim: SimConfig::default(),
            settle_time: 1.0,
            max_late_landing: 1.0,
            record_dt: 0.01,
            fall: FallCriteria::default(),
        }
    }
}

/// What a jump did.
#[derive(Clone, Debug)]
pub struct JumpRun {
    pub target: JumpTarget,
    /// Start of the flight that ended in the landing: the last instant, before the switch,
    /// from which every foot stayed below the contact threshold (s).
    pub lift_off: Option<f64>,
    /// Its end: the first foot at or above the threshold (s). A bounce before `T_posing`
    /// (e.g. a foot tapping the ground in the two-leg phase) is not a landing.
    pub touch_down: Option<f64>,
    /// The switch to the landing controller (s).
    pub switch: Option<f64>,
    /// At the end (touch-down + `settle_time`): horizontal distance of the base to the
    /// target (m), yaw error (rad, wrapped), |roll|, |pitch| (rad).
    pub position_error: f64,
    pub yaw_error: f64,
    pub roll: f64,
    pub pitch: f64,
    /// The robot fell ([`FallCriteria`]), never landed, or the simulation diverged.
    pub fell: bool,
    /// Why the run ended early, if it did.
    pub failure: Option<String>,
    /// Largest torque applied (N m, after the motors' limits).
    pub max_torque: f64,
    /// Control periods with a torque clipped at a motor limit.
    pub saturated_controls: u64,
    pub controller: JumpControllerStats,
    /// The run, every `record_dt`.
    pub trajectory: Trajectory,
}

/// Runs `reference` on `model` (simulated and controlled with the same robot) on
/// `terrain`, starting at rest in the reference's first configuration.
pub fn run_jump(model: &Model, terrain: &dyn Terrain, reference: &Trajectory, settings: &JumpSettings) -> Result<JumpRun, JumpControlError> {
    run_jump_on(model, model, terrain, reference, settings, Vector2::zeros())
}

/// [`run_jump`] with a simulated robot `plant` that may differ from the controller's
/// `model` (mass and inertia errors), the initial base moved horizontally by `base_offset`
/// (m) and set onto the ground.
pub fn run_jump_on(plant: &Model, model: &Model, terrain: &dyn Terrain, reference: &Trajectory, settings: &JumpSettings, base_offset: Vector2<f64>) -> Result<JumpRun, JumpControlError> {
    let positive = |x: f64| x.is_finite() && x > 0.0;
    if !(positive(settings.settle_time) && positive(settings.max_late_landing) && positive(settings.record_dt)) {
        return Err(JumpControlError::Setting { field: "settle_time/max_late_landing/record_dt", expected: "positive, finite times (s)".into() });
    }
    if plant.nq != model.nq || plant.feet.len() != model.feet.len() {
        return Err(JumpControlError::Robot(format!("the simulated robot '{}' and the controller's '{}' differ in structure", plant.name, model.name)));
    }
    let reference = settings.reference(model, reference)?;
    let target = reference.target();
    let t_end = reference.duration_end();
    let (q0, v0) = reference.initial_state();
    let mut q0 = q0.clone();
    q0[0] += base_offset.x;
    q0[1] += base_offset.y;
    // Lift the offset robot onto the ground as far as the reference stood on it.
    let rise = ground_clearance(model, terrain, reference.initial_state().0) - ground_clearance(plant, terrain, &q0);
    q0[2] += rise;
    let v0 = v0.clone();
    let mut controller = JumpController::new(model, reference, settings.jump_gains, settings.landing, settings.extension)?;
    let mut sim = Simulator::new(plant, terrain, settings.sim.clone(), q0, Some(v0))?;
    let physics_dt = settings.sim.physics_dt;
    let record_every = (settings.record_dt / physics_dt).round().max(1.0) as u64;
    let mut trajectory = Trajectory::new(plant, "jump", record_every as f64 * physics_dt, terrain.spec());
    let threshold = settings.landing.contact_threshold;
    let (mut lift_off, mut touch_down) = (None, None);
    // The current and the last completed interval with every foot unloaded, until the switch.
    let mut unloaded_since: Option<f64> = None;
    let mut last_flight: Option<(f64, f64)> = None;
    let mut failure = None;
    let mut fell = false;
    let mut step: u64 = 0;
    loop {
        let t = sim.state().t;
        if let Some(td) = touch_down {
            if t >= td + settings.settle_time {
                break;
            }
        } else if t > t_end + settings.max_late_landing {
            failure = Some(format!("never landed: still in the air {} s after the reference's end", settings.max_late_landing));
            fell = true;
            break;
        }
        controller.sense(sim.feet());
        if step % record_every == 0 {
            trajectory.knots.push(sim.knot());
        }
        match sim.step(&mut controller) {
            Ok(()) => {}
            Err(SimError::Diverged { t, reason, .. }) => {
                failure = Some(format!("simulation diverged at t = {t:.3} s: {reason}"));
                fell = true;
                break;
            }
            Err(e) => return Err(e.into()),
        }
        step += 1;
        let loaded = sim.feet().iter().any(|f| f.contact.normal_force >= threshold);
        let t = sim.state().t;
        if touch_down.is_none() {
            match (loaded, unloaded_since) {
                (false, None) => unloaded_since = Some(t),
                (true, Some(start)) => {
                    last_flight = Some((start, t));
                    unloaded_since = None;
                }
                _ => {}
            }
            if controller.switch().switched_at().is_some() {
                lift_off = last_flight.map(|f| f.0);
                touch_down = last_flight.map(|f| f.1).or(Some(t));
            }
        }
        if touch_down.is_some() {
            if let Some(reason) = fallen(&settings.fall, terrain, &sim.state().q) {
                failure = Some(format!("fell at t = {t:.3} s: {reason}"));
                fell = true;
                break;
            }
        }
    }
    trajectory.knots.push(sim.knot());
    let q = &sim.state().q;
    let (roll, pitch, yaw) = base_orientation(q.as_slice()).euler_angles();
    let position_error = Vector2::new(q[0] - target.position.x, q[1] - target.position.y).norm();
    let yaw_error = wrap_angle(yaw - target.yaw);
    let stats = sim.stats();
    Ok(JumpRun {
        target,
        lift_off,
        touch_down,
        switch: controller.switch().switched_at(),
        position_error,
        yaw_error,
        roll: roll.abs(),
        pitch: pitch.abs(),
        fell,
        failure,
        max_torque: stats.max_torque,
        saturated_controls: stats.saturated_controls,
        controller: *controller.stats(),
        trajectory,
    })
}

/// The angle in `(-pi, pi]`.
pub fn wrap_angle(a: f64) -> f64 {
    let two_pi = 2.0 * std::f64::consts::PI;
    let w = a.rem_euclid(two_pi);
    if w > std::f64::consts::PI {
        w - two_pi
    } else {
        w
    }
}

/// Height of the lowest foot sphere's bottom above the ground under it (m).
fn ground_clearance(model: &Model, terrain: &dyn Terrain, q: &DVector<f64>) -> f64 {
    let mut data = crate::dynamics::Data::new(model);
    crate::dynamics::forward_kinematics(model, &mut data, q);
    model
        .feet
        .iter()
        .map(|f| {
            let p = crate::dynamics::frame_position(model, &data, f.frame);
            p.z - f.radius - terrain.height(p.x, p.y)
        })
        .fold(f64::INFINITY, f64::min)
}

/// Why the robot at `q` counts as fallen, if it does.
fn fallen(criteria: &FallCriteria, terrain: &dyn Terrain, q: &DVector<f64>) -> Option<String> {
    let height = q[2] - terrain.height(q[0], q[1]);
    let (roll, pitch, _) = base_orientation(q.as_slice()).euler_angles();
    if height < criteria.min_base_height {
        Some(format!("base {height:.3} m above the ground"))
    } else if roll.abs() > criteria.max_tilt || pitch.abs() > criteria.max_tilt {
        Some(format!("roll {:.1} deg, pitch {:.1} deg", roll.to_degrees(), pitch.to_degrees()))
    } else {
        None
    }
}
