use super::{skew, Force, Matrix3, Matrix6, Motion, Vector3, SE3};
use std::ops::Add;

/// A rigid-body spatial inertia: mass, centre of mass `com` (in the body frame) and the
/// rotational inertia `inertia_com` about the centre of mass (in the body frame axes).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Inertia {
    pub mass: f64,
    pub com: Vector3<f64>,
    pub inertia_com: Matrix3<f64>,
}

/// Why a spatial inertia is not physical.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum InertiaError {
    #[error("mass must be finite and positive, got {0}")]
    Mass(f64),
    #[error("a value is not finite (NaN or infinite)")]
    NotFinite,
    #[error("rotational inertia is not symmetric")]
    NotSymmetric,
    #[error("rotational inertia is not positive definite (eigenvalues {0:?})")]
    NotPositiveDefinite([f64; 3]),
    #[error("rotational inertia violates the triangle inequality (eigenvalues {0:?})")]
    Triangle([f64; 3]),
}

impl Default for Inertia {
    fn default() -> Self {
        Self::zero()
    }
}

impl Inertia {
    /// A body with mass, centre of mass and rotational inertia about the centre of mass.
    /// No check: use [`Inertia::validated`] on user input.
    pub fn new(mass: f64, com: Vector3<f64>, inertia_com: Matrix3<f64>) -> Self {
        Self { mass, com, inertia_com }
    }
    /// Like [`Inertia::new`], but refuses a non-positive or non-finite mass and a rotational
    /// inertia that is not symmetric positive definite and physically realisable
    /// (principal moments obey the triangle inequality).
    pub fn validated(mass: f64, com: Vector3<f64>, inertia_com: Matrix3<f64>) -> Result<Self, InertiaError> {
        if !com.iter().chain(inertia_com.iter()).all(|x| x.is_finite()) || !mass.is_finite() {
            return Err(InertiaError::NotFinite);
        }
        if mass <= 0.0 {
            return Err(InertiaError::Mass(mass));
        }
        let scale = inertia_com.norm().max(f64::MIN_POSITIVE);
        if (inertia_com - inertia_com.transpose()).norm() > 1e-9 * scale {
            return Err(InertiaError::NotSymmetric);
        }
        let eig = nalgebra::SymmetricEigen::new(inertia_com).eigenvalues;
        let mut e = [eig[0], eig[1], eig[2]];
        e.sort_by(|a, b| a.total_cmp(b));
        if e[0] <= 0.0 {
            return Err(InertiaError::NotPositiveDefinite(e));
        }
        if e[0] + e[1] < e[2] * (1.0 - 1e-6) {
            return Err(InertiaError::Triangle(e));
        }
        Ok(Self { mass, com, inertia_com })
    }
    pub fn zero() -> Self {
        Self { mass: 0.0, com: Vector3::zeros(), inertia_com: Matrix3::zeros() }
    }
    /// Rotational inertia about the frame origin: `I_o = I_c - m [c]x [c]x`.
    #[inline]
    pub fn inertia_origin(&self) -> Matrix3<f64> {
        let c = skew(&self.com);
        self.inertia_com - c * c * self.mass
    }
    /// The 6x6 matrix `[m I, -m [c]x; m [c]x, I_c - m [c]x [c]x]` (linear first).
    pub fn matrix(&self) -> Matrix6 {
        let mut y = Matrix6::zeros();
        let c = skew(&self.com);
        let mc = c * self.mass;
        y[(0, 0)] = self.mass;
        y[(1, 1)] = self.mass;
        y[(2, 2)] = self.mass;
        y.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-mc));
        y.fixed_view_mut::<3, 3>(3, 0).copy_from(&mc);
        y.fixed_view_mut::<3, 3>(3, 3).copy_from(&(self.inertia_com - mc * c));
        y
    }
    /// Momentum of the body moving with twist `m`:
    /// `f = m (v - c x w)`, `n = I_c w + c x f`.
    #[inline]
    pub fn mul_motion(&self, m: &Motion) -> Force {
        let f = (m.v - self.com.cross(&m.w)) * self.mass;
        Force { f, n: self.inertia_com * m.w + self.com.cross(&f) }
    }
    /// The inertia expressed in frame `a`, given `aMb` and the inertia in `b`.
    #[inline]
    pub fn transformed(&self, a_m_b: &SE3) -> Inertia {
        let r = &a_m_b.rotation;
        Inertia { mass: self.mass, com: a_m_b.act_point(&self.com), inertia_com: rotate_symmetric(r, &self.inertia_com) }
    }
    /// Inverse of [`Inertia::transformed`]: the inertia in `b`, given `aMb` and the inertia in `a`.
    #[inline]
    pub fn transformed_inv(&self, a_m_b: &SE3) -> Inertia {
        let r = &a_m_b.rotation;
        Inertia {
            mass: self.mass,
            com: r.tr_mul(&(self.com - a_m_b.translation)),
            inertia_com: r.transpose() * self.inertia_com * r,
        }
    }
    /// Kinetic energy `1/2 m^T I m` of a twist.
    pub fn kinetic_energy(&self, m: &Motion) -> f64 {
        0.5 * m.dot(&self.mul_motion(m))
    }
    pub fn is_finite(&self) -> bool {
        self.mass.is_finite() && self.com.iter().chain(self.inertia_com.iter()).all(|x| x.is_finite())
    }
}

