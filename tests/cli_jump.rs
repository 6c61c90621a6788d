//! `legwork jump` and `legwork bench jumps` as a user runs them, in a short form (8 knots per
//! phase): the exit code of the outcome, the files written, the summary's figures against
//! the printed ones, bad input refused with a named error. The outcome itself (landed, fell)
//! is the controllers' and is reported, not asserted: the exit code must say it.

use legwork::io::Trajectory;
use serde_json::Value;
use std::path::PathBuf;
use std::process::{Command, Output};

fn legwork(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_legwork")).args(args).current_dir(env!("CARGO_MANIFEST_DIR")).output().unwrap()
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8(bytes.to_vec()).unwrap()
}

fn out_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("legwork-cli-jump-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

#[test]
fn lateral_jump_end_to_end_in_short_form() {
    let dir = out_dir("lateral");
    let out = legwork(&["jump", "lateral", "--knots", "8", "--out", dir.to_str().unwrap()]);
    let stdout = text(&out.stdout);
    let code = out.status.code().unwrap();
    let traj = Trajectory::load_file(dir.join("contact_timing.json")).unwrap();
    assert_eq!(traj.metadata.robot, "a1");
    assert_eq!(traj.knots.len(), 2 * 8 + 1);
    let s = &traj.summary;
    // The exit code is the verdict's, printed and in the summary.
    let verdict = s["verdict"].as_str().unwrap();
    let expected = match verdict { "Landed" => 0, "MissedTarget" | "Fell" => 1, "ContactTimingFailed" | "FullBodyFailed" => 3, other => panic!("verdict {other}") };
    assert_eq!(code, expected, "{stdout}\n{}", text(&out.stderr));
    assert_eq!(s["exit_code"], code);
    assert!(stdout.contains("8 knots each") && stdout.contains(&format!("(exit code {code})")), "{stdout}");
    let ct = &s["contact_timing"];
    assert_eq!(ct["status"], "Solved");
    assert_eq!(ct["knots_per_phase"], 8);
    let durations: Vec<f64> = ct["phase_durations_s"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
    // The knots' times are the optimal durations, the total within [T_min, T_max].
    assert!((traj.duration() - durations.iter().sum::<f64>()).abs() < 1e-9, "{} vs {durations:?}", traj.duration());
    assert!((0.5..=1.5).contains(&traj.duration()));
    let printed = format!("phase durations [10 ms]: {}", ct["phase_durations_10ms"].as_array().unwrap().iter().map(|v| format!("{:.1}", v.as_f64().unwrap())).collect::<Vec<_>>().join(", "));
    assert!(stdout.contains(&printed), "{printed} not in {stdout}");
    // The plan lands 0.3 m to the side: the last knot's base moved by the displacement.
    let (q0, q1) = (&traj.knots[0].q, &traj.knots.last().unwrap().q);
    assert!((q1[1] - q0[1] - 0.3).abs() < 1e-6 && (q1[0] - q0[0]).abs() < 1e-6, "{:?} -> {:?}", &q0[..3], &q1[..3]);
    // Stance: every foot in contact with a force; flight: none.
    assert!(traj.knots[0].in_contact.iter().all(|&c| c) && traj.knots[0].contact_force.iter().all(|f| f[2] > 0.0));
    assert!(traj.knots[10].in_contact.iter().all(|&c| !c));
    // The short form plans end to end: the full-body plan (10 ms knots, within its limits)
    // and the controllers' re-run are written.
    assert_eq!(s["full_body_stage"], "done", "{stdout}");
    assert_eq!(s["full_body"]["limits_met"], true);
    let plan = Trajectory::load_file(dir.join("trajectory.json")).unwrap();
    assert!((plan.metadata.dt - 0.01).abs() < 1e-12 && (plan.duration() - traj.duration()).abs() < 0.011, "{} vs {}", plan.duration(), traj.duration());
    assert_eq!(plan.summary["contact_timing"], s["contact_timing"]);
    let rerun = Trajectory::load_file(dir.join("rerun.json")).unwrap();
    assert!(rerun.duration() > plan.duration(), "the re-run goes on after the landing");
    let error = s["rerun"]["position_error_m"].as_f64().unwrap();
    assert!(stdout.contains(&format!("landing error {:.1} mm", 1e3 * error)), "{stdout}");
    for file in ["replay.html", "plots/phase_timings.svg", "plots/contact_timing_forces.svg", "plots/contact_timing_pose.svg", "plots/plan_ground_forces.svg", "plots/plan_torques.svg", "plots/rerun_torques.svg", "plots/plan/base_pose.svg"] {
        let bytes = std::fs::metadata(dir.join(file)).map(|m| m.len()).unwrap_or(0);
        assert!(bytes > 1000, "{file}: {bytes} bytes");
    }
    let svg = std::fs::read_to_string(dir.join("plots/phase_timings.svg")).unwrap();
    assert!(svg.contains("Nguyen 2022, Table I: 50.0, 28.0"), "the paper's row is drawn");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_box_jump_writes_its_box_and_names_the_conflicts() {
    // The barrel roll with the reference script's landing target (0.2 m to +y, over the
    // box; the embedded file lands 0.36 m to +y, clear of it).
    let dir = out_dir("barrel");
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("barrel_roll_script_target.toml");
    let barrel = std::fs::read_to_string(format!("{}/jumps/barrel_roll.toml", env!("CARGO_MANIFEST_DIR"))).unwrap();
    std::fs::write(&file, barrel.replace("displacement = [0.0, 0.36, -0.4]", "displacement = [0.0, 0.2, -0.4]")).unwrap();
    let out = legwork(&["jump", file.to_str().unwrap(), "--knots", "6", "--out", dir.to_str().unwrap()]);
    let stdout = text(&out.stdout);
    assert!(matches!(out.status.code(), Some(1 | 3)), "{stdout}\n{}", text(&out.stderr));
    assert!(stdout.contains("warning: RF lands at (0.215, 0.067), over the box"), "{stdout}");
    let traj = Trajectory::load_file(dir.join("contact_timing.json")).unwrap();
    let terrain: Value = serde_json::to_value(&traj.metadata.terrain).unwrap();
    assert_eq!(terrain["kind"], "boxes");
    assert_eq!(terrain["boxes"][0]["top"], 0.4);
    let html = std::fs::read_to_string(dir.join("replay.html")).unwrap();
    assert!(html.contains("\"boxes\":[[-0.5,0.5,-0.5,0.17,0.0,0.4]]"), "the replay draws the box");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bad_jumps_are_refused_with_exit_code_2() {
    let out = legwork(&["jump", "moonwalk"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(text(&out.stderr).contains("no embedded jump named 'moonwalk'"), "{}", text(&out.stderr));
    let dir = out_dir("bad");
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("bad.toml");
    let lateral = std::fs::read_to_string(format!("{}/jumps/lateral.toml", env!("CARGO_MANIFEST_DIR"))).unwrap();
    std::fs::write(&file, lateral.replace("angle_deg = 0.0", "angle_deg = 0.0\nturns = 1.0")).unwrap();
    let out = legwork(&["jump", file.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let e = text(&out.stderr);
    assert!(e.contains("bad.toml: field `target`: expected exactly one of `angle_deg` and `turns`"), "{e}");
    let out = legwork(&["jump", "lateral", "--trials", "1000000"]);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out.stderr));
    assert!(text(&out.stderr).contains("--trials: expected at most 1000"), "{}", text(&out.stderr));
    // 0 knots, and a billion (which aborted on its allocation): refused with the range.
    for knots in ["0", "1000000000"] {
        let out = legwork(&["jump", "lateral", "--knots", knots]);
        assert_eq!(out.status.code(), Some(2), "{}", text(&out.stderr));
        assert!(text(&out.stderr).contains("knots_per_phase") && text(&out.stderr).contains("between 1 and 1000"), "{}", text(&out.stderr));
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bench_jumps_json_has_a_row_per_jump() {
    let out = legwork(&["bench", "jumps", "--json", "--repeats", "1", "--knots", "6", "--trials", "0", "--jumps", "lateral,double_backflip"]);
    let v: Value = serde_json::from_slice(&out.stdout).unwrap_or_else(|e| panic!("not JSON ({e}): {}", text(&out.stderr)));
    // No trials, so no row meets the targets (every trial landed): the verdict is "missed",
    // exit code 1, the same in the JSON.
    assert_eq!(v["meets_targets"], serde_json::json!([false, false]));
    assert_eq!((v["verdict"].as_str(), v["exit_code"].as_i64()), (Some("missed"), Some(1)));
    assert_eq!(out.status.code(), Some(1), "{}", text(&out.stderr));
    let rows = v["jumps"].as_array().unwrap();
    let names: Vec<&str> = rows.iter().map(|r| r["jump"].as_str().unwrap()).collect();
    assert_eq!(names, ["lateral", "double_backflip"]);
    for r in rows {
        let phases = r["paper"]["timings_10ms"].as_array().unwrap().len();
        assert_eq!(r["phase_durations_10ms"].as_array().unwrap().len(), phases, "{r}");
        assert!(r["contact_timing_min_s"].as_f64().unwrap() > 0.0);
        // No trials asked for: no success rate; a stage without a figure says why.
        assert!(r["success_rate"].is_null() && r["trials"] == 0, "{r}");
        let notes: Vec<&str> = r["notes"].as_array().unwrap().iter().map(|n| n.as_str().unwrap()).collect();
        if r["full_body_solve_s"].is_null() {
            assert!(notes.iter().any(|n| n.starts_with("full body: ")), "{r}");
        }
        if r["landing_error_m"].is_null() {
            assert!(notes.iter().any(|n| n.starts_with("controllers: ") || n.starts_with("full body: ")), "{r}");
        }
    }
}

#[test]
fn control_serve_answers_states_with_torques_and_refuses_bad_requests() {
    use std::io::{BufRead, BufReader, Write};
    let dir = out_dir("serve");
    let out = legwork(&["jump", "lateral", "--knots", "8", "--out", dir.to_str().unwrap()]);
    assert!(matches!(out.status.code(), Some(0 | 1)), "{}", text(&out.stdout));
    let plan_path = dir.join("trajectory.json");
    let plan = Trajectory::load_file(&plan_path).unwrap();
    let mut server = Command::new(env!("CARGO_BIN_EXE_legwork"))
        .args(["control", "serve", "--reference", plan_path.to_str().unwrap()])
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut input = server.stdin.take().unwrap();
    let mut output = BufReader::new(server.stdout.take().unwrap());
    let k = &plan.knots[0];
    let mut ask = |line: String| {
        writeln!(input, "{line}").unwrap();
        let mut reply = String::new();
        output.read_line(&mut reply).unwrap();
        serde_json::from_str::<Value>(&reply).unwrap()
    };
    // The plan's first state with its forces: the jump controller's torques, near the plan's
    // own (the state is the reference's: feedback is zero, feed-forward remains).
    let reply = ask(serde_json::json!({ "t": k.t, "q": k.q, "v": k.v, "forces": k.contact_force }).to_string());
    let tau: Vec<f64> = reply["tau"].as_array().unwrap_or_else(|| panic!("{reply}")).iter().map(|x| x.as_f64().unwrap()).collect();
    assert_eq!(tau.len(), 12);
    assert_eq!(reply["landing"], false);
    let gap = tau.iter().zip(&k.tau).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
    assert!(gap < 1.0, "torques {tau:?} against the plan's {:?}", k.tau);
    let reply = ask(serde_json::json!({ "t": k.t, "q": [0.0], "v": k.v, "forces": k.contact_force }).to_string());
    assert!(reply["error"].as_str().unwrap().contains("expected q of 19"), "{reply}");
    let status = server.wait().unwrap();
    // A malformed request is bad input: exit code 2.
    assert_eq!(status.code(), Some(2));
    let _ = std::fs::remove_dir_all(&dir);
}
