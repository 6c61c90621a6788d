//! `legwork walk` and `legwork bench terrain`, run as a user would: the files written and
//! consistent with each other and with the printed summary, the JSON table's fields, and bad
//! input refused with a named error. The walk itself may fail (the trial's outcome is
//! reported, not asserted): these tests check the outputs' structure and consistency.

use legwork::io::Trajectory;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn legwork(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_legwork")).args(args).current_dir(env!("CARGO_MANIFEST_DIR")).output().unwrap()
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8(bytes.to_vec()).unwrap()
}

fn out_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("legwork-cli-walk-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// A short scenario (1 m onto a 10 cm step) as a file in `dir`, to keep the runs short.
fn short_scenario(dir: &Path) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let path = dir.join("short_step.toml");
    let toml = "name = \"short_step\"\nsummary = \"walk 1 m onto a 10 cm step\"\nstart = [0.0, 0.0, 0.0]\ngoal = [1.0, 0.0, 0.0]\ntime_limit = 12.0\n\n\
                [world]\norigin = [-1.0, -1.0]\nsize = [3.0, 2.0]\n\n[[world.block]]\nname = \"step\"\nx = [0.9, 2.0]\ny = [-0.5, 0.5]\ntop = 0.1\n";
    std::fs::write(&path, toml).unwrap();
    path
}

fn f(v: &Value, key: &str) -> f64 {
    v[key].as_f64().unwrap_or_else(|| panic!("{key} is not a number in {v}"))
}

#[test]
fn walk_writes_its_files_and_a_consistent_summary() {
    let out = out_dir("flat");
    let o = legwork(&["walk", "flat", "--out", out.to_str().unwrap(), "--seed", "3"]);
    let stdout = text(&o.stdout);
    assert!(matches!(o.status.code(), Some(0 | 1)), "{}\n{stdout}", text(&o.stderr));

    // summary.json: the trial's numbers, consistent with each other.
    let summary: Value = serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let trial = &summary["trial"];
    assert_eq!(trial["scenario"], "flat");
    assert_eq!(trial["seed"], 3);
    assert_eq!(summary["robot"], "hyq");
    let success = trial["success"].as_bool().unwrap();
    assert_eq!(trial["failure"].is_null(), success, "{trial}");
    // The exit code is the trial's verdict: 0 reached the goal, 1 did not.
    assert_eq!(o.status.code(), Some(if success { 0 } else { 1 }), "{trial}");
    let timings = trial["plan_timings"].as_array().unwrap();
    let plans = trial["plans"].as_u64().unwrap() as usize;
    assert_eq!(timings.len(), plans);
    assert_eq!(trial["plan_reasons"].as_array().unwrap().len(), plans);
    assert!(plans >= 1, "no plan was made: {trial}");
    assert_eq!(timings[0]["reason"], "start");
    for p in timings {
        assert!(f(p, "first_solution_ms") <= f(p, "body_search_ms") + 1e-9, "{p}");
        assert!(f(p, "body_search_ms") + f(p, "footstep_ms") + f(p, "zmp_ms") <= f(p, "total_ms") + 1e-6, "{p}");
        assert!(f(p, "epsilon") >= 1.0, "{p}");
    }
    let max_plan = timings.iter().map(|p| f(p, "total_ms")).fold(0.0, f64::max);
    assert_eq!(f(trial, "max_plan_ms"), max_plan);
    let worst = timings.iter().map(|p| f(p, "zmp_min_margin_m")).fold(f64::INFINITY, f64::min);
    assert_eq!(f(trial, "worst_zmp_margin_m"), worst);
    if success {
        // Start-to-goal distance (3 m) over the walking time.
        assert!((f(trial, "speed_cm_s") - 300.0 / f(trial, "walking_time_s")).abs() < 1e-9, "{trial}");
        assert!(f(trial, "goal_error_m") <= 0.1);
    }
    assert!(f(trial, "map_updates") >= 1.0);

    // trajectory.json: the executed motion, as long as the summary says.
    let traj = Trajectory::load_file(out.join("trajectory.json")).unwrap();
    assert_eq!(traj.metadata.robot, "hyq");
    assert!(traj.metadata.scenario.contains("flat"));
    assert!((traj.duration() - f(trial, "simulated_time_s")).abs() < 1e-9);
    assert_eq!(traj.summary["success"].as_bool(), Some(success));
    assert!(matches!(traj.metadata.terrain, legwork::terrain::TerrainSpec::HeightMap(_)), "the world's height map is the trajectory's terrain");

    // replay.html: self-contained, with the plan overlay.
    let replay = std::fs::read_to_string(out.join("replay.html")).unwrap();
    assert!(replay.len() > 10_000 && !replay.contains("https://"));
    for needle in ["\"overlay\":{\"footholds\":[{\"foot\":", "\"name\":\"planned CoG\"", "\"name\":\"planned ZMP (cart-table)\"", "\"supports\":[{\"t0\":"] {
        assert!(replay.contains(needle), "the replay has no {needle}");
    }

    // Plots: the trajectory's and the walk's.
    for file in ["base_pose.svg", "gait.svg", "contact_forces.svg", "cog_zmp_support.svg", "cog_tracking.svg"] {
        assert!(out.join("plots").join(file).exists(), "{file} missing");
    }
    let fig8 = std::fs::read_to_string(out.join("plots").join("cog_zmp_support.svg")).unwrap();
    assert!(fig8.contains("Fig. 8") && fig8.contains("planned CoG") && fig8.contains("swings"), "Fig. 8 lacks its captions");

    // The printed summary says the same.
    for needle in ["Walking flat", "goal error", "walking time", "ARA* first solution", "ZMP QP", "map updates", "clipped torque ticks", "Wrote"] {
        assert!(stdout.contains(needle), "missing {needle:?} in:\n{stdout}");
    }
    assert!(stdout.contains(if success { "flat: reached the goal" } else { "flat: FAILED" }), "{stdout}");
    assert!(stdout.contains(&format!("  plans                 {plans} (start")), "{stdout}");
    std::fs::remove_dir_all(&out).ok();
}

