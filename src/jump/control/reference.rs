//! The jump reference of the full-body optimization (Nguyen 2022, sec. III): joint angles
//! and velocities, feed-forward torques, and the feet's positions and velocities relative
//! to the base, per 10 ms knot, linearly interpolated to the 1 kHz control rate.
//!
//! The feet are taken relative to the base, in base axes, from the joint angles alone (the
//! paper's "w.r.t. their hips": a hip is fixed in the base frame, so the offset cancels in
//! `p_f,d - p_f` and the Jacobian is the same). They are computed once per knot here and
//! interpolated like the other profiles, as the paper does.

use super::feet::BaseFrameFeet;
use super::JumpControlError;
use crate::control::{interpolate_state, knot_bracket, KnotBracket};
use crate::dynamics::base_orientation;
use crate::io::Trajectory;
use crate::model::Model;
use nalgebra::{DVector, Vector3};

/// How close to the final knot's joint state a knot must be to count as the pre-landing
/// configuration (Nguyen 2022 sec. II-C: `q_j = q_N^d`, `qd_j = 0` over the last `a` knots).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PosingTolerance {
    /// Largest joint angle difference to the final knot (rad). Default 1e-3.
    pub angle: f64,
    /// Largest joint speed (rad/s). Default 1e-2.
    pub speed: f64,
}

impl Default for PosingTolerance {
    fn default() -> Self {
        Self { angle: 1e-3, speed: 1e-2 }
    }
}

/// The reference sampled at one instant (preallocated, overwritten by [`JumpReference::sample`]).
#[derive(Clone, Debug)]
pub struct ReferenceSample {
    /// Configuration (`nq`) and velocity (`nv`).
    pub q: DVector<f64>,
    pub v: DVector<f64>,
    /// Feed-forward torques (`nv`, base entries zero).
    pub tau: DVector<f64>,
    /// Per foot (model order): position and velocity relative to the base, base axes.
    pub foot_position: Vec<Vector3<f64>>,
    pub foot_velocity: Vec<Vector3<f64>>,
    dq: DVector<f64>,
}

impl ReferenceSample {
    pub fn new(model: &Model) -> Self {
        let feet = model.feet.len();
        Self {
            q: DVector::zeros(model.nq),
            v: DVector::zeros(model.nv),
            tau: DVector::zeros(model.nv),
            foot_position: vec![Vector3::zeros(); feet],
            foot_velocity: vec![Vector3::zeros(); feet],
            dq: DVector::zeros(model.nv),
        }
    }
}

/// Where the jump should end: the base position and yaw of the reference's last knot.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JumpTarget {
    /// Base position, world frame (m).
    pub position: Vector3<f64>,
    /// Base yaw (rad).
    pub yaw: f64,
}

/// A jump reference converted once from its trajectory file.
#[derive(Clone, Debug)]
pub struct JumpReference {
    t: Vec<f64>,
    q: Vec<DVector<f64>>,
    v: Vec<DVector<f64>>,
    tau: Vec<DVector<f64>>,
    foot_position: Vec<Vec<Vector3<f64>>>,
    foot_velocity: Vec<Vec<Vector3<f64>>>,
    /// Per knot and foot: whether the plan has the foot in contact there.
    in_contact: Vec<Vec<bool>>,
    /// Per foot (model order): the leg's actuated velocity indices.
    leg_dofs: Vec<[usize; 3]>,
    /// Per knot `k` and foot: the plan's normal force over `[t_k, t_k+1)` (N; 0 where the
    /// trajectory carries no forces).
    normal_force: Vec<Vec<f64>>,
    /// Per knot `k` and foot: how early a foot lifting off at knot `k + 1` ends its push
    /// (s; [`JumpReference::with_lift_off_lead`], [`JumpReference::with_lift_off_release`]);
    /// 0 by default.
    lift_off_lead: Vec<Vec<f64>>,
    /// `T_posing`: start of the pre-landing configuration (s).
    t_posing: f64,
    /// The pre-landing configuration: the last knot (`nq`).
    pre_landing: DVector<f64>,
    target: JumpTarget,
    /// The reference's base velocity at its last knot (touch-down), world frame: linear
    /// and angular (Remark 3's "body velocity reference at the impact").
    impact_velocity: (Vector3<f64>, Vector3<f64>),
}

