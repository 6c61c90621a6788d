//! `legwork jump <name|file.toml>` and `legwork jumps`: Nguyen 2022's 3D jumps, planned and
//! run as far as this build's pipeline goes ([`legwork::jump::pipeline`]).

use anyhow::{Context, Result};
use clap::Args;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use legwork::jump::{pipeline, srb_plan_trajectory, Jump, JumpReport, PipelineOptions, Stage, EMBEDDED_JUMPS};
use legwork::model::Model;
use legwork::srb::{ContactTimingSettings, SrbParams};
use std::path::{Path, PathBuf};
use super::outcome::OrCouldNotFinish;
use std::process::ExitCode;
use std::time::{Duration, Instant};

#[derive(Debug, Args)]
pub struct JumpArgs {
    /// An embedded jump (`legwork jumps`) or a jump file (`.toml`).
    jump: String,
    /// Output folder (created); default `out/jump/<jump>`.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Overrides the contact-timing knots per phase `N_i` (the paper's 30): a short form for
    /// quick checks.
    #[arg(long)]
    knots: Option<usize>,
    /// Robustness trials after the nominal re-run (+-5 % mass and inertia, +-2 cm base
    /// offset; issue 17 asks for 20).
    #[arg(long, default_value_t = 0)]
    trials: usize,
    /// Threads of the full body's stage evaluations and of the trials (0: one per core, the
    /// default; 1: sequential). The contact timing solves on one thread whatever this says:
    /// its stages are too small to share (1.3-1.5x slower on two threads, BENCHMARKS.md).
    #[arg(long, default_value_t = 0)]
    threads: usize,
}

/// Runs `work` on a pool of `threads` threads (0: one per core) with the full body's stage
/// evaluations parallel when there is more than one.
pub(super) fn with_threads<T>(threads: usize, options: &mut PipelineOptions, work: impl FnOnce(&PipelineOptions) -> Result<T> + Send) -> Result<T>
where
    T: Send,
{
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().context("--threads: cannot start the thread pool")?;
    options.full_body.solver.parallel = pool.current_num_threads() > 1;
    let options = &*options;
    pool.install(|| work(options))
}

/// The jump's settings with the command line's overrides.
pub(super) fn settings_of(jump: &Jump, knots: Option<usize>) -> Result<ContactTimingSettings> {
    let settings = ContactTimingSettings { knots_per_phase: knots.unwrap_or(jump.contact_timing.knots_per_phase), ..jump.contact_timing.clone() };
    settings.validate().context("--knots")?;
    Ok(settings)
}

fn stage_name(stage: Stage) -> &'static str {
    match stage {
        Stage::ContactTiming => "contact timing (single rigid body, sec. II-B)",
        Stage::FullBody => "full-body trajectory optimization (sec. II-C)",
        Stage::Controllers => "jump and landing controllers in legwork's simulator (sec. III)",
        Stage::Trials => "robustness trials (mass, inertia, base offset)",
    }
}

/// `legwork jumps`: one line per embedded jump.
pub fn list() -> Result<()> {
    let width = EMBEDDED_JUMPS.iter().map(|(n, _, _)| n.len()).max().unwrap_or(0);
    for (name, _, _) in EMBEDDED_JUMPS {
        let jump = Jump::embedded(name)?;
        say!("{name:<width$}  {} ({}, {} phases, T in [{}, {}] s)", jump.summary, jump.robot, jump.phases.len(), jump.total_time.0, jump.total_time.1);
    }
    Ok(())
}

pub fn run(args: JumpArgs) -> Result<ExitCode> {
    super::check_trials(args.trials)?;
    let jump = Jump::load(&args.jump)?;
    let (model, _) = super::robot::load(&jump.robot)?;
    let settings = settings_of(&jump, args.knots)?;
    let out = args.out.clone().unwrap_or_else(|| PathBuf::from("out").join("jump").join(&jump.name));
    say!(
        "Jump {} ({}) for {}: {} phases, {} knots each, T in [{}, {}] s, box {} m",
        jump.name,
        jump.summary,
        model.name,
        jump.phases.len(),
        settings.knots_per_phase,
        jump.total_time.0,
        jump.total_time.1,
        jump.box_height()
    );
    let started = Instant::now();
    let bar = ProgressBar::with_draw_target(None, ProgressDrawTarget::stderr());
    bar.set_style(ProgressStyle::with_template("{spinner} {msg} ({elapsed})").expect("static template"));
    bar.enable_steady_tick(Duration::from_millis(120));
    let mut options = PipelineOptions { contact_timing: settings.clone(), trials: args.trials, ..PipelineOptions::of(&jump) };
    let report = with_threads(super::capped_threads(args.threads), &mut options, |options| {
        Ok(pipeline::run(&jump, &model, options, |stage, done| {
            if done {
                bar.println(format!("  done: {}", stage_name(stage)));
            } else {
                bar.set_message(stage_name(stage).to_string());
            }
        })?)
    })
    .or_could_not_finish()?;
    bar.finish_and_clear();
    let written = write_outputs(&jump, &model, &options, &report, &out).or_could_not_finish()?;
    print_report(&jump, &report);
    say!("Wrote {} ({}) in {:.1} s", out.display(), written.join(", "), started.elapsed().as_secs_f64());
    let verdict = report.verdict();
    say!("{} (exit code {})", verdict.describe(), verdict.exit_code());
    Ok(ExitCode::from(verdict.exit_code()))
}

