//! The reference state between two knots of a planned motion, as the controllers that
//! follow a plan sample it.

use crate::dynamics::{difference, integrate};
use crate::model::Model;
use nalgebra::DVector;

/// `q* = q_a (+) s (q_b (-) q_a)` on the configuration manifold and `v* = (1 - s) v_a + s v_b`,
/// for `s` in `[0, 1]`, into `(q_out, v_out)`; `dq` is scratch (`nv`).
pub fn interpolate_state(model: &Model, a: (&DVector<f64>, &DVector<f64>), b: (&DVector<f64>, &DVector<f64>), s: f64, dq: &mut DVector<f64>, q_out: &mut DVector<f64>, v_out: &mut DVector<f64>) {
    difference(model, a.0, b.0, dq);
    *dq *= s;
    integrate(model, a.0, dq, q_out);
    v_out.copy_from(a.1);
    v_out.axpy(s, b.1, 1.0 - s);
}

/// Where a time falls on a plan's knot times.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum KnotBracket {
    /// At or before the first knot, or at or after the last: hold knot `k`.
    Hold(usize),
    /// Between knots `k` and `k + 1`, at the fraction `s` in `[0, 1]` of the interval.
    Between(usize, f64),
}

/// Brackets `t` by the increasing knot times `times` (non-empty): the controllers hold the
/// plan's ends and interpolate linearly between its knots.
pub fn knot_bracket(times: &[f64], t: f64) -> KnotBracket {
    let n = times.len();
    let k = times.partition_point(|&tk| tk <= t).saturating_sub(1);
    if t <= times[0] {
        KnotBracket::Hold(0)
    } else if k + 1 >= n {
        KnotBracket::Hold(n - 1)
    } else {
        KnotBracket::Between(k, ((t - times[k]) / (times[k + 1] - times[k])).clamp(0.0, 1.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn knot_bracket_holds_the_ends_and_finds_the_interval() {
        let times = [0.0, 0.1, 0.3];
        assert_eq!(knot_bracket(&times, -1.0), KnotBracket::Hold(0));
        assert_eq!(knot_bracket(&times, 0.0), KnotBracket::Hold(0));
        assert_eq!(knot_bracket(&times, 0.3), KnotBracket::Hold(2));
        assert_eq!(knot_bracket(&times, 5.0), KnotBracket::Hold(2));
        let KnotBracket::Between(k, s) = knot_bracket(&times, 0.25) else { panic!("not between knots") };
        assert_eq!(k, 1);
        assert!((s - 0.75).abs() < 1e-12);
        assert_eq!(knot_bracket(&[0.0], 0.5), KnotBracket::Hold(0));
    }
}
