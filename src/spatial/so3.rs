//! Exponential and logarithm maps of SO(3) and SE(3) (Murray, Li & Sastry 1994, ch. 2;
//! Sola et al. 2018, "A micro Lie theory", appendices), with Taylor expansions near zero.

use super::{Matrix3, Matrix6, Motion, Vector3, SE3};

/// The skew-symmetric matrix `[v]x` with `[v]x u = v x u`.
#[inline]
pub fn skew(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// Rodrigues: `Exp(w) = I + sin(t)/t [w]x + (1 - cos t)/t^2 [w]x^2`, `t = |w|`.
pub fn exp3(w: &Vector3<f64>) -> Matrix3<f64> {
    let t2 = w.norm_squared();
    let (a, b) = if t2 < 1e-8 {
        (1.0 - t2 / 6.0 + t2 * t2 / 120.0, 0.5 - t2 / 24.0 + t2 * t2 / 720.0)
    } else {
        let t = t2.sqrt();
        (t.sin() / t, (1.0 - t.cos()) / t2)
    };
    let s = skew(w);
    Matrix3::identity() + s * a + s * s * b
}

/// `Log(R)`: the rotation vector `w` with `Exp(w) = R`, `|w| <= pi`.
///
/// `theta = atan2(|vee(R - R^T)| / 2, (tr R - 1) / 2)` keeps full precision near zero
/// (where `acos` of the trace loses half the digits); near `pi` the axis comes from the
/// symmetric part `(R + R^T)/2 - cos(theta) I = (1 - cos theta) a a^T`.
pub fn log3(r: &Matrix3<f64>) -> Vector3<f64> {
    let v = Vector3::new(r[(2, 1)] - r[(1, 2)], r[(0, 2)] - r[(2, 0)], r[(1, 0)] - r[(0, 1)]) * 0.5;
    let cos = ((r.trace() - 1.0) * 0.5).clamp(-1.0, 1.0);
    let sin = v.norm();
    let theta = sin.atan2(cos);
    if cos > -0.9 {
        // theta / sin(theta), with its Taylor series near zero
        let k = if sin < 1e-8 { 1.0 + sin * sin / 6.0 } else { theta / sin };
        return v * k;
    }
    let b = (r + r.transpose()) * 0.5 - Matrix3::identity() * cos;
    let (mut best, mut big) = (0, b[(0, 0)]);
    for i in 1..3 {
        if b[(i, i)] > big {
            best = i;
            big = b[(i, i)];
        }
    }
    let mut axis = b.column(best).into_owned() / big.max(f64::MIN_POSITIVE).sqrt();
    axis /= axis.norm();
    if axis.dot(&v) < 0.0 {
        axis = -axis;
    }
    axis * theta
}

/// Right Jacobian of `Exp` on SO(3): `Exp(w + dw) = Exp(w) Exp(Jr(w) dw)` to first order.
pub fn jexp3(w: &Vector3<f64>) -> Matrix3<f64> {
    let t2 = w.norm_squared();
    let (a, b) = if t2 < 1e-8 {
        (0.5 - t2 / 24.0, 1.0 / 6.0 - t2 / 120.0)
    } else {
        let t = t2.sqrt();
        ((1.0 - t.cos()) / t2, (t - t.sin()) / (t2 * t))
    };
    let s = skew(w);
    Matrix3::identity() - s * a + s * s * b
}

/// Inverse of [`jexp3`]: `Log(Exp(w) Exp(dw)) = w + Jr^-1(w) dw` to first order.
pub fn jlog3(w: &Vector3<f64>) -> Matrix3<f64> {
    let t2 = w.norm_squared();
    let c = if t2 < 1e-8 {
        1.0 / 12.0 + t2 / 720.0
    } else {
        let t = t2.sqrt();
        1.0 / t2 - (1.0 + t.cos()) / (2.0 * t * t.sin())
    };
    let s = skew(w);
    Matrix3::identity() + s * 0.5 + s * s * c
}

/// SE(3) exponential of a twist `[v; w]` (linear first):
/// `R = Exp(w)`, `p = V(w) v` with `V = I + (1 - cos t)/t^2 [w]x + (t - sin t)/t^3 [w]x^2`.
pub fn exp6(m: &Motion) -> SE3 {
    let w = &m.w;
    let t2 = w.norm_squared();
    let (b, c) = if t2 < 1e-8 {
        (0.5 - t2 / 24.0, 1.0 / 6.0 - t2 / 120.0)
    } else {
        let t = t2.sqrt();
        ((1.0 - t.cos()) / t2, (t - t.sin()) / (t2 * t))
    };
    let s = skew(w);
    let v_mat = Matrix3::identity() + s * b + s * s * c;
    SE3::new(exp3(w), v_mat * m.v)
}

/// Right Jacobian of `Exp` on SE(3) for a twist `[v; w]` (linear first, as [`exp6`]):
/// `exp6(m + dm) = exp6(m) exp6(Jr(m) dm)` to first order.
///
/// `Jr(v, w) = Jl(-v, -w)`, `Jl = [[Jl3(w), Q(v, w)], [0, Jl3(w)]]` with (Barfoot & Furgale
/// 2014, eq. 102; `t = |w|`, `V = [v]x`, `W = [w]x`)
///
/// ```text
/// Q = V/2 + (t - sin t)/t^3 (W V + V W + W V W)
///         + (t^2 + 2 cos t - 2)/(2 t^4) (W W V + V W W - 3 W V W)
///         + (2 t - 3 sin t + t cos t)/(2 t^5) (W V W W + W W V W)
/// ```
///
/// The three coefficients are evaluated by their Taylor series below `t = 0.1`, where the
/// closed forms cancel catastrophically.
pub fn jexp6(m: &Motion) -> Matrix6 {
    let v = -m.v;
    let w = -m.w;
    let t2 = w.norm_squared();
    let (c1, c2, c3) = if t2 < 1e-2 {
        (
            1.0 / 6.0 - t2 / 120.0 + t2 * t2 / 5040.0,
            1.0 / 24.0 - t2 / 720.0 + t2 * t2 / 40320.0,
            1.0 / 120.0 - t2 / 2520.0 + t2 * t2 / 120960.0,
        )
    } else {
        let t = t2.sqrt();
        let (s, c) = t.sin_cos();
        ((t - s) / (t2 * t), (t2 + 2.0 * c - 2.0) / (2.0 * t2 * t2), (2.0 * t - 3.0 * s + t * c) / (2.0 * t2 * t2 * t))
    };
    let vv = skew(&v);
    let ww = skew(&w);
    let wvw = ww * vv * ww;
    let q = vv * 0.5 + (ww * vv + vv * ww + wvw) * c1 + (ww * ww * vv + vv * ww * ww - wvw * 3.0) * c2 + (wvw * ww + ww * wvw) * c3;
    // Jl3(-w) = Jr3(w).
    let jr3 = jexp3(&m.w);
    let mut out = Matrix6::zeros();
    out.fixed_view_mut::<3, 3>(0, 0).copy_from(&jr3);
    out.fixed_view_mut::<3, 3>(3, 3).copy_from(&jr3);
    out.fixed_view_mut::<3, 3>(0, 3).copy_from(&q);
    out
}

/// SE(3) logarithm: the twist `[v; w]` with `exp6(twist) = M`.
pub fn log6(m: &SE3) -> Motion {
    let w = log3(&m.rotation);
    let t2 = w.norm_squared();
    // V^-1 = I - 1/2 [w]x + (1/t^2) (1 - t sin t / (2 (1 - cos t))) [w]x^2
    let c = if t2 < 1e-8 {
        1.0 / 12.0 + t2 / 720.0
    } else {
        let t = t2.sqrt();
        (1.0 - t * t.sin() / (2.0 * (1.0 - t.cos()))) / t2
    };
    let s = skew(&w);
    let v_inv = Matrix3::identity() - s * 0.5 + s * s * c;
    Motion::new(v_inv * m.translation, w)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spatial::Vector6;

    #[test]
    fn exp_log_roundtrip() {
        for w in [
            Vector3::new(0.3, -1.2, 0.5),
            Vector3::new(1e-6, 0.0, 2e-6),
            Vector3::new(0.0, 3.0, 0.0),
            Vector3::new(1.0, -2.0, 2.0) * (std::f64::consts::PI - 1e-7) / 3.0,
            Vector3::new(0.0, 0.0, 1e-12),
        ] {
            let r = exp3(&w);
            assert!((r.transpose() * r - Matrix3::identity()).norm() < 1e-14);
            assert!((log3(&r) - w).norm() < 1e-12, "{w}");
            let m = Motion::new(Vector3::new(0.1, 0.7, -0.4), w);
            let back = log6(&exp6(&m));
            assert!((back.to_vector() - m.to_vector()).norm() < 1e-11);
        }
    }

    #[test]
    fn se3_right_jacobian_matches_finite_differences() {
        let h = 1e-6;
        for m in [
            Motion::new(Vector3::new(0.3, -0.2, 0.5), Vector3::new(0.4, -0.9, 0.3)),
            Motion::new(Vector3::new(-1.0, 0.4, 0.2), Vector3::new(0.01, 0.03, -0.02)), // series branch
            Motion::new(Vector3::new(0.5, 0.1, -0.3), Vector3::new(0.0, 0.0, 0.0)),
        ] {
            let jr = jexp6(&m);
            let base_inv = exp6(&m).inverse();
            for k in 0..6 {
                let mut d = Vector6::zeros();
                d[k] = h;
                let plus = log6(&(base_inv * exp6(&Motion::from_vector(&(m.to_vector() + d))))).to_vector();
                let minus = log6(&(base_inv * exp6(&Motion::from_vector(&(m.to_vector() - d))))).to_vector();
                let col = (plus - minus) / (2.0 * h);
                assert!((col - jr.column(k)).norm() < 1e-8, "column {k} of Jr({m:?}): {col} vs {}", jr.column(k));
            }
        }
    }

    #[test]
    fn right_jacobian_matches_finite_differences() {
        let w = Vector3::new(0.4, -0.9, 0.3);
        let jr = jexp3(&w);
        let h = 1e-6;
        for k in 0..3 {
            let mut d = Vector3::zeros();
            d[k] = h;
            // central difference: Log(Exp(w)^T Exp(w +- d)) = +- Jr d + O(h^2)
            let plus = log3(&(exp3(&w).transpose() * exp3(&(w + d))));
            let minus = log3(&(exp3(&w).transpose() * exp3(&(w - d))));
            let col = (plus - minus) / (2.0 * h);
            assert!((col - jr.column(k)).norm() < 1e-8, "column {k}: {col} vs {}", jr.column(k));
        }
        assert!((jlog3(&w) * jr - Matrix3::identity()).norm() < 1e-12);
    }
}
