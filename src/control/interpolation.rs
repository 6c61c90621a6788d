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
