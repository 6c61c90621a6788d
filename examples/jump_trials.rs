//! Runs a jump reference on the A1 in legwork's simulator under Nguyen 2022's jump and
//! landing controllers: once nominal, then the 20 landing trials of issue 17 (+-5 % link
//! mass and inertia, +-2 cm initial base offset), and prints what they measured.
//!
//! ```text
//! cargo run --release --example jump_trials -- REFERENCE.json [TRIALS]
//! cargo run --release --example jump_trials -- drop:HEIGHT:VY [TRIALS]
//! cargo run --release --example jump_trials -- guess:JUMP [TRIALS]
//! cargo run --release --example jump_trials -- solved:JUMP [TRIALS]
//! cargo run --release --example jump_trials -- REFERENCE.json [TRIALS] --jump NAME
//! ```
//!
//! `--jump NAME` runs on the embedded jump's terrain (its box); flat ground otherwise.
//! `JUMP_RUN_OUT=run.json` writes the nominal run's recorded knots.
//! `--normal-force-max N`, `--stance-kp`, `--stance-kd`, `--position-kp`, `--position-kd`,
//! `--extension-time S`, `--orientation-kp`, `--orientation-kd`, `--moment-weight` set the landing controller's settings of those names.
//! `--lift-off-lead S` sets `JumpSettings::lift_off_lead` to the constant lead `S` (s).
//!
//! `REFERENCE.json` is a trajectory file (`io::Trajectory`, 10 ms knots) of the full-body
//! optimization; `drop:0.15:0.6` is the built-in ballistic reference
//! ([`legwork::jump::control::check_references::drop_reference`]); `guess:lateral30` the
//! full-body optimizer's initial guess of a jump (`fullbody::initial_guess`), `solved:lateral30`
//! its full-body plan (`fullbody::FullBodyProblem::solve`).

use anyhow::{bail, Context};
use legwork::io::Trajectory;
use legwork::jump::control::{check_references, run_jump, JumpRun, JumpSettings};
use legwork::jump::trials::{run_trials, TrialSettings};
use legwork::model::embedded;
use legwork::terrain::Plane;

mod common;

fn row(name: &str, run: &JumpRun, success: Option<bool>) {
    let t = |x: Option<f64>| x.map_or("-".to_string(), |t| format!("{t:.3}"));
    println!(
        "{name:>8} lift-off {:>6} touch-down {:>6} switch {:>6} | pos err {:>6.1} mm yaw err {:>5.2} deg roll {:>5.2} pitch {:>5.2} deg | max tau {:>5.1} N m sat {:>4} | qp {} fail {} it<={} {}{}",
        t(run.lift_off),
        t(run.touch_down),
        t(run.switch),
        1e3 * run.position_error,
        run.yaw_error.to_degrees(),
        run.roll.to_degrees(),
        run.pitch.to_degrees(),
        run.max_torque,
        run.saturated_controls,
        run.controller.qp_solves,
        run.controller.qp_failures,
        run.controller.max_qp_iterations,
        if run.fell { "FELL " } else { "" },
        success.map_or(String::new(), |s| if s { "ok".into() } else { "FAIL".into() })
    );
    if let Some(f) = &run.failure {
        println!("         {f}");
    }
}

/// The full-body optimizer's initial guess of jump `name` (contact timing solved, legs by
/// IK, torques `-J^T f`), or with `solve` the full-body optimization's plan from it.
fn initial_guess_reference(model: &legwork::model::Model, name: &str, solve: bool) -> anyhow::Result<Trajectory> {
    use legwork::fullbody::{FullBodyProblem, FullBodySettings};
    use legwork::srb::{jumps, ContactTimingProblem, ContactTimingSettings, SrbParams, SrbTrajectory};
    let params = SrbParams::a1()?;
    let jump = jumps().into_iter().find(|j| j.name == name).with_context(|| format!("no jump named '{name}'"))?;
    let problem = ContactTimingProblem::new(&jump, &params, &ContactTimingSettings::default())?;
    let mut solver = problem.solver(legwork::ipocp::Settings::default())?;
    let result = problem.solve(&mut solver)?;
    let settings = FullBodySettings::default();
    let srb = SrbTrajectory::from_solution(&problem, &result.last.primal)?.resample(settings.dt)?;
    let guess = legwork::fullbody::initial_guess(model, &srb, settings.pre_landing_knots)?;
    if !solve {
        return Ok(guess);
    }
    if jump.box_height > 0.0 {
        bail!("jump '{name}' starts from a box: the trials run on flat ground only for now");
    }
    let plan = FullBodyProblem::new(model, &srb, &guess, &settings, None)?.solve()?;
    println!("full-body plan of {name}: {:?} after {} iterations, limits {}", plan.report.status, plan.report.iterations, if plan.limits.all_met(1e-6) { "met" } else { "VIOLATED" });
    Ok(plan.trajectory)
}

