//! legwork's robot description format: bad files are refused with errors that name the
//! file, the line, the field and the expectation; mirroring and per-leg values build the
//! model they describe.

use legwork::model::description::{self, DescriptionError};
use legwork::model::embedded;

/// The embedded A1 description with `from` replaced by `to` (exactly once).
fn a1_with(from: &str, to: &str) -> String {
    let src = embedded::source("a1").unwrap();
    assert_eq!(src.matches(from).count(), 1, "test setup: '{from}' must occur once in a1.toml");
    src.replacen(from, to, 1)
}

fn error_of(src: &str) -> DescriptionError {
    match description::from_str(src, "a1.toml") {
        Ok(_) => panic!("expected an error"),
        Err(e) => e,
    }
}

fn line_of(src: &str, needle: &str) -> usize {
    src.lines().position(|l| l.contains(needle)).unwrap() + 1
}

#[test]
fn unknown_fields_are_errors_naming_file_line_and_field() {
    let src = a1_with("mass = 1.013\n", "mass = 1.013\nmas = 1.0\n");
    let e = error_of(&src);
    assert_eq!((e.file.as_str(), e.field.as_str(), e.line), ("a1.toml", "thigh.mas", Some(line_of(&src, "mas = 1.0"))), "{e}");
    assert!(e.message.contains("unknown field `mas`"), "{e}");

    let src = a1_with("format = 1\n", "format = 1\ncolour = \"red\"\n");
    let e = error_of(&src);
    assert_eq!(e.field, "colour", "{e}");

    let src = a1_with("[standing]\n", "[standing]\nbase_roll = 0.1\n");
    assert_eq!(error_of(&src).field, "standing.base_roll");

    let src = a1_with("[standing]\n", "[stance]\nx = 1\n[standing]\n");
    let e = error_of(&src);
    assert!(e.message.contains("unknown field `stance`"), "{e}");
}

#[test]
fn wrong_types_and_missing_fields_name_the_field() {
    let src = a1_with("mass = 1.013", "mass = \"heavy\"");
    let e = error_of(&src);
    assert_eq!((e.field.as_str(), e.line), ("thigh.mass", Some(line_of(&src, "\"heavy\""))), "{e}");
    assert!(e.to_string().starts_with(&format!("a1.toml:{}: thigh.mass: ", line_of(&src, "\"heavy\""))), "{e}");

    let src = a1_with("effort = 33.5\nmass = 0.696", "mass = 0.696");
    let e = error_of(&src);
    assert!(e.message.contains("missing field `effort`"), "{e}");
    assert_eq!(e.field, "hip", "{e}");

    let src = a1_with("thigh = 0.8", "thigh = [0.8, 0.8, 0.8]");
    let e = error_of(&src);
    assert_eq!(e.field, "standing.thigh", "{e}");
    assert!(e.message.contains("4 numbers [LF, RF, LH, RH]"), "{e}");

    let src = a1_with("hind = \"same\"\n\n[shank]", "hind = \"flip\"\n\n[shank]");
    let e = error_of(&src);
    assert_eq!(e.field, "thigh.hind", "{e}");
    assert!(e.message.contains("mirror"), "{e}");
}

#[test]
fn unphysical_bodies_are_errors() {
    for (from, to, field) in [
        ("mass = 1.013", "mass = nan", "thigh.mass"),
        ("mass = 1.013", "mass = -1.013", "thigh.mass"),
        ("mass = 0.166", "mass = 0.0", "shank.mass"),
        ("mass = 6.001", "mass = inf", "base.mass"),
        ("com = [-0.003237, -0.022327, -0.027326]", "com = [nan, 0.0, 0.0]", "thigh.com"),
        ("inertia = [0.005529065, 0.005139339, 0.001367788,", "inertia = [0.005529065, 0.005139339, -0.001367788,", "thigh.inertia"),
        // Positive definite but not a rigid body: izz > ixx + iyy.
        ("inertia = [0.005529065, 0.005139339, 0.001367788,", "inertia = [0.005529065, 0.005139339, 0.02,", "thigh.inertia"),
        ("inertia = [0.0000096, 0.0000096, 0.0000096,", "inertia = [0.0000096, 0.0000096, 0.0,", "foot.inertia"),
    ] {
        let e = error_of(&a1_with(from, to));
        assert_eq!((e.file.as_str(), e.field.as_str()), ("a1.toml", field), "{from} -> {to}: {e}");
        assert!(e.message.starts_with("expected"), "{e}");
    }
    let e = error_of(&a1_with("mass = 1.013", "mass = -1.013"));
    assert_eq!(e.to_string(), "a1.toml: thigh.mass: expected a finite positive mass in kg, got -1.013");
}

