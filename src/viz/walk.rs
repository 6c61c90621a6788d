//! Drawing a planned walk (Winkler 2015): what the planners intended beside what the robot
//! did.
//!
//! * [`plan_overlay`]: the replay's [`ReplayOverlay`] of a trial: the footholds of every
//!   plan coloured by leg (hollow where a later plan replaced them before the foot got
//!   there), the planned CoG path (at the planned CoG height) and the cart-table ZMP path
//!   (eq. 5, on the ground under it) over the part of each plan that ran, and the support
//!   polygon of each phase, as planned and shrunk by the stability margin `d` (eq. 6).
//! * [`write_walk_plots`]: `cog_zmp_support.svg`, the paper's Fig. 8 (top: the walk from
//!   above, actual and planned CoG and the footholds; bottom: the shrunk support triangles
//!   of the first plan's first steps with the planned CoG and ZMP over them, inserted
//!   four-leg phases in red), and `cog_tracking.svg` (CoG x and y against time, planned and
//!   actual, with the planned ZMP).
//!
//! A plan "ran" from its start to the next plan's start (a re-plan replaces the rest), to
//! its own end, or to the end of the trial, whichever comes first: [`executed_windows`].

use super::plots::{house_style, plot_error, time_range, value_range, FONT, MAX_POINTS, PALETTE, PANEL_HEIGHT, WIDTH};
use super::replay::{OverlayFoothold, OverlayPath, OverlaySupport, ReplayOverlay};
use super::VizError;
use crate::dynamics::{center_of_mass, Data};
use crate::io::Trajectory;
use crate::model::description::LEG_ORDER;
use crate::model::Model;
use crate::terrain::Terrain;
use crate::walk::motion::MotionPlan;
use crate::walk::trial::PlanRecord;
use crate::zmp::PhaseOrigin;
use nalgebra::{DVector, Point2};
use plotters::element::DashedPathElement;
use plotters::prelude::*;
use std::ops::Range;
use std::path::{Path, PathBuf};

/// Time between two samples of the planned CoG and ZMP paths (s).
pub const PATH_SAMPLE_INTERVAL: f64 = 0.02;
/// Colours of the planned CoG and ZMP, in the replay and the figures.
pub const COG_COLOR: RGBColor = RGBColor(142, 36, 170);
pub const ZMP_COLOR: RGBColor = RGBColor(46, 125, 50);
/// Colours of the legs' footholds (LF, RF, LH, RH: left legs warm, right legs cool), as the
/// replay draws them.
pub const LEG_COLORS: [RGBColor; 4] = [RGBColor(214, 39, 40), RGBColor(31, 119, 180), RGBColor(255, 127, 14), RGBColor(23, 190, 207)];
/// Fig. 8's bottom panel shows the first plan from its first swing to the end of this many
/// swings (the paper: three steps and the four-leg phase inserted between them).
const FIG8_SWINGS: usize = 3;
/// Colours of consecutive phases in Fig. 8 (brown, green, gold, blue, purple, teal); an
/// inserted four-leg phase is red.
const PHASE_COLORS: [RGBColor; 6] = [RGBColor(141, 85, 36), RGBColor(46, 160, 67), RGBColor(214, 170, 0), RGBColor(31, 119, 180), RGBColor(148, 103, 189), RGBColor(23, 160, 170)];
const FOUR_LEG_COLOR: RGBColor = RGBColor(214, 39, 40);

fn css(c: RGBColor) -> String {
    format!("#{:02x}{:02x}{:02x}", c.0, c.1, c.2)
}

/// The time span `[start, end]` of each plan that ran (simulation time, s); `end_time` is
/// the end of the trial. A window is empty (`end == start`) when the next plan started at
/// once.
pub fn executed_windows(plans: &[PlanRecord], end_time: f64) -> Vec<(f64, f64)> {
    plans
        .iter()
        .enumerate()
        .map(|(k, record)| {
            let start = record.plan.start_time;
            let next = plans.get(k + 1).map_or(f64::INFINITY, |n| n.plan.start_time);
            (start, record.plan.end_time().min(next).min(end_time).max(start))
        })
        .collect()
}

/// `a, a + dt, ..., b` (both ends; one sample when `b == a`).
fn sample_times(a: f64, b: f64, dt: f64) -> Vec<f64> {
    let n = ((b - a) / dt).ceil().max(0.0) as usize;
    let mut t: Vec<f64> = (0..n).map(|i| a + i as f64 * dt).collect();
    t.push(b);
    t
}

