//! The HTML replay: one self-contained page (`replay.html`) that plays a trajectory back.
//!
//! Everything the page draws is computed here, with legwork's forward kinematics: for each
//! displayed instant (the knots thinned to at most [`MAX_FRAME_RATE`] frames per second),
//! the world position of every joint origin, of every foot and of the 8 corners of a box
//! standing for the trunk (sized from the hip positions), the contact forces and flags, and
//! the ground height under the base (for the shadow). The links are drawn as capsules from
//! each joint's origin to its child joints' origins and to the feet. The terrain of
//! `metadata.terrain` is sampled on a grid around the motion (a shaded mesh, a few thousand
//! cells at most). The page (`replay.html` beside this file, Canvas 2D and plain
//! JavaScript, inlined) projects and draws that; it has no kinematics of its own and loads
//! nothing from anywhere.
//!
//! An optional [`ReplayOverlay`] ([`replay_html_with_overlay`]) adds what a planner
//! intended to the scene: planned footholds coloured by foot, time-stamped paths (a
//! planned CoG, its ZMP) with a marker at the current instant, and the support polygon in
//! use at each instant (as planned, and shrunk by a stability margin). A page without one
//! reads as before: the overlay is an optional field of the page's data.
//!
//! ```
//! use legwork::{io::Trajectory, model::embedded, terrain::TerrainSpec, viz};
//! let model = embedded::load("a1").unwrap();
//! let q = model.reference_configuration("standing").unwrap();
//! let mut traj = Trajectory::new(&model, "stand", 0.01, TerrainSpec::flat());
//! for k in 0..3 {
//!     traj.knots.push(legwork::io::Knot {
//!         t: 0.01 * k as f64, q: q.as_slice().to_vec(), v: vec![0.0; 18], tau: vec![0.0; 12],
//!         contact_force: vec![[0.0, 0.0, 33.7]; 4], in_contact: vec![true; 4], feedback_gain: None,
//!     });
//! }
//! let html = viz::replay_html(&model, &traj).unwrap();
//! assert!(html.starts_with("<!DOCTYPE html>") && !html.contains("https://"));
//! ```

use super::signals::{self, Panel};
use super::VizError;
use crate::dynamics::{forward_kinematics, update_frame_placements, Data};
use crate::io::{Trajectory, TrajectoryError};
use crate::model::{Model, STANDARD_GRAVITY};
use crate::terrain::Terrain;
use nalgebra::{DVector, Vector3};
use serde::Serialize;
use std::path::Path;

/// The page, with [`DATA_SLOT`] where the data goes.
const TEMPLATE: &str = include_str!("replay.html");
/// Placeholder in the template's `<script type="application/json">` element.
const DATA_SLOT: &str = "/*LEGWORK_DATA*/";

/// At most this many frames per second of motion go into the page for the 3D view.
pub const MAX_FRAME_RATE: f64 = 100.0;
/// At most this many samples per curve go into the page's plots.
const MAX_PLOT_POINTS: usize = 1500;
/// At most this many terrain cells along each side of the displayed patch.
const MAX_TERRAIN_CELLS: usize = 90;

/// The replay page of `traj` played by `model`, as one HTML string with everything inline.
///
/// Checks the trajectory first ([`Trajectory::validate`], [`Trajectory::check_against`]):
/// a trajectory that does not fit the model is an error, not a panic.
pub fn replay_html(model: &Model, traj: &Trajectory) -> Result<String, VizError> {
    replay_html_with_overlay(model, traj, None)
}

