//! `legwork simulate`: a robot on a terrain with a controller, written to a folder.

use super::outcome::{OrCouldNotFinish, Verdict};
use anyhow::{bail, Context, Result};
use clap::{Args, ValueEnum};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use legwork::control::{FeedbackPolicy, JointPd, TrackingController};
use legwork::io::Trajectory;
use legwork::sim::{standing_on_ground, Controller, Integrator, Push, SimConfig, Simulator};
use legwork::terrain::{HeightMap, Plane, Terrain};
use serde_json::json;
use std::path::PathBuf;
use std::time::{Duration, Instant};

#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum ControllerKind {
    /// Joint PD to the standing pose (no feedforward).
    Stand,
    /// Neunert 2017's tracking controller on a planned trajectory (`--reference`).
    Track,
    /// The planned trajectory's exported feedback policy, `tau = tau_ff + K [q (-) q*; v - v*]`
    /// (`--reference`, written by `legwork solve`).
    Policy,
}

#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum IntegratorKind {
    /// Semi-implicit (symplectic) Euler.
    Euler,
    /// Runge-Kutta 4.
    Rk4,
}

#[derive(Debug, Args)]
pub struct SimulateArgs {
    /// Embedded robot name (`legwork robot list`), a URDF file or a legwork description.
    #[arg(long, default_value = "hyq")]
    robot: String,
    /// The controller.
    #[arg(long, value_enum, default_value = "stand")]
    controller: ControllerKind,
    /// Planned trajectory (trajectory.json) for `--controller track`.
    #[arg(long)]
    reference: Option<PathBuf>,
    /// Simulated time (s).
    #[arg(long, default_value_t = 3.0, allow_negative_numbers = true)]
    duration: f64,
    /// A push on the base: X,Y,Z@T:DUR (N in the world frame, start and duration in s),
    /// e.g. 0,50,0@1:0.2. Repeatable.
    #[arg(long, value_name = "X,Y,Z@T:DUR")]
    push: Vec<String>,
    /// Start with the feet this far (m) above the ground (standing pose).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    drop_height: f64,
    /// Ground: a height-map file (TOML, see `legwork::terrain::HeightMapFile`); flat
    /// ground at z = 0 if absent.
    #[arg(long)]
    terrain: Option<PathBuf>,
    #[arg(long, value_enum, default_value = "euler")]
    integrator: IntegratorKind,
    /// Physics rate (Hz).
    #[arg(long, default_value_t = 2000.0)]
    physics_rate: f64,
    /// Control rate (Hz), a whole divisor of the physics rate.
    #[arg(long, default_value_t = 1000.0)]
    control_rate: f64,
    /// Recording rate (Hz), a whole divisor of the physics rate; default: the control rate,
    /// or for runs that would record more than a million knots (about 1.2 KB each in
    /// memory) the rate that records a million, with a warning.
    #[arg(long)]
    record_rate: Option<f64>,
    /// Output folder (created).
    #[arg(long, default_value = "out/simulate")]
    out: PathBuf,
}

/// The highest `--physics-rate` (Hz).
const MAX_PHYSICS_RATE: f64 = 1e5;
/// The longest `--duration` (s): a day.
const MAX_DURATION: f64 = 86_400.0;
/// The highest `--drop-height` (m).
const MAX_DROP_HEIGHT: f64 = 10.0;
/// The memory of a simulation (bytes): the model, the simulator, the replay; and per
/// recorded knot. Measured as `legwork simulate`'s peak resident size on HyQ: 18 MB for 10 s,
/// 48 MB for 40 s at 1 kHz (1.0 KB per knot; 2026-12-03).
const RUN_MEMORY_BYTES: f64 = 16e6;
const KNOT_MEMORY_BYTES: f64 = 1.2e3;
/// trajectory.json and trajectory.csv per recorded knot (bytes): 111 MB for 40,000 knots.
const KNOT_FILE_BYTES: f64 = 2.8e3;
/// The most knots a run records unless `--record-rate` says otherwise (about 1.2 GB in
/// memory, 2.8 GB of files).
const MAX_DEFAULT_KNOTS: f64 = 1e6;
/// Physics steps past which a run is long enough to say how long (about a minute).
const LONG_RUN_STEPS: f64 = 2e7;

