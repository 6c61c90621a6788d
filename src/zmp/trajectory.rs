//! The planned CoG trajectory: the spline of eq. (3) over the phases actually used, with its
//! state and cart-table ZMP (eq. 5) at any time, its cost (eq. 7), and the checks the
//! tests and callers use (ZMP margin on a dense time grid, continuity at the junctions).

use super::phases::PlannedPhase;
use super::quintic::Quintic;
use super::ZmpError;
use nalgebra::{Point2, Vector2};

/// Horizontal CoG state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CogState {
    pub position: Vector2<f64>,
    pub velocity: Vector2<f64>,
    pub acceleration: Vector2<f64>,
}

impl CogState {
    /// At rest at `position`.
    pub fn at_rest(position: Vector2<f64>) -> Self {
        Self { position, velocity: Vector2::zeros(), acceleration: Vector2::zeros() }
    }

    /// Cart-table ZMP, eq. (5): `p = c - z_cog c̈ / g_0` (constant height, `z̈_cog = 0`).
    pub fn zmp(&self, cog_height: f64, gravity: f64) -> Point2<f64> {
        Point2::from(self.position - self.acceleration * (cog_height / gravity))
    }

    pub(crate) fn is_finite(&self) -> bool {
        self.position.iter().chain(self.velocity.iter()).chain(self.acceleration.iter()).all(|v| v.is_finite())
    }
}

/// One spline of eq. (3): `x(t - start_time)`, `y(t - start_time)` on
/// `[start_time, start_time + duration]`, inside plan phase `phase`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CogSpline {
    pub start_time: f64,
    pub duration: f64,
    pub phase: usize,
    pub x: Quintic,
    pub y: Quintic,
}

impl CogSpline {
    /// State at local time `t` in `[0, duration]`.
    pub fn state(&self, t: f64) -> CogState {
        CogState {
            position: Vector2::new(self.x.position(t), self.y.position(t)),
            velocity: Vector2::new(self.x.velocity(t), self.y.velocity(t)),
            acceleration: Vector2::new(self.x.acceleration(t), self.y.acceleration(t)),
        }
    }
}

/// Numbers about the QP and its solution.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SolveInfo {
    pub phases: usize,
    pub splines: usize,
    /// QP unknowns: the CoG state of both axes (6) at every junction between two splines.
    /// The QP has no equality rows: eq. (4) and the initial and goal states hold by
    /// construction (see [`super::qp`]).
    pub variables: usize,
    /// Rows of eq. (6) in the last QP solved: one per ZMP sample and edge of the shrunk
    /// support polygon, for the edges the ZMP approaches (see "Lazy rows" in [`super::qp`]).
    pub inequality_constraints: usize,
    /// All rows of eq. (6), each checked at the solution.
    pub zmp_constraints: usize,
    /// QPs solved: one, plus one per round of left-out rows found violated.
    pub rounds: u32,
    /// Interior-point iterations, all rounds.
    pub iterations: u32,
    /// Clarabel stopped at its reduced tolerances (status `AlmostSolved`, about 1e-4
    /// instead of 1e-8): [`CogTrajectory::check_zmp`] tells how well eq. (6) holds.
    pub reduced_accuracy: bool,
    /// Clarabel's own time (s), setup and solve, all rounds.
    pub solver_seconds: f64,
    /// Cost eq. (7) of the returned trajectory.
    pub cost: f64,
}

/// Worst ZMP margin found on a time grid (see [`CogTrajectory::check_zmp`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ZmpCheck {
    /// Smallest left side of eq. (6) over the shrunk support polygon's edges, over all
    /// samples (m): the ZMP's distance to the shrunk boundary if positive, a violation if
    /// negative.
    pub worst_margin: f64,
    /// Where it occurs.
    pub time: f64,
    pub phase: usize,
    pub samples: usize,
}

/// The planned ZMP-stable CoG trajectory (Winkler 2015, sec. IV).
#[derive(Clone, Debug)]
pub struct CogTrajectory {
    pub(crate) splines: Vec<CogSpline>,
    pub(crate) phases: Vec<PlannedPhase>,
    pub(crate) gravity: f64,
    pub(crate) weights: [f64; 2],
    pub(crate) info: SolveInfo,
}

