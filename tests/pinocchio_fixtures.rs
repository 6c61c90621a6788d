//! The URDF importer and the dynamics against Pinocchio 4.0.0 (`shared/fixtures/`): models
//! built by `legwork::model::urdf::load_file` from the shared URDFs must match
//! `pin.buildModelFromUrdf(urdf, pin.JointModelFreeFlyer())` joint by joint, and every
//! algorithm must reproduce the fixtures' values on all 20 random and 3 special samples.
//!
//! Tolerances (norm-relative, `|a - b| <= tol * max(1, |b|)`, Frobenius norm): 1e-9 for the
//! model and the values, 1e-6 for the ABA derivatives.

use legwork::dynamics::*;
use legwork::model::{urdf, JointKind, Model};
use nalgebra::{DMatrix, DVector, Matrix6xX};
use serde_json::Value;

const VALUE_TOL: f64 = 1e-9;
const DERIVATIVE_TOL: f64 = 1e-6;
const ROBOTS: [(&str, &str); 2] = [("hyq", "hyq/hyq_no_sensors.urdf"), ("a1", "a1/a1.urdf")];

fn shared(rel: &str) -> String {
    format!("{}/../shared/{rel}", env!("CARGO_MANIFEST_DIR"))
}

fn fixture(robot: &str) -> Value {
    let path = shared(&format!("fixtures/{robot}_pinocchio.json"));
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{path}: {e}"))
}

fn model(urdf_rel: &str) -> Model {
    urdf::load_file(shared(&format!("robots/{urdf_rel}"))).unwrap_or_else(|e| panic!("{e}"))
}

fn num(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}
fn dvec(v: &Value) -> DVector<f64> {
    DVector::from_vec(v.as_array().expect("array").iter().map(num).collect())
}
fn mat(v: &Value) -> DMatrix<f64> {
    let rows: Vec<DVector<f64>> = v.as_array().expect("array of rows").iter().map(dvec).collect();
    DMatrix::from_fn(rows.len(), rows[0].len(), |r, c| rows[r][c])
}
fn as_dmat<R: nalgebra::Dim, C: nalgebra::Dim, S: nalgebra::RawStorage<f64, R, C>>(m: &nalgebra::Matrix<f64, R, C, S>) -> DMatrix<f64> {
    DMatrix::from_fn(m.nrows(), m.ncols(), |r, c| m[(r, c)])
}
fn as_dvec(s: &[f64]) -> DVector<f64> {
    DVector::from_column_slice(s)
}

/// Asserts `|got - want| <= tol * max(1, |want|)` (Frobenius) and returns the relative error.
fn check(what: &str, got: &DMatrix<f64>, want: &DMatrix<f64>, tol: f64) -> f64 {
    assert_eq!(got.shape(), want.shape(), "{what}: shape");
    let scale = want.norm().max(1.0);
    let err = (got - want).norm() / scale;
    assert!(err <= tol, "{what}: relative error {err:.3e} > {tol:.0e}\n got {got}\nwant {want}");
    err
}
fn checkv(what: &str, got: &DVector<f64>, want: &DVector<f64>, tol: f64) -> f64 {
    check(what, &as_dmat(got), &as_dmat(want), tol)
}
fn check_scalar(what: &str, got: f64, want: f64, tol: f64) -> f64 {
    check(what, &DMatrix::from_element(1, 1, got), &DMatrix::from_element(1, 1, want), tol)
}

fn samples(fx: &Value) -> Vec<&Value> {
    let s: Vec<&Value> = fx["samples"].as_array().unwrap().iter().chain(fx["special_samples"].as_array().unwrap()).collect();
    assert_eq!(s.len(), 23);
    s
}

/// Pinocchio's limits are +-f64::MAX where ours are infinite.
fn check_limit(what: &str, got: f64, want: f64) {
    if want.abs() >= f64::MAX {
        assert!(got.is_infinite() && got.signum() == want.signum(), "{what}: {got} vs unbounded {want}");
    } else {
        check_scalar(what, got, want, VALUE_TOL);
    }
}

