//! The execution controller of Winkler 2015, sec. V (Fig. 6): a virtual model on the
//! trunk (eq. 9) gives feedback accelerations that are added to the plan's feed-forward
//! accelerations (eq. 10); floating-base inverse dynamics by partitioning (eq. 11) turns
//! them into contact forces and joint torques; a low-gain joint PD compensates model
//! errors. It runs as a [`Controller`] in the [`crate::sim::Simulator`] (1 kHz control).
//!
//! # What the plan must provide at every tick
//!
//! A [`MotionSource`] is sampled once per control tick at time `t` and fills a
//! [`WholeBodyReference`] (preallocated, one entry per foot in `model.feet` order):
//!
//! * [`BodyMotion`] (world frame): CoG position, velocity and feed-forward acceleration
//!   (the ZMP planner's quintic spline and its derivatives, Winkler 2015 eq. 3; `z` from
//!   the footholds), base orientation as a unit quaternion, angular velocity and
//!   feed-forward angular acceleration as world-frame vectors. The CoG is the whole-body
//!   centre of mass ([`crate::dynamics::center_of_mass`]). Accelerations should be
//!   continuous (eq. 4): a step in the reference is a step in the torques.
//! * per leg, [`LegMotion::Stance`] (the foot is on the ground and stays where it is) or
//!   [`LegMotion::Swing`] with the foot-sphere centre's position, velocity and feed-forward
//!   acceleration ([`FootMotion`], world frame). A swing trajectory should end at the
//!   foothold (foot-sphere centre one radius above the terrain) with zero velocity, and
//!   the leg be switched to `Stance` at touchdown.
//! * at least one stance leg (the base is not actuated); three or more not on one line for
//!   the base rows of eq. (11) to be met exactly (two give the least-squares forces).
//!
//! Any `FnMut(f64, &mut WholeBodyReference)` closure is a source;
//! [`WholeBodyController::execute`] takes a reference directly (no source).
//!
//! # One tick
//!
//! 1. kinematics at the measured `(q, v)`: CoG and its velocity, the composite inertia
//!    `I_c` about the CoG, each foot's position, velocity, Jacobian and `Jd v`;
//! 2. eq. (9)-(10): virtual wrench, reference CoG and angular acceleration, moved to the
//!    base coordinates `vd[0..6]` (`bX_cog`, [`virtual_model::base_acceleration`]);
//! 3. legs: stance legs get the joint accelerations that keep the foot still,
//!    `J_c vd + Jd_c v = 0`; swing legs those that give the foot
//!    `pdd^d + K_p (p^d - p) + K_d (pd^d - pd)` (task-space PD through the 3 x 3 leg
//!    Jacobian; a damped least-squares solve near a stretched knee);
//! 4. eq. (11): `b = RNEA(q, v, vd^ref)`, `lambda = (J_cb^T)^+ b_b` over the stance feet
//!    (tangential components weighted), clipped into the friction cones and, if that
//!    changed a force, redistributed inside them by the priority of each base row
//!    ([`FrictionConeDistribution`]); `tau^id = b_q - J_cq^T lambda`;
//! 5. joint targets for the PD: Newton inverse kinematics of every leg with the base at
//!    its desired pose (stance feet where they are, swing feet at their targets), joint
//!    velocities from the leg Jacobians; `tau = tau^id + K_p (q^d - q) + K_d (qd^d - qd)`;
//! 6. clipped to the model's effort limits (counted in [`WholeBodyStats`]).
//!
//! Nothing allocates in a tick: every buffer lives in the controller.

mod force_distribution;
mod inverse_dynamics;
mod legs;
mod reference;
pub mod virtual_model;

#[cfg(test)]
mod tests;

pub use force_distribution::{project_to_cone, DistributionInfo, DistributionProblem, DistributionSettings, FrictionConeDistribution};
pub use inverse_dynamics::{clip_to_friction_cones, contact_forces, friction_weighted_contact_forces, joint_torques};
pub use legs::{foot_position, leg_chains, leg_jacobian, legs_inverse_kinematics, solve_leg, velocities_and_bias, FootKinematics, LegChain};
pub use reference::{BodyMotion, FootMotion, LegMotion, MotionSource, WholeBodyReference};