/// [`replay_html`] with `overlay` drawn over the scene (checked first: finite numbers, feet
/// of the model, one time per path point).
pub fn replay_html_with_overlay(model: &Model, traj: &Trajectory, overlay: Option<&ReplayOverlay>) -> Result<String, VizError> {
    traj.validate("trajectory")?;
    traj.check_against(model, "trajectory")?;
    if !model.has_free_flyer() || model.nq != traj.knots[0].q.len() {
        return Err(TrajectoryError::Invalid {
            origin: "trajectory".into(),
            field: "metadata.robot".into(),
            problem: format!("robot '{}' has no free-flying base, and trajectory files describe floating-base robots (q = [base position, quaternion, joints])", model.name),
        }
        .into());
    }
    if let Some(overlay) = overlay {
        overlay.validate(traj.metadata.foot_names.len())?;
    }
    let terrain = traj.metadata.terrain.build("metadata.terrain")?;
    let data = ReplayData::new(model, traj, terrain.as_ref(), overlay);
    let json = serde_json::to_string(&data).map_err(|e| VizError::Io { path: "replay data".into(), source: e.into() })?;
    // In JSON, `<` only occurs inside strings, where `\u003c` means the same: no name in
    // the file can close the <script> element the data sits in.
    let json = json.replace('<', "\\u003c");
    Ok(TEMPLATE.replacen(DATA_SLOT, &json, 1))
}

/// Writes [`replay_html`] to `path` (creating its folder if needed).
pub fn write_replay(model: &Model, traj: &Trajectory, path: impl AsRef<Path>) -> Result<(), VizError> {
    write_replay_with_overlay(model, traj, None, path)
}

/// Writes [`replay_html_with_overlay`] to `path` (creating its folder if needed).
pub fn write_replay_with_overlay(model: &Model, traj: &Trajectory, overlay: Option<&ReplayOverlay>, path: impl AsRef<Path>) -> Result<(), VizError> {
    let path = path.as_ref();
    let html = replay_html_with_overlay(model, traj, overlay)?;
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| VizError::io(dir, e))?;
    }
    std::fs::write(path, html).map_err(|e| VizError::io(path, e))
}

/// Everything the page reads, serialised as JSON into it.
#[derive(Serialize)]
struct ReplayData {
    robot: String,
    scenario: String,
    legwork_version: String,
    /// The run's verdict (`met`, `missed`, ...), if its summary has one.
    verdict: Option<String>,
    /// The summary's target checks as a table (runs side by side), if it has them.
    targets: Option<TargetTable>,
    /// The whole summary, pretty-printed, for the page's disclosure.
    summary_json: String,
    foot_names: Vec<String>,
    skeleton: Skeleton,
    frames: Frames,
    /// Length of a force arrow per newton (m/N), and the same in words.
    force_scale: f64,
    force_scale_label: String,
    terrain: TerrainPatch,
    plot_t: Vec<f64>,
    plots: Vec<PlotData>,
    /// Absent when there is nothing to overlay (pages written before overlays existed read
    /// the same).
    #[serde(skip_serializing_if = "Option::is_none")]
    overlay: Option<ReplayOverlay>,
}

/// The target checks of a summary (`summary.target`: run name -> the checks' results, or
/// "failed"), one row per check of the first run, one column per run.
#[derive(Clone, Debug, PartialEq, Serialize)]
struct TargetTable {
    runs: Vec<String>,
    rows: Vec<TargetRow>,
}

#[derive(Clone, Debug, PartialEq, Serialize)]
struct TargetRow {
    what: String,
    required: String,
    /// Per run: the value and whether it is met; `None` where the run failed or lacks the check.
    cells: Vec<Option<(String, bool)>>,
}

impl TargetTable {
    /// The table of `summary["target"]`, if it holds checks in the shape `legwork solve`
    /// writes them (`legwork::ocp::TargetResult`).
    fn of(summary: &serde_json::Map<String, serde_json::Value>) -> Option<Self> {
        let runs = summary.get("target")?.as_object()?;
        /// One check of one run, as `summary.target` holds it.
        struct Check<'j> {
            what: &'j str,
            required: &'j str,
            value: &'j str,
            met: bool,
        }
        fn checks(v: &serde_json::Value) -> Option<Vec<Check<'_>>> {
            v.as_array()?.iter().map(|r| Some(Check { what: r.get("what")?.as_str()?, required: r.get("required")?.as_str()?, value: r.get("value")?.as_str()?, met: r.get("met")?.as_bool()? })).collect()
        }
        let columns: Vec<Option<Vec<Check>>> = runs.values().map(checks).collect();
        let first = columns.iter().find_map(Option::as_ref)?;
        let rows = first
            .iter()
            .map(|check| TargetRow {
                what: check.what.to_string(),
                required: check.required.to_string(),
                cells: columns.iter().map(|c| c.as_ref().and_then(|c| c.iter().find(|r| r.what == check.what)).map(|r| (r.value.to_string(), r.met))).collect(),
            })
            .collect();
        Some(Self { runs: runs.keys().cloned().collect(), rows })
    }
}

