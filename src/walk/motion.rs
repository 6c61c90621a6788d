//! The whole-body motion generator (Winkler 2015, sec. IV): from a footstep sequence to the
//! reference the execution controller tracks at every tick.
//!
//! * the horizontal CoG motion is the ZMP-stable quintic spline of [`crate::zmp::ZmpQp`]
//!   (eq. 3-7), with four-leg support phases inserted where consecutive shrunk support
//!   triangles are disjoint;
//! * the remaining degrees of freedom follow the footholds (sec. IV-C, "chosen based mostly
//!   on the foothold heights"): during each phase the CoG height moves to the mean foothold
//!   height plus the nominal CoG height, the pitch to the slope between the front and hind
//!   footholds, the roll to the slope between the left and right ones, and the yaw to the
//!   body action's, each along the rest-to-rest quintic `sigma(u) = 10u^3 - 15u^4 + 6u^5`
//!   (zero velocity and acceleration at the phase ends, so the reference stays twice
//!   differentiable and a re-plan at a phase boundary starts from rest in these); the height
//!   is taken halfway between the mean and the lowest foothold, so that over a step the
//!   leg on the lower level keeps reaching its foot;
//! * each swing follows a [`SwingTrajectory`] that clears the terrain between the footholds.

use crate::plan::body::BodyPose;
use crate::plan::footstep::Footstep;
use crate::plan::TerrainCostField;
use crate::control::{BodyMotion, FootMotion, LegMotion, WholeBodyReference};
use crate::zmp::swing::rest_to_rest;
use crate::zmp::{self, CogState, CogTrajectory, PhaseOrigin, SupportPhase, SwingShape, SwingTrajectory, ZmpQp};
use nalgebra::{Point2, Point3, UnitQuaternion, Vector2, Vector3};

/// Timing and shape of the walk.
#[derive(Clone, Debug, PartialEq)]
pub struct GaitParams {
    /// Duration of a swing on level ground (s).
    pub swing_duration: f64,
    /// Extra swing time per metre the foot must rise or drop (above the higher foothold to
    /// clear the terrain between, or from one level to another) (s/m): stepping onto a
    /// pallet takes longer than a level step.
    pub swing_time_per_height: f64,
    /// Extra swing time when forbidden ground (cost 1: a lip, a gap, the pit around a
    /// stepping stone) lies within a cell of the foothold or of a stance foot (s): those
    /// feet have a few centimetres of room, and a slower swing lands more softly and asks
    /// the stance feet for smaller forces, so they slide less.
    pub careful_swing_extra: f64,
    /// Four-leg support before the first step of a plan (s).
    pub initial_stance: f64,
    /// Four-leg support after the last step, while the CoG settles at the goal (s).
    pub final_stance: f64,
    /// Swing apex above the highest point between the footholds (m).
    pub step_height: f64,
    /// Height above that point the foot keeps while it moves horizontally (m).
    pub clearance: f64,
    /// CoG height above the footholds (m): `z_cog` of the cart-table model (eq. 5).
    pub cog_height: f64,
    /// Distance between the front and hind footholds and between the left and right ones in
    /// the nominal stance (m): the levers of the pitch and roll that follow the footholds.
    pub stance_length: f64,
    pub stance_width: f64,
    /// Foot sphere radius (m): swing targets are foot centres, one radius above the ground.
    pub foot_radius: f64,
    /// How far below the mapped surface a swing ends (m). A loaded foot sinks about 1 cm
    /// into the soft contact and the mapped height is off by the map's noise: a swing that
    /// ends on the surface leaves the foot hanging at the planned touchdown, and the stance
    /// controller, which then gives it its share of the weight, slams it down. Aiming below
    /// makes the foot meet the ground near the end of its (slowing) descent instead.
    pub touchdown_depth: f64,
}

/// The slow, smooth parts of the body pose: CoG height (world z) and roll, pitch, yaw.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Posture {
    pub cog_z: f64,
    pub roll: f64,
    pub pitch: f64,
    pub yaw: f64,
}

impl Posture {
    fn as_array(&self) -> [f64; 4] {
        [self.cog_z, self.roll, self.pitch, self.yaw]
    }

    /// The posture over four footholds (LF, RF, LH, RH surface points) for body yaw `yaw`.
    pub fn over_footholds(feet: &[Vector3<f64>; 4], yaw: f64, gait: &GaitParams) -> Self {
        // Halfway between the mean and the lowest foothold: over a step the body rises less
        // than the mean would lift it, so the leg on the lower level still reaches its foot.
        let mean = 0.5 * (feet.iter().map(|f| f.z).sum::<f64>() / 4.0 + feet.iter().map(|f| f.z).fold(f64::INFINITY, f64::min));
        let front = 0.5 * (feet[0].z + feet[1].z);
        let hind = 0.5 * (feet[2].z + feet[3].z);
        let left = 0.5 * (feet[0].z + feet[2].z);
        let right = 0.5 * (feet[1].z + feet[3].z);
        // Nose up (front higher) is a negative rotation about the base y axis (z up).
        Self { cog_z: mean + gait.cog_height, roll: ((left - right) / gait.stance_width).atan(), pitch: -((front - hind) / gait.stance_length).atan(), yaw }
    }
}

