//! The figures of a jump (Nguyen 2022): the phase timings beside the paper's Table I, the
//! ground forces against the friction cone and the force bound, the base pose, and the joint
//! torques against their limits.

use super::plots::{draw_panels, house_style, plot_error, FONT, PALETTE, WIDTH};
use super::signals::{joint_groups, unwrap_angles, Panel, Series};
use super::VizError;
use crate::io::Trajectory;
use crate::model::Model;
use crate::srb::SrbKnot;
use nalgebra::{Rotation3, UnitQuaternion};
use plotters::prelude::*;
use std::path::Path;

const FEET: [&str; 4] = ["LF", "RF", "LH", "RH"];

/// Bars of the optimal phase durations (10 ms): legwork's `durations` (s) beside the
/// paper's `paper_10ms` (when given), one group per phase named by its feet in contact.
pub fn write_phase_timings(path: &Path, title: &str, phases: &[[bool; 4]], durations: &[f64], paper_10ms: Option<&[f64]>) -> Result<(), VizError> {
    let err = |e: &dyn std::fmt::Display| plot_error(path, e);
    let ours: Vec<f64> = durations.iter().map(|t| t * 100.0).collect();
    let top = ours.iter().chain(paper_10ms.unwrap_or(&[])).fold(1.0f64, |m, &v| m.max(v)) * 1.45;
    let n = phases.len();
    let root = SVGBackend::new(path, (WIDTH, 360)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, (FONT, 20))
        .margin(8)
        .margin_right(20)
        .x_label_area_size(38)
        .y_label_area_size(70)
        .build_cartesian_2d(-0.6..n as f64 - 0.4, 0.0..top)
        .map_err(|e| err(&e))?;
    let label = |x: &f64| {
        let i = x.round();
        if (x - i).abs() > 1e-6 || i < 0.0 || i as usize >= n {
            return String::new();
        }
        let feet: Vec<&str> = FEET.iter().zip(phases[i as usize]).filter(|(_, c)| *c).map(|(f, _)| *f).collect();
        format!("phase {} ({})", i as usize + 1, if feet.is_empty() { "flight".to_string() } else { feet.join(" ") })
    };
    house_style(&mut chart.configure_mesh()).x_labels(n).x_label_formatter(&label).disable_x_mesh().x_desc("").y_desc("[10 ms]").draw().map_err(|e| err(&e))?;
    let mut groups = vec![("legwork", PALETTE[0], ours.clone(), -0.36)];
    if let Some(p) = paper_10ms {
        groups.push(("Nguyen 2022, Table I", PALETTE[1], p.to_vec(), 0.02));
    }
    for (name, color, values, offset) in groups {
        chart
            .draw_series(values.iter().enumerate().map(|(i, &v)| Rectangle::new([(i as f64 + offset, 0.0), (i as f64 + offset + 0.34, v)], color.mix(0.85).filled())))
            .map_err(|e| err(&e))?
            .label(format!("{name}: {}", values.iter().map(|v| format!("{v:.1}")).collect::<Vec<_>>().join(", ")))
            .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 18, y + 5)], color.filled()));
    }
    chart.configure_series_labels().position(SeriesLabelPosition::UpperRight).background_style(WHITE.mix(0.85)).label_font((FONT, 14)).draw().map_err(|e| err(&e))?;
    root.present().map_err(|e| err(&e))
}

/// The single-rigid-body plan's ground forces: each foot's friction use `|F_t| / F_n` in
/// contact against the cone's `mu`, and its normal force against `[f_min, f_max]`.
pub fn write_srb_forces(path: &Path, knots: &[SrbKnot], mu: f64, f_bounds: (f64, f64)) -> Result<(), VizError> {
    let t: Vec<f64> = knots.iter().map(|k| k.t).collect();
    let mut friction: Vec<Series> = (0..4).map(|f| Series { name: FEET[f].into(), values: knots.iter().map(|k| if k.contacts[f] && k.forces[f].z > 1e-9 { k.forces[f].xy().norm() / k.forces[f].z } else { 0.0 }).collect() }).collect();
    friction.push(Series { name: format!("mu = {mu}"), values: vec![mu; t.len()] });
    let mut normal: Vec<Series> = (0..4).map(|f| Series { name: FEET[f].into(), values: knots.iter().map(|k| k.forces[f].z).collect() }).collect();
    normal.push(Series { name: format!("f_max = {} N", f_bounds.1), values: vec![f_bounds.1; t.len()] });
    let panels = [
        Panel { title: "Friction use |F_t| / F_n against the cone (contact-timing plan)".into(), unit: "-".into(), series: friction },
        Panel { title: "Normal ground force per foot against its bound (contact-timing plan)".into(), unit: "N".into(), series: normal },
    ];
    draw_panels(path, &t, &panels, &[])
}