impl JumpReference {
    /// Converts `trajectory` (checked against `model`: joint names, sizes, finite values)
    /// and finds `T_posing`: the earliest knot from which every knot holds the last knot's
    /// joint angles with zero joint speed, within `tolerance`.
    pub fn new(model: &Model, trajectory: &Trajectory, tolerance: PosingTolerance) -> Result<Self, JumpControlError> {
        let invalid = |e: crate::io::TrajectoryError| JumpControlError::Reference(e.to_string());
        trajectory.check_against(model, "jump reference").map_err(invalid)?;
        trajectory.validate("jump reference").map_err(invalid)?;
        if trajectory.knots.len() < 2 {
            return Err(JumpControlError::Reference(format!("expected at least 2 knots, got {}", trajectory.knots.len())));
        }
        if !(tolerance.angle >= 0.0 && tolerance.speed >= 0.0) {
            return Err(JumpControlError::Setting { field: "posing_tolerance", expected: "non-negative angle and speed".into() });
        }
        let nj = model.nv - 6;
        let mut feet = BaseFrameFeet::new(model)?;
        let mut r = Self {
            t: vec![],
            q: vec![],
            v: vec![],
            tau: vec![],
            foot_position: vec![],
            foot_velocity: vec![],
            in_contact: vec![],
            leg_dofs: vec![],
            normal_force: vec![],
            lift_off_lead: vec![],
            t_posing: 0.0,
            pre_landing: DVector::zeros(model.nq),
            target: JumpTarget { position: Vector3::zeros(), yaw: 0.0 },
            impact_velocity: (Vector3::zeros(), Vector3::zeros()),
        };
        r.leg_dofs = vec![[0; 3]; model.feet.len()];
        for leg in feet.legs() {
            r.leg_dofs[leg.foot] = leg.v_index;
        }
        for k in &trajectory.knots {
            r.in_contact.push(if k.in_contact.len() == model.feet.len() { k.in_contact.clone() } else { vec![false; model.feet.len()] });
            r.normal_force.push(if k.contact_force.len() == model.feet.len() { k.contact_force.iter().map(|f| f[2].max(0.0)).collect() } else { vec![0.0; model.feet.len()] });
            r.lift_off_lead.push(vec![0.0; model.feet.len()]);
            let q = DVector::from_column_slice(&k.q);
            let v = DVector::from_column_slice(&k.v);
            let mut tau = DVector::zeros(model.nv);
            tau.rows_mut(6, nj).copy_from_slice(&k.tau);
            let mut p = vec![Vector3::zeros(); model.feet.len()];
            let mut pd = vec![Vector3::zeros(); model.feet.len()];
            feet.evaluate(model, &q, &v);
            for (i, leg) in feet.legs().iter().enumerate() {
                p[leg.foot] = feet.position[i];
                pd[leg.foot] = feet.velocity[i];
            }
            r.t.push(k.t);
            r.q.push(q);
            r.v.push(v);
            r.tau.push(tau);
            r.foot_position.push(p);
            r.foot_velocity.push(pd);
        }
        let last = r.q.len() - 1;
        r.pre_landing.copy_from(&r.q[last]);
        let posing = |k: usize| {
            model.actuated_joints().all(|j| (r.q[k][j.idx_q] - r.q[last][j.idx_q]).abs() <= tolerance.angle && r.v[k][j.idx_v].abs() <= tolerance.speed)
        };
        let mut first = last;
        while first > 0 && posing(first - 1) {
            first -= 1;
        }
        r.t_posing = r.t[first];
        let rotation = base_orientation(r.q[last].as_slice());
        let (_, _, yaw) = rotation.euler_angles();
        r.target = JumpTarget { position: Vector3::new(r.q[last][0], r.q[last][1], r.q[last][2]), yaw };
        let v = &r.v[last];
        r.impact_velocity = (rotation * Vector3::new(v[0], v[1], v[2]), rotation * Vector3::new(v[3], v[4], v[5]));
        Ok(r)
    }

    /// The same reference with `T_posing` and the pre-landing configuration given (as the
    /// full-body optimizer reports them) instead of found.
    pub fn with_posing(mut self, t_posing: f64, pre_landing: &DVector<f64>) -> Result<Self, JumpControlError> {
        if !t_posing.is_finite() || t_posing < self.t[0] || t_posing > self.duration_end() {
            return Err(JumpControlError::Setting { field: "t_posing", expected: format!("a time within the reference [{}, {}] s, got {t_posing}", self.t[0], self.duration_end()) });
        }
        if pre_landing.len() != self.pre_landing.len() || pre_landing.iter().any(|x| !x.is_finite()) {
            return Err(JumpControlError::Setting { field: "pre_landing", expected: format!("{} finite entries (nq)", self.pre_landing.len()) });
        }
        self.t_posing = t_posing;
        self.pre_landing.copy_from(pre_landing);
        Ok(self)
    }

    /// The same reference with each leg's feed-forward switched to its lift-off knot's
    /// `lead` seconds before that knot (s, at most one 10 ms interval), whatever its push.
    ///
    /// Why: the plan's contact is rigid, the simulators' is compliant. At the end of a push
    /// the ground is pressed in by about `f / k_n` (legwork's A1 contact: ~8 mm under the
    /// 260 N per foot of barrel_roll's last push), and the foot only unloads once the leg has
    /// retracted that far: with the plan's timing the foot went on pushing ~5 ms after the
    /// plan's lift-off and the barrel roll left with 12 % more roll momentum than planned
    /// (`docs/experiments/jump-flip.md`). Ending the push early on the lifting legs only
    /// hands the unloading the time it takes; the stance legs keep the plan's timing.
    pub fn with_lift_off_lead(mut self, lead: f64) -> Result<Self, JumpControlError> {
        let interval = self.t.windows(2).map(|w| w[1] - w[0]).fold(f64::INFINITY, f64::min);
        if !(lead.is_finite() && lead >= 0.0 && lead <= interval) {
            return Err(JumpControlError::Setting { field: "lift_off_lead", expected: format!("a time in [0, {interval}] s (one knot interval), got {lead}") });
        }
        self.lift_off_lead.iter_mut().for_each(|leads| leads.iter_mut().for_each(|l| *l = lead));
        Ok(self)
    }

