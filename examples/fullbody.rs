//! Nguyen 2022's full-body trajectory optimization (sec. II-C) of the jumps, end to end:
//! contact timing on the single rigid body, its solution resampled at 10 ms, the initial
//! guess, the full-body solve with ipocp, every limit checked at every knot.
//!
//! ```text
//! cargo run --release --example fullbody -- [--repeats 3] [--no-box] [--overhang 0.01]
//!     [--pre-landing 10] [--sequential] [--max-iterations 300] [--verbose] [--limits]
//!     [--no-restoration] [--plain-guess] [--reference-targets] [--w-acceleration W]
//!     [--max-acceleration A] [--w-velocity W] [--max-stance-speed V] [--out DIR]
//!     [--barrier RULE] [--ct-barrier RULE] [--curvature-after N] [--curvature-violation V]
//!     [--curvature-by-jacobians] [--curvature-stall W] [--curvature-refresh R] [--id-torques] [--rnea-tr-mul on|off] [--foot-margin M] [--lift-off-force F]
//!     [--ballistic off|angular|full] [--w-flight-momentum W] [--stance-balance] [--start-defect]
//!     [jump ... | file.toml ...]
//! ```
//!
//! The pipeline's settings (`legwork jump`, `legwork bench jumps`) are `--curvature-after 60
//! --curvature-stall 5 --curvature-refresh 2 --foot-margin 0.01` plus the jump file's
//! `--lift-off-force` (lateral_down: 20); without them the example solves Gauss-Newton
//! throughout; `--curvature-refresh R`: the curvature formed every R iterations, reused in
//! between (default 1). `--curvature-violation V`: hand over to
//! the curvature phase at violation V (default 1); `--curvature-stall W`: also before N
//! iterations once the violation is at most V and has not reached a new low for W iterations;
//! `--curvature-by-jacobians`: that
//! curvature by central differences of the full Jacobians (the reference) instead of
//! forward differences of the multiplier-weighted gradient; `--id-torques`: the start's
//! torques by inverse dynamics of the guess; `--rnea-tr-mul on|off`: the curvature's
//! `w^T d RNEA / d(q, v)` by the weighted backward sweep (on) or the two derivative matrices
//! (off); `--start-defect`: no solve, the start's
//! constraint violation per knot instead (dynamics defect in the base and joint rows of `dq`
//! and `v`, equalities, inequalities against their bounds).
//!
//! `--w-acceleration`, `--max-acceleration`, `--w-velocity` override the settings' joint
//! acceleration weight and bound and velocity weight; `--out DIR` writes each plan to
//! `DIR/<jump>.json` (for `jump_trials` and `jump_momentum`).
//!
//! The box of a jump from a platform is the jump file's (as `legwork jump` has it), or with
//! `--overhang` the start feet's footprint grown by that much in x and y; its top under the
//! feet's spheres. `--no-restoration` turns ipocp's feasibility restoration off,
//! `--plain-guess` the box-aware initial guess, `--reference-targets` solves the reference
//! script's landing targets instead of the files'.

