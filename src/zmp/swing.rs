//! Swing-foot trajectory from lift-off to touch-down that clears the terrain in between.
//!
//! Winkler 2015 chooses the swing-leg trajectories "based mostly on the foothold heights"
//! (sec. IV-C, details in their \[1\]); this is legwork's version, built from the rest-to-rest
//! quintic `sigma(u) = 10 u^3 - 15 u^4 + 6 u^5` (zero velocity and acceleration at both ends),
//! so that the foot path is twice continuously differentiable and starts and ends at rest:
//!
//! * height: rises from the lift-off height to the apex `top + step_height` in the first half
//!   of the swing, comes down to the touch-down height in the second (both halves meet at
//!   the apex with zero vertical velocity and acceleration), where `top` is the highest of
//!   the two footholds and the terrain between them;
//! * horizontal: moves from lift-off to touch-down only while the foot is at least
//!   `clearance` above `top` (from the rise's crossing of `top + clearance` to the descent's),
//!   so that an edge anywhere between the footholds (a pallet's, a stone's) is cleared by at
//!   least `clearance`. On flat ground with zero clearance the foot moves horizontally
//!   during the whole swing.

use nalgebra::{Point3, Vector3};

/// Invalid swing input; names the field.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SwingError {
    #[error("swing trajectory: field `{field}`: expected {expected}, got {got}")]
    Invalid { field: &'static str, expected: &'static str, got: String },
}

/// Shape parameters of a swing (m).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SwingShape {
    /// Apex height above `top` (the highest of footholds and terrain in between).
    pub step_height: f64,
    /// Height above `top` the foot must have before (and keeps until after) it moves
    /// horizontally; less than `step_height`.
    pub clearance: f64,
}

/// A planned swing: position, velocity and acceleration of the foot at any time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SwingTrajectory {
    lift_off: Point3<f64>,
    touch_down: Point3<f64>,
    duration: f64,
    apex: f64,
    /// Fractions of the swing between which the foot moves horizontally.
    horizontal_start: f64,
    horizontal_end: f64,
}

/// `sigma(u)`, `sigma'(u)`, `sigma''(u)` of the rest-to-rest quintic, `u` clamped to [0, 1].
pub(crate) fn rest_to_rest(u: f64) -> (f64, f64, f64) {
    let u = u.clamp(0.0, 1.0);
    let (u2, u3) = (u * u, u * u * u);
    (u3 * (10.0 - 15.0 * u + 6.0 * u2), 30.0 * u2 * (1.0 - 2.0 * u + u2), 60.0 * u * (1.0 - 3.0 * u + 2.0 * u2))
}

/// `u` in [0, 1] with `sigma(u) = level` (sigma increases strictly on (0, 1)); bisection to
/// machine precision.
fn rest_to_rest_inverse(level: f64) -> f64 {
    let (mut low, mut high) = (0.0, 1.0);
    for _ in 0..60 {
        let mid = 0.5 * (low + high);
        if rest_to_rest(mid).0 < level {
            low = mid;
        } else {
            high = mid;
        }
    }
    0.5 * (low + high)
}