use self::legs::{base_jacobian, foot_kinematics};
use self::virtual_model::{base_acceleration, desired_base, reference_acceleration, virtual_model_wrench, BodyState, CompositeInertia};
use super::{BaseGains, PdGains};
use crate::dynamics::{base_orientation, centroidal_map, rnea, Data};
use crate::model::Model;
use crate::sim::{ControlError, Controller, SimState};
use crate::spatial::{log3, Motion};
use nalgebra::{DVector, Vector3, Vector6};

/// Natural frequency of the default virtual springs (Hz), critically damped.
const VIRTUAL_MODEL_HZ: f64 = 3.0;
/// Natural frequency of the default swing-foot PD (Hz), critically damped.
const SWING_FOOT_HZ: f64 = 8.0;
/// The default joint PD's stiffness is this fraction of the standing controller's
/// ([`PdGains::from_model`]): "low-gain", the inverse dynamics does the work.
const JOINT_STIFFNESS_FRACTION: f64 = 0.1;
/// Its damping is this fraction of the standing controller's. Damping is what keeps the
/// stance feet from ringing on a compliant ground: with the simulator's contact model, a
/// foot 7 mm deep sits on a tangential spring of about 14 kN/m damped at about 35 N s/m
/// (damping ratio below 0.1), which a tenth of the standing damping leaves oscillating
/// (measured: feet sliding 28 mm, realized accelerations ringing) and half of it settles.
const JOINT_DAMPING_FRACTION: f64 = 0.5;
/// Tangential contact forces cost ten times the normal ones in eq. (11)'s distribution: the
/// pure Moore-Penrose forces let HyQ's loaded feet slide 3-13 cm per stance while crawling
/// (stepping-stone trials: 25 % success at 1, 80 % at 10, no further gain at 30 or 100).
const TANGENTIAL_FORCE_WEIGHT: f64 = 10.0;
/// The friction coefficient the controller assumes: the simulator's ground has 0.8, and a
/// margin below it keeps clipped feet from sliding. Clipping at 0.6 stopped the stance feet
/// sliding off a pallet's edge while HyQ climbed it (two pallets: 19/20 -> 20/20 trials,
/// pallet appearing: 18/20 -> 20/20).
const FRICTION_COEFFICIENT: f64 = 0.6;
/// Row priorities of the redistribution inside the friction cones, base frame: the vertical
/// force and the roll and pitch moments (over a 0.3 m lever, about HyQ's half stance width)
/// ten times the horizontal forces and the yaw moment. A tilting base drags its feet off
/// their stones; a lagging CoG is caught by the virtual model. Stepping stones, 80 trials:
/// 74/80 with the forces only clipped, 76/80 redistributed with these priorities; of the
/// first 40, 37 clipped, 39 with these, 39 / 37 / 37 with roll and pitch at 30, everything
/// equal, or yaw at 10.
fn default_cone_distribution() -> DistributionSettings {
    let lever_squared = 0.3 * 0.3;
    DistributionSettings {
        wrench_priority: Vector6::new(1.0, 1.0, 10.0, 10.0 / lever_squared, 10.0 / lever_squared, 1.0 / lever_squared),
        regularization: 1e-4,
        max_iterations: 300,
        tolerance: 1e-3,
    }
}

/// Inverse kinematics: foot tolerance (m) and Newton steps per tick (warm-started).
const IK_TOLERANCE: f64 = 1e-8;
const IK_MAX_ITERATIONS: usize = 5;

/// The controller cannot be built for this robot or with these gains.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum WholeBodyError {
    #[error("whole-body controller on robot '{robot}': {problem}")]
    Structure { robot: String, problem: String },
    #[error("whole-body controller gains `{field}`: expected {expected}")]
    Gains { field: &'static str, expected: String },
}

impl From<WholeBodyError> for ControlError {
    fn from(e: WholeBodyError) -> Self {
        ControlError { controller: "whole body".into(), problem: e.to_string() }
    }
}

