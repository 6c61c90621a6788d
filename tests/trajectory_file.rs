//! trajectory.json: round trip through a file, CSV columns, and every kind of bad file
//! refused with the field and the knot named.

use legwork::control::JointPd;
use legwork::io::Trajectory;
use legwork::model::embedded;
use legwork::sim::{standing_on_ground, SimConfig, Simulator};
use legwork::terrain::Plane;

fn simulated() -> Trajectory {
    let model = embedded::load("hyq").unwrap();
    let ground = Plane::flat(0.0);
    let q0 = standing_on_ground(&model, &ground, 0.02).unwrap();
    let mut sim = Simulator::new(&model, &ground, SimConfig::default(), q0, None).unwrap();
    let mut stand = JointPd::standing(&model, 0.001).unwrap();
    let mut traj = sim.run(0.1, &mut stand, |_| {}).unwrap().trajectory;
    traj.summary.insert("final_base_height_m".into(), serde_json::json!(0.57));
    traj
}

fn temp(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("legwork-traj-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

#[test]
fn round_trip_through_a_file_is_exact() {
    let traj = simulated();
    assert_eq!(traj.knots.len(), 101);
    let path = temp("round_trip.json");
    traj.save_file(&path).unwrap();
    let back = Trajectory::load_file(&path).unwrap();
    assert_eq!(back, traj);
    back.check_against(&embedded::load("hyq").unwrap(), "x").unwrap();
    assert_eq!(back.metadata.units.torque, "N m");
    assert_eq!(back.metadata.legwork_version, env!("CARGO_PKG_VERSION"));
    std::fs::remove_dir_all(path.parent().unwrap()).ok();
}

#[test]
fn csv_has_one_column_per_quantity() {
    let traj = simulated();
    let mut out = Vec::new();
    traj.write_csv(&mut out).unwrap();
    let text = String::from_utf8(out).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    // t + q (19) + v (18) + tau (12) + forces (4 x 3) + contact flags (4)
    assert_eq!(header.len(), 1 + 19 + 18 + 12 + 12 + 4);
    assert_eq!(header[0], "t");
    assert!(header.contains(&"q_base_qw") && header.contains(&"tau_lf_kfe_joint") && header.contains(&"f_rh_foot_z") && header.contains(&"contact_lf_foot"));
    let rows: Vec<&str> = lines.collect();
    assert_eq!(rows.len(), traj.knots.len());
    let last: Vec<f64> = rows.last().unwrap().split(',').map(|x| x.parse().unwrap()).collect();
    assert_eq!(last.len(), header.len());
    assert_eq!(last[0], traj.knots.last().unwrap().t);
}

/// Edits the JSON of a good trajectory and expects an error containing every `needle`.
fn refused(edit: impl Fn(&mut serde_json::Value), needles: &[&str]) {
    let mut json = serde_json::to_value(simulated()).unwrap();
    edit(&mut json);
    let err = Trajectory::from_json(&json.to_string(), "bad.json").unwrap_err().to_string();
    assert!(err.starts_with("bad.json"), "{err}");
    for n in needles {
        assert!(err.contains(n), "error should mention {n:?}: {err}");
    }
}

#[test]
fn a_missing_field_is_named_with_its_knot() {
    refused(|j| drop(j["knots"][7].as_object_mut().unwrap().remove("tau")), &["knots[7]", "missing field `tau`"]);
    refused(|j| drop(j["metadata"].as_object_mut().unwrap().remove("joint_names")), &["metadata", "joint_names"]);
}

#[test]
fn a_wrong_length_is_named_with_its_knot() {
    refused(|j| drop(j["knots"][3]["q"].as_array_mut().unwrap().pop()), &["knots[3].q", "expected 19 numbers", "got 18"]);
    refused(|j| drop(j["knots"][5]["contact_force"].as_array_mut().unwrap().pop()), &["knots[5].contact_force", "expected 4"]);
    refused(|j| j["knots"][2]["feedback_gain"] = serde_json::json!(vec![vec![0.0; 36]; 11]), &["knots[2].feedback_gain", "12 rows"]);
}

#[test]
fn a_nan_is_named_with_its_knot() {
    // JSON has no NaN: serde writes it as null, which reading refuses at its place.
    refused(|j| j["knots"][9]["v"][4] = serde_json::Value::Null, &["knots[9].v[4]", "null"]);
    // A NaN that reaches validation (a trajectory built in code) is named too.
    let mut traj = simulated();
    traj.knots[4].tau[2] = f64::NAN;
    let err = traj.validate("in memory").unwrap_err().to_string();
    assert!(err.contains("knots[4].tau[2]") && err.contains("finite"), "{err}");
}

#[test]
fn unknown_fields_and_joint_names_are_refused() {
    refused(|j| j["knots"][1]["torque"] = serde_json::json!(1.0), &["knots[1]", "unknown field `torque`"]);
    refused(|j| j["metadata"]["dt"] = serde_json::json!(-0.001), &["metadata.dt", "positive"]);
    refused(|j| j["knots"][6]["t"] = serde_json::json!(0.0), &["knots[6].t", "after the previous"]);
    let mut traj = simulated();
    traj.metadata.joint_names[4] = "lf_elbow_joint".into();
    let err = traj.check_against(&embedded::load("hyq").unwrap(), "walk.json").unwrap_err().to_string();
    assert!(err.contains("walk.json") && err.contains("metadata.joint_names[4]") && err.contains("no joint 'lf_elbow_joint'"), "{err}");
    // The right joints in another robot's order are refused too.
    let mut traj = simulated();
    traj.metadata.joint_names.swap(0, 3);
    let err = traj.check_against(&embedded::load("hyq").unwrap(), "x").unwrap_err().to_string();
    assert!(err.contains("metadata.joint_names[0]") && err.contains("at position 3"), "{err}");
    // And a trajectory of another robot.
    let err = simulated().check_against(&embedded::load("a1").unwrap(), "x").unwrap_err().to_string();
    assert!(err.contains("robot 'a1' has no joint"), "{err}");
}