impl SwingTrajectory {
    /// The swing from `lift_off` to `touch_down` in `duration` seconds over terrain whose
    /// highest point between them is `terrain_top` (`None`: no higher than the footholds).
    pub fn new(
        lift_off: Point3<f64>,
        touch_down: Point3<f64>,
        duration: f64,
        terrain_top: Option<f64>,
        shape: SwingShape,
    ) -> Result<Self, SwingError> {
        let bad = |field, expected, got: String| Err(SwingError::Invalid { field, expected, got });
        if !lift_off.iter().all(|v| v.is_finite()) {
            return bad("lift_off", "a finite point", format!("{lift_off}"));
        }
        if !touch_down.iter().all(|v| v.is_finite()) {
            return bad("touch_down", "a finite point", format!("{touch_down}"));
        }
        if !(duration > 0.0 && duration.is_finite()) {
            return bad("duration", "a positive number of seconds", format!("{duration}"));
        }
        if terrain_top.is_some_and(|t| !t.is_finite()) {
            return bad("terrain_top", "a finite height", format!("{terrain_top:?}"));
        }
        if !(shape.step_height > 0.0 && shape.step_height.is_finite()) {
            return bad("step_height", "a positive number of metres", format!("{}", shape.step_height));
        }
        if !(shape.clearance >= 0.0 && shape.clearance < shape.step_height) {
            return bad("clearance", "a number of metres in [0, step_height)", format!("{}", shape.clearance));
        }
        let top = lift_off.z.max(touch_down.z).max(terrain_top.unwrap_or(f64::NEG_INFINITY));
        let apex = top + shape.step_height;
        let level = top + shape.clearance;
        // Rise on s in [0, 1/2]: z = z0 + (apex - z0) sigma(2 s); crossing of `level`.
        let horizontal_start = if level <= lift_off.z {
            0.0
        } else {
            0.5 * rest_to_rest_inverse((level - lift_off.z) / (apex - lift_off.z))
        };
        // Descent on s in [1/2, 1]: z = apex + (z1 - apex) sigma(2 s - 1).
        let horizontal_end = if level <= touch_down.z {
            1.0
        } else {
            0.5 + 0.5 * rest_to_rest_inverse((apex - level) / (apex - touch_down.z))
        };
        Ok(Self { lift_off, touch_down, duration, apex, horizontal_start, horizontal_end })
    }

    pub fn duration(&self) -> f64 {
        self.duration
    }

    /// Apex height (m).
    pub fn apex_height(&self) -> f64 {
        self.apex
    }

    /// Times (s) between which the foot moves horizontally.
    pub fn horizontal_window(&self) -> (f64, f64) {
        (self.horizontal_start * self.duration, self.horizontal_end * self.duration)
    }

