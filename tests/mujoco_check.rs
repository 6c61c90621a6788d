//! legwork's robots in MuJoCo (issue 16, item 5): the exported MJCF loaded by MuJoCo 4.0.0
//! (the checker's Python, `scripts/install-mujoco.sh`) against legwork's own dynamics, HyQ
//! and A1 dropped and standing in MuJoCo, and every embedded task, shortened, checked end
//! to end.
//!
//! Without the checker's environment the tests fail when `CI` is set, and otherwise say
//! they skipped (the rule of tests/replay_browser.rs for Chromium).

use legwork::dynamics::{crba, forward_kinematics, frame_position, rnea, Data};
use legwork::export::{check_plan_in_mujoco, mjcf_model, stand_in_mujoco, MjcfSettings, StandingFigures};
use legwork::model::embedded;
use legwork::ocp::{solve_task, Rerun, SolveOptions, TaskSpec, EMBEDDED_TASKS};
use legwork::sim::{standing_on_ground, SimConfig, Simulator};
use legwork::terrain::{Plane, Terrain, TerrainSpec};
use nalgebra::DVector;
use std::path::{Path, PathBuf};

mod common;
#[path = "support/mujoco.rs"]
mod mujoco;
use mujoco::mujoco_or_skip;

/// A test's folder, removed when the test is done with it (kept if the test fails, to look at).
struct Scratch(PathBuf);

impl std::ops::Deref for Scratch {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        if !std::thread::panicking() {
            std::fs::remove_dir_all(&self.0).ok();
        }
    }
}