/// Planned CoG `[x, y, z]` at simulation time `t` (z: the planned posture's CoG height).
fn planned_cog(plan: &MotionPlan, t: f64) -> [f64; 3] {
    let c = plan.cog_state(t).position;
    [c.x, c.y, plan.posture(t).0.cog_z]
}

/// Cart-table ZMP (eq. 5) `(x, y)` at simulation time `t`.
fn planned_zmp(plan: &MotionPlan, t: f64) -> Option<Point2<f64>> {
    plan.cog.zmp((t - plan.start_time).clamp(0.0, plan.duration())).ok()
}

/// Simulation time at which footstep `step` of `plan` touches down (end of its swing).
fn touchdown_time(plan: &MotionPlan, step: usize) -> Option<f64> {
    let k = plan.swings.iter().position(|s| s.as_ref().is_some_and(|s| s.step == step))?;
    Some(plan.start_time + plan.cog.phases()[k].end_time())
}

/// Every plan's footholds, in order, with their touch-down times; executed when the swing
/// ended within the plan's window (whose end is `window_ends[k]` for plan `k`).
fn footholds_of(plans: &[PlanRecord], window_ends: impl Iterator<Item = f64>) -> Vec<OverlayFoothold> {
    let mut footholds = Vec::new();
    for (record, b) in plans.iter().zip(window_ends) {
        let plan = &record.plan;
        for (j, step) in plan.footsteps.iter().enumerate() {
            let t = touchdown_time(plan, j).unwrap_or(plan.end_time());
            footholds.push(OverlayFoothold { foot: step.leg, position: [step.to.x, step.to.y, step.to.z], t, executed: t <= b + 1e-9 });
        }
    }
    footholds
}

/// The replay overlay of a trial's plans (see the module docs); `terrain` (the world)
/// places the ZMP and the support polygons on the ground; `end_time` is the end of the
/// trial.
pub fn plan_overlay(plans: &[PlanRecord], terrain: &dyn Terrain, end_time: f64) -> ReplayOverlay {
    let windows = executed_windows(plans, end_time);
    let mut cog = OverlayPath { name: "planned CoG".into(), color: css(COG_COLOR), t: Vec::new(), points: Vec::new() };
    let mut zmp = OverlayPath { name: "planned ZMP (cart-table)".into(), color: css(ZMP_COLOR), t: Vec::new(), points: Vec::new() };
    let footholds = footholds_of(plans, windows.iter().map(|w| w.1));
    let mut supports = Vec::new();
    let on_ground = |p: &Point2<f64>| [p.x, p.y, terrain.height(p.x, p.y)];
    for (record, &(a, b)) in plans.iter().zip(&windows) {
        let plan = &record.plan;
        if b <= a {
            continue;
        }
        for t in sample_times(a, b, PATH_SAMPLE_INTERVAL) {
            cog.t.push(t);
            cog.points.push(planned_cog(plan, t));
            if let Some(z) = planned_zmp(plan, t) {
                zmp.t.push(t);
                zmp.points.push(on_ground(&z));
            }
        }
        for phase in plan.cog.phases() {
            let (t0, t1) = ((plan.start_time + phase.start_time).max(a), (plan.start_time + phase.end_time()).min(b));
            if t1 > t0 {
                supports.push(OverlaySupport {
                    t0,
                    t1,
                    polygon: phase.support.vertices().iter().map(on_ground).collect(),
                    shrunk: phase.shrunk_support.vertices().iter().map(on_ground).collect(),
                });
            }
        }
    }
    let paths = [cog, zmp].into_iter().filter(|p| !p.t.is_empty()).collect();
    ReplayOverlay { footholds, paths, supports }
}