fn check_model(robot: &str, urdf_rel: &str) {
    let fx = fixture(robot);
    let model = model(urdf_rel);
    let fm = &fx["model"];
    assert_eq!(model.nq, fm["nq"].as_u64().unwrap() as usize);
    assert_eq!(model.nv, fm["nv"].as_u64().unwrap() as usize);
    assert_eq!(model.njoints(), fm["njoints_including_universe"].as_u64().unwrap() as usize);
    let names: Vec<&str> = model.joints.iter().skip(1).map(|j| j.name.as_str()).collect();
    let want: Vec<&str> = fm["joint_names_in_order"].as_array().unwrap().iter().map(|n| n.as_str().unwrap()).collect();
    assert_eq!(names, want, "{robot}: joint order");
    check_scalar(&format!("{robot}: total mass"), model.total_mass(), num(&fm["total_mass"]), VALUE_TOL);
    check_vec_gravity(robot, &model, fm);

    for fj in fm["joints"].as_array().unwrap() {
        let name = fj["name"].as_str().unwrap();
        let ctx = |what: &str| format!("{robot}/{name}: {what}");
        let id = model.joint_id(name).unwrap();
        assert_eq!(id, fj["index"].as_u64().unwrap() as usize, "{}", ctx("index"));
        let j = &model.joints[id];
        assert_eq!(j.parent, fj["parent"].as_u64().unwrap() as usize, "{}", ctx("parent"));
        for (got, key) in [(j.idx_q, "idx_q"), (j.nq, "nq"), (j.idx_v, "idx_v"), (j.nv, "nv")] {
            assert_eq!(got, fj[key].as_u64().unwrap() as usize, "{}", ctx(key));
        }
        match (fj["type"].as_str().unwrap(), j.kind) {
            ("JointModelFreeFlyer", JointKind::FreeFlyer) => {}
            (_, JointKind::Revolute { axis }) => {
                checkv(&ctx("axis"), &as_dvec(axis.as_slice()), &dvec(&fj["axis_in_joint_frame"]), VALUE_TOL);
            }
            (t, k) => panic!("{}", ctx(&format!("type {t} vs {k:?}"))),
        }
        let pl = &fj["placement_in_parent"];
        check(&ctx("placement rotation"), &as_dmat(&j.placement.rotation), &mat(&pl["rotation"]), VALUE_TOL);
        checkv(&ctx("placement translation"), &as_dvec(j.placement.translation.as_slice()), &dvec(&pl["translation"]), VALUE_TOL);
        let bi = &fj["body_inertia"];
        let inertia = &model.inertias[id];
        check_scalar(&ctx("mass"), inertia.mass, num(&bi["mass"]), VALUE_TOL);
        checkv(&ctx("com"), &as_dvec(inertia.com.as_slice()), &dvec(&bi["com_in_joint_frame"]), VALUE_TOL);
        check(
            &ctx("rotational inertia"),
            &as_dmat(&inertia.inertia_com),
            &mat(&bi["rotational_inertia_about_com_in_joint_frame"]),
            VALUE_TOL,
        );
        let lim = &j.limits;
        for (got, key) in [
            (&lim.lower, "lower_position_limit"),
            (&lim.upper, "upper_position_limit"),
            (&lim.effort, "effort_limit"),
            (&lim.velocity, "velocity_limit"),
        ] {
            let want = dvec(&fj[key]);
            assert_eq!(got.len(), want.len(), "{}", ctx(key));
            for (k, (g, w)) in got.iter().zip(want.iter()).enumerate() {
                check_limit(&ctx(&format!("{key}[{k}]")), *g, *w);
            }
        }
    }

    let fx_feet = fm["feet"].as_array().unwrap();
    assert_eq!(model.feet.len(), fx_feet.len(), "{robot}: number of feet");
    for ff in fx_feet {
        let name = ff["name"].as_str().unwrap();
        let foot = model.feet.iter().find(|f| f.name == name).unwrap_or_else(|| panic!("{robot}: no foot {name}"));
        let frame = &model.frames[foot.frame];
        assert_eq!(model.joints[frame.parent_joint].name, ff["parent_joint_name"].as_str().unwrap(), "{robot}/{name}: parent");
        let pl = &ff["placement_in_parent_joint"];
        check(&format!("{robot}/{name}: rotation"), &as_dmat(&frame.placement.rotation), &mat(&pl["rotation"]), VALUE_TOL);
        checkv(
            &format!("{robot}/{name}: translation"),
            &as_dvec(frame.placement.translation.as_slice()),
            &dvec(&pl["translation"]),
            VALUE_TOL,
        );
    }
    let standing = model.reference_configuration("standing").unwrap_or_else(|| panic!("{robot}: no standing pose"));
    checkv(&format!("{robot}: standing"), standing, &dvec(&fm["srdf_standing_q"]), VALUE_TOL);
}

fn check_vec_gravity(robot: &str, model: &Model, fm: &Value) {
    checkv(&format!("{robot}: gravity"), &as_dvec(model.gravity.v.as_slice()), &dvec(&fm["gravity_linear"]), VALUE_TOL);
    checkv(&format!("{robot}: gravity angular"), &as_dvec(model.gravity.w.as_slice()), &dvec(&fm["gravity_angular"]), VALUE_TOL);
}

#[test]
fn urdf_models_match_pinocchio() {
    for (robot, path) in ROBOTS {
        check_model(robot, path);
    }
}