fn scratch(name: &str) -> Scratch {
    let dir = std::env::temp_dir().join(format!("legwork-mujoco-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    Scratch(dir)
}

/// A small deterministic generator of U(0, 1) samples.
fn uniform(seed: u64) -> impl FnMut() -> f64 {
    let mut s = seed;
    move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max)
}

/// MuJoCo's sizes, mass and body count are the model's; in the standing pose its foot
/// spheres are where legwork's forward kinematics puts them and its mass matrix is
/// legwork's; at random states in the air
/// its mass matrix (mj_fullM) and inverse dynamics (mj_inverse) agree with legwork's CRBA
/// and RNEA to 1e-8, once the free joint's conventions are converted.
#[test]
fn mjcf_in_mujoco_is_legworks_model() {
    let Some(check) = mujoco_or_skip() else { return };
    for name in ["hyq", "a1"] {
        let model = embedded::load(name).unwrap();
        let dir = scratch(&format!("inspect-{name}"));
        let mjcf = dir.join("model.xml");
        std::fs::write(&mjcf, mjcf_model(&model, &TerrainSpec::flat(), &MjcfSettings::default()).unwrap()).unwrap();
        let standing = model.reference_configuration("standing").unwrap().clone();
        let mut states = vec![(standing.clone(), DVector::zeros(model.nv), DVector::zeros(model.nv))];
        let mut u = uniform(0x5eed + name.len() as u64);
        for _ in 0..3 {
            let mut q = legwork::dynamics::random_configuration(&model, &mut u);
            q[2] += 5.0; // in the air: no contact, no constraint force in mj_inverse
            let v = DVector::from_fn(model.nv, |_, _| 4.0 * u() - 2.0);
            let a = DVector::from_fn(model.nv, |_, _| 20.0 * u() - 10.0);
            states.push((q, v, a));
        }
        let out = check.inspect(&dir, &model, &mjcf, &states, &[]).unwrap();
        assert_eq!(out["nq"], model.nq as u64, "{name}");
        assert_eq!(out["nv"], model.nv as u64, "{name}");
        assert_eq!(out["nu"], (model.nv - 6) as u64, "{name}");
        assert_eq!(out["nbody"], model.njoints() as u64, "{name}: the world and one body per joint");
        let mass = out["total_mass"].as_f64().unwrap();
        assert!((mass - model.total_mass()).abs() < 1e-12 * mass, "{name}: MuJoCo {mass} kg, legwork {} kg", model.total_mass());
        let mut data = Data::new(&model);
        for (k, (q, v, a)) in states.iter().enumerate() {
            let s = &out["states"][k];
            forward_kinematics(&model, &mut data, q);
            for (i, foot) in model.feet.iter().enumerate() {
                let p = frame_position(&model, &data, foot.frame);
                let mj: Vec<f64> = s["feet"][i].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
                assert!(max_abs_diff(p.as_slice(), &mj) < 1e-12, "{name} state {k} foot {}: legwork {p:?}, MuJoCo {mj:?}", foot.name);
            }
            let m = crba(&model, &mut data, q).clone();
            let m = DVector::from_iterator(model.nv * model.nv, (0..model.nv).flat_map(|r| (0..model.nv).map(move |c| (r, c))).map(|(r, c)| m[(r.min(c), r.max(c))]));
            let mj_m: Vec<f64> = s["mass_matrix"].as_array().unwrap().iter().flat_map(|row| row.as_array().unwrap().iter().map(|x| x.as_f64().unwrap())).collect();
            let dm = max_abs_diff(m.as_slice(), &mj_m);
            let tau = rnea(&model, &mut data, q, v, a).clone();
            let mj_tau: Vec<f64> = s["inverse_dynamics"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
            let dt = max_abs_diff(tau.as_slice(), &mj_tau);
            let contact = if k == 0 { " (standing on the ground: MuJoCo's contact forces included)" } else { "" };
            println!("{name} state {k}: |M_legwork - M_mujoco|_max = {dm:.2e}, |rnea - mj_inverse|_max = {dt:.2e}{contact} (|tau|_max {:.1})", tau.amax());
            assert!(dm < 1e-8, "{name} state {k}: mass matrices differ by {dm:e}");
            if k == 0 {
                // Standing on the ground: MuJoCo's contacts add constraint forces.
                continue;
            }
            assert_eq!(s["ncon"], 0, "{name} state {k}: in the air");
            assert!(dt < 1e-8 * tau.amax().max(1.0), "{name} state {k}: inverse dynamics differ by {dt:e}");
        }
    }
}

/// The checker's controllers are legwork's: on a trot of HyQ (some feet in swing, the
/// reference between knots), at perturbed states, MuJoCo's `track` gives the torques of
/// legwork's [`TrackingController`] with its default gains (feet and Jacobians from
/// MuJoCo, the reference interpolated on SE(3) in Python), and `policy` gives
/// `tau_ff + K [q (-) q*; v - v*]` computed with legwork's own `difference`, to 1e-9 (the
/// tracking controller to 1e-7: see below).
#[test]
fn the_checkers_controllers_are_legworks() {
    let Some(check) = mujoco_or_skip() else { return };
    let (model, mut reference) = common::hyq_trot(1.5);
    let mut u = uniform(11);
    for knot in &mut reference.knots {
        knot.feedback_gain = Some((0..model.nv - 6).map(|_| (0..2 * model.nv).map(|_| 200.0 * u() - 100.0).collect()).collect());
    }
    let dir = scratch("controllers");
    let mjcf = dir.join("model.xml");
    std::fs::write(&mjcf, mjcf_model(&model, &TerrainSpec::flat(), &MjcfSettings::default()).unwrap()).unwrap();
    let reference_path = dir.join("reference.json");
    reference.save_file(&reference_path).unwrap();
    // States near the reference (perturbed from the knot at or after t).
    let perturbed = |t: f64, u: &mut dyn FnMut() -> f64| {
        let k = reference.knots.iter().position(|k| k.t >= t).unwrap();
        let mut q = DVector::from_column_slice(&reference.knots[k].q);
        let dq = DVector::from_fn(model.nv, |_, _| 0.04 * u() - 0.02);
        let q_ref = q.clone();
        legwork::dynamics::integrate(&model, &q_ref, &dq, &mut q);
        let v = DVector::from_column_slice(&reference.knots[k].v) + DVector::from_fn(model.nv, |_, _| 0.4 * u() - 0.2);
        (q, v)
    };
    let track_states: Vec<(f64, DVector<f64>, DVector<f64>)> = [0.3, 0.7013, 0.8871, 1.0005].iter().map(|&t| {
        let (q, v) = perturbed(t, &mut u);
        (t, q, v)
    }).collect();
    let settings = legwork::export::ControllerSettings::tracking(&model, &reference, 0.001).unwrap();
    let theirs = check.torques(&dir, &mjcf, &reference_path, legwork::export::CheckController::Track, &settings, &track_states).unwrap();
    let mut ours = legwork::control::TrackingController::with_default_gains(&model, &reference, 0.001).unwrap();
    for ((t, q, v), theirs) in track_states.iter().zip(&theirs) {
        let mut tau = DVector::zeros(model.nv);
        let state = legwork::sim::SimState { t: *t, q: q.clone(), v: v.clone(), anchors: vec![None; model.feet.len()] };
        legwork::sim::Controller::compute(&mut ours, &model, &state, &mut tau).unwrap();
        let d = max_abs_diff(&tau.as_slice()[6..], theirs);
        println!("track at t = {t}: |tau_legwork - tau_checker|_max = {d:.2e} (|tau|_max {:.1})", tau.amax());
        // With two stance feet G G^T is singular but for its eps = 1e-8 of the trace
        // (condition about 1e8): the two solves' round-off differs by some 1e-8 relative.
        assert!(d < 1e-7 * tau.amax().max(1.0), "track at t = {t}: legwork {:?}, checker {theirs:?}", &tau.as_slice()[6..]);
    }
    // The policy at knots and between them (the feedforward and gain held over the interval,
    // the reference state interpolated), against legwork's own `FeedbackPolicy`.
    let dt = reference.metadata.dt;
    let policy_states: Vec<(f64, DVector<f64>, DVector<f64>)> = [(20usize, 0.0), (351, 0.37), (444, 0.0), (600, 0.81)].iter().map(|&(k, s)| {
        let t = reference.knots[k].t + s * dt;
        let (q, v) = perturbed(reference.knots[k].t, &mut u);
        (t, q, v)
    }).collect();
    let theirs = check.torques(&dir, &mjcf, &reference_path, legwork::export::CheckController::Policy, &legwork::export::ControllerSettings::Policy {}, &policy_states).unwrap();
    let mut ours = legwork::control::FeedbackPolicy::new(&model, &reference).unwrap();
    for ((t, q, v), theirs) in policy_states.iter().zip(&theirs) {
        let mut tau = DVector::zeros(model.nv);
        let state = legwork::sim::SimState { t: *t, q: q.clone(), v: v.clone(), anchors: vec![None; model.feet.len()] };
        legwork::sim::Controller::compute(&mut ours, &model, &state, &mut tau).unwrap();
        let tau = &tau.as_slice()[6..];
        let d = max_abs_diff(tau, theirs);
        println!("policy at t = {t}: |tau_legwork - tau_checker|_max = {d:.2e}");
        assert!(d < 1e-9 * tau.iter().fold(1.0f64, |a, x| a.max(x.abs())), "policy at t = {t}: legwork {tau:?}, checker {theirs:?}");
    }
}

/// A walk scenario's world (stepping stones over a pit, between two pallets) as MuJoCo's
/// hfield: under random points whose grid cell is flat (where legwork's bilinear
/// interpolation and MuJoCo's two triangles per cell agree), MuJoCo's ray cast finds
/// legwork's height (to MuJoCo's single-precision height data). The stones are off the centre line in y, so a field flipped in y fails.
#[test]
fn a_scenario_height_map_in_mujoco_is_legworks() {
    let Some(check) = mujoco_or_skip() else { return };
    let model = embedded::load("hyq").unwrap();
    let scenario = legwork::walk::ScenarioSpec::embedded("stepping_stones").unwrap();
    let map = scenario.world_at(0.0);
    let dir = scratch("hfield");
    let mjcf = dir.join("model.xml");
    std::fs::write(&mjcf, mjcf_model(&model, &map.spec(), &MjcfSettings::default()).unwrap()).unwrap();
    let (origin, r, (columns, rows)) = (map.origin(), map.resolution(), map.size());
    let mut u = uniform(7);
    let mut points = Vec::new();
    let mut levels = std::collections::BTreeSet::new();
    while points.len() < 200 {
        let (i, j) = (((columns - 1) as f64 * u()) as usize, ((rows - 1) as f64 * u()) as usize);
        let h = map.at(i, j);
        if [map.at(i + 1, j), map.at(i, j + 1), map.at(i + 1, j + 1)].iter().all(|&x| x == h) {
            points.push([origin[0] + (i as f64 + u()) * r, origin[1] + (j as f64 + u()) * r]);
            levels.insert((h * 1e3).round() as i64);
        }
    }
    assert!(levels.len() >= 3, "the sample covers the ground, the pit and the stones or pallets: {levels:?}");
    let out = check.inspect(&dir, &model, &mjcf, &[], &points).unwrap();
    for (p, h) in points.iter().zip(out["ground_heights"].as_array().unwrap()) {
        let ours = map.height(p[0], p[1]);
        let theirs = h.as_f64().unwrap_or_else(|| panic!("no ground under {p:?} in MuJoCo"));
        // MuJoCo keeps hfield data in single precision: 0.65 m of span to 6e-8 relative.
        assert!((ours - theirs).abs() < 1e-6, "at {p:?}: legwork {ours} m, MuJoCo {theirs} m");
    }
}

/// HyQ and A1 dropped from 0.1 m onto flat ground under the standing joint PD, in MuJoCo
/// (default contact) and in legwork's simulator: static penetration per foot, rest base
/// height, sinking and bounce after touch-down (printed: the calibration data of
/// docs/experiments/mujoco-check.md). Asserted: finite, and the robot stands (every foot
/// down at the end, the base within 3 cm of legwork's standing height, the feet less than
/// 1 cm deep).
#[test]
fn robots_stand_in_mujoco_after_a_drop() {
    let Some(check) = mujoco_or_skip() else { return };
    for name in ["hyq", "a1"] {
        let model = embedded::load(name).unwrap();
        let ground = Plane::flat(0.0);
        let standing_height = standing_on_ground(&model, &ground, 0.0).unwrap()[2];
        let (mujoco, failed) = stand_in_mujoco(&check, &model, 0.1, 2.0, &scratch(&format!("stand-{name}"))).unwrap();
        assert_eq!(failed, None, "{name}");
        let figures = StandingFigures::of(&model, &ground, &mujoco, 0.5);
        // legwork's own: `legwork simulate --controller stand --drop-height 0.1`.
        let config = SimConfig::default();
        let pd = legwork::control::JointPd::standing(&model, config.control_dt).unwrap();
        let q0 = standing_on_ground(&model, &ground, 0.1).unwrap();
        let mut sim = Simulator::new(&model, &ground, config, q0, None).unwrap();
        let ours = sim.run(2.0, &mut pd.clone(), |_| {}).unwrap().trajectory;
        let legwork = StandingFigures::of(&model, &ground, &ours, 0.5);
        for (sim, f) in [("MuJoCo 4.0.0", &figures), ("legwork", &legwork)] {
            println!(
                "{name} {sim:<12}: penetration {} mm, rest height {:.4} m (standing pose {:.4}), undershoot {:.1} mm, bounce {:.1} mm, lift-offs after touch-down {}, settled at {:.3} s, touch-down at {:.3} s",
                f.penetration.iter().map(|p| format!("{:.2}", p * 1e3)).collect::<Vec<_>>().join("/"),
                f.rest_height,
                standing_height,
                f.undershoot * 1e3,
                f.overshoot * 1e3,
                f.liftoffs_after_touchdown,
                f.settle_time,
                f.touchdown_time.unwrap_or(f64::NAN)
            );
        }
        let last = mujoco.knots.last().unwrap();
        assert!(last.in_contact.iter().all(|&c| c), "{name}: every foot down at the end in MuJoCo: {:?}", last.in_contact);
        assert!(figures.penetration.iter().all(|p| p.is_finite() && p.abs() < 0.01), "{name}: {:?}", figures.penetration);
        assert!(figures.rest_height.is_finite() && (figures.rest_height - standing_height).abs() < 0.03, "{name}: rest {} against standing {standing_height}", figures.rest_height);
        let weight = model.total_mass() * 9.81;
        let fz: f64 = last.contact_force.iter().map(|f| f[2]).sum();
        assert!((fz - weight).abs() < 0.05 * weight, "{name}: MuJoCo's feet carry {fz} N of the {weight} N weight");
    }
}

/// Every embedded task in a shortened form (0.3 s, 2 SLQ iterations, no continuation, no exploration,
/// the waypoints within the horizon) solved, then checked in MuJoCo with both controllers:
/// both runs come back as trajectories of the whole horizon with finite figures (not that
/// they meet the tasks' targets: the full tasks are `legwork bench slq --check mujoco`).
#[test]
fn every_embedded_task_shortened_checked_in_mujoco() {
    let Some(check) = mujoco_or_skip() else { return };
    let ground = Plane::flat(0.0);
    for (name, _) in EMBEDDED_TASKS {
        let mut spec = TaskSpec::embedded(name).unwrap();
        spec.duration = 0.3;
        spec.iterations = Some(2);
        spec.continuation = None;
        spec.exploration = None;
        spec.waypoints.retain(|w| w.time <= spec.duration);
        let model = embedded::load(&spec.robot).unwrap();
        let run = solve_task(&spec, &model, &ground, name, &SolveOptions::default(), |_| {}).unwrap();
        let reruns = check_plan_in_mujoco(&check, &model, &run.plan, &TerrainSpec::flat(), &scratch(&format!("task-{name}"))).unwrap();
        assert_eq!(reruns.version, "4.0.0");
        for (what, rerun) in [("track", &reruns.tracking), ("policy", &reruns.policy)] {
            let (traj, metrics) = match rerun {
                Rerun::Completed { trajectory, metrics } => (trajectory, metrics),
                Rerun::Failed { reason } => panic!("{name}: MuJoCo {what} failed: {reason}"),
            };
            assert!((traj.duration() - run.plan.duration()).abs() < 1e-9, "{name} {what}: {} s of {} s", traj.duration(), run.plan.duration());
            assert_eq!(traj.knots.len(), (run.plan.duration() / 0.001).round() as usize + 1, "{name} {what}: a knot per millisecond");
            let figures = [metrics.apex_base_height, metrics.flight_time, metrics.all_feet_down, metrics.final_base_position[0], metrics.final_base_position[2], metrics.final_base_rpy_deg[1]];
            assert!(figures.iter().all(|x| x.is_finite()), "{name} {what}: {metrics:?}");
            let weight = model.total_mass() * 9.81;
            let fz: f64 = traj.knots[0].contact_force.iter().map(|f| f[2]).sum();
            assert!(fz > 0.5 * weight && fz < 2.0 * weight, "{name} {what}: the feet carry {fz} N at the start (weight {weight} N)");
            println!("{name:<16} MuJoCo {what:<6}: apex {:.4} m, final base ({:.3}, {:.3}, {:.3}) m, flight {:.3} s, all feet down {:.0} %", metrics.apex_base_height, metrics.final_base_position[0], metrics.final_base_position[1], metrics.final_base_position[2], metrics.flight_time, 100.0 * metrics.all_feet_down);
        }
    }
}
