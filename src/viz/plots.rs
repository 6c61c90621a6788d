//! Static figures of a trajectory, as SVG files for papers and reports (`plotters`' SVG
//! backend): the base pose, the base twist, the joint torques (one panel per leg), the
//! contact forces (one panel per foot, contact phases shaded) and the gait diagram (one bar
//! per foot where it is in contact).
//!
//! No font library is involved: the SVG backend writes text as `<text>` elements that the
//! viewer renders with its own fonts, and plotters lays them out with its built-in estimate
//! of glyph widths. So the figures build and render on any machine.
//!
//! ```
//! use legwork::{io::{Knot, Trajectory}, model::embedded, terrain::TerrainSpec, viz};
//! let model = embedded::load("a1").unwrap();
//! let q = model.reference_configuration("standing").unwrap();
//! let mut traj = Trajectory::new(&model, "stand", 0.01, TerrainSpec::flat());
//! for k in 0..5 {
//!     traj.knots.push(Knot {
//!         t: 0.01 * k as f64, q: q.as_slice().to_vec(), v: vec![0.0; 18], tau: vec![1.0; 12],
//!         contact_force: vec![[0.0, 0.0, 33.7]; 4], in_contact: vec![true; 4], feedback_gain: None,
//!     });
//! }
//! let dir = std::env::temp_dir().join(format!("legwork-plots-doc-{}", std::process::id()));
//! let files = viz::write_plots(&traj, &dir).unwrap();
//! assert_eq!(files.len(), 5);
//! # std::fs::remove_dir_all(&dir).ok();
//! ```

use super::signals::{self, Panel};
use super::VizError;
use crate::io::Trajectory;
use plotters::chart::MeshStyle;
use plotters::coord::ranged1d::SegmentValue;
use plotters::prelude::*;
use std::ops::Range;
use std::path::{Path, PathBuf};

/// At most this many samples per curve (the knots are thinned evenly in time beyond it).
pub(super) const MAX_POINTS: usize = 4000;
/// Figure width and height of one panel, px.
pub(super) const WIDTH: u32 = 960;
pub(super) const PANEL_HEIGHT: u32 = 270;

pub(super) const XYZ: [RGBColor; 3] = [RGBColor(214, 39, 40), RGBColor(44, 160, 44), RGBColor(31, 119, 180)];
pub(super) const PALETTE: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];
const CONTACT: RGBColor = RGBColor(39, 163, 90);
pub(super) const FONT: &str = "sans-serif";

/// Writes the figures of `traj` into the folder `dir` (created if needed) and returns the
/// files written: `base_pose.svg`, `base_twist.svg`, `joint_torques.svg`,
/// `contact_forces.svg`, `gait.svg`.
pub fn write_plots(traj: &Trajectory, dir: impl AsRef<Path>) -> Result<Vec<PathBuf>, VizError> {
    traj.validate("trajectory")?;
    let dir = dir.as_ref();
    std::fs::create_dir_all(dir).map_err(|e| VizError::io(dir, e))?;
    let idx = signals::decimate(traj, MAX_POINTS);
    let t = signals::times(traj, &idx);
    let m = &traj.metadata;
    let mut written = Vec::new();

    let path = dir.join("base_pose.svg");
    draw_panels(&path, &t, &[signals::base_position(traj, &idx), signals::base_orientation(traj, &idx)], &[])?;
    written.push(path);

    let path = dir.join("base_twist.svg");
    draw_panels(&path, &t, &[signals::base_linear_velocity(traj, &idx), signals::base_angular_velocity(traj, &idx)], &[])?;
    written.push(path);

    let path = dir.join("joint_torques.svg");
    let torques: Vec<Panel> = signals::joint_groups(&m.joint_names)
        .iter()
        .map(|(leg, joints)| {
            let title = if leg.is_empty() { "Joint torques".to_string() } else { format!("Joint torques, leg {leg}") };
            signals::joint_torques(traj, &idx, joints, &title)
        })
        .collect();
    draw_panels(&path, &t, &torques, &[])?;
    written.push(path);

    let phases: Vec<Vec<(f64, f64)>> = (0..m.foot_names.len()).map(|f| contact_phases(traj, f)).collect();
    let path = dir.join("contact_forces.svg");
    let forces: Vec<Panel> = (0..m.foot_names.len()).map(|f| signals::contact_force(traj, &idx, f)).collect();
    draw_panels(&path, &t, &forces, &phases)?;
    written.push(path);

    let path = dir.join("gait.svg");
    draw_gait(&path, traj, &phases)?;
    written.push(path);
    Ok(written)
}

