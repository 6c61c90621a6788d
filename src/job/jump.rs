//! The jump job (`legwork jump`, Python's `legwork.jump`): Nguyen 2022's 3D jump as far as
//! the pipeline goes (contact timing, full body, jump and landing controllers, trials), and
//! its folder: `contact_timing.json`, `trajectory.json` (the full-body plan), `rerun.json`,
//! `replay.html` and the plots.

use super::{JobError, OrCouldNotFinish};
use crate::jump::{pipeline, srb_plan_trajectory, Jump, JumpReport, PipelineOptions, Stage};
use crate::model::Model;
use crate::srb::{ContactTimingSettings, SrbParams};
use std::path::Path;

/// The jump's contact-timing settings with `knots` knots per phase (the file's otherwise).
pub fn settings_of(jump: &Jump, knots: Option<usize>, knots_setting: &str) -> Result<ContactTimingSettings, JobError> {
    let settings = ContactTimingSettings { knots_per_phase: knots.unwrap_or(jump.contact_timing.knots_per_phase), ..jump.contact_timing.clone() };
    settings.validate().map_err(|e| JobError::bad_input(format!("{knots_setting}: {e}")))?;
    Ok(settings)
}

/// Runs `work` on a pool of `threads` threads (0: one per core) with the full body's stage
/// evaluations parallel when there is more than one.
pub fn with_threads<T: Send>(threads: usize, options: &mut PipelineOptions, work: impl FnOnce(&PipelineOptions) -> Result<T, JobError> + Send) -> Result<T, JobError> {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().map_err(|e| JobError::could_not_finish(format!("cannot start the thread pool: {e}")))?;
    options.full_body.solver.parallel = pool.current_num_threads() > 1;
    let options = &*options;
    pool.install(|| work(options))
}

/// What each stage of the pipeline is, for progress messages.
pub fn stage_name(stage: Stage) -> &'static str {
    match stage {
        Stage::ContactTiming => "contact timing (single rigid body, sec. II-B)",
        Stage::FullBody => "full-body trajectory optimization (sec. II-C)",
        Stage::Controllers => "jump and landing controllers in legwork's simulator (sec. III)",
        Stage::Trials => "robustness trials (mass, inertia, base offset)",
    }
}

/// Runs the pipeline on `threads` threads (`on_stage` sees each stage start and end) and,
/// with `out`, writes the folder (`png`: the plots as PNG too); returns the report and the
/// files written.
pub fn jump(jump: &Jump, model: &Model, options: &mut PipelineOptions, threads: usize, out: Option<&Path>, png: bool, on_stage: impl FnMut(Stage, bool) + Send) -> Result<(JumpReport, Vec<String>), JobError> {
    let report = with_threads(threads, options, |options| pipeline::run(jump, model, options, on_stage).or_could_not_finish())?;
    let written = match out {
        Some(out) => {
            let mut written = write_outputs(jump, model, options, &report, out).or_could_not_finish()?;
            if png {
                let plots = out.join("plots");
                let svgs: Vec<_> = [plots.clone(), plots.join("plan"), plots.join("rerun")].iter().flat_map(|d| crate::viz::png::svgs_in(d)).collect();
                written.push(format!("{} PNGs", crate::viz::png::write_pngs(&svgs, crate::viz::png::PNG_SCALE).or_could_not_finish()?.len()));
            }
            written
        }
        None => Vec::new(),
    };
    Ok((report, written))
}

/// trajectory.json (the full-body plan), rerun.json (the controllers' run),
/// contact_timing.json (the single-rigid-body plan), replay.html (the re-run, or the best
/// plan there is) and the plots; returns what was written.
fn write_outputs(jump: &Jump, model: &Model, options: &PipelineOptions, report: &JumpReport, out: &Path) -> Result<Vec<String>, Box<dyn std::error::Error + Send + Sync>> {
    use crate::viz::jump as plots;
    std::fs::create_dir_all(out).map_err(|e| format!("cannot create the output folder {}: {e}", out.display()))?;
    let dir = out.join("plots");
    std::fs::create_dir_all(&dir).map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
    let summary = report.summary(jump);
    let terrain = crate::terrain::Terrain::spec(&jump.terrain());
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
        crate::viz::write_plots(&traj, dir.join("plan"))?;
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
        crate::viz::write_plots(&traj, dir.join("rerun"))?;
        written.push("rerun.json, plots/rerun_{ground_forces,torques}.svg, plots/rerun/".into());
        replay = traj;
    }
    crate::viz::write_replay(model, &replay, out.join("replay.html"))?;
    written.push(format!("replay.html ({})", replay.metadata.scenario));
    Ok(written)
}