/// What a planner intended, drawn over the replay's scene (all in the world frame, m and s).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct ReplayOverlay {
    /// Planned footholds.
    pub footholds: Vec<OverlayFoothold>,
    /// Paths drawn as lines, with a marker at the current instant while it lies within them.
    pub paths: Vec<OverlayPath>,
    /// Support polygons, each shown while it is in use.
    pub supports: Vec<OverlaySupport>,
}

/// A planned foothold: where foot `foot` (an index into the trajectory's `foot_names`) is
/// to touch down, and when.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct OverlayFoothold {
    pub foot: usize,
    /// Surface point `[x, y, z]`.
    pub position: [f64; 3],
    /// Planned touch-down time (s).
    pub t: f64,
    /// False when a later plan replaced this one before the foot got there (drawn hollow).
    pub executed: bool,
}

/// A time-stamped path: `points[i]` at time `t[i]` (increasing).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct OverlayPath {
    /// Legend text.
    pub name: String,
    /// CSS colour (`#rrggbb`).
    pub color: String,
    pub t: Vec<f64>,
    pub points: Vec<[f64; 3]>,
}

/// A support polygon in use from `t0` to `t1`: the hull of the stance feet, and the region
/// the ZMP is kept in (the hull shrunk by the stability margin; may be empty).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct OverlaySupport {
    pub t0: f64,
    pub t1: f64,
    pub polygon: Vec<[f64; 3]>,
    pub shrunk: Vec<[f64; 3]>,
}

impl ReplayOverlay {
    /// Checks what the page relies on: finite numbers, feet among the `n_feet` of the
    /// trajectory, one time per path point and increasing times, `t0 <= t1`.
    pub fn validate(&self, n_feet: usize) -> Result<(), VizError> {
        let bad = |field: String, problem: String| VizError::Overlay { field, problem };
        let finite = |field: &dyn Fn() -> String, values: &[f64]| match values.iter().find(|v| !v.is_finite()) {
            Some(v) => Err(bad(field(), format!("expected finite numbers, got {v}"))),
            None => Ok(()),
        };
        for (i, f) in self.footholds.iter().enumerate() {
            if f.foot >= n_feet {
                return Err(bad(format!("footholds[{i}].foot"), format!("expected a foot index below {n_feet}, got {}", f.foot)));
            }
            finite(&|| format!("footholds[{i}]"), &[f.position[0], f.position[1], f.position[2], f.t])?;
        }
        for (i, p) in self.paths.iter().enumerate() {
            if p.t.len() != p.points.len() {
                return Err(bad(format!("paths[{i}].t"), format!("expected one time per point ({}), got {}", p.points.len(), p.t.len())));
            }
            finite(&|| format!("paths[{i}].t"), &p.t)?;
            finite(&|| format!("paths[{i}].points"), p.points.as_flattened())?;
            if let Some(k) = p.t.windows(2).position(|w| w[1] < w[0]) {
                return Err(bad(format!("paths[{i}].t[{}]", k + 1), format!("expected increasing times, got {} after {}", p.t[k + 1], p.t[k])));
            }
        }
        for (i, s) in self.supports.iter().enumerate() {
            finite(&|| format!("supports[{i}]"), &[s.t0, s.t1])?;
            finite(&|| format!("supports[{i}].polygon"), s.polygon.as_flattened())?;
            finite(&|| format!("supports[{i}].shrunk"), s.shrunk.as_flattened())?;
            if s.t1 < s.t0 {
                return Err(bad(format!("supports[{i}].t1"), format!("expected t1 >= t0 = {}, got {}", s.t0, s.t1)));
            }
        }
        Ok(())
    }

