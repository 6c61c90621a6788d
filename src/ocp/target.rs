//! What counts as done: the `[[target]]` entries of a task file, checked on a motion.
//!
//! A task's costs say what the optimizer pulls towards; its targets say what a user accepts.
//! `legwork solve` checks them on the plan (and, at twice the tolerances, on the closed-loop
//! re-runs and the MuJoCo check, issue 4's convention) and exits with the command line's
//! "ran but missed its target" code, 1, when the plan misses one.
//!
//! ```toml
//! [[target]]
//! at = "end"                           # "end" (default), "apex" (the highest base), or a time in s
//! base_position = [2.0, 0.0, "any"]    # m, world; "start" = the first knot's value, "any" = not checked
//! position_tolerance = 0.05            # m: required with base_position or feet
//! base_rpy_deg = ["any", "any", 45.0]  # deg (roll, pitch, yaw)
//! angle_tolerance_deg = 5.0            # deg: required with base_rpy_deg
//! feet = { lf_foot = [0.65, "start", 0.2] }  # foot-sphere centres, m, world
//! feet_down = ["lh_foot", "rh_foot"]   # in contact at `at`
//! feet_up = ["lf_foot", "rf_foot"]     # off the ground at `at`
//! feet_up_from = 1.0                   # s: the `feet_up` feet stay up from this time to the end (not only at `at`)
//! liftoffs_per_foot = 5                # every foot leaves the ground at least this often (whole motion)
//! min_flight_time = 0.1                # s with all feet off the ground (whole motion)
//! min_diagonal_correlation = 0.8       # contact flags of LF-RH and RF-LH, each at least this (whole motion; four feet)
//! max_lateral_correlation = 0.0        # contact flags of LF-RF and LH-RH, each at most this (whole motion; four feet)
//! min_base_height = 0.45               # m, world z: the base never lower than this (whole motion)
//! ```
//!
//! There are no default tolerances: a target names its own. `min_base_height` is a bound,
//! not a tolerance: re-runs are held to it as it stands (a robot that fell and slid to its
//! goal must not meet a distance target).

use super::metrics::{flight_time, liftoffs, pair_correlations, Snapshot};
use super::task::TaskError;
use crate::io::Trajectory;
use crate::model::Model;
use serde::Deserialize;
use std::collections::BTreeMap;

/// When a target is checked.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(untagged)]
pub enum TargetTime {
    /// Seconds from the start.
    Time(f64),
    /// `"end"` or `"apex"`.
    Keyword(String),
}

impl Default for TargetTime {
    fn default() -> Self {
        TargetTime::Keyword("end".into())
    }
}

/// A target coordinate: a number, `"start"` (the first knot's value) or `"any"`.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(untagged)]
pub enum TargetCoordinate {
    Value(f64),
    Keyword(String),
}

/// One `[[target]]` entry of a task file.
#[derive(Clone, Debug, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TargetSpec {
    #[serde(default)]
    pub at: TargetTime,
    pub base_position: Option<[TargetCoordinate; 3]>,
    pub base_rpy_deg: Option<[TargetCoordinate; 3]>,
    pub feet: Option<BTreeMap<String, [TargetCoordinate; 3]>>,
    pub position_tolerance: Option<f64>,
    pub angle_tolerance_deg: Option<f64>,
    pub feet_down: Option<Vec<String>>,
    pub feet_up: Option<Vec<String>>,
    pub feet_up_from: Option<f64>,
    pub liftoffs_per_foot: Option<usize>,
    pub min_flight_time: Option<f64>,
    pub min_diagonal_correlation: Option<f64>,
    pub max_lateral_correlation: Option<f64>,
    pub min_base_height: Option<f64>,
}

/// When a resolved target is checked.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CheckTime {
    End,
    Apex,
    At(f64),
}

/// A value to reach on one coordinate.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Goal {
    Value(f64),
    Start,
}

