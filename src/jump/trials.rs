//! Landing trials (issue 17): a jump run many times with the simulated robot's links'
//! masses and inertias off by up to +-5 % (the controller keeps the nominal model) and the
//! initial base moved by up to +-2 cm, each trial from its own seed, in parallel (rayon).
//!
//! Success: upright one second after touch-down (|roll|, |pitch| below 10 deg), no fall,
//! the base within 5 cm and 5 deg of yaw of the target.

use crate::io::Trajectory;
use crate::jump::control::{run_jump_on, JumpControlError, JumpRun, JumpSettings};
use crate::model::Model;
use crate::terrain::Terrain;
use nalgebra::Vector2;
use rand::{rngs::Xoshiro256PlusPlus, RngExt, SeedableRng};
use rayon::prelude::*;

/// The landing test of issue 17.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SuccessCriteria {
    /// |roll| and |pitch| one second after touch-down (rad). Default 10 deg.
    pub max_tilt: f64,
    /// Horizontal distance of the base to the target (m). Default 5 cm.
    pub max_position_error: f64,
    /// |yaw error| (rad). Default 5 deg.
    pub max_yaw_error: f64,
}

impl Default for SuccessCriteria {
    fn default() -> Self {
        Self { max_tilt: 10f64.to_radians(), max_position_error: 0.05, max_yaw_error: 5f64.to_radians() }
    }
}

impl SuccessCriteria {
    pub fn met_by(&self, run: &JumpRun) -> bool {
        !run.fell && run.roll < self.max_tilt && run.pitch < self.max_tilt && run.position_error <= self.max_position_error && run.yaw_error.abs() <= self.max_yaw_error
    }
}

/// How the trials are drawn.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrialSettings {
    /// Default 20.
    pub trials: usize,
    /// Each link's mass scaled by a factor uniform in `1 +- mass_error`. Default 0.05.
    pub mass_error: f64,
    /// Each link's rotational inertia (about its CoM) scaled by a factor uniform in
    /// `1 +- inertia_error`, drawn independently of its mass. Default 0.05.
    pub inertia_error: f64,
    /// Initial base offset, uniform in `+-base_offset` along x and y (m). Default 0.02 m.
    pub base_offset: f64,
    /// Trial `i` draws from `seed + i`. Default 17.
    pub seed: u64,
    pub criteria: SuccessCriteria,
}

impl Default for TrialSettings {
    fn default() -> Self {
        Self { trials: 20, mass_error: 0.05, inertia_error: 0.05, base_offset: 0.02, seed: 17, criteria: SuccessCriteria::default() }
    }
}

/// The perturbation of one trial.
#[derive(Clone, Debug)]
pub struct Perturbation {
    pub seed: u64,
    /// The simulated robot.
    pub plant: Model,
    /// Its total mass over the nominal one.
    pub mass_ratio: f64,
    pub base_offset: Vector2<f64>,
}

impl Perturbation {
    /// The perturbation drawn from `seed`.
    pub fn draw(nominal: &Model, settings: &TrialSettings, seed: u64) -> Self {
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed ^ 0x6a75_6d70);
        let mut uniform = |half: f64| half * (2.0 * rng.random::<f64>() - 1.0);
        let mut plant = nominal.clone();
        for inertia in plant.inertias.iter_mut().filter(|i| i.mass > 0.0) {
            inertia.mass *= 1.0 + uniform(settings.mass_error);
            inertia.inertia_com *= 1.0 + uniform(settings.inertia_error);
        }
        let base_offset = Vector2::new(uniform(settings.base_offset), uniform(settings.base_offset));
        let mass_ratio = plant.total_mass() / nominal.total_mass();
        Self { seed, plant, mass_ratio, base_offset }
    }
}

/// One trial's outcome.
#[derive(Clone, Debug)]
pub struct TrialOutcome {
    pub seed: u64,
    pub mass_ratio: f64,
    pub base_offset: Vector2<f64>,
    pub run: JumpRun,
    pub success: bool,
}

/// All trials of one jump.
#[derive(Clone, Debug)]
pub struct TrialsReport {
    pub outcomes: Vec<TrialOutcome>,
}

impl TrialsReport {
    pub fn successes(&self) -> usize {
        self.outcomes.iter().filter(|o| o.success).count()
    }

    /// Successes over trials, in `[0, 1]`.
    pub fn success_rate(&self) -> f64 {
        self.successes() as f64 / self.outcomes.len().max(1) as f64
    }
}

/// Runs the trials of `reference` on `terrain` in parallel; the controller uses `model`.
pub fn run_trials(model: &Model, terrain: &dyn Terrain, reference: &Trajectory, jump: &JumpSettings, settings: &TrialSettings) -> Result<TrialsReport, JumpControlError> {
    let fraction = |x: f64| x.is_finite() && (0.0..1.0).contains(&x);
    if !(fraction(settings.mass_error) && fraction(settings.inertia_error)) {
        return Err(JumpControlError::Setting { field: "trials.mass_error/inertia_error", expected: "fractions in [0, 1)".into() });
    }
    if !(settings.base_offset.is_finite() && settings.base_offset >= 0.0) || settings.trials == 0 {
        return Err(JumpControlError::Setting { field: "trials.base_offset/trials", expected: "a non-negative offset (m) and at least one trial".into() });
    }
    let outcomes: Result<Vec<TrialOutcome>, JumpControlError> = (0..settings.trials)
        .into_par_iter()
        .map(|i| {
            let seed = settings.seed + i as u64;
            let p = Perturbation::draw(model, settings, seed);
            let run = run_jump_on(&p.plant, model, terrain, reference, jump, p.base_offset)?;
            let success = settings.criteria.met_by(&run);
            Ok(TrialOutcome { seed, mass_ratio: p.mass_ratio, base_offset: p.base_offset, run, success })
        })
        .collect();
    Ok(TrialsReport { outcomes: outcomes? })
}