use legwork::fullbody::{initial_guess_clear_of, BoxObstacle, FullBodyProblem, FullBodySettings};
use legwork::ipocp::Settings;
use legwork::jump::{box_obstacle, embedded_jumps, Jump};
use legwork::model::embedded;
use legwork::srb::{ContactTimingProblem, ContactTimingSettings, JumpSpec, SrbParams, SrbTrajectory};

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let mut repeats = 3;
    let mut with_box = true;
    let mut verbose = false;
    let mut show_limits = false;
    let mut overhang = None;
    let mut restoration = true;
    let mut plain_guess = false;
    let mut reference_targets = false;
    let mut pre_landing = None;
    let mut parallel = true;
    let mut max_iterations = None;
    let mut box_rows = false;
    let mut curvature = None;
    let mut curvature_violation = None;
    let mut curvature_by_jacobians = false;
    let mut id_torques = false;
    let mut rnea_tr_mul = None;
    let mut curvature_stall = None;
    let mut curvature_refresh = 1;
    let mut start_defect = false;
    let mut foot_margin = 0.0;
    let mut lift_off_force = f64::INFINITY;
    let mut names = Vec::new();
    let mut w_acceleration = None;
    let mut max_acceleration = None;
    let mut w_velocity = None;
    let mut out_dir: Option<String> = None;
    let mut max_stance_speed = None;
    let mut barrier_update = None;
    let mut ct_barrier_update = None;
    let mut ballistic_flight = None;
    let mut w_flight_momentum = None;
    let mut stance_balance = false;
    while let Some(a) = args.next() {
        match a.as_str() {
            "--repeats" => repeats = args.next().ok_or_else(|| anyhow::anyhow!("--repeats: a number"))?.parse()?,
            "--overhang" => overhang = Some(args.next().ok_or_else(|| anyhow::anyhow!("--overhang: metres"))?.parse::<f64>()?),
            "--no-restoration" => restoration = false,
            "--plain-guess" => plain_guess = true,
            "--reference-targets" => reference_targets = true,
            "--no-box" => with_box = false,
            "--pre-landing" => pre_landing = Some(args.next().ok_or_else(|| anyhow::anyhow!("--pre-landing: knots"))?.parse()?),
            "--verbose" => verbose = true,
            "--sequential" => parallel = false,
            "--max-iterations" => max_iterations = Some(args.next().ok_or_else(|| anyhow::anyhow!("--max-iterations: a number"))?.parse()?),
            "--limits" => show_limits = true,
            "--w-acceleration" => w_acceleration = Some(args.next().ok_or_else(|| anyhow::anyhow!("--w-acceleration: a weight"))?.parse::<f64>()?),
            "--max-acceleration" => max_acceleration = Some(args.next().ok_or_else(|| anyhow::anyhow!("--max-acceleration: rad/s^2"))?.parse::<f64>()?),
            "--w-velocity" => w_velocity = Some(args.next().ok_or_else(|| anyhow::anyhow!("--w-velocity: a weight"))?.parse::<f64>()?),
            "--max-stance-speed" => max_stance_speed = Some(args.next().ok_or_else(|| anyhow::anyhow!("--max-stance-speed: m/s"))?.parse::<f64>()?),
            "--out" => out_dir = Some(args.next().ok_or_else(|| anyhow::anyhow!("--out: a directory"))?),
            "--box-rows" => box_rows = true,
            "--stance-balance" => stance_balance = true,
            "--ballistic" => ballistic_flight = Some(args.next().ok_or_else(|| anyhow::anyhow!("--ballistic: off, angular or full"))?.parse().map_err(anyhow::Error::msg)?),
            "--w-flight-momentum" => w_flight_momentum = Some(args.next().ok_or_else(|| anyhow::anyhow!("--w-flight-momentum: a weight"))?.parse::<f64>()?),
            "--lift-off-force" => lift_off_force = args.next().ok_or_else(|| anyhow::anyhow!("--lift-off-force: N"))?.parse()?,
            "--barrier" => barrier_update = Some(args.next().ok_or_else(|| anyhow::anyhow!("--barrier: a rule"))?.parse().map_err(anyhow::Error::msg)?),
            "--ct-barrier" => ct_barrier_update = Some(args.next().ok_or_else(|| anyhow::anyhow!("--ct-barrier: a rule"))?.parse().map_err(anyhow::Error::msg)?),
            "--foot-margin" => foot_margin = args.next().ok_or_else(|| anyhow::anyhow!("--foot-margin: metres"))?.parse()?,
            "--curvature-violation" => curvature_violation = Some(args.next().ok_or_else(|| anyhow::anyhow!("--curvature-violation: a bound"))?.parse::<f64>()?),
            "--curvature-by-jacobians" => curvature_by_jacobians = true,
            "--id-torques" => id_torques = true,
            "--curvature-refresh" => curvature_refresh = args.next().ok_or_else(|| anyhow::anyhow!("--curvature-refresh: iterations"))?.parse()?,
            "--curvature-stall" => curvature_stall = Some(args.next().ok_or_else(|| anyhow::anyhow!("--curvature-stall: iterations"))?.parse()?),
            "--rnea-tr-mul" => rnea_tr_mul = Some(args.next().as_deref() == Some("on")),
            "--start-defect" => start_defect = true,
            "--curvature-after" => curvature = Some(args.next().ok_or_else(|| anyhow::anyhow!("--curvature-after: iterations"))?.parse()?),
            _ => names.push(a),
        }
    }
    let model = embedded::load("a1")?;
    let params = SrbParams::a1()?;
    let defaults = FullBodySettings::default();
    let settings = FullBodySettings {
        solver: Settings {
            verbose,
            parallel,
            restoration,
            max_iterations: max_iterations.unwrap_or(defaults.solver.max_iterations),
            barrier_update: barrier_update.unwrap_or(defaults.solver.barrier_update),
            ..defaults.solver.clone()
        },
        pre_landing_knots: pre_landing.unwrap_or(defaults.pre_landing_knots),
        w_acceleration: w_acceleration.unwrap_or(defaults.w_acceleration),
        max_joint_acceleration: max_acceleration.unwrap_or(defaults.max_joint_acceleration),
        w_velocity: w_velocity.unwrap_or(defaults.w_velocity),
        constraint_curvature_after: curvature,
        curvature_max_violation: curvature_violation.unwrap_or(defaults.curvature_max_violation),
        start_torques_by_inverse_dynamics: id_torques,
        curvature_on_stall: curvature_stall,
        curvature_refresh,
        curvature_rnea_tr_mul: rnea_tr_mul.unwrap_or(defaults.curvature_rnea_tr_mul),
        airborne_foot_margin: foot_margin,
        lift_off_normal_force: lift_off_force,
        ballistic_flight: ballistic_flight.unwrap_or(defaults.ballistic_flight),
        w_flight_momentum: w_flight_momentum.unwrap_or(defaults.w_flight_momentum),
        momentum_balance_in_stance: stance_balance || defaults.momentum_balance_in_stance,
        ..defaults
    };
    // The files' jumps under the reference script's names; a `.toml` argument is a jump file.
    let files: Vec<Jump> = names.iter().filter(|n| n.ends_with(".toml")).map(Jump::load_file).collect::<Result<_, _>>()?;
    let as_problem = |file: &Jump| {
        let spec = if reference_targets { file.reference_srb() } else { file.srb() };
        (JumpSpec { name: file.anchor.unwrap_or(spec.name), ..spec }, box_obstacle(file, model.feet[0].radius))
    };
    let all: Vec<(JumpSpec, Option<BoxObstacle>)> = embedded_jumps()?.iter().map(as_problem).collect();
    let selected: Vec<_> = if names.is_empty() {
        all.clone()
    } else {
        all.iter().filter(|(j, _)| names.iter().any(|n| n == j.name)).cloned().chain(files.iter().map(as_problem)).collect()
    };
    println!("jump                 T (10 ms)     box     status             iters (resto)  median s   (min s)  eval s  kkt s   viol      limits  binding");
    for (jump, file_box) in &selected {
        let ct_defaults = ContactTimingSettings::default();
        let ct_settings = ContactTimingSettings { max_stance_speed: max_stance_speed.unwrap_or(ct_defaults.max_stance_speed), ..ct_defaults };
        let ct = ContactTimingProblem::new(jump, &params, &ct_settings)?;
        let ct_solver_settings = ContactTimingProblem::solver_settings();
        let mut solver = ct.solver(Settings { barrier_update: ct_barrier_update.unwrap_or(ct_solver_settings.barrier_update), ..ct_solver_settings })?;
        let r = ct.solve(&mut solver)?;
        let srb = SrbTrajectory::from_solution(&ct, &r.last.primal)?.resample(settings.dt)?;
        let obstacle = match overhang {
            _ if !with_box || jump.box_height <= 0.0 => None,
            None => *file_box,
            Some(overhang) => {
                let feet = &ct.feet_start;
                let lo = |a: usize| feet.iter().map(|f| f[a]).fold(f64::INFINITY, f64::min) - overhang;
                let hi = |a: usize| feet.iter().map(|f| f[a]).fold(f64::NEG_INFINITY, f64::max) + overhang;
                Some(BoxObstacle { top: jump.box_height - model.feet[0].radius, x: [lo(0), hi(0)], y: [lo(1), hi(1)] })
            }
        };
        let guess = initial_guess_clear_of(&model, &srb, settings.pre_landing_knots, if plain_guess { None } else { obstacle.as_ref() })?;
        let fb = FullBodyProblem::new(&model, &srb, &guess, &settings, obstacle)?;
        fb.set_curvature_by_jacobians(curvature_by_jacobians);
        if start_defect {
            print_start_defect(&fb);
            continue;
        }
        let mut times = Vec::new();
        let mut plan = None;
        for _ in 0..repeats.max(1) {
            let p = fb.solve()?;
            times.push(p.report.time.as_secs_f64());
            plan = Some(p);
        }
        let plan = plan.expect("at least one solve");
        times.sort_by(f64::total_cmp);
        let rep = &plan.report;
        println!(
            "{:20} {:13} {:7} {:18} {:5} {:7}  {:.4}    ({:.4})  {:.3}   {:.3}   {:.1e}   {:7} {}",
            jump.name,
            format!("{:?}", srb.phase_knots),
            obstacle.map_or("-".to_string(), |b| format!("{:.2} m", b.top)),
            format!("{:?}", rep.status),
            rep.iterations,
            format!("({})", rep.restoration_iterations),
            times[times.len() / 2],
            times[0],
            rep.evaluation_time.as_secs_f64(),
            rep.kkt_time.as_secs_f64(),
            rep.primal_infeasibility,
            if plan.limits.all_met(1e-6) { "met" } else { "VIOLATED" },
            plan.limits.binding(1e-3).join(", ")
        );
        if let Some(dir) = &out_dir {
            std::fs::create_dir_all(dir)?;
            plan.trajectory.save_file(format!("{dir}/{}.json", jump.name))?;
        }
        if box_rows {
            if let Some(b) = &obstacle {
                print_box_rows(&model, &srb, &plan.trajectory, b, &settings)?;
            }
        }
        if show_limits {
            println!("{}", plan.limits);
            for (kind, v) in &rep.max_violation {
                println!("  optimizer rows {kind:20} {v:.2e}");
            }
        }
    }
    Ok(())
}