/// One check of a target, resolved against the robot (feet by index).
#[derive(Clone, Debug, PartialEq)]
enum Check {
    BasePosition { axis: usize, goal: Goal, tolerance: f64 },
    BaseAngle { axis: usize, goal: Goal, tolerance_deg: f64 },
    FootPosition { foot: usize, axis: usize, goal: Goal, tolerance: f64 },
    FootDown { foot: usize, down: bool },
    /// Up at every knot from `from` s to the end.
    FootUpFrom { foot: usize, from: f64 },
}

/// A task's targets, resolved against its robot: what [`Target::check`] measures.
#[derive(Clone, Debug, PartialEq)]
pub struct Target {
    entries: Vec<(CheckTime, Vec<Check>)>,
    liftoffs_per_foot: Option<usize>,
    min_flight_time: Option<f64>,
    min_diagonal_correlation: Option<f64>,
    max_lateral_correlation: Option<f64>,
    min_base_height: Option<f64>,
    foot_names: Vec<String>,
}

/// The outcome of one check on one motion.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct TargetResult {
    /// What was checked and when, e.g. `base x at the end`.
    pub what: String,
    /// The motion's value, e.g. `1.838 m`.
    pub value: String,
    /// The requirement, e.g. `2.000 +- 0.050 m`.
    pub required: String,
    pub met: bool,
}

const AXES: [&str; 3] = ["x", "y", "z"];
const ANGLES: [&str; 3] = ["roll", "pitch", "yaw"];

