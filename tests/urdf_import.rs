//! URDF import: every shared robot loads with the structure listed in
//! `shared/robots/README.md`; every kind of bad input gives an error naming the file and the
//! link or joint; mutated URDFs never make the importer panic.

use legwork::model::urdf::{self, RootJoint, UrdfError, UrdfErrorKind};
use legwork::model::{FrameKind, JointKind, Model};
use proptest::prelude::*;

#[path = "support/number_spans.rs"]
mod number_spans;
use number_spans::number_spans;

fn shared(rel: &str) -> String {
    format!("{}/../shared/{rel}", env!("CARGO_MANIFEST_DIR"))
}

// ---------------------------------------------------------------------------------------
// The shared robots
// ---------------------------------------------------------------------------------------

struct Expected {
    urdf: &'static str,
    mass: f64,
    /// Foot frames in the order LF, RF, LH, RH.
    feet: [&'static str; 4],
    foot_radius: f64,
    standing_z: f64,
}

const fn legs(p: [&'static str; 4], j: [&'static str; 3], sep: &'static str) -> [[&'static str; 5]; 4] {
    [[p[0], sep, j[0], j[1], j[2]], [p[1], sep, j[0], j[1], j[2]], [p[2], sep, j[0], j[1], j[2]], [p[3], sep, j[0], j[1], j[2]]]
}

