//! A solved contact-timing problem read back as a time-stamped single-rigid-body
//! trajectory, and its resampling on the uniform grid of the full-body optimization
//! (Nguyen 2022, sec. II-C2: "linearly interpolated to get their profiles sampling at
//! dt = 10 ms").
//!
//! Knot `k` of the solution lies in phase `i = min(k, N_c - 1) / N_i` and its interval lasts
//! `T_i / N_i` (eq. 2i-2j); the controls of knot `k` (forces of the stance feet, positions of
//! the swing feet) hold over that interval, as the forward-Euler step (2h) uses them.

use super::contact_timing::{ContactTimingProblem, Contacts};
use super::stage::{P, R, T, V, W};
use crate::spatial::{exp3, log3};
use nalgebra::{DVector, Matrix3, Vector3};

/// One instant of the single-rigid-body motion.
#[derive(Clone, Debug, PartialEq)]
pub struct SrbKnot {
    /// Time from the start (s).
    pub t: f64,
    /// CoM position and velocity (world).
    pub com: Vector3<f64>,
    pub com_velocity: Vector3<f64>,
    /// Body rotation (body -> world).
    pub rotation: Matrix3<f64>,
    /// Angular velocity in the body frame `Omega`.
    pub omega: Vector3<f64>,
    /// Feet positions (world, order LF, RF, LH, RH): stance feet at their contact points.
    pub feet: [Vector3<f64>; 4],
    /// Ground forces on the feet over the interval that starts at this knot (world; zero off
    /// the ground and on the last knot).
    pub forces: [Vector3<f64>; 4],
    /// Feet in contact over the interval that starts at this knot (none on the last knot).
    pub contacts: Contacts,
}

/// A single-rigid-body trajectory: knots, and the phases they are grouped in.
#[derive(Clone, Debug, PartialEq)]
pub struct SrbTrajectory {
    pub knots: Vec<SrbKnot>,
    /// Phase durations `T_i` (s).
    pub phase_durations: Vec<f64>,
    /// Intervals per phase (`N_i` of the solution, `round(T_i / dt)` after resampling).
    pub phase_knots: Vec<usize>,
    /// Feet in contact per phase.
    pub phase_contacts: Vec<Contacts>,
}

/// Why a solution cannot be read or resampled.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SrbSolutionError {
    #[error("the primal has {got} stages, the contact-timing problem {expected}")]
    Stages { got: usize, expected: usize },
    #[error("stage {stage} of the primal has {got} entries, expected {expected}")]
    StageSize { stage: usize, got: usize, expected: usize },
    #[error("phase {phase}: duration T = {value} s, expected a finite positive number")]
    Duration { phase: usize, value: f64 },
    #[error("resample: dt = {0} s, expected a finite positive step")]
    Step(f64),
    #[error("resample: phase {phase} lasts {duration} s, shorter than half a step dt = {dt} s")]
    PhaseTooShort { phase: usize, duration: f64, dt: f64 },
}

impl SrbTrajectory {
    /// Reads the iterate `primal` (for instance `SolveResult::last.primal`) of `problem`.
    pub fn from_solution(problem: &ContactTimingProblem, primal: &[DVector<f64>]) -> Result<Self, SrbSolutionError> {
        let nc = problem.knots;
        let np = problem.phases;
        let n = problem.knots_per_phase;
        if primal.len() != nc + 1 {
            return Err(SrbSolutionError::Stages { got: primal.len(), expected: nc + 1 });
        }
        let nx = T + np;
        for (k, z) in primal.iter().enumerate() {
            let expected = if k == nc { nx } else { nx + 12 };
            if z.len() != expected {
                return Err(SrbSolutionError::StageSize { stage: k, got: z.len(), expected });
            }
        }
        let durations: Vec<f64> = (0..np).map(|i| primal[0][T + i]).collect();
        for (phase, &value) in durations.iter().enumerate() {
            if !(value.is_finite() && value > 0.0) {
                return Err(SrbSolutionError::Duration { phase, value });
            }
        }
        let v3 = |z: &DVector<f64>, i: usize| Vector3::new(z[i], z[i + 1], z[i + 2]);
        let mut knots = Vec::with_capacity(nc + 1);
        let mut t = 0.0;
        for (k, z) in primal.iter().enumerate() {
            let last = k == nc;
            let phase = k.min(nc - 1) / n;
            let contacts = if last { [false; 4] } else { problem.phase_contacts[phase] };
            let mut feet = [Vector3::zeros(); 4];
            let mut forces = [Vector3::zeros(); 4];
            for f in 0..4 {
                if last {
                    feet[f] = problem.feet_goal[f];
                } else if contacts[f] {
                    feet[f] = problem.feet_start[f];
                    forces[f] = v3(z, nx + 3 * f);
                } else {
                    feet[f] = v3(z, nx + 3 * f);
                }
            }
            knots.push(SrbKnot {
                t,
                com: v3(z, P),
                com_velocity: v3(z, V),
                rotation: Matrix3::from_fn(|a, b| z[R + a + 3 * b]),
                omega: v3(z, W),
                feet,
                forces,
                contacts,
            });
            t += durations[phase] / n as f64;
        }
        Ok(Self { knots, phase_durations: durations, phase_knots: vec![n; np], phase_contacts: problem.phase_contacts.clone() })
    }