    /// Position, velocity and acceleration at `t` (s), clamped to [0, duration] (the foot
    /// rests at the footholds before and after).
    pub fn state(&self, t: f64) -> (Point3<f64>, Vector3<f64>, Vector3<f64>) {
        let s = (t / self.duration).clamp(0.0, 1.0);
        let rate = 1.0 / self.duration;
        // Vertical: chain rule through u = 2 s (rise) or u = 2 s - 1 (descent).
        let (from, to, u) = if s <= 0.5 {
            (self.lift_off.z, self.apex, 2.0 * s)
        } else {
            (self.apex, self.touch_down.z, 2.0 * s - 1.0)
        };
        let (sz, dsz, ddsz) = rest_to_rest(u);
        let du = 2.0 * rate;
        let (z, vz, az) = (from + (to - from) * sz, (to - from) * dsz * du, (to - from) * ddsz * du * du);
        // Horizontal: u = (s - s_a) / (s_b - s_a).
        let window = self.horizontal_end - self.horizontal_start;
        let (sh, dsh, ddsh) = rest_to_rest((s - self.horizontal_start) / window);
        let du = rate / window;
        let delta = (self.touch_down - self.lift_off).xy();
        let xy = self.lift_off.xy() + delta * sh;
        let position = Point3::new(xy.x, xy.y, z);
        let velocity = Vector3::new(delta.x * dsh * du, delta.y * dsh * du, vz);
        let acceleration = Vector3::new(delta.x * ddsh * du * du, delta.y * ddsh * du * du, az);
        (position, velocity, acceleration)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SHAPE: SwingShape = SwingShape { step_height: 0.1, clearance: 0.03 };

    /// Stepping up onto a 0.15 m pallet: ends at rest on the footholds, apex 0.1 m above the
    /// pallet, no horizontal motion below pallet height + clearance.
    #[test]
    fn step_up_rests_at_ends_and_clears_the_edge() {
        let (a, b) = (Point3::new(0.2, 0.3, 0.0), Point3::new(0.45, 0.32, 0.15));
        let swing = SwingTrajectory::new(a, b, 0.6, None, SHAPE).unwrap();
        let (p0, v0, a0) = swing.state(0.0);
        let (p1, v1, a1) = swing.state(0.6);
        assert!((p0 - a).norm() < 1e-15 && (p1 - b).norm() < 1e-15);
        assert!(v0.norm() < 1e-15 && v1.norm() < 1e-15 && a0.norm() < 1e-15 && a1.norm() < 1e-15);
        assert!((swing.state(0.3).0.z - 0.25).abs() < 1e-15 && (swing.apex_height() - 0.25).abs() < 1e-15);
        let (start, end) = swing.horizontal_window();
        // Lift-off side: the rise crosses 0.18 m at sigma(u) = 0.18 / 0.25, u = 2 start / 0.6.
        assert!((rest_to_rest(2.0 * start / 0.6).0 - 0.18 / 0.25).abs() < 1e-14);
        // Touch-down side: the descent crosses 0.18 m at sigma(u) = (0.25 - 0.18) / (0.25 - 0.15).
        assert!((rest_to_rest(2.0 * end / 0.6 - 1.0).0 - 0.7).abs() < 1e-14);
        let mut between = 0;
        for i in 0..=600 {
            let t = 0.6 * i as f64 / 600.0;
            let (p, _, _) = swing.state(t);
            // Away from both footholds (horizontally), the foot is above the pallet + clearance.
            if (p.xy() - a.xy()).norm() > 0.0 && (p.xy() - b.xy()).norm() > 0.0 {
                between += 1;
                assert!(t >= start && t <= end && p.z >= 0.18 - 1e-12, "t = {t}: z = {} while moving", p.z);
            }
            assert!(p.z >= -1e-15 && p.z <= 0.25 + 1e-15);
        }
        assert!(between > 100, "{between}");
    }

    /// Analytic velocity and acceleration agree with central differences, and are continuous
    /// where the pieces meet (window ends, apex).
    #[test]
    fn derivatives_match_finite_differences_and_are_continuous() {
        let swing =
            SwingTrajectory::new(Point3::new(0.0, 0.0, 0.1), Point3::new(0.3, -0.1, 0.0), 0.5, Some(0.2), SHAPE)
                .unwrap();
        let h = 1e-5;
        // Off the knots (the jerk jumps there, which costs central differences O(h)).
        for i in 0..100 {
            let t = 0.5 * (i as f64 + 0.37) / 100.0;
            let (_, v, a) = swing.state(t);
            let fd_v = (swing.state(t + h).0 - swing.state(t - h).0) / (2.0 * h);
            let fd_a = (swing.state(t + h).1 - swing.state(t - h).1) / (2.0 * h);
            assert!((fd_v - v).norm() < 1e-6 * (1.0 + v.norm()), "t = {t}: {fd_v} vs {v}");
            assert!((fd_a - a).norm() < 1e-4 * (1.0 + a.norm()), "t = {t}: {fd_a} vs {a}");
        }
        let (start, end) = swing.horizontal_window();
        assert!(start > 0.0 && end < 0.5, "{start} {end}");
        for t in [start, 0.25, end] {
            let (before, after) = (swing.state(t - 1e-9), swing.state(t + 1e-9));
            assert!((before.1 - after.1).norm() < 1e-6 && (before.2 - after.2).norm() < 1e-5, "t = {t}");
        }
    }

    #[test]
    fn rejects_bad_input_naming_the_field() {
        let (a, b) = (Point3::new(0.0, 0.0, 0.0), Point3::new(0.2, 0.0, 0.0));
        let e = SwingTrajectory::new(a, b, 0.0, None, SHAPE).unwrap_err().to_string();
        assert!(e.contains("`duration`"), "{e}");
        let e = SwingTrajectory::new(a, b, 0.5, None, SwingShape { step_height: 0.1, clearance: 0.1 }).unwrap_err();
        assert!(e.to_string().contains("`clearance`"), "{e}");
        let e = SwingTrajectory::new(Point3::new(f64::NAN, 0.0, 0.0), b, 0.5, None, SHAPE).unwrap_err();
        assert!(e.to_string().contains("`lift_off`"), "{e}");
        let e = SwingTrajectory::new(a, b, 0.5, Some(f64::INFINITY), SHAPE).unwrap_err();
        assert!(e.to_string().contains("`terrain_top`"), "{e}");
    }
}
