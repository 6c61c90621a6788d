//! Task targets (`[[target]]`, issue 18): parsing with named errors, and the checks on a
//! motion built knot by knot, so each verdict is known before the check runs.

use legwork::io::{Knot, Trajectory};
use legwork::model::{embedded, Model};
use legwork::ocp::{all_met, TargetResult, TaskError, TaskSpec};
use legwork::terrain::{Plane, Terrain};

const TASK: &str = r#"
name = "shift"
summary = "move the base 5 cm forward"
robot = "hyq"
duration = 1.0
dt = 0.01
[running]
[final]
base_position = [1000.0, 1000.0, 1000.0]
[input]
weight = 1e-4
"#;

fn task(targets: &str) -> Result<TaskSpec, TaskError> {
    TaskSpec::from_toml(&format!("{TASK}\n{targets}"), "shift.toml")
}

fn error_of(targets: &str, model: &Model) -> String {
    match task(targets).and_then(|t| t.target(model, "shift.toml")) {
        Ok(_) => panic!("accepted: {targets}"),
        Err(e) => e.to_string(),
    }
}

/// HyQ standing still for 1 s, then moved: base x and yaw ramp to `x_end`, `yaw_end_deg`
/// over the motion; the front-left foot is off the ground from 0.3 to 0.5 s, and every foot
/// from 0.6 to 0.75 s.
fn motion(model: &Model, x_end: f64, yaw_end_deg: f64) -> Trajectory {
    let ground = Plane::flat(0.0);
    let stance = legwork::sim::standing_on_ground(model, &ground, 0.0).unwrap();
    let mut traj = Trajectory::new(model, "test", 0.01, ground.spec());
    for k in 0..=100 {
        let t = k as f64 * 0.01;
        let mut q: Vec<f64> = stance.iter().copied().collect();
        q[0] += x_end * t;
        let half = 0.5 * (yaw_end_deg * t).to_radians();
        // Base orientation (x, y, z, w), a yaw.
        q[3..7].copy_from_slice(&[0.0, 0.0, half.sin(), half.cos()]);
        let lf_up = (30..50).contains(&k);
        let all_up = (60..75).contains(&k);
        let in_contact = vec![!lf_up && !all_up, !all_up, !all_up, !all_up];
        traj.knots.push(Knot { t, q, v: vec![0.0; model.nv], tau: vec![0.0; model.nv - 6], contact_force: vec![[0.0; 3]; 4], in_contact, feedback_gain: None });
    }
    traj
}

fn by_what<'a>(results: &'a [TargetResult], what: &str) -> &'a TargetResult {
    results.iter().find(|r| r.what == what).unwrap_or_else(|| panic!("no check '{what}' in {results:?}"))
}

#[test]
fn bad_targets_are_named() {
    let model = embedded::load("hyq").unwrap();
    for (targets, expected) in [
        ("[[target]]\nbase_position = [2.0, 0.0, \"any\"]", vec!["shift.toml", "target[0].position_tolerance", "no default"]),
        ("[[target]]\nbase_rpy_deg = [0.0, 0.0, 45.0]\nangle_tolerance_deg = -1.0", vec!["target[0].angle_tolerance_deg", "positive"]),
        ("[[target]]\nat = 2.0\nfeet_up = [\"lf_foot\"]", vec!["target[0].at", "0-1 s"]),
        ("[[target]]\nat = \"takeoff\"\nfeet_up = [\"lf_foot\"]", vec!["target[0].at", "\"takeoff\""]),
        ("[[target]]\nfeet_up = [\"left_paw\"]", vec!["target[0].feet_up", "no foot named \"left_paw\"", "lf_foot"]),
        ("[[target]]\nbase_position = [\"somewhere\", 0.0, 0.0]\nposition_tolerance = 0.1", vec!["target[0].base_position[0]", "\"somewhere\""]),
        ("[[target]]\nat = \"end\"", vec!["target[0]", "checks nothing"]),
        ("[[target]]\nposition_tolerance = 0.1\nfeet_up = [\"lf_foot\"]", vec!["target[0].position_tolerance", "without base_position or feet"]),
        ("[[target]]\nliftoffs_per_foot = 1\n[[target]]\nliftoffs_per_foot = 2", vec!["target[1].liftoffs_per_foot", "give it once"]),
        ("[[target]]\nmin_diagonal_correlation = 1.5", vec!["target[0].min_diagonal_correlation", "[-1, 1]", "1.5"]),
        ("[[target]]\nmax_lateral_correlation = 0.0\n[[target]]\nmax_lateral_correlation = 0.1", vec!["target[1].max_lateral_correlation", "give it once"]),
        ("[[target]]\nfeet_up_from = 0.5", vec!["target[0].feet_up_from", "without feet_up"]),
        ("[[target]]\nfeet_up = [\"lf_foot\"]\nfeet_up_from = 3.0", vec!["target[0].feet_up_from", "0-1 s"]),
        ("[[target]]\nmin_base_height = nan", vec!["target[0].min_base_height", "a height in m", "NaN"]),
        ("[[target]]\nmin_base_height = 0.4\n[[target]]\nmin_base_height = 0.5", vec!["target[1].min_base_height", "give it once"]),
    ] {
        let message = error_of(targets, &model);
        for part in expected {
            assert!(message.contains(part), "'{message}' does not say '{part}'");
        }
    }
    // An unknown field is the parser's error, with the file's name.
    let message = task("[[target]]\nbase_height = 0.8").unwrap_err().to_string();
    assert!(message.contains("shift.toml") && message.contains("base_height"), "{message}");
}

