//! The dynamics algorithms against Pinocchio on the fixtures' own model description
//! (joint placements, axes and lumped body inertias as Pinocchio built them), independent of
//! the URDF importer. Tolerances: 1e-9 relative for values, 1e-6 for derivatives.

use legwork::dynamics::*;
use legwork::model::{JointKind, JointLimits, Model};
use legwork::spatial::{Inertia, SE3};
use nalgebra::{DMatrix, DVector, Matrix3, Matrix6xX, Vector3};
use serde_json::Value;

fn fixture(robot: &str) -> Value {
    let path = format!("{}/../shared/fixtures/{robot}_pinocchio.json", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    serde_json::from_str(&text).unwrap()
}

fn vec_of(v: &Value) -> Vec<f64> {
    v.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect()
}
fn dvec(v: &Value) -> DVector<f64> {
    DVector::from_vec(vec_of(v))
}
fn mat(v: &Value) -> DMatrix<f64> {
    let rows: Vec<Vec<f64>> = v.as_array().unwrap().iter().map(vec_of).collect();
    DMatrix::from_fn(rows.len(), rows[0].len(), |r, c| rows[r][c])
}
fn m3(v: &Value) -> Matrix3<f64> {
    let m = mat(v);
    Matrix3::from_fn(|r, c| m[(r, c)])
}
fn v3(v: &Value) -> Vector3<f64> {
    let x = vec_of(v);
    Vector3::new(x[0], x[1], x[2])
}

fn model_from_fixture(fx: &Value) -> (Model, Vec<usize>) {
    let mut model = Model::new(fx["robot"].as_str().unwrap());
    for j in fx["model"]["joints"].as_array().unwrap() {
        let kind = match j["type"].as_str().unwrap() {
            "JointModelFreeFlyer" => JointKind::FreeFlyer,
            _ => JointKind::revolute(v3(&j["axis_in_joint_frame"])),
        };
        let pl = &j["placement_in_parent"];
        let placement = SE3::new(m3(&pl["rotation"]), v3(&pl["translation"]));
        let limits = if kind == JointKind::FreeFlyer {
            JointLimits::unbounded(6)
        } else {
            JointLimits::new(
                vec_of(&j["lower_position_limit"])[0],
                vec_of(&j["upper_position_limit"])[0],
                vec_of(&j["velocity_limit"])[0],
                vec_of(&j["effort_limit"])[0],
            )
        };
        let id = model
            .add_joint(j["parent"].as_u64().unwrap() as usize, j["name"].as_str().unwrap(), kind, placement, limits)
            .unwrap();
        let bi = &j["body_inertia"];
        let inertia = Inertia::new(
            bi["mass"].as_f64().unwrap(),
            v3(&bi["com_in_joint_frame"]),
            m3(&bi["rotational_inertia_about_com_in_joint_frame"]),
        );
        model.append_body(id, format!("{}_body", j["name"].as_str().unwrap()), inertia, SE3::identity());
    }
    let mut feet = Vec::new();
    for f in fx["model"]["feet"].as_array().unwrap() {
        let pl = &f["placement_in_parent_joint"];
        let frame = model
            .add_frame(legwork::model::Frame {
                name: f["name"].as_str().unwrap().into(),
                kind: legwork::model::FrameKind::Body,
                parent_joint: f["parent_joint"].as_u64().unwrap() as usize,
                placement: SE3::new(m3(&pl["rotation"]), v3(&pl["translation"])),
            })
            .unwrap();
        feet.push(frame);
    }
    (model, feet)
}

/// Asserts `max|got - want| <= rel * max(1, max|want|)` and returns the relative error.
fn close(name: &str, got: &DMatrix<f64>, want: &DMatrix<f64>, rel: f64) -> f64 {
    assert_eq!(got.shape(), want.shape(), "{name}: shape");
    let err = (got - want).amax();
    let scale = want.amax().max(1.0);
    assert!(err <= rel * scale, "{name}: max abs error {err:.3e} (scale {scale:.3e})");
    err / scale
}
fn closev(name: &str, got: &DVector<f64>, want: &DVector<f64>, rel: f64) -> f64 {
    assert_eq!(got.len(), want.len(), "{name}: length");
    let err = (got - want).amax();
    let scale = want.amax().max(1.0);
    assert!(err <= rel * scale, "{name}: max abs error {err:.3e} (scale {scale:.3e})\n got {got}\nwant {want}");
    err / scale
}

fn check_robot(robot: &str) {
    let fx = fixture(robot);
    let (model, feet) = model_from_fixture(&fx);
    assert_eq!(model.nq, 19);
    assert_eq!(model.nv, 18);
    assert!((model.total_mass() - fx["model"]["total_mass"].as_f64().unwrap()).abs() < 1e-9);
    let mut data = Data::new(&model);
    let samples: Vec<&Value> =
        fx["samples"].as_array().unwrap().iter().chain(fx["special_samples"].as_array().unwrap()).collect();
    assert_eq!(samples.len(), 23);
    let (mut worst_value, mut worst_derivative) = (0.0f64, 0.0f64);
    for s in samples {
        let tag = s["tag"].as_str().unwrap();
        let (q, v, tau) = (dvec(&s["q"]), dvec(&s["v"]), dvec(&s["tau"]));
        let ctx = |what: &str| format!("{robot}/{tag}/{what}");
        worst_value = worst_value.max(closev(&ctx("aba"), aba(&model, &mut data, &q, &v, &tau), &dvec(&s["aba_qdd"]), 1e-9));
        worst_value = worst_value.max(closev(&ctx("rnea"), rnea(&model, &mut data, &q, &v, &dvec(&s["rnea_input_qdd"])), &dvec(&s["rnea_tau"]), 1e-9));
        worst_value = worst_value.max(close(&ctx("crba"), crba(&model, &mut data, &q), &mat(&s["crba_M"]), 1e-9));
        worst_value = worst_value.max(closev(&ctx("nle"), nonlinear_effects(&model, &mut data, &q, &v), &dvec(&s["nonlinear_effects"]), 1e-9));
        worst_value = worst_value.max(closev(&ctx("g"), generalized_gravity(&model, &mut data, &q), &dvec(&s["generalized_gravity"]), 1e-9));
        let com = center_of_mass(&model, &mut data, &q);
        worst_value = worst_value.max(closev(&ctx("com"), &DVector::from_column_slice(com.as_slice()), &dvec(&s["com_world"]), 1e-9));
        compute_joint_jacobians(&model, &mut data, &q);
        update_frame_placements(&model, &mut data);
        let mut jac = Matrix6xX::zeros(model.nv);
        assert_eq!(s["feet"].as_array().unwrap().len(), 4);
        for (k, f) in s["feet"].as_array().unwrap().iter().enumerate() {
            let m = data.o_m_f[feet[k]];
            worst_value = worst_value.max(closev(&ctx("foot p"), &DVector::from_column_slice(m.translation.as_slice()), &dvec(&f["translation_world"]), 1e-9));
            frame_jacobian(&model, &data, feet[k], ReferenceFrame::LocalWorldAligned, &mut jac);
            let jd = DMatrix::from_fn(6, model.nv, |r, c| jac[(r, c)]);
            worst_value = worst_value.max(close(&ctx("foot J"), &jd, &mat(&f["jacobian_lwa"]), 1e-9));
        }
        compute_aba_derivatives(&model, &mut data, &q, &v, &tau);
        worst_derivative = worst_derivative.max(close(&ctx("Minv"), &data.minv, &mat(&s["aba_Minv"]), 1e-6));
        worst_derivative = worst_derivative.max(close(&ctx("dqdd/dv"), &data.ddq_dv, &mat(&s["aba_dqdd_dv"]), 1e-6));
        worst_derivative = worst_derivative.max(close(&ctx("dqdd/dq"), &data.ddq_dq, &mat(&s["aba_dqdd_dq"]), 1e-6));
    }
    eprintln!("{robot}: worst relative error over 23 samples: values {worst_value:.2e}, derivatives {worst_derivative:.2e}");
}

#[test]
fn hyq_matches_pinocchio() {
    check_robot("hyq");
}

#[test]
fn a1_matches_pinocchio() {
    check_robot("a1");
}
