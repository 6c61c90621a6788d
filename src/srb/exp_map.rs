//! The exponential map of SO(3) in Rodrigues' form `exp(hat(w)) = I + a(s) A + b(s) A^2`,
//! `A = hat(w)`, `s = |w|^2`, with its first and second derivatives in `w`: the SO(3) step
//! of Nguyen 2022, eq. (2i), `R_{k+1} = R_k exp(hat(Omega_k T_i / N_i))`.
//!
//! The paper's 4th-order Taylor polynomial `I + A + A^2/2 + A^3/6 + A^4/24` has the same form
//! (`A^3 = -s A` for a skew matrix): `a = 1 - s/6`, `b = 1/2 - s/24`. The exact map has
//! `a = sin(t)/t`, `b = (1 - cos t)/t^2` (`t = |w|`), evaluated by their power series in `s`
//! (entire functions; 30 terms are exact to round-off for `|w| < 2 pi`).

use nalgebra::{Matrix3, Vector3};

/// Which exponential the SO(3) step uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ExpMap {
    /// The exact exponential (orthonormal for any step).
    #[default]
    Exact,
    /// The paper's 4th-order Taylor polynomial (sec. II-B; what its CasADi code uses).
    Taylor4,
}

/// `a(s), a'(s), a''(s), b(s), b'(s), b''(s)`.
fn coefficients(map: ExpMap, s: f64) -> [f64; 6] {
    match map {
        ExpMap::Taylor4 => [1.0 - s / 6.0, -1.0 / 6.0, 0.0, 0.5 - s / 24.0, -1.0 / 24.0, 0.0],
        ExpMap::Exact => {
            // a = sum (-s)^n / (2n+1)!, b = sum (-s)^n / (2n+2)!, and their s-derivatives.
            let mut c = [0.0; 6];
            let mut fa = 1.0; // 1/(2n+1)!
            let mut fb = 0.5; // 1/(2n+2)!
            let mut pow = [1.0, 0.0, 0.0]; // (-s)^n and the powers the derivatives need
            for n in 0..30usize {
                let nf = n as f64;
                let sn = pow[0]; // (-s)^n
                c[0] += sn * fa;
                c[3] += sn * fb;
                if n >= 1 {
                    // d/ds (-s)^n = -n (-s)^(n-1)
                    let d1 = -nf * pow[1];
                    c[1] += d1 * fa;
                    c[4] += d1 * fb;
                }
                if n >= 2 {
                    let d2 = nf * (nf - 1.0) * pow[2];
                    c[2] += d2 * fa;
                    c[5] += d2 * fb;
                }
                pow = [pow[0] * -s, pow[0], pow[1]];
                fa /= (2.0 * nf + 2.0) * (2.0 * nf + 3.0);
                fb /= (2.0 * nf + 3.0) * (2.0 * nf + 4.0);
            }
            c
        }
    }
}

/// `hat(w)`: `hat(w) v = w x v`.
pub fn hat(w: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -w[2], w[1], w[2], 0.0, -w[0], -w[1], w[0], 0.0)
}

/// The exponential, its derivatives `dE/dw_j` and `d2E/dw_i dw_j` at `w`.
#[derive(Clone, Debug)]
pub struct ExpDerivatives {
    pub value: Matrix3<f64>,
    pub first: [Matrix3<f64>; 3],
    /// `second[i][j]` (symmetric in `i`, `j`).
    pub second: [[Matrix3<f64>; 3]; 3],
}

/// `exp(hat(w))` alone.
pub fn exp(map: ExpMap, w: &Vector3<f64>) -> Matrix3<f64> {
    let s = w.norm_squared();
    let c = coefficients(map, s);
    let a = hat(w);
    Matrix3::identity() + a * c[0] + a * a * c[3]
}

/// `exp(hat(w))` and its first and second derivatives.
pub fn exp_derivatives(map: ExpMap, w: &Vector3<f64>) -> ExpDerivatives {
    let s = w.norm_squared();
    let [ca, ca1, ca2, cb, cb1, cb2] = coefficients(map, s);
    let a = hat(w);
    let a2 = a * a;
    let g = [hat(&Vector3::x()), hat(&Vector3::y()), hat(&Vector3::z())];
    let d1 = a * ca1 + a2 * cb1; // a' A + b' A^2
    let d2 = a * ca2 + a2 * cb2; // a'' A + b'' A^2
    let sym = |i: usize| g[i] * a + a * g[i]; // d(A^2)/dw_i
    let first: [Matrix3<f64>; 3] = std::array::from_fn(|i| d1 * (2.0 * w[i]) + g[i] * ca + sym(i) * cb);
    let second: [[Matrix3<f64>; 3]; 3] = std::array::from_fn(|i| {
        std::array::from_fn(|j| {
            let mut m = d2 * (4.0 * w[i] * w[j]) + (g[j] * ca1 + sym(j) * cb1) * (2.0 * w[i]) + (g[i] * ca1 + sym(i) * cb1) * (2.0 * w[j]) + (g[i] * g[j] + g[j] * g[i]) * cb;
            if i == j {
                m += d1 * 2.0;
            }
            m
        })
    });
    ExpDerivatives { value: Matrix3::identity() + a * ca + a2 * cb, first, second }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_map_is_rodrigues_and_orthonormal() {
        let w = Vector3::new(0.3, -1.1, 2.0);
        let t: f64 = w.norm();
        let k = hat(&(w / t));
        let rodrigues = Matrix3::identity() + k * t.sin() + k * k * (1.0 - t.cos());
        let e = exp(ExpMap::Exact, &w);
        assert!((e - rodrigues).amax() < 1e-14);
        assert!((e.transpose() * e - Matrix3::identity()).amax() < 1e-14);
    }

    #[test]
    fn taylor4_is_the_polynomial() {
        let w: Vector3<f64> = Vector3::new(0.2, 0.1, -0.3);
        let a = hat(&w);
        let p = Matrix3::identity() + a + a * a / 2.0 + a * a * a / 6.0 + a * a * a * a / 24.0;
        assert!((exp(ExpMap::Taylor4, &w) - p).amax() < 1e-15);
    }

    #[test]
    fn derivatives_match_finite_differences() {
        for map in [ExpMap::Exact, ExpMap::Taylor4] {
            for w in [Vector3::<f64>::new(0.4, -0.7, 0.25), Vector3::new(1e-9, 0.0, 0.0), Vector3::zeros()] {
                let d = exp_derivatives(map, &w);
                let h = 1e-6;
                for j in 0..3 {
                    let mut wp = w;
                    wp[j] += h;
                    let mut wm = w;
                    wm[j] -= h;
                    let fd = (exp(map, &wp) - exp(map, &wm)) / (2.0 * h);
                    assert!((fd - d.first[j]).amax() < 1e-9, "{map:?} first {j}");
                    let dp = exp_derivatives(map, &wp);
                    let dm = exp_derivatives(map, &wm);
                    for i in 0..3 {
                        let fd2 = (dp.first[i] - dm.first[i]) / (2.0 * h);
                        assert!((fd2 - d.second[i][j]).amax() < 1e-8, "{map:?} second {i} {j}");
                    }
                }
            }
        }
    }
}
