use super::{Force, Vector3, Vector6};
use std::ops::{Add, AddAssign, Mul, Neg, Sub, SubAssign};

/// A spatial motion vector (twist or spatial acceleration): linear part `v`, angular part `w`.
///
/// ```
/// use legwork::spatial::Motion;
/// use nalgebra::Vector3;
/// let a = Motion::new(Vector3::new(1.0, 0.0, 0.0), Vector3::new(0.0, 0.0, 1.0));
/// // [w]x v + [v]x w ... the motion cross product of a with itself vanishes.
/// assert!(a.cross(&a).to_vector().norm() < 1e-15);
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Motion {
    /// Linear part.
    pub v: Vector3<f64>,
    /// Angular part.
    pub w: Vector3<f64>,
}

impl Motion {
    #[inline]
    pub fn new(v: Vector3<f64>, w: Vector3<f64>) -> Self {
        Self { v, w }
    }
    #[inline]
    pub fn zero() -> Self {
        Self { v: Vector3::zeros(), w: Vector3::zeros() }
    }
    #[inline]
    pub fn from_vector(x: &Vector6) -> Self {
        Self { v: Vector3::new(x[0], x[1], x[2]), w: Vector3::new(x[3], x[4], x[5]) }
    }
    #[inline]
    pub fn from_slice(x: &[f64]) -> Self {
        Self { v: Vector3::new(x[0], x[1], x[2]), w: Vector3::new(x[3], x[4], x[5]) }
    }
    #[inline]
    pub fn to_vector(&self) -> Vector6 {
        Vector6::new(self.v.x, self.v.y, self.v.z, self.w.x, self.w.y, self.w.z)
    }
    /// Motion cross product `self x m` (Featherstone's `crm(self) m`):
    /// `[w x m.v + v x m.w ; w x m.w]`.
    #[inline]
    pub fn cross(&self, m: &Motion) -> Motion {
        Motion { v: self.w.cross(&m.v) + self.v.cross(&m.w), w: self.w.cross(&m.w) }
    }
    /// Force cross product `self x* f` (Featherstone's `crf(self) f`):
    /// `[w x f.f ; w x f.n + v x f.f]`.
    #[inline]
    pub fn cross_force(&self, f: &Force) -> Force {
        Force { f: self.w.cross(&f.f), n: self.w.cross(&f.n) + self.v.cross(&f.f) }
    }
    /// Power `v . f`.
    #[inline]
    pub fn dot(&self, f: &Force) -> f64 {
        self.v.dot(&f.f) + self.w.dot(&f.n)
    }
    #[inline]
    pub fn is_finite(&self) -> bool {
        self.v.iter().chain(self.w.iter()).all(|x| x.is_finite())
    }
}

impl Add for Motion {
    type Output = Motion;
    #[inline]
    fn add(self, o: Motion) -> Motion {
        Motion { v: self.v + o.v, w: self.w + o.w }
    }
}
impl Sub for Motion {
    type Output = Motion;
    #[inline]
    fn sub(self, o: Motion) -> Motion {
        Motion { v: self.v - o.v, w: self.w - o.w }
    }
}
impl Neg for Motion {
    type Output = Motion;
    #[inline]
    fn neg(self) -> Motion {
        Motion { v: -self.v, w: -self.w }
    }
}
impl AddAssign for Motion {
    #[inline]
    fn add_assign(&mut self, o: Motion) {
        self.v += o.v;
        self.w += o.w;
    }
}
impl SubAssign for Motion {
    #[inline]
    fn sub_assign(&mut self, o: Motion) {
        self.v -= o.v;
        self.w -= o.w;
    }
}
impl Mul<f64> for Motion {
    type Output = Motion;
    #[inline]
    fn mul(self, s: f64) -> Motion {
        Motion { v: self.v * s, w: self.w * s }
    }
}
