//! The embedded robots (`robots/hyq.toml`, `robots/a1.toml`, legwork's own descriptions)
//! against the reference descriptions of the same robots:
//!
//! * the reference URDFs in `shared/robots`, read by legwork's URDF importer: total mass,
//!   the four foot positions in the SRDF standing pose, and every joint's position,
//!   velocity and effort limits, within 1 %;
//! * Pinocchio's numbers for those URDFs in `shared/fixtures` (independent of the importer):
//!   the same checks, plus the centre of mass and the joint-space inertia matrix in the
//!   standing pose, which also check every link's mass, centre of mass and inertia.
//!
//! The joint order differs (legwork: LF, RF, LH, RH; Pinocchio's HyQ: LF, LH, RF, RH), so
//! everything is mapped by joint and foot name, never by position.

use legwork::dynamics::{center_of_mass, crba, forward_kinematics, frame_placement, Data};
use legwork::model::{embedded, urdf, Model};
use nalgebra::{DMatrix, DVector, Vector3};
use serde_json::Value;

const ROBOTS: [(&str, &str); 2] = [("hyq", "hyq/hyq_no_sensors.urdf"), ("a1", "a1/a1.urdf")];

fn shared(rel: &str) -> String {
    format!("{}/../shared/{rel}", env!("CARGO_MANIFEST_DIR"))
}

fn fixture(robot: &str) -> Value {
    let path = shared(&format!("fixtures/{robot}_pinocchio.json"));
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    serde_json::from_str(&text).unwrap()
}

fn floats(v: &Value) -> Vec<f64> {
    v.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect()
}

fn v3(v: &Value) -> Vector3<f64> {
    let x = floats(v);
    Vector3::new(x[0], x[1], x[2])
}

/// The fixture's SRDF standing pose, as (joint name, value) pairs plus the 7 base coordinates.
fn standing_by_name(fx: &Value) -> (Vec<f64>, Vec<(String, f64)>) {
    let q = floats(&fx["model"]["srdf_standing_q"]);
    let names: Vec<String> = fx["model"]["actuated_joint_names_in_v_order"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| n.as_str().unwrap().to_string())
        .collect();
    let joints = names.into_iter().zip(q[7..].iter().copied()).collect();
    (q[..7].to_vec(), joints)
}

/// A configuration of `model` from base coordinates and joint values given by name.
fn q_of(model: &Model, base: &[f64], joints: &[(String, f64)]) -> DVector<f64> {
    let mut q = model.neutral();
    q.rows_mut(0, 7).copy_from_slice(base);
    for (name, value) in joints {
        let i = model.q_index(name).unwrap_or_else(|e| panic!("{}: {e}", model.name));
        q[i] = *value;
    }
    q
}

/// World position of every foot, by foot frame name.
fn feet_world(model: &Model, q: &DVector<f64>, names: &[String]) -> Vec<Vector3<f64>> {
    let mut data = Data::new(model);
    forward_kinematics(model, &mut data, q);
    names
        .iter()
        .map(|n| {
            let f = model.frame_id(n).unwrap_or_else(|e| panic!("{}: {e}", model.name));
            frame_placement(model, &mut data, f).translation
        })
        .collect()
}

fn foot_names(model: &Model) -> Vec<String> {
    model.feet.iter().map(|f| f.name.clone()).collect()
}

/// Largest foot position error relative to the foot's distance from the base origin.
fn foot_error(ours: &[Vector3<f64>], reference: &[Vector3<f64>], base: &Vector3<f64>) -> (f64, f64) {
    let mut max_abs: f64 = 0.0;
    let mut max_rel: f64 = 0.0;
    for (a, b) in ours.iter().zip(reference) {
        let e = (a - b).norm();
        max_abs = max_abs.max(e);
        max_rel = max_rel.max(e / (b - base).norm());
    }
    (max_abs, max_rel)
}

fn rel(a: f64, b: f64) -> f64 {
    if a == b {
        0.0
    } else {
        (a - b).abs() / b.abs().max(1e-12)
    }
}

/// Compares limits joint by joint (by name); returns the largest relative difference.
fn limits_error(ours: &Model, reference: &Model) -> f64 {
    let mut worst: f64 = 0.0;
    let names = ours.actuated_joint_names();
    assert_eq!(names.len(), reference.actuated_joint_names().len(), "{}: number of joints", ours.name);
    for name in names {
        let a = &ours.joints[ours.joint_id(name).unwrap()].limits;
        let b = &reference.joints[reference.joint_id(name).unwrap_or_else(|e| panic!("{}: {e}", ours.name))].limits;
        for (x, y, what) in [
            (a.lower[0], b.lower[0], "lower"),
            (a.upper[0], b.upper[0], "upper"),
            (a.velocity[0], b.velocity[0], "velocity"),
            (a.effort[0], b.effort[0], "effort"),
        ] {
            let r = rel(x, y);
            assert!(r <= 0.01, "{} {name} {what} limit: ours {x}, reference {y}", ours.name);
            worst = worst.max(r);
        }
    }
    worst
}

