//! The simulate job (`legwork simulate`, Python's `legwork.simulate`): a robot on a terrain
//! with a controller (the standing PD, Neunert 2017's tracking controller on a plan, or a
//! plan's exported feedback policy), pushes on the base, and the folder of files:
//! `trajectory.json`, `trajectory.csv`, `replay.html`, plots.

use super::resources::{check_memory, MemoryLimit};
use super::{JobError, OrCouldNotFinish};
use crate::control::{FeedbackPolicy, JointPd, TrackingController};
use crate::io::Trajectory;
use crate::model::Model;
use crate::sim::{standing_on_ground, Controller, Integrator, Push, RunStats, SimConfig, Simulator};
use crate::terrain::{Plane, Terrain};
use nalgebra::DVector;
use serde_json::json;
use std::path::Path;

/// The highest physics rate (Hz).
pub const MAX_PHYSICS_RATE: f64 = 1e5;
/// The longest simulated time (s): a day.
pub const MAX_DURATION: f64 = 86_400.0;
/// The highest drop height (m).
pub const MAX_DROP_HEIGHT: f64 = 10.0;
/// The memory of a simulation (bytes): the model, the simulator, the replay; and per
/// recorded knot. Measured as `legwork simulate`'s peak resident size on HyQ: 18 MB for 10 s,
/// 48 MB for 40 s at 1 kHz (1.0 KB per knot; 2026-12-03).
const RUN_MEMORY_BYTES: f64 = 16e6;
const KNOT_MEMORY_BYTES: f64 = 1.2e3;
/// trajectory.json and trajectory.csv per recorded knot (bytes): 111 MB for 40,000 knots.
const KNOT_FILE_BYTES: f64 = 2.8e3;
/// The most knots a run records unless the record rate says otherwise (about 1.2 GB in
/// memory, 2.8 GB of files).
const MAX_DEFAULT_KNOTS: f64 = 1e6;
/// Physics steps past which a run is long enough to say how long (about a minute).
const LONG_RUN_STEPS: f64 = 2e7;

/// The controller of a simulation.
pub enum SimController {
    /// Joint PD to the standing pose (no feedforward), from the standing pose raised by the
    /// drop height.
    Stand,
    /// Neunert 2017's tracking controller on a plan, from the plan's first state, in the
    /// world the plan records.
    Track(Trajectory),
    /// The plan's exported feedback policy `tau = tau_ff + K [q (-) q*; v - v*]`.
    Policy(Trajectory),
}

/// A simulation to run. Rates in Hz; the names of the settings (`--duration`,
/// `duration=`) come from the front end through `setting`.
pub struct SimulateJob<'a> {
    pub model: &'a Model,
    pub controller: SimController,
    /// Where the plan came from, for messages (`out/gallop/trajectory.json`).
    pub reference_origin: String,
    /// The ground; `None`: the plan's (tracking, policy) or flat ground at z = 0.
    pub terrain: Option<&'a dyn Terrain>,
    pub duration: f64,
    pub pushes: Vec<Push>,
    pub drop_height: f64,
    pub integrator: Integrator,
    pub physics_rate: f64,
    pub control_rate: f64,
    /// `None`: the control rate, or for runs that would record more than a million knots
    /// the rate that records a million (said in a warning).
    pub record_rate: Option<f64>,
    /// What the run is (`legwork simulate --robot hyq ...`), in the trajectory's metadata.
    pub scenario: String,
    pub memory_limit: MemoryLimit<'a>,
    /// Also write each plot as PNG (`--png`).
    pub png: bool,
    /// Names a setting in messages: `setting("duration")` is `--duration` on the command line.
    pub setting: fn(&str) -> String,
}

/// A finished simulation.
pub struct Simulated {
    /// The run, its summary filled.
    pub trajectory: Trajectory,
    pub stats: RunStats,
    pub controller: String,
    pub final_height: f64,
    pub standing_height: f64,
    pub drift: f64,
    /// Plots written (0 when no folder was given).
    pub plots: usize,
}