/// trajectory.json (the full-body plan), rerun.json (the controllers' run),
/// contact_timing.json (the single-rigid-body plan), replay.html (the re-run, or the best
/// plan there is) and the plots; returns what was written.
fn write_outputs(jump: &Jump, model: &Model, options: &PipelineOptions, report: &JumpReport, out: &Path) -> Result<Vec<String>> {
    use legwork::viz::jump as plots;
    std::fs::create_dir_all(out).with_context(|| format!("cannot create the output folder {}", out.display()))?;
    let dir = out.join("plots");
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let summary = report.summary(jump);
    let terrain = legwork::terrain::Terrain::spec(&jump.terrain());
    let mut written = Vec::new();
    let params = SrbParams::from_model(model, "standing")?;
    let ct = &report.contact_timing;
    let mut srb = srb_plan_trajectory(model, jump, &params, ct.knots())?;
    srb.summary = summary.clone();
    srb.summary.insert("trajectory".into(), "the contact-timing plan: the single rigid body's base and ground forces, legs by inverse kinematics to its feet, no joint torques (tau = 0)".into());
    srb.save_file(out.join("contact_timing.json"))?;
    written.push("contact_timing.json".to_string());
    let ct_settings = &options.contact_timing;
    plots::write_phase_timings(&dir.join("phase_timings.svg"), &format!("{}: optimal phase durations", jump.name), &jump.phases, &ct.durations, jump.paper.as_ref().map(|p| p.timings_10ms.as_slice()))?;
    plots::write_srb_forces(&dir.join("contact_timing_forces.svg"), ct.knots(), ct_settings.mu, (ct_settings.f_min, ct_settings.f_max))?;
    plots::write_srb_pose(&dir.join("contact_timing_pose.svg"), ct.knots())?;
    written.push("plots/phase_timings.svg, contact_timing_{forces,pose}.svg".into());
    let mut replay = srb.clone();
    if let Some(plan) = &report.full_body_plan {
        let mut traj = plan.trajectory.clone();
        traj.metadata.terrain = terrain.clone();
        traj.summary = summary.clone();
        traj.save_file(out.join("trajectory.json"))?;
        let fb = &options.full_body;
        plots::write_trajectory_forces(&dir.join("plan_ground_forces.svg"), &traj, fb.mu, fb.min_normal_force)?;
        plots::write_torque_limits(&dir.join("plan_torques.svg"), model, &traj)?;
        legwork::viz::write_plots(&traj, dir.join("plan"))?;
        written.push("trajectory.json (full-body plan), plots/plan_{ground_forces,torques}.svg, plots/plan/".into());
        replay = traj;
    }
    if let Some(run) = &report.rerun {
        let mut traj = run.trajectory.clone();
        traj.metadata.terrain = terrain.clone();
        traj.summary = summary.clone();
        traj.save_file(out.join("rerun.json"))?;
        plots::write_trajectory_forces(&dir.join("rerun_ground_forces.svg"), &traj, model.contact.friction, 0.0)?;
        plots::write_torque_limits(&dir.join("rerun_torques.svg"), model, &traj)?;
        legwork::viz::write_plots(&traj, dir.join("rerun"))?;
        written.push("rerun.json, plots/rerun_{ground_forces,torques}.svg, plots/rerun/".into());
        replay = traj;
    }
    legwork::viz::write_replay(model, &replay, out.join("replay.html"))?;
    written.push(format!("replay.html ({})", replay.metadata.scenario));
    Ok(written)
}

fn print_report(jump: &Jump, report: &JumpReport) {
    let ct = &report.contact_timing;
    let tenths = |v: &[f64]| v.iter().map(|x| format!("{x:.1}")).collect::<Vec<_>>().join(", ");
    let ours: Vec<f64> = ct.durations.iter().map(|t| t * 100.0).collect();
    say!(
        "  contact timing: {:?} after {} iterations in {:.3} s, cost {:.6e}, constraint violation {:.1e}",
        ct.status,
        ct.iterations,
        ct.solve_time_s,
        ct.objective,
        ct.primal_infeasibility
    );
    match &jump.paper {
        Some(p) => say!("  phase durations [10 ms]: {} (paper, Table I: {}; its contact timing {} s, full body {} s)", tenths(&ours), tenths(&p.timings_10ms), p.contact_timing_s, p.full_body_s),
        None => say!("  phase durations [10 ms]: {}", tenths(&ours)),
    }
    say!("  full body: {}", report.full_body);
    if let Some(p) = &report.full_body_plan {
        let r = &p.report;
        say!(
            "    {:?} after {} iterations in {:.3} s (evaluation {:.3} s, KKT {:.3} s), cost {:.6e}, violation {:.1e}, limits {}",
            r.status,
            r.iterations,
            r.time.as_secs_f64(),
            r.evaluation_time.as_secs_f64(),
            r.kkt_time.as_secs_f64(),
            r.objective,
            r.primal_infeasibility,
            if p.limits.all_met(1e-6) { "met" } else { "VIOLATED" }
        );
    }
    say!("  controllers: {}", report.controllers);
    if let Some(r) = &report.rerun {
        let t = |x: Option<f64>| x.map_or("-".to_string(), |t| format!("{t:.3} s"));
        say!(
            "    lift-off {}, touch-down {}, landing switch {}; landing error {:.1} mm, yaw error {:.2} deg, roll {:.1} deg, pitch {:.1} deg{}",
            t(r.lift_off),
            t(r.touch_down),
            t(r.switch),
            1e3 * r.position_error,
            r.yaw_error.to_degrees(),
            r.roll.to_degrees(),
            r.pitch.to_degrees(),
            if r.fell { "; FELL" } else { "" }
        );
        if let Some(f) = &r.failure {
            say!("    {f}");
        }
    }
    if let Some(tr) = &report.trials {
        say!("  trials: {}/{} landed on target ({:.0} %)", tr.successes(), tr.outcomes.len(), 100.0 * tr.success_rate());
    }
    for c in &report.stance_conflicts {
        say!("  warning: {c}: the target is not a landing on the ground beside the box");
    }
}
