//! The whole-body controller's tick allocates nothing: a counting global allocator around
//! ticks of HyQ standing and stepping (one leg in swing).

use legwork::control::{FootMotion, LegMotion, WholeBodyController, WholeBodyReference};
use legwork::model::embedded;
use nalgebra::{DVector, Vector3};
#[path = "support/counting_allocator.rs"]
mod counting_allocator;
use counting_allocator::ALLOCATIONS;
use std::sync::atomic::Ordering;

#[test]
fn a_control_tick_allocates_nothing() {
    let model = embedded::load("hyq").unwrap();
    let q = model.reference_configuration("standing").unwrap().clone();
    let hold = WholeBodyReference::holding(&model, &q);
    let lf = Vector3::new(0.37, 0.33, 0.0);
    let source = move |t: f64, r: &mut WholeBodyReference| {
        r.clone_from(&hold);
        r.body.cog_position.y += 0.01 * t.sin();
        if t > 0.005 {
            r.legs[0] = LegMotion::Swing(FootMotion { position: lf, velocity: Vector3::new(0.0, 0.0, 0.1), acceleration: Vector3::zeros() });
        }
    };
    let mut controller = WholeBodyController::with_default_gains(&model, source, 0.001).unwrap();
    let v = DVector::from_element(model.nv, 0.05);
    let mut tau = DVector::zeros(model.nv);
    // The first tick may size nothing either, but warm up anyway.
    controller.compute_torques(&model, 0.0, &q, &v, &mut tau).unwrap();
    let before = ALLOCATIONS.load(Ordering::Relaxed);
    for k in 1..20 {
        controller.compute_torques(&model, k as f64 * 0.001, &q, &v, &mut tau).unwrap();
    }
    let allocations = ALLOCATIONS.load(Ordering::Relaxed) - before;
    assert_eq!(allocations, 0, "19 ticks allocated {allocations} times");
    assert!(matches!(controller.reference().legs[0], LegMotion::Swing(_)), "the swing branch ran");
}