impl Target {
    /// Resolves the `[[target]]` entries of a task (`duration` s long) for `model`; names the
    /// file and the field of anything it cannot use.
    pub fn resolve(specs: &[TargetSpec], model: &Model, duration: f64, origin: &str) -> Result<Self, TaskError> {
        let mut entries = Vec::new();
        let mut liftoffs_per_foot = None;
        let mut min_flight_time = None;
        let (mut min_diagonal_correlation, mut max_lateral_correlation) = (None, None);
        let mut min_base_height = None;
        for (i, spec) in specs.iter().enumerate() {
            let field = |name: &str| format!("target[{i}].{name}");
            let bad = |name: &str, problem: String| TaskError::Invalid { origin: origin.into(), field: field(name), problem };
            let at = match &spec.at {
                TargetTime::Time(t) if t.is_finite() && (0.0..=duration).contains(t) => CheckTime::At(*t),
                TargetTime::Time(t) => return Err(bad("at", format!("expected a time within the task's 0-{duration} s, \"end\" or \"apex\", got {t}"))),
                TargetTime::Keyword(k) if k == "end" => CheckTime::End,
                TargetTime::Keyword(k) if k == "apex" => CheckTime::Apex,
                TargetTime::Keyword(k) => return Err(bad("at", format!("expected a time in s, \"end\" or \"apex\", got \"{k}\""))),
            };
            let tolerance = |name: &str, value: Option<f64>, needed_by: &str| -> Result<f64, TaskError> {
                match value {
                    Some(v) if v.is_finite() && v > 0.0 => Ok(v),
                    Some(v) => Err(bad(name, format!("expected a positive number, got {v}"))),
                    None => Err(bad(name, format!("missing: `{needed_by}` needs a tolerance (there is no default)"))),
                }
            };
            let goal = |name: String, c: &TargetCoordinate| -> Result<Option<Goal>, TaskError> {
                match c {
                    TargetCoordinate::Value(v) if v.is_finite() => Ok(Some(Goal::Value(*v))),
                    TargetCoordinate::Value(v) => Err(TaskError::Invalid { origin: origin.into(), field: field(&name), problem: format!("expected a finite number, \"start\" or \"any\", got {v}") }),
                    TargetCoordinate::Keyword(k) if k == "start" => Ok(Some(Goal::Start)),
                    TargetCoordinate::Keyword(k) if k == "any" => Ok(None),
                    TargetCoordinate::Keyword(k) => Err(TaskError::Invalid { origin: origin.into(), field: field(&name), problem: format!("expected a number, \"start\" or \"any\", got \"{k}\"") }),
                }
            };
            let foot_index = |name: &str, what: &str| -> Result<usize, TaskError> {
                model.feet.iter().position(|f| f.name == name).ok_or_else(|| {
                    bad(what, format!("{} has no foot named \"{name}\" (its feet: {})", model.name, model.feet.iter().map(|f| f.name.as_str()).collect::<Vec<_>>().join(", ")))
                })
            };
            let mut checks = Vec::new();
            if let Some(p) = &spec.base_position {
                let tolerance = tolerance("position_tolerance", spec.position_tolerance, "base_position")?;
                for (axis, c) in p.iter().enumerate() {
                    if let Some(goal) = goal(format!("base_position[{axis}]"), c)? {
                        checks.push(Check::BasePosition { axis, goal, tolerance });
                    }
                }
            }
            if let Some(r) = &spec.base_rpy_deg {
                let tolerance_deg = tolerance("angle_tolerance_deg", spec.angle_tolerance_deg, "base_rpy_deg")?;
                for (axis, c) in r.iter().enumerate() {
                    if let Some(goal) = goal(format!("base_rpy_deg[{axis}]"), c)? {
                        checks.push(Check::BaseAngle { axis, goal, tolerance_deg });
                    }
                }
            }
            if let Some(feet) = &spec.feet {
                let tolerance = tolerance("position_tolerance", spec.position_tolerance, "feet")?;
                for (name, p) in feet {
                    let foot = foot_index(name, &format!("feet.{name}"))?;
                    for (axis, c) in p.iter().enumerate() {
                        if let Some(goal) = goal(format!("feet.{name}[{axis}]"), c)? {
                            checks.push(Check::FootPosition { foot, axis, goal, tolerance });
                        }
                    }
                }
            }
            if let Some(from) = spec.feet_up_from {
                if !(from.is_finite() && (0.0..=duration).contains(&from)) {
                    return Err(bad("feet_up_from", format!("expected a time within the task's 0-{duration} s, got {from}")));
                }
                if spec.feet_up.as_ref().is_none_or(|f| f.is_empty()) {
                    return Err(bad("feet_up_from", "given without feet_up to apply to".into()));
                }
            }
            for (list, down, name) in [(&spec.feet_down, true, "feet_down"), (&spec.feet_up, false, "feet_up")] {
                for foot in list.iter().flatten() {
                    let foot = foot_index(foot, name)?;
                    checks.push(match spec.feet_up_from {
                        Some(from) if !down => Check::FootUpFrom { foot, from },
                        _ => Check::FootDown { foot, down },
                    });
                }
            }
            if spec.position_tolerance.is_some() && spec.base_position.is_none() && spec.feet.is_none() {
                return Err(bad("position_tolerance", "given without base_position or feet to apply to".into()));
            }
            if spec.angle_tolerance_deg.is_some() && spec.base_rpy_deg.is_none() {
                return Err(bad("angle_tolerance_deg", "given without base_rpy_deg to apply to".into()));
            }
            if let Some(n) = spec.liftoffs_per_foot {
                if liftoffs_per_foot.is_some() {
                    return Err(bad("liftoffs_per_foot", "given in two targets; it counts over the whole motion, give it once".into()));
                }
                liftoffs_per_foot = Some(n);
            }
            if let Some(t) = spec.min_flight_time {
                if !(t.is_finite() && t > 0.0 && t <= duration) {
                    return Err(bad("min_flight_time", format!("expected a time within the task's 0-{duration} s, got {t}")));
                }
                if min_flight_time.is_some() {
                    return Err(bad("min_flight_time", "given in two targets; it counts over the whole motion, give it once".into()));
                }
                min_flight_time = Some(t);
            }
            for (value, slot, name) in [(spec.min_diagonal_correlation, &mut min_diagonal_correlation, "min_diagonal_correlation"), (spec.max_lateral_correlation, &mut max_lateral_correlation, "max_lateral_correlation")] {
                if let Some(c) = value {
                    if !(-1.0..=1.0).contains(&c) {
                        return Err(bad(name, format!("expected a correlation in [-1, 1], got {c}")));
                    }
                    if model.feet.len() != 4 {
                        return Err(bad(name, format!("pairs of feet need a four-footed robot; {} has {} feet", model.name, model.feet.len())));
                    }
                    if slot.is_some() {
                        return Err(bad(name, "given in two targets; it counts over the whole motion, give it once".into()));
                    }
                    *slot = Some(c);
                }
            }
            if let Some(h) = spec.min_base_height {
                if !h.is_finite() {
                    return Err(bad("min_base_height", format!("expected a height in m, got {h}")));
                }
                if min_base_height.is_some() {
                    return Err(bad("min_base_height", "given in two targets; it holds over the whole motion, give it once".into()));
                }
                min_base_height = Some(h);
            }
            let whole_motion = [spec.liftoffs_per_foot.is_some(), spec.min_flight_time.is_some(), spec.min_diagonal_correlation.is_some(), spec.max_lateral_correlation.is_some(), spec.min_base_height.is_some()];
            if checks.is_empty() && !whole_motion.contains(&true) {
                return Err(TaskError::Invalid { origin: origin.into(), field: format!("target[{i}]"), problem: "checks nothing: give base_position, base_rpy_deg, feet, feet_down, feet_up, liftoffs_per_foot, min_flight_time, min_diagonal_correlation, max_lateral_correlation or min_base_height".into() });
            }
            if !checks.is_empty() {
                entries.push((at, checks));
            }
        }
        Ok(Self { entries, liftoffs_per_foot, min_flight_time, min_diagonal_correlation, max_lateral_correlation, min_base_height, foot_names: model.feet.iter().map(|f| f.name.clone()).collect() })
    }

