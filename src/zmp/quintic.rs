//! The fifth-order polynomial of Winkler 2015, eq. (3), and the closed forms the QP is made
//! of: position, velocity, acceleration and cart-table ZMP (eq. 5) as linear functions of
//! the coefficients, and the integral of the squared acceleration (eq. 7).
//!
//! The QP's unknowns are the coefficients in normalized time `tau = t / T` of each spline
//! of duration `T`: `x(t) = sum_k alpha_k tau^k`. They relate to the paper's coefficients
//! (`x(t) = a t^5 + b t^4 + c t^3 + d t^2 + e t + f`, i.e. `c_k` of `t^k`) by
//! `c_k = alpha_k / T^k`. All `alpha_k` are lengths, whatever `T`; the paper's `c_5` of a
//! 0.2 s spline is 3,000 times its `alpha_5`, which the interior-point solver would see as a
//! badly scaled problem.

/// `x(t) = sum_k c_k t^k` on `[0, duration]`: one spline of eq. (3), `coefficients` in
/// ascending powers (`[f, e, d, c, b, a]` in the paper's letters).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Quintic {
    pub coefficients: [f64; 6],
}

impl Quintic {
    /// From normalized-time coefficients `alpha` (`x = sum alpha_k (t / T)^k`).
    pub fn from_normalized(alpha: &[f64], duration: f64) -> Self {
        let mut coefficients = [0.0; 6];
        let mut scale = 1.0;
        for k in 0..6 {
            coefficients[k] = alpha[k] * scale;
            scale /= duration;
        }
        Self { coefficients }
    }

    /// `x(t)` (Horner).
    pub fn position(&self, t: f64) -> f64 {
        self.coefficients.iter().rev().fold(0.0, |acc, c| acc * t + c)
    }

    /// `ẋ(t)`.
    pub fn velocity(&self, t: f64) -> f64 {
        (1..6).rev().fold(0.0, |acc, k| acc * t + k as f64 * self.coefficients[k])
    }

    /// `ẍ(t)`.
    pub fn acceleration(&self, t: f64) -> f64 {
        (2..6).rev().fold(0.0, |acc, k| acc * t + (k * (k - 1)) as f64 * self.coefficients[k])
    }

    /// `∫_0^T ẍ(t)^2 dt` in closed form: with `ẍ = sum_k k (k-1) c_k t^(k-2)`, each product
    /// of two terms integrates to `j (j-1) k (k-1) c_j c_k T^(j+k-3) / (j+k-3)`.
    pub fn squared_acceleration_integral(&self, duration: f64) -> f64 {
        let c = &self.coefficients;
        let mut sum = 0.0;
        for j in 2..6 {
            for k in 2..6 {
                let power = (j + k - 3) as i32;
                sum += ((j * (j - 1) * k * (k - 1)) as f64) * c[j] * c[k] * duration.powi(power) / power as f64;
            }
        }
        sum
    }
}

/// Row `r` with `x(tau T) = r · alpha`: `tau^k`.
pub fn position_row(tau: f64) -> [f64; 6] {
    let mut row = [0.0; 6];
    let mut power = 1.0;
    for entry in row.iter_mut() {
        *entry = power;
        power *= tau;
    }
    row
}

/// Row `r` with `ẋ(tau T) = r · alpha`: `k tau^(k-1) / T`.
pub fn velocity_row(tau: f64, duration: f64) -> [f64; 6] {
    let mut row = [0.0; 6];
    let mut power = 1.0 / duration;
    for (k, entry) in row.iter_mut().enumerate().skip(1) {
        *entry = k as f64 * power;
        power *= tau;
    }
    row
}

/// Row `r` with `ẍ(tau T) = r · alpha`: `k (k-1) tau^(k-2) / T^2`.
pub fn acceleration_row(tau: f64, duration: f64) -> [f64; 6] {
    let mut row = [0.0; 6];
    let mut power = 1.0 / (duration * duration);
    for (k, entry) in row.iter_mut().enumerate().skip(2) {
        *entry = (k * (k - 1)) as f64 * power;
        power *= tau;
    }
    row
}

/// Row `r` with `x_zmp(tau T) = r · alpha`: the cart-table ZMP of eq. (5),
/// `x_zmp = x_cog - z_cog ẍ_cog / (z̈_cog + g_0)`, with a constant CoG height (`z̈ = 0`).
pub fn zmp_row(tau: f64, duration: f64, cog_height: f64, gravity: f64) -> [f64; 6] {
    let position = position_row(tau);
    let acceleration = acceleration_row(tau, duration);
    let lever = cog_height / gravity;
    std::array::from_fn(|k| position[k] - lever * acceleration[k])
}