/// The single-rigid-body plan's CoM position and body roll, pitch, yaw (unwrapped).
pub fn write_srb_pose(path: &Path, knots: &[SrbKnot]) -> Result<(), VizError> {
    let t: Vec<f64> = knots.iter().map(|k| k.t).collect();
    let axis = |a: usize| knots.iter().map(|k| k.com[a]).collect::<Vec<_>>();
    let rpy: Vec<(f64, f64, f64)> = knots.iter().map(|k| UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix(&k.rotation)).euler_angles()).collect();
    let deg = |a: usize| {
        let mut c: Vec<f64> = rpy.iter().map(|r| [r.0, r.1, r.2][a]).collect();
        unwrap_angles(&mut c);
        c.iter().map(|x| x.to_degrees()).collect::<Vec<_>>()
    };
    let series = |names: [&str; 3], cols: [Vec<f64>; 3]| names.iter().zip(cols).map(|(n, values)| Series { name: (*n).into(), values }).collect();
    let panels = [
        Panel { title: "CoM position (contact-timing plan)".into(), unit: "m".into(), series: series(["x", "y", "z"], [axis(0), axis(1), axis(2)]) },
        Panel { title: "Body roll, pitch, yaw (contact-timing plan, unwrapped)".into(), unit: "deg".into(), series: series(["roll", "pitch", "yaw"], [deg(0), deg(1), deg(2)]) },
    ];
    draw_panels(path, &t, &panels, &[])
}

/// The knots a figure draws: at most [`super::plots::MAX_POINTS`], spread over the motion
/// (a long recording would make an SVG of millions of points).
fn drawn_knots(traj: &Trajectory) -> Vec<&crate::io::Knot> {
    super::signals::decimate(traj, super::plots::MAX_POINTS).into_iter().map(|k| &traj.knots[k]).collect()
}

/// Each joint's `|tau| / tau_max` (the model's effort limit), one panel per leg, with the
/// limit at 1.
pub fn write_torque_limits(path: &Path, model: &Model, traj: &Trajectory) -> Result<(), VizError> {
    let knots = drawn_knots(traj);
    let t: Vec<f64> = knots.iter().map(|k| k.t).collect();
    let limits: Vec<f64> = model.actuated_joints().map(|j| j.limits.effort[0]).collect();
    let mut panels = Vec::new();
    for (leg, joints) in joint_groups(&traj.metadata.joint_names) {
        let mut series: Vec<Series> = joints
            .iter()
            .map(|&j| Series { name: traj.metadata.joint_names[j].clone(), values: knots.iter().map(|k| k.tau[j].abs() / limits.get(j).copied().unwrap_or(f64::INFINITY)).collect() })
            .collect();
        series.push(Series { name: "limit".into(), values: vec![1.0; t.len()] });
        panels.push(Panel { title: format!("{leg}: |torque| / limit"), unit: "-".into(), series });
    }
    draw_panels(path, &t, &panels, &[])
}

/// A trajectory's ground forces: each foot's friction use `|F_t| / F_n` while in contact
/// against the cone's `mu`, and its normal force against the minimum `f_min` a stance
/// foot must push with (world z as the normal: flat ground and box tops).
pub fn write_trajectory_forces(path: &Path, traj: &Trajectory, mu: f64, f_min: f64) -> Result<(), VizError> {
    let knots = drawn_knots(traj);
    let t: Vec<f64> = knots.iter().map(|k| k.t).collect();
    let feet = &traj.metadata.foot_names;
    let ratio = |k: &crate::io::Knot, f: usize| {
        let [x, y, z] = k.contact_force[f];
        if k.in_contact[f] && z > 1e-9 { x.hypot(y) / z } else { 0.0 }
    };
    let mut friction: Vec<Series> = feet.iter().enumerate().map(|(f, name)| Series { name: name.clone(), values: knots.iter().map(|k| ratio(k, f)).collect() }).collect();
    friction.push(Series { name: format!("mu = {mu}"), values: vec![mu; t.len()] });
    let mut normal: Vec<Series> = feet.iter().enumerate().map(|(f, name)| Series { name: name.clone(), values: knots.iter().map(|k| k.contact_force[f][2]).collect() }).collect();
    normal.push(Series { name: format!("minimum in contact = {f_min} N"), values: vec![f_min; t.len()] });
    let panels = [
        Panel { title: format!("{}: friction use |F_t| / F_n against the cone", traj.metadata.scenario), unit: "-".into(), series: friction },
        Panel { title: "Normal ground force per foot".into(), unit: "N".into(), series: normal },
    ];
    draw_panels(path, &t, &panels, &[])
}
