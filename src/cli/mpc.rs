//! `legwork mpc <task>`: the task in closed loop under receding-horizon SLQ.

use super::outcome::Verdict;
use super::solve::{job_error, load_task};
use anyhow::Result;
use clap::Args;
use legwork::job::mpc::{ClosedLoopSim, MpcJob};
use legwork::job::solve::SolveJob;
use legwork::mpc::{MpcSettings, PolicyLatency};
use legwork::ocp::SolveOptions;
use legwork::sim::Push;
use std::path::PathBuf;

#[derive(Debug, Args)]
pub struct MpcArgs {
    /// An embedded task (`legwork tasks`) or a task file (`.toml`).
    task: String,
    /// The robot (embedded name, URDF or legwork description); default: the task's.
    #[arg(long)]
    robot: Option<String>,
    /// Output folder (created; the plan's solve in `plan/` inside it); default `out/mpc/<task>`.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Length of the receding window (s).
    #[arg(long, default_value_t = 0.5)]
    horizon: f64,
    /// Ticks per second: a solve from the measured state every 1 / rate s.
    #[arg(long, default_value_t = 200.0)]
    rate: f64,
    /// Knot spacing of the window (s); default the tick period. The period must be a whole
    /// number of knots.
    #[arg(long)]
    knot_dt: Option<f64>,
    /// Only the window's first FINE_HEAD seconds in knots of --knot-dt, the rest in knots of
    /// --tail-ticks tick periods; a head as long as the horizon or longer: no tail (with
    /// --knot-dt 0.001 --fine-head 0.05, a 0.5 s window of 1 ms knots for 0.05 s and 5 ms
    /// ones after: 140 knots instead of 500).
    #[arg(long)]
    fine_head: Option<f64>,
    /// The knots after --fine-head in tick periods: 1, or 2 with knots of the tick period
    /// (--fine-head 0.2 --tail-ticks 2: a 0.5 s window of 5 ms knots for 0.2 s and 10 ms
    /// ones after, 70 knots instead of 100; the head alternates by a knot from tick to tick).
    #[arg(long, default_value_t = 1)]
    tail_ticks: usize,
    /// Integration steps per window knot (default: the fewest within the robot's
    /// contact.max_step, one per 1 ms knot on HyQ). With --knot-dt 0.001 against MuJoCo, 4:
    /// the window's rollouts then hold through hard landings.
    #[arg(long)]
    substeps: Option<usize>,
    /// SLQ iterations per tick (real-time iteration: 1).
    #[arg(long, default_value_t = 1)]
    iterations_per_tick: usize,
    /// Run each whole tick after its measurement. Default: the next tick's model and
    /// backward pass are prepared as soon as a policy is out, and a measurement waits only
    /// for the rollouts from it (the same iterates; the policy sooner).
    #[arg(long)]
    no_prepare_ahead: bool,
    /// Threads of the controller's solver (and of the plan's solve).
    #[arg(long, default_value_t = 2)]
    threads: usize,
    /// Run the solver's threads under SCHED_FIFO at this priority (1-99), as robot
    /// controllers run their MPC (Linux; root, CAP_SYS_NICE or an rtprio limit). Default:
    /// the operating system's scheduling. The plant keeps the default.
    #[arg(long, value_name = "PRIORITY")]
    realtime_priority: Option<i32>,
    /// When a tick's policy reaches the robot: `measured` (after the solve's wall time, as
    /// on a robot; ticks back to back), `paced` (measured, and each tick starts at its time
    /// on the wall clock, as a robot's control loop) or a fixed number of seconds
    /// (reproducible runs).
    #[arg(long, default_value = "measured")]
    latency: String,
    /// A push on the base: X,Y,Z@T:DUR (N in the world frame, start and duration in s), e.g.
    /// `0,100,0@1.0:0.2`. Repeatable.
    #[arg(long)]
    push: Vec<String>,
    /// Drop the task's own state costs from the window (track the plan only).
    #[arg(long)]
    no_task_costs: bool,
    /// End the windows on the tracking cost's terminal weights instead of the plan's value function.
    #[arg(long)]
    no_plan_value: bool,
    /// The shortest window (s): a window that reaches the task's end ends there, its final
    /// cost last as in the plan, but spans at least this long.
    #[arg(long, default_value_t = 0.1)]
    shortest_window: f64,
    /// Keep the window's length past the task's end (its knots there tracking the plan's
    /// final state) instead of ending it at the task's end.
    #[arg(long)]
    window_past_end: bool,
    /// Linearize without the contact anchors as states (smaller, faster windows; needs
    /// --no-plan-value: the plan's value function is on the anchored state).
    #[arg(long)]
    no_anchor_states: bool,
    /// Linearize every substep of a window's knot exactly (default: the first substep's
    /// model held over the knot, one derivative evaluation per knot).
    #[arg(long)]
    exact_knots: bool,
    /// Keep most knots' models from tick to tick: HEAD,PERIOD linearizes the first HEAD
    /// knots, the new ones and every PERIOD-th other each tick (multi-level iteration);
    /// the rest keep their models, their cost gradients moved to the new trajectory.
    #[arg(long, value_name = "HEAD,PERIOD")]
    reuse_models: Option<String>,
    /// What the robot's policy feeds back between ticks: `optimizer` (the window's gains on
    /// legwork's state, the stance feet's contact anchors estimated) or `physical` (the
    /// gains a plan exports: on joint and base positions and velocities alone, the stance
    /// feet held planted; for a stiff ground, MuJoCo's or a robot's).
    #[arg(long, value_enum, default_value_t = FeedbackChoice::Optimizer)]
    feedback: FeedbackChoice,
    /// The smallest regularization of the window's SLQ (1e-3).
    #[arg(long, default_value_t = 1e-3)]
    regularization: f64,
    /// Scale of the tracking weights (0: none).
    #[arg(long, default_value_t = 1.0)]
    tracking: f64,
    /// The window's base-position tracking weights along the world's x, y and z, before
    /// `--tracking` scales them (default 1000,2000,1000: the sideways one doubled against the
    /// walk forward's sway in MuJoCo, docs/experiments/mpc-21.md).
    #[arg(long, value_name = "X,Y,Z")]
    tracking_base_position: Option<String>,
    /// Overrides the plan's iteration limit.
    #[arg(long)]
    iterations: Option<usize>,
    /// Overrides one value of the task (`PATH=VALUE`, as `legwork solve --set`). Repeatable.
    #[arg(long = "set", value_name = "PATH=VALUE")]
    set: Vec<String>,
    /// The physics of the closed loop: legwork's simulator, or MuJoCo (through the checker's
    /// Python, `scripts/install-mujoco.sh`).
    #[arg(long, value_enum, default_value_t = SimChoice::Legwork)]
    sim: SimChoice,
    /// With `--sim mujoco`: the controller reads MuJoCo's state as measured, instead of with
    /// the base lowered to the depth at which legwork's contact model carries MuJoCo's
    /// measured foot forces (legwork's feet rest 3-4 mm deeper than MuJoCo's; on MuJoCo's
    /// depth its contact would carry a few percent of the weight).
    #[arg(long)]
    measured_depth: bool,
    /// Also write every plot as PNG beside its SVG.
    #[arg(long)]
    png: bool,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum FeedbackChoice {
    Optimizer,
    Physical,
}

impl From<FeedbackChoice> for legwork::mpc::MpcFeedback {
    fn from(choice: FeedbackChoice) -> Self {
        match choice {
            FeedbackChoice::Optimizer => Self::Optimizer,
            FeedbackChoice::Physical => Self::Physical,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum SimChoice {
    Legwork,
    Mujoco,
}

/// `measured`, `paced` or seconds.
pub fn parse_latency(text: &str) -> Result<PolicyLatency> {
    match text {
        "measured" => return Ok(PolicyLatency::Measured),
        "paced" => return Ok(PolicyLatency::Paced),
        _ => {}
    }
    match text.parse::<f64>() {
        Ok(l) if l.is_finite() && l >= 0.0 => Ok(PolicyLatency::Fixed(l)),
        _ => anyhow::bail!("--latency {text}: expected `measured`, `paced` or a number of seconds >= 0"),
    }
}

/// `--measured-depth` names MuJoCo's measured state: refused with any other physics.
pub fn check_measured_depth(measured_depth: bool, sim: SimChoice) -> Result<()> {
    if measured_depth && sim != SimChoice::Mujoco {
        anyhow::bail!("--measured-depth: applies to --sim mujoco only (legwork's simulator has legwork's own contact depth)");
    }
    Ok(())
}

/// `--realtime-priority`: tried on a short-lived thread first, so that a machine that
/// refuses SCHED_FIFO is told before the plan's solve, not after it.
pub fn check_realtime_priority(priority: Option<i32>) -> Result<()> {
    let Some(priority) = priority else { return Ok(()) };
    let tried = std::thread::spawn(move || legwork::slq::set_realtime_priority(priority)).join();
    match tried {
        Ok(Ok(())) => Ok(()),
        Ok(Err(e)) => anyhow::bail!("--realtime-priority {priority}: {e}"),
        Err(_) => anyhow::bail!("--realtime-priority {priority}: the thread trying it panicked"),
    }
}

/// `HEAD,PERIOD` of `--reuse-models`.
pub fn parse_model_reuse(text: &str) -> Result<legwork::slq::ModelReuse> {
    let parsed = text.split_once(',').and_then(|(head, period)| Some((head.trim().parse().ok()?, period.trim().parse().ok()?)));
    match parsed {
        Some((fresh_head, refresh_period)) if refresh_period >= 1 => Ok(legwork::slq::ModelReuse { fresh_head, refresh_period }),
        _ => anyhow::bail!("--reuse-models {text}: expected HEAD,PERIOD (knots, whole numbers, PERIOD >= 1), e.g. 10,5"),
    }
}

/// The window's tracking weights: the defaults, the base position's per axis from
/// `--tracking-base-position X,Y,Z` if given (finite, >= 0), all times `--tracking`.
pub fn tracking_weights(scale: f64, base_position: Option<&str>) -> Result<legwork::mpc::TrackingWeights> {
    let mut weights = legwork::mpc::TrackingWeights::default();
    if let Some(text) = base_position {
        let axes: Vec<Option<f64>> = text.split(',').map(|w| w.trim().parse::<f64>().ok().filter(|w| w.is_finite() && *w >= 0.0)).collect();
        weights.base_position = match axes[..] {
            [Some(x), Some(y), Some(z)] => [x, y, z],
            _ => anyhow::bail!("--tracking-base-position {text}: expected three finite weights >= 0 along x, y, z, e.g. 1000,2000,1000"),
        };
    }
    Ok(weights.scaled(scale))
}

/// The exit code's verdict: the closed-loop motion meets the task's targets at twice
/// their tolerances (as every re-run of a plan).
pub fn run(args: MpcArgs) -> Result<Verdict> {
    let (spec, origin) = load_task(&args.task, &args.set)?;
    let model = match &args.robot {
        Some(robot) => super::robot::load(robot)?.0,
        None => spec.load_robot(&origin)?,
    };
    check_measured_depth(args.measured_depth, args.sim)?;
    check_realtime_priority(args.realtime_priority)?;
    let latency = parse_latency(&args.latency)?;
    let pushes = args.push.iter().map(|p| Push::parse(p).map_err(anyhow::Error::msg)).collect::<Result<Vec<_>>>()?;
    let out = args.out.clone().unwrap_or_else(|| PathBuf::from("out").join("mpc").join(&spec.name));
    let plan_out = out.join("plan");
    let threads = super::capped_threads(args.threads);
    let settings = MpcSettings { horizon: args.horizon, rate: args.rate, knot_dt: args.knot_dt, fine_head: args.fine_head, tail_ticks: args.tail_ticks, substeps: args.substeps, iterations_per_tick: args.iterations_per_tick, prepare_ahead: !args.no_prepare_ahead, threads, realtime_priority: args.realtime_priority, task_costs: !args.no_task_costs, plan_value: !args.no_plan_value, ends_at_task_end: (!args.window_past_end).then_some(args.shortest_window), anchor_states: !args.no_anchor_states, regularization: args.regularization, linearization: if args.exact_knots { legwork::ocp::KnotLinearization::EverySubstep } else { legwork::ocp::KnotLinearization::FirstSubstep }, tracking: tracking_weights(args.tracking, args.tracking_base_position.as_deref())?, model_reuse: args.reuse_models.as_deref().map(parse_model_reuse).transpose()?, feedback: args.feedback.into(), ..MpcSettings::default() };
    let sim = match args.sim {
        SimChoice::Legwork => ClosedLoopSim::Legwork,
        SimChoice::Mujoco => ClosedLoopSim::Mujoco { check: legwork::export::MujocoCheck::locate()?, depth_matching: !args.measured_depth },
    };
    let job = MpcJob {
        solve: SolveJob {
            spec: &spec,
            origin: &origin,
            model: &model,
            options: SolveOptions { threads, max_iterations: args.iterations, exploration: None, value_function: true },
            mujoco: None,
            out: &plan_out,
            memory_limit: super::resources::memory_limit(),
            png: args.png,
        },
        settings,
        sim,
        latency,
        pushes,
        out: &out,
    };
    job.check().map_err(job_error)?;
    let s = &job.settings;
    say!("Planning {} ({}) for {}: {} s, then MPC in {} at {} Hz on a {} s window of {} knots of {} s{} ({} integration step(s) a knot), {} iteration(s) per tick{}{}, {} thread(s){}", spec.name, spec.summary, model.name, spec.duration, if args.sim == SimChoice::Mujoco { "MuJoCo" } else { "legwork's simulator" }, s.rate, s.horizon, s.knot_counts().0, s.knot_dt(), if s.knot_counts().1 > 0 { format!(" and {} of {} s", s.knot_counts().1, s.tail_knot_dt()) } else { String::new() }, s.knot_substeps(model.contact.max_step), s.iterations_per_tick, if s.prepare_ahead { " (the next tick's model and backward pass prepared ahead of its measurement)" } else { "" }, s.model_reuse.map(|r| format!(" (models kept: the first {} knots, the new ones and every {}th other relinearized)", r.fresh_head, r.refresh_period)).unwrap_or_default(), s.threads, s.realtime_priority.map(|p| format!(" under SCHED_FIFO priority {p}")).unwrap_or_default());
    let (plan, run) = job.run(|_| {}, |_| {}).map_err(job_error)?;
    let sum = &run.summary;
    let ms = |key: &str| sum[key].as_f64().unwrap_or(f64::NAN) * 1e3;
    say!("plan: {:.2} s to solve; closed loop: {} ticks, solve time per tick median {:.2} ms, p99 {:.2} ms, max {:.2} ms; {} over the {:.1} ms period; latency median {:.2} ms, p99 {:.2} ms; {} restarted from the plan, {} held (every trial past the valid states before the window's end), {} failed", sum["plan_solve_time_s"].as_f64().unwrap_or(0.0), sum["ticks"], ms("tick_time_p50_s"), ms("tick_time_p99_s"), ms("tick_time_max_s"), sum["ticks_over_period"], s.period() * 1e3, ms("latency_p50_s"), ms("latency_p99_s"), sum["restarted_ticks"], sum["held_ticks"], sum["failed_ticks"]);
    if let Some(reason) = &run.closed_loop.stopped {
        say!("the closed loop stopped: {reason}");
    }
    let plan_checks = plan.checked.iter().find(|(n, _)| *n == "plan").and_then(|(_, r)| r.as_ref());
    say!("  {:<46}  {:<14}  {:<14}", "target", "plan", "MPC (2x tol)");
    if let Some(plan_checks) = plan_checks {
        for (i, p) in plan_checks.iter().enumerate() {
            let m = run.checked.as_ref().and_then(|c| c.get(i));
            let cell = |r: Option<&legwork::ocp::TargetResult>| r.map_or("failed".to_string(), |r| format!("{} {}", r.value, if r.met { "ok" } else { "MISSED" }));
            say!("  {:<46}  {:<14}  {:<14}", format!("{} ({})", p.what, p.required), cell(Some(p)), cell(m));
        }
    }
    say!("{}: wrote {}", if run.verdict == legwork::job::Verdict::Met { "TARGET MET" } else { "TARGET MISSED" }, out.display());
    Ok(run.verdict)
}
