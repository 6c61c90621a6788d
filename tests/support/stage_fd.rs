//! Central differences of an `ipocp` stage's values against its analytic first derivatives
//! (shared by the tests of the contact-timing and the full-body stages).

use legwork::ipocp::{Stage, StageJacobians, StageValues};
use nalgebra::DVector;

/// Asserts that `stage.jacobians` at `z` matches central differences of `stage.evaluate`
/// with step `h`: every entry within `tol * (1 + |analytic|)`, the failing row named.
pub fn assert_jacobians_match_central_differences(stage: &dyn Stage, z: &DVector<f64>, h: f64, tol: f64) {
    let d = stage.dims();
    let mut jac = StageJacobians::zeros(d);
    stage.jacobians(z.as_slice(), &mut jac);
    for i in 0..d.nz() {
        let (mut zp, mut zm) = (z.clone(), z.clone());
        zp[i] += h;
        zm[i] -= h;
        let (mut vp, mut vm) = (StageValues::zeros(d), StageValues::zeros(d));
        stage.evaluate(zp.as_slice(), &mut vp);
        stage.evaluate(zm.as_slice(), &mut vm);
        let fd = |a: &DVector<f64>, b: &DVector<f64>| (a - b) / (2.0 * h);
        let close = |fd: f64, an: f64, what: &str| assert!((fd - an).abs() < tol * (1.0 + an.abs()), "{what} column {i}: fd {fd} analytic {an}");
        close((vp.cost - vm.cost) / (2.0 * h), jac.cost_gradient[i], "cost gradient");
        for (r, v) in fd(&vp.dynamics, &vm.dynamics).iter().enumerate() {
            close(*v, jac.dynamics[(r, i)], &format!("dynamics row {r}"));
        }
        for (r, v) in fd(&vp.equalities, &vm.equalities).iter().enumerate() {
            close(*v, jac.equalities[(r, i)], &format!("equality row {r}"));
        }
        for (r, v) in fd(&vp.inequalities, &vm.inequalities).iter().enumerate() {
            close(*v, jac.inequalities[(r, i)], &format!("inequality row {r}"));
        }
    }
}
