//! The jump and landing controllers as one [`Controller`] (Nguyen 2022, sec. III):
//!
//! * before the switch ([`LandingSwitch`]): eq. (5) on every leg, tracking the reference;
//!   from `T_posing` on, with the pre-landing configuration extended along the impact
//!   velocity (Remark 3, [`LegExtension`]);
//! * after it: the landing QP ([`LandingQp`]) on the feet in contact, `tau = -J^T f + joint
//!   PD` (the leg pushes the ground with `-f`), and eq. (5) towards the pre-landing
//!   configuration, with no feed-forward, on the legs still in the air (Remark 2).
//!
//! The contact sensors are read from the simulator with [`JumpController::sense`] before
//! each physics step. Nothing allocates in a tick.

use super::landing_qp::{LandingQp, LandingQpSettings, QpFoot, SrbState, SrbTarget};
use super::reference::{JumpReference, ReferenceSample};
use super::switch::LandingSwitch;
use super::tracking::{JumpGains, JumpTracking};
use super::JumpControlError;
use crate::control::whole_body::{foot_position, leg_chains, leg_jacobian, legs_inverse_kinematics, LegChain};
use crate::dynamics::{base_orientation, compute_joint_jacobians, Data};
use crate::model::Model;
use crate::sim::{ControlError, Controller, FootState, SimState};
use crate::srb::SrbParams;
use nalgebra::{DVector, Matrix3, Vector3};

/// The landing controller's settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LandingSettings {
    /// `delta`, the foot force that counts as an impact (N). Default 20 N: well above what
    /// the smooth contact model gives a foot skimming the ground (a few N), well below an
    /// A1 foot's standing load (34 N).
    pub contact_threshold: f64,
    pub qp: LandingQpSettings,
    /// Eq. (5)'s gains on the legs in the air after the switch. Default [`JumpGains::default`].
    pub swing: JumpGains,
    /// Joint PD of a stance leg towards the pre-landing configuration (N m/rad, N m s/rad).
    /// Defaults 5 and 1: the QP carries the body, the PD only keeps the knee from folding
    /// where the QP's single rigid body does not see the leg.
    pub stance_joint_kp: f64,
    pub stance_joint_kd: f64,
}

impl Default for LandingSettings {
    fn default() -> Self {
        Self { contact_threshold: 20.0, qp: LandingQpSettings::default(), swing: JumpGains::default(), stance_joint_kp: 5.0, stance_joint_kd: 1.0 }
    }
}

/// Remark 3: the pre-landing feet moved along the reference's horizontal base velocity at
/// impact by `time` times that velocity (at most `max_offset`), so that the ground's
/// braking force at the feet, which are then ahead of the CoM, points closer to it. The
/// paper applies it to its fast jumps; the offset vanishes with the horizontal velocity, so
/// it is on for every jump here (`time = 0` turns it off).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LegExtension {
    /// (s). Default 0.05 s (measured: see `docs/experiments/jump-control.md`).
    pub time: f64,
    /// (m). Default 0.08 m, what the A1's legs reach from its standing pose.
    pub max_offset: f64,
}

impl Default for LegExtension {
    fn default() -> Self {
        Self { time: 0.05, max_offset: 0.08 }
    }
}

/// What the controller did over a run.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct JumpControllerStats {
    pub qp_solves: u64,
    /// Solves clarabel did not finish; the previous forces were held.
    pub qp_failures: u64,
    pub max_qp_iterations: u32,
    /// Largest `|A f - b|` (N, N m): the wrench the feet could not give.
    pub max_wrench_residual: f64,
}

/// See the module documentation.
pub struct JumpController {
    reference: JumpReference,
    jump_gains: JumpGains,
    landing: LandingSettings,
    srb: SrbParams,
    sample: ReferenceSample,
    /// The pre-landing configuration (extended by Remark 3 when it applies) as a reference
    /// sample with zero velocity and no feed-forward.
    landing_pose: ReferenceSample,
    extended: bool,
    tracking: JumpTracking,
    switch: LandingSwitch,
    qp: LandingQp,
    target: SrbTarget,
    legs: Vec<LegChain>,
    /// Per leg (order of `legs`): the motors' effort limits (N m).
    torque_limits: Vec<Vector3<f64>>,
    data: Data,
    sensed_force: Vec<f64>,
    sensed_normal: Vec<Vector3<f64>>,
    qp_feet: Vec<QpFoot>,
    forces: Vec<Vector3<f64>>,
    all_legs: Vec<bool>,
    swing_legs: Vec<bool>,
    stats: JumpControllerStats,
}

