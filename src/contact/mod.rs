//! The smooth contact model of Neunert 2017 (sec. III-B, eq. 9-11): a foot sphere against
//! the [`crate::terrain::Terrain`], a nonlinear spring-damper along the surface normal, a
//! tangential spring to the point where contact was established plus damping, and a
//! friction cone that saturates the tangential force.
//!
//! The simulator and the trajectory optimizer use the same function,
//! [`contact_force`], so that what is optimized is what is simulated. Its derivatives with
//! respect to the foot position and velocity ([`ContactForce::d_position`],
//! [`ContactForce::d_velocity`]) are exact for the model as written here, given the local
//! surface (point and normal) and the anchor; they are checked against finite differences
//! in the tests.

mod anchor;

pub use anchor::{anchor_derivatives, AnchorDerivatives};

use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};

/// Parameters of the contact model: a property of the robot's feet on the ground, not of a
/// task ([`crate::model::Model::contact`]; a robot description's `[contact]` section).
///
/// # Calibration (issue 16, "one world")
///
/// The values come from [`ContactParams::for_foot_load`], calibrated against MuJoCo 4.0's
/// default contact (`solref = 0.02 1`, `solimp = 0.9 0.95 0.001`), the engine legwork's motions
/// are checked in. MuJoCo's default contact is mass-normalized (a reference acceleration with a
/// 20 ms time constant, critically damped), so legwork scales its stiffnesses and dampings
/// with the load one foot carries standing, `m_f = total mass / number of feet`, and the feet of
/// a light and a heavy robot behave alike. Measured with a foot-sphere of `m_f = 21.7 kg` (HyQ)
/// dropped from 0.1 m onto MuJoCo's default plane at a 1 ms step: 0.37 mm static
/// penetration, 10.2 mm at impact, no lift-off after touch-down (rebound 0.19 m/s of 1.39);
/// tangentially a loaded sphere creeps 3.5-25 mm/s under `|F_t| / F_n` = 0.2-0.75 and moves
/// 0.1-0.8 mm within 50 ms. legwork's spring-damper (eq. 9-11) is chosen to match the drop
/// and to hold a loaded foot as firmly:
///
/// * `alpha_c = 0.01` m (Table I);
/// * `k_n = 9000 m_f` N/m: HyQ standing under its joint PD and dropped from 0.1 m (legwork's
///   simulator, 1 or 2 kHz) sinks at most 9.1-9.3 mm (MuJoCo's foot-load drop: 10.2 mm) and
///   rests at 4.7 mm (MuJoCo 0.37 mm: a spring cannot have both MuJoCo's impact compliance
///   and its near-rigid rest; the impact is what a motion's landings feel);
/// * `d_n = 4500 m_f` and `d_t = 4500 m_f` N s/m^2: about as much damping as stays stable at
///   the step [`max_step`](Self::max_step) on the whole robot (on HyQ, twice as much makes
///   the feet chatter at 1 ms). The foot load alone on this contact would rebound at 64 % of
///   its impact speed; on the robot the legs absorb it: the dropped HyQ keeps every foot on
///   the ground after touch-down, as in MuJoCo (A1: 12.7 mm, two brief lift-offs);
/// * `k_t = 2.3e6 m_f` N/m^2: the tangential spring stiffens with the penetration (it
///   multiplies `s(p_n)`); standing, HyQ's foot then resists like a 54 kN/m spring, so
///   100 N of side load stretches it 1.8 mm (Table I's largest `k_t`, 5e6 N/m^2, gives
///   18 mm: feet that move while they stick);
/// * `mu = 0.8`, the friction of the MuJoCo check.
///
/// On the whole robot, standing under its joint PD and dropped from 0.1 m (MuJoCo with
/// legwork's MJCF export at 1 ms, legwork's simulator at 2 kHz; `tests/mujoco_check.rs`,
/// docs/experiments/mujoco-check.md):
///
/// | | static penetration (mm) | rest base height (m) | sink below rest (mm) | bounce (mm) |
/// |---|---|---|---|---|
/// | HyQ, MuJoCo | 0.96-1.29 | 0.5792 | 27.8 | 9.5 |
/// | HyQ, legwork | 4.28-5.03 | 0.5812 | 30.1 | 7.3 |
/// | A1, MuJoCo | 0.69-0.95 | 0.2574 | 16.6 | 0.7 |
/// | A1, legwork | 3.94-5.27 | 0.2538 | 15.6 | 5.1 |
///
/// (Table I's contact, the former default: HyQ 6.3-7.4 mm, 0.5769 m, 35.0 mm, 10.8 mm.)
///
/// These are outside Table I's ranges for `k_n` (8e3-9e4), `d_n` (2e3-5e4) and `k_t` (0-5e6):
/// Table I's contacts are softer and bouncier than MuJoCo's (HyQ's foot load dropped from
/// 0.1 m on `k_n = 9e4`, `d_n = 2e4` rebounds at 80 % of its impact speed, MuJoCo's at 13 %).
/// The price is the step: these contacts need integration steps of at most
/// [`max_step`](Self::max_step) = 1 ms (HyQ diverges at 2 ms), so the optimizer integrates each
/// knot interval in substeps of at most 1 ms.
///
/// ```
/// let p = legwork::contact::ContactParams::for_foot_load(86.8 / 4.0);
/// assert_eq!(p.alpha, 0.01);
/// assert!((p.normal_stiffness - 195_300.0).abs() < 1e-6);
/// p.validate().unwrap();
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ContactParams {
    /// Smoothing penetration `alpha_c` (m): the force grows quadratically below it.
    pub alpha: f64,
    /// Normal stiffness `k_n` (N/m).
    pub normal_stiffness: f64,
    /// Normal damping `d_n` (N s/m^2: it multiplies the penetration, eq. 9).
    pub normal_damping: f64,
    /// Tangential stiffness `k_t` (N/m^2), towards the point where contact began.
    pub tangential_stiffness: f64,
    /// Tangential damping `d_t` (N s/m^2).
    pub tangential_damping: f64,
    /// Friction coefficient `mu` (static = dynamic, as the paper).
    pub friction: f64,
    /// The largest integration step (s) at which this contact is stable on its robot:
    /// simulations and the optimizer's substeps may not be longer.
    pub max_step: f64,
}