#[test]
fn targets_check_position_angle_feet_and_counts_on_a_known_motion() {
    let model = embedded::load("hyq").unwrap();
    let spec = task(
        r#"
[[target]]
base_position = [0.30, "start", "any"]
position_tolerance = 0.05
base_rpy_deg = ["any", "any", 45.0]
angle_tolerance_deg = 5.0
liftoffs_per_foot = 1
min_flight_time = 0.1

[[target]]
at = 0.4
feet_up = ["lf_foot"]
feet_down = ["rf_foot", "lh_foot", "rh_foot"]
"#,
    )
    .unwrap();
    let target = spec.target(&model, "shift.toml").unwrap();
    assert!(!target.is_empty());

    // x 0.33 m (0.03 off), yaw 47 deg (2 deg off): met.
    let results = target.check(&model, &motion(&model, 0.33, 47.0), 1.0);
    assert!(all_met(&results), "{results:#?}");
    assert_eq!(by_what(&results, "lift-offs per foot").value, "2/1/1/1");
    assert_eq!(by_what(&results, "flight time (all feet up)").value, "0.150 s");
    assert!(by_what(&results, "lf_foot at 0.4 s").met);

    // x 0.39 m: 0.09 off, missed at the plan's tolerance, met at twice it.
    let far = motion(&model, 0.39, 47.0);
    let results = target.check(&model, &far, 1.0);
    assert!(!all_met(&results));
    let x = by_what(&results, "base x at the end");
    assert!(!x.met && x.value == "0.390 m" && x.required == "0.300 +- 0.050 m", "{x:?}");
    assert!(all_met(&target.check(&model, &far, 2.0)));

    // Yaw compares on the circle: a goal of 178 deg is met by -179 deg.
    let spec = task("[[target]]\nbase_rpy_deg = [\"any\", \"any\", 178.0]\nangle_tolerance_deg = 5.0").unwrap();
    let results = spec.target(&model, "shift.toml").unwrap().check(&model, &motion(&model, 0.0, -179.0), 1.0);
    assert!(all_met(&results), "{results:?}");
    let results = spec.target(&model, "shift.toml").unwrap().check(&model, &motion(&model, 0.0, 160.0), 1.0);
    assert!(!all_met(&results), "{results:?}");

    // "start" is the first knot's value: y stays where it started.
    let y = by_what(&target.check(&model, &motion(&model, 0.3, 45.0), 1.0), "base y at the end").clone();
    assert!(y.met, "{y:?}");
}

/// `motion` with its contact flags replaced: foot `f` is down at knot `k` if `down(f, k)`.
fn with_contacts(model: &Model, down: impl Fn(usize, usize) -> bool) -> Trajectory {
    let mut traj = motion(model, 0.0, 0.0);
    for (k, knot) in traj.knots.iter_mut().enumerate() {
        knot.in_contact = (0..4).map(|f| down(f, k)).collect();
    }
    traj
}