/// `R S R^T` for a symmetric `S`, computing the six distinct entries only.
#[inline]
pub(crate) fn rotate_symmetric(r: &Matrix3<f64>, s: &Matrix3<f64>) -> Matrix3<f64> {
    let a = r * s; // A = R S; (R S R^T)_ij = A_i . R_j
    let mut out = Matrix3::zeros();
    for i in 0..3 {
        for j in i..3 {
            let x = a[(i, 0)] * r[(j, 0)] + a[(i, 1)] * r[(j, 1)] + a[(i, 2)] * r[(j, 2)];
            out[(i, j)] = x;
            out[(j, i)] = x;
        }
    }
    out
}

/// Lumping two bodies expressed in the same frame (parallel-axis theorem).
impl Add for Inertia {
    type Output = Inertia;
    fn add(self, o: Inertia) -> Inertia {
        let m = self.mass + o.mass;
        if m <= 0.0 {
            return Inertia::zero();
        }
        let c = (self.com * self.mass + o.com * o.mass) / m;
        let d1 = skew(&(self.com - c));
        let d2 = skew(&(o.com - c));
        let i = self.inertia_com - d1 * d1 * self.mass + o.inertia_com - d2 * d2 * o.mass;
        Inertia { mass: m, com: c, inertia_com: i }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn matrix_matches_mul_motion_and_transform() {
        let i = Inertia::new(2.5, Vector3::new(0.1, -0.2, 0.3), Matrix3::new(0.3, 0.01, 0.02, 0.01, 0.4, 0.03, 0.02, 0.03, 0.5));
        let m = Motion::new(Vector3::new(0.3, 0.1, -0.7), Vector3::new(1.0, 2.0, -0.5));
        let f1 = i.mul_motion(&m).to_vector();
        let f2 = i.matrix() * m.to_vector();
        assert!((f1 - f2).norm() < 1e-13);
        let x = SE3::new(crate::spatial::exp3(&Vector3::new(0.2, 0.5, -0.3)), Vector3::new(0.4, -0.1, 0.9));
        let ya = x.act_inertia_matrix(&i.matrix());
        assert!((ya - i.transformed(&x).matrix()).norm() < 1e-12);
        let y_ref = x.dual_action_matrix() * i.matrix() * x.inverse().action_matrix();
        assert!((ya - y_ref).norm() < 1e-12);
        let back = i.transformed(&x).transformed_inv(&x);
        assert!((back.matrix() - i.matrix()).norm() < 1e-12);
    }
    #[test]
    fn lumping_preserves_momentum() {
        let a = Inertia::new(1.0, Vector3::new(0.1, 0.0, 0.0), Matrix3::identity() * 0.01);
        let b = Inertia::new(3.0, Vector3::new(0.0, 0.2, -0.1), Matrix3::identity() * 0.02);
        assert!(((a + b).matrix() - (a.matrix() + b.matrix())).norm() < 1e-13);
    }
    #[test]
    fn validation_refuses_unphysical() {
        assert!(Inertia::validated(0.0, Vector3::zeros(), Matrix3::identity()).is_err());
        assert!(Inertia::validated(1.0, Vector3::zeros(), -Matrix3::identity()).is_err());
        assert!(Inertia::validated(1.0, Vector3::new(f64::NAN, 0.0, 0.0), Matrix3::identity()).is_err());
        assert!(Inertia::validated(1.0, Vector3::zeros(), Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, 5.0))).is_err());
        assert!(Inertia::validated(1.0, Vector3::zeros(), Matrix3::identity()).is_ok());
    }
}

/// The same spatial inertia as [`Inertia`], stored as its mass moments about the frame
/// origin: mass `m`, first moment `h = m c` and second moment (rotational inertia about the
/// origin) `I_o = I_c - m [c]x [c]x`. As a 6x6 matrix: `[m I, -[h]x; [h]x, I_o]`.
///
/// Adding two bodies is a plain sum and moving to another frame costs one `R I R^T`, which
/// makes this the form of the composite (subtree) inertias inside CRBA and the derivative
/// algorithms.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InertiaMoments {
    pub mass: f64,
    pub first: Vector3<f64>,
    pub second: Matrix3<f64>,
}