fn joint_names(parts: [[&'static str; 5]; 4]) -> Vec<String> {
    parts.iter().flat_map(|l| (2..5).map(move |k| format!("{}{}{}", l[0], l[1], l[k]))).collect()
}

fn expected() -> Vec<(Expected, Vec<String>)> {
    let unitree = legs(["FL", "FR", "RL", "RR"], ["hip_joint", "thigh_joint", "calf_joint"], "_");
    let anymal = legs(["LF", "LH", "RF", "RH"], ["HAA", "HFE", "KFE"], "_");
    let e = |urdf, mass, names: Vec<String>, feet, foot_radius, standing_z| {
        (Expected { urdf, mass, feet, foot_radius, standing_z }, names)
    };
    vec![
        e(
            "hyq/hyq_no_sensors.urdf",
            86.774005,
            joint_names(legs(["lf", "lh", "rf", "rh"], ["haa_joint", "hfe_joint", "kfe_joint"], "_")),
            ["lf_foot", "rf_foot", "lh_foot", "rh_foot"],
            0.02175,
            0.5775,
        ),
        e("a1/a1.urdf", 13.741, joint_names(unitree), ["FL_foot", "FR_foot", "RL_foot", "RR_foot"], 0.02, 0.26),
        e("go1/go1.urdf", 13.100529, joint_names(unitree), ["FL_foot", "FR_foot", "RL_foot", "RR_foot"], 0.02, 0.26),
        e(
            "solo12/solo12.urdf",
            2.500003,
            joint_names(legs(["FL", "FR", "HL", "HR"], ["HAA", "HFE", "KFE"], "_")),
            ["FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT"],
            0.0,
            0.235,
        ),
        e("anymal_b/anymal.urdf", 30.475397, joint_names(anymal), ["LF_FOOT", "RF_FOOT", "LH_FOOT", "RH_FOOT"], 0.031, 0.4792),
        e("anymal_c/anymal.urdf", 52.13485, joint_names(anymal), ["LF_FOOT", "RF_FOOT", "LH_FOOT", "RH_FOOT"], 0.03, 0.528),
    ]
}

#[test]
fn every_shared_robot_loads_as_in_the_readme() {
    let all = expected();
    // Every URDF in shared/robots/*/ is covered.
    let mut on_disk: Vec<String> = std::fs::read_dir(shared("robots"))
        .unwrap()
        .filter_map(|d| d.ok())
        .filter(|d| d.path().is_dir())
        .flat_map(|d| std::fs::read_dir(d.path()).unwrap().filter_map(|f| f.ok()).map(|f| f.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "urdf"))
        .map(|p| format!("{}/{}", p.parent().unwrap().file_name().unwrap().to_str().unwrap(), p.file_name().unwrap().to_str().unwrap()))
        .collect();
    on_disk.sort();
    let mut listed: Vec<String> = all.iter().map(|(e, _)| e.urdf.to_string()).collect();
    listed.sort();
    assert_eq!(on_disk, listed);

    for (e, joints) in &all {
        let model = urdf::load_file(shared(&format!("robots/{}", e.urdf))).unwrap_or_else(|err| panic!("{err}"));
        let ctx = e.urdf;
        assert_eq!((model.nq, model.nv, model.njoints()), (19, 18, 14), "{ctx}");
        assert_eq!(model.joints[1].name, "root_joint", "{ctx}");
        assert_eq!(model.joints[1].kind, JointKind::FreeFlyer, "{ctx}");
        assert!((model.total_mass() - e.mass).abs() < 1e-5, "{ctx}: mass {} vs {}", model.total_mass(), e.mass);
        assert_eq!(model.actuated_joint_names(), joints.iter().map(String::as_str).collect::<Vec<_>>(), "{ctx}");
        assert!(model.joints.iter().skip(2).all(|j| matches!(j.kind, JointKind::Revolute { .. })), "{ctx}");
        let feet: Vec<&str> = model.feet.iter().map(|f| f.name.as_str()).collect();
        assert_eq!(feet, e.feet, "{ctx}");
        for f in &model.feet {
            assert_eq!(model.frames[f.frame].kind, FrameKind::Body, "{ctx}");
            assert!((f.radius - e.foot_radius).abs() < 1e-12, "{ctx}: {} radius {}", f.name, f.radius);
        }
        let standing = model.reference_configuration("standing").unwrap_or_else(|| panic!("{ctx}: no standing pose"));
        assert_eq!(standing.len(), 19);
        assert!((standing[2] - e.standing_z).abs() < 1e-12, "{ctx}");
        assert!((standing.rows(3, 4).norm() - 1.0).abs() < 1e-12, "{ctx}");
        model.check_configuration(standing).unwrap();

        // Fixed base: the same tree without the free flyer.
        let fixed = urdf::load_file_with_root(shared(&format!("robots/{}", e.urdf)), RootJoint::Fixed).unwrap();
        assert_eq!((fixed.nq, fixed.nv), (12, 12), "{ctx}");
        assert_eq!(fixed.joints[1].parent, 0);
    }
}

#[test]
fn hyq_limits_and_efforts_match_the_readme() {
    let m = urdf::load_file(shared("robots/hyq/hyq_no_sensors.urdf")).unwrap();
    let lim = |n: &str| m.joints[m.joint_id(n).unwrap()].limits.clone();
    let l = lim("lf_kfe_joint");
    assert!((l.lower[0] + 2.4435).abs() < 1e-4 && (l.upper[0] + 0.3491).abs() < 1e-4);
    assert_eq!(l.effort[0], 150.0);
    let l = lim("rh_hfe_joint");
    assert!((l.lower[0] + 1.2217).abs() < 1e-4 && (l.upper[0] - 0.8727).abs() < 1e-4);
    let a1 = urdf::load_file(shared("robots/a1/a1.urdf")).unwrap();
    let l = &a1.joints[a1.joint_id("RR_thigh_joint").unwrap()].limits;
    // [-60, 240] degrees.
    assert!((l.lower[0] + std::f64::consts::FRAC_PI_3).abs() < 1e-12 && (l.upper[0] - 4.0 * std::f64::consts::FRAC_PI_3).abs() < 1e-12);
    assert_eq!((l.effort[0], l.velocity[0]), (33.5, 21.0));
}

#[test]
fn merged_links_become_frames() {
    let m = urdf::load_file(shared("robots/a1/a1.urdf")).unwrap();
    let frame = |name: &str, kind: FrameKind| m.frames.iter().find(|f| f.name == name && f.kind == kind).unwrap();
    // The root link and the trunk welded to it share the free flyer.
    assert_eq!(frame("base", FrameKind::Body).parent_joint, 1);
    assert_eq!(frame("floating_base", FrameKind::Fixed).parent_joint, 1);
    assert_eq!(frame("trunk", FrameKind::Body).parent_joint, 1);
    assert_eq!(frame("imu_link", FrameKind::Body).parent_joint, 1);
    let calf = m.joint_id("FL_calf_joint").unwrap();
    let foot = frame("FL_foot", FrameKind::Body);
    assert_eq!(foot.parent_joint, calf);
    assert!((foot.placement.translation - nalgebra::Vector3::new(0.0, 0.0, -0.2)).norm() < 1e-15);
    assert_eq!(frame("FL_foot_fixed", FrameKind::Fixed).placement, foot.placement);
    // Every joint keeps its joint frame and every link its body frame.
    for j in m.joints.iter().skip(1) {
        frame(&j.name, FrameKind::Joint);
    }
}

// ---------------------------------------------------------------------------------------
// A small URDF and its broken variants
// ---------------------------------------------------------------------------------------

const FILE: &str = "mini.urdf";

/// A two-legged toy: revolute hip, continuous knee, fixed foot; a prismatic leg; an IMU.
const MINI: &str = r#"<?xml version="1.0"?>
<!-- a toy robot for the importer tests -->
<robot name="mini">
  <link name="base">
    <inertial>
      <origin xyz="0.01 0 0" rpy="0 0 0"/>
      <mass value="5"/>
      <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.2" iyz="0" izz="0.25"/>
    </inertial>
  </link>
  <joint name="lf_hip_joint" type="revolute">
    <origin xyz="0.2 0.1 0" rpy="0 0 0"/>
    <parent link="base"/>
    <child link="lf_thigh"/>
    <axis xyz="0 1 0"/>
    <limit lower="-1" upper="1" effort="20" velocity="10"/>
  </joint>
  <link name="lf_thigh">
    <inertial>
      <origin xyz="0 0 -0.1" rpy="0.1 0.2 0.3"/>
      <mass value="1"/>
      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.002"/>
    </inertial>
  </link>
  <joint name="lf_knee_joint" type="continuous">
    <origin xyz="0 0 -0.2" rpy="0 0 0"/>
    <parent link="lf_thigh"/>
    <child link="lf_shank"/>
    <axis xyz="0 1 0"/>
  </joint>
  <link name="lf_shank">
    <inertial>
      <origin xyz="0 0 -0.1" rpy="0 0 0"/>
      <mass value="0.5"/>
      <inertia ixx="0.004" ixy="0" ixz="0" iyy="0.004" iyz="0" izz="0.0005"/>
    </inertial>
  </link>
  <joint name="lf_foot_joint" type="fixed">
    <origin xyz="0 0 -0.2" rpy="0 0 0"/>
    <parent link="lf_shank"/>
    <child link="lf_foot"/>
  </joint>
  <link name="lf_foot">
    <collision>
      <origin xyz="0 0 0" rpy="0 0 0"/>
      <geometry><sphere radius="0.02"/></geometry>
    </collision>
  </link>
  <joint name="rf_slide" type="prismatic">
    <origin xyz="0.2 -0.1 0" rpy="0 0 0"/>
    <parent link="base"/>
    <child link="rf_leg"/>
    <axis xyz="0 0 1"/>
    <limit lower="-0.1" upper="0.1" effort="100" velocity="1"/>
  </joint>
  <link name="rf_leg">
    <inertial>
      <origin xyz="0 0 -0.2" rpy="0 0 0"/>
      <mass value="1.5"/>
      <inertia ixx="0.02" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.001"/>
    </inertial>
  </link>
  <joint name="rf_foot_joint" type="fixed">
    <origin xyz="0 0 -0.4" rpy="0 0 0"/>
    <parent link="rf_leg"/>
    <child link="rf_foot"/>
  </joint>
  <link name="rf_foot"/>
  <joint name="imu_joint" type="fixed">
    <origin xyz="0 0 0.05" rpy="0 0 1.5707963267948966"/>
    <parent link="base"/>
    <child link="imu"/>
  </joint>
  <link name="imu">
    <inertial>
      <mass value="0.1"/>
      <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/>
    </inertial>
  </link>
</robot>
"#;

fn load(xml: &str) -> Result<Model, UrdfError> {
    urdf::from_str(xml, FILE, RootJoint::FreeFlyer)
}

/// `MINI` with `from` (which must occur exactly once) replaced by `to`.
fn mini_with(from: &str, to: &str) -> String {
    assert_eq!(MINI.matches(from).count(), 1, "'{from}' must occur once in MINI");
    MINI.replacen(from, to, 1)
}

/// Loading `xml` fails with `kind`, and the message names the file and every one of `names`.
#[track_caller]
fn assert_error(xml: &str, kind: UrdfErrorKind, names: &[&str]) -> UrdfError {
    let err = match load(xml) {
        Ok(_) => panic!("expected a {kind:?} error, the URDF loaded"),
        Err(e) => e,
    };
    let text = err.to_string();
    assert_eq!(err.kind, kind, "{text}");
    assert!(text.starts_with(FILE), "{text}");
    for n in names {
        assert!(text.contains(n), "'{text}' does not name '{n}'");
    }
    err
}

#[test]
fn the_mini_robot_loads() {
    let m = load(MINI).unwrap();
    assert_eq!((m.nq, m.nv), (10, 9));
    assert_eq!(m.actuated_joint_names(), ["lf_hip_joint", "lf_knee_joint", "rf_slide"]);
    assert!((m.total_mass() - 8.1).abs() < 1e-12);
    // The continuous knee: one coordinate, unbounded.
    let knee = &m.joints[m.joint_id("lf_knee_joint").unwrap()];
    assert_eq!((knee.nq, knee.nv), (1, 1));
    assert_eq!((knee.limits.lower[0], knee.limits.upper[0]), (f64::NEG_INFINITY, f64::INFINITY));
    assert!(matches!(m.joints[m.joint_id("rf_slide").unwrap()].kind, JointKind::Prismatic { .. }));
    // The IMU point mass is lumped into the base.
    let base = &m.inertias[1];
    assert!((base.mass - 5.1).abs() < 1e-12);
    assert!((base.com.x - 0.05 / 5.1).abs() < 1e-12 && (base.com.z - 0.005 / 5.1).abs() < 1e-12);
    // Inertial rpy rotates the thigh's inertia: its trace is invariant, its diagonal is not.
    let thigh = &m.inertias[m.joint_id("lf_hip_joint").unwrap()];
    assert!((thigh.inertia_com.trace() - 0.022).abs() < 1e-12);
    assert!((thigh.inertia_com[(2, 2)] - 0.002).abs() > 1e-5);
    // Feet: LF then RF; radius from the collision sphere (none for rf_foot).
    let feet: Vec<(&str, f64)> = m.feet.iter().map(|f| (f.name.as_str(), f.radius)).collect();
    assert_eq!(feet, [("lf_foot", 0.02), ("rf_foot", 0.0)]);
    // No SRDF from a string.
    assert!(m.reference_configurations.is_empty());
}

#[test]
fn children_are_visited_in_bytewise_joint_name_order() {
    // 'Z' < 'a' bytewise: the prismatic leg renamed "Z_slide" now comes first.
    let xml = MINI.replace("rf_slide", "Z_slide");
    let m = load(&xml).unwrap();
    assert_eq!(m.actuated_joint_names(), ["Z_slide", "lf_hip_joint", "lf_knee_joint"]);
}

#[test]
fn a_fixed_root_is_welded_to_the_world() {
    let m = urdf::from_str(MINI, FILE, RootJoint::Fixed).unwrap();
    assert_eq!((m.nq, m.nv), (3, 3));
    assert_eq!(m.joints[1].parent, 0);
    // The welded base does not count as moving mass.
    assert!((m.total_mass() - 3.0).abs() < 1e-12);
    assert!(m.frames.iter().any(|f| f.name == "base" && f.kind == FrameKind::Body && f.parent_joint == 0));
}

#[test]
fn malformed_xml_names_the_file() {
    // Where the text stops: inside which element.
    let cut = MINI.find("<mass value=\"0.5\"/>").unwrap();
    let e = assert_error(&MINI[..cut], UrdfErrorKind::Xml, &["malformed XML", "ends before </inertial>", "lf_shank"]);
    assert!(e.message.contains("XML"), "{e}");
    assert_error("<robot name='x'><link name='a'></robot>", UrdfErrorKind::Xml, &["</robot> closes <link name=\"a\">"]);
    assert_error(&mini_with("<link name=\"rf_leg\">", "<link name=\"rf_leg\"><visual>"), UrdfErrorKind::Xml, &["</link> closes <visual>", "rf_leg"]);
    assert_error("<robot name='x'><link name='a' mass=1/></robot>", UrdfErrorKind::Xml, &["Line: 1"]);
    assert_error("", UrdfErrorKind::Xml, &[]);
    assert_error(&mini_with("<sphere radius=\"0.02\"/>", "<sphere radius=\"0.02\"/>oops"), UrdfErrorKind::Xml, &["lf_foot", "oops"]);
    assert_error(&mini_with("<sphere radius=\"0.02\"/>", "<cone radius=\"0.02\"/>"), UrdfErrorKind::Xml, &["lf_foot", "cone"]);
    assert_error("<sdf><model/></sdf>", UrdfErrorKind::Xml, &["sdf"]);
    // A value urdf-rs cannot parse: the diagnostic names the link and the attribute.
    assert_error(&mini_with(r#"<mass value="0.5"/>"#, r#"<mass value="heavy"/>"#), UrdfErrorKind::Xml, &["lf_shank", "heavy"]);
    assert_error(&mini_with(r#"<axis xyz="0 0 1"/>"#, r#"<axis xyz="0 1"/>"#), UrdfErrorKind::Xml, &["rf_slide", "axis"]);
    assert_error(&mini_with(r#"<parent link="rf_leg"/>"#, ""), UrdfErrorKind::Xml, &["rf_foot_joint", "parent"]);
}

#[test]
fn a_missing_file_is_an_io_error_naming_it() {
    let e = urdf::load_file("/nonexistent/robot.urdf").unwrap_err();
    assert_eq!(e.kind, UrdfErrorKind::Io);
    assert!(e.to_string().contains("/nonexistent/robot.urdf"), "{e}");
}

#[test]
fn errors_from_files_name_the_path() {
    let dir = std::env::temp_dir().join(format!("legwork-urdf-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("broken.urdf");
    std::fs::write(&path, mini_with(r#"<mass value="1.5"/>"#, r#"<mass value="-1.5"/>"#)).unwrap();
    let e = urdf::load_file(&path).unwrap_err();
    assert!(e.to_string().starts_with(&path.display().to_string()), "{e}");
    assert!(e.to_string().contains("rf_leg"), "{e}");
    // With a valid URDF, an SRDF beside it gives the reference poses.
    std::fs::write(&path, MINI).unwrap();
    std::fs::write(
        dir.join("broken.srdf"),
        r#"<robot name="mini"><group_state name="standing" group="all">
             <joint name="root_joint" value="0 0 0.4 0 0 0 2"/>
             <joint name="lf_hip_joint" value="0.3"/>
             <joint name="lf_foot_joint" value="0"/>
           </group_state></robot>"#,
    )
    .unwrap();
    let m = urdf::load_file(&path).unwrap();
    let q = m.reference_configuration("standing").unwrap();
    assert_eq!(q.as_slice(), &[0.0, 0.0, 0.4, 0.0, 0.0, 0.0, 1.0, 0.3, 0.0, 0.0]);
    // An SRDF naming an unknown joint is an error naming the SRDF and the joint.
    std::fs::write(dir.join("broken.srdf"), r#"<robot><group_state name="standing"><joint name="elbow" value="1"/></group_state></robot>"#)
        .unwrap();
    let e = urdf::load_file(&path).unwrap_err();
    assert_eq!(e.kind, UrdfErrorKind::Srdf);
    assert!(e.to_string().contains("broken.srdf") && e.to_string().contains("elbow"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_moving_link_without_mass_is_refused() {
    // No <inertial> at all on the shank (nothing massive fixed to it: the foot is massless).
    let no_inertial = {
        let start = MINI.find("<link name=\"lf_shank\">").unwrap();
        let end = start + MINI[start..].find("</link>").unwrap();
        format!("{}<link name=\"lf_shank\">{}", &MINI[..start], &MINI[end..])
    };
    assert_error(&no_inertial, UrdfErrorKind::MissingInertial, &["lf_knee_joint", "lf_shank"]);
    assert_error(
        &mini_with(r#"<mass value="0.5"/>"#, r#"<mass value="0"/>"#).replace(
            r#"<inertia ixx="0.004" ixy="0" ixz="0" iyy="0.004" iyz="0" izz="0.0005"/>"#,
            r#"<inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/>"#,
        ),
        UrdfErrorKind::MissingInertial,
        &["lf_knee_joint", "lf_shank"],
    );
    // ...but a massless link is fine when a massive one is fixed to it.
    let lumped = no_inertial.replace(
        r#"<link name="lf_foot">"#,
        r#"<link name="lf_foot"><inertial><mass value="0.2"/><inertia ixx="1e-4" ixy="0" ixz="0" iyy="1e-4" iyz="0" izz="1e-4"/></inertial>"#,
    );
    let m = load(&lumped).unwrap();
    let knee = m.joint_id("lf_knee_joint").unwrap();
    assert!((m.inertias[knee].mass - 0.2).abs() < 1e-15);
    assert!((m.inertias[knee].com.z + 0.2).abs() < 1e-15);
}

#[test]
fn bad_masses_and_inertias_are_refused() {
    assert_error(&mini_with(r#"<mass value="1.5"/>"#, r#"<mass value="-1.5"/>"#), UrdfErrorKind::BadMass, &["rf_leg", "-1.5"]);
    assert_error(&mini_with(r#"<mass value="1.5"/>"#, r#"<mass value="NaN"/>"#), UrdfErrorKind::NotFinite, &["rf_leg"]);
    // Not positive semi-definite.
    assert_error(
        &mini_with(r#"ixx="0.02" ixy="0" ixz="0" iyy="0.02""#, r#"ixx="-0.02" ixy="0" ixz="0" iyy="0.02""#),
        UrdfErrorKind::BadInertia,
        &["rf_leg"],
    );
    // Positive definite but unphysical (triangle inequality) on a moving body.
    assert_error(
        &mini_with(r#"ixx="0.02" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.001""#, r#"ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.05""#),
        UrdfErrorKind::BadInertia,
        &["rf_slide", "rf_leg"],
    );
    // A point mass alone on a moving joint has no rotational inertia: not positive definite.
    assert_error(
        &mini_with(r#"ixx="0.02" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.001""#, r#"ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0""#),
        UrdfErrorKind::BadInertia,
        &["rf_slide", "rf_leg"],
    );
}

#[test]
fn joint_types_are_checked() {
    assert_error(&mini_with(r#"type="continuous""#, r#"type="bendy""#), UrdfErrorKind::UnknownJointType, &["lf_knee_joint", "bendy"]);
    assert_error(&mini_with(r#"<joint name="lf_knee_joint" type="continuous">"#, r#"<joint name="lf_knee_joint">"#), UrdfErrorKind::UnknownJointType, &["lf_knee_joint"]);
    for t in ["floating", "planar", "spherical"] {
        assert_error(&mini_with(r#"type="prismatic""#, &format!(r#"type="{t}""#)), UrdfErrorKind::UnsupportedJointType, &["rf_slide", t]);
    }
}

#[test]
fn the_tree_is_checked() {
    // A joint naming a link that does not exist.
    assert_error(&mini_with(r#"<child link="rf_leg"/>"#, r#"<child link="rf_legg"/>"#), UrdfErrorKind::MissingLink, &["rf_slide", "rf_legg"]);
    assert_error(&mini_with(r#"<parent link="lf_shank"/>"#, r#"<parent link="shank"/>"#), UrdfErrorKind::MissingLink, &["lf_foot_joint", "shank"]);
    // A link with two parents.
    let two_parents = MINI.replace(
        "</robot>",
        r#"<joint name="extra" type="fixed"><parent link="base"/><child link="lf_foot"/></joint></robot>"#,
    );
    assert_error(&two_parents, UrdfErrorKind::TwoParents, &["lf_foot", "lf_foot_joint", "extra"]);
    // A loop through the root: no root left.
    let through_root = MINI.replace(
        "</robot>",
        r#"<joint name="back" type="fixed"><parent link="rf_foot"/><child link="base"/></joint></robot>"#,
    );
    assert_error(&through_root, UrdfErrorKind::KinematicLoop, &["loop"]);
    // A loop beside the tree: its links are unreachable.
    let side_loop = MINI.replace(
        "</robot>",
        r#"<link name="p"/><link name="r"/>
           <joint name="p_to_r" type="fixed"><parent link="p"/><child link="r"/></joint>
           <joint name="r_to_p" type="fixed"><parent link="r"/><child link="p"/></joint></robot>"#,
    );
    assert_error(&side_loop, UrdfErrorKind::KinematicLoop, &["p", "r"]);
    // Two roots.
    assert_error(&MINI.replace("</robot>", r#"<link name="orphan"/></robot>"#), UrdfErrorKind::Root, &["orphan", "base"]);
    // Duplicate names.
    assert_error(&MINI.replace("</robot>", r#"<link name="imu"/></robot>"#), UrdfErrorKind::DuplicateName, &["imu"]);
    assert_error(
        &MINI.replace("</robot>", r#"<link name="imu2"/><joint name="imu_joint" type="fixed"><parent link="base"/><child link="imu2"/></joint></robot>"#),
        UrdfErrorKind::DuplicateName,
        &["imu_joint"],
    );
    // A joint clashing with the free flyer's name.
    assert_error(&MINI.replace("rf_slide", "root_joint"), UrdfErrorKind::Model, &["root_joint"]);
}

#[test]
fn non_finite_numbers_are_refused() {
    assert_error(&mini_with(r#"<origin xyz="0.2 -0.1 0" rpy="0 0 0"/>"#, r#"<origin xyz="0.2 NaN 0" rpy="0 0 0"/>"#), UrdfErrorKind::NotFinite, &["rf_slide", "origin"]);
    assert_error(&mini_with(r#"<origin xyz="0 0 -0.4" rpy="0 0 0"/>"#, r#"<origin xyz="0 0 -0.4" rpy="0 inf 0"/>"#), UrdfErrorKind::NotFinite, &["rf_foot_joint"]);
    assert_error(&mini_with(r#"<origin xyz="0 0 -0.1" rpy="0.1 0.2 0.3"/>"#, r#"<origin xyz="0 0 nan" rpy="0.1 0.2 0.3"/>"#), UrdfErrorKind::NotFinite, &["lf_thigh", "inertial"]);
    assert_error(&mini_with(r#"iyy="0.004" iyz="0" izz="0.0005""#, r#"iyy="0.004" iyz="NaN" izz="0.0005""#), UrdfErrorKind::NotFinite, &["lf_shank"]);
    assert_error(&mini_with(r#"<limit lower="-1" upper="1""#, r#"<limit lower="NaN" upper="1""#), UrdfErrorKind::NotFinite, &["lf_hip_joint", "lower"]);
    assert_error(&mini_with(r#"<axis xyz="0 0 1"/>"#, r#"<axis xyz="0 0 NaN"/>"#), UrdfErrorKind::NotFinite, &["rf_slide", "axis"]);
    assert_error(&mini_with(r#"<sphere radius="0.02"/>"#, r#"<sphere radius="nan"/>"#), UrdfErrorKind::NotFinite, &["lf_foot"]);
    assert_error(
        &mini_with(r#"<axis xyz="0 0 1"/>"#, r#"<axis xyz="0 0 1"/><dynamics damping="NaN" friction="0"/>"#),
        UrdfErrorKind::NotFinite,
        &["rf_slide", "damping"],
    );
}

#[test]
fn axes_and_limits_are_checked() {
    assert_error(&mini_with(r#"<axis xyz="0 0 1"/>"#, r#"<axis xyz="0 0 0"/>"#), UrdfErrorKind::BadAxis, &["rf_slide", "zero"]);
    assert_error(&mini_with(r#"<axis xyz="0 0 1"/>"#, r#"<axis xyz="0 0 2"/>"#), UrdfErrorKind::BadAxis, &["rf_slide", "unit"]);
    // Rounded unit axes are accepted and normalised.
    let m = load(&mini_with(r#"<axis xyz="0 0 1"/>"#, r#"<axis xyz="0 0.7071 0.7071"/>"#)).unwrap();
    match m.joints[m.joint_id("rf_slide").unwrap()].kind {
        JointKind::Prismatic { axis } => assert!((axis.norm() - 1.0).abs() < 1e-15),
        k => panic!("{k:?}"),
    }
    assert_error(&mini_with(r#"<limit lower="-1" upper="1""#, r#"<limit lower="1" upper="-1""#), UrdfErrorKind::BadLimits, &["lf_hip_joint", "lower"]);
    assert_error(&mini_with(r#"effort="20""#, r#"effort="-20""#), UrdfErrorKind::BadLimits, &["lf_hip_joint", "effort"]);
    assert_error(&mini_with(r#"<limit lower="-0.1" upper="0.1" effort="100" velocity="1"/>"#, ""), UrdfErrorKind::BadLimits, &["rf_slide", "limit"]);
}

#[test]
fn the_srdf_parser_checks_its_input() {
    let mut m = load(MINI).unwrap();
    let err = |srdf: &str| urdf::add_srdf_states(&mut m.clone(), srdf, "mini.srdf").unwrap_err().to_string();
    assert!(err("<robot><group_state name='s'><joint name='lf_hip_joint' value='x'/></group_state></robot>").contains("lf_hip_joint"));
    assert!(err("<robot><group_state name='s'><joint name='root_joint' value='0 0 0 0 0 0 0'/></group_state></robot>").contains("quaternion"));
    assert!(err("<robot><group_state name='s'><joint name='root_joint' value='0 0 0'/></group_state></robot>").contains("7"));
    assert!(err("<robot><group_state name='s'><joint name='lf_hip_joint' value='inf'/></group_state></robot>").contains("finite"));
    assert!(err("<robot><group_state").starts_with("mini.srdf: malformed XML"));
    let added = urdf::add_srdf_states(&mut m, "<robot><group_state name='a'/><group_state name='b'><joint name='rf_slide' value='0.05'/></group_state></robot>", "x").unwrap();
    assert_eq!(added, ["a", "b"]);
    assert_eq!(m.reference_configuration("b").unwrap()[9], 0.05);
}

#[test]
fn foot_prefixes_give_the_lf_rf_lh_rh_order() {
    for (name, rank) in [
        ("lf_foot", 0), ("FL_FOOT", 0), ("rf_foot", 1), ("FR_foot", 1),
        ("lh_foot", 2), ("HL_FOOT", 2), ("RL_foot", 2), ("rh_foot", 3), ("HR_FOOT", 3), ("RR_foot", 3),
        ("lffoot", 0), ("left_foot", 4), ("foot", 4), ("rhino_foot", 4),
    ] {
        assert_eq!(urdf::foot_rank(name), rank, "{name}");
    }
}

// ---------------------------------------------------------------------------------------
// Robustness: mutated URDFs never panic
// ---------------------------------------------------------------------------------------

fn a1_urdf() -> &'static str {
    static A1: std::sync::OnceLock<String> = std::sync::OnceLock::new();
    A1.get_or_init(|| std::fs::read_to_string(shared("robots/a1/a1.urdf")).unwrap())
}

/// Loading must return (Ok or a named error), never panic; errors always name the file.
fn must_not_panic(xml: &str) -> Result<(), TestCaseError> {
    match urdf::from_str(xml, FILE, RootJoint::FreeFlyer) {
        Ok(m) => {
            prop_assert!(m.nq >= 7);
        }
        Err(e) => {
            prop_assert!(e.to_string().starts_with(FILE));
            prop_assert!(!e.message.is_empty());
        }
    }
    Ok(())
}

const POISON: [&str; 8] = ["NaN", "-1", "0", "inf", "-inf", "1e308", "", "0 0"];

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, .. ProptestConfig::default() })]

    #[test]
    fn truncated_urdfs_never_panic(cut in 0usize..MINI.len(), big in any::<bool>()) {
        let src = if big { a1_urdf() } else { MINI };
        let cut = cut * src.len() / MINI.len();
        let cut = (0..=cut).rev().find(|&c| src.is_char_boundary(c)).unwrap_or(0);
        must_not_panic(&src[..cut])?;
    }

    #[test]
    fn byte_edits_never_panic(edits in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>(), 0u8..3), 1..8), big in any::<bool>()) {
        let mut bytes = if big { a1_urdf() } else { MINI }.as_bytes().to_vec();
        for (at, byte, op) in edits {
            if bytes.is_empty() { break; }
            let i = at.index(bytes.len());
            match op {
                0 => bytes[i] = byte,
                1 => { bytes.remove(i); }
                _ => bytes.insert(i, byte),
            }
        }
        must_not_panic(&String::from_utf8_lossy(&bytes))?;
    }

    #[test]
    fn poisoned_numbers_never_panic(picks in prop::collection::vec((any::<prop::sample::Index>(), 0usize..POISON.len()), 1..4), big in any::<bool>()) {
        let mut s = if big { a1_urdf() } else { MINI }.to_string();
        for (at, p) in picks {
            let spans = number_spans(&s);
            let (a, b) = spans[at.index(spans.len())];
            s.replace_range(a..b, POISON[p]);
        }
        must_not_panic(&s)?;
    }
}

#[test]
fn every_single_number_poisoned_gives_ok_or_a_named_error() {
    // Exhaustive over the toy: each number replaced by each poison value.
    for (a, b) in number_spans(MINI) {
        for p in POISON {
            let mut s = MINI.to_string();
            s.replace_range(a..b, p);
            if let Err(e) = load(&s) {
                assert!(e.to_string().starts_with(FILE), "{e}");
            }
        }
    }
}

/// A chain of `n` revolute joints, each link 1 kg, as URDF text; with `wide`, `n` fixed
/// links hang off the base instead.
fn generated(n: usize, wide: bool) -> String {
    let link = |name: String| format!(r#"<link name="{name}"><inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>"#);
    let mut text = String::from(r#"<robot name="generated">"#);
    text += &link("l0".into());
    for i in 1..=n {
        text += &link(format!("l{i}"));
        let (parent, kind, limit) = if wide { ("l0".to_string(), "fixed", "") } else { (format!("l{}", i - 1), "revolute", r#"<limit lower="-1" upper="1" effort="10" velocity="1"/>"#) };
        text += &format!(r#"<joint name="j{i}" type="{kind}"><parent link="{parent}"/><child link="l{i}"/><axis xyz="0 0 1"/>{limit}</joint>"#);
    }
    text + "</robot>"
}

/// Deep input is refused with the limit named, before any recursion can overflow the stack
/// (30,000 nested elements aborted the process; a 30,000-joint chain took 16 s and 2.4 GB).
#[test]
fn deep_xml_and_deep_trees_are_refused_with_their_limits() {
    let nested = format!("<robot name=\"r\">{}{}</robot>", "<a>".repeat(30_000), "</a>".repeat(30_000));
    let e = assert_error(&nested, UrdfErrorKind::TooDeep, &["nest 65 deep", "at most 64"]);
    assert!(!e.to_string().contains("panicked"));
    // Comments, CDATA and self-closing elements do not count as nesting.
    let flat = format!("<robot name=\"r\"><!-- {} --><![CDATA[{}]]>{}</robot>", "<a>".repeat(100), "<b>".repeat(100), "<c/>".repeat(100));
    assert!(!matches!(load(&flat), Err(UrdfError { kind: UrdfErrorKind::TooDeep, .. })));
    assert_error(&generated(300, false), UrdfErrorKind::TooDeep, &["joint 'j257' is 257 joints from the root link", "at most 256"]);
    // At the limit, the chain loads.
    let model = load(&generated(255, false)).unwrap();
    assert_eq!(model.nv, 6 + 255);
}

/// A wide tree (fixed links merged into the base) loads with every link as a frame; frame
/// names are checked for uniqueness by a hash, not by a scan of the frames so far.
#[test]
fn wide_trees_load_with_every_link_a_frame() {
    let model = load(&generated(5_000, true)).unwrap();
    assert_eq!(model.nv, 6);
    assert!(model.frame_id("l4999").is_ok());
    let mass: f64 = model.inertias.iter().map(|i| i.mass).sum();
    assert!((mass - 5_001.0).abs() < 1e-6, "{mass}");
}