/// `G` with `∫_0^T ẍ(t)^2 dt = alpha^T G alpha` (eq. 7 for one spline and one axis): with
/// `ẍ = T^-2 sum_k k (k-1) alpha_k tau^(k-2)` and `dt = T dtau`,
/// `G_jk = j (j-1) k (k-1) / ((j+k-3) T^3)` for `j, k >= 2`, zero otherwise.
pub fn squared_acceleration_gram(duration: f64) -> [[f64; 6]; 6] {
    let mut gram = [[0.0; 6]; 6];
    let scale = 1.0 / duration.powi(3);
    for (j, row) in gram.iter_mut().enumerate().skip(2) {
        for (k, entry) in row.iter_mut().enumerate().skip(2) {
            *entry = ((j * (j - 1) * k * (k - 1)) as f64) / ((j + k - 3) as f64) * scale;
        }
    }
    gram
}

/// The quintic Hermite basis: `alpha = HERMITE_BASIS h` gives the normalized-time
/// coefficients (ascending powers of `tau`) of the quintic with boundary values
/// `h = (x(0), x'(0), x''(0), x(1), x'(1), x''(1))`, derivatives taken in `tau`; in time,
/// `h = (x_0, T v_0, T^2 a_0, x_1, T v_1, T^2 a_1)`. Column `i` holds the coefficients of the
/// basis polynomial that has boundary value `i` equal to one and the other five zero:
/// `1 - 10 tau^3 + 15 tau^4 - 6 tau^5`, `tau - 6 tau^3 + 8 tau^4 - 3 tau^5`,
/// `(tau^2 - 3 tau^3 + 3 tau^4 - tau^5) / 2`, `10 tau^3 - 15 tau^4 + 6 tau^5`,
/// `-4 tau^3 + 7 tau^4 - 3 tau^5`, `(tau^3 - 2 tau^4 + tau^5) / 2`. Splines written in these
/// boundary states meet eq. (4) by construction when neighbours share their junction state.
pub const HERMITE_BASIS: [[f64; 6]; 6] = [
    [1.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [0.0, 1.0, 0.0, 0.0, 0.0, 0.0],
    [0.0, 0.0, 0.5, 0.0, 0.0, 0.0],
    [-10.0, -6.0, -1.5, 10.0, -4.0, 0.5],
    [15.0, 8.0, 1.5, -15.0, 7.0, -1.0],
    [-6.0, -3.0, -0.5, 6.0, -3.0, 0.5],
];

/// Normalized-time coefficients `alpha = HERMITE_BASIS h` of the quintic with boundary
/// values `h` (see [`HERMITE_BASIS`]).
pub fn normalized_from_hermite(h: &[f64; 6]) -> [f64; 6] {
    std::array::from_fn(|k| HERMITE_BASIS[k].iter().zip(h).map(|(m, v)| m * v).sum())
}

/// A row over normalized-time coefficients (`value = row · alpha`, as [`position_row`] and
/// the others) rewritten over the boundary values: `value = (row HERMITE_BASIS) · h`.
pub fn hermite_row(row: &[f64; 6]) -> [f64; 6] {
    std::array::from_fn(|i| (0..6).map(|k| row[k] * HERMITE_BASIS[k][i]).sum())
}

/// `K` with `∫_0^T ẍ(t)^2 dt = h^T K h` over the boundary values `h` (see
/// [`HERMITE_BASIS`]): `K = M^T G M` with `M = HERMITE_BASIS` and `G` of
/// [`squared_acceleration_gram`], `1 / T^3` times the exact rational matrix below (worked out
/// by hand from the basis polynomials; the tests compare it with `M^T G M` and quadrature).
/// Its top-left entry is the rest-to-rest cost `120 / (7 T^3)` per squared metre.
pub fn hermite_squared_acceleration_gram(duration: f64) -> [[f64; 6]; 6] {
    const UNIT: [[f64; 6]; 6] = [
        [120.0 / 7.0, 60.0 / 7.0, 3.0 / 7.0, -120.0 / 7.0, 60.0 / 7.0, -3.0 / 7.0],
        [60.0 / 7.0, 192.0 / 35.0, 11.0 / 35.0, -60.0 / 7.0, 108.0 / 35.0, -4.0 / 35.0],
        [3.0 / 7.0, 11.0 / 35.0, 3.0 / 35.0, -3.0 / 7.0, 4.0 / 35.0, 1.0 / 70.0],
        [-120.0 / 7.0, -60.0 / 7.0, -3.0 / 7.0, 120.0 / 7.0, -60.0 / 7.0, 3.0 / 7.0],
        [60.0 / 7.0, 108.0 / 35.0, 4.0 / 35.0, -60.0 / 7.0, 192.0 / 35.0, -11.0 / 35.0],
        [-3.0 / 7.0, -4.0 / 35.0, 1.0 / 70.0, 3.0 / 7.0, -11.0 / 35.0, 3.0 / 35.0],
    ];
    let scale = 1.0 / duration.powi(3);
    UNIT.map(|row| row.map(|entry| entry * scale))
}

/// 8-point Gauss-Legendre nodes and weights on [-1, 1] (exact for degree 15): the reference
/// quadrature of the tests.
#[cfg(test)]
pub(crate) const GAUSS_LEGENDRE_8: [(f64, f64); 8] = [
    (-0.960_289_856_497_536_2, 0.101_228_536_290_376_26),
    (-0.796_666_477_413_626_7, 0.222_381_034_453_374_47),
    (-0.525_532_409_916_329, 0.313_706_645_877_887_3),
    (-0.183_434_642_495_649_8, 0.362_683_783_378_362),
    (0.183_434_642_495_649_8, 0.362_683_783_378_362),
    (0.525_532_409_916_329, 0.313_706_645_877_887_3),
    (0.796_666_477_413_626_7, 0.222_381_034_453_374_47),
    (0.960_289_856_497_536_2, 0.101_228_536_290_376_26),
];

#[cfg(test)]
mod tests {
    use super::*;

    fn dot(a: &[f64; 6], b: &[f64]) -> f64 {
        a.iter().zip(b).map(|(x, y)| x * y).sum()
    }

    const ALPHA: [f64; 6] = [0.3, -0.7, 1.1, 0.4, -2.0, 0.9];

    /// The rows agree with the paper-form polynomial and its derivatives (Horner), which
    /// agree with central differences of the position.
    #[test]
    fn rows_match_polynomial_and_finite_differences() {
        let duration = 0.35;
        let poly = Quintic::from_normalized(&ALPHA, duration);
        for tau in [0.0, 0.2, 0.5, 0.77, 1.0] {
            let t = tau * duration;
            assert!((dot(&position_row(tau), &ALPHA) - poly.position(t)).abs() < 1e-14);
            assert!((dot(&velocity_row(tau, duration), &ALPHA) - poly.velocity(t)).abs() < 1e-12);
            assert!((dot(&acceleration_row(tau, duration), &ALPHA) - poly.acceleration(t)).abs() < 1e-10);
            let h = 1e-4;
            let fd_v = (poly.position(t + h) - poly.position(t - h)) / (2.0 * h);
            let fd_a = (poly.velocity(t + h) - poly.velocity(t - h)) / (2.0 * h);
            assert!((fd_v - poly.velocity(t)).abs() < 1e-6, "{fd_v} {}", poly.velocity(t));
            assert!((fd_a - poly.acceleration(t)).abs() < 1e-5);
            let (height, g) = (0.6, 9.81);
            let zmp = poly.position(t) - height / g * poly.acceleration(t);
            assert!((dot(&zmp_row(tau, duration, height, g), &ALPHA) - zmp).abs() < 1e-12);
        }
    }

    /// The Gram matrix and the paper-form closed form both equal Gauss-Legendre quadrature of
    /// `ẍ^2` (exact: degree 6).
    #[test]
    fn squared_acceleration_integral_matches_quadrature() {
        let duration = 0.45;
        let poly = Quintic::from_normalized(&ALPHA, duration);
        let quadrature: f64 = GAUSS_LEGENDRE_8
            .iter()
            .map(|(node, weight)| {
                let t = 0.5 * duration * (node + 1.0);
                0.5 * duration * weight * poly.acceleration(t).powi(2)
            })
            .sum();
        let gram = squared_acceleration_gram(duration);
        let quadratic: f64 = (0..6).map(|j| (0..6).map(|k| ALPHA[j] * gram[j][k] * ALPHA[k]).sum::<f64>()).sum();
        assert!((quadratic - quadrature).abs() < 1e-10 * quadrature, "{quadratic} {quadrature}");
        assert!((poly.squared_acceleration_integral(duration) - quadrature).abs() < 1e-10 * quadrature);
    }

    const BOUNDARY: [f64; 6] = [0.2, -0.4, 0.9, 0.5, 0.3, -1.3];

    /// The Hermite basis takes each boundary value to itself: position, first and second
    /// derivative in `tau` at both ends of the quintic built from them.
    #[test]
    fn hermite_basis_reproduces_boundary_values() {
        let alpha = normalized_from_hermite(&BOUNDARY);
        for (end, tau) in [(0, 0.0), (3, 1.0)] {
            assert!((dot(&position_row(tau), &alpha) - BOUNDARY[end]).abs() < 1e-14);
            assert!((dot(&velocity_row(tau, 1.0), &alpha) - BOUNDARY[end + 1]).abs() < 1e-14);
            assert!((dot(&acceleration_row(tau, 1.0), &alpha) - BOUNDARY[end + 2]).abs() < 1e-13);
        }
        // In time: h = (x0, T v0, T^2 a0, ...) gives v0 and a0 back.
        let duration = 0.35;
        let poly = Quintic::from_normalized(&alpha, duration);
        assert!((poly.velocity(0.0) * duration - BOUNDARY[1]).abs() < 1e-14);
        assert!((poly.acceleration(duration) * duration * duration - BOUNDARY[5]).abs() < 1e-12);
    }

    /// A row rewritten over the boundary values gives the same value; the Hermite Gram
    /// matrix gives the closed-form `ẍ^2` integral of the quintic with these boundary values
    /// (itself checked against quadrature above) and equals `M^T G M`.
    #[test]
    fn hermite_row_and_gram_match_coefficient_form() {
        let duration = 0.45;
        let alpha = normalized_from_hermite(&BOUNDARY);
        let zmp = zmp_row(0.3, duration, 0.6, 9.81);
        assert!((dot(&hermite_row(&zmp), &BOUNDARY) - dot(&zmp, &alpha)).abs() < 1e-13);
        let poly = Quintic::from_normalized(&alpha, duration);
        let gram = hermite_squared_acceleration_gram(duration);
        let quadratic: f64 =
            (0..6).map(|j| (0..6).map(|k| BOUNDARY[j] * gram[j][k] * BOUNDARY[k]).sum::<f64>()).sum();
        let expected = poly.squared_acceleration_integral(duration);
        assert!((quadratic - expected).abs() < 1e-12 * expected, "{quadratic} {expected}");
        // K = M^T G M entry by entry.
        let coefficient_gram = squared_acceleration_gram(duration);
        for i in 0..6 {
            for l in 0..6 {
                let product: f64 = (0..6)
                    .map(|a| (0..6).map(|b| HERMITE_BASIS[a][i] * coefficient_gram[a][b] * HERMITE_BASIS[b][l]).sum::<f64>())
                    .sum();
                assert!((gram[i][l] - product).abs() < 1e-12 * gram[0][0], "K[{i}][{l}]: {} vs {product}", gram[i][l]);
            }
        }
    }

    /// Hand computation: the rest-to-rest quintic `Δ (10 tau^3 - 15 tau^4 + 6 tau^5)` has
    /// `ẍ = 60 Δ / T^2 (tau - 3 tau^2 + 2 tau^3)` and `∫ (tau - 3 tau^2 + 2 tau^3)^2 dtau =
    /// 1/3 - 6/4 + 13/5 - 12/6 + 4/7 = 1/210`, so `∫ ẍ^2 dt = 3600 Δ^2 / (210 T^3) =
    /// 120 Δ^2 / (7 T^3)`.
    #[test]
    fn rest_to_rest_quintic_cost_by_hand() {
        let (delta, duration) = (0.3, 0.8);
        let alpha = [0.0, 0.0, 0.0, 10.0 * delta, -15.0 * delta, 6.0 * delta];
        let poly = Quintic::from_normalized(&alpha, duration);
        let expected = 120.0 * delta * delta / (7.0 * duration.powi(3));
        assert!((poly.squared_acceleration_integral(duration) - expected).abs() < 1e-12);
        assert!((poly.position(duration) - delta).abs() < 1e-14);
        assert!(poly.velocity(duration).abs() < 1e-13 && poly.acceleration(duration).abs() < 1e-12);
    }
}