    /// The same reference with each lifting leg's push ended by the time its foot needs to
    /// rise out of the ground its last push pressed in ([`JumpReference::with_lift_off_lead`]
    /// for why): `lead = (f_n / k_n) / v_r`, at most the interval, with `f_n` the plan's normal
    /// force over the foot's last pushing interval, `k_n` the contact's normal stiffness
    /// (N/m) and `v_r` the retraction speed (m/s). A push that ends lightly loaded (20 N at
    /// lateral_down's lift-off) gets 0.3 ms (A1: `k_n` 30,900 N/m, `v_r` 2.3 m/s), a hard
    /// one (260 N at barrel_roll's) 3.7 ms.
    pub fn with_lift_off_release(mut self, normal_stiffness: f64, retraction_speed: f64) -> Result<Self, JumpControlError> {
        if !(normal_stiffness.is_finite() && normal_stiffness > 0.0 && retraction_speed.is_finite() && retraction_speed > 0.0) {
            return Err(JumpControlError::Setting {
                field: "lift_off_retraction_speed",
                expected: format!("a positive stiffness and speed, got {normal_stiffness} N/m and {retraction_speed} m/s"),
            });
        }
        for k in 0..self.t.len() - 1 {
            let interval = self.t[k + 1] - self.t[k];
            for f in 0..self.lift_off_lead[k].len() {
                let pressed_in = self.normal_force[k][f] / normal_stiffness;
                self.lift_off_lead[k][f] = (pressed_in / retraction_speed).min(interval);
            }
        }
        Ok(self)
    }

    /// `T_posing` (s).
    pub fn t_posing(&self) -> f64 {
        self.t_posing
    }

    /// Time of the last knot (s).
    pub fn duration_end(&self) -> f64 {
        self.t[self.t.len() - 1]
    }

    pub fn pre_landing(&self) -> &DVector<f64> {
        &self.pre_landing
    }

    pub fn target(&self) -> JumpTarget {
        self.target
    }

    /// The reference's first configuration and velocity (the robot at rest before take-off).
    pub fn initial_state(&self) -> (&DVector<f64>, &DVector<f64>) {
        (&self.q[0], &self.v[0])
    }

    /// Base linear and angular velocity (world) of the last knot.
    pub fn impact_velocity(&self) -> (Vector3<f64>, Vector3<f64>) {
        self.impact_velocity
    }

    /// Linear interpolation of the state between the knots around `t` into `out` (held at the
    /// ends; after the last knot, the pre-landing configuration with zero joint velocity),
    /// the feed-forward torque held from the knot at or before `t`. Configurations are
    /// interpolated on the manifold ([`interpolate_state`]).
    pub fn sample(&self, model: &Model, t: f64, out: &mut ReferenceSample) {
        let (k, s) = match knot_bracket(&self.t, t) {
            KnotBracket::Hold(k) => {
                out.q.copy_from(&self.q[k]);
                out.v.copy_from(&self.v[k]);
                out.tau.copy_from(&self.tau[k]);
                out.foot_position.copy_from_slice(&self.foot_position[k]);
                out.foot_velocity.copy_from_slice(&self.foot_velocity[k]);
                return;
            }
            KnotBracket::Between(k, s) => (k, s),
        };
        interpolate_state(model, (&self.q[k], &self.v[k]), (&self.q[k + 1], &self.v[k + 1]), s, &mut out.dq, &mut out.q, &mut out.v);
        // The feed-forward is held over the interval, as the plan applied it: the full-body
        // optimization's torques and forces are piecewise constant (`u_k` acts over
        // `[t_k, t_k+1)`, semi-implicit Euler). Interpolated, the last stance interval's
        // push would fade towards the flight torques and deliver half its impulse.
        out.tau.copy_from(&self.tau[k]);
        for (f, dofs) in self.leg_dofs.iter().enumerate() {
            let lead = self.lift_off_lead[k][f];
            if lead > 0.0 && self.t[k + 1] - t <= lead && self.in_contact[k][f] && !self.in_contact[k + 1][f] {
                for &i in dofs {
                    out.tau[i] = self.tau[k + 1][i];
                }
            }
        }
        for f in 0..out.foot_position.len() {
            out.foot_position[f] = self.foot_position[k][f].lerp(&self.foot_position[k + 1][f], s);
            out.foot_velocity[f] = self.foot_velocity[k][f].lerp(&self.foot_velocity[k + 1][f], s);
        }
    }
}