/// The figures that need the robot, into `dir` (created if needed): each joint's
/// `|torque| / effort limit` with the limit at 1 (`torque_limits.svg`), and each foot's
/// friction use `|F_t| / F_n` against the robot's friction coefficient with its normal
/// force (`ground_forces.svg`). Returns the files written.
pub fn write_limit_plots(model: &crate::model::Model, traj: &Trajectory, dir: impl AsRef<Path>) -> Result<Vec<PathBuf>, VizError> {
    traj.validate("trajectory")?;
    let dir = dir.as_ref();
    std::fs::create_dir_all(dir).map_err(|e| VizError::io(dir, e))?;
    let torques = dir.join("torque_limits.svg");
    super::jump::write_torque_limits(&torques, model, traj)?;
    let forces = dir.join("ground_forces.svg");
    super::jump::write_trajectory_forces(&forces, traj, model.contact.friction, 0.0)?;
    Ok(vec![torques, forces])
}

/// The intervals `[start, end)` during which foot `foot` is in contact: each knot in
/// contact covers the time up to the next knot.
fn contact_phases(traj: &Trajectory, foot: usize) -> Vec<(f64, f64)> {
    let knots = &traj.knots;
    let mut phases: Vec<(f64, f64)> = Vec::new();
    for (k, knot) in knots.iter().enumerate() {
        if !knot.in_contact[foot] {
            continue;
        }
        let end = knots.get(k + 1).map_or(knot.t, |next| next.t);
        match phases.last_mut() {
            Some(last) if k > 0 && knots[k - 1].in_contact[foot] => last.1 = end,
            _ => phases.push((knot.t, end)),
        }
    }
    phases
}

/// The axes, grid and fonts every figure shares; time along x.
pub(super) fn house_style<'m, 'a, 'b, X: Ranged, Y: Ranged, DB: DrawingBackend>(mesh: &'m mut MeshStyle<'a, 'b, X, Y, DB>) -> &'m mut MeshStyle<'a, 'b, X, Y, DB> {
    mesh.x_desc("t [s]")
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 15))
        .light_line_style(RGBColor(238, 240, 243))
        .bold_line_style(RGBColor(214, 218, 224))
}

pub(super) fn plot_error(path: &Path, e: impl std::fmt::Display) -> VizError {
    VizError::Plot { path: path.display().to_string(), message: e.to_string() }
}

/// `[lo, hi]` of the values with a 6 % margin; a flat curve gets a band around it.
pub(super) fn value_range<'a>(values: impl Iterator<Item = &'a f64>) -> Range<f64> {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| (lo.min(*v), hi.max(*v)));
    if !lo.is_finite() {
        return -1.0..1.0;
    }
    let pad = if hi - lo > 1e-12 { 0.06 * (hi - lo) } else { (0.1 * hi.abs()).max(1e-3) };
    (lo - pad)..(hi + pad)
}

pub(super) fn time_range(t: &[f64]) -> Range<f64> {
    match (t.first(), t.last()) {
        (Some(&a), Some(&b)) if b > a => a..b,
        (Some(&a), _) => a..a + 1e-3,
        _ => 0.0..1.0,
    }
}