/// The controller's gains.
#[derive(Clone, Debug, PartialEq)]
pub struct WholeBodyGains {
    /// Virtual springs and dampers of eq. (9), diagonal, world frame: `P_x` (N/m), `D_x`
    /// (N s/m), `P_th` (N m/rad), `D_th` (N m s/rad).
    pub virtual_model: BaseGains,
    /// Swing-foot task-space PD, acceleration level, per world axis: stiffness (1/s^2) and
    /// damping (1/s).
    pub swing_foot: (Vector3<f64>, Vector3<f64>),
    /// The low-gain joint PD (indexed like `v`, base entries unused).
    pub joint: PdGains,
    /// `w_t`, the weight of the tangential contact forces against the normal ones in the
    /// distribution of eq. (11) ([`contact_forces`]; 1 = the paper's Moore-Penrose).
    pub tangential_force_weight: f64,
    /// Re-weight the tangential forces by each foot's normal force
    /// ([`friction_weighted_contact_forces`]) rather than one pass of [`contact_forces`].
    pub friction_weighting: bool,
    /// Friction coefficient the distributed forces are clipped to ([`clip_to_friction_cones`]),
    /// or `None` to leave them as eq. (11) gives them (the paper).
    pub friction_coefficient: Option<f64>,
    /// When clipping changed some force: redistribute all stance forces inside the cones
    /// by these row priorities ([`FrictionConeDistribution`]), or `None` to keep the
    /// clipped forces.
    pub cone_distribution: Option<DistributionSettings>,
}

impl WholeBodyGains {
    /// Gains derived from the robot at configuration `q_ref`, for control period
    /// `control_dt` (s):
    ///
    /// * virtual model critically damped at 3 Hz with the robot's mass and its rotational
    ///   inertia about the CoG: `P = m w^2`, `D = 2 m w` (HyQ: 30.8 kN/m, 3.27 kN s/m);
    /// * swing feet critically damped at 8 Hz (`K_p = w^2`, `K_d = 2 w`);
    /// * joint PD stiffness a tenth of [`PdGains::from_model`]'s, damping half of it (HyQ:
    ///   75 N m/rad; 15 / 15 / 13 N m s/rad).
    pub fn from_model(model: &Model, q_ref: &DVector<f64>, control_dt: f64) -> Self {
        let mut data = Data::new(model);
        centroidal_map(model, &mut data, q_ref);
        let whole = data.o_y_crb[0].to_inertia();
        let w = 2.0 * std::f64::consts::PI * VIRTUAL_MODEL_HZ;
        let inertia = whole.inertia_com.diagonal();
        let virtual_model = BaseGains {
            position: (Vector3::repeat(whole.mass * w * w), Vector3::repeat(2.0 * whole.mass * w)),
            orientation: (inertia * w * w, inertia * 2.0 * w),
        };
        let wf = 2.0 * std::f64::consts::PI * SWING_FOOT_HZ;
        let mut joint = PdGains::from_model(model, q_ref, control_dt);
        joint.kp *= JOINT_STIFFNESS_FRACTION;
        joint.kd *= JOINT_DAMPING_FRACTION;
        Self { virtual_model, swing_foot: (Vector3::repeat(wf * wf), Vector3::repeat(2.0 * wf)), joint, tangential_force_weight: TANGENTIAL_FORCE_WEIGHT, friction_weighting: true, friction_coefficient: Some(FRICTION_COEFFICIENT), cone_distribution: Some(default_cone_distribution()) }
    }