    /// Every point of the overlay (for the extent of the terrain patch).
    fn points(&self) -> impl Iterator<Item = Vector3<f64>> + '_ {
        let footholds = self.footholds.iter().map(|f| f.position);
        let paths = self.paths.iter().flat_map(|p| p.points.iter().copied());
        let supports = self.supports.iter().flat_map(|s| s.polygon.iter().copied());
        footholds.chain(paths).chain(supports).map(Vector3::from)
    }

    /// The overlay with its numbers rounded for the page (mm and ms are enough).
    fn rounded(&self) -> Self {
        let p3 = |p: &[f64; 3]| p.map(|x| round(x, 3));
        let ps = |v: &[[f64; 3]]| v.iter().map(p3).collect::<Vec<_>>();
        ReplayOverlay {
            footholds: self.footholds.iter().map(|f| OverlayFoothold { position: p3(&f.position), t: round(f.t, 3), ..f.clone() }).collect(),
            paths: self.paths.iter().map(|p| OverlayPath { name: p.name.clone(), color: p.color.clone(), t: p.t.iter().map(|t| round(*t, 3)).collect(), points: ps(&p.points) }).collect(),
            supports: self.supports.iter().map(|s| OverlaySupport { t0: round(s.t0, 3), t1: round(s.t1, 3), polygon: ps(&s.polygon), shrunk: ps(&s.shrunk) }).collect(),
        }
    }
}

/// How the page joins the points of a frame into a robot. Points, per frame: joint origins
/// `0..njoints` (0 is the world origin), then the feet, then the 8 trunk corners (corner
/// `c` at `+-x` by bit 0, `+-y` by bit 1, `+-z` by bit 2 in the base frame).
#[derive(Serialize)]
struct Skeleton {
    n_points: usize,
    /// Capsules `[from, to, side]`, side 0 left, 1 right, 2 middle.
    links: Vec<[usize; 3]>,
    link_radius: f64,
    /// Points drawn as joint knobs.
    joints: Vec<usize>,
    feet: Vec<usize>,
    foot_radius: f64,
    trunk: [usize; 8],
    base: usize,
    /// A length that sets the default camera distance (body length, m).
    size: f64,
}

/// The displayed instants.
#[derive(Serialize)]
struct Frames {
    t: Vec<f64>,
    /// `[x, y, z]` of every skeleton point, flat, per frame.
    points: Vec<Vec<f64>>,
    /// `[fx, fy, fz]` of every foot, flat, per frame (N, world).
    forces: Vec<Vec<f64>>,
    contact: Vec<Vec<u8>>,
    /// Ground height under the base.
    ground: Vec<f64>,
}

/// Heights `z[j * nx + i]` at `(x0 + i dx, y0 + j dx)`; a checkerboard of squares of side
/// `checker` painted on it (so that motion over the ground shows).
#[derive(Serialize)]
struct TerrainPatch {
    kind: &'static str,
    checker: f64,
    x0: f64,
    y0: f64,
    dx: f64,
    nx: usize,
    ny: usize,
    z: Vec<f64>,
    /// Boxes on the ground, `[x0, x1, y0, y1, z0, z1]` (drawn as solids over the grid).
    boxes: Vec<[f64; 6]>,
}

#[derive(Serialize)]
struct PlotData {
    title: String,
    unit: String,
    series: Vec<SeriesData>,
}

#[derive(Serialize)]
struct SeriesData {
    name: String,
    y: Vec<f64>,
}

/// `x` rounded to `decimals` places (and `-0` written `0`): the page needs no more.
fn round(x: f64, decimals: i32) -> f64 {
    let s = 10f64.powi(decimals);
    (x * s).round() / s + 0.0
}