/// Per knot, the start's (the guess's) constraint violation: the dynamics defect
/// `f_k(z_k) - x_{k+1}` split into the base and joint rows of `dq` and of `v`, the largest
/// equality and inequality violation; and their largest values over all knots
/// (`--start-defect`: where the guess is dynamically inconsistent).
fn print_start_defect(fb: &FullBodyProblem) {
    use legwork::ipocp::StageValues;
    let n = fb.start.len();
    let amax = |v: &[f64]| v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    println!("knot  dq base  dq joint   v base   v joint   eq       ineq");
    let mut worst = [0.0f64; 6];
    for k in 0..n {
        let stage = fb.problem.stage(k);
        let d = stage.dims();
        let mut values = StageValues::zeros(d);
        stage.evaluate(fb.start[k].as_slice(), &mut values);
        let nv = d.nx / 2;
        let mut row = [0.0f64; 6];
        if d.nx_next > 0 {
            let defect: Vec<f64> = (0..d.nx_next).map(|i| values.dynamics[i] - fb.start[k + 1][i]).collect();
            row[0] = amax(&defect[..6]);
            row[1] = amax(&defect[6..nv]);
            row[2] = amax(&defect[nv..nv + 6]);
            row[3] = amax(&defect[nv + 6..]);
        }
        row[4] = amax(values.equalities.as_slice());
        let (mut lo, mut hi) = (vec![0.0; d.nh], vec![0.0; d.nh]);
        stage.inequality_bounds(&mut lo, &mut hi);
        row[5] = (0..d.nh).map(|i| (lo[i] - values.inequalities[i]).max(values.inequalities[i] - hi[i]).max(0.0)).fold(0.0, f64::max);
        println!("{k:4} {}", row.iter().map(|x| format!("{x:8.3}")).collect::<Vec<_>>().join(" "));
        for i in 0..6 {
            worst[i] = worst[i].max(row[i]);
        }
    }
    println!(" max {}", worst.iter().map(|x| format!("{x:8.3}")).collect::<Vec<_>>().join(" "));
}

