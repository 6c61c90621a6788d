//! `legwork robot list` and `legwork robot info`, run as a user would.

use std::process::{Command, Output};

fn legwork(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_legwork")).args(args).current_dir(env!("CARGO_MANIFEST_DIR")).output().unwrap()
}

fn stdout(o: &Output) -> String {
    String::from_utf8(o.stdout.clone()).unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8(o.stderr.clone()).unwrap()
}

#[test]
fn robot_list_shows_every_embedded_robot_with_a_summary() {
    let o = legwork(&["robot", "list"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(lines.len(), 2, "{out}");
    assert!(lines[0].starts_with("hyq ") && lines[0].contains("HyQ"), "{out}");
    assert!(lines[1].starts_with("a1 ") && lines[1].contains("Unitree A1"), "{out}");
}

#[test]
fn robot_info_of_an_embedded_robot() {
    let o = legwork(&["robot", "info", "hyq"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    for expected in [
        "hyq (embedded): IIT HyQ",
        "nq = 19, nv = 18, 13 joints, 4 feet",
        "    lf_haa_joint      revolute   axis (-1, 0, 0)",
        "total mass 86.774 kg",
        "<- foot LF, radius 0.02175 m",
        "-1.2217 (-70.0°) .. 0.4363 (25.0°)",
        "base height 0.5775 m",
        "LF  lf_foot  (0.3708, 0.3241, 0.0000)",
        "RH  rh_foot  (-0.3708, -0.3241, 0.0000)",
    ] {
        assert!(out.contains(expected), "missing '{expected}' in\n{out}");
    }
    let out = stdout(&legwork(&["robot", "info", "a1"]));
    assert!(out.contains("total mass 13.741 kg") && out.contains("FL_calf_joint") && out.contains("base height 0.2600 m"), "{out}");
}

#[test]
fn robot_info_of_a_urdf_and_of_a_description_file() {
    let o = legwork(&["robot", "info", "../shared/robots/a1/a1.urdf"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(out.starts_with("a1 (from ../shared/robots/a1/a1.urdf)"), "{out}");
    assert!(out.contains("total mass 13.741 kg") && out.contains("base height 0.2600 m"), "{out}");

    let o = legwork(&["robot", "info", "robots/hyq.toml"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("total mass 86.774 kg"));
}

#[test]
fn bad_input_fails_with_a_message_naming_it() {
    let o = legwork(&["robot", "info", "spot"]);
    assert!(!o.status.success());
    assert_eq!(stderr(&o).trim(), "error: 'spot' is neither an embedded robot (hyq, a1) nor a .urdf file nor a legwork robot description (.toml)");

    let dir = std::env::temp_dir().join(format!("legwork-cli-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("broken.toml");
    let src = include_str!("../robots/a1.toml").replacen("mass = 1.013", "mass = -1.013", 1);
    std::fs::write(&file, src).unwrap();
    let o = legwork(&["robot", "info", file.to_str().unwrap()]);
    std::fs::remove_dir_all(&dir).ok();
    assert!(!o.status.success());
    assert_eq!(stderr(&o).trim(), format!("error: {}: thigh.mass: expected a finite positive mass in kg, got -1.013", file.display()));

    let o = legwork(&["robot", "info", "missing.urdf"]);
    assert!(!o.status.success());
    assert!(stderr(&o).starts_with("error: missing.urdf: cannot read"), "{}", stderr(&o));
}