/// A 1-2-5 number at most `x` (for scales and grid steps people read).
fn nice_floor(x: f64) -> f64 {
    let e = 10f64.powf(x.log10().floor());
    [5.0, 2.0, 1.0].into_iter().map(|m| m * e).find(|&v| v <= x * (1.0 + 1e-9)).unwrap_or(e)
}

/// The fixed parts of the drawing, from the model alone.
struct Sketch {
    skeleton: Skeleton,
    /// Base joint (1 for a free flyer, 0 for a fixed base).
    base: usize,
    /// Trunk box corners in the base frame.
    corners: [Vector3<f64>; 8],
    /// Base height over the lowest foot-sphere bottom in the standing pose (m).
    stance_height: f64,
}

impl Sketch {
    fn new(model: &Model, data: &mut Data) -> Self {
        let nj = model.njoints();
        let base = usize::from(model.has_free_flyer());
        let hips: Vec<usize> = (1..nj).filter(|&i| i != base && model.joints[i].parent == base).collect();
        // Which side of the body each joint is on: that of the hip it hangs from.
        let mut side = vec![2usize; nj];
        for i in 1..nj {
            let p = model.joints[i].parent;
            side[i] = if p == base {
                let y = model.joints[i].placement.translation.y;
                if y > 1e-6 { 0 } else if y < -1e-6 { 1 } else { 2 }
            } else {
                side[p]
            };
        }
        let mut links: Vec<[usize; 3]> = (1..nj)
            .filter(|&i| i != base && model.joints[i].parent != base)
            .map(|i| [model.joints[i].parent, i, side[i]])
            .collect();
        let foot_radius = model.feet.iter().map(|f| f.radius).fold(0.0, f64::max);
        let feet: Vec<usize> = (0..model.feet.len()).map(|k| nj + k).collect();
        for (k, foot) in model.feet.iter().enumerate() {
            let parent = model.frames[foot.frame].parent_joint;
            if parent != base {
                links.push([parent, nj + k, side[parent]]);
            }
        }

        // Sizes from the standing pose (or the neutral one).
        let q = model.reference_configuration("standing").cloned().unwrap_or_else(|| model.neutral());
        forward_kinematics(model, data, &q);
        update_frame_placements(model, data);
        let point = |i: usize, data: &Data| {
            if i < nj {
                data.o_m_i[i].translation
            } else {
                data.o_m_f[model.feet[i - nj].frame].translation
            }
        };
        let mut lengths: Vec<f64> = links.iter().map(|l| (point(l[1], data) - point(l[0], data)).norm()).collect();
        lengths.sort_by(f64::total_cmp);
        let typical_link = lengths.get(lengths.len() / 2).copied().filter(|&l| l > 1e-3).unwrap_or(0.2);

        let hip_xy: Vec<Vector3<f64>> = hips.iter().map(|&h| model.joints[h].placement.translation).collect();
        let (lo, hi) = hip_xy.iter().fold((Vector3::repeat(f64::INFINITY), Vector3::repeat(f64::NEG_INFINITY)), |(lo, hi), p| (lo.inf(p), hi.sup(p)));
        let (centre, half) = if hip_xy.len() >= 2 && hi.x - lo.x > 1e-3 {
            let length = hi.x - lo.x;
            let hx = 0.56 * length;
            let hy = (0.45 * (hi.y - lo.y)).max(0.2 * length);
            let hz = (0.55 * hy).max(0.12 * length);
            (Vector3::new(0.5 * (lo.x + hi.x), 0.5 * (lo.y + hi.y), 0.5 * (lo.z + hi.z)), Vector3::new(hx, hy, hz))
        } else {
            (Vector3::zeros(), Vector3::new(1.0, 0.5, 0.3) * typical_link * 0.5)
        };
        let corners = std::array::from_fn(|c| {
            let s = |bit: usize| if c & (1 << bit) != 0 { 1.0 } else { -1.0 };
            centre + Vector3::new(s(0) * half.x, s(1) * half.y, s(2) * half.z)
        });

        let base_z = data.o_m_i[base].translation.z;
        let lowest = (0..model.feet.len()).map(|k| point(nj + k, data).z - model.feet[k].radius).fold(f64::INFINITY, f64::min);
        let stance_height = if (base_z - lowest).is_finite() && base_z - lowest > 1e-2 { base_z - lowest } else { 2.0 * typical_link };

        let joints = (1..nj).filter(|&i| i != base).collect();
        let skeleton = Skeleton {
            n_points: nj + model.feet.len() + 8,
            links,
            link_radius: round((0.08 * typical_link).clamp(0.005, 0.06), 4),
            joints,
            feet,
            foot_radius: round(if foot_radius > 0.0 { foot_radius } else { 0.1 * typical_link }, 4),
            trunk: std::array::from_fn(|c| nj + model.feet.len() + c),
            base,
            size: round((2.0 * half.x).max(stance_height), 3),
        };
        Sketch { skeleton, base, corners, stance_height }
    }

