//! The seven embedded jump files: they load, and they are the jumps of the reference
//! script (`../shared/anchors/nguyen2022/contact_timing.py`, its `JUMPS`); their boxes.

use legwork::jump::{embedded_jumps, Jump};
use legwork::srb::SrbParams;
use legwork::terrain::Terrain;
use nalgebra::Vector3;
use std::f64::consts::PI;

const ALL: [bool; 4] = [true; 4];
const NONE: [bool; 4] = [false; 4];
const RIGHT: [bool; 4] = [false, true, false, true];
const REAR: [bool; 4] = [false, false, true, true];

/// `(file, script name, displacement, axis, angle, box, phases, [T_min, T_max], paper's T)`
/// as the script defines them.
#[allow(clippy::type_complexity)]
fn reference() -> Vec<(&'static str, &'static str, [f64; 3], [f64; 3], f64, f64, Vec<[bool; 4]>, (f64, f64), Vec<f64>)> {
    vec![
        ("lateral", "lateral30", [0.0, 0.3, 0.0], [0.0, 0.0, 1.0], 0.0, 0.0, vec![ALL, NONE], (0.5, 1.5), vec![50.0, 28.0]),
        ("lateral_down", "lateral_down", [0.0, 0.3, -0.3], [0.0, 0.0, 1.0], 0.0, 0.3, vec![ALL, NONE], (0.5, 1.5), vec![52.0, 35.0]),
        ("spin_90", "spin90", [0.0, 0.0, 0.0], [0.0, 0.0, 1.0], PI / 2.0, 0.0, vec![ALL, NONE], (0.5, 1.5), vec![56.0, 31.0]),
        ("diagonal", "diagonal", [0.4, -0.3, 0.0], [0.0, 0.0, 1.0], PI / 4.0, 0.0, vec![ALL, REAR, NONE], (1.0, 2.0), vec![54.0, 30.0, 33.0]),
        ("barrel_roll", "barrel_roll", [0.0, 0.2, -0.4], [1.0, 0.0, 0.0], -2.0 * PI, 0.4, vec![ALL, RIGHT, NONE], (1.0, 2.0), vec![51.0, 32.0, 35.0]),
        ("double_barrel_roll", "double_barrel_roll", [0.0, 0.3, -0.9], [1.0, 0.0, 0.0], -4.0 * PI, 0.9, vec![ALL, RIGHT, NONE], (1.0, 2.0), vec![52.0, 34.0, 55.0]),
        ("double_backflip", "double_backflip", [-0.3, 0.0, -2.0], [0.0, 1.0, 0.0], -4.0 * PI, 2.0, vec![ALL, REAR, NONE], (1.0, 2.0), vec![50.0, 33.0, 69.0]),
    ]
}

#[test]
fn the_seven_files_are_the_reference_jumps() {
    let jumps = embedded_jumps().unwrap();
    assert_eq!(jumps.len(), 7);
    for (jump, (name, anchor, d, axis, angle, height, phases, total, paper)) in jumps.iter().zip(reference()) {
        assert_eq!(jump.name, name);
        assert_eq!(jump.anchor, Some(anchor));
        assert_eq!(jump.robot, "a1");
        // The script's problem is the reference variant (the files land clear of the box).
        let s = jump.reference_srb();
        assert_eq!(s.displacement, Vector3::from(d), "{name}");
        assert_eq!(s.axis, Vector3::from(axis), "{name}");
        // Degrees and turns convert to radians within one rounding.
        assert!((s.angle - angle).abs() <= 4.0 * f64::EPSILON * angle.abs(), "{name}: {} vs {angle}", s.angle);
        assert_eq!(s.box_height, height, "{name}");
        assert_eq!(s.phases, phases, "{name}");
        assert_eq!(s.total_time, total, "{name}");
        assert_eq!(jump.paper.as_ref().unwrap().timings_10ms, paper, "{name}");
        // The formulation's settings are the defaults: no file overrides them.
        assert_eq!(jump.contact_timing, Default::default(), "{name}");
    }
}

#[test]
fn srb_jumps_are_the_files_under_the_script_names() {
    let names: Vec<&str> = legwork::srb::jumps().iter().map(|j| j.name).collect();
    assert_eq!(names, ["lateral30", "lateral_down", "spin90", "diagonal", "barrel_roll", "double_barrel_roll", "double_backflip"]);
    for (spec, file) in legwork::srb::jumps().into_iter().zip(embedded_jumps().unwrap()) {
        assert_eq!(legwork::srb::JumpSpec { name: file.srb().name, ..spec }, file.srb());
    }
    for (spec, file) in legwork::srb::reference_jumps().into_iter().zip(embedded_jumps().unwrap()) {
        assert_eq!(legwork::srb::JumpSpec { name: file.srb().name, ..spec }, file.reference_srb());
    }
}

#[test]
fn boxes_carry_the_start_stance_and_the_conflicting_landings_are_named() {
    let params = SrbParams::a1().unwrap();
    let radius = 0.02;
    for jump in embedded_jumps().unwrap() {
        let terrain = jump.terrain();
        assert_eq!(terrain.height(0.0, 0.0), jump.box_height(), "{}", jump.name);
        assert_eq!(terrain.height(5.0, 5.0), 0.0);
        // Every start foot stands on the box and every landing foot is at least ~5 cm clear
        // of it (the files' landing offsets).
        let conflicts = jump.stance_conflicts(&params, 0.049);
        assert!(conflicts.is_empty(), "{}: {conflicts:?}", jump.name);
        // The script's own targets land the barrel roll (0.2 m to the side) and the backflip
        // (0.3 m back) over the box.
        let reference = jump.reference();
        let landing: Vec<&str> = reference.stance_conflicts(&params, radius).iter().map(|c| c.foot).collect();
        let expected: &[&str] = match jump.name.as_str() {
            "barrel_roll" => &["RF", "RH"],
            "double_backflip" => &["LF", "RF"],
            _ => &[],
        };
        assert_eq!(landing, expected, "{}", jump.name);
    }
    // The double barrel roll's right feet land 5.0 cm beyond the box edge (the script's:
    // 2.04 cm, one foot radius).
    let j = Jump::embedded("double_barrel_roll").unwrap();
    assert!(j.stance_conflicts(&params, 0.050).is_empty());
    assert_eq!(j.stance_conflicts(&params, 0.051).len(), 2);
    let script = j.reference();
    assert!(script.stance_conflicts(&params, 0.020).is_empty());
    assert_eq!(script.stance_conflicts(&params, 0.021).len(), 2);
}