impl InertiaMoments {
    pub fn zero() -> Self {
        Self { mass: 0.0, first: Vector3::zeros(), second: Matrix3::zeros() }
    }
    /// From (mass, centre of mass, inertia about the centre of mass).
    #[inline]
    pub fn from_inertia(i: &Inertia) -> Self {
        Self { mass: i.mass, first: i.com * i.mass, second: i.inertia_origin() }
    }
    /// Back to (mass, centre of mass, inertia about the centre of mass); zero mass gives zero.
    pub fn to_inertia(&self) -> Inertia {
        if self.mass <= 0.0 {
            return Inertia::zero();
        }
        let c = self.first / self.mass;
        let s = skew(&c);
        Inertia { mass: self.mass, com: c, inertia_com: self.second + s * s * self.mass }
    }
    /// The moments in frame `a`, given `aMb` and the moments in `b` (`r' = R r + p`):
    /// `h' = R h + m p`, `I' = R I R^T - [p]x [g]x - [g]x [p]x - m [p]x [p]x` with `g = R h`,
    /// which by `[a]x [b]x = b a^T - (a.b) I` is
    /// `I' = R I R^T - g p^T - p g^T - m p p^T + (2 p.g + m |p|^2) I`.
    #[inline]
    pub fn transformed(&self, a_m_b: &SE3) -> InertiaMoments {
        let r = &a_m_b.rotation;
        let p = &a_m_b.translation;
        let g = r * self.first;
        let m = self.mass;
        let mut second = rotate_symmetric(r, &self.second);
        let diag = 2.0 * p.dot(&g) + m * p.norm_squared();
        for i in 0..3 {
            for j in i..3 {
                let mut x = second[(i, j)] - g[i] * p[j] - p[i] * g[j] - m * p[i] * p[j];
                if i == j {
                    x += diag;
                }
                second[(i, j)] = x;
                second[(j, i)] = x;
            }
        }
        InertiaMoments { mass: m, first: g + p * m, second }
    }
    /// Momentum of a twist: `f = m v - h x w`, `n = h x v + I_o w`.
    #[inline]
    pub fn mul_motion(&self, m: &Motion) -> Force {
        Force { f: m.v * self.mass - self.first.cross(&m.w), n: self.first.cross(&m.v) + self.second * m.w }
    }
    /// The 6x6 matrix `[m I, -[h]x; [h]x, I_o]`.
    pub fn matrix(&self) -> Matrix6 {
        let mut y = Matrix6::zeros();
        let h = skew(&self.first);
        y[(0, 0)] = self.mass;
        y[(1, 1)] = self.mass;
        y[(2, 2)] = self.mass;
        y.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-h));
        y.fixed_view_mut::<3, 3>(3, 0).copy_from(&h);
        y.fixed_view_mut::<3, 3>(3, 3).copy_from(&self.second);
        y
    }
}

impl Add for InertiaMoments {
    type Output = InertiaMoments;
    #[inline]
    fn add(self, o: InertiaMoments) -> InertiaMoments {
        InertiaMoments { mass: self.mass + o.mass, first: self.first + o.first, second: self.second + o.second }
    }
}

impl std::ops::AddAssign for InertiaMoments {
    #[inline]
    fn add_assign(&mut self, o: InertiaMoments) {
        self.mass += o.mass;
        self.first += o.first;
        self.second += o.second;
    }
}

#[cfg(test)]
mod moments_tests {
    use super::*;
    #[test]
    fn moments_agree_with_inertia() {
        let i = Inertia::new(2.5, Vector3::new(0.1, -0.2, 0.3), Matrix3::new(0.3, 0.01, 0.02, 0.01, 0.4, 0.03, 0.02, 0.03, 0.5));
        let m = InertiaMoments::from_inertia(&i);
        assert!((m.matrix() - i.matrix()).norm() < 1e-13);
        let x = SE3::new(crate::spatial::exp3(&Vector3::new(0.2, 0.5, -0.3)), Vector3::new(0.4, -0.1, 0.9));
        assert!((m.transformed(&x).matrix() - i.transformed(&x).matrix()).norm() < 1e-12);
        let tw = Motion::new(Vector3::new(0.3, 0.1, -0.7), Vector3::new(1.0, 2.0, -0.5));
        assert!((m.mul_motion(&tw).to_vector() - i.mul_motion(&tw).to_vector()).norm() < 1e-13);
        assert!((m.to_inertia().matrix() - i.matrix()).norm() < 1e-12);
        let j = Inertia::new(1.0, Vector3::new(0.0, 0.4, 0.0), Matrix3::identity() * 0.1);
        let sum = m + InertiaMoments::from_inertia(&j);
        assert!((sum.matrix() - (i + j).matrix()).norm() < 1e-12);
    }
}