    /// World positions of every skeleton point for configuration `q` (flat `[x, y, z]`).
    fn points(&self, model: &Model, data: &mut Data, q: &DVector<f64>) -> Vec<Vector3<f64>> {
        forward_kinematics(model, data, q);
        update_frame_placements(model, data);
        let mut pts: Vec<Vector3<f64>> = data.o_m_i.iter().map(|m| m.translation).collect();
        pts.extend(model.feet.iter().map(|f| data.o_m_f[f.frame].translation));
        let base = &data.o_m_i[self.base];
        pts.extend(self.corners.iter().map(|c| base.act_point(c)));
        pts
    }
}

impl ReplayData {
    fn new(model: &Model, traj: &Trajectory, terrain: &dyn Terrain, overlay: Option<&ReplayOverlay>) -> Self {
        let mut data = Data::new(model);
        let sketch = Sketch::new(model, &mut data);
        // 3D frames.
        let idx = signals::sample_indices(&traj.knots, 1.0 / MAX_FRAME_RATE);
        let mut frames = Frames { t: Vec::new(), points: Vec::new(), forces: Vec::new(), contact: Vec::new(), ground: Vec::new() };
        let (mut lo, mut hi) = (Vector3::repeat(f64::INFINITY), Vector3::repeat(f64::NEG_INFINITY));
        for &k in &idx {
            let knot = &traj.knots[k];
            let pts = sketch.points(model, &mut data, &DVector::from_column_slice(&knot.q));
            for p in &pts[1..] {
                (lo, hi) = (lo.inf(p), hi.sup(p));
            }
            let b = pts[sketch.base];
            frames.t.push(round(knot.t, 4));
            frames.points.push(pts.iter().flat_map(|p| p.iter().map(|x| round(*x, 3)).collect::<Vec<_>>()).collect());
            frames.forces.push(knot.contact_force.iter().flatten().map(|f| round(*f, 1)).collect());
            frames.contact.push(knot.in_contact.iter().map(|&c| u8::from(c)).collect());
            frames.ground.push(round(terrain.height(b.x, b.y), 3));
        }
        // The terrain patch also covers what the overlay draws (footholds of plans the robot
        // did not finish).
        for p in overlay.into_iter().flat_map(|o| o.points()) {
            (lo, hi) = (lo.inf(&p), hi.sup(&p));
        }

        // Force arrows: the robot's weight is drawn about as long as the stance height.
        let weight = model.total_mass() * STANDARD_GRAVITY;
        let force_scale = if weight > 0.0 { nice_floor(sketch.stance_height / weight) } else { 1e-3 };
        let force_scale_label = if force_scale >= 1e-3 {
            format!("{} mm per N", round(force_scale * 1e3, 3))
        } else {
            format!("1 mm per {} N", round(1e-3 / force_scale, 1))
        };

        // Plots.
        let pidx = signals::decimate(traj, MAX_PLOT_POINTS);
        let all_joints: Vec<usize> = (0..traj.metadata.joint_names.len()).collect();
        let mut panels = vec![
            signals::base_position(traj, &pidx),
            signals::base_orientation(traj, &pidx),
            signals::base_linear_velocity(traj, &pidx),
            signals::base_angular_velocity(traj, &pidx),
            signals::joint_torques(traj, &pidx, &all_joints, "Joint torques"),
        ];
        panels.push(normal_forces(model, &mut data, traj, &pidx, terrain));

        let summary_json = if traj.summary.is_empty() { String::new() } else { serde_json::to_string_pretty(&traj.summary).unwrap_or_default() };
        let m = &traj.metadata;
        ReplayData {
            robot: m.robot.clone(),
            scenario: m.scenario.clone(),
            legwork_version: m.legwork_version.clone(),
            verdict: traj.summary.get("verdict").and_then(|v| v.as_str()).map(String::from),
            targets: TargetTable::of(&traj.summary),
            summary_json,
            foot_names: m.foot_names.clone(),
            terrain: terrain_patch(terrain, &m.terrain, lo, hi, sketch.skeleton.size),
            skeleton: sketch.skeleton,
            frames,
            force_scale,
            force_scale_label,
            plot_t: signals::times(traj, &pidx).into_iter().map(|t| round(t, 4)).collect(),
            plots: panels.into_iter().map(plot_data).collect(),
            overlay: overlay.map(ReplayOverlay::rounded),
        }
    }
}