impl CogTrajectory {
    /// Total duration (s), including the inserted four-leg phases.
    pub fn duration(&self) -> f64 {
        self.phases.last().map_or(0.0, |p| p.end_time())
    }

    /// The phases actually optimized: the given ones and the inserted four-leg phases, with
    /// start times and shrunk support polygons.
    pub fn phases(&self) -> &[PlannedPhase] {
        &self.phases
    }

    /// The splines of eq. (3), in time order.
    pub fn splines(&self) -> &[CogSpline] {
        &self.splines
    }

    pub fn info(&self) -> &SolveInfo {
        &self.info
    }

    /// Index of the spline in use at `t` (the later one at a junction).
    fn spline_index(&self, t: f64) -> usize {
        self.splines.partition_point(|s| s.start_time <= t).saturating_sub(1)
    }

    fn checked(&self, t: f64) -> Result<(usize, f64), ZmpError> {
        if !(t >= 0.0 && t.is_finite()) {
            return Err(ZmpError::InvalidTime { t, duration: self.duration() });
        }
        let last = self.splines.len() - 1;
        if t >= self.duration() {
            return Ok((last, self.splines[last].duration));
        }
        let index = self.spline_index(t);
        let spline = &self.splines[index];
        Ok((index, (t - spline.start_time).min(spline.duration)))
    }

    /// CoG state at time `t` (s). After the end the CoG rests at the goal (the last spline
    /// ends with zero velocity and acceleration), so later times give the final state.
    pub fn state(&self, t: f64) -> Result<CogState, ZmpError> {
        let (index, local) = self.checked(t)?;
        Ok(self.splines[index].state(local))
    }

    /// Index of the plan phase in use at `t` (the later one at a switch).
    pub fn phase_index(&self, t: f64) -> Result<usize, ZmpError> {
        Ok(self.splines[self.checked(t)?.0].phase)
    }

    /// Cart-table ZMP at `t` (eq. 5), with the CoG height of the phase in use.
    pub fn zmp(&self, t: f64) -> Result<Point2<f64>, ZmpError> {
        let (index, local) = self.checked(t)?;
        let spline = &self.splines[index];
        Ok(spline.state(local).zmp(self.phases[spline.phase].phase.cog_height, self.gravity))
    }

    /// Cost eq. (7), `w_x ∫ ẍ^2 dt + w_y ∫ ÿ^2 dt`, in closed form per spline.
    pub fn cost(&self) -> f64 {
        let [wx, wy] = self.weights;
        self.splines
            .iter()
            .map(|s| {
                wx * s.x.squared_acceleration_integral(s.duration) + wy * s.y.squared_acceleration_integral(s.duration)
            })
            .sum()
    }

    /// The ZMP margin (eq. 6 against the shrunk support polygon) on a uniform grid of step at
    /// most `max_step` over every spline, both ends included. At a phase switch both phases
    /// are checked, each with its own polygon and CoG height, as the constraints hold on
    /// each phase's closed interval.
    pub fn check_zmp(&self, max_step: f64) -> ZmpCheck {
        let mut check = ZmpCheck { worst_margin: f64::INFINITY, time: 0.0, phase: 0, samples: 0 };
        for spline in &self.splines {
            let phase = &self.phases[spline.phase];
            let intervals = (spline.duration / max_step).ceil().max(1.0) as usize;
            for j in 0..=intervals {
                let local = spline.duration * j as f64 / intervals as f64;
                let zmp = spline.state(local).zmp(phase.phase.cog_height, self.gravity);
                let margin = phase.shrunk_support.margin(zmp);
                check.samples += 1;
                if margin < check.worst_margin {
                    check = ZmpCheck {
                        worst_margin: margin,
                        time: spline.start_time + local,
                        phase: spline.phase,
                        ..check
                    };
                }
            }
        }
        check
    }

    /// Largest jump of position, velocity or acceleration (either axis) at a spline junction:
    /// eq. (4) says zero.
    pub fn continuity_error(&self) -> f64 {
        self.splines
            .windows(2)
            .map(|pair| {
                let (end, start) = (pair[0].state(pair[0].duration), pair[1].state(0.0));
                (end.position - start.position)
                    .amax()
                    .max((end.velocity - start.velocity).amax())
                    .max((end.acceleration - start.acceleration).amax())
            })
            .fold(0.0, f64::max)
    }
}
