use super::{skew, Force, Matrix3, Matrix6, Motion, Vector3};
use nalgebra::{Quaternion, UnitQuaternion};
use std::ops::Mul;

/// A rigid transform `aMb`: rotation `rotation` (`R_ab`) and translation `translation`
/// (origin of `b` in `a`). Maps `b` coordinates into `a` coordinates: `p_a = R p_b + t`.
///
/// ```
/// use legwork::spatial::{SE3, Motion};
/// use nalgebra::{Matrix3, Vector3};
/// let m = SE3::new(Matrix3::identity(), Vector3::new(0.0, 0.0, 1.0));
/// // A pure rotation about z, seen from a frame one metre above, gains linear velocity.
/// let w = Motion::new(Vector3::zeros(), Vector3::new(1.0, 0.0, 0.0));
/// let w_a = m.act(&w);
/// assert!((w_a.v - Vector3::new(0.0, 1.0, 0.0)).norm() < 1e-15);
/// assert!((m.act_inv(&w_a).to_vector() - w.to_vector()).norm() < 1e-15);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SE3 {
    pub rotation: Matrix3<f64>,
    pub translation: Vector3<f64>,
}

impl Default for SE3 {
    fn default() -> Self {
        Self::identity()
    }
}

impl SE3 {
    #[inline]
    pub fn new(rotation: Matrix3<f64>, translation: Vector3<f64>) -> Self {
        Self { rotation, translation }
    }
    #[inline]
    pub fn identity() -> Self {
        Self { rotation: Matrix3::identity(), translation: Vector3::zeros() }
    }
    /// From a translation and a unit quaternion given as `(x, y, z, w)` (Pinocchio's `q` layout).
    /// The quaternion is normalised here; callers validate it first.
    pub fn from_translation_quaternion(t: Vector3<f64>, x: f64, y: f64, z: f64, w: f64) -> Self {
        let uq = UnitQuaternion::from_quaternion(Quaternion::new(w, x, y, z));
        Self { rotation: uq.to_rotation_matrix().into_inner(), translation: t }
    }
    /// The unit quaternion `(x, y, z, w)` of the rotation, with `w >= 0`.
    pub fn quaternion_xyzw(&self) -> [f64; 4] {
        let r = nalgebra::Rotation3::from_matrix_unchecked(self.rotation);
        let q = UnitQuaternion::from_rotation_matrix(&r);
        let s = if q.w < 0.0 { -1.0 } else { 1.0 };
        [s * q.i, s * q.j, s * q.k, s * q.w]
    }
    /// Roll-pitch-yaw with fixed axes (URDF): `R = Rz(yaw) Ry(pitch) Rx(roll)`.
    pub fn from_rpy_xyz(rpy: [f64; 3], xyz: [f64; 3]) -> Self {
        Self { rotation: rpy_to_matrix(rpy), translation: Vector3::new(xyz[0], xyz[1], xyz[2]) }
    }
    #[inline]
    pub fn inverse(&self) -> SE3 {
        let rt = self.rotation.transpose();
        SE3 { rotation: rt, translation: -(rt * self.translation) }
    }
    /// `self.inverse() * other` without forming the inverse.
    #[inline]
    pub fn inv_mul(&self, other: &SE3) -> SE3 {
        let rt = self.rotation.transpose();
        SE3 { rotation: rt * other.rotation, translation: rt * (other.translation - self.translation) }
    }
    /// Point transform `R p + t`.
    #[inline]
    pub fn act_point(&self, p: &Vector3<f64>) -> Vector3<f64> {
        self.rotation * p + self.translation
    }
    /// Motion from `b` to `a`: `w_a = R w`, `v_a = R v + t x w_a`.
    #[inline]
    pub fn act(&self, m: &Motion) -> Motion {
        let w = self.rotation * m.w;
        Motion { v: self.rotation * m.v + self.translation.cross(&w), w }
    }
    /// Motion from `a` to `b`: `w = R^T w_a`, `v = R^T (v_a - t x w_a)`.
    #[inline]
    pub fn act_inv(&self, m: &Motion) -> Motion {
        Motion {
            v: self.rotation.tr_mul(&(m.v - self.translation.cross(&m.w))),
            w: self.rotation.tr_mul(&m.w),
        }
    }
    /// Force from `b` to `a`: `f_a = R f`, `n_a = R n + t x f_a`.
    #[inline]
    pub fn act_force(&self, f: &Force) -> Force {
        let fa = self.rotation * f.f;
        Force { f: fa, n: self.rotation * f.n + self.translation.cross(&fa) }
    }
    /// Force from `a` to `b`: `f = R^T f_a`, `n = R^T (n_a - t x f_a)`.
    #[inline]
    pub fn act_inv_force(&self, f: &Force) -> Force {
        Force {
            f: self.rotation.tr_mul(&f.f),
            n: self.rotation.tr_mul(&(f.n - self.translation.cross(&f.f))),
        }
    }
    /// The 6x6 motion action matrix `X = [R, [t]x R; 0, R]`.
    pub fn action_matrix(&self) -> Matrix6 {
        let mut x = Matrix6::zeros();
        let r = self.rotation;
        x.fixed_view_mut::<3, 3>(0, 0).copy_from(&r);
        x.fixed_view_mut::<3, 3>(3, 3).copy_from(&r);
        x.fixed_view_mut::<3, 3>(0, 3).copy_from(&(skew(&self.translation) * r));
        x
    }
    /// The 6x6 force action matrix `X* = [R, 0; [t]x R, R]` (= `X^-T`).
    pub fn dual_action_matrix(&self) -> Matrix6 {
        let mut x = Matrix6::zeros();
        let r = self.rotation;
        x.fixed_view_mut::<3, 3>(0, 0).copy_from(&r);
        x.fixed_view_mut::<3, 3>(3, 3).copy_from(&r);
        x.fixed_view_mut::<3, 3>(3, 0).copy_from(&(skew(&self.translation) * r));
        x
    }
    /// Congruence transform of a 6x6 spatial inertia-like symmetric matrix from `b` to `a`:
    /// `Y_a = X* Y X^-1`. With `Y = [A B; B^T C]`, `A' = R A R^T` (likewise B', C') and `P = [t]x`:
    ///
    /// `Y_a = [A', B' - A'P; (B' - A'P)^T, C' - B'^T P + P (B' - A'P)]`.
    ///
    /// This is the articulated-inertia step of ABA (Featherstone 2008, Table 7.1).
    #[inline]
    pub fn act_inertia_matrix(&self, y: &Matrix6) -> Matrix6 {
        let r = &self.rotation;
        let a = r * y.fixed_view::<3, 3>(0, 0) * r.transpose();
        let b = r * y.fixed_view::<3, 3>(0, 3) * r.transpose();
        let c = r * y.fixed_view::<3, 3>(3, 3) * r.transpose();
        let p = skew(&self.translation);
        let b2 = b - a * p; // B' - A'P
        let c2 = c - b.transpose() * p + p * b2;
        let mut out = Matrix6::zeros();
        out.fixed_view_mut::<3, 3>(0, 0).copy_from(&a);
        out.fixed_view_mut::<3, 3>(0, 3).copy_from(&b2);
        out.fixed_view_mut::<3, 3>(3, 0).copy_from(&b2.transpose());
        out.fixed_view_mut::<3, 3>(3, 3).copy_from(&c2);
        out
    }
    pub fn is_finite(&self) -> bool {
        self.rotation.iter().chain(self.translation.iter()).all(|x| x.is_finite())
    }
}

impl Mul for SE3 {
    type Output = SE3;
    #[inline]
    fn mul(self, o: SE3) -> SE3 {
        SE3 { rotation: self.rotation * o.rotation, translation: self.translation + self.rotation * o.translation }
    }
}
impl<'a> Mul<&'a SE3> for &'a SE3 {
    type Output = SE3;
    #[inline]
    fn mul(self, o: &SE3) -> SE3 {
        SE3 { rotation: self.rotation * o.rotation, translation: self.translation + self.rotation * o.translation }
    }
}

/// URDF fixed-axis roll-pitch-yaw: `R = Rz(yaw) Ry(pitch) Rx(roll)`.
pub fn rpy_to_matrix(rpy: [f64; 3]) -> Matrix3<f64> {
    let (sr, cr) = rpy[0].sin_cos();
    let (sp, cp) = rpy[1].sin_cos();
    let (sy, cy) = rpy[2].sin_cos();
    Matrix3::new(
        cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr,
        sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr,
        -sp, cp * sr, cp * cr,
    )
}