/// Normal component of each foot's contact force, the normal being the terrain's under the
/// foot (forward kinematics gives where the foot is).
fn normal_forces(model: &Model, data: &mut Data, traj: &Trajectory, idx: &[usize], terrain: &dyn Terrain) -> Panel {
    let nfeet = model.feet.len();
    let mut cols = vec![Vec::with_capacity(idx.len()); nfeet];
    for &k in idx {
        let knot = &traj.knots[k];
        forward_kinematics(model, data, &DVector::from_column_slice(&knot.q));
        update_frame_placements(model, data);
        for (f, foot) in model.feet.iter().enumerate() {
            let p = data.o_m_f[foot.frame].translation;
            let n = terrain.normal(p.x, p.y);
            cols[f].push(Vector3::from(knot.contact_force[f]).dot(&n));
        }
    }
    let series = traj.metadata.foot_names.iter().zip(cols).map(|(n, values)| signals::Series { name: n.clone(), values }).collect();
    Panel { title: "Contact normal forces".into(), unit: "N".into(), series }
}

/// Rounds a panel's values to about 4 significant digits of its largest value.
fn plot_data(panel: Panel) -> PlotData {
    let max = panel.series.iter().flat_map(|s| s.values.iter()).fold(0.0f64, |m, v| m.max(v.abs()));
    let decimals = if max > 0.0 { (4 - max.log10().ceil() as i32).clamp(0, 6) } else { 0 };
    PlotData {
        title: panel.title,
        unit: panel.unit,
        series: panel.series.into_iter().map(|s| SeriesData { name: s.name, y: s.values.iter().map(|v| round(*v, decimals)).collect() }).collect(),
    }
}

