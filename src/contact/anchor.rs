//! The tangential-spring anchor as a state of the linearization.
//!
//! Neunert 2017 (sec. III-B) treats the anchor of the tangential spring of eq. (10) as a
//! hidden state: it is set where the foot touches down, kept while the foot sticks, dragged
//! when the friction cone of eq. (11) saturates the force ([`super::update_anchor`]), and
//! forgotten at lift-off. A linearization that holds the anchor fixed tells the optimizer
//! that moving a foot that lands later always stretches the spring to the old landing
//! point, while the rollout plants the anchor where the foot actually lands. These are the
//! missing derivatives: of the contact force with respect to the anchor, and of the anchor
//! after a step with respect to the foot position, velocity and the anchor before it.

use super::{ContactForce, ContactParams};
use nalgebra::{Matrix3, Vector3};

/// Derivatives of the anchor's role in one step (all 3 x 3, world frame, surface held).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AnchorDerivatives {
    /// `d F / d a`: the contact force's dependence on the anchor (zero without one).
    pub force: Matrix3<f64>,
    /// `d a' / d p`, `d a' / d pdot`, `d a' / d a` of the anchor after the step
    /// ([`super::update_anchor`]); all zero when the foot leaves (`a' = None`).
    pub next_d_position: Matrix3<f64>,
    pub next_d_velocity: Matrix3<f64>,
    pub next_d_anchor: Matrix3<f64>,
}

/// The derivatives of [`super::contact_force`] with respect to the anchor, and of
/// [`super::update_anchor`], for the foot whose contact `contact` was evaluated at velocity
/// `velocity` against a surface of unit normal `normal` with anchor `anchor`.
///
/// ```text
/// stick:  F_t = -s (k_t P (c - a) + d_t P pdot)       dF/da = s k_t P,  a' = a
/// slip:   F_t = mu F_n u / |u|                         dF/da = mu F_n (I - u^ u^T) / |u| k_t P
///         a'  = c - beta o / |o|,  o = P (c - a),  beta = mu max(k_n + d_n pd_n, 0) / k_t
/// touch:  a'  = c                                       (anchor set where the foot is)
/// ```
///
/// (`beta` is the spring stretch at the cone, `mu F_n / (k_t s)`: `s` cancels.)
pub fn anchor_derivatives(params: &ContactParams, contact: &ContactForce, velocity: &Vector3<f64>, normal: &Vector3<f64>, anchor: Option<&Vector3<f64>>) -> AnchorDerivatives {
    let zero = Matrix3::zeros();
    let mut d = AnchorDerivatives { force: zero, next_d_position: zero, next_d_velocity: zero, next_d_anchor: zero };
    if contact.penetration <= 0.0 {
        return d; // no force; the anchor is forgotten
    }
    let tangent = Matrix3::identity() - normal * normal.transpose();
    if anchor.is_none() {
        d.next_d_position = Matrix3::identity(); // a' = c = p - r n
        return d;
    }
    let (s, _) = params.profile(contact.penetration);
    let offset = contact.tangential_offset;
    let k_t = params.tangential_stiffness;
    // The force.
    if contact.slipping {
        let u = -(offset * k_t + tangent * velocity * params.tangential_damping);
        let u_norm = u.norm();
        if u_norm > 0.0 {
            let dir = u / u_norm;
            let limit = params.friction * contact.normal_force;
            d.force = (Matrix3::identity() - dir * dir.transpose()) * (limit * k_t / u_norm) * tangent;
        }
    } else {
        d.force = tangent * (s * k_t);
    }
    // The anchor after the step.
    if !contact.slipping {
        d.next_d_anchor = Matrix3::identity();
        return d;
    }
    let spring = offset.norm() * k_t * s;
    let limit = params.friction * contact.normal_force;
    if spring > limit && spring > 0.0 {
        // a' = c - beta o^, beta = mu gain / k_t.
        let o_norm = offset.norm();
        let o_hat = offset / o_norm;
        let beta = limit / (k_t * s);
        let d_hat = (Matrix3::identity() - o_hat * o_hat.transpose()) * tangent / o_norm;
        d.next_d_position = Matrix3::identity() - d_hat * beta;
        d.next_d_anchor = d_hat * beta;
        if contact.normal_force > 0.0 {
            // d beta / d pdot = mu d_n / k_t d pd_n / d pdot = -mu d_n / k_t n^T.
            d.next_d_velocity = o_hat * normal.transpose() * (params.friction * params.normal_damping / k_t);
        }
    } else {
        // The damping alone saturated the cone: a' = c - P (c - a).
        d.next_d_position = Matrix3::identity() - tangent;
        d.next_d_anchor = tangent;
    }
    d
}

#[cfg(test)]
mod tests {
    use super::super::{contact_force, update_anchor, Surface};
    use super::*;

    fn surfaces() -> [Surface; 2] {
        [
            Surface { point: Vector3::zeros(), normal: Vector3::z() },
            Surface { point: Vector3::new(0.1, -0.2, 0.05), normal: Vector3::new(0.2, -0.1, 1.0).normalize() },
        ]
    }

    /// The anchor after one update from `(p, pdot, a)`.
    fn next_anchor(params: &ContactParams, r: f64, p: &Vector3<f64>, v: &Vector3<f64>, s: &Surface, a: Option<&Vector3<f64>>) -> Option<Vector3<f64>> {
        let c = contact_force(params, r, p, v, s, a);
        let mut anchor = a.copied();
        update_anchor(params, &c, &mut anchor);
        anchor
    }

