//! Compares a jump plan's take-off with its runs: per knot, the CoM height and velocity and
//! each foot's normal force of the plan, of the nominal run in legwork's simulator under the
//! jump controllers, and (optionally) of another recorded run (e.g. MuJoCo's, recorded as a
//! trajectory with `q`, `v`, `contact_force` per knot).
//!
//! ```text
//! cargo run --release --example jump_takeoff -- PLAN.json [FROM_S TO_S] [--jump NAME] [--every S] [--other RUN.json]
//! ```
//!
//! `--stiffness-scale S` (a diagnosis, not a setting of any jump) scales the simulated
//! robot's normal contact stiffness and damping by `S` and runs the physics at 0.25 ms, to
//! see how much of a take-off depends on how far the loaded feet sink.
//!
//! `--feet` adds each foot's position. `--lift-off-lead S`: the controllers' constant lift-off
//! lead (`JumpSettings::lift_off_lead`).
//!
//! `--every S` prints every `S` seconds (default 0.01; the legwork run is recorded at 1 ms,
//! the plan is interpolated between its knots). The CoM is what a take-off decides: its
//! velocity at lift-off fixes the flight's parabola.

use anyhow::Context;
use legwork::dynamics::{center_of_mass, centroidal_momentum, Data};
use legwork::io::{Knot, Trajectory};
use legwork::jump::control::{run_jump, JumpSettings};
use legwork::model::{embedded, Model};
use nalgebra::{DVector, Vector3};

mod common;

use common::take;

/// CoM position and velocity (world) and the angular momentum about the CoM (world axes) of
/// a knot.
fn com_state(model: &Model, data: &mut Data, k: &Knot) -> (Vector3<f64>, Vector3<f64>, Vector3<f64>) {
    let q = DVector::from_column_slice(&k.q);
    let v = DVector::from_column_slice(&k.v);
    let h = centroidal_momentum(model, data, &q, &v);
    let c = center_of_mass(model, data, &q);
    (c, h.f / model.total_mass(), h.n)
}

/// The knot of `trajectory` nearest to `t`.
fn nearest(trajectory: &Trajectory, t: f64) -> &Knot {
    trajectory.knots.iter().min_by(|a, b| (a.t - t).abs().total_cmp(&(b.t - t).abs())).unwrap()
}

/// The plan's knot holding `t` (its forces act over `[t_k, t_k+1)`).
fn holding(trajectory: &Trajectory, t: f64) -> &Knot {
    trajectory.knots.iter().rev().find(|k| k.t <= t + 1e-9).unwrap_or(&trajectory.knots[0])
}

fn main() -> anyhow::Result<()> {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let terrain = common::jump_terrain(&mut args)?;
    let show_feet = match args.iter().position(|a| a == "--feet") {
        Some(i) => {
            args.remove(i);
            true
        }
        None => false,
    };
    let every: f64 = take(&mut args, "--every")?.map(|s| s.parse()).transpose()?.unwrap_or(0.01);
    let other = take(&mut args, "--other")?.map(Trajectory::load_file).transpose()?;
    // Every flag is taken before the positional arguments are read.
    let stiffness_scale: Option<f64> = take(&mut args, "--stiffness-scale")?.map(|s| s.parse()).transpose()?;
    let lift_off_lead: Option<f64> = take(&mut args, "--lift-off-lead")?.map(|s| s.parse()).transpose()?;
    let plan = Trajectory::load_file(args.first().context("usage: jump_takeoff PLAN.json [FROM TO]")?)?;
    let from: f64 = args.get(1).map(|s| s.parse()).transpose()?.unwrap_or(0.0);
    let to: f64 = args.get(2).map(|s| s.parse()).transpose()?.unwrap_or(plan.duration());
    let mut model = embedded::load("a1")?;
    let mut settings = JumpSettings { record_dt: 0.001, lift_off_lead, ..JumpSettings::default() };
    if let Some(scale) = stiffness_scale {
        model.contact.normal_stiffness *= scale;
        model.contact.normal_damping *= scale;
        settings.sim.physics_dt = 0.00025;
    }
    let run = run_jump(&model, terrain.as_ref(), &plan, &settings)?;
    println!("mass {:.3} kg; run: lift-off {:?} touch-down {:?} fell {}", model.total_mass(), run.lift_off, run.touch_down, run.fell);
    let mut data = Data::new(&model);
    let mut describe = |k: &Knot, forces: &Knot| {
        let (c, cd, l) = com_state(&model, &mut data, k);
        let (roll, pitch, _) = legwork::dynamics::base_orientation(&k.q).euler_angles();
        let feet = if show_feet {
            legwork::dynamics::forward_kinematics(&model, &mut data, &DVector::from_column_slice(&k.q));
            legwork::dynamics::update_frame_placements(&model, &mut data);
            let p: Vec<String> = model.feet.iter().map(|f| {
                let p = legwork::dynamics::frame_position(&model, &data, f.frame);
                format!("{} y {:.3} z {:.3}", f.name, p.y, p.z)
            }).collect();
            format!(" | feet {}", p.join(", "))
        } else {
            String::new()
        };
        let fz: Vec<f64> = forces.contact_force.iter().map(|f| f[2]).collect();
        format!(
            "c z {:.4} y {:.4} | cd y {:5.3} z {:6.3} | roll {:5.1} pitch {:5.1} L {:5.2} {:5.2} {:5.2} | fz {} = {:4.0}",
            c.z,
            c.y,
            cd.y,
            cd.z,
            roll.to_degrees(),
            pitch.to_degrees(),
            l.x,
            l.y,
            l.z,
            fz.iter().map(|f| format!("{f:4.0}")).collect::<Vec<_>>().join(" "),
            fz.iter().sum::<f64>()
        ) + &feet
    };
    let steps = ((to - from) / every).round() as usize;
    for i in 0..=steps {
        let t = from + i as f64 * every;
        let p = nearest(&plan, t);
        let line_plan = if (p.t - t).abs() < 1e-6 { describe(p, holding(&plan, t)) } else { String::from("(between knots)") };
        let r = nearest(&run.trajectory, t);
        println!("{t:.3} plan  {line_plan}\n      run   {}", describe(r, r));
        if let Some(o) = &other {
            let k = nearest(o, t);
            println!("      other {}", describe(k, k));
        }
    }
    Ok(())
}
