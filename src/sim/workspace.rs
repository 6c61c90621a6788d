//! The discrete dynamics through contact, allocation-free: contact forces at the feet,
//! the joint stops' generalized force, ABA with external forces, one integration step.
//! One workspace per thread.

use super::joint_limits::{JointLimitParams, JointStops};
use crate::contact::{contact_force, update_anchor, ContactForce, ContactParams, Surface};
use crate::dynamics::{aba_with_external_forces, aba_with_external_forces_after_kinematics, forward_kinematics_velocity, integrate, Data};
use crate::model::Model;
use crate::spatial::Force;
use crate::terrain::Terrain;
use nalgebra::{DVector, Vector3};

/// One foot at the last contact evaluation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FootState {
    /// Centre of the foot sphere, world frame.
    pub position: Vector3<f64>,
    /// Its velocity, world frame.
    pub velocity: Vector3<f64>,
    /// Surface normal under the foot.
    pub normal: Vector3<f64>,
    pub contact: ContactForce,
}

/// Everything one physics step needs, allocated once: a dynamics [`Data`], the external
/// forces per body, the feet, the joint stops, and integrator scratch.
pub struct ContactModelWorkspace<'a> {
    pub(super) model: &'a Model,
    pub(super) terrain: &'a dyn Terrain,
    pub(super) params: ContactParams,
    pub(super) data: Data,
    /// The configuration of the last [`Self::evaluate_contacts`], whose joint placements
    /// are in `data` (ABA reuses them at the same `q`).
    kinematics_q: DVector<f64>,
    pub(super) f_ext: Vec<Force>,
    pub(super) feet: Vec<FootState>,
    feet_at_start: Vec<FootState>,
    pub(super) stops: JointStops,
    /// The torques plus the stops' generalized force, ABA's input.
    tau_total: DVector<f64>,
    // RK4 scratch.
    q_stage: DVector<f64>,
    v_stage: DVector<f64>,
    pub(super) dv: [DVector<f64>; 4],
    vs: [DVector<f64>; 4],
    pub(super) step_v: DVector<f64>,
    q_next: DVector<f64>,
}

impl<'a> ContactModelWorkspace<'a> {
    /// A workspace in the robot's contact model ([`Model::contact`]: the simulator and the
    /// optimizer share it), without joint stops (as [`super::SimConfig`]'s default);
    /// [`Self::with_joint_limits`] adds them.
    pub fn new(model: &'a Model, terrain: &'a dyn Terrain) -> Self {
        let params = model.contact;
        let nv = model.nv;
        let z = || DVector::zeros(nv);
        let no_contact = FootState {
            position: Vector3::zeros(),
            velocity: Vector3::zeros(),
            normal: Vector3::z(),
            contact: ContactForce::none(Vector3::zeros(), f64::NEG_INFINITY),
        };
        Self {
            model,
            terrain,
            params,
            data: Data::new(model),
            kinematics_q: DVector::from_element(model.nq, f64::NAN),
            f_ext: vec![Force::zero(); model.njoints()],
            feet: vec![no_contact; model.feet.len()],
            feet_at_start: vec![no_contact; model.feet.len()],
            stops: JointStops::new(model, None),
            tau_total: z(),
            q_stage: DVector::zeros(model.nq),
            v_stage: z(),
            dv: [z(), z(), z(), z()],
            vs: [z(), z(), z(), z()],
            step_v: z(),
            q_next: DVector::zeros(model.nq),
        }
    }

    /// The same workspace with the joint stops `joint_limits` (`None`: no stops).
    pub fn with_joint_limits(mut self, joint_limits: Option<JointLimitParams>) -> Self {
        self.stops = JointStops::new(self.model, joint_limits);
        self
    }

    /// The joint stops acting in [`Self::step`].
    pub fn joint_stops(&self) -> &JointStops {
        &self.stops
    }