/// Writes the walk's figures into `dir` (created if needed) and returns the files written:
/// `cog_zmp_support.svg` (Fig. 8) and `cog_tracking.svg`. `traj` is the executed motion of
/// `model` (for the actual CoG).
pub fn write_walk_plots(model: &Model, plans: &[PlanRecord], traj: &Trajectory, dir: impl AsRef<Path>) -> Result<Vec<PathBuf>, VizError> {
    traj.validate("trajectory")?;
    traj.check_against(model, "trajectory")?;
    let dir = dir.as_ref();
    std::fs::create_dir_all(dir).map_err(|e| VizError::io(dir, e))?;
    let end_time = traj.knots.last().map_or(0.0, |k| k.t);
    let windows = executed_windows(plans, end_time);
    let idx = super::signals::decimate(traj, MAX_POINTS);
    let mut data = Data::new(model);
    let actual: Vec<(f64, [f64; 3])> = idx
        .iter()
        .map(|&k| {
            let c = center_of_mass(model, &mut data, &DVector::from_column_slice(&traj.knots[k].q));
            (traj.knots[k].t, [c.x, c.y, c.z])
        })
        .collect();
    let mut planned: Vec<PlannedSample> = Vec::new();
    for (record, &(a, b)) in plans.iter().zip(&windows) {
        if b > a {
            planned.extend(sample_times(a, b, 0.5 * PATH_SAMPLE_INTERVAL).into_iter().map(|t| PlannedSample { t, cog: planned_cog(&record.plan, t), zmp: planned_zmp(&record.plan, t) }));
        }
    }
    let mut written = Vec::new();
    let path = dir.join("cog_zmp_support.svg");
    draw_fig8(&path, plans, &windows, &actual, &planned)?;
    written.push(path);
    // The horizontal tracking error where a plan ran.
    let error: Vec<(f64, f64)> = actual
        .iter()
        .filter_map(|&(t, c)| {
            let k = windows.iter().rposition(|&(a, b)| a <= t && t <= b && b > a)?;
            let p = planned_cog(&plans[k].plan, t);
            Some((t, 100.0 * ((c[0] - p[0]).powi(2) + (c[1] - p[1]).powi(2)).sqrt()))
        })
        .collect();
    let path = dir.join("cog_tracking.svg");
    draw_tracking(&path, &actual, &planned, &error)?;
    written.push(path);
    Ok(written)
}

/// The plan at one instant: CoG `[x, y, z]` and ZMP.
struct PlannedSample {
    t: f64,
    cog: [f64; 3],
    zmp: Option<Point2<f64>>,
}

/// Ranges around `points` with a margin, widened so that one metre is as long along x as
/// along y in a plotting area of `width` x `height` px.
fn equal_aspect(points: &[(f64, f64)], width: f64, height: f64) -> (Range<f64>, Range<f64>) {
    let (mut lo, mut hi) = ((f64::INFINITY, f64::INFINITY), (f64::NEG_INFINITY, f64::NEG_INFINITY));
    for &(x, y) in points.iter().filter(|(x, y)| x.is_finite() && y.is_finite()) {
        lo = (lo.0.min(x), lo.1.min(y));
        hi = (hi.0.max(x), hi.1.max(y));
    }
    if !lo.0.is_finite() {
        (lo, hi) = ((-1.0, -1.0), (1.0, 1.0));
    }
    let pad = 0.06 * (hi.0 - lo.0).max(hi.1 - lo.1).max(0.1);
    let (mut sx, mut sy) = (hi.0 - lo.0 + 2.0 * pad, hi.1 - lo.1 + 2.0 * pad);
    let (cx, cy) = (0.5 * (lo.0 + hi.0), 0.5 * (lo.1 + hi.1));
    // Metres per pixel along each axis must match: widen the tighter one.
    if sx / width > sy / height {
        sy = sx * height / width;
    } else {
        sx = sy * width / height;
    }
    ((cx - 0.5 * sx)..(cx + 0.5 * sx), (cy - 0.5 * sy)..(cy + 0.5 * sy))
}

/// What the x-y panels of [`draw_fig8`] take from their width and height for margins, labels
/// and the caption (px, about).
const XY_MARGINS: (u32, u32) = (96, 86);

/// Plotting area of an x-y panel of `width` x `height` px.
fn plot_area(width: u32, height: u32) -> (f64, f64) {
    (width.saturating_sub(XY_MARGINS.0).max(1) as f64, height.saturating_sub(XY_MARGINS.1).max(1) as f64)
}