    #[test]
    fn derivatives_match_finite_differences() {
        // Table I's contact and the calibrated one (stiffer, more damped).
        for params in [crate::contact::table_i(), ContactParams::default()] {
            derivatives_match_finite_differences_for(&params);
        }
    }

    fn derivatives_match_finite_differences_for(params: &ContactParams) {
        let params = *params;
        let r = 0.02;
        // (depth, lateral position, velocity, anchor offset from the contact point): sticking,
        // slipping on the spring, slipping on the damping, touching down, leaving fast.
        let cases = [
            (0.006, Vector3::new(0.01, -0.02, 0.0), Vector3::new(0.05, -0.02, -0.1), Some(Vector3::new(0.001, 0.0005, 0.0))),
            (0.012, Vector3::new(0.0, 0.01, 0.0), Vector3::new(0.1, 0.05, -0.05), Some(Vector3::new(0.05, -0.03, 0.0))),
            (0.003, Vector3::new(0.0, 0.0, 0.0), Vector3::new(5.0, -1.0, 3.0), Some(Vector3::new(0.0002, 0.0, 0.0))),
            (0.008, Vector3::new(0.02, 0.0, 0.0), Vector3::new(0.3, 0.1, -0.2), None),
            (0.01, Vector3::new(0.0, 0.0, 0.0), Vector3::new(0.2, 0.0, 6.0), Some(Vector3::new(0.01, 0.0, 0.0))),
        ];
        let h = 1e-7;
        for surface in surfaces() {
            let n = surface.normal;
            let tangent = Matrix3::identity() - n * n.transpose();
            for (k, (depth, lateral, vel, anchor_offset)) in cases.iter().enumerate() {
                let base = surface.point + tangent * lateral;
                let p = base + n * (r - depth);
                let a = anchor_offset.map(|o| base - tangent * o);
                let c = contact_force(&params, r, &p, vel, &surface, a.as_ref());
                let d = anchor_derivatives(&params, &c, vel, &n, a.as_ref());
                assert!(next_anchor(&params, r, &p, vel, &surface, a.as_ref()).is_some(), "case {k}: the foot keeps an anchor");
                let (mut fa, mut ap, mut av, mut aa) = (Matrix3::zeros(), Matrix3::zeros(), Matrix3::zeros(), Matrix3::zeros());
                for i in 0..3 {
                    let e = Vector3::ith(i, h);
                    let diff = |plus: Option<Vector3<f64>>, minus: Option<Vector3<f64>>| (plus.unwrap() - minus.unwrap()) / (2.0 * h);
                    ap.set_column(i, &diff(next_anchor(&params, r, &(p + e), vel, &surface, a.as_ref()), next_anchor(&params, r, &(p - e), vel, &surface, a.as_ref())));
                    av.set_column(i, &diff(next_anchor(&params, r, &p, &(vel + e), &surface, a.as_ref()), next_anchor(&params, r, &p, &(vel - e), &surface, a.as_ref())));
                    if let Some(a) = a {
                        let fp = contact_force(&params, r, &p, vel, &surface, Some(&(a + e))).force;
                        let fm = contact_force(&params, r, &p, vel, &surface, Some(&(a - e))).force;
                        fa.set_column(i, &((fp - fm) / (2.0 * h)));
                        aa.set_column(i, &diff(next_anchor(&params, r, &p, vel, &surface, Some(&(a + e))), next_anchor(&params, r, &p, vel, &surface, Some(&(a - e)))));
                    }
                }
                let close = |what: &str, analytic: &Matrix3<f64>, numeric: &Matrix3<f64>| {
                    assert!((analytic - numeric).norm() / (1.0 + numeric.norm()) < 1e-6, "case {k}, {what}:\n{analytic}\nvs\n{numeric}");
                };
                close("dF/da", &d.force, &fa);
                close("da'/dp", &d.next_d_position, &ap);
                close("da'/dpdot", &d.next_d_velocity, &av);
                close("da'/da", &d.next_d_anchor, &aa);
            }
        }
    }

    #[test]
    fn the_cases_are_what_they_claim() {
        // The test above covers each branch: check that the cases reach them (with Table I's
        // contact; the calibrated one's stiffer spring slips in the damping case too).
        let params = crate::contact::table_i();
        let s = Surface { point: Vector3::zeros(), normal: Vector3::z() };
        let r = 0.02;
        let at = |depth: f64| Vector3::new(0.0, 0.0, r - depth);
        let stick = contact_force(&params, r, &at(0.006), &Vector3::new(0.05, -0.02, -0.1), &s, Some(&Vector3::new(-0.001, 0.0, 0.0)));
        assert!(!stick.slipping && stick.normal_force > 0.0);
        let spring_slip = contact_force(&params, r, &at(0.012), &Vector3::new(0.1, 0.05, -0.05), &s, Some(&Vector3::new(-0.05, 0.03, 0.0)));
        assert!(spring_slip.slipping && spring_slip.tangential_offset.norm() * params.tangential_stiffness > params.friction * spring_slip.normal_force / params.profile(0.012).0);
        let damping_slip = contact_force(&params, r, &at(0.003), &Vector3::new(5.0, -1.0, 3.0), &s, Some(&Vector3::new(-0.0002, 0.0, 0.0)));
        let spring = damping_slip.tangential_offset.norm() * params.tangential_stiffness * params.profile(0.003).0;
        assert!(damping_slip.slipping && spring < params.friction * damping_slip.normal_force);
        let leaving = contact_force(&params, r, &at(0.01), &Vector3::new(0.2, 0.0, 6.0), &s, Some(&Vector3::new(-0.01, 0.0, 0.0)));
        assert!(leaving.slipping && leaving.normal_force == 0.0);
    }
}