    pub fn terrain(&self) -> &'a dyn Terrain {
        self.terrain
    }

    pub fn params(&self) -> &ContactParams {
        &self.params
    }

    /// The feet at the last [`Self::evaluate_contacts`].
    pub fn feet(&self) -> &[FootState] {
        &self.feet
    }

    /// Foot positions and velocities by forward kinematics, contact forces (Neunert 2017,
    /// eq. 9-11), and their spatial forces on the feet's bodies, in each body's joint frame,
    /// applied at the foot sphere's centre (the point foot whose velocity the model uses).
    pub fn evaluate_contacts(&mut self, q: &DVector<f64>, v: &DVector<f64>, anchors: &[Option<Vector3<f64>>]) {
        let model = self.model;
        forward_kinematics_velocity(model, &mut self.data, q, v);
        self.kinematics_q.copy_from(q);
        for f in self.f_ext.iter_mut() {
            *f = Force::zero();
        }
        for (k, foot) in model.feet.iter().enumerate() {
            let frame = &model.frames[foot.frame];
            let j = frame.parent_joint;
            let o_m_j = &self.data.o_m_i[j];
            let local = frame.placement.translation;
            let position = o_m_j.act_point(&local);
            // Point velocity in the joint frame, v + w x r, rotated to the world.
            let vj = &self.data.v[j];
            let velocity = o_m_j.rotation * (vj.v + vj.w.cross(&local));
            let (h, normal) = self.terrain.surface(position.x, position.y);
            let mut surface = Surface { point: Vector3::new(position.x, position.y, h), normal };
            // Above everything the foot could touch: no contact, even where the tangent plane
            // under the foot (a cliff's edge) passes within a radius of it.
            let highest = self.terrain.highest_near(position.x, position.y, foot.radius);
            if position.z - foot.radius > highest {
                surface = Surface { point: Vector3::new(position.x, position.y, highest), normal: Vector3::z() };
            }
            let contact = contact_force(&self.params, foot.radius, &position, &velocity, &surface, anchors[k].as_ref());
            if contact.normal_force > 0.0 {
                // f in the joint frame: R^T F at the point r: moment r x R^T F.
                let f_local = o_m_j.rotation.tr_mul(&contact.force);
                self.f_ext[j].f += f_local;
                self.f_ext[j].n += local.cross(&f_local);
            }
            self.feet[k] = FootState { position, velocity, normal, contact };
        }
    }

    /// Adds a world-frame force at the base origin to the external forces.
    fn add_base_push(&mut self, q: &DVector<f64>, push: &Vector3<f64>) {
        if push.iter().any(|x| *x != 0.0) {
            let b = 1; // the free-flyer joint
            let iq = self.model.joints[b].idx_q;
            let quat = crate::dynamics::base_orientation(&q.as_slice()[iq..]);
            self.f_ext[b].f += quat.inverse_transform_vector(push);
        }
    }

    /// `qdd = ABA(q, v, tau + tau_l(q, v), f_ext)` with the joint stops' generalized force
    /// `tau_l` ([`super::JointLimitParams`]), the contact forces of the last evaluation plus the
    /// push; into `out`.
    pub(super) fn acceleration(&mut self, q: &DVector<f64>, v: &DVector<f64>, tau: &DVector<f64>, push: &Vector3<f64>, out_index: usize) {
        self.add_base_push(q, push);
        self.tau_total.copy_from(tau);
        self.stops.add_torques(q, v, &mut self.tau_total);
        // The contacts' kinematics at this q left its placements in `data`: ABA reuses them.
        let ddq = if *q == self.kinematics_q {
            aba_with_external_forces_after_kinematics(self.model, &mut self.data, q, v, &self.tau_total, &self.f_ext)
        } else {
            aba_with_external_forces(self.model, &mut self.data, q, v, &self.tau_total, &self.f_ext)
        };
        self.dv[out_index].copy_from(ddq);
    }

    /// Semi-implicit Euler, after [`Self::evaluate_contacts`] at `(q, v, anchors)`:
    /// `v' = v + dt qdd`, `q' = q (+) dt v'`; then the anchors are updated.
    pub fn integrate_semi_implicit(
        &mut self,
        q: &mut DVector<f64>,
        v: &mut DVector<f64>,
        anchors: &mut [Option<Vector3<f64>>],
        tau: &DVector<f64>,
        push: &Vector3<f64>,
        dt: f64,
    ) {
        self.acceleration(q, v, tau, push, 0);
        self.advance_semi_implicit(q, v, anchors, dt);
    }

    /// The update of semi-implicit Euler from the acceleration in `dv[0]`: `v' = v + dt qdd`,
    /// `q' = q (+) dt v'` (`dt v'` is left in `step_v`), then the anchors. Shared by the
    /// simulator and the step's linearization ([`super::StepDerivatives`]).
    pub(super) fn advance_semi_implicit(&mut self, q: &mut DVector<f64>, v: &mut DVector<f64>, anchors: &mut [Option<Vector3<f64>>], dt: f64) {
        v.axpy(dt, &self.dv[0], 1.0);
        self.step_v.copy_from(v);
        self.step_v *= dt;
        integrate(self.model, q, &self.step_v, &mut self.q_next);
        q.copy_from(&self.q_next);
        self.update_anchors(anchors);
    }

    /// Runge-Kutta 4 in the tangent space at the step's start, after
    /// [`Self::evaluate_contacts`] at `(q, v, anchors)`; anchors held over the step, then
    /// updated from the contacts at the step's start.
    ///
    /// ```text
    /// k_i = (v_i, a_i),  a_i = qdd(q (+) c_i dt v_{i-1}, v + c_i dt a_{i-1}),  c = (0, 1/2, 1/2, 1)
    /// q' = q (+) dt/6 (v_1 + 2 v_2 + 2 v_3 + v_4),  v' = v + dt/6 (a_1 + 2 a_2 + 2 a_3 + a_4)
    /// ```
    pub fn integrate_rk4(
        &mut self,
        q: &mut DVector<f64>,
        v: &mut DVector<f64>,
        anchors: &mut [Option<Vector3<f64>>],
        tau: &DVector<f64>,
        push: &Vector3<f64>,
        dt: f64,
    ) {
        self.feet_at_start.copy_from_slice(&self.feet);
        self.vs[0].copy_from(v);
        self.acceleration(q, v, tau, push, 0);
        for (stage, c) in [(1usize, 0.5), (2, 0.5), (3, 1.0)] {
            // v_stage = v + c dt a_{stage-1};  q_stage = q (+) c dt v_{stage-1}
            self.step_v.copy_from(&self.vs[stage - 1]);
            self.step_v *= c * dt;
            integrate(self.model, q, &self.step_v, &mut self.q_stage);
            self.v_stage.copy_from(v);
            self.v_stage.axpy(c * dt, &self.dv[stage - 1], 1.0);
            self.vs[stage].copy_from(&self.v_stage);
            let (qs, vs) = (std::mem::take(&mut self.q_stage), std::mem::take(&mut self.v_stage));
            self.evaluate_contacts(&qs, &vs, anchors);
            self.acceleration(&qs, &vs, tau, push, stage);
            self.q_stage = qs;
            self.v_stage = vs;
        }
        // Weighted sums (1, 2, 2, 1) / 6.
        self.step_v.fill(0.0);
        for (i, w) in [1.0, 2.0, 2.0, 1.0].iter().enumerate() {
            self.step_v.axpy(w * dt / 6.0, &self.vs[i], 1.0);
            v.axpy(w * dt / 6.0, &self.dv[i], 1.0);
        }
        integrate(self.model, q, &self.step_v, &mut self.q_next);
        q.copy_from(&self.q_next);
        self.feet.copy_from_slice(&self.feet_at_start);
        self.update_anchors(anchors);
    }

    /// Moves each foot's anchor as its contact of the last [`Self::evaluate_contacts`]
    /// says ([`update_anchor`]): set at touch-down, dragged along while slipping, dropped
    /// at lift-off.
    pub fn update_anchors(&self, anchors: &mut [Option<Vector3<f64>>]) {
        for (foot, anchor) in self.feet.iter().zip(anchors.iter_mut()) {
            update_anchor(&self.params, &foot.contact, anchor);
        }
    }

    /// Evaluate contacts and advance one semi-implicit Euler step: the discrete dynamics
    /// `x_{k+1} = f(x_k, u_k)` shared by the simulator and the optimizer.
    pub fn step(
        &mut self,
        q: &mut DVector<f64>,
        v: &mut DVector<f64>,
        anchors: &mut [Option<Vector3<f64>>],
        tau: &DVector<f64>,
        dt: f64,
    ) {
        self.evaluate_contacts(q, v, anchors);
        self.integrate_semi_implicit(q, v, anchors, tau, &Vector3::zeros(), dt);
    }
}
