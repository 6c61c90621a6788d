use super::{Vector3, Vector6};
use std::ops::{Add, AddAssign, Mul, Neg, Sub, SubAssign};

/// A spatial force (wrench): linear force `f`, moment `n` about the frame origin.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Force {
    /// Linear part.
    pub f: Vector3<f64>,
    /// Angular part (moment about the frame origin).
    pub n: Vector3<f64>,
}

impl Force {
    #[inline]
    pub fn new(f: Vector3<f64>, n: Vector3<f64>) -> Self {
        Self { f, n }
    }
    #[inline]
    pub fn zero() -> Self {
        Self { f: Vector3::zeros(), n: Vector3::zeros() }
    }
    #[inline]
    pub fn from_vector(x: &Vector6) -> Self {
        Self { f: Vector3::new(x[0], x[1], x[2]), n: Vector3::new(x[3], x[4], x[5]) }
    }
    #[inline]
    pub fn to_vector(&self) -> Vector6 {
        Vector6::new(self.f.x, self.f.y, self.f.z, self.n.x, self.n.y, self.n.z)
    }
    #[inline]
    pub fn is_finite(&self) -> bool {
        self.f.iter().chain(self.n.iter()).all(|x| x.is_finite())
    }
}

impl Add for Force {
    type Output = Force;
    #[inline]
    fn add(self, o: Force) -> Force {
        Force { f: self.f + o.f, n: self.n + o.n }
    }
}
impl Sub for Force {
    type Output = Force;
    #[inline]
    fn sub(self, o: Force) -> Force {
        Force { f: self.f - o.f, n: self.n - o.n }
    }
}
impl Neg for Force {
    type Output = Force;
    #[inline]
    fn neg(self) -> Force {
        Force { f: -self.f, n: -self.n }
    }
}
impl AddAssign for Force {
    #[inline]
    fn add_assign(&mut self, o: Force) {
        self.f += o.f;
        self.n += o.n;
    }
}
impl SubAssign for Force {
    #[inline]
    fn sub_assign(&mut self, o: Force) {
        self.f -= o.f;
        self.n -= o.n;
    }
}
impl Mul<f64> for Force {
    type Output = Force;
    #[inline]
    fn mul(self, s: f64) -> Force {
        Force { f: self.f * s, n: self.n * s }
    }
}