impl SimulateJob<'_> {
    /// The settings checked, the record rate decided and the memory bounded, before any
    /// work; returns the record rate and warnings to show (a long run, a high drop).
    pub fn check(&self) -> Result<(f64, Vec<String>), JobError> {
        let s = self.setting;
        let mut warnings = Vec::new();
        if !(self.duration > 0.0 && self.duration <= MAX_DURATION) {
            return Err(JobError::bad_input(format!("{}: expected a positive time of at most {MAX_DURATION} s (a day of robot time, about 10 min of simulation at 2 kHz), got {}", s("duration"), self.duration)));
        }
        if self.physics_rate > MAX_PHYSICS_RATE {
            return Err(JobError::bad_input(format!("{}: expected at most {MAX_PHYSICS_RATE} Hz (the contact model needs steps of at most 1 ms; 100 kHz is a hundred times finer), got {}", s("physics_rate"), self.physics_rate)));
        }
        let record_rate = match self.record_rate {
            Some(rate) => rate,
            None if self.duration * self.control_rate > MAX_DEFAULT_KNOTS && self.physics_rate.is_finite() && self.physics_rate > 0.0 => {
                let every = (self.duration * self.physics_rate / MAX_DEFAULT_KNOTS).ceil();
                let rate = self.physics_rate / every;
                warnings.push(format!(
                    "{} s at the control rate would record {:.1e} knots; recording at {rate:.4} Hz instead (at most {MAX_DEFAULT_KNOTS:.0e} knots; {} sets it)",
                    self.duration,
                    self.duration * self.control_rate,
                    s("record_rate")
                ));
                rate
            }
            None => self.control_rate,
        };
        for (name, rate) in [("physics_rate", self.physics_rate), ("control_rate", self.control_rate), ("record_rate", record_rate)] {
            if !(rate.is_finite() && rate > 0.0) {
                return Err(JobError::bad_input(format!("{}: expected a positive rate in Hz, got {rate}", s(name))));
            }
        }
        if !(0.0..=MAX_DROP_HEIGHT).contains(&self.drop_height) {
            return Err(JobError::bad_input(format!("{}: expected 0-{MAX_DROP_HEIGHT} m (from 10 m a robot lands at 14 m/s, past any legged robot's drop test), got {}", s("drop_height"), self.drop_height)));
        }
        if self.drop_height > 1.0 {
            warnings.push(format!("{} {} m: the feet land at {:.1} m/s, faster than the drops legged robots are tested with (up to about 1 m, 4.4 m/s)", s("drop_height"), self.drop_height, (2.0 * 9.81 * self.drop_height).sqrt()));
        }
        let knots = self.duration * record_rate;
        check_memory(
            &format!("simulating {} s recorded at {record_rate} Hz ({knots:.0} knots)", self.duration),
            RUN_MEMORY_BYTES + KNOT_MEMORY_BYTES * knots,
            &format!("record less often with {} or shorten {}", s("record_rate"), s("duration")),
            self.memory_limit,
        )?;
        let steps = self.duration * self.physics_rate;
        if steps > LONG_RUN_STEPS {
            warnings.push(format!(
                "{steps:.1e} physics steps ({} s at {} Hz): about {:.0} min at the simulator's ~300,000 steps/s on one core, and about {:.1} GB of trajectory.json and .csv",
                self.duration,
                self.physics_rate,
                steps / 3e5 / 60.0,
                knots * KNOT_FILE_BYTES / 1e9
            ));
        }
        Ok((record_rate, warnings))
    }

    /// Runs the simulation (`on_progress` sees the fraction done) and, with `out`, writes
    /// the folder.
    pub fn run(&self, out: Option<&Path>, on_progress: impl FnMut(f64)) -> Result<Simulated, JobError> {
        let (record_rate, _) = self.check()?;
        let model = self.model;
        let config = SimConfig { physics_dt: 1.0 / self.physics_rate, control_dt: 1.0 / self.control_rate, record_dt: 1.0 / record_rate, integrator: self.integrator, ..SimConfig::default() };
        // Tracking replays the plan in the world its file records (its ground unless a
        // terrain is given, its first state and contact anchors, its joint stops), as
        // `legwork solve`'s own tracking re-run does.
        let reference = match &self.controller {
            SimController::Stand => None,
            SimController::Track(plan) | SimController::Policy(plan) => {
                plan.check_against(model, &self.reference_origin).map_err(JobError::bad_input)?;
                Some(plan)
            }
        };
        let built: Box<dyn Terrain>;
        let terrain: &dyn Terrain = match (self.terrain, reference) {
            (Some(t), _) => t,
            (None, Some(plan)) => {
                built = plan.metadata.terrain.build(&format!("{}: metadata.terrain", self.reference_origin)).map_err(JobError::bad_input)?;
                built.as_ref()
            }
            (None, None) => {
                built = Box::new(Plane::flat(0.0));
                built.as_ref()
            }
        };
        let mut controller: Box<dyn Controller> = match &self.controller {
            SimController::Stand => Box::new(JointPd::standing(model, config.control_dt).map_err(JobError::bad_input)?),
            SimController::Track(plan) => Box::new(TrackingController::with_default_gains(model, plan, config.control_dt).map_err(JobError::bad_input)?),
            SimController::Policy(plan) => Box::new(FeedbackPolicy::new(model, plan).map_err(JobError::bad_input)?),
        };
        let standing_height = standing_on_ground(model, terrain, 0.0).map_err(JobError::bad_input)?[2];
        let mut sim = match reference {
            Some(plan) => Simulator::from_plan(model, terrain, plan, config.clone()).map_err(JobError::bad_input)?,
            None => {
                let q0 = standing_on_ground(model, terrain, self.drop_height).map_err(JobError::bad_input)?;
                Simulator::new(model, terrain, config.clone(), q0, None).map_err(JobError::bad_input)?
            }
        };
        let q0: DVector<f64> = sim.state().q.clone();
        for p in &self.pushes {
            sim.add_push(*p);
        }
        let run = sim.run(self.duration, controller.as_mut(), on_progress).or_could_not_finish()?;
        let stats = run.stats;
        let last = run.trajectory.knots.last().ok_or_else(|| JobError::could_not_finish("the simulation recorded no knot"))?;
        let final_height = last.q[2];
        let drift = ((last.q[0] - q0[0]).powi(2) + (last.q[1] - q0[1]).powi(2)).sqrt();
        let mut trajectory = run.trajectory;
        trajectory.metadata.scenario = self.scenario.clone();
        let summary = json!({
            // A simulation has no target: it met its job by running to the end.
            "verdict": super::Verdict::Met.as_str(),
            "exit_code": super::Verdict::Met.exit_code(),
            "robot": model.name,
            "controller": controller.name(),
            "duration_s": self.duration,
            "physics_rate_hz": self.physics_rate,
            "control_rate_hz": self.control_rate,
            "final_base_height_m": final_height,
            "standing_height_m": standing_height,
            "final_horizontal_drift_m": drift,
            "max_penetration_m": stats.max_penetration,
            "max_torque_nm": stats.max_torque,
            "max_friction_ratio": stats.max_friction_ratio,
            "friction_coefficient": model.contact.friction,
            "slipping_steps": stats.slipping_steps,
            "saturated_control_periods": stats.saturated_controls,
            "physics_steps": stats.steps,
            "wall_time_s": stats.wall_time,
            "steps_per_second": stats.steps as f64 / stats.wall_time,
            "real_time_factor": self.duration / stats.wall_time,
        });
        if let serde_json::Value::Object(map) = summary {
            trajectory.summary = map;
        }
        let plots = match out {
            Some(out) => write_files(model, &trajectory, out, self.png).or_could_not_finish()?,
            None => 0,
        };
        Ok(Simulated { trajectory, stats, controller: controller.name().to_string(), final_height, standing_height, drift, plots })
    }
}

/// `trajectory.json`, `trajectory.csv`, `replay.html` and the plots; returns the number of plots.
fn write_files(model: &Model, trajectory: &Trajectory, out: &Path, png: bool) -> Result<usize, Box<dyn std::error::Error + Send + Sync>> {
    std::fs::create_dir_all(out).map_err(|e| format!("cannot create the output folder {}: {e}", out.display()))?;
    trajectory.save_file(out.join("trajectory.json"))?;
    trajectory.save_csv(out.join("trajectory.csv"))?;
    crate::viz::write_replay(model, trajectory, out.join("replay.html"))?;
    let mut plots = crate::viz::write_plots(trajectory, out.join("plots"))?;
    plots.extend(crate::viz::write_limit_plots(model, trajectory, out.join("plots"))?);
    if png {
        crate::viz::png::write_pngs(&plots, crate::viz::png::PNG_SCALE)?;
    }
    Ok(plots.len())
}