/// Per kilogram of the standing load of one foot: the calibration of [`ContactParams`].
pub mod calibration {
    /// `k_n / m_f` (N/m per kg).
    pub const NORMAL_STIFFNESS_PER_KG: f64 = 9000.0;
    /// `d_n / m_f` (N s/m^2 per kg).
    pub const NORMAL_DAMPING_PER_KG: f64 = 4500.0;
    /// `k_t / m_f` (N/m^2 per kg).
    pub const TANGENTIAL_STIFFNESS_PER_KG: f64 = 2.3e6;
    /// `d_t / m_f` (N s/m^2 per kg).
    pub const TANGENTIAL_DAMPING_PER_KG: f64 = 4500.0;
    /// `alpha_c` (m), Neunert 2017 Table I.
    pub const ALPHA: f64 = 0.01;
    /// Friction coefficient of the ground (MuJoCo check: 0.8).
    pub const FRICTION: f64 = 0.8;
    /// Largest stable integration step (s).
    pub const MAX_STEP: f64 = 0.001;
    /// HyQ's standing load per foot (86.8 kg / 4), the load of [`super::ContactParams::default`].
    pub const REFERENCE_FOOT_LOAD: f64 = 21.7;
}

impl ContactParams {
    /// The calibrated contact ([`ContactParams`], "Calibration") for feet that each carry
    /// `mass_per_foot` kg standing.
    pub fn for_foot_load(mass_per_foot: f64) -> Self {
        use calibration::*;
        Self {
            alpha: ALPHA,
            normal_stiffness: NORMAL_STIFFNESS_PER_KG * mass_per_foot,
            normal_damping: NORMAL_DAMPING_PER_KG * mass_per_foot,
            tangential_stiffness: TANGENTIAL_STIFFNESS_PER_KG * mass_per_foot,
            tangential_damping: TANGENTIAL_DAMPING_PER_KG * mass_per_foot,
            friction: FRICTION,
            max_step: MAX_STEP,
        }
    }
}

/// The calibrated contact for HyQ's foot load (21.7 kg); a robot's own is
/// [`crate::model::Model::contact`].
impl Default for ContactParams {
    fn default() -> Self {
        Self::for_foot_load(calibration::REFERENCE_FOOT_LOAD)
    }
}

/// A contact parameter out of its range; names the field.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("contact parameter `{field}`: expected {expected}, got {value}")]
pub struct ContactParamsError {
    pub field: &'static str,
    pub expected: &'static str,
    pub value: f64,
}