/// Winkler 2015, Fig. 8 (see the module docs).
fn draw_fig8(path: &Path, plans: &[PlanRecord], windows: &[(f64, f64)], actual: &[(f64, [f64; 3])], planned: &[PlannedSample]) -> Result<(), VizError> {
    let err = |e: &dyn std::fmt::Display| plot_error(path, e);
    // Top: the walk from above.
    let footholds = footholds_of(plans, windows.iter().map(|w| w.1));
    let mut extent: Vec<(f64, f64)> = actual.iter().map(|(_, p)| (p[0], p[1])).collect();
    extent.extend(planned.iter().map(|p| (p.cog[0], p.cog[1])));
    extent.extend(footholds.iter().map(|f| (f.position[0], f.position[1])));
    // The panel's height follows the walk's extent at one scale (at least a quarter of its
    // width), within one to two panel heights.
    let (w, _) = plot_area(WIDTH, 0);
    let (xr, yr) = equal_aspect(&extent, w, 0.25 * w);
    let top_h = ((w * (yr.end - yr.start) / (xr.end - xr.start)) as u32 + XY_MARGINS.1).clamp(PANEL_HEIGHT, 2 * PANEL_HEIGHT);
    let bottom_h = 3 * PANEL_HEIGHT;
    let (w, h) = plot_area(WIDTH, top_h);
    let (xr, yr) = equal_aspect(&extent, w, h);
    let root = SVGBackend::new(path, (WIDTH, top_h + bottom_h)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let (top, bottom) = root.split_vertically(top_h);
    let mut chart = ChartBuilder::on(&top)
        .caption("The walk from above: CoG (actual, planned) and planned footholds", (FONT, 20))
        .margin(8)
        .margin_right(20)
        .x_label_area_size(38)
        .y_label_area_size(60)
        .build_cartesian_2d(xr, yr)
        .map_err(|e| err(&e))?;
    house_style(&mut chart.configure_mesh()).x_desc("x [m]").y_desc("y [m]").draw().map_err(|e| err(&e))?;
    for (leg, name) in LEG_ORDER.iter().enumerate() {
        let color = LEG_COLORS[leg];
        let done = footholds.iter().filter(|f| f.foot == leg && f.executed).map(|f| Circle::new((f.position[0], f.position[1]), 4, color.filled()));
        chart.draw_series(done).map_err(|e| err(&e))?.label(format!("{name} foothold")).legend(move |(x, y)| Circle::new((x + 9, y), 4, color.filled()));
        let replaced = footholds.iter().filter(|f| f.foot == leg && !f.executed).map(|f| Circle::new((f.position[0], f.position[1]), 4, color.stroke_width(1)));
        chart.draw_series(replaced).map_err(|e| err(&e))?;
    }
    // The plan wide and light under the actual CoG, so that both show where they agree.
    for (k, segment) in split_by_window(planned, windows).into_iter().enumerate() {
        let series = chart.draw_series(LineSeries::new(segment.iter().map(|p| (p.cog[0], p.cog[1])), COG_COLOR.mix(0.55).stroke_width(5))).map_err(|e| err(&e))?;
        if k == 0 {
            series.label("planned CoG").legend(|(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], COG_COLOR.mix(0.55).stroke_width(5)));
        }
    }
    chart
        .draw_series(LineSeries::new(actual.iter().map(|(_, p)| (p[0], p[1])), BLACK.stroke_width(1)))
        .map_err(|e| err(&e))?
        .label("actual CoG")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], BLACK.stroke_width(2)));
    chart.configure_series_labels().position(SeriesLabelPosition::UpperLeft).background_style(WHITE.mix(0.85)).border_style(RGBColor(190, 196, 204)).label_font((FONT, 13)).draw().map_err(|e| err(&e))?;

    // Bottom: the first plan's first phases.
    let Some(first) = plans.first() else {
        bottom.titled("no plan was made", (FONT, 20)).map_err(|e| err(&e))?;
        return root.present().map_err(|e| err(&e));
    };
    let plan = &first.plan;
    let phases = plan.cog.phases();
    let from = phases.iter().position(|p| p.phase.swing_leg().is_some()).unwrap_or(0);
    let mut shown: Vec<usize> = Vec::new();
    let mut swings = 0;
    for (k, phase) in phases.iter().enumerate().skip(from) {
        if swings == FIG8_SWINGS {
            break;
        }
        shown.push(k);
        swings += usize::from(phase.phase.swing_leg().is_some());
    }
    let samples = |k: usize, dt: f64| {
        let p = &phases[k];
        sample_times(plan.start_time + p.start_time, plan.start_time + p.end_time(), dt)
    };
    let mut extent: Vec<(f64, f64)> = Vec::new();
    for &k in &shown {
        extent.extend(phases[k].support.vertices().iter().map(|v| (v.x, v.y)));
        extent.extend(samples(k, PATH_SAMPLE_INTERVAL).into_iter().map(|t| planned_cog(plan, t)).map(|c| (c[0], c[1])));
    }
    let (w, h) = plot_area(WIDTH, bottom_h);
    let (xr, yr) = equal_aspect(&extent, w, h);
    let (t0, t1) = shown.first().zip(shown.last()).map_or((0.0, 0.0), |(&a, &b)| (plan.start_time + phases[a].start_time, plan.start_time + phases[b].end_time()));
    let mut chart = ChartBuilder::on(&bottom)
        .caption(format!("First plan, t = {t0:.2}..{t1:.2} s: shrunk support polygons, planned CoG (line) and ZMP (x) (Winkler 2015, Fig. 8)"), (FONT, 18))
        .margin(8)
        .margin_right(20)
        .x_label_area_size(38)
        .y_label_area_size(60)
        .build_cartesian_2d(xr, yr)
        .map_err(|e| err(&e))?;
    house_style(&mut chart.configure_mesh()).x_desc("x [m]").y_desc("y [m]").draw().map_err(|e| err(&e))?;
    let mut next_color = 0;
    for &k in &shown {
        let phase = &phases[k];
        let inserted = matches!(phase.origin, PhaseOrigin::Inserted { .. });
        let color = if inserted {
            FOUR_LEG_COLOR
        } else {
            next_color += 1;
            PHASE_COLORS[(next_color - 1) % PHASE_COLORS.len()]
        };
        let ring = |v: &[Point2<f64>]| v.iter().chain(v.first()).map(|p| (p.x, p.y)).collect::<Vec<_>>();
        let hull = ring(phase.support.vertices());
        chart.draw_series(std::iter::once(DashedPathElement::new(hull, 5, 4, color.mix(0.6).stroke_width(1)))).map_err(|e| err(&e))?;
        let shrunk: Vec<(f64, f64)> = phase.shrunk_support.vertices().iter().map(|p| (p.x, p.y)).collect();
        if shrunk.len() >= 3 {
            chart.draw_series(std::iter::once(Polygon::new(shrunk.clone(), color.mix(0.1).filled()))).map_err(|e| err(&e))?;
            chart.draw_series(std::iter::once(PathElement::new(ring(phase.shrunk_support.vertices()), color.stroke_width(2)))).map_err(|e| err(&e))?;
        }
        let label = match (phase.phase.swing_leg(), inserted) {
            (_, true) => format!("phase {k}: four-leg support (inserted)"),
            (Some(leg), _) => format!("phase {k}: {} swings", leg.name()),
            (None, _) => format!("phase {k}: four-leg support"),
        };
        let cog: Vec<(f64, f64)> = samples(k, 0.5 * PATH_SAMPLE_INTERVAL).into_iter().map(|t| planned_cog(plan, t)).map(|c| (c[0], c[1])).collect();
        chart
            .draw_series(LineSeries::new(cog, color.stroke_width(3)))
            .map_err(|e| err(&e))?
            .label(label)
            .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 18, y + 5)], color.mix(0.5).filled()));
        // The ZMP samples carry no label: the legend's entries are the phases.
        let zmp: Vec<(f64, f64)> = samples(k, PATH_SAMPLE_INTERVAL).into_iter().filter_map(|t| planned_zmp(plan, t)).map(|z| (z.x, z.y)).collect();
        chart.draw_series(zmp.into_iter().map(|p| Cross::new(p, 4, color.stroke_width(2)))).map_err(|e| err(&e))?;
    }
    chart.configure_series_labels().position(SeriesLabelPosition::UpperLeft).background_style(WHITE.mix(0.85)).border_style(RGBColor(190, 196, 204)).label_font((FONT, 13)).draw().map_err(|e| err(&e))?;
    root.present().map_err(|e| err(&e))
}

