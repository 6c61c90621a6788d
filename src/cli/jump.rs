//! `legwork jump <name|file.toml>` and `legwork jumps`: Nguyen 2022's 3D jumps, planned and
//! run as far as this build's pipeline goes ([`legwork::jump::pipeline`]).

use anyhow::Result;
use clap::Args;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use legwork::job::jump::stage_name;
use legwork::jump::{Jump, JumpReport, PipelineOptions, EMBEDDED_JUMPS};
use legwork::srb::ContactTimingSettings;
use std::path::PathBuf;
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
    /// Also write every plot as PNG (2x, text in the embedded DejaVu Sans) beside its SVG.
    #[arg(long)]
    png: bool,
}

/// The jump's settings with the command line's `--knots`.
pub(super) fn settings_of(jump: &Jump, knots: Option<usize>) -> Result<ContactTimingSettings> {
    legwork::job::jump::settings_of(jump, knots, "--knots").map_err(super::solve::job_error)
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
    let result = legwork::job::jump::jump(&jump, &model, &mut options, super::capped_threads(args.threads), Some(&out), args.png, |stage, done| {
        if done {
            bar.println(format!("  done: {}", stage_name(stage)));
        } else {
            bar.set_message(stage_name(stage).to_string());
        }
    });
    bar.finish_and_clear();
    let (report, written) = result.map_err(super::solve::job_error)?;
    print_report(&jump, &report);
    say!("Wrote {} ({}) in {:.1} s", out.display(), written.join(", "), started.elapsed().as_secs_f64());
    let verdict = report.verdict();
    say!("{} (exit code {})", verdict.describe(), verdict.exit_code());
    Ok(ExitCode::from(verdict.exit_code()))
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