    fn check(&self, nv: usize) -> Result<(), WholeBodyError> {
        let bad = |field: &'static str, expected: String| Err(WholeBodyError::Gains { field, expected });
        let vm = &self.virtual_model;
        let vectors = [
            ("virtual_model.position", &vm.position.0, &vm.position.1),
            ("virtual_model.orientation", &vm.orientation.0, &vm.orientation.1),
            ("swing_foot", &self.swing_foot.0, &self.swing_foot.1),
        ];
        for (field, p, d) in vectors {
            if p.iter().chain(d.iter()).any(|g| !g.is_finite() || *g < 0.0) {
                return bad(field, "finite, non-negative stiffness and damping".into());
            }
        }
        if !(self.tangential_force_weight.is_finite() && self.tangential_force_weight > 0.0) {
            return bad("tangential_force_weight", format!("a finite number > 0, got {}", self.tangential_force_weight));
        }
        if let Some(mu) = self.friction_coefficient {
            if !(mu.is_finite() && mu > 0.0) {
                return bad("friction_coefficient", format!("a finite number > 0 (or none), got {mu}"));
            }
        }
        if let Some(d) = &self.cone_distribution {
            if d.wrench_priority.iter().any(|w| !(w.is_finite() && *w > 0.0)) {
                return bad("cone_distribution.wrench_priority", format!("six finite numbers > 0, got {:?}", d.wrench_priority.as_slice()));
            }
            if !(d.regularization.is_finite() && d.regularization >= 0.0) {
                return bad("cone_distribution.regularization", format!("a finite number >= 0, got {}", d.regularization));
            }
            if d.max_iterations == 0 || !(d.tolerance.is_finite() && d.tolerance > 0.0) {
                return bad("cone_distribution", format!("max_iterations > 0 and a finite tolerance > 0, got {} and {}", d.max_iterations, d.tolerance));
            }
        }
        if self.joint.kp.len() != nv || self.joint.kd.len() != nv {
            return bad("joint", format!("kp and kd of length nv = {nv}, got {} and {}", self.joint.kp.len(), self.joint.kd.len()));
        }
        if self.joint.kp.iter().chain(self.joint.kd.iter()).any(|g| !g.is_finite() || *g < 0.0) {
            return bad("joint", "finite, non-negative kp and kd".into());
        }
        Ok(())
    }
}

/// What the last tick computed (for reports, plots and tests).
#[derive(Clone, Debug, PartialEq)]
pub struct WholeBodyTick {
    /// Time of the tick (s).
    pub t: f64,
    /// `vd^ref` (`nv`): base part from eq. (10) and `bX_cog`, legs from stance constraints and
    /// swing-foot PD.
    pub reference_acceleration: DVector<f64>,
    /// `lambda` per foot (world frame, the ground on the foot; zero for swing feet).
    pub contact_forces: Vec<Vector3<f64>>,
    /// `tau^id` of eq. (11) (`nv`, base entries zero), before the PD and clipping.
    pub inverse_dynamics_torque: DVector<f64>,
    /// The joint PD's torque (`nv`, base entries zero).
    pub feedback_torque: DVector<f64>,
    /// The joint-space targets of the PD: desired base pose and leg inverse kinematics (`nq`),
    /// and their velocities (`nv`).
    pub desired_configuration: DVector<f64>,
    pub desired_velocity: DVector<f64>,
    /// Virtual force and torque of eq. (9), world frame (N, N m).
    pub virtual_force: Vector3<f64>,
    pub virtual_torque: Vector3<f64>,
    /// The reference CoG and angular accelerations of eq. (10), world frame.
    pub cog_reference_acceleration: Vector3<f64>,
    pub angular_reference_acceleration: Vector3<f64>,
    /// Measured CoG and its error `x_cog^d - x_cog` (m); orientation error
    /// `e(R^d R^T)` (rad, world).
    pub cog: Vector3<f64>,
    pub cog_error: Vector3<f64>,
    pub orientation_error: Vector3<f64>,
    /// `|b_b - J_cb^T lambda|`: zero unless the stance feet cannot produce the base wrench
    /// (measured before the friction-cone clipping).
    pub base_row_residual: f64,
    /// Stance feet whose force was clipped into its friction cone this tick.
    pub cone_clipped_feet: usize,
    /// The redistribution inside the cones after a clip (zero iterations when none ran).
    pub distribution: DistributionInfo,
    /// Largest foot error of the inverse kinematics (m): non-zero for an unreachable target.
    pub ik_residual: f64,
    /// Legs whose Jacobian was solved by damped least squares (near-singular).
    pub singular_legs: usize,
    /// Joints whose torque was clipped to the effort limit.
    pub clipped_joints: usize,
}

/// Counts over all ticks.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct WholeBodyStats {
    pub ticks: u64,
    /// Ticks in which some joint torque was clipped to its effort limit, and the number of
    /// clipped joint torques summed over ticks.
    pub clipped_ticks: u64,
    pub clipped_joint_torques: u64,
    /// Largest applied |torque| (N m).
    pub max_torque: f64,
    pub max_base_row_residual: f64,
    pub max_ik_residual: f64,
    pub singular_leg_solves: u64,
    /// Ticks whose forces were redistributed inside the friction cones, those whose
    /// redistribution hit its iteration limit, and the most iterations one took.
    pub redistributed_ticks: u64,
    pub unconverged_redistributions: u64,
    pub max_redistribution_iterations: usize,
}