#[test]
fn gait_targets_tell_a_trot_from_a_pronk_and_a_stand() {
    let model = embedded::load("hyq").unwrap();
    let spec = task("[[target]]\nmin_diagonal_correlation = 0.8\nmax_lateral_correlation = 0.0\nliftoffs_per_foot = 4").unwrap();
    let target = spec.target(&model, "shift.toml").unwrap();
    // Feet LF, RF, LH, RH; a 10-knot cycle. Trot: LF+RH down in the first half, RF+LH in the second.
    let trot = with_contacts(&model, |f, k| (k % 10 < 5) == (f == 0 || f == 3));
    let results = target.check(&model, &trot, 1.0);
    assert!(all_met(&results), "{results:#?}");
    assert_eq!(by_what(&results, "diagonal contact correlation (LF-RH / RF-LH)").value, "1.00 / 1.00");
    assert_eq!(by_what(&results, "lateral contact correlation (LF-RF / LH-RH)").value, "-1.00 / -1.00");
    // Pronk: all four together; diagonal 1 but lateral 1 too.
    let pronk = with_contacts(&model, |_, k| k % 10 < 5);
    let results = target.check(&model, &pronk, 1.0);
    assert!(by_what(&results, "diagonal contact correlation (LF-RH / RF-LH)").met);
    assert!(!by_what(&results, "lateral contact correlation (LF-RF / LH-RH)").met);
    // Standing: no foot changes, no correlation at all: missed.
    let results = target.check(&model, &with_contacts(&model, |_, _| true), 1.0);
    let diagonal = by_what(&results, "diagonal contact correlation (LF-RH / RF-LH)");
    assert!(!diagonal.met && diagonal.value == "none / none", "{diagonal:?}");

    // The front feet up from 0.5 s to the end, checked at every knot.
    let spec = task("[[target]]\nfeet_up = [\"lf_foot\", \"rf_foot\"]\nfeet_up_from = 0.5").unwrap();
    let target = spec.target(&model, "shift.toml").unwrap();
    let rear = |last_touch: usize| with_contacts(&model, move |f, k| f >= 2 || k < 50 || k == last_touch);
    assert!(all_met(&target.check(&model, &rear(0), 1.0)));
    let results = target.check(&model, &rear(90), 1.0);
    let lf = by_what(&results, "lf_foot off the ground from 0.5 s");
    assert!(!lf.met && lf.value == "98 % of knots", "{lf:?}");
}

#[test]
fn a_task_without_targets_has_none_and_every_embedded_task_has_one() {
    let model = embedded::load("hyq").unwrap();
    assert!(task("").unwrap().target(&model, "shift.toml").unwrap().is_empty());
    assert!(!all_met(&[]), "no result is not a met target");
    for (name, _) in legwork::ocp::EMBEDDED_TASKS {
        let spec = TaskSpec::embedded(name).unwrap();
        let target = spec.target(&embedded::load(&spec.robot).unwrap(), name).unwrap();
        assert!(!target.is_empty(), "{name} declares no target");
    }
}

#[test]
fn the_lowest_base_height_tells_a_robot_that_fell_from_one_that_stood() {
    let model = embedded::load("hyq").unwrap();
    let spec = task("[[target]]\nbase_position = [0.3, \"any\", \"any\"]\nposition_tolerance = 0.05\nmin_base_height = 0.4").unwrap();
    let target = spec.target(&model, "shift.toml").unwrap();
    let standing = motion(&model, 0.3, 0.0);
    let stance_height = standing.knots[0].q[2];
    assert!(stance_height > 0.5, "HyQ stands with its base at {stance_height} m");
    let results = target.check(&model, &standing, 2.0);
    assert!(all_met(&results), "{results:#?}");
    assert_eq!(by_what(&results, "lowest base height").required, ">= 0.400 m");

    // The same distance, but the base down to 0.2 m from 0.5 to 0.7 s: the position is met,
    // the height is not, at any scale of the tolerances (a bound, not a tolerance).
    let mut fell = standing.clone();
    for knot in fell.knots.iter_mut().filter(|k| (0.5..0.7).contains(&k.t)) {
        knot.q[2] = 0.2;
    }
    for scale in [1.0, 2.0, 10.0] {
        let results = target.check(&model, &fell, scale);
        assert!(by_what(&results, "base x at the end").met);
        let low = by_what(&results, "lowest base height");
        assert!(!low.met && low.value == "0.200 m at 0.50 s", "{low:?}");
    }

    // A diverged run (a NaN height) misses.
    let mut diverged = standing;
    diverged.knots[60].q[2] = f64::NAN;
    assert!(!by_what(&target.check(&model, &diverged, 2.0), "lowest base height").met);
}