impl JumpController {
    /// The controller of `reference` on `model` (the controller's nominal robot; its single
    /// rigid body from [`SrbParams::from_model`] in the pose `standing`).
    pub fn new(model: &Model, reference: JumpReference, jump_gains: JumpGains, landing: LandingSettings, extension: LegExtension) -> Result<Self, JumpControlError> {
        jump_gains.validate("jump_gains")?;
        landing.swing.validate("landing.swing")?;
        let gain_ok = |x: f64| x.is_finite() && x >= 0.0;
        if !(gain_ok(landing.stance_joint_kp) && gain_ok(landing.stance_joint_kd)) {
            return Err(JumpControlError::Setting { field: "landing.stance_joint_kp/kd", expected: "finite, non-negative gains".into() });
        }
        if !(landing.contact_threshold.is_finite() && landing.contact_threshold > 0.0) {
            return Err(JumpControlError::Setting { field: "landing.contact_threshold", expected: "a positive force (N)".into() });
        }
        if !(gain_ok(extension.time) && gain_ok(extension.max_offset)) {
            return Err(JumpControlError::Setting { field: "extension", expected: "a finite, non-negative time and offset".into() });
        }
        let srb = SrbParams::from_model(model, "standing").map_err(|e| JumpControlError::Robot(e.to_string()))?;
        let legs = leg_chains(model).map_err(|e| JumpControlError::Robot(e.to_string()))?;
        let gravity = model.gravity.v;
        let qp = LandingQp::new(landing.qp, srb.mass, srb.inertia, gravity, model.feet.len())?;
        let (landing_pose, extended) = landing_pose(model, &reference, &legs, &extension)?;
        let last = reference.pre_landing();
        let rotation = base_orientation(last.as_slice()).to_rotation_matrix().into_inner();
        let target = SrbTarget { com: Vector3::new(last[0], last[1], last[2]) + rotation * srb.com_in_base, rotation };
        let feet = model.feet.len();
        let effort = |iv: usize| model.joints[model.joint_of_dof[iv]].limits.effort[0];
        let torque_limits: Vec<Vector3<f64>> = legs.iter().map(|leg| Vector3::new(effort(leg.v_index[0]), effort(leg.v_index[1]), effort(leg.v_index[2]))).collect();
        if torque_limits.iter().any(|t| t.iter().any(|x| !(*x > 0.0))) {
            return Err(JumpControlError::Robot(format!("robot '{}': every leg joint needs a positive effort limit for the landing QP", model.name)));
        }
        Ok(Self {
            switch: LandingSwitch::new(landing.contact_threshold, reference.t_posing(), feet),
            sample: ReferenceSample::new(model),
            tracking: JumpTracking::new(model)?,
            reference,
            jump_gains,
            landing,
            srb,
            landing_pose,
            extended,
            qp,
            target,
            legs,
            data: Data::new(model),
            sensed_force: vec![0.0; feet],
            sensed_normal: vec![Vector3::z(); feet],
            qp_feet: vec![QpFoot { position: Vector3::zeros(), normal: Vector3::z(), in_contact: false, leg_jacobian: Matrix3::zeros(), torque_limit: Vector3::zeros() }; feet],
            torque_limits,
            forces: vec![Vector3::zeros(); feet],
            all_legs: vec![true; feet],
            swing_legs: vec![true; feet],
            stats: JumpControllerStats::default(),
        })
    }

    /// Reads the contact sensors: each foot's normal force and surface normal.
    pub fn sense(&mut self, feet: &[FootState]) {
        for ((force, normal), foot) in self.sensed_force.iter_mut().zip(self.sensed_normal.iter_mut()).zip(feet) {
            *force = foot.contact.normal_force;
            *normal = foot.normal;
        }
    }

    pub fn switch(&self) -> &LandingSwitch {
        &self.switch
    }

    pub fn stats(&self) -> &JumpControllerStats {
        &self.stats
    }

    pub fn reference(&self) -> &JumpReference {
        &self.reference
    }

    /// Whether Remark 3's extension changed the pre-landing configuration.
    pub fn legs_extended(&self) -> bool {
        self.extended
    }

    /// The ground reaction forces the landing QP commanded last (world, N).
    pub fn commanded_forces(&self) -> &[Vector3<f64>] {
        &self.forces
    }

    /// The single rigid body at the measured state (CoM of the legs-locked body).
    fn srb_state(&self, q: &DVector<f64>, v: &DVector<f64>) -> SrbState {
        let rotation = base_orientation(q.as_slice()).to_rotation_matrix().into_inner();
        let w_body = Vector3::new(v[3], v[4], v[5]);
        let v_body = Vector3::new(v[0], v[1], v[2]);
        SrbState {
            com: Vector3::new(q[0], q[1], q[2]) + rotation * self.srb.com_in_base,
            rotation,
            com_velocity: rotation * (v_body + w_body.cross(&self.srb.com_in_base)),
            angular_velocity: rotation * w_body,
        }
    }

