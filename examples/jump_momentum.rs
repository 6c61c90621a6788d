//! Diagnoses a jump plan against its run in legwork's simulator: per 10 ms knot, the base
//! roll/pitch/yaw, the base angular velocity and the centroidal angular momentum (about the
//! CoM, world axes) of the plan and of the nominal run under the jump controllers.
//!
//! ```text
//! cargo run --release --example jump_momentum -- PLAN.json [FROM_S TO_S] [--jump NAME]
//! ```
//!
//! `--jump NAME` runs on the embedded jump's terrain (its box); flat ground otherwise.

use anyhow::Context;
use legwork::dynamics::{base_orientation, centroidal_momentum, Data};
use legwork::io::Trajectory;
use legwork::jump::control::{run_jump, JumpSettings};
use legwork::model::embedded;
use nalgebra::DVector;

mod common;

fn main() -> anyhow::Result<()> {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let terrain = common::jump_terrain(&mut args)?;
    let plan = Trajectory::load_file(args.first().context("usage: jump_momentum PLAN.json [FROM TO]")?)?;
    let from: f64 = args.get(1).map(|s| s.parse()).transpose()?.unwrap_or(0.0);
    let to: f64 = args.get(2).map(|s| s.parse()).transpose()?.unwrap_or(f64::INFINITY);
    let model = embedded::load("a1")?;
    let run = run_jump(&model, terrain.as_ref(), &plan, &JumpSettings::default())?;
    println!("run: lift-off {:?} touch-down {:?} fell {}", run.lift_off, run.touch_down, run.fell);
    let mut data = Data::new(&model);
    let mut describe = |k: &legwork::io::Knot| {
        let q = DVector::from_column_slice(&k.q);
        let v = DVector::from_column_slice(&k.v);
        let h = centroidal_momentum(&model, &mut data, &q, &v);
        let (r, p, y) = base_orientation(&k.q).euler_angles();
        let fz: f64 = k.contact_force.iter().map(|f| f[2]).sum();
        format!(
            "rpy {:6.1} {:6.1} {:6.1} w {:6.2} {:6.2} {:6.2} L {:6.2} {:6.2} {:6.2} fz {:5.0}",
            r.to_degrees(), p.to_degrees(), y.to_degrees(), k.v[3], k.v[4], k.v[5], h.n.x, h.n.y, h.n.z, fz
        )
    };
    println!("   t   | plan                                                              | run");
    for k in plan.knots.iter().filter(|k| k.t >= from - 1e-9 && k.t <= to + 1e-9) {
        let r = run.trajectory.knots.iter().min_by(|a, b| (a.t - k.t).abs().total_cmp(&(b.t - k.t).abs())).unwrap();
        println!("{:.3} | {} | {}", k.t, describe(k), describe(r));
    }
    Ok(())
}