    /// The state at fraction `s` in `[0, 1)` of phase `phase`, interpolated between the
    /// knots: linearly for positions, velocities and feet, along the geodesic for the rotation
    /// (`R_j exp(s log(R_j^T R_{j+1}))`); forces and contacts are those of the interval that
    /// holds the sample, which belongs to the phase.
    pub fn sample(&self, phase: usize, fraction: f64) -> SrbKnot {
        let first: usize = self.phase_knots[..phase].iter().sum();
        let x = fraction.clamp(0.0, 1.0) * self.phase_knots[phase] as f64;
        let m = (x.floor() as usize).min(self.phase_knots[phase] - 1);
        let s = x - m as f64;
        let (a, b) = (&self.knots[first + m], &self.knots[first + m + 1]);
        let lerp = |x: &Vector3<f64>, y: &Vector3<f64>| x + (y - x) * s;
        let rotation = a.rotation * exp3(&(log3(&(a.rotation.transpose() * b.rotation)) * s));
        SrbKnot {
            t: a.t + (b.t - a.t) * s,
            com: lerp(&a.com, &b.com),
            com_velocity: lerp(&a.com_velocity, &b.com_velocity),
            rotation,
            omega: lerp(&a.omega, &b.omega),
            // A foot pushing over the interval stays at its contact point.
            feet: std::array::from_fn(|f| if a.contacts[f] { a.feet[f] } else { lerp(&a.feet[f], &b.feet[f]) }),
            forces: a.forces,
            contacts: a.contacts,
        }
    }

    /// The trajectory on a uniform grid of step `dt`, phase by phase: phase `i` gets
    /// `n_i = round(T_i / dt)` intervals, and its knot `m` samples the solution at
    /// `S_i + (m / n_i) T_i` (`S_i` the phase's start), so that the phase switches fall on
    /// grid points; each phase is stretched by `n_i dt / T_i` (at most half a step over
    /// its duration). The new phase durations are `n_i dt`.
    pub fn resample(&self, dt: f64) -> Result<SrbTrajectory, SrbSolutionError> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(SrbSolutionError::Step(dt));
        }
        let mut phase_knots = Vec::with_capacity(self.phase_durations.len());
        for (phase, &duration) in self.phase_durations.iter().enumerate() {
            let n = (duration / dt).round() as usize;
            if n == 0 {
                return Err(SrbSolutionError::PhaseTooShort { phase, duration, dt });
            }
            phase_knots.push(n);
        }
        let total: usize = phase_knots.iter().sum();
        let mut knots = Vec::with_capacity(total + 1);
        for (phase, &n) in phase_knots.iter().enumerate() {
            for m in 0..n {
                let mut k = self.sample(phase, m as f64 / n as f64);
                k.t = knots.len() as f64 * dt;
                knots.push(k);
            }
        }
        let mut end = self.knots[self.knots.len() - 1].clone();
        end.t = total as f64 * dt;
        knots.push(end);
        Ok(SrbTrajectory {
            knots,
            phase_durations: phase_knots.iter().map(|&n| n as f64 * dt).collect(),
            phase_knots,
            phase_contacts: self.phase_contacts.clone(),
        })
    }

    /// Index of the phase the interval starting at knot `k` belongs to (the last phase for
    /// the last knot).
    pub fn phase_of_knot(&self, k: usize) -> usize {
        let mut start = 0;
        for (i, &n) in self.phase_knots.iter().enumerate() {
            if k < start + n {
                return i;
            }
            start += n;
        }
        self.phase_knots.len() - 1
    }
}