fn main() -> anyhow::Result<()> {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let terrain = common::jump_terrain(&mut args)?;
    let lift_off_lead: Option<f64> = common::take(&mut args, "--lift-off-lead")?.map(|s| s.parse()).transpose().context("--lift-off-lead: a time (s)")?;
    let mut number = |flag: &str| -> anyhow::Result<Option<f64>> { common::take(&mut args, flag)?.map(|s| s.parse::<f64>()).transpose().with_context(|| format!("{flag}: a number")) };
    let normal_force_max = number("--normal-force-max")?;
    let stance_kp = number("--stance-kp")?;
    let stance_kd = number("--stance-kd")?;
    let position_kd = number("--position-kd")?;
    let position_kp = number("--position-kp")?;
    let extension_time = number("--extension-time")?;
    let orientation_kp = number("--orientation-kp")?;
    let orientation_kd = number("--orientation-kd")?;
    let moment_weight = number("--moment-weight")?;
    let Some(source) = args.first() else { bail!("usage: jump_trials REFERENCE.json|drop:HEIGHT:VY [TRIALS]") };
    let trials: usize = args.get(1).map(|s| s.parse()).transpose().context("TRIALS must be a whole number")?.unwrap_or(20);
    let model = embedded::load("a1")?;
    let ground = Plane::flat(0.0);
    let reference = if let Some(spec) = source.strip_prefix("drop:") {
        let parts: Vec<f64> = spec.split(':').map(|s| s.parse::<f64>()).collect::<Result<_, _>>().context("drop:HEIGHT:VY takes two numbers")?;
        if parts.len() != 2 {
            bail!("drop:HEIGHT:VY takes two numbers, got '{spec}'");
        }
        check_references::drop_reference(&model, &ground, parts[0], parts[1])?
    } else if let Some(name) = source.strip_prefix("guess:") {
        initial_guess_reference(&model, name, false)?
    } else if let Some(name) = source.strip_prefix("solved:") {
        initial_guess_reference(&model, name, true)?
    } else {
        Trajectory::load_file(source)?
    };
    let defaults = JumpSettings::default();
    let mut settings = JumpSettings { lift_off_lead: lift_off_lead.or(defaults.lift_off_lead), ..defaults };
    // Landing settings under test (docs/experiments/jump-flip-4.md); absent: the defaults.
    let landing = &mut settings.landing;
    landing.qp.normal_force_max = normal_force_max.unwrap_or(landing.qp.normal_force_max);
    landing.stance_joint_kp = stance_kp.unwrap_or(landing.stance_joint_kp);
    landing.stance_joint_kd = stance_kd.unwrap_or(landing.stance_joint_kd);
    landing.qp.position_kd = position_kd.map_or(landing.qp.position_kd, nalgebra::Vector3::repeat);
    landing.qp.position_kp = position_kp.map_or(landing.qp.position_kp, nalgebra::Vector3::repeat);
    landing.qp.orientation_kp = orientation_kp.map_or(landing.qp.orientation_kp, nalgebra::Vector3::repeat);
    landing.qp.orientation_kd = orientation_kd.map_or(landing.qp.orientation_kd, nalgebra::Vector3::repeat);
    if let Some(w) = moment_weight {
        landing.qp.wrench_weight.fixed_rows_mut::<3>(3).fill(w);
    }
    settings.extension.time = extension_time.unwrap_or(settings.extension.time);
    if let Ok(path) = std::env::var("JUMP_REFERENCE_OUT") {
        reference.save_file(&path)?;
    }
    let start = std::time::Instant::now();
    let nominal = run_jump(&model, terrain.as_ref(), &reference, &settings)?;
    println!("reference {source}: {} knots, {:.2} s; target ({:.3}, {:.3}) m, yaw {:.1} deg", reference.knots.len(), reference.duration(), nominal.target.position.x, nominal.target.position.y, nominal.target.yaw.to_degrees());
    row("nominal", &nominal, None);
    if let Ok(path) = std::env::var("JUMP_RUN_OUT") {
        nominal.trajectory.save_file(&path)?;
    }
    println!("(nominal run: {:.2} s wall)", start.elapsed().as_secs_f64());
    let trial_settings = TrialSettings { trials, ..TrialSettings::default() };
    let start = std::time::Instant::now();
    let report = run_trials(&model, terrain.as_ref(), &reference, &settings, &trial_settings)?;
    for o in &report.outcomes {
        row(&format!("seed {}", o.seed), &o.run, Some(o.success));
        println!("         mass x{:.4}, base offset ({:+.1}, {:+.1}) mm", o.mass_ratio, 1e3 * o.base_offset.x, 1e3 * o.base_offset.y);
    }
    let errors: Vec<f64> = report.outcomes.iter().map(|o| o.run.position_error).collect();
    let yaw: Vec<f64> = report.outcomes.iter().map(|o| o.run.yaw_error.abs()).collect();
    let max = |v: &[f64]| v.iter().copied().fold(0.0, f64::max);
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    println!(
        "success {}/{} ({:.0} %); position error mean {:.1} mm, max {:.1} mm; |yaw error| mean {:.2} deg, max {:.2} deg; {:.1} s wall",
        report.successes(),
        report.outcomes.len(),
        100.0 * report.success_rate(),
        1e3 * mean(&errors),
        1e3 * max(&errors),
        mean(&yaw).to_degrees(),
        max(&yaw).to_degrees(),
        start.elapsed().as_secs_f64()
    );
    Ok(())
}