impl ContactParams {
    /// Every parameter finite; `alpha`, `k_n`, `max_step` positive; the others non-negative.
    pub fn validate(&self) -> Result<(), ContactParamsError> {
        let checks: [(&'static str, f64, bool); 7] = [
            ("alpha", self.alpha, true),
            ("normal_stiffness", self.normal_stiffness, true),
            ("normal_damping", self.normal_damping, false),
            ("tangential_stiffness", self.tangential_stiffness, false),
            ("tangential_damping", self.tangential_damping, false),
            ("friction", self.friction, false),
            ("max_step", self.max_step, true),
        ];
        for (field, value, strictly_positive) in checks {
            let ok = value.is_finite() && if strictly_positive { value > 0.0 } else { value >= 0.0 };
            if !ok {
                let expected = if strictly_positive { "a finite number > 0" } else { "a finite number >= 0" };
                return Err(ContactParamsError { field, expected, value });
            }
        }
        Ok(())
    }

    /// The smoothing profile of eq. (9)-(10) and its derivative:
    /// `s(p) = 0` for `p <= 0`, `p^2 / (2 alpha)` for `0 < p < alpha`, `p - alpha / 2` above.
    #[inline]
    pub fn profile(&self, p: f64) -> (f64, f64) {
        if p <= 0.0 {
            (0.0, 0.0)
        } else if p < self.alpha {
            (p * p / (2.0 * self.alpha), p / self.alpha)
        } else {
            (p - 0.5 * self.alpha, 1.0)
        }
    }

    /// The penetration at which the foot, at rest, carries a normal force `f_n`: the inverse
    /// of the static part of eq. (9), `f_n = k_n s(p)`, so `s = f_n / k_n` and
    /// `p = sqrt(2 alpha s)` below `s = alpha / 2`, `s + alpha / 2` above (0 for `f_n <= 0`).
    ///
    /// ```
    /// let c = legwork::contact::ContactParams::for_foot_load(86.8 / 4.0);
    /// let p = c.static_penetration(86.8 / 4.0 * 9.81);
    /// assert!((c.normal_stiffness * c.profile(p).0 - 86.8 / 4.0 * 9.81).abs() < 1e-9);
    /// assert!(p > 0.004 && p < 0.005);  // HyQ's feet rest 4.3-5.0 mm deep
    /// ```
    pub fn static_penetration(&self, f_n: f64) -> f64 {
        if f_n.is_nan() || f_n <= 0.0 {
            return 0.0;
        }
        let s = f_n / self.normal_stiffness;
        if s < 0.5 * self.alpha {
            (2.0 * self.alpha * s).sqrt()
        } else {
            s + 0.5 * self.alpha
        }
    }
}

/// Where the surface is under a foot: the local tangent plane.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Surface {
    /// A point of the surface (below the foot).
    pub point: Vector3<f64>,
    /// Unit normal, out of the ground.
    pub normal: Vector3<f64>,
}

/// The contact force on one foot and its derivatives.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContactForce {
    /// Force of the ground on the foot, world frame (N).
    pub force: Vector3<f64>,
    /// Penetration `p_n` of the foot sphere into the surface (m, positive inside).
    pub penetration: f64,
    /// The contact point: the lowest point of the sphere along the normal.
    pub point: Vector3<f64>,
    /// True when the tangential force was cut to the friction cone (the foot slips).
    pub slipping: bool,
    /// `d force / d p` (3 x 3), foot centre position, anchor and surface held.
    pub d_position: Matrix3<f64>,
    /// `d force / d pdot` (3 x 3).
    pub d_velocity: Matrix3<f64>,
    /// Normal force magnitude `F_n` (N).
    pub normal_force: f64,
    /// Tangential displacement from the anchor to the contact point, in the tangent plane.
    pub tangential_offset: Vector3<f64>,
}

impl ContactForce {
    /// No contact: zero force, zero derivatives.
    pub fn none(point: Vector3<f64>, penetration: f64) -> Self {
        Self {
            force: Vector3::zeros(),
            penetration,
            point,
            slipping: false,
            d_position: Matrix3::zeros(),
            d_velocity: Matrix3::zeros(),
            normal_force: 0.0,
            tangential_offset: Vector3::zeros(),
        }
    }
}