/// One figure of stacked panels over the times `t`; `shade[i]`, when given, are time
/// intervals shaded behind panel `i` (contact phases).
pub(super) fn draw_panels(path: &Path, t: &[f64], panels: &[Panel], shade: &[Vec<(f64, f64)>]) -> Result<(), VizError> {
    let err = |e: &dyn std::fmt::Display| plot_error(path, e);
    let height = PANEL_HEIGHT * panels.len().max(1) as u32;
    let root = SVGBackend::new(path, (WIDTH, height)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let areas = root.split_evenly((panels.len().max(1), 1));
    for (i, (panel, area)) in panels.iter().zip(&areas).enumerate() {
        let x_range = time_range(t);
        let y_range = value_range(panel.series.iter().flat_map(|s| s.values.iter()));
        let mut chart = ChartBuilder::on(area)
            .caption(&panel.title, (FONT, 20))
            .margin(8)
            .margin_right(20)
            .x_label_area_size(38)
            .y_label_area_size(70)
            .build_cartesian_2d(x_range.clone(), y_range.clone())
            .map_err(|e| err(&e))?;
        house_style(&mut chart.configure_mesh()).y_desc(format!("[{}]", panel.unit)).draw().map_err(|e| err(&e))?;
        if let Some(phases) = shade.get(i) {
            let style = CONTACT.mix(0.12).filled();
            chart
                .draw_series(phases.iter().map(|&(a, b)| Rectangle::new([(a, y_range.start), (b, y_range.end)], style)))
                .map_err(|e| err(&e))?
                .label("in contact")
                .legend(|(x, y)| Rectangle::new([(x, y - 5), (x + 18, y + 5)], CONTACT.mix(0.25).filled()));
        }
        for (k, series) in panel.series.iter().enumerate() {
            let color = if panel.series.len() == 3 { XYZ[k] } else { PALETTE[k % PALETTE.len()] };
            chart
                .draw_series(LineSeries::new(t.iter().copied().zip(series.values.iter().copied()), color.stroke_width(2)))
                .map_err(|e| err(&e))?
                .label(&series.name)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(3)));
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(190, 196, 204))
            .label_font((FONT, 14))
            .draw()
            .map_err(|e| err(&e))?;
    }
    root.present().map_err(|e| err(&e))
}