/// Per knot from lift-off on: the SRB's CoM (y, z), the plan's base (y, z), and the box
/// clearance of each leg's knee and foot and of the nearest trunk corner (`--box-rows`:
/// which point binds where).
fn print_box_rows(model: &legwork::model::Model, srb: &SrbTrajectory, plan: &legwork::io::Trajectory, b: &BoxObstacle, s: &FullBodySettings) -> anyhow::Result<()> {
    use legwork::dynamics::{forward_kinematics, Data};
    use legwork::fullbody::kinematics::{foot_position, knee_position, legs};
    use nalgebra::{DVector, Vector3};
    let legs = legs(model)?;
    let mut data = Data::new(model);
    println!("knot  srb y    srb z    base y   base z  | knee LF RF LH RH (cm)       | foot LF RF LH RH (cm)       | corner (cm)");
    for (k, knot) in plan.knots.iter().enumerate() {
        if knot.in_contact.iter().all(|&c| c) {
            continue;
        }
        forward_kinematics(model, &mut data, &DVector::from_column_slice(&knot.q));
        let base = data.o_m_i[1];
        let d = |p: &Vector3<f64>| 100.0 * b.signed_distance(p).0;
        let knees: Vec<f64> = legs.iter().map(|l| d(&knee_position(&data, l)) - 100.0 * s.clearance).collect();
        let feet: Vec<f64> = legs.iter().enumerate().map(|(f, l)| d(&foot_position(model, &data, l)) - 100.0 * model.feet[f].radius).collect();
        let corner = (0..8)
            .map(|c| {
                let sign = Vector3::new(if c & 4 == 0 { 1.0 } else { -1.0 }, if c & 2 == 0 { 1.0 } else { -1.0 }, if c & 1 == 0 { 1.0 } else { -1.0 });
                d(&base.act_point(&s.trunk_half_extents.component_mul(&sign))) - 100.0 * s.clearance
            })
            .fold(f64::INFINITY, f64::min);
        let c = &srb.knots[k.min(srb.knots.len() - 1)].com;
        let f = |v: &[f64]| v.iter().map(|x| format!("{x:6.1}")).collect::<Vec<_>>().join(" ");
        println!("{k:4} {:8.3} {:8.3} {:8.3} {:8.3} | {} | {} | {corner:6.1}", c.y, c.z, knot.q[1], knot.q[2], f(&knees), f(&feet));
    }
    Ok(())
}