/// Contact force on a foot sphere of radius `radius` with centre `position` moving at
/// `velocity`, against the local `surface`, with the tangential spring anchored at
/// `anchor` (the contact point when contact began; `None` = contact begins now, the spring
/// is unstretched). Neunert 2017:
///
/// ```text
/// p_n  = r - n . (p - s)                        penetration of the sphere (s on the surface)
/// pd_n = -n . pdot                              penetration rate
/// F_n  = max(k_n + d_n pd_n, 0) s(p_n)          eq. (9), s the smoothing profile
/// u    = -(k_t P (c - a) + d_t P pdot)          eq. (10) before smoothing, P = I - n n^T,
/// F_t  = u s(p_n)                               c = p - r n the contact point, a the anchor
/// F_t  = mu F_n F_t / |F_t|  if |F_t| > mu F_n  eq. (11), the friction cone
/// F    = F_n n + F_t
/// ```
///
/// **No adhesion.** The damping term of eq. (9) alone would pull the foot into the ground
/// when the foot leaves the surface fast (`pd_n < -k_n / d_n`); the factor
/// `k_n + d_n pd_n` is therefore clamped at zero, so `F_n >= 0` always, and the friction
/// cone bounds `|F_t| <= mu F_n`, so the ground only ever pushes.
///
/// The foot is a point on the sphere's centre for velocities (rolling of the sphere is
/// neglected, as in the paper's point-foot model).
#[inline]
pub fn contact_force(
    params: &ContactParams,
    radius: f64,
    position: &Vector3<f64>,
    velocity: &Vector3<f64>,
    surface: &Surface,
    anchor: Option<&Vector3<f64>>,
) -> ContactForce {
    let n = &surface.normal;
    let penetration = radius - n.dot(&(position - surface.point));
    let point = position - n * radius;
    let (s, ds) = params.profile(penetration);
    if s == 0.0 {
        return ContactForce::none(point, penetration);
    }
    let n_t = n.transpose();
    // Normal force, eq. (9), with the damping factor clamped at zero (no adhesion).
    let penetration_rate = -n.dot(velocity);
    let gain = params.normal_stiffness + params.normal_damping * penetration_rate;
    let (normal_force, dfn_dp, dfn_dv) = if gain > 0.0 {
        (gain * s, -(n_t * (gain * ds)), -(n_t * (params.normal_damping * s)))
    } else {
        (0.0, nalgebra::RowVector3::zeros(), nalgebra::RowVector3::zeros())
    };
    // Tangential spring to the anchor and damping, eq. (10).
    let tangent = Matrix3::identity() - n * n_t;
    let offset = match anchor {
        Some(a) => tangent * (point - a),
        None => Vector3::zeros(),
    };
    let u = -(offset * params.tangential_stiffness + tangent * velocity * params.tangential_damping);
    let du_dp = if anchor.is_some() { -tangent * params.tangential_stiffness } else { Matrix3::zeros() };
    let du_dv = -tangent * params.tangential_damping;
    let tangential = u * s;
    let limit = params.friction * normal_force;
    let tangential_norm = tangential.norm();
    let (tangential, dft_dp, dft_dv, slipping) = if tangential_norm > limit {
        // Friction cone, eq. (11): F_t = mu F_n u / |u|.
        let u_norm = u.norm();
        let dir = u / u_norm;
        let d_dir = (Matrix3::identity() - dir * dir.transpose()) / u_norm;
        let mu = params.friction;
        (
            dir * limit,
            dir * dfn_dp * mu + d_dir * du_dp * limit,
            dir * dfn_dv * mu + d_dir * du_dv * limit,
            true,
        )
    } else {
        // d(u s)/dp = s du/dp + u ds/dp, ds/dp = -ds n^T.
        (tangential, du_dp * s - u * n_t * ds, du_dv * s, false)
    };
    ContactForce {
        force: n * normal_force + tangential,
        penetration,
        point,
        slipping,
        d_position: n * dfn_dp + dft_dp,
        d_velocity: n * dfn_dv + dft_dv,
        normal_force,
        tangential_offset: offset,
    }
}