#[test]
fn embedded_robots_agree_with_the_reference_urdfs() {
    for (robot, urdf_rel) in ROBOTS {
        let ours = embedded::load(robot).unwrap_or_else(|e| panic!("{e}"));
        let reference = urdf::load_file(shared(&format!("robots/{urdf_rel}"))).unwrap_or_else(|e| panic!("{e}"));

        let (m_ours, m_ref) = (ours.total_mass(), reference.total_mass());
        println!("{robot}: total mass {m_ours} kg, URDF {m_ref} kg, relative difference {:.2e}", rel(m_ours, m_ref));
        assert!(rel(m_ours, m_ref) <= 0.01, "{robot}: total mass {m_ours} vs {m_ref}");

        let fx = fixture(robot);
        let (base, joints) = standing_by_name(&fx);
        let names = foot_names(&ours);
        let p_ours = feet_world(&ours, &q_of(&ours, &base, &joints), &names);
        let p_ref = feet_world(&reference, &q_of(&reference, &base, &joints), &names);
        let (abs, relative) = foot_error(&p_ours, &p_ref, &Vector3::new(base[0], base[1], base[2]));
        println!("{robot}: feet in the standing pose, max error {abs:.2e} m ({relative:.2e} of the foot's distance from the base)");
        assert!(relative <= 0.01, "{robot}: feet {p_ours:?} vs {p_ref:?}");

        let worst = limits_error(&ours, &reference);
        println!("{robot}: joint limits, max relative difference {worst:.2e}");
    }
}

#[test]
fn embedded_robots_agree_with_pinocchio_fixtures() {
    for (robot, _) in ROBOTS {
        let ours = embedded::load(robot).unwrap_or_else(|e| panic!("{e}"));
        let fx = fixture(robot);
        let model = &fx["model"];

        let m_ref = model["total_mass"].as_f64().unwrap();
        let m_ours = ours.total_mass();
        println!("{robot}: total mass {m_ours} kg, Pinocchio {m_ref} kg, relative difference {:.2e}", rel(m_ours, m_ref));
        assert!(rel(m_ours, m_ref) <= 0.01);

        // Limits by name.
        for j in model["joints"].as_array().unwrap().iter().skip(1) {
            let name = j["name"].as_str().unwrap();
            let l = &ours.joints[ours.joint_id(name).unwrap_or_else(|e| panic!("{robot}: {e}"))].limits;
            for (x, key) in [(l.lower[0], "lower_position_limit"), (l.upper[0], "upper_position_limit"), (l.velocity[0], "velocity_limit"), (l.effort[0], "effort_limit")] {
                let y = floats(&j[key])[0];
                assert!(rel(x, y) <= 1e-9, "{robot} {name} {key}: ours {x}, Pinocchio {y}");
            }
        }

        // Our own `standing` is the SRDF's.
        let (base, joints) = standing_by_name(&fx);
        let q = q_of(&ours, &base, &joints);
        let standing = ours.reference_configuration("standing").expect("a standing pose");
        assert!((standing - &q).amax() < 1e-12, "{robot}: standing {standing} vs SRDF {q}");

        // Feet, CoM and the joint-space inertia matrix in the standing pose.
        let sample = fx["special_samples"].as_array().unwrap().iter().find(|s| s["tag"] == "srdf_standing_zero_v_zero_tau").unwrap();
        let names: Vec<String> = sample["feet"].as_array().unwrap().iter().map(|f| f["name"].as_str().unwrap().to_string()).collect();
        let mut ours_names = foot_names(&ours);
        ours_names.sort();
        let mut sorted = names.clone();
        sorted.sort();
        assert_eq!(ours_names, sorted, "{robot}: foot names");
        let p_ref: Vec<Vector3<f64>> = sample["feet"].as_array().unwrap().iter().map(|f| v3(&f["translation_world"])).collect();
        let p_ours = feet_world(&ours, &q, &names);
        let (abs, relative) = foot_error(&p_ours, &p_ref, &Vector3::new(base[0], base[1], base[2]));
        println!("{robot}: feet vs Pinocchio, max error {abs:.2e} m ({relative:.2e} relative)");
        assert!(abs < 1e-9, "{robot}: feet {p_ours:?} vs {p_ref:?}");

        let mut data = Data::new(&ours);
        let com = center_of_mass(&ours, &mut data, &q);
        let com_err = (com - v3(&sample["com_world"])).norm();
        println!("{robot}: centre of mass error {com_err:.2e} m");

        // M in Pinocchio's order: permute ours by name.
        let order: Vec<usize> = (0..6)
            .chain(
                model["actuated_joint_names_in_v_order"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|n| ours.v_index(n.as_str().unwrap()).unwrap()),
            )
            .collect();
        let m = crba(&ours, &mut data, &q).clone();
        let m_perm = DMatrix::from_fn(ours.nv, ours.nv, |r, c| m[(order[r], order[c])]);
        let rows: Vec<Vec<f64>> = sample["crba_M"].as_array().unwrap().iter().map(floats).collect();
        let m_ref = DMatrix::from_fn(ours.nv, ours.nv, |r, c| rows[r][c]);
        let m_err = (&m_perm - &m_ref).amax() / m_ref.amax();
        println!("{robot}: joint-space inertia matrix, max error {m_err:.2e} of max |M|");
        // HyQ's URDF has 1e-6 kg placeholder links (base_link, feet) that legwork's
        // description leaves out; A1's description has every mass.
        let (com_tol, m_tol) = if robot == "hyq" { (1e-7, 1e-7) } else { (1e-10, 1e-10) };
        assert!(com_err < com_tol, "{robot}: CoM {com} vs {}", v3(&sample["com_world"]));
        assert!(m_err < m_tol, "{robot}: M differs by {m_err}\nours {m_perm}\nPinocchio {m_ref}");
    }
}