    fn land(&mut self, model: &Model, q: &DVector<f64>, v: &DVector<f64>, tau: &mut DVector<f64>) {
        for (swing, &contact) in self.swing_legs.iter_mut().zip(self.switch.in_contact()) {
            *swing = !contact;
        }
        // Remark 2: the legs in the air hold the pre-landing configuration.
        self.tracking.compute(model, q, v, &self.landing_pose, &self.landing.swing, &self.swing_legs, tau);
        if self.swing_legs.iter().all(|&s| s) {
            return;
        }
        compute_joint_jacobians(model, &mut self.data, q);
        for (leg, limit) in self.legs.iter().zip(&self.torque_limits) {
            let p = foot_position(&self.data, leg);
            self.qp_feet[leg.foot] =
                QpFoot { position: p, normal: self.sensed_normal[leg.foot], in_contact: !self.swing_legs[leg.foot], leg_jacobian: leg_jacobian(&self.data, leg, &p), torque_limit: *limit };
        }
        let state = self.srb_state(q, v);
        self.stats.qp_solves += 1;
        match self.qp.solve(&state, &self.target, &self.qp_feet) {
            Ok((forces, info)) => {
                self.forces.copy_from_slice(forces);
                self.stats.max_qp_iterations = self.stats.max_qp_iterations.max(info.iterations);
                self.stats.max_wrench_residual = self.stats.max_wrench_residual.max(info.wrench_residual);
            }
            Err(_) => self.stats.qp_failures += 1,
        }
        let pose = &self.landing_pose;
        for leg in &self.legs {
            if self.swing_legs[leg.foot] {
                continue;
            }
            let p = foot_position(&self.data, leg);
            let push = -(leg_jacobian(&self.data, leg, &p).transpose() * self.forces[leg.foot]);
            for k in 0..3 {
                let (iq, iv) = (leg.q_index[k], leg.v_index[k]);
                tau[iv] = push[k] + self.landing.stance_joint_kp * (pose.q[iq] - q[iq]) - self.landing.stance_joint_kd * v[iv];
            }
        }
    }
}

impl Controller for JumpController {
    fn name(&self) -> &str {
        "jump"
    }

    fn compute(&mut self, model: &Model, state: &SimState, tau: &mut DVector<f64>) -> Result<(), ControlError> {
        tau.fill(0.0);
        let (q, v) = (&state.q, &state.v);
        if self.switch.update(state.t, &self.sensed_force) {
            self.land(model, q, v, tau);
            return Ok(());
        }
        self.reference.sample(model, state.t, &mut self.sample);
        if self.extended && state.t >= self.reference.t_posing() {
            // Remark 3: the extended pre-landing configuration, the reference's feed-forward.
            for leg in &self.legs {
                for k in 0..3 {
                    self.sample.q[leg.q_index[k]] = self.landing_pose.q[leg.q_index[k]];
                    self.sample.v[leg.v_index[k]] = 0.0;
                }
                self.sample.foot_position[leg.foot] = self.landing_pose.foot_position[leg.foot];
                self.sample.foot_velocity[leg.foot] = Vector3::zeros();
            }
        }
        self.tracking.compute(model, q, v, &self.sample, &self.jump_gains, &self.all_legs, tau);
        Ok(())
    }
}

/// The pre-landing configuration as a reference sample (zero velocity, no feed-forward),
/// its feet moved along the horizontal impact velocity by Remark 3; and whether they were.
fn landing_pose(model: &Model, reference: &JumpReference, legs: &[LegChain], extension: &LegExtension) -> Result<(ReferenceSample, bool), JumpControlError> {
    let mut pose = ReferenceSample::new(model);
    let mut q = reference.pre_landing().clone();
    q.rows_mut(0, 7).copy_from_slice(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]);
    let mut data = Data::new(model);
    compute_joint_jacobians(model, &mut data, &q);
    let mut feet: Vec<Vector3<f64>> = vec![Vector3::zeros(); model.feet.len()];
    for leg in legs {
        feet[leg.foot] = foot_position(&data, leg);
    }
    let (velocity, _) = reference.impact_velocity();
    let horizontal = Vector3::new(velocity.x, velocity.y, 0.0) * extension.time;
    let extended = horizontal.norm() > 1e-4 && extension.max_offset > 0.0;
    if extended {
        let rotation = base_orientation(reference.pre_landing().as_slice());
        let offset = rotation.inverse() * horizontal.cap_magnitude(extension.max_offset);
        for p in feet.iter_mut() {
            *p += offset;
        }
        let residual = legs_inverse_kinematics(model, &mut data, legs, &feet, &mut q, 1e-6, 50);
        if residual > 1e-3 {
            return Err(JumpControlError::Setting { field: "extension", expected: format!("feet the legs can reach: the extended pre-landing feet are {residual:.3} m out of reach") });
        }
        for leg in legs {
            feet[leg.foot] = foot_position(&data, leg);
        }
    }
    pose.q.copy_from(reference.pre_landing());
    for leg in legs {
        for k in 0..3 {
            pose.q[leg.q_index[k]] = q[leg.q_index[k]];
        }
    }
    pose.foot_position.copy_from_slice(&feet);
    Ok((pose, extended))
}