/// The anchor after a simulation step: kept while in contact, set to the contact point
/// when contact begins, forgotten when the foot leaves the surface. When the friction
/// cone saturated the force, the anchor is dragged along the surface towards the contact
/// point so that the spring stretch shrinks by the same factor as the force was cut
/// (`a' = c - offset * mu F_n / |F_t,spring|`): the foot slides instead of snapping back.
pub fn update_anchor(params: &ContactParams, contact: &ContactForce, anchor: &mut Option<Vector3<f64>>) {
    if contact.penetration <= 0.0 {
        *anchor = None;
        return;
    }
    match anchor {
        None => *anchor = Some(contact.point),
        Some(a) if contact.slipping => {
            let (s, _) = params.profile(contact.penetration);
            let spring = contact.tangential_offset.norm() * params.tangential_stiffness * s;
            let limit = params.friction * contact.normal_force;
            let keep = if spring > limit && spring > 0.0 { limit / spring } else { 1.0 };
            *a = contact.point - contact.tangential_offset * keep;
        }
        Some(_) => {}
    }
}

/// Values inside Neunert 2017's Table I (the unit tests' numbers are worked out for them).
#[cfg(test)]
pub(crate) fn table_i() -> ContactParams {
    ContactParams { alpha: 0.01, normal_stiffness: 90_000.0, normal_damping: 20_000.0, tangential_stiffness: 2_000_000.0, tangential_damping: 5_000.0, friction: 0.8, max_step: 0.001 }
}

#[cfg(test)]
mod tests {
    use super::*;

    use super::table_i;

    fn flat() -> Surface {
        Surface { point: Vector3::zeros(), normal: Vector3::z() }
    }

    fn inclined() -> Surface {
        Surface { point: Vector3::new(0.1, -0.2, 0.05), normal: Vector3::new(0.2, -0.1, 1.0).normalize() }
    }

    /// Central differences of `contact_force` in position and velocity.
    fn numeric(params: &ContactParams, r: f64, p: &Vector3<f64>, v: &Vector3<f64>, s: &Surface, a: Option<&Vector3<f64>>) -> (Matrix3<f64>, Matrix3<f64>) {
        let h = 1e-7;
        let mut dp = Matrix3::zeros();
        let mut dv = Matrix3::zeros();
        for k in 0..3 {
            let e = Vector3::ith(k, h);
            let fp = contact_force(params, r, &(p + e), v, s, a).force;
            let fm = contact_force(params, r, &(p - e), v, s, a).force;
            dp.set_column(k, &((fp - fm) / (2.0 * h)));
            let fp = contact_force(params, r, p, &(v + e), s, a).force;
            let fm = contact_force(params, r, p, &(v - e), s, a).force;
            dv.set_column(k, &((fp - fm) / (2.0 * h)));
        }
        (dp, dv)
    }

    #[test]
    fn normal_force_follows_eq_9() {
        let params = table_i();
        let r = 0.02;
        // Above the ground: nothing.
        let c = contact_force(&params, r, &Vector3::new(0.0, 0.0, 0.03), &Vector3::zeros(), &flat(), None);
        assert_eq!(c.force, Vector3::zeros());
        // 4 mm (quadratic zone), at rest: k_n p^2 / (2 alpha).
        let c = contact_force(&params, r, &Vector3::new(0.0, 0.0, r - 0.004), &Vector3::zeros(), &flat(), None);
        assert!((c.force.z - 90_000.0 * 0.004f64.powi(2) / 0.02).abs() < 1e-9);
        // 15 mm (linear zone), moving down at 0.1 m/s: (k_n + d_n 0.1)(p - alpha / 2).
        let c = contact_force(&params, r, &Vector3::new(0.0, 0.0, r - 0.015), &Vector3::new(0.0, 0.0, -0.1), &flat(), None);
        assert!((c.force.z - (90_000.0 + 20_000.0 * 0.1) * (0.015 - 0.005)).abs() < 1e-9);
        assert!((c.penetration - 0.015).abs() < 1e-15);
    }

    #[test]
    fn no_adhesion_when_leaving_fast() {
        let params = table_i();
        // Leaving at 10 m/s: k_n + d_n pd_n = 90000 - 200000 < 0: no pull.
        let c = contact_force(&params, 0.02, &Vector3::new(0.0, 0.0, 0.01), &Vector3::new(0.3, 0.0, 10.0), &flat(), Some(&Vector3::new(-0.01, 0.0, 0.0)));
        assert_eq!(c.normal_force, 0.0);
        assert_eq!(c.force, Vector3::zeros()); // the cone closes the tangential force too
    }