    /// True if the task declares no target.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty() && self.liftoffs_per_foot.is_none() && self.min_flight_time.is_none() && self.min_diagonal_correlation.is_none() && self.max_lateral_correlation.is_none() && self.min_base_height.is_none()
    }

    /// Checks `traj` (a motion of `model`, at least one knot) with every tolerance multiplied
    /// by `scale` (1 for the plan, 2 for re-runs in another controller or simulator).
    pub fn check(&self, model: &Model, traj: &Trajectory, scale: f64) -> Vec<TargetResult> {
        let mut results = Vec::new();
        if traj.knots.is_empty() {
            return results;
        }
        let start = Snapshot::at(model, traj, traj.knots[0].t);
        for (at, checks) in &self.entries {
            let (snapshot, when) = match at {
                CheckTime::End => {
                    let end = traj.knots.last().map_or(0.0, |k| k.t);
                    (Snapshot::at(model, traj, end), "at the end".to_string())
                }
                CheckTime::Apex => {
                    let apex = traj.knots.iter().max_by(|a, b| a.q[2].total_cmp(&b.q[2])).map_or(0.0, |k| k.t);
                    (Snapshot::at(model, traj, apex), format!("at the apex ({apex:.3} s)"))
                }
                CheckTime::At(t) => (Snapshot::at(model, traj, *t), format!("at {t} s")),
            };
            for check in checks {
                let goal_value = |goal: Goal, start: f64| match goal {
                    Goal::Value(v) => v,
                    Goal::Start => start,
                };
                let result = match *check {
                    Check::BasePosition { axis, goal, tolerance } => {
                        let (value, want, tol) = (snapshot.base_position[axis], goal_value(goal, start.base_position[axis]), tolerance * scale);
                        TargetResult { what: format!("base {} {when}", AXES[axis]), value: format!("{value:.3} m"), required: format!("{want:.3} +- {tol:.3} m"), met: (value - want).abs() <= tol }
                    }
                    Check::BaseAngle { axis, goal, tolerance_deg } => {
                        let (value, want, tol) = (snapshot.base_rpy_deg[axis], goal_value(goal, start.base_rpy_deg[axis]), tolerance_deg * scale);
                        // Angles compare on the circle: 179 deg is 2 deg from -179 deg.
                        let difference = (value - want + 180.0).rem_euclid(360.0) - 180.0;
                        TargetResult { what: format!("base {} {when}", ANGLES[axis]), value: format!("{value:.1} deg"), required: format!("{want:.1} +- {tol:.1} deg"), met: difference.abs() <= tol }
                    }
                    Check::FootPosition { foot, axis, goal, tolerance } => {
                        let (value, want, tol) = (snapshot.feet[foot][axis], goal_value(goal, start.feet[foot][axis]), tolerance * scale);
                        TargetResult { what: format!("{} {} {when}", self.foot_names[foot], AXES[axis]), value: format!("{value:.3} m"), required: format!("{want:.3} +- {tol:.3} m"), met: (value - want).abs() <= tol }
                    }
                    Check::FootDown { foot, down } => {
                        let state = |d: bool| if d { "down" } else { "up" };
                        let is_down = snapshot.in_contact.get(foot).copied().unwrap_or(false);
                        TargetResult { what: format!("{} {when}", self.foot_names[foot]), value: state(is_down).into(), required: state(down).into(), met: is_down == down }
                    }
                    Check::FootUpFrom { foot, from } => {
                        let window: Vec<bool> = traj.knots.iter().filter(|k| k.t >= from - 1e-9).map(|k| k.in_contact.get(foot).copied().unwrap_or(false)).collect();
                        let up = window.iter().filter(|&&down| !down).count() as f64 / window.len().max(1) as f64;
                        TargetResult { what: format!("{} off the ground from {from} s", self.foot_names[foot]), value: format!("{:.0} % of knots", 100.0 * up), required: "100 %".into(), met: !window.is_empty() && up == 1.0 }
                    }
                };
                results.push(result);
            }
        }
        if let Some(n) = self.liftoffs_per_foot {
            let counts = liftoffs(&traj.knots);
            let least = counts.iter().copied().min().unwrap_or(0);
            results.push(TargetResult {
                what: "lift-offs per foot".into(),
                value: counts.iter().map(|c| c.to_string()).collect::<Vec<_>>().join("/"),
                required: format!("each >= {n}"),
                met: least >= n,
            });
        }
        let (diagonal, lateral) = pair_correlations(&traj.knots);
        let shown = |c: &[Option<f64>; 2]| c.iter().map(|c| c.map_or("none".to_string(), |c| format!("{c:.2}"))).collect::<Vec<_>>().join(" / ");
        if let Some(least) = self.min_diagonal_correlation {
            // A pair with a foot that never lifts has no correlation: not a gait, so missed.
            results.push(TargetResult { what: "diagonal contact correlation (LF-RH / RF-LH)".into(), value: shown(&diagonal), required: format!("each >= {least:.2}"), met: diagonal.iter().all(|c| c.is_some_and(|c| c >= least)) });
        }
        if let Some(most) = self.max_lateral_correlation {
            results.push(TargetResult { what: "lateral contact correlation (LF-RF / LH-RH)".into(), value: shown(&lateral), required: format!("each <= {most:.2}"), met: lateral.iter().all(|c| c.is_some_and(|c| c <= most)) });
        }
        if let Some(t) = self.min_flight_time {
            let flight = flight_time(&traj.knots);
            results.push(TargetResult { what: "flight time (all feet up)".into(), value: format!("{flight:.3} s"), required: format!(">= {t:.3} s"), met: flight >= t });
        }
        if let Some(least) = self.min_base_height {
            // The lowest knot, not interpolated: a fall lasts far longer than a knot. A knot
            // that is not finite (a diverged run) misses.
            let lowest = traj.knots.iter().min_by(|a, b| a.q[2].total_cmp(&b.q[2])).map_or((f64::NAN, 0.0), |k| (k.q[2], k.t));
            let finite = traj.knots.iter().all(|k| k.q[2].is_finite());
            results.push(TargetResult { what: "lowest base height".into(), value: format!("{:.3} m at {:.2} s", lowest.0, lowest.1), required: format!(">= {least:.3} m"), met: finite && lowest.0 >= least });
        }
        results
    }
}

/// True if every result is met (and there is at least one).
pub fn all_met(results: &[TargetResult]) -> bool {
    !results.is_empty() && results.iter().all(|r| r.met)
}