/// The gait diagram: time along x, one row per foot, a bar wherever the foot is in
/// contact; each row says the foot's share of time in contact (duty factor).
fn draw_gait(path: &Path, traj: &Trajectory, phases: &[Vec<(f64, f64)>]) -> Result<(), VizError> {
    let err = |e: &dyn std::fmt::Display| plot_error(path, e);
    let feet = &traj.metadata.foot_names;
    let n = feet.len();
    let t: Vec<f64> = traj.knots.iter().map(|k| k.t).collect();
    let x_range = time_range(&t);
    let span = x_range.end - x_range.start;
    let labels: Vec<String> = feet
        .iter()
        .zip(phases)
        .map(|(name, ph)| {
            let duty = ph.iter().map(|(a, b)| b - a).sum::<f64>() / span.max(1e-12);
            format!("{name} {:.0}%", 100.0 * duty)
        })
        .collect();
    let height = 110 + 46 * n.max(1) as u32;
    let root = SVGBackend::new(path, (WIDTH, height)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    // Rows top to bottom in foot order: row of foot f is segment n - 1 - f.
    let rows = n.max(1) as i32;
    let mut chart = ChartBuilder::on(&root)
        .caption("Contact schedule (gait diagram)", (FONT, 20))
        .margin(8)
        .margin_right(20)
        .x_label_area_size(38)
        .y_label_area_size(130)
        .build_cartesian_2d(x_range, (0..rows - 1).into_segmented()) // integer ranges include their end
        .map_err(|e| err(&e))?;
    let row_label = |v: &SegmentValue<i32>| match v {
        SegmentValue::CenterOf(row) if (0..rows).contains(row) => labels.get((rows - 1 - row) as usize).cloned().unwrap_or_default(),
        _ => String::new(),
    };
    house_style(&mut chart.configure_mesh()).disable_y_mesh().y_labels(n + 1).y_label_formatter(&row_label).draw().map_err(|e| err(&e))?;
    for (f, ph) in phases.iter().enumerate() {
        let row = rows - 1 - f as i32;
        let bars = ph.iter().map(|&(a, b)| {
            Rectangle::new([(a, SegmentValue::Exact(row)), (b, SegmentValue::Exact(row + 1))], CONTACT.mix(0.85).filled())
        });
        chart.draw_series(bars).map_err(|e| err(&e))?;
        // A white rule between rows keeps the bars of neighbouring feet apart.
        let rule = PathElement::new(vec![(chart.x_range().start, SegmentValue::Exact(row)), (chart.x_range().end, SegmentValue::Exact(row))], WHITE.stroke_width(6));
        chart.draw_series(std::iter::once(rule)).map_err(|e| err(&e))?;
    }
    root.present().map_err(|e| err(&e))
}

/// The SLQ cost per iteration over the initial cost (Neunert 2017, Fig. 12) into an SVG:
/// the normalized cost on a log scale (a converged solve falls by orders of magnitude, which
/// a linear axis flattens to zero after the first iterations), the iterations in whole
/// numbers. Costs that are not positive (an augmented-Lagrangian round's cost can be) have no
/// place on a log axis: they are left out and the caption says how many.
pub fn write_cost_plot(costs: &[f64], title: &str, path: impl AsRef<Path>) -> Result<(), VizError> {
    let path = path.as_ref();
    let err = |e: &dyn std::fmt::Display| plot_error(path, e);
    let first = costs.first().copied().filter(|c| c.is_finite() && *c > 0.0).unwrap_or(1.0);
    let normalized: Vec<(u32, f64)> = costs.iter().enumerate().map(|(i, c)| (i as u32, c / first)).filter(|(_, c)| c.is_finite() && *c > 0.0).collect();
    let left_out = costs.len() - normalized.len();
    let (lo, hi) = normalized.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &(_, c)| (lo.min(c), hi.max(c)));
    // Whole decades around the data (at least one).
    let (lo, hi) = if lo.is_finite() { (10f64.powf(lo.log10().floor()), 10f64.powf(hi.log10().ceil().max(lo.log10().floor() + 1.0))) } else { (0.1, 1.0) };
    let root = SVGBackend::new(path, (WIDTH, 2 * PANEL_HEIGHT)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let last = (costs.len().max(2) - 1) as u32;
    let caption = if left_out > 0 { format!("{title} ({left_out} iterations with cost <= 0 not drawn)") } else { title.to_string() };
    let mut chart = ChartBuilder::on(&root)
        .caption(caption, (FONT, 20))
        .margin(8)
        .margin_right(20)
        .x_label_area_size(38)
        .y_label_area_size(70)
        .build_cartesian_2d(0..last, (lo..hi).log_scale())
        .map_err(|e| err(&e))?;
    chart
        .configure_mesh()
        .x_desc("iteration")
        .y_desc("cost / initial cost (log)")
        .x_labels((last as usize + 1).min(12))
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 15))
        .light_line_style(RGBColor(238, 240, 243))
        .bold_line_style(RGBColor(214, 218, 224))
        .draw()
        .map_err(|e| err(&e))?;
    chart.draw_series(LineSeries::new(normalized.iter().copied(), PALETTE[0].stroke_width(2))).map_err(|e| err(&e))?;
    chart.draw_series(normalized.iter().map(|&p| Circle::new(p, 3, PALETTE[0].filled()))).map_err(|e| err(&e))?;
    root.present().map_err(|e| err(&e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_never_collapse() {
        let r = value_range([2.0, 2.0].iter());
        assert!(r.start < 2.0 && r.end > 2.0);
        let r = value_range([].iter());
        assert_eq!(r, -1.0..1.0);
        assert_eq!(time_range(&[0.5]), 0.5..0.501);
    }

    #[test]
    fn cost_plot_is_written_normalized() {
        let path = std::env::temp_dir().join(format!("legwork-cost-{}.svg", std::process::id()));
        write_cost_plot(&[200.0, 50.0, 10.0, 9.0, 2.0, 0.02], "squat_jump: normalized cost", &path).unwrap();
        let svg = std::fs::read_to_string(&path).unwrap();
        assert!(svg.contains("squat_jump: normalized cost") && svg.contains("cost / initial cost (log)"));
        assert_eq!(svg.matches("<circle").count(), 6);
        // The texts of the SVG: decades as y labels, whole-number iterations as x labels.
        let texts: Vec<&str> = svg.split("</text>").filter_map(|t| t.rsplit('>').next()).map(str::trim).collect();
        let decades: Vec<&&str> = texts.iter().filter(|t| t.starts_with("1e")).collect();
        assert!(decades.len() >= 3 && texts.contains(&"1e0"), "{texts:?}");
        let iterations: Vec<&&str> = texts.iter().filter(|t| !t.starts_with("1e") && t.parse::<f64>().is_ok()).collect();
        assert!(iterations.iter().all(|t| t.parse::<u32>().is_ok()) && texts.contains(&"5"), "{texts:?}");
        // A cost <= 0 is left out and said so.
        write_cost_plot(&[200.0, 50.0, -10.0, 9.0], "al round", &path).unwrap();
        let svg = std::fs::read_to_string(&path).unwrap();
        assert!(svg.contains("1 iterations with cost &lt;= 0 not drawn") || svg.contains("1 iterations with cost <= 0 not drawn"), "{svg}");
        assert_eq!(svg.matches("<circle").count(), 3);
        std::fs::remove_file(&path).ok();
    }
}