/// Buffers of a tick, allocated once.
struct Workspace {
    data: Data,
    ik_data: Data,
    velocity: Vec<Motion>,
    bias: Vec<Motion>,
    feet: Vec<FootKinematics>,
    stance: Vec<bool>,
    /// Per-foot tangential weights of the friction-weighted second pass.
    tangential_weights: Vec<f64>,
    distribution: FrictionConeDistribution,
    ik_targets: Vec<Vector3<f64>>,
    /// The inverse kinematics has a previous solution to start from.
    ik_warm: bool,
}

/// Winkler 2015's execution controller; see the module documentation.
///
/// ```
/// use legwork::control::{WholeBodyController, WholeBodyReference};
/// use legwork::model::embedded;
/// let model = embedded::load("hyq").unwrap();
/// let q = model.reference_configuration("standing").unwrap().clone();
/// let hold = WholeBodyReference::holding(&model, &q);
/// let source = move |_t: f64, r: &mut WholeBodyReference| r.clone_from(&hold);
/// let mut controller = WholeBodyController::with_default_gains(&model, source, 0.001).unwrap();
/// let mut tau = nalgebra::DVector::zeros(model.nv);
/// controller.compute_torques(&model, 0.0, &q, &nalgebra::DVector::zeros(model.nv), &mut tau).unwrap();
/// // Standing still: the four feet carry the weight.
/// let fz: f64 = controller.last_tick().contact_forces.iter().map(|f| f.z).sum();
/// assert!((fz - model.total_mass() * 9.81).abs() < 1e-6);
/// ```
pub struct WholeBodyController<S> {
    source: S,
    reference: WholeBodyReference,
    legs: Vec<LegChain>,
    gains: WholeBodyGains,
    /// Effort limit per `v` entry (infinite where the model gives none).
    effort: DVector<f64>,
    nq: usize,
    nv: usize,
    ws: Workspace,
    tick: WholeBodyTick,
    stats: WholeBodyStats,
}

impl<S: MotionSource> WholeBodyController<S> {
    /// A controller for `model` (checked: free-flyer base, three-joint legs) following
    /// `source`.
    pub fn new(model: &Model, source: S, gains: WholeBodyGains) -> Result<Self, WholeBodyError> {
        let legs = leg_chains(model)?;
        gains.check(model.nv)?;
        let (nq, nv, nfeet) = (model.nq, model.nv, model.feet.len());
        let mut effort = DVector::from_element(nv, f64::INFINITY);
        for j in model.actuated_joints() {
            let e = j.limits.effort[0];
            if e.is_finite() && e > 0.0 {
                effort[j.idx_v] = e;
            }
        }
        let q0 = model.reference_configuration("standing").cloned().unwrap_or_else(|| model.neutral());
        Ok(Self {
            source,
            reference: WholeBodyReference::holding(model, &q0),
            legs,
            gains,
            effort,
            nq,
            nv,
            ws: Workspace {
                data: Data::new(model),
                ik_data: Data::new(model),
                velocity: vec![Motion::zero(); model.njoints()],
                bias: vec![Motion::zero(); model.njoints()],
                feet: vec![FootKinematics::default(); nfeet],
                stance: vec![true; nfeet],
                tangential_weights: vec![0.0; nfeet],
                distribution: FrictionConeDistribution::new(nfeet),
                ik_targets: vec![Vector3::zeros(); nfeet],
                ik_warm: false,
            },
            tick: WholeBodyTick {
                t: 0.0,
                reference_acceleration: DVector::zeros(nv),
                contact_forces: vec![Vector3::zeros(); nfeet],
                inverse_dynamics_torque: DVector::zeros(nv),
                feedback_torque: DVector::zeros(nv),
                desired_configuration: q0,
                desired_velocity: DVector::zeros(nv),
                virtual_force: Vector3::zeros(),
                virtual_torque: Vector3::zeros(),
                cog_reference_acceleration: Vector3::zeros(),
                angular_reference_acceleration: Vector3::zeros(),
                cog: Vector3::zeros(),
                cog_error: Vector3::zeros(),
                orientation_error: Vector3::zeros(),
                base_row_residual: 0.0,
                cone_clipped_feet: 0,
                distribution: DistributionInfo::default(),
                ik_residual: 0.0,
                singular_legs: 0,
                clipped_joints: 0,
            },
            stats: WholeBodyStats::default(),
        })
    }