#[test]
fn bench_terrain_json_has_the_promised_fields() {
    let dir = out_dir("bench");
    let scenario = short_scenario(&dir);
    let scenarios = format!("pallet,{}", scenario.display());
    let o = legwork(&["bench", "terrain", "--trials", "1", "--json", "--threads", "2", "--scenarios", &scenarios]);
    let report: Value = serde_json::from_str(&text(&o.stdout)).unwrap_or_else(|e| panic!("not JSON ({e}):\n{}", text(&o.stdout)));
    // The exit code is the table's verdict: 1 when a paper terrain's row misses its targets.
    let missed = report["terrains"].as_array().unwrap().iter().any(|r| r["meets_targets"] == false);
    assert_eq!(report["verdict"], if missed { "missed" } else { "met" });
    assert_eq!(o.status.code(), Some(if missed { 1 } else { 0 }), "{}", text(&o.stderr));
    assert_eq!(report["robot"], "hyq");
    assert_eq!(report["trials_per_terrain"], 1);
    assert_eq!(report["threads"], 2);
    assert!(report["randomization"].as_str().unwrap().contains("+-5 cm"));
    let rows = report["terrains"].as_array().unwrap();
    assert_eq!(rows.iter().map(|r| r["scenario"].as_str().unwrap()).collect::<Vec<_>>(), ["pallet", "short_step"]);
    for row in rows {
        for key in [
            "scenario",
            "paper_speed_cm_s",
            "paper_success_rate",
            "trials",
            "successes",
            "success_rate",
            "speed_cm_s",
            "plans",
            "mean_plan_ms",
            "max_plan_ms",
            "mean_first_solution_ms",
            "mean_zmp_ms",
            "worst_zmp_margin_m",
            "max_map_update_ms",
            "clipped_ticks",
            "mean_trial_wall_s",
            "target_success_rate",
            "target_speed_cm_s",
            "meets_targets",
            "failures",
        ] {
            assert!(row.get(key).is_some(), "no {key} in {row}");
        }
        assert_eq!(row["trials"], 1);
        assert_eq!(row["target_success_rate"], 0.95);
        let successes = row["successes"].as_u64().unwrap();
        assert_eq!(row["success_rate"].as_f64().unwrap(), successes as f64);
        assert_eq!(row["failures"].as_array().unwrap().len() as u64, 1 - successes);
        assert_eq!(row["speed_cm_s"].is_null(), successes == 0);
        if successes == 0 {
            assert_eq!(row["failures"][0]["seed"], 1);
        }
        assert!(row["plans"].as_u64().unwrap() >= 1, "{row}");
        assert!(f(row, "mean_first_solution_ms") <= f(row, "mean_plan_ms"));
    }
    // The paper's pallet (Table I: 9.5 cm/s, 100 %), and the target: twice its speed.
    let pallet = &rows[0];
    assert_eq!((f(pallet, "paper_speed_cm_s"), f(pallet, "paper_success_rate"), f(pallet, "target_speed_cm_s")), (9.5, 1.0, 19.0));
    let met = pallet["successes"] == 1 && f(pallet, "speed_cm_s") >= 19.0;
    assert_eq!(pallet["meets_targets"].as_bool(), Some(met));
    // Not a terrain of the paper's: no paper row, no verdict.
    assert!(rows[1]["paper_speed_cm_s"].is_null() && rows[1]["target_speed_cm_s"].is_null() && rows[1]["meets_targets"].is_null());
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn bad_walk_input_is_refused_with_a_named_error() {
    let dir = out_dir("bad");
    std::fs::create_dir_all(&dir).unwrap();
    let bad_field = dir.join("bad.toml");
    std::fs::write(&bad_field, include_str!("../scenarios/flat.toml").replace("time_limit = 60.0", "time_limit = -1.0")).unwrap();
    let cases: [(Vec<&str>, &str); 5] = [
        (vec!["walk", "moon"], "no embedded scenario named 'moon'"),
        (vec!["walk", "/no/such/scenario.toml"], "/no/such/scenario.toml"),
        (vec!["walk", bad_field.to_str().unwrap()], "time_limit"),
        (vec!["bench", "terrain", "--trials", "0"], "--trials"),
        (vec!["bench", "terrain", "--scenarios", "moon"], "no embedded scenario named 'moon'"),
    ];
    for (args, needle) in cases {
        let o = legwork(&args);
        let err = text(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: bad input is exit code 2: {err}");
        assert!(err.starts_with("error: ") && err.contains(needle), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?} panicked: {err}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// A walk that cannot reach its goal (behind a 1 m wall) runs, says FAILED and why, and
/// exits with 1, the "ran but missed its target" code; summary.json says the same.
#[test]
fn a_failed_walk_exits_with_the_target_missed_code() {
    let dir = out_dir("walled");
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("walled.toml");
    let toml = "name = \"walled\"\nsummary = \"a goal behind a 1 m wall\"\nstart = [0.0, 0.0, 0.0]\ngoal = [1.0, 0.0, 0.0]\ntime_limit = 12.0\n\n\
                [world]\norigin = [-1.0, -1.0]\nsize = [3.0, 2.0]\n\n[[world.block]]\nname = \"wall\"\nx = [0.7, 1.5]\ny = [-1.0, 1.0]\ntop = 1.0\n";
    std::fs::write(&path, toml).unwrap();
    let out = dir.join("out");
    let o = legwork(&["walk", path.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    let stdout = text(&o.stdout);
    assert_eq!(o.status.code(), Some(1), "{stdout}\n{}", text(&o.stderr));
    assert!(stdout.contains("walled: FAILED: "), "{stdout}");
    let traj = Trajectory::load_file(out.join("trajectory.json")).unwrap();
    assert_eq!(traj.summary["verdict"], "missed");
    assert_eq!(traj.summary["exit_code"], 1);
    std::fs::remove_dir_all(&dir).ok();
}