/// Whether a cell next to the foothold `p` (or its own) is forbidden (terrain cost 1).
fn next_to_forbidden_ground(terrain: &dyn TerrainCostField, p: Point2<f64>) -> bool {
    crate::plan::costs_around(terrain, p.x, p.y, 1).any(|c| c >= 1.0)
}

/// Orientation `Rz(yaw) Ry(pitch) Rx(roll)` and its world angular velocity for the rates.
fn orientation_and_rate(rpy: [f64; 3], rates: [f64; 3]) -> (UnitQuaternion<f64>, Vector3<f64>) {
    let [roll, pitch, yaw] = rpy;
    let rz = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw);
    let ry = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), pitch);
    let rx = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), roll);
    // w = z yaw' + Rz y pitch' + Rz Ry x roll'
    let w = Vector3::z() * rates[2] + rz * (Vector3::y() * rates[1]) + (rz * ry) * (Vector3::x() * rates[0]);
    (rz * ry * rx, w)
}

/// One swing of the plan.
#[derive(Clone, Debug, PartialEq)]
pub struct PlannedSwing {
    pub leg: usize,
    /// Index into [`MotionPlan::footsteps`].
    pub step: usize,
    pub trajectory: SwingTrajectory,
}

/// Problems building a motion plan.
#[derive(Debug, thiserror::Error)]
pub enum MotionError {
    #[error("ZMP body trajectory: {0}")]
    Zmp(#[from] zmp::ZmpError),
    #[error("swing of {leg} (step {step}): {source}")]
    Swing { leg: &'static str, step: usize, source: zmp::SwingError },
}

/// A planned motion: ZMP CoG spline, postures, swings, on the simulation clock from
/// `start_time`.
#[derive(Clone, Debug)]
pub struct MotionPlan {
    pub start_time: f64,
    pub footsteps: Vec<Footstep>,
    pub cog: CogTrajectory,
    /// Posture at the start of each planned phase, and one more at the end of the last.
    pub postures: Vec<Posture>,
    /// The swing of each planned phase (`None` in four-leg support).
    pub swings: Vec<Option<PlannedSwing>>,
    /// The feet (surface points) at the end of the plan.
    pub final_feet: [Vector3<f64>; 4],
    pub gait: GaitParams,
}

impl MotionPlan {
    /// Plans the body motion for `footsteps` from the feet at `feet` (surface points), the
    /// horizontal CoG state `cog_start`, the posture `posture_start` (at rest), to a CoG at
    /// rest at `goal_cog`.
    #[allow(clippy::too_many_arguments)]
    pub fn build(
        terrain: &dyn TerrainCostField,
        qp: &mut ZmpQp,
        gait: &GaitParams,
        start_time: f64,
        feet: [Vector3<f64>; 4],
        cog_start: &CogState,
        posture_start: Posture,
        footsteps: Vec<Footstep>,
        goal_cog: Vector2<f64>,
    ) -> Result<Self, MotionError> {
        // The support phases: four-leg stance, one swing per step (its duration from the
        // height the foot must travel), four-leg stance at the end.
        let mut support = feet.map(|f| Point2::new(f.x, f.y));
        let mut phases = Vec::with_capacity(footsteps.len() + 2);
        phases.push(SupportPhase::four_leg(support, gait.initial_stance, gait.cog_height));
        for s in &footsteps {
            let top = terrain_top(terrain, &s.from, &s.to).unwrap_or(f64::NEG_INFINITY);
            let travel = (s.to.z - s.from.z).abs().max(top - s.from.z.max(s.to.z)).max(0.0);
            let target = Point2::new(s.to.x, s.to.y);
            let stance_near_forbidden = (0..4).filter(|&l| l != s.leg).any(|l| next_to_forbidden_ground(terrain, support[l]));
            let careful = if stance_near_forbidden || next_to_forbidden_ground(terrain, target) { gait.careful_swing_extra } else { 0.0 };
            let duration = gait.swing_duration + gait.swing_time_per_height * travel + careful;
            phases.push(SupportPhase::swing(support, zmp::Leg::ALL[s.leg], duration, gait.cog_height));
            support[s.leg] = target;
        }
        phases.push(SupportPhase::four_leg(support, gait.final_stance, gait.cog_height));
        let cog = qp.solve(&phases, cog_start, Point2::from(goal_cog))?;

        let mut postures = vec![posture_start];
        let mut swings = Vec::with_capacity(cog.phases().len());
        let mut current = feet;
        let mut yaw = posture_start.yaw;
        for planned in cog.phases() {
            let swing = match planned.origin {
                // Given phase 0 is the initial stance; given phase j >= 1 is step j - 1 (the
                // last given phase is the final stance).
                PhaseOrigin::Given(j) if j >= 1 && j <= footsteps.len() => {
                    let step = j - 1;
                    let s = &footsteps[step];
                    let lift_off = Point3::new(s.from.x, s.from.y, s.from.z + gait.foot_radius);
                    let touch_down = Point3::new(s.to.x, s.to.y, s.to.z + gait.foot_radius - gait.touchdown_depth);
                    let top = terrain_top(terrain, &s.from, &s.to).map(|h| h + gait.foot_radius);
                    let trajectory = SwingTrajectory::new(lift_off, touch_down, planned.phase.duration, top, SwingShape { step_height: gait.step_height, clearance: gait.clearance })
                        .map_err(|source| MotionError::Swing { leg: crate::model::description::LEG_ORDER[s.leg], step, source })?;
                    current[s.leg] = s.to;
                    yaw = s.body.yaw;
                    Some(PlannedSwing { leg: s.leg, step, trajectory })
                }
                _ => None,
            };
            swings.push(swing);
            postures.push(Posture::over_footholds(&current, yaw, gait));
        }
        Ok(Self { start_time, footsteps, cog, postures, swings, final_feet: current, gait: gait.clone() })
    }

    /// Duration of the plan (s).
    pub fn duration(&self) -> f64 {
        self.cog.duration()
    }

    /// Simulation time at which the plan ends.
    pub fn end_time(&self) -> f64 {
        self.start_time + self.duration()
    }

    /// Index of the planned phase at simulation time `t` (clamped to the plan).
    pub fn phase_at(&self, t: f64) -> usize {
        let local = (t - self.start_time).clamp(0.0, self.duration());
        self.cog.phase_index(local).unwrap_or(self.cog.phases().len() - 1)
    }

    /// The horizontal CoG state at simulation time `t` (clamped to the plan).
    pub fn cog_state(&self, t: f64) -> CogState {
        let local = (t - self.start_time).clamp(0.0, self.duration());
        self.cog.state(local).unwrap_or_else(|_| CogState::at_rest(self.cog.splines().last().map(|s| s.state(s.duration).position).unwrap_or_default()))
    }

    /// Posture, its rate and its acceleration at simulation time `t`.
    pub fn posture(&self, t: f64) -> (Posture, [f64; 4], [f64; 4]) {
        let local = (t - self.start_time).clamp(0.0, self.duration());
        let k = self.phase_at(t);
        let phase = &self.cog.phases()[k];
        let (a, b) = (self.postures[k].as_array(), self.postures[k + 1].as_array());
        let duration = phase.phase.duration;
        let (s, ds, dds) = rest_to_rest((local - phase.start_time) / duration);
        let mut p = [0.0; 4];
        let mut rate = [0.0; 4];
        let mut acc = [0.0; 4];
        for i in 0..4 {
            p[i] = a[i] + (b[i] - a[i]) * s;
            rate[i] = (b[i] - a[i]) * ds / duration;
            acc[i] = (b[i] - a[i]) * dds / (duration * duration);
        }
        (Posture { cog_z: p[0], roll: p[1], pitch: p[2], yaw: p[3] }, rate, acc)
    }

    /// The leg swinging at simulation time `t`, if any.
    pub fn swing_at(&self, t: f64) -> Option<&PlannedSwing> {
        if t < self.start_time || t > self.end_time() {
            return None;
        }
        self.swings[self.phase_at(t)].as_ref()
    }

    /// The controller's reference at simulation time `t` (after the plan: holding its end).
    pub fn reference(&self, t: f64, out: &mut WholeBodyReference) {
        let cog = self.cog_state(t);
        let (posture, rate, acc) = self.posture(t);
        let rpy = [posture.roll, posture.pitch, posture.yaw];
        let (orientation, angular_velocity) = orientation_and_rate(rpy, [rate[1], rate[2], rate[3]]);
        // The angular acceleration by a central difference of the exact angular velocity.
        let h = 1e-5;
        let at = |dt: f64| {
            let r: [f64; 3] = std::array::from_fn(|i| rpy[i] + rate[i + 1] * dt + 0.5 * acc[i + 1] * dt * dt);
            let d: [f64; 3] = std::array::from_fn(|i| rate[i + 1] + acc[i + 1] * dt);
            orientation_and_rate(r, d).1
        };
        let angular_acceleration = (at(h) - at(-h)) / (2.0 * h);
        out.body = BodyMotion {
            cog_position: Vector3::new(cog.position.x, cog.position.y, posture.cog_z),
            cog_velocity: Vector3::new(cog.velocity.x, cog.velocity.y, rate[0]),
            cog_acceleration: Vector3::new(cog.acceleration.x, cog.acceleration.y, acc[0]),
            orientation,
            angular_velocity,
            angular_acceleration,
        };
        let swing = self.swing_at(t);
        for (leg, motion) in out.legs.iter_mut().enumerate() {
            *motion = match swing {
                Some(s) if s.leg == leg => {
                    let phase = &self.cog.phases()[self.phase_at(t)];
                    let (position, velocity, acceleration) = s.trajectory.state(t - self.start_time - phase.start_time);
                    LegMotion::Swing(FootMotion { position: position.coords, velocity, acceleration })
                }
                _ => LegMotion::Stance,
            };
        }
    }

    /// The body pose the plan ends in.
    pub fn final_body(&self) -> Option<BodyPose> {
        self.footsteps.last().map(|s| s.body)
    }
}

/// The highest terrain between two footholds (along the straight line), if any point is
/// higher than both.
fn terrain_top(terrain: &dyn TerrainCostField, from: &Vector3<f64>, to: &Vector3<f64>) -> Option<f64> {
    let length = (to.xy() - from.xy()).norm();
    let samples = ((length / (0.5 * terrain.resolution())).ceil() as usize).max(1);
    let mut top = f64::NEG_INFINITY;
    for s in 0..=samples {
        let p = from.xy() + (to.xy() - from.xy()) * (s as f64 / samples as f64);
        let h = terrain.height(p.x, p.y);
        if h.is_finite() {
            top = top.max(h);
        }
    }
    (top > from.z.max(to.z)).then_some(top)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn angular_velocity_matches_the_derivative_of_the_orientation() {
        let rpy = [0.1, -0.2, 0.7];
        let rates = [0.3, -0.5, 0.9];
        let (r0, w) = orientation_and_rate(rpy, rates);
        let h = 1e-6;
        let (r1, _) = orientation_and_rate(std::array::from_fn(|i| rpy[i] + rates[i] * h), rates);
        // R1 = exp(w h) R0 in world axes.
        let numeric = (r1 * r0.inverse()).scaled_axis() / h;
        assert!((numeric - w).norm() < 1e-5, "{numeric} vs {w}");
    }

    /// Flat ground whose cells beyond x = 1 m are forbidden (a gap's lip), 4 cm cells.
    struct LipAtOneMetre;

    impl TerrainCostField for LipAtOneMetre {
        fn cost(&self, x: f64, _y: f64) -> f64 {
            if x > 1.0 { 1.0 } else { 0.1 }
        }
        fn height(&self, _x: f64, _y: f64) -> f64 {
            0.0
        }
        fn resolution(&self) -> f64 {
            0.04
        }
    }

    /// A foothold within a cell (4 cm) of forbidden ground asks for a careful swing; one two
    /// cells away does not.
    #[test]
    fn forbidden_ground_within_a_cell_is_noticed() {
        let near = |x: f64| next_to_forbidden_ground(&LipAtOneMetre, Point2::new(x, 0.3));
        assert!(near(1.02) && near(0.97) && near(0.965));
        assert!(!near(0.95) && !near(0.9) && !near(0.0));
    }

    #[test]
    fn posture_follows_the_footholds() {
        let gait = GaitParams { swing_duration: 0.3, swing_time_per_height: 1.3, careful_swing_extra: 0.0, initial_stance: 0.3, final_stance: 0.5, step_height: 0.1, clearance: 0.05, cog_height: 0.55, stance_length: 0.74, stance_width: 0.65, foot_radius: 0.02, touchdown_depth: 0.0 };
        // Front feet 0.15 m up (on a pallet): nose up, i.e. negative pitch.
        let feet = [Vector3::new(0.37, 0.32, 0.15), Vector3::new(0.37, -0.32, 0.15), Vector3::new(-0.37, 0.32, 0.0), Vector3::new(-0.37, -0.32, 0.0)];
        let p = Posture::over_footholds(&feet, 0.2, &gait);
        assert!((p.cog_z - (0.5 * (0.075 + 0.0) + 0.55)).abs() < 1e-12);
        assert!((p.pitch + (0.15f64 / 0.74).atan()).abs() < 1e-12);
        assert_eq!(p.roll, 0.0);
        assert_eq!(p.yaw, 0.2);
    }
}