    /// With [`WholeBodyGains::from_model`] at the model's standing configuration (its
    /// neutral one if it has none).
    pub fn with_default_gains(model: &Model, source: S, control_dt: f64) -> Result<Self, WholeBodyError> {
        let q = model.reference_configuration("standing").cloned().unwrap_or_else(|| model.neutral());
        Self::new(model, source, WholeBodyGains::from_model(model, &q, control_dt))
    }

    /// One tick at time `t`: samples the source, then [`Self::execute`]'s computation.
    pub fn compute_torques(&mut self, model: &Model, t: f64, q: &DVector<f64>, v: &DVector<f64>, tau: &mut DVector<f64>) -> Result<(), ControlError> {
        self.source.sample(t, &mut self.reference)?;
        self.tick.t = t;
        self.run(model, q, v, tau)
    }
}

impl<S> WholeBodyController<S> {
    pub fn gains(&self) -> &WholeBodyGains {
        &self.gains
    }
    pub fn legs(&self) -> &[LegChain] {
        &self.legs
    }
    pub fn source(&self) -> &S {
        &self.source
    }
    pub fn source_mut(&mut self) -> &mut S {
        &mut self.source
    }
    /// The reference of the last tick.
    pub fn reference(&self) -> &WholeBodyReference {
        &self.reference
    }
    pub fn last_tick(&self) -> &WholeBodyTick {
        &self.tick
    }
    pub fn stats(&self) -> &WholeBodyStats {
        &self.stats
    }
    /// Forget the inverse-kinematics warm start (after a jump in the state or the plan).
    pub fn reset(&mut self) {
        self.ws.ik_warm = false;
    }

    /// One tick with an explicit reference (the source is not sampled): joint torques
    /// (`nv` entries, base entries zero, clipped to the effort limits) into `tau`.
    pub fn execute(
        &mut self,
        model: &Model,
        q: &DVector<f64>,
        v: &DVector<f64>,
        reference: &WholeBodyReference,
        tau: &mut DVector<f64>,
    ) -> Result<(), ControlError> {
        self.reference.clone_from(reference);
        self.run(model, q, v, tau)
    }