pub fn run(args: SimulateArgs) -> Result<()> {
    if !(args.duration > 0.0 && args.duration <= MAX_DURATION) {
        bail!("--duration: expected a positive time of at most {MAX_DURATION} s (a day of robot time, about 10 min of simulation at 2 kHz), got {}", args.duration);
    }
    if args.physics_rate > MAX_PHYSICS_RATE {
        bail!("--physics-rate: expected at most {MAX_PHYSICS_RATE} Hz (the contact model needs steps of at most 1 ms; 100 kHz is a hundred times finer), got {}", args.physics_rate);
    }
    // Long runs record less often by default: at most MAX_DEFAULT_KNOTS knots, at a rate
    // that divides the physics rate, said in a warning.
    let record_rate = match args.record_rate {
        Some(rate) => rate,
        None if args.duration * args.control_rate > MAX_DEFAULT_KNOTS && args.physics_rate.is_finite() && args.physics_rate > 0.0 => {
            let every = (args.duration * args.physics_rate / MAX_DEFAULT_KNOTS).ceil();
            let rate = args.physics_rate / every;
            eprintln!(
                "warning: {} s at the control rate would record {:.1e} knots; recording at {rate:.4} Hz instead (at most {MAX_DEFAULT_KNOTS:.0e} knots; --record-rate sets it)",
                args.duration,
                args.duration * args.control_rate
            );
            rate
        }
        None => args.control_rate,
    };
    for (flag, rate) in [("--physics-rate", args.physics_rate), ("--control-rate", args.control_rate), ("--record-rate", record_rate)] {
        if !(rate.is_finite() && rate > 0.0) {
            bail!("{flag}: expected a positive rate in Hz, got {rate}");
        }
    }
    if !(0.0..=MAX_DROP_HEIGHT).contains(&args.drop_height) {
        bail!("--drop-height: expected 0-{MAX_DROP_HEIGHT} m (from 10 m a robot lands at 14 m/s, past any legged robot's drop test), got {}", args.drop_height);
    }
    if args.drop_height > 1.0 {
        eprintln!("warning: --drop-height {} m: the feet land at {:.1} m/s, faster than the drops legged robots are tested with (up to about 1 m, 4.4 m/s)", args.drop_height, (2.0 * 9.81 * args.drop_height).sqrt());
    }
    // Resources, before any work: the recording's memory, and the time the physics takes.
    let knots = args.duration * record_rate;
    super::resources::check_memory(
        &format!("simulating {} s recorded at {record_rate} Hz ({knots:.0} knots)", args.duration),
        RUN_MEMORY_BYTES + KNOT_MEMORY_BYTES * knots,
        "record less often with --record-rate or shorten --duration",
    )?;
    let steps = args.duration * args.physics_rate;
    if steps > LONG_RUN_STEPS {
        eprintln!(
            "warning: {steps:.1e} physics steps ({} s at {} Hz): about {:.0} min at the simulator's ~300,000 steps/s on one core, and about {:.1} GB of trajectory.json and .csv",
            args.duration,
            args.physics_rate,
            steps / 3e5 / 60.0,
            knots * KNOT_FILE_BYTES / 1e9
        );
    }
    let (model, _) = super::robot::load(&args.robot)?;
    let terrain: Box<dyn Terrain> = match &args.terrain {
        Some(path) => Box::new(HeightMap::load_file(path)?),
        None => Box::new(Plane::flat(0.0)),
    };
    let pushes = args.push.iter().map(|p| Push::parse(p).map_err(anyhow::Error::msg)).collect::<Result<Vec<_>>>()?;
    let config = SimConfig {
        physics_dt: 1.0 / args.physics_rate,
        control_dt: 1.0 / args.control_rate,
        record_dt: 1.0 / record_rate,
        integrator: match args.integrator {
            IntegratorKind::Euler => Integrator::SemiImplicitEuler,
            IntegratorKind::Rk4 => Integrator::Rk4,
        },
        ..SimConfig::default()
    };
    // The controller, and where the run starts: the standing pose (raised by the drop
    // height), or the reference's first state when tracking it.
    let (mut controller, q0, reference): (Box<dyn Controller>, _, Option<Trajectory>) = match (args.controller, &args.reference) {
        (ControllerKind::Stand, None) => {
            (Box::new(JointPd::standing(&model, config.control_dt)?), standing_on_ground(&model, terrain.as_ref(), args.drop_height)?, None)
        }
        (ControllerKind::Stand, Some(_)) => bail!("--reference is for --controller track or policy"),
        (ControllerKind::Track | ControllerKind::Policy, None) => bail!("--controller {} needs --reference <trajectory.json>", if matches!(args.controller, ControllerKind::Track) { "track" } else { "policy" }),
        (kind, Some(path)) => {
            let reference = Trajectory::load_file(path)?;
            reference.check_against(&model, &path.display().to_string())?;
            let controller: Box<dyn Controller> = match kind {
                ControllerKind::Policy => Box::new(FeedbackPolicy::new(&model, &reference)?),
                _ => Box::new(TrackingController::with_default_gains(&model, &reference, config.control_dt)?),
            };
            (controller, nalgebra::DVector::zeros(0), Some(reference))
        }
    };
    // Tracking replays the plan in the world its file records (its ground unless --terrain
    // says otherwise, its first state and contact anchors, its joint stops), as `legwork
    // solve`'s own tracking re-run does.
    let plan_terrain: Option<Box<dyn Terrain>> = match (&reference, &args.terrain) {
        (Some(plan), None) => Some(plan.metadata.terrain.build(&format!("{}: metadata.terrain", args.reference.as_ref().map(|p| p.display().to_string()).unwrap_or_default()))?),
        _ => None,
    };
    let terrain: Box<dyn Terrain> = plan_terrain.unwrap_or(terrain);
    let standing_height = standing_on_ground(&model, terrain.as_ref(), 0.0)?[2];
    let mut sim = match &reference {
        Some(plan) => Simulator::from_plan(&model, terrain.as_ref(), plan, config.clone())?,
        None => Simulator::new(&model, terrain.as_ref(), config.clone(), q0.clone(), None)?,
    };
    let q0 = sim.state().q.clone();
    for p in pushes {
        sim.add_push(p);
    }

    // A progress bar, shown only once the run has taken more than a second.
    let bar = ProgressBar::with_draw_target(Some(1000), ProgressDrawTarget::hidden());
    bar.set_style(ProgressStyle::with_template("{msg} [{bar:40}] {percent}% ({eta} left)").expect("static template"));
    bar.set_message(format!("simulating {} s", args.duration));
    let started = Instant::now();
    let mut shown = false;
    let result = sim.run(args.duration, controller.as_mut(), |fraction| {
        if !shown && started.elapsed() > Duration::from_secs(1) {
            bar.set_draw_target(ProgressDrawTarget::stderr());
            shown = true;
        }
        bar.set_position((fraction * 1000.0) as u64);
    });
    bar.finish_and_clear();
    let run = result.or_could_not_finish()?;
    let stats = &run.stats;
    let last = run.trajectory.knots.last().context("empty trajectory")?;
    let final_height = last.q[2];
    let drift = ((last.q[0] - q0[0]).powi(2) + (last.q[1] - q0[1]).powi(2)).sqrt();
    let steps_per_second = stats.steps as f64 / stats.wall_time;
    let mut traj = run.trajectory;
    traj.metadata.scenario = format!(
        "legwork simulate --robot {} --controller {:?} --duration {}{}{}",
        args.robot,
        args.controller,
        args.duration,
        if args.drop_height > 0.0 { format!(" --drop-height {}", args.drop_height) } else { String::new() },
        args.push.iter().map(|p| format!(" --push {p}")).collect::<String>()
    )
    .to_lowercase();
    let summary = json!({
        // A simulation has no target: it met its job by running to the end.
        "verdict": Verdict::Met.as_str(),
        "exit_code": Verdict::Met.exit_code(),
        "robot": model.name,
        "controller": controller.name(),
        "duration_s": args.duration,
        "physics_rate_hz": args.physics_rate,
        "control_rate_hz": args.control_rate,
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
        "steps_per_second": steps_per_second,
        "real_time_factor": args.duration / stats.wall_time,
    });
    if let serde_json::Value::Object(map) = summary {
        traj.summary = map;
    }
    std::fs::create_dir_all(&args.out).with_context(|| format!("cannot create the output folder {}", args.out.display())).or_could_not_finish()?;
    let json_path = args.out.join("trajectory.json");
    let csv_path = args.out.join("trajectory.csv");
    traj.save_file(&json_path).or_could_not_finish()?;
    traj.save_csv(&csv_path).or_could_not_finish()?;
    let replay_path = args.out.join("replay.html");
    legwork::viz::write_replay(&model, &traj, &replay_path).or_could_not_finish()?;
    let mut plots = legwork::viz::write_plots(&traj, args.out.join("plots")).or_could_not_finish()?;
    plots.extend(legwork::viz::write_limit_plots(&model, &traj, args.out.join("plots")).or_could_not_finish()?);

    say!("Simulated {} for {} s with the {} controller ({} physics steps).", model.name, args.duration, controller.name(), stats.steps);
    say!("  final base height     {:.4} m (standing height {:.4} m, difference {:+.1} mm)", final_height, standing_height, (final_height - standing_height) * 1e3);
    say!("  horizontal drift      {:.1} mm", drift * 1e3);
    say!("  max penetration       {:.2} mm", stats.max_penetration * 1e3);
    say!("  max torque            {:.1} N m", stats.max_torque);
    say!("  max |F_t| / F_n       {:.3} (friction coefficient {})", stats.max_friction_ratio, model.contact.friction);
    say!("  speed                 {:.0} steps/s, {:.1}x real time", steps_per_second, args.duration / stats.wall_time);
    say!("Wrote {}, {}, {} and {} plots in {}", json_path.display(), csv_path.display(), replay_path.display(), plots.len(), args.out.join("plots").display());
    Ok(())
}