/// Values of every algorithm (not the derivatives) on every sample; returns the worst
/// relative error.
fn check_values(robot: &str, urdf_rel: &str) -> f64 {
    let fx = fixture(robot);
    let model = model(urdf_rel);
    let mut data = Data::new(&model);
    let mut jac = Matrix6xX::zeros(model.nv);
    let mut worst = 0.0f64;
    for s in samples(&fx) {
        let tag = s["tag"].as_str().unwrap();
        let ctx = |what: &str| format!("{robot}/{tag}: {what}");
        let (q, v, tau) = (dvec(&s["q"]), dvec(&s["v"]), dvec(&s["tau"]));
        let mut w = |e: f64| worst = worst.max(e);
        w(checkv(&ctx("aba_qdd"), aba(&model, &mut data, &q, &v, &tau), &dvec(&s["aba_qdd"]), VALUE_TOL));
        w(checkv(&ctx("rnea_tau"), rnea(&model, &mut data, &q, &v, &dvec(&s["rnea_input_qdd"])), &dvec(&s["rnea_tau"]), VALUE_TOL));
        w(check(&ctx("crba_M"), crba(&model, &mut data, &q), &mat(&s["crba_M"]), VALUE_TOL));
        w(checkv(&ctx("nonlinear_effects"), nonlinear_effects(&model, &mut data, &q, &v), &dvec(&s["nonlinear_effects"]), VALUE_TOL));
        w(checkv(&ctx("generalized_gravity"), generalized_gravity(&model, &mut data, &q), &dvec(&s["generalized_gravity"]), VALUE_TOL));
        let com = center_of_mass(&model, &mut data, &q);
        w(checkv(&ctx("com_world"), &as_dvec(com.as_slice()), &dvec(&s["com_world"]), VALUE_TOL));
        w(check_scalar(&ctx("total_mass"), model.total_mass(), num(&s["total_mass"]), VALUE_TOL));

        compute_joint_jacobians(&model, &mut data, &q);
        update_frame_placements(&model, &mut data);
        let feet = s["feet"].as_array().unwrap();
        assert_eq!(feet.len(), 4, "{}", ctx("feet"));
        for f in feet {
            let name = f["name"].as_str().unwrap();
            let frame = model.frame_id(name).unwrap_or_else(|e| panic!("{}", ctx(&e.to_string())));
            let m = data.o_m_f[frame];
            w(checkv(&ctx(&format!("{name} translation_world")), &as_dvec(m.translation.as_slice()), &dvec(&f["translation_world"]), VALUE_TOL));
            w(check(&ctx(&format!("{name} rotation_world")), &as_dmat(&m.rotation), &mat(&f["rotation_world"]), VALUE_TOL));
            frame_jacobian(&model, &data, frame, ReferenceFrame::LocalWorldAligned, &mut jac);
            w(check(&ctx(&format!("{name} jacobian_lwa")), &as_dmat(&jac), &mat(&f["jacobian_lwa"]), VALUE_TOL));
            let vel = &jac * &v;
            let want_vel = DVector::from_iterator(6, dvec(&f["velocity_lwa_linear"]).iter().chain(dvec(&f["velocity_lwa_angular"]).iter()).copied());
            w(checkv(&ctx(&format!("{name} velocity_lwa")), &as_dvec(vel.as_slice()), &want_vel, VALUE_TOL));
        }
    }
    eprintln!("{robot}: worst relative error of the values over 23 samples: {worst:.2e}");
    worst
}

#[test]
fn hyq_values_match_pinocchio() {
    check_values(ROBOTS[0].0, ROBOTS[0].1);
}

#[test]
fn a1_values_match_pinocchio() {
    check_values(ROBOTS[1].0, ROBOTS[1].1);
}

/// `compute_aba_derivatives`: `d qdd / dq`, `d qdd / dv` and `M^-1` on every sample.
fn check_derivatives(robot: &str, urdf_rel: &str) {
    let fx = fixture(robot);
    let model = model(urdf_rel);
    let mut data = Data::new(&model);
    let mut worst = 0.0f64;
    for s in samples(&fx) {
        let tag = s["tag"].as_str().unwrap();
        let ctx = |what: &str| format!("{robot}/{tag}: {what}");
        let (q, v, tau) = (dvec(&s["q"]), dvec(&s["v"]), dvec(&s["tau"]));
        compute_aba_derivatives(&model, &mut data, &q, &v, &tau);
        worst = worst.max(check(&ctx("aba_Minv"), &data.minv, &mat(&s["aba_Minv"]), DERIVATIVE_TOL));
        worst = worst.max(check(&ctx("aba_dqdd_dv"), &data.ddq_dv, &mat(&s["aba_dqdd_dv"]), DERIVATIVE_TOL));
        worst = worst.max(check(&ctx("aba_dqdd_dq"), &data.ddq_dq, &mat(&s["aba_dqdd_dq"]), DERIVATIVE_TOL));
    }
    eprintln!("{robot}: worst relative error of the ABA derivatives over 23 samples: {worst:.2e}");
}

#[test]
fn aba_derivatives_match_pinocchio() {
    for (robot, path) in ROBOTS {
        check_derivatives(robot, path);
    }
}
