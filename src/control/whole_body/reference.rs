//! What a planned motion must provide to the execution controller at every control tick
//! (Winkler 2015, sec. V and Fig. 6: the whole-body motion generator's desired body motion,
//! eq. 8, and the swing-leg trajectories).

use crate::dynamics::{base_orientation, center_of_mass, Data};
use crate::model::Model;
use crate::sim::ControlError;
use nalgebra::{DVector, UnitQuaternion, Vector3};

/// The desired motion of the trunk at one instant, Winkler 2015 eq. (8):
/// `x = (x_cog, R_b)`, `xd = (xd_cog, w_b)`, `xdd = (xdd_cog, wd_b)`, all in the world
/// frame.
///
/// The CoG is the whole-body centre of mass ([`crate::dynamics::center_of_mass`]), the
/// point the ZMP planner's cart-table model moves (Winkler 2015, eq. 5). Velocities and
/// accelerations are time derivatives in world axes; the angular velocity and acceleration
/// of the base are world-frame vectors (not the base-frame `v[3..6]` of the state).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BodyMotion {
    /// Desired CoG position `x_cog^d` (m).
    pub cog_position: Vector3<f64>,
    /// `xd_cog^d` (m/s).
    pub cog_velocity: Vector3<f64>,
    /// Feed-forward `xdd_cog^d` (m/s^2), e.g. the second derivative of the ZMP quintic spline.
    pub cog_acceleration: Vector3<f64>,
    /// Desired base orientation `R_b^d` (base frame to world).
    pub orientation: UnitQuaternion<f64>,
    /// `w_b^d` (rad/s), world axes.
    pub angular_velocity: Vector3<f64>,
    /// Feed-forward `wd_b^d` (rad/s^2), world axes.
    pub angular_acceleration: Vector3<f64>,
}

impl BodyMotion {
    /// Holding a pose: CoG at `cog`, base at `orientation`, no motion.
    pub fn at_rest(cog: Vector3<f64>, orientation: UnitQuaternion<f64>) -> Self {
        Self {
            cog_position: cog,
            cog_velocity: Vector3::zeros(),
            cog_acceleration: Vector3::zeros(),
            orientation,
            angular_velocity: Vector3::zeros(),
            angular_acceleration: Vector3::zeros(),
        }
    }

    /// The first non-finite field, if any.
    fn non_finite_field(&self) -> Option<&'static str> {
        let fields: [(&'static str, &Vector3<f64>); 5] = [
            ("cog_position", &self.cog_position),
            ("cog_velocity", &self.cog_velocity),
            ("cog_acceleration", &self.cog_acceleration),
            ("angular_velocity", &self.angular_velocity),
            ("angular_acceleration", &self.angular_acceleration),
        ];
        if !self.orientation.coords.iter().all(|x| x.is_finite()) {
            return Some("orientation");
        }
        fields.iter().find(|(_, x)| !x.iter().all(|c| c.is_finite())).map(|(name, _)| *name)
    }
}

/// The desired motion of one foot (its sphere centre, the model's foot frame), world
/// frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FootMotion {
    /// m
    pub position: Vector3<f64>,
    /// m/s
    pub velocity: Vector3<f64>,
    /// Feed-forward acceleration (m/s^2).
    pub acceleration: Vector3<f64>,
}

impl FootMotion {
    /// A foot held at `position`.
    pub fn at_rest(position: Vector3<f64>) -> Self {
        Self { position, velocity: Vector3::zeros(), acceleration: Vector3::zeros() }
    }

    fn is_finite(&self) -> bool {
        self.position.iter().chain(self.velocity.iter()).chain(self.acceleration.iter()).all(|x| x.is_finite())
    }
}

/// What one leg does at this tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LegMotion {
    /// The foot is on the ground and must not move (`J_c vd + Jd_c v = 0`); it carries a
    /// share of the contact forces `lambda` (Winkler 2015, eq. 11). Its joint-space target
    /// is the leg posture that keeps the foot where it is now, under the desired base.
    Stance,
    /// The foot follows this trajectory (task-space PD on the foot, no contact force).
    Swing(FootMotion),
}

/// Everything the controller needs from the plan at one tick: the body motion and, per
/// foot in the model's order (`model.feet`: LF, RF, LH, RH on HyQ), stance or a swing
/// target.
#[derive(Debug, PartialEq)]
pub struct WholeBodyReference {
    pub body: BodyMotion,
    pub legs: Vec<LegMotion>,
}

/// `clone_from` reuses the `legs` buffer (the derived one would allocate a new one), so that
/// a source can copy a stored reference into the controller's at every tick for free.
impl Clone for WholeBodyReference {
    fn clone(&self) -> Self {
        Self { body: self.body, legs: self.legs.clone() }
    }
    fn clone_from(&mut self, source: &Self) {
        self.body = source.body;
        self.legs.clone_from(&source.legs);
    }
}

impl WholeBodyReference {
    /// Hold the CoG and base orientation of configuration `q`, all feet in stance.
    pub fn holding(model: &Model, q: &DVector<f64>) -> Self {
        let mut data = Data::new(model);
        let cog = center_of_mass(model, &mut data, q);
        Self { body: BodyMotion::at_rest(cog, base_orientation(q.as_slice())), legs: vec![LegMotion::Stance; model.feet.len()] }
    }

    /// Checks the reference against `nfeet` feet: one leg entry per foot, every number
    /// finite, at least one stance foot (the base is not actuated: without a contact no
    /// torque can realize a body acceleration).
    pub(super) fn check(&self, nfeet: usize) -> Result<(), String> {
        if self.legs.len() != nfeet {
            return Err(format!("reference `legs` needs one entry per foot ({nfeet}), got {}", self.legs.len()));
        }
        if let Some(field) = self.body.non_finite_field() {
            return Err(format!("reference `body.{field}` is not finite"));
        }
        for (i, leg) in self.legs.iter().enumerate() {
            if let LegMotion::Swing(foot) = leg {
                if !foot.is_finite() {
                    return Err(format!("reference `legs[{i}]` swing target is not finite"));
                }
            }
        }
        if !self.legs.iter().any(|l| matches!(l, LegMotion::Stance)) {
            return Err("reference has no stance leg: the unactuated base cannot be controlled in flight".into());
        }
        Ok(())
    }
}

/// The source of the plan, sampled once per control tick at the simulation (or robot)
/// time `t`: the ZMP body trajectory and the swing-foot trajectories at integration.
/// It writes into `reference` (sized for the model's feet), so that sampling allocates
/// nothing.
///
/// Any `FnMut(f64, &mut WholeBodyReference)` closure is a source.
pub trait MotionSource {
    fn sample(&mut self, t: f64, reference: &mut WholeBodyReference) -> Result<(), ControlError>;
}

impl<F: FnMut(f64, &mut WholeBodyReference)> MotionSource for F {
    fn sample(&mut self, t: f64, reference: &mut WholeBodyReference) -> Result<(), ControlError> {
        self(t, reference);
        Ok(())
    }
}