#[test]
fn inconsistent_descriptions_are_errors() {
    for (from, to, field) in [
        ("format = 1", "format = 2", "format"),
        ("lower = -0.8028514559", "lower = 0.9", "hip.lower"),
        ("velocity = 21.0\neffort = 33.5\nmass = 0.166", "velocity = 0.0\neffort = 33.5\nmass = 0.166", "shank.velocity"),
        ("axis = [1.0, 0.0, 0.0]", "axis = [0.0, 0.0, 0.0]", "hip.axis"),
        ("axis = [1.0, 0.0, 0.0]", "axis = [1.0, 0.0, 0.0]\nsigns = [1, 1, 2, 1]", "hip.signs"),
        ("joint = \"{leg}_hip_joint\"", "joint = \"hip_joint\"", "hip.joint"),
        ("names = [\"FL\", \"FR\", \"RL\", \"RR\"]", "names = [\"FL\", \"FR\", \"FL\", \"RR\"]", "legs.names"),
        ("radius = 0.02", "radius = -0.02", "foot.radius"),
        ("shank = -1.81", "shank = -0.5", "standing.shank"),
        ("offset = [0.1805, 0.047, 0.0]", "offset = [0.1805, 0.047, 0.0]\noffsets = [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]", "hip.offsets"),
        ("offset = [0.1805, 0.047, 0.0]", "", "hip.offset"),
        ("body = \"{leg}_calf\"", "body = \"{leg}_thigh\"", ""),
    ] {
        let e = error_of(&a1_with(from, to));
        assert_eq!(e.field, field, "{from} -> {to}: {e}");
        assert!(e.to_string().starts_with("a1.toml: "), "{e}");
    }
}

#[test]
fn a_missing_file_is_named() {
    let e = description::load_file("/nonexistent/robot.toml").unwrap_err();
    assert!(e.to_string().starts_with("/nonexistent/robot.toml: cannot read"), "{e}");
}

#[test]
fn explicit_per_leg_offsets_equal_the_mirrored_ones() {
    let mirrored = embedded::load("a1").unwrap();
    let explicit = description::from_str(
        &a1_with(
            "offset = [0.1805, 0.047, 0.0]",
            "offsets = [[0.1805, 0.047, 0.0], [0.1805, -0.047, 0.0], [-0.1805, 0.047, 0.0], [-0.1805, -0.047, 0.0]]",
        ),
        "a1.toml",
    )
    .unwrap();
    for (a, b) in mirrored.joints.iter().zip(&explicit.joints) {
        assert_eq!(a.placement, b.placement, "{}", a.name);
    }
}

#[test]
fn models_have_legworks_layout() {
    for (robot, first_joints, feet) in [
        ("hyq", ["lf_haa_joint", "lf_hfe_joint", "lf_kfe_joint", "rf_haa_joint"], ["lf_foot", "rf_foot", "lh_foot", "rh_foot"]),
        ("a1", ["FL_hip_joint", "FL_thigh_joint", "FL_calf_joint", "FR_hip_joint"], ["FL_foot", "FR_foot", "RL_foot", "RR_foot"]),
    ] {
        let m = embedded::load(robot).unwrap();
        assert_eq!(m.joints[1].name, "root_joint");
        assert_eq!(&m.actuated_joint_names()[..4], &first_joints[..]);
        let names: Vec<&str> = m.feet.iter().map(|f| f.name.as_str()).collect();
        assert_eq!(names, feet);
        // Mirror symmetry of the hips: RF = (x, -y, z), LH = (-x, y, z).
        let hip = |k: usize| m.joints[2 + 3 * k].placement.translation;
        assert_eq!(hip(1), hip(0).component_mul(&nalgebra::Vector3::new(1.0, -1.0, 1.0)));
        assert_eq!(hip(2), hip(0).component_mul(&nalgebra::Vector3::new(-1.0, 1.0, 1.0)));
        assert_eq!(hip(3), -hip(0).component_mul(&nalgebra::Vector3::new(1.0, 1.0, -1.0)));
    }
    assert_eq!(embedded::load("hyq").unwrap().feet[0].radius, 0.02175);
    assert_eq!(embedded::load("a1").unwrap().feet[0].radius, 0.02);
}
