//! `legwork simulate`: a robot on a terrain with a controller, written to a folder.

use anyhow::{bail, Result};
use clap::{Args, ValueEnum};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use legwork::io::Trajectory;
use legwork::job::simulate::{SimController, SimulateJob};
use legwork::sim::{Integrator, Push};
use legwork::terrain::{HeightMap, Terrain};
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
    /// Also write every plot as PNG (2x, text in the embedded DejaVu Sans) beside its SVG.
    #[arg(long)]
    png: bool,
}

/// `--duration` for the job's `duration`.
fn flag(setting: &str) -> String {
    format!("--{}", setting.replace('_', "-"))
}

pub fn run(args: SimulateArgs) -> Result<()> {
    let (model, _) = super::robot::load(&args.robot)?;
    let terrain: Option<Box<dyn Terrain>> = match &args.terrain {
        Some(path) => Some(Box::new(HeightMap::load_file(path)?)),
        None => None,
    };
    let pushes = args.push.iter().map(|p| Push::parse(p).map_err(anyhow::Error::msg)).collect::<Result<Vec<_>>>()?;
    let reference_origin = args.reference.as_ref().map(|p| p.display().to_string()).unwrap_or_default();
    let controller = match (args.controller, &args.reference) {
        (ControllerKind::Stand, None) => SimController::Stand,
        (ControllerKind::Stand, Some(_)) => bail!("--reference is for --controller track or policy"),
        (ControllerKind::Track | ControllerKind::Policy, None) => bail!("--controller {} needs --reference <trajectory.json>", if matches!(args.controller, ControllerKind::Track) { "track" } else { "policy" }),
        (ControllerKind::Track, Some(path)) => SimController::Track(Trajectory::load_file(path)?),
        (ControllerKind::Policy, Some(path)) => SimController::Policy(Trajectory::load_file(path)?),
    };
    let scenario = format!(
        "legwork simulate --robot {} --controller {:?} --duration {}{}{}",
        args.robot,
        args.controller,
        args.duration,
        if args.drop_height > 0.0 { format!(" --drop-height {}", args.drop_height) } else { String::new() },
        args.push.iter().map(|p| format!(" --push {p}")).collect::<String>()
    )
    .to_lowercase();
    let job = SimulateJob {
        model: &model,
        controller,
        reference_origin,
        terrain: terrain.as_deref(),
        duration: args.duration,
        pushes,
        drop_height: args.drop_height,
        integrator: match args.integrator {
            IntegratorKind::Euler => Integrator::SemiImplicitEuler,
            IntegratorKind::Rk4 => Integrator::Rk4,
        },
        physics_rate: args.physics_rate,
        control_rate: args.control_rate,
        record_rate: args.record_rate,
        scenario,
        memory_limit: super::resources::memory_limit(),
        png: args.png,
        setting: flag,
    };
    let (_, warnings) = job.check().map_err(super::solve::job_error)?;
    for w in warnings {
        eprintln!("warning: {w}");
    }

    // A progress bar, shown only once the run has taken more than a second.
    let bar = ProgressBar::with_draw_target(Some(1000), ProgressDrawTarget::hidden());
    bar.set_style(ProgressStyle::with_template("{msg} [{bar:40}] {percent}% ({eta} left)").expect("static template"));
    bar.set_message(format!("simulating {} s", args.duration));
    let started = Instant::now();
    let mut shown = false;
    let result = job.run(Some(&args.out), |fraction| {
        if !shown && started.elapsed() > Duration::from_secs(1) {
            bar.set_draw_target(ProgressDrawTarget::stderr());
            shown = true;
        }
        bar.set_position((fraction * 1000.0) as u64);
    });
    bar.finish_and_clear();
    let done = result.map_err(super::solve::job_error)?;
    let stats = &done.stats;
    let steps_per_second = stats.steps as f64 / stats.wall_time;
    say!("Simulated {} for {} s with the {} controller ({} physics steps).", model.name, args.duration, done.controller, stats.steps);
    say!("  final base height     {:.4} m (standing height {:.4} m, difference {:+.1} mm)", done.final_height, done.standing_height, (done.final_height - done.standing_height) * 1e3);
    say!("  horizontal drift      {:.1} mm", done.drift * 1e3);
    say!("  max penetration       {:.2} mm", stats.max_penetration * 1e3);
    say!("  max torque            {:.1} N m", stats.max_torque);
    say!("  max |F_t| / F_n       {:.3} (friction coefficient {})", stats.max_friction_ratio, model.contact.friction);
    say!("  speed                 {:.0} steps/s, {:.1}x real time", steps_per_second, args.duration / stats.wall_time);
    say!(
        "Wrote {}, {}, {} and {} plots in {}",
        args.out.join("trajectory.json").display(),
        args.out.join("trajectory.csv").display(),
        args.out.join("replay.html").display(),
        done.plots,
        args.out.join("plots").display()
    );
    Ok(())
}
