//! `legwork jump <name|file.toml>` and `legwork jumps`: Nguyen 2022's 3D jumps, planned and
//! run as far as this build's pipeline goes ([`legwork::jump::pipeline`]).

use anyhow::{Context, Result};
use clap::Args;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use legwork::jump::{pipeline, srb_plan_trajectory, Jump, JumpReport, Stage, EMBEDDED_JUMPS};
use legwork::model::Model;
use legwork::srb::{ContactTimingSettings, SrbParams};
use std::path::{Path, PathBuf};
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
    }
}

/// `legwork jumps`: one line per embedded jump.
pub fn list() -> Result<()> {
    let width = EMBEDDED_JUMPS.iter().map(|(n, _)| n.len()).max().unwrap_or(0);
    for (name, _) in EMBEDDED_JUMPS {
        let jump = Jump::embedded(name)?;
        say!("{name:<width$}  {} ({}, {} phases, T in [{}, {}] s)", jump.summary, jump.robot, jump.phases.len(), jump.total_time.0, jump.total_time.1);
    }
    Ok(())
}

pub fn run(args: JumpArgs) -> Result<ExitCode> {
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
    let report = pipeline::run(&jump, &model, &settings, |stage, done| {
        if done {
            bar.println(format!("  done: {}", stage_name(stage)));
        } else {
            bar.set_message(stage_name(stage).to_string());
        }
    })?;
    bar.finish_and_clear();
    let written = write_outputs(&jump, &model, &settings, &report, &out)?;
    print_report(&jump, &report);
    say!("Wrote {} ({}) in {:.1} s", out.display(), written.join(", "), started.elapsed().as_secs_f64());
    let verdict = report.verdict();
    say!("{} (exit code {})", verdict.describe(), verdict.exit_code());
    Ok(ExitCode::from(verdict.exit_code()))
}

/// trajectory.json, replay.html and the plots; returns what was written.
fn write_outputs(jump: &Jump, model: &Model, settings: &ContactTimingSettings, report: &JumpReport, out: &Path) -> Result<Vec<String>> {
    std::fs::create_dir_all(out).with_context(|| format!("cannot create the output folder {}", out.display()))?;
    let params = SrbParams::from_model(model, "standing")?;
    let ct = &report.contact_timing;
    // Until the full-body plan exists, the trajectory is the contact-timing plan, and says so.
    let mut traj = srb_plan_trajectory(model, jump, &params, &ct.knots)?;
    traj.summary = report.summary(jump);
    traj.summary.insert("trajectory".into(), "the contact-timing plan: the single rigid body's base and ground forces, legs by inverse kinematics to its feet, no joint torques (tau = 0)".into());
    traj.save_file(out.join("trajectory.json"))?;
    legwork::viz::write_replay(model, &traj, out.join("replay.html"))?;
    let plots = out.join("plots");
    std::fs::create_dir_all(&plots).with_context(|| format!("cannot create {}", plots.display()))?;
    let viz = legwork::viz::jump::write_phase_timings;
    viz(&plots.join("phase_timings.svg"), &format!("{}: optimal phase durations", jump.name), &jump.phases, &ct.durations, jump.paper.as_ref().map(|p| p.timings_10ms.as_slice()))?;
    legwork::viz::jump::write_srb_forces(&plots.join("ground_forces.svg"), &ct.knots, settings.mu, (settings.f_min, settings.f_max))?;
    legwork::viz::jump::write_srb_pose(&plots.join("base_pose.svg"), &ct.knots)?;
    Ok(vec!["trajectory.json (contact-timing plan)".into(), "replay.html".into(), "plots: phase timings, ground forces against the cone, base pose; no torque plot without a full-body plan".into()])
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
    say!("  controllers: {}", report.controllers);
    for c in &report.stance_conflicts {
        say!("  warning: {c}: the target is not a landing on the ground");
    }
}