/// The terrain on a grid over the motion's footprint (`lo`, `hi`: bounds of every drawn
/// point) plus a margin: a plane on a grid of readable steps, a height map at its own
/// resolution unless that makes more than [`MAX_TERRAIN_CELLS`] cells along a side.
fn terrain_patch(terrain: &dyn Terrain, spec: &crate::terrain::TerrainSpec, lo: Vector3<f64>, hi: Vector3<f64>, size: f64) -> TerrainPatch {
    use crate::terrain::TerrainSpec;
    let (lo, hi) = if lo.x.is_finite() { (lo, hi) } else { (Vector3::zeros(), Vector3::zeros()) };
    let margin = (0.8 * size).max(0.5);
    let (x_lo, x_hi, y_lo, y_hi) = (lo.x - margin, hi.x + margin, lo.y - margin, hi.y + margin);
    let extent = (x_hi - x_lo).max(y_hi - y_lo);
    let checker = nice_floor(extent / 20.0);
    let (kind, dx) = match spec {
        TerrainSpec::Plane { .. } | TerrainSpec::Boxes { .. } => ("plane", checker),
        TerrainSpec::HeightMap(map) => ("height_map", map.resolution.max(extent / MAX_TERRAIN_CELLS as f64)),
    };
    // Boxes: the grid is their ground, the boxes are drawn as solids with sharp edges.
    let (ground, boxes) = match spec {
        TerrainSpec::Boxes { ground, boxes } => (Some(*ground), boxes.iter().map(|b| [b.x[0], b.x[1], b.y[0], b.y[1], *ground, b.top].map(|v| round(v, 4))).collect()),
        _ => (None, Vec::new()),
    };
    // Snap the grid to multiples of the step, so the checkerboard stays put on the ground.
    let (x0, y0) = ((x_lo / dx).floor() * dx, (y_lo / dx).floor() * dx);
    let nx = (((x_hi - x0) / dx).ceil() as usize + 1).clamp(2, MAX_TERRAIN_CELLS + 2);
    let ny = (((y_hi - y0) / dx).ceil() as usize + 1).clamp(2, MAX_TERRAIN_CELLS + 2);
    let mut z = Vec::with_capacity(nx * ny);
    for j in 0..ny {
        for i in 0..nx {
            z.push(round(ground.unwrap_or_else(|| terrain.height(x0 + i as f64 * dx, y0 + j as f64 * dx)), 3));
        }
    }
    TerrainPatch { kind, checker, x0: round(x0, 4), y0: round(y0, 4), dx: round(dx, 5), nx, ny, z, boxes }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nice_numbers_and_rounding() {
        assert_eq!(nice_floor(0.0007), 0.0005);
        assert_eq!(nice_floor(0.0023), 0.002);
        assert_eq!(nice_floor(1.0), 1.0);
        assert_eq!(nice_floor(0.99), 0.5);
        assert_eq!(round(-0.00001, 3).to_string(), "0");
        assert_eq!(round(1.23456, 2), 1.23);
    }

    #[test]
    fn overlay_checks_name_the_field() {
        let path = |t: Vec<f64>, n: usize| OverlayPath { name: "CoG".into(), color: "#8e24aa".into(), t, points: vec![[0.0, 0.0, 0.5]; n] };
        let good = ReplayOverlay {
            footholds: vec![OverlayFoothold { foot: 3, position: [0.3, -0.2, 0.0], t: 1.0, executed: true }],
            paths: vec![path(vec![0.0, 0.5, 0.5, 1.0], 4)],
            supports: vec![OverlaySupport { t0: 0.0, t1: 1.0, polygon: vec![[0.0, 0.0, 0.0]; 3], shrunk: Vec::new() }],
        };
        good.validate(4).unwrap();
        let cases = [
            (ReplayOverlay { footholds: vec![OverlayFoothold { foot: 4, ..good.footholds[0].clone() }], ..good.clone() }, "footholds[0].foot"),
            (ReplayOverlay { footholds: vec![OverlayFoothold { t: f64::NAN, ..good.footholds[0].clone() }], ..good.clone() }, "footholds[0]"),
            (ReplayOverlay { paths: vec![path(vec![0.0, 1.0], 3)], ..good.clone() }, "paths[0].t"),
            (ReplayOverlay { paths: vec![path(vec![0.0, 1.0, 0.5], 3)], ..good.clone() }, "paths[0].t[2]"),
            (ReplayOverlay { supports: vec![OverlaySupport { t1: -1.0, ..good.supports[0].clone() }], ..good.clone() }, "supports[0].t1"),
            (ReplayOverlay { supports: vec![OverlaySupport { shrunk: vec![[f64::INFINITY, 0.0, 0.0]], ..good.supports[0].clone() }], ..good.clone() }, "supports[0].shrunk"),
        ];
        for (overlay, field) in cases {
            let e = overlay.validate(4).unwrap_err().to_string();
            assert!(e.starts_with(&format!("replay overlay: {field}:")), "{e}");
        }
    }
}
