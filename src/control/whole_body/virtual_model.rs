//! The virtual model of Winkler 2015, sec. V-A: virtual springs and dampers between the
//! trunk and its desired trajectory (eq. 9), turned into the 6D reference acceleration of
//! the body (eq. 10), and moved from the CoG to the base coordinates `vd[0..6]` of the
//! inverse dynamics (sec. V-B, the transform `bX_cog`).

use super::reference::BodyMotion;
use crate::control::BaseGains;
use crate::spatial::log3;
use nalgebra::{Matrix3, Vector3, Vector6};

/// The measured body, world frame: what eq. (9) compares with the plan.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BodyState {
    /// CoG `x_cog` (m) and its velocity (m/s).
    pub cog: Vector3<f64>,
    pub cog_velocity: Vector3<f64>,
    /// Base orientation `R_b` (base to world).
    pub orientation: Matrix3<f64>,
    /// Base angular velocity `w_b`, world axes (rad/s).
    pub angular_velocity: Vector3<f64>,
}

/// The composite rigid-body inertia `I_c` of the whole robot at its current configuration,
/// about the CoG in world axes: `[m I, 0; 0, I_G]` (block-diagonal about the CoG).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CompositeInertia {
    pub mass: f64,
    /// Rotational inertia about the CoG, world axes (kg m^2).
    pub rotational: Matrix3<f64>,
}

/// The virtual wrench of Winkler 2015, eq. (9), world frame, about the CoG:
///
/// ```text
/// F_vm = P_x (x_cog^d - x_cog) + D_x (xd_cog^d - xd_cog)
/// T_vm = P_th e(R_b^d R_b^T) + D_th (w_b^d - w_b)
/// ```
///
/// with `e(.)` the rotation vector of a rotation matrix ([`log3`]) and diagonal gains.
pub fn virtual_model_wrench(gains: &BaseGains, desired: &BodyMotion, body: &BodyState) -> (Vector3<f64>, Vector3<f64>) {
    let (p_x, d_x) = &gains.position;
    let (p_th, d_th) = &gains.orientation;
    let r_desired = desired.orientation.to_rotation_matrix().into_inner();
    let force = p_x.component_mul(&(desired.cog_position - body.cog)) + d_x.component_mul(&(desired.cog_velocity - body.cog_velocity));
    let torque =
        p_th.component_mul(&log3(&(r_desired * body.orientation.transpose()))) + d_th.component_mul(&(desired.angular_velocity - body.angular_velocity));
    (force, torque)
}

/// The 6D reference acceleration of Winkler 2015, eq. (10):
/// `xdd^ref = xdd^d + I_c^-1 W_vm`, i.e. `xdd_cog^ref = xdd_cog^d + F_vm / m` and
/// `wd_b^ref = wd_b^d + I_G^-1 T_vm` (about the CoG `I_c` is block-diagonal).
/// Returns `(xdd_cog^ref, wd_b^ref)`, world frame.
pub fn reference_acceleration(desired: &BodyMotion, force: &Vector3<f64>, torque: &Vector3<f64>, inertia: &CompositeInertia) -> (Vector3<f64>, Vector3<f64>) {
    let angular = inertia.rotational.cholesky().map(|c| c.solve(torque)).unwrap_or_else(Vector3::zeros);
    (desired.cog_acceleration + force / inertia.mass, desired.angular_acceleration + angular)
}

/// The base coordinates of the reference acceleration, `vd[0..6]` of the state's
/// convention (base-frame linear and angular parts), from the CoG acceleration: the
/// translational transform `bX_cog` of Winkler 2015, sec. V-B, which treats the CoG as a
/// point of the trunk at offset `r = x_cog - p_b` (world):
///
/// ```text
/// pdd_b = xdd_cog - wd x r - w x (w x r)                   (classical, world)
/// vd_lin = R^T pdd_b - w_b x v_lin,   vd_ang = R^T wd       (v_lin, w_b: base frame)
/// ```
///
/// The `- w_b x v_lin` term turns the classical acceleration into the derivative of the
/// base-frame velocity `v[0..3]` (the free-flyer convention, Pinocchio's).
pub fn base_acceleration(
    cog_acceleration: &Vector3<f64>,
    angular_acceleration: &Vector3<f64>,
    cog_offset: &Vector3<f64>,
    body: &BodyState,
    base_linear_velocity: &Vector3<f64>,
    base_angular_velocity: &Vector3<f64>,
) -> Vector6<f64> {
    let w = &body.angular_velocity;
    let r = cog_offset;
    let base = cog_acceleration - angular_acceleration.cross(r) - w.cross(&w.cross(r));
    let rt = body.orientation.transpose();
    let lin = rt * base - base_angular_velocity.cross(base_linear_velocity);
    let ang = rt * angular_acceleration;
    Vector6::new(lin.x, lin.y, lin.z, ang.x, ang.y, ang.z)
}

/// The desired base pose and velocity that put the CoG on its plan, the CoG held at its
/// current offset in the base frame (`r_b = R^T (x_cog - p_b)`):
/// `p_b^d = x_cog^d - R^d r_b`, `pd_b^d = xd_cog^d - w^d x (R^d r_b)`.
/// Returns `(p_b^d, pd_b^d)`, world frame.
pub fn desired_base(desired: &BodyMotion, cog_offset_in_base: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let r = desired.orientation * cog_offset_in_base;
    (desired.cog_position - r, desired.cog_velocity - desired.angular_velocity.cross(&r))
}