    #[test]
    fn friction_cone_bounds_the_tangential_force() {
        let params = table_i();
        let anchor = Vector3::new(-0.05, 0.02, 0.0); // far: the spring would exceed the cone
        let c = contact_force(&params, 0.02, &Vector3::new(0.0, 0.0, 0.012), &Vector3::new(0.1, 0.0, 0.0), &flat(), Some(&anchor));
        assert!(c.slipping);
        let ft = Vector3::new(c.force.x, c.force.y, 0.0).norm();
        assert!((ft - params.friction * c.force.z).abs() < 1e-9, "{ft} vs {}", params.friction * c.force.z);
        // The force points back towards the anchor (and against the motion).
        assert!(c.force.x < 0.0 && c.force.y > 0.0);
    }

    #[test]
    fn derivatives_match_finite_differences() {
        let params = table_i();
        let r = 0.02;
        let cases = [
            // (surface, position offset along -normal (penetration), lateral position, velocity, anchor offset)
            (flat(), 0.004, Vector3::new(0.01, -0.02, 0.0), Vector3::new(0.05, -0.02, -0.1), Some(Vector3::new(0.001, 0.0005, 0.0))),
            (flat(), 0.014, Vector3::new(0.0, 0.0, 0.0), Vector3::new(0.0, 0.0, 0.3), Some(Vector3::new(-0.0002, 0.0001, 0.0))),
            (inclined(), 0.006, Vector3::new(0.03, 0.01, 0.0), Vector3::new(-0.2, 0.1, 0.05), Some(Vector3::new(0.0003, -0.0004, 0.0))),
            (inclined(), 0.02, Vector3::new(0.0, 0.0, 0.0), Vector3::new(0.4, 0.0, -0.2), Some(Vector3::new(0.03, 0.0, 0.0))), // slipping
            (flat(), 0.008, Vector3::new(0.0, 0.0, 0.0), Vector3::new(0.3, 0.1, 0.0), None),
        ];
        for (k, (surface, depth, lateral, vel, anchor_offset)) in cases.iter().enumerate() {
            let n = surface.normal;
            let tangent = Matrix3::identity() - n * n.transpose();
            let base = surface.point + tangent * lateral;
            let p = base + n * (r - depth);
            let anchor = anchor_offset.map(|o| base - tangent * o);
            let c = contact_force(&params, r, &p, vel, surface, anchor.as_ref());
            let (dp, dv) = numeric(&params, r, &p, vel, surface, anchor.as_ref());
            let scale = 1.0 + c.d_position.norm();
            assert!((c.d_position - dp).norm() / scale < 1e-6, "case {k}: dF/dp\n{}\nvs\n{}", c.d_position, dp);
            assert!((c.d_velocity - dv).norm() / (1.0 + dv.norm()) < 1e-6, "case {k}: dF/dv\n{}\nvs\n{}", c.d_velocity, dv);
        }
    }

    #[test]
    fn anchor_is_set_kept_dragged_and_released() {
        let params = table_i();
        let mut anchor = None;
        let p = Vector3::new(0.0, 0.0, 0.012);
        let c = contact_force(&params, 0.02, &p, &Vector3::zeros(), &flat(), anchor.as_ref());
        update_anchor(&params, &c, &mut anchor);
        assert!((anchor.unwrap() - Vector3::new(0.0, 0.0, -0.008)).norm() < 1e-15);
        // Far from the anchor: slipping, the anchor is dragged until the spring is at the cone.
        let p2 = Vector3::new(0.05, 0.0, 0.012);
        let c = contact_force(&params, 0.02, &p2, &Vector3::zeros(), &flat(), anchor.as_ref());
        assert!(c.slipping);
        update_anchor(&params, &c, &mut anchor);
        let c = contact_force(&params, 0.02, &p2, &Vector3::zeros(), &flat(), anchor.as_ref());
        assert!(!c.slipping || (c.force.xy().norm() - params.friction * c.normal_force).abs() < 1e-9);
        // Lifted off: the anchor is forgotten.
        let c = contact_force(&params, 0.02, &Vector3::new(0.0, 0.0, 0.05), &Vector3::zeros(), &flat(), anchor.as_ref());
        update_anchor(&params, &c, &mut anchor);
        assert!(anchor.is_none());
    }

    #[test]
    fn bad_parameters_are_named() {
        let p = ContactParams { normal_stiffness: f64::NAN, ..table_i() };
        assert_eq!(p.validate().unwrap_err().field, "normal_stiffness");
        let p = ContactParams { friction: -0.1, ..table_i() };
        assert!(p.validate().unwrap_err().to_string().contains("friction"));
    }
}
