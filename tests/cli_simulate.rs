//! `legwork simulate`, run as a user would: files written, summary printed, a tracked
//! replay of its own output, and bad input refused with a named error.

use legwork::io::Trajectory;
use std::path::PathBuf;
use std::process::{Command, Output};

fn legwork(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_legwork")).args(args).current_dir(env!("CARGO_MANIFEST_DIR")).output().unwrap()
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8(bytes.to_vec()).unwrap()
}

fn out_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("legwork-cli-sim-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

#[test]
fn simulate_writes_the_trajectory_and_prints_a_summary() {
    let dir = out_dir("drop");
    let o = legwork(&["simulate", "--robot", "a1", "--duration", "0.6", "--drop-height", "0.05", "--push", "5,0,0@0.3:0.1", "--out", dir.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let out = text(&o.stdout);
    for needle in ["Simulated a1 for 0.6 s", "final base height", "max penetration", "max torque", "steps/s", "real time", "trajectory.json"] {
        assert!(out.contains(needle), "missing {needle:?} in:\n{out}");
    }
    let traj = Trajectory::load_file(dir.join("trajectory.json")).unwrap();
    assert_eq!(traj.knots.len(), 601);
    assert_eq!(traj.metadata.robot, "a1");
    assert!(traj.metadata.scenario.contains("--push 5,0,0@0.3:0.1"));
    assert!(traj.summary["max_penetration_m"].as_f64().unwrap() < 0.02);
    assert!(traj.summary["steps_per_second"].as_f64().unwrap() > 0.0);
    let replay = std::fs::read_to_string(dir.join("replay.html")).unwrap();
    assert!(replay.len() > 10_000 && !replay.contains("https://"));
    assert!(dir.join("plots").join("gait.svg").exists() && dir.join("plots").join("base_pose.svg").exists());
    assert!(dir.join("plots").join("torque_limits.svg").exists() && dir.join("plots").join("ground_forces.svg").exists());
    let csv = std::fs::read_to_string(dir.join("trajectory.csv")).unwrap();
    assert_eq!(csv.lines().count(), 602);

    // Track that motion with Neunert's tracking controller.
    let tracked = out_dir("track");
    let reference = dir.join("trajectory.json");
    let o = legwork(&["simulate", "--robot", "a1", "--controller", "track", "--reference", reference.to_str().unwrap(), "--duration", "0.5", "--out", tracked.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert!(text(&o.stdout).contains("with the track controller"));
    std::fs::remove_dir_all(&dir).ok();
    std::fs::remove_dir_all(&tracked).ok();
}

#[test]
fn bad_simulate_input_is_refused_with_a_named_error() {
    let cases: [(&[&str], &str); 6] = [
        (&["simulate", "--push", "1,2@3"], "X,Y,Z@T:DUR"),
        (&["simulate", "--duration", "-1"], "--duration"),
        (&["simulate", "--physics-rate", "0"], "--physics-rate"),
        (&["simulate", "--terrain", "/no/such/map.toml"], "/no/such/map.toml"),
        (&["simulate", "--controller", "track"], "--reference"),
        (&["simulate", "--robot", "hyq", "--controller", "track", "--reference", "Cargo.toml"], "Cargo.toml"),
    ];
    for (args, needle) in cases {
        let o = legwork(args);
        assert!(!o.status.success(), "{args:?} should fail");
        let err = text(&o.stderr);
        assert!(err.contains(needle) && !err.contains("panicked"), "{args:?}: {err}");
    }
}

#[test]
fn tasks_lists_the_embedded_tasks_and_bench_slq_reports_json() {
    let o = legwork(&["tasks"]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert!(text(&o.stdout).lines().any(|l| l.starts_with("squat_jump ")));
    // Structure only: the numbers are timings, checked by the benchmark itself, not here.
    let bench = out_dir("bench-slq");
    let o = legwork(&["bench", "slq", "--json", "--iterations", "1", "--out", bench.to_str().unwrap()]);
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap_or_else(|e| panic!("not JSON ({e}): {}", text(&o.stderr)));
    // The exit code is the tasks' verdict: 1 while any embedded task misses its target.
    let missed = report["tasks"].as_array().unwrap().iter().any(|t| t["target_met"] != true);
    assert_eq!(report["verdict"], if missed { "missed" } else { "met" });
    assert_eq!(o.status.code(), Some(if missed { 1 } else { 0 }), "{}", text(&o.stderr));
    assert_eq!(report["scaling"].as_array().unwrap().len(), 6);
    assert!(report["linear_fit"]["r_squared"].is_number());
    assert_eq!(report["tasks"].as_array().unwrap().len(), legwork::ocp::EMBEDDED_TASKS.len());
    // Every task's solve folder, and the report page over them with the scaling table.
    let page = std::fs::read_to_string(bench.join("report.html")).unwrap();
    assert!(page.contains("Fig. 13"));
    for (name, _) in legwork::ocp::EMBEDDED_TASKS {
        assert!(bench.join(name).join("replay.html").is_file(), "{name}");
        assert!(page.contains(&format!("<a href=\"{name}/replay.html\">replay</a>")), "{name}");
    }
    std::fs::remove_dir_all(&bench).ok();
    let o = legwork(&["solve", "no_such_task"]);
    assert!(!o.status.success() && text(&o.stderr).contains("no embedded task named 'no_such_task'"));
}

/// A short task for the replay tests: shift the base 5 cm forward in 0.6 s (a few
/// iterations; the replays must agree whatever the plan's quality).
const SHIFT_TASK: &str = r#"
name = "shift"
summary = "move the base 5 cm forward"
robot = "hyq"
duration = 0.6
dt = 0.002
iterations = 4
[desired]
base_position = [0.05, "start", "start"]
[running]
base_position = [100.0, 100.0, 100.0]
[final]
base_position = [1000.0, 1000.0, 1000.0]
[input]
weight = 1e-4
"#;

/// The README's recipe: `legwork simulate --controller track --reference <solve's
/// trajectory.json>` runs in the world the plan was made in (contact model, start state,
/// contact anchors, ground, joint stops), so it reproduces `legwork solve`'s own tracking
/// re-run knot for knot.
#[test]
fn simulate_track_reproduces_the_tracking_rerun_of_solve() {
    let dir = out_dir("solve-track");
    std::fs::create_dir_all(&dir).unwrap();
    let task = dir.join("shift.toml");
    std::fs::write(&task, SHIFT_TASK).unwrap();
    let solved = dir.join("solved");
    let o = legwork(&["solve", task.to_str().unwrap(), "--out", solved.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let plan = solved.join("trajectory.json");
    let replay = dir.join("replay");
    let o = legwork(&["simulate", "--controller", "track", "--reference", plan.to_str().unwrap(), "--duration", "0.6", "--out", replay.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let ours = Trajectory::load_file(replay.join("trajectory.json")).unwrap();
    let solves = Trajectory::load_file(solved.join("rerun_tracking.json")).unwrap();
    assert_eq!(ours.knots.len(), solves.knots.len());
    for (a, b) in ours.knots.iter().zip(&solves.knots) {
        assert_eq!((a.t, &a.q, &a.v, &a.tau), (b.t, &b.q, &b.v, &b.tau), "the replays part at t = {}", a.t);
    }
    // The plan records the world it was made in.
    let plan = Trajectory::load_file(&plan).unwrap();
    assert!(plan.metadata.initial_anchors.as_ref().is_some_and(|a| a.iter().all(Option::is_some)), "four feet down at the start");
    std::fs::remove_dir_all(&dir).ok();
}

/// `legwork solve`'s exit codes (`legwork --help`): 0 the plan met the task's target, 1 it
/// ran and missed it (said in the summary and in trajectory.json), 2 bad input, 3 the job
/// could not finish (here: the output folder cannot be created).
#[test]
fn solve_exit_codes_tell_met_missed_bad_input_and_could_not_finish() {
    let dir = out_dir("exit-codes");
    std::fs::create_dir_all(&dir).unwrap();
    let solve = |name: &str, target: &str, out: &std::path::Path| {
        let task = dir.join(format!("{name}.toml"));
        std::fs::write(&task, format!("{SHIFT_TASK}\n{target}")).unwrap();
        legwork(&["solve", task.to_str().unwrap(), "--out", out.to_str().unwrap()])
    };
    // Anywhere within 5 cm of the 5 cm goal: the 4-iteration plan gets there.
    let met = "[[target]]\nbase_position = [0.05, 0.0, \"any\"]\nposition_tolerance = 0.05\n";
    let o = solve("met", met, &dir.join("met"));
    let stdout = text(&o.stdout);
    assert_eq!(o.status.code(), Some(0), "{stdout}\n{}", text(&o.stderr));
    assert!(stdout.contains("Target met by the plan (exit code 0)."), "{stdout}");
    // 100 m ahead in 0.6 s: missed, and said.
    let o = solve("far", "[[target]]\nbase_position = [100.0, \"any\", \"any\"]\nposition_tolerance = 0.05\n", &dir.join("far"));
    let stdout = text(&o.stdout);
    assert_eq!(o.status.code(), Some(1), "{stdout}\n{}", text(&o.stderr));
    assert!(stdout.contains("base x at the end (100.000 +- 0.050 m)") && stdout.contains("MISSED") && stdout.contains("TARGET MISSED"), "{stdout}");
    let summary = Trajectory::load_file(dir.join("far").join("trajectory.json")).unwrap().summary;
    assert_eq!((summary["verdict"].as_str(), summary["exit_code"].as_u64()), (Some("missed"), Some(1)));
    assert_eq!(summary["target"]["plan"][0]["met"], false);
    // No target declared: said, exit code 0.
    let o = solve("none", "", &dir.join("none"));
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    assert!(text(&o.stdout).contains("Target: none declared"));
    // Bad input: a target without its tolerance, named.
    let o = solve("bad", "[[target]]\nbase_position = [0.05, 0.0, \"any\"]\n", &dir.join("bad"));
    let err = text(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("bad.toml") && err.contains("target[0].position_tolerance"), "{err}");
    // Could not finish: the output folder would be inside a file.
    let blocker = dir.join("a-file");
    std::fs::write(&blocker, "not a folder").unwrap();
    let o = solve("blocked", met, &blocker.join("out"));
    let err = text(&o.stderr);
    assert_eq!(o.status.code(), Some(3), "{err}");
    assert!(err.contains("cannot create the output folder"), "{err}");
    std::fs::remove_dir_all(&dir).ok();
}

/// Runs that would not fit or make no physical sense are refused before any work, with the
/// estimate or the range and the way out (issue 18), exit code 2.
#[test]
fn absurd_runs_are_refused_before_they_start() {
    let dir = out_dir("absurd");
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("out");
    let out = out.to_str().unwrap();
    let refused = |args: &[&str], needles: &[&str]| {
        let o = legwork(args);
        let err = text(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        for n in needles {
            assert!(err.contains(n), "{args:?}: '{err}' does not say '{n}'");
        }
    };
    refused(&["simulate", "--duration", "1e9", "--out", out], &["--duration", "at most 86400 s"]);
    // The limit given, so that the test does not depend on this machine's memory.
    refused(&["--memory-limit", "16", "simulate", "--duration", "86400", "--record-rate", "2000", "--out", out], &["would need about 207.4 GB of memory", "--record-rate", "--memory-limit"]);
    refused(&["--memory-limit", "0.001", "simulate", "--duration", "10", "--out", out], &["over the limit of 0.0 GB (--memory-limit 0.001)"]);
    refused(&["simulate", "--drop-height", "1e6", "--out", out], &["--drop-height", "0-10 m"]);
    refused(&["simulate", "--physics-rate", "1e12", "--out", out], &["--physics-rate", "at most 100000 Hz"]);
    refused(&["simulate", "--duration", "nan", "--out", out], &["--duration", "positive"]);
    // A MuJoCo-only option on legwork's own simulator is refused, not ignored.
    refused(&["mpc", "sidestep", "--measured-depth", "--out", out], &["--measured-depth", "--sim mujoco only"]);
    refused(&["bench", "mpc", "--measured-depth", "--tasks", "sidestep", "--out", out], &["--measured-depth", "--sim mujoco only"]);
    // A real-time priority outside SCHED_FIFO's range, before the plan's solve.
    refused(&["mpc", "sidestep", "--realtime-priority", "0", "--out", out], &["--realtime-priority 0", "1..=99"]);
    refused(&["bench", "mpc", "--realtime-priority", "100", "--tasks", "sidestep", "--out", out], &["--realtime-priority 100", "1..=99"]);
    // Window steps longer than the robot's contact model takes, before the plan's solve.
    refused(&["mpc", "sidestep", "--substeps", "2", "--out", out], &["`substeps`", "0.0025 s", "contact.max_step", "at least 5"]);
    refused(&["mpc", "sidestep", "--substeps", "0", "--out", out], &["`substeps`", "at least 1"]);
    refused(&["bench", "mpc", "--substeps", "2", "--tasks", "sidestep", "--out", out], &["`substeps`", "at least 5"]);
    // Tracking weights that are not three weights >= 0, before the plan's solve.
    refused(&["mpc", "sidestep", "--tracking-base-position", "1000,nan,1000", "--out", out], &["--tracking-base-position 1000,nan,1000", "three finite weights >= 0"]);
    refused(&["bench", "mpc", "--tracking-base-position", "1000,2000", "--tasks", "sidestep", "--out", out], &["--tracking-base-position 1000,2000", "x, y, z"]);
    let long = dir.join("long.toml");
    std::fs::write(&long, SHIFT_TASK.replace("duration = 0.6", "duration = 2000.0")).unwrap();
    refused(&["--memory-limit", "16", "solve", long.to_str().unwrap(), "--out", out], &["long.toml", "1000000 knots", "would need about 64.0 GB", "limit of 16.0 GB (--memory-limit 16)"]);
    let coarse = dir.join("coarse.toml");
    std::fs::write(&coarse, SHIFT_TASK.replace("dt = 0.002", "dt = 0.05")).unwrap();
    refused(&["solve", coarse.to_str().unwrap(), "--out", out], &["coarse.toml", "field `dt`", "at most 0.02 s", "got 0.05"]);
    // A trajectory whose base is 1e300 m away is not a motion.
    let o = legwork(&["simulate", "--robot", "a1", "--duration", "0.05", "--out", dir.join("sim").to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let mut traj = Trajectory::load_file(dir.join("sim").join("trajectory.json")).unwrap();
    traj.knots[1].q[0] = 1e300;
    let far = dir.join("far.json");
    std::fs::write(&far, serde_json::to_string(&traj).unwrap()).unwrap();
    refused(&["simulate", "--robot", "a1", "--controller", "track", "--reference", far.to_str().unwrap(), "--out", out], &["far.json", "knots[1].q[0]", "within 10000 m", "1.000e300"]);
    // More threads than cores: capped, with a warning, and the run goes on.
    let o = legwork(&["bench", "terrain", "--trials", "1", "--threads", "100000", "--scenarios", "flat", "--json"]);
    let err = text(&o.stderr);
    assert!(err.contains("warning: --threads 100000: capped at") && err.contains("--force-threads"), "{err}");
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap_or_else(|e| panic!("not JSON ({e}): {err}"));
    assert_eq!(report["threads"].as_u64(), std::thread::available_parallelism().ok().map(|n| n.get() as u64));
    std::fs::remove_dir_all(&dir).ok();
}