/// The planned samples of each window, in order (a re-plan starts a new line).
fn split_by_window<'a>(planned: &'a [PlannedSample], windows: &[(f64, f64)]) -> Vec<&'a [PlannedSample]> {
    let mut out = Vec::new();
    let mut rest = planned;
    for &(a, b) in windows.iter().filter(|(a, b)| b > a) {
        let n = sample_times(a, b, 0.5 * PATH_SAMPLE_INTERVAL).len().min(rest.len());
        out.push(&rest[..n]);
        rest = &rest[n..];
    }
    out
}

/// CoG x and y against time (actual, planned, and the planned ZMP), and the horizontal
/// tracking error `error` (cm).
fn draw_tracking(path: &Path, actual: &[(f64, [f64; 3])], planned: &[PlannedSample], error: &[(f64, f64)]) -> Result<(), VizError> {
    let err = |e: &dyn std::fmt::Display| plot_error(path, e);
    let root = SVGBackend::new(path, (WIDTH, 3 * PANEL_HEIGHT)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let areas = root.split_evenly((3, 1));
    let t: Vec<f64> = actual.iter().map(|a| a.0).collect();
    for (axis, (area, name)) in areas.iter().zip(["x", "y"]).enumerate() {
        let values = actual.iter().map(|a| &a.1[axis]).chain(planned.iter().map(|p| &p.cog[axis])).chain(planned.iter().filter_map(|p| p.zmp.as_ref().map(|z| &z.coords[axis])));
        let y_range = value_range(values);
        let mut chart = ChartBuilder::on(area)
            .caption(format!("CoG {name}: planned and actual"), (FONT, 20))
            .margin(8)
            .margin_right(20)
            .x_label_area_size(38)
            .y_label_area_size(70)
            .build_cartesian_2d(time_range(&t), y_range)
            .map_err(|e| err(&e))?;
        house_style(&mut chart.configure_mesh()).y_desc(format!("{name} [m]")).draw().map_err(|e| err(&e))?;
        chart
            .draw_series(LineSeries::new(planned.iter().filter_map(|p| p.zmp.map(|z| (p.t, z.coords[axis]))), ZMP_COLOR.mix(0.7).stroke_width(1)))
            .map_err(|e| err(&e))?
            .label("planned ZMP")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], ZMP_COLOR.stroke_width(2)));
        chart
            .draw_series(LineSeries::new(planned.iter().map(|p| (p.t, p.cog[axis])), COG_COLOR.mix(0.55).stroke_width(5)))
            .map_err(|e| err(&e))?
            .label("planned CoG")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], COG_COLOR.mix(0.55).stroke_width(5)));
        chart
            .draw_series(LineSeries::new(actual.iter().map(|a| (a.0, a.1[axis])), BLACK.stroke_width(1)))
            .map_err(|e| err(&e))?
            .label("actual CoG")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], BLACK.stroke_width(2)));
        chart.configure_series_labels().position(SeriesLabelPosition::UpperLeft).background_style(WHITE.mix(0.85)).border_style(RGBColor(190, 196, 204)).label_font((FONT, 14)).draw().map_err(|e| err(&e))?;
    }
    let worst = error.iter().map(|e| e.1).fold(0.0, f64::max);
    let mut chart = ChartBuilder::on(&areas[2])
        .caption(format!("CoG tracking error, horizontal (largest {worst:.1} cm)"), (FONT, 20))
        .margin(8)
        .margin_right(20)
        .x_label_area_size(38)
        .y_label_area_size(70)
        .build_cartesian_2d(time_range(&t), 0.0..(1.06 * worst).max(0.1))
        .map_err(|e| err(&e))?;
    house_style(&mut chart.configure_mesh()).y_desc("[cm]").draw().map_err(|e| err(&e))?;
    chart.draw_series(LineSeries::new(error.iter().copied(), PALETTE[3].stroke_width(2))).map_err(|e| err(&e))?;
    root.present().map_err(|e| err(&e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn samples_cover_both_ends() {
        assert_eq!(sample_times(1.0, 1.05, 0.02), vec![1.0, 1.02, 1.04, 1.05]);
        assert_eq!(sample_times(2.0, 2.0, 0.02), vec![2.0]);
    }

    #[test]
    fn equal_aspect_keeps_metres_square() {
        let (x, y) = equal_aspect(&[(0.0, 0.0), (3.0, 0.5)], 800.0, 400.0);
        let (sx, sy) = (x.end - x.start, y.end - y.start);
        assert!((sx / 800.0 - sy / 400.0).abs() < 1e-12);
        assert!(x.start < 0.0 && x.end > 3.0 && y.start < 0.0 && y.end > 0.5);
        assert!((0.5 * (y.start + y.end) - 0.25).abs() < 1e-12);
    }
}