    fn run(&mut self, model: &Model, q: &DVector<f64>, v: &DVector<f64>, tau: &mut DVector<f64>) -> Result<(), ControlError> {
        let err = |problem: String| ControlError { controller: "whole body".into(), problem };
        if model.nq != self.nq || model.nv != self.nv || model.feet.len() != self.legs.len() {
            return Err(err(format!("built for a robot with nq = {}, nv = {}, {} feet; called with '{}'", self.nq, self.nv, self.legs.len(), model.name)));
        }
        if q.len() != self.nq || v.len() != self.nv || tau.len() != self.nv {
            return Err(err(format!("expected q, v, tau of lengths {}, {}, {}; got {}, {}, {}", self.nq, self.nv, self.nv, q.len(), v.len(), tau.len())));
        }
        if let Some(i) = q.iter().chain(v.iter()).position(|x| !x.is_finite()) {
            return Err(err(format!("state entry {i} of (q, v) is not finite")));
        }
        self.reference.check(self.legs.len()).map_err(err)?;
        let reference = &self.reference;
        let ws = &mut self.ws;
        let tick = &mut self.tick;
        let gains = &self.gains;

        // 1. Kinematics at the measured state. `centroidal_map` runs forward kinematics,
        //    the world Jacobian and the composite inertias in one pass.
        centroidal_map(model, &mut ws.data, q);
        velocities_and_bias(model, &ws.data, v, &mut ws.velocity, &mut ws.bias);
        for leg in &self.legs {
            foot_kinematics(&ws.data, leg, &ws.velocity, &ws.bias, &mut ws.feet[leg.foot]);
            ws.stance[leg.foot] = matches!(reference.legs[leg.foot], LegMotion::Stance);
        }
        let whole = ws.data.o_y_crb[0].to_inertia();
        let inertia = CompositeInertia { mass: whole.mass, rotational: whole.inertia_com };
        // CoG velocity: the linear rows of the centroidal momentum matrix, over the mass.
        let mut momentum = Vector3::zeros();
        for (c, vc) in v.iter().enumerate() {
            momentum += ws.data.centroidal_matrix.fixed_view::<3, 1>(0, c) * *vc;
        }
        let rotation = base_orientation(q.as_slice()).to_rotation_matrix().into_inner();
        let base_linear = Vector3::new(v[0], v[1], v[2]);
        let base_angular = Vector3::new(v[3], v[4], v[5]);
        let body = BodyState { cog: whole.com, cog_velocity: momentum / whole.mass, orientation: rotation, angular_velocity: rotation * base_angular };

        // 2. Virtual model, eq. (9), and the reference acceleration, eq. (10), in the base
        //    coordinates.
        let (force, torque) = virtual_model_wrench(&gains.virtual_model, &reference.body, &body);
        let (cog_acc, ang_acc) = reference_acceleration(&reference.body, &force, &torque, &inertia);
        let base_position = Vector3::new(q[0], q[1], q[2]);
        let cog_offset = body.cog - base_position;
        let base_acc = base_acceleration(&cog_acc, &ang_acc, &cog_offset, &body, &base_linear, &base_angular);
        let acc = &mut tick.reference_acceleration;
        acc.fixed_rows_mut::<6>(0).copy_from(&base_acc);

        // 3. Joint accelerations: J_q qdd = pdd_foot - Jd v - J_b vd_b, with pdd_foot = 0 in
        //    stance and the swing-foot PD otherwise.
        let (kp_foot, kd_foot) = &gains.swing_foot;
        tick.singular_legs = 0;
        for leg in &self.legs {
            let foot = &ws.feet[leg.foot];
            let target = match reference.legs[leg.foot] {
                LegMotion::Stance => Vector3::zeros(),
                LegMotion::Swing(m) => {
                    m.acceleration + kp_foot.component_mul(&(m.position - foot.position)) + kd_foot.component_mul(&(m.velocity - foot.velocity))
                }
            };
            let rhs = target - foot.bias_acceleration - foot.base_jacobian * base_acc;
            let (qdd, singular) = solve_leg(&foot.leg_jacobian, &rhs);
            tick.singular_legs += singular as usize;
            for k in 0..3 {
                acc[leg.v_index[k]] = qdd[k];
            }
        }

        // 4. Inverse dynamics by partitioning, eq. (11).
        rnea(model, &mut ws.data, q, v, acc);
        let base_rows = ws.data.tau.fixed_rows::<6>(0).into_owned();
        tick.base_row_residual = if self.gains.friction_weighting {
            friction_weighted_contact_forces(&base_rows, &ws.feet, &ws.stance, self.gains.tangential_force_weight, &mut ws.tangential_weights, &mut tick.contact_forces)
        } else {
            contact_forces(&base_rows, &ws.feet, &ws.stance, self.gains.tangential_force_weight, &mut tick.contact_forces)
        };
        if let Some(mu) = self.gains.friction_coefficient {
            tick.cone_clipped_feet = clip_to_friction_cones(&mut tick.contact_forces, &ws.stance, mu);
            tick.distribution = match (&self.gains.cone_distribution, tick.cone_clipped_feet) {
                (Some(settings), clipped) if clipped > 0 => {
                    let problem = DistributionProblem { base_rows: &base_rows, feet: &ws.feet, stance: &ws.stance, mu, tangential_weight: self.gains.tangential_force_weight };
                    ws.distribution.solve(settings, &problem, &mut tick.contact_forces)
                }
                _ => DistributionInfo::default(),
            };
        }
        joint_torques(&ws.data.tau, &self.legs, &ws.feet, &tick.contact_forces, &mut tick.inverse_dynamics_torque);

        // 5. Joint-space targets: the base at its desired pose, the legs by inverse
        //    kinematics (stance feet where they are, swing feet on their trajectories).
        let (base_desired, base_velocity_desired) = desired_base(&reference.body, &(rotation.transpose() * cog_offset));
        let qd = &mut tick.desired_configuration;
        if !ws.ik_warm {
            qd.copy_from(q);
        }
        qd.fixed_rows_mut::<3>(0).copy_from(&base_desired);
        let o = reference.body.orientation.quaternion();
        qd.fixed_rows_mut::<4>(3).copy_from(&nalgebra::Vector4::new(o.i, o.j, o.k, o.w));
        for leg in &self.legs {
            ws.ik_targets[leg.foot] = match reference.legs[leg.foot] {
                LegMotion::Stance => ws.feet[leg.foot].position,
                LegMotion::Swing(m) => m.position,
            };
        }
        tick.ik_residual = legs_inverse_kinematics(model, &mut ws.ik_data, &self.legs, &ws.ik_targets, qd, IK_TOLERANCE, IK_MAX_ITERATIONS);
        ws.ik_warm = true;
        let r_desired = reference.body.orientation.to_rotation_matrix();
        let vb_lin = r_desired.inverse() * base_velocity_desired;
        let vb_ang = r_desired.inverse() * reference.body.angular_velocity;
        let vb = Vector6::new(vb_lin.x, vb_lin.y, vb_lin.z, vb_ang.x, vb_ang.y, vb_ang.z);
        let vd = &mut tick.desired_velocity;
        vd.fixed_rows_mut::<6>(0).copy_from(&vb);
        for leg in &self.legs {
            let p = foot_position(&ws.ik_data, leg);
            let foot_velocity = match reference.legs[leg.foot] {
                LegMotion::Stance => Vector3::zeros(),
                LegMotion::Swing(m) => m.velocity,
            };
            let (qdot, _) = solve_leg(&leg_jacobian(&ws.ik_data, leg, &p), &(foot_velocity - base_jacobian(&ws.ik_data, &p) * vb));
            for k in 0..3 {
                vd[leg.v_index[k]] = qdot[k];
            }
        }

        // 6. tau = tau^id + low-gain joint PD, clipped to the effort limits.
        let (kp, kd) = (&gains.joint.kp, &gains.joint.kd);
        tau.fill(0.0);
        tick.feedback_torque.fill(0.0);
        tick.clipped_joints = 0;
        for j in model.actuated_joints() {
            let (iq, iv) = (j.idx_q, j.idx_v);
            let pd = kp[iv] * (qd[iq] - q[iq]) + kd[iv] * (vd[iv] - v[iv]);
            tick.feedback_torque[iv] = pd;
            let raw = tick.inverse_dynamics_torque[iv] + pd;
            let limit = self.effort[iv];
            tau[iv] = raw.clamp(-limit, limit);
            if tau[iv] != raw {
                tick.clipped_joints += 1;
            }
            self.stats.max_torque = self.stats.max_torque.max(tau[iv].abs());
        }
        if let Some(i) = tau.iter().position(|x| !x.is_finite()) {
            return Err(err(format!("torque of v entry {i} is not finite")));
        }

        tick.virtual_force = force;
        tick.virtual_torque = torque;
        tick.cog_reference_acceleration = cog_acc;
        tick.angular_reference_acceleration = ang_acc;
        tick.cog = body.cog;
        tick.cog_error = reference.body.cog_position - body.cog;
        tick.orientation_error = log3(&(reference.body.orientation.to_rotation_matrix().into_inner() * rotation.transpose()));
        let stats = &mut self.stats;
        stats.ticks += 1;
        stats.clipped_ticks += (tick.clipped_joints > 0) as u64;
        stats.clipped_joint_torques += tick.clipped_joints as u64;
        stats.max_base_row_residual = stats.max_base_row_residual.max(tick.base_row_residual);
        stats.max_ik_residual = stats.max_ik_residual.max(tick.ik_residual);
        stats.singular_leg_solves += tick.singular_legs as u64;
        if tick.distribution.iterations > 0 {
            stats.redistributed_ticks += 1;
            stats.unconverged_redistributions += !tick.distribution.converged as u64;
            stats.max_redistribution_iterations = stats.max_redistribution_iterations.max(tick.distribution.iterations);
        }
        Ok(())
    }
}

impl<S: MotionSource> Controller for WholeBodyController<S> {
    fn name(&self) -> &str {
        "whole_body"
    }
    fn compute(&mut self, model: &Model, state: &SimState, tau: &mut DVector<f64>) -> Result<(), ControlError> {
        self.compute_torques(model, state.t, &state.q, &state.v, tau)
    }
}
