//! Diagnoses a jump plan against its run in legwork's simulator: per 10 ms knot, the base
//! roll/pitch/yaw, the base angular velocity and the centroidal angular momentum (about the
//! CoM, world axes) of the plan and of the nominal run under the jump controllers.
//!
//! ```text
//! cargo run --release --example jump_momentum -- PLAN.json [FROM_S TO_S] [--jump NAME]
//! ```
//!
//! `--jump NAME` runs on the embedded jump's terrain (its box); flat ground otherwise.
//! `--lift-off-lead S`: the controllers' constant lift-off lead (`JumpSettings::lift_off_lead`).
//!
//! First line: the plan's flight drift, the centroidal angular momentum of every flight knot
//! (no foot in contact) against the first one's: in flight only gravity acts, so physics
//! keeps it constant.

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
    let lift_off_lead: Option<f64> = common::take(&mut args, "--lift-off-lead")?.map(|s| s.parse()).transpose().context("--lift-off-lead: a time (s)")?;
    let plan = Trajectory::load_file(args.first().context("usage: jump_momentum PLAN.json [FROM TO]")?)?;
    let from: f64 = args.get(1).map(|s| s.parse()).transpose()?.unwrap_or(0.0);
    let to: f64 = args.get(2).map(|s| s.parse()).transpose()?.unwrap_or(f64::INFINITY);
    let model = embedded::load("a1")?;
    print_flight_drift(&model, &plan);
    let run = run_jump(&model, terrain.as_ref(), &plan, &JumpSettings { lift_off_lead, ..JumpSettings::default() })?;
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

/// The plan's angular momentum over its flight (knots with no foot in contact): first, last,
/// and the largest deviation from the first, absolute and relative to its norm.
fn print_flight_drift(model: &legwork::model::Model, plan: &Trajectory) {
    let mut data = Data::new(model);
    let flight: Vec<_> = plan
        .knots
        .iter()
        .filter(|k| k.in_contact.iter().all(|&c| !c))
        .map(|k| {
            let h = centroidal_momentum(model, &mut data, &DVector::from_column_slice(&k.q), &DVector::from_column_slice(&k.v));
            (k.t, h.n)
        })
        .collect();
    let (Some(first), Some(last)) = (flight.first(), flight.last()) else {
        println!("plan flight drift: no flight knot");
        return;
    };
    let (t_worst, worst) = flight.iter().map(|(t, n)| (*t, (n - first.1).norm())).fold((first.0, 0.0), |a, b| if b.1 > a.1 { b } else { a });
    println!(
        "plan flight drift: {} knots {:.3}-{:.3} s, L first {:.3} {:.3} {:.3}, last {:.3} {:.3} {:.3} N m s, max |L - L_first| {:.3} N m s ({:.1} %) at {:.3} s",
        flight.len(), first.0, last.0, first.1.x, first.1.y, first.1.z, last.1.x, last.1.y, last.1.z, worst, 100.0 * worst / first.1.norm().max(1e-12), t_worst
    );
}
