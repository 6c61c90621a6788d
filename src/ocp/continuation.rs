//! Horizon continuation: solve the task on shorter horizons first, each warm-starting the
//! next, the full task last. legwork's addition to Neunert 2017's SLQ (the paper solves each
//! task on its full horizon from the standing PD policy).
//!
//! Why: around a stance the linearization holds each planted foot's anchor (it moves only
//! when the friction cone saturates), so an SLQ step cannot see a foot lifted and put down
//! elsewhere; it only reshapes contact changes the current trajectory already has. From a
//! standing start those first appear where the goal pulls, at the end of the horizon, and
//! spread backwards an iteration at a time: the gallop stood still for 1.5 s and lunged.
//! A stage of horizon `T_s` asks for part of the way in part of the time, so its contact
//! changes appear near `T_s`; stage by stage they cover the horizon before the full task is
//! solved.
//!
//! Stage `s` is the task with
//!
//! ```text
//! duration     T_s
//! waypoints    at t_p T_s / T
//! base goal    p_0 + (p* - p_0) (T_s / T)^e      every numeric coordinate of a desired
//!                                                 base position (task and waypoints);
//!                                                 p_0 the initial state's
//! ```
//!
//! solved for `iterations` SLQ iterations (no early stop) from the previous stage's policy
//! `u = u_k + K_k (x (-) x_k)` on its knots and the standing PD after them.

use super::{Coordinate, TaskSpec};
use serde::Deserialize;

/// The task file's `[continuation]` table.
///
/// ```toml
/// [continuation]
/// horizons = [0.5, 1.0, 1.5, 2.0, 2.5]   # s: the stages before the full horizon, increasing
/// iterations = 4                          # SLQ iterations per stage (counted in the task's limit)
/// progress_exponent = 1.6                 # e: the base goal's share of the way, (T_s / T)^e
/// ```
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ContinuationSpec {
    pub horizons: Vec<f64>,
    pub iterations: usize,
    pub progress_exponent: f64,
}

impl ContinuationSpec {
    /// SLQ iterations spent before the full horizon.
    pub fn stage_iterations(&self) -> usize {
        self.iterations * self.horizons.len()
    }

    /// `Err((field, problem))` unless the horizons increase within `(0, duration)` (at
    /// least one knot of `dt` each), the iterations are at least one per stage and the
    /// exponent is finite and positive.
    pub(crate) fn check(&self, duration: f64, dt: f64) -> Result<(), (&'static str, String)> {
        if self.horizons.is_empty() {
            return Err(("horizons", "expected at least one stage horizon (s)".into()));
        }
        let mut previous = 0.0;
        for &h in &self.horizons {
            if !(h.is_finite() && h >= dt && h > previous && h < duration) {
                return Err(("horizons", format!("expected increasing horizons of at least dt = {dt} s and shorter than the duration {duration} s, got {:?}", self.horizons)));
            }
            previous = h;
        }
        if self.iterations == 0 {
            return Err(("iterations", "expected at least 1 per stage".into()));
        }
        if !(self.progress_exponent.is_finite() && self.progress_exponent > 0.0) {
            return Err(("progress_exponent", format!("expected a finite number > 0, got {}", self.progress_exponent)));
        }
        Ok(())
    }
}

impl TaskSpec {
    /// The continuation stage of horizon `horizon` (see the module documentation), for a
    /// robot whose base starts at `start`: the task on `horizon` seconds, its waypoints'
    /// times and its base goals scaled, no continuation of its own.
    pub fn continuation_stage(&self, horizon: f64, exponent: f64, start: [f64; 3]) -> TaskSpec {
        let time_scale = horizon / self.duration;
        let progress = time_scale.powf(exponent);
        let toward = |p: &mut [Coordinate; 3]| {
            for (c, p0) in p.iter_mut().zip(start) {
                if let Coordinate::Value(v) = c {
                    *v = p0 + (*v - p0) * progress;
                }
            }
        };
        let mut stage = self.clone();
        stage.duration = horizon;
        stage.continuation = None;
        if let Some(p) = &mut stage.desired.base_position {
            toward(p);
        }
        for w in &mut stage.waypoints {
            w.time *= time_scale;
            if let Some(p) = &mut w.desired.base_position {
                toward(p);
            }
        }
        stage
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GALLOP: &str = r#"
name = "g"
summary = "s"
robot = "hyq"
duration = 3.0
dt = 0.002
[desired]
base_position = [2.0, "start", 0.6]
[running]
[final]
base_position = [1.0, 1.0, 1.0]
[input]
weight = 0.01
[continuation]
horizons = [1.0, 2.0]
iterations = 5
progress_exponent = 2.0
[[waypoint]]
time = 3.0
rho = 50.0
desired = { base_position = [2.0, "start", "start"] }
weights = { base_position = [1.0, 0.0, 0.0] }
"#;

    #[test]
    fn a_stage_scales_time_and_the_base_goal() {
        let spec = TaskSpec::from_toml(GALLOP, "g.toml").unwrap();
        let stage = spec.continuation_stage(1.5, 2.0, [0.1, 0.0, 0.5]);
        // (1.5 / 3)^2 = 1/4 of the way from the start.
        let x = |p: &Option<[Coordinate; 3]>| p.clone().unwrap();
        assert_eq!(x(&stage.desired.base_position), [Coordinate::Value(0.1 + 1.9 / 4.0), Coordinate::Keyword("start".into()), Coordinate::Value(0.5 + 0.1 / 4.0)]);
        assert_eq!(x(&stage.waypoints[0].desired.base_position)[0], Coordinate::Value(0.1 + 1.9 / 4.0));
        assert_eq!(stage.waypoints[0].time, 1.5);
        assert_eq!(stage.duration, 1.5);
        assert_eq!(stage.continuation, None);
        // Everything else is the task's.
        assert_eq!((stage.running.clone(), stage.terminal.clone(), stage.dt), (spec.running.clone(), spec.terminal.clone(), spec.dt));
    }
}
