//! Jump files: the seven jumps of Nguyen 2022 (Table I) and any other, as TOML.
//!
//! ```toml
//! name = "lateral_down"
//! summary = "jump 0.3 m sideways off a 0.3 m box"
//! robot = "a1"
//! phases = [["LF", "RF", "LH", "RH"], []]   # feet in contact per phase; [] = flight
//! total_time = [0.5, 1.5]            # [T_min, T_max] of (2j), s
//! phase_time = [[0.1, 1.0], [0.1, 1.0]]  # optional: [lo, hi] of each phase's T_i, s
//!                                    # (absent: [contact_timing] t_lo, t_hi for every phase)
//!
//! [target]
//! displacement = [0.0, 0.3, -0.3]    # CoM displacement, world, m
//! axis = [0.0, 0.0, 1.0]             # unit axis of the base's rotation over the jump
//! angle_deg = 0.0                    # or `turns = -2.0`: exactly one of the two
//! landing_extension = 0.0            # optional: the CoM this much (m) higher over the
//!                                    # landing feet than standing (straighter legs at
//!                                    # touch-down), 0 <= x <= 0.12 (default 0)
//!
//! [box]                              # optional: the start box (absent: flat ground)
//! height = 0.3                       # top above the ground (z = 0), m
//! x = [-0.5, 0.5]                    # extent, world, m
//! y = [-0.5, 0.147]
//!
//! [reference]                        # optional: the reference script's own target, where
//! displacement = [0.0, 0.3, -0.3]    # the file's differs (its contact-timing optimum check)
//!
//! [contact_timing]                   # optional overrides of ContactTimingSettings
//! knots_per_phase = 30
//!
//! [full_body]                        # optional: the jump's full-body plan settings
//! lift_off_normal_force = 20.0       # N, bound on a lifting foot's last push (default none)
//! airborne_foot_margin = 0.01        # m, an airborne foot's clearance from the box beyond
//!                                    # its radius (default: the pipeline's, 0.01)
//!
//! [paper]                            # optional: the paper's Table I row
//! timings_10ms = [52, 35]
//! contact_timing_s = 5.02
//! full_body_s = 32.0
//! ```
//!
//! Every table refuses unknown fields; every error names the file, the field and what was
//! expected. The jump starts standing on the box (or the ground) and lands on the ground:
//! `displacement[2] = -box.height`.

use crate::srb::{BoxExtent, ContactTimingError, ContactTimingSettings, Contacts, ExpMap, JumpSpec, SrbParams, MAX_LANDING_EXTENSION};
use crate::terrain::{BoxSpec, Boxes};
use nalgebra::{Matrix3, Vector3};
use serde::Deserialize;
use std::f64::consts::PI;
use std::path::Path;

/// The embedded jumps (Nguyen 2022, Table I), as `(name, the jump's name in the reference
/// script ../shared/anchors/nguyen2022/contact_timing.py and its results, TOML text)`, in the
/// table's order.
pub const EMBEDDED_JUMPS: &[(&str, &str, &str)] = &[
    ("lateral", "lateral30", include_str!("../../jumps/lateral.toml")),
    ("lateral_down", "lateral_down", include_str!("../../jumps/lateral_down.toml")),
    ("spin_90", "spin90", include_str!("../../jumps/spin_90.toml")),
    ("diagonal", "diagonal", include_str!("../../jumps/diagonal.toml")),
    ("barrel_roll", "barrel_roll", include_str!("../../jumps/barrel_roll.toml")),
    ("double_barrel_roll", "double_barrel_roll", include_str!("../../jumps/double_barrel_roll.toml")),
    ("double_backflip", "double_backflip", include_str!("../../jumps/double_backflip.toml")),
];

/// Foot names of the `phases` lists, in the contact-timing formulation's order.
pub const FOOT_NAMES: [&str; 4] = ["LF", "RF", "LH", "RH"];

/// A jump file that cannot be used; names the file and the field.
#[derive(Debug, thiserror::Error)]
pub enum JumpError {
    #[error("{path}: cannot read the jump file: {error}")]
    Io { path: String, error: std::io::Error },
    #[error("{origin}: {message}")]
    Parse { origin: String, message: String },
    #[error("{origin}: field `{field}`: expected {expected}, got {got}")]
    Invalid { origin: String, field: String, expected: String, got: String },
    #[error("no embedded jump named '{name}' (embedded jumps: {known})")]
    Unknown { name: String, known: String },
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct JumpFile {
    name: String,
    summary: String,
    robot: String,
    phases: Vec<Vec<String>>,
    total_time: [f64; 2],
    #[serde(default)]
    phase_time: Option<Vec<[f64; 2]>>,
    target: TargetFile,
    #[serde(default, rename = "box")]
    platform: Option<PlatformFile>,
    #[serde(default)]
    reference: Option<ReferenceFile>,
    #[serde(default)]
    contact_timing: ContactTimingOverrides,
    #[serde(default)]
    full_body: FullBodyOverrides,
    #[serde(default)]
    paper: Option<PaperRow>,
}

/// The jump's own full-body settings (`[full_body]`); an absent field keeps the pipeline's.
#[derive(Clone, Debug, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FullBodyOverrides {
    /// `FullBodySettings::lift_off_normal_force` (N): the bound on each foot's normal force
    /// over its last pushing interval. Absent: no bound.
    pub lift_off_normal_force: Option<f64>,
    /// `FullBodySettings::airborne_foot_margin` (m): an airborne foot's clearance from the
    /// box beyond its radius. Absent: the pipeline's (`PipelineOptions::of`).
    pub airborne_foot_margin: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ReferenceFile {
    displacement: [f64; 3],
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct TargetFile {
    displacement: [f64; 3],
    axis: [f64; 3],
    #[serde(default)]
    angle_deg: Option<f64>,
    #[serde(default)]
    turns: Option<f64>,
    #[serde(default)]
    landing_extension: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PlatformFile {
    height: f64,
    x: [f64; 2],
    y: [f64; 2],
}

/// Overrides of [`ContactTimingSettings`]; an absent field keeps the setting's default.
#[derive(Clone, Debug, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ContactTimingOverrides {
    pub knots_per_phase: Option<usize>,
    pub mu: Option<f64>,
    pub f_min: Option<f64>,
    pub f_max: Option<f64>,
    pub radius: Option<f64>,
    pub max_stance_speed: Option<f64>,
    pub t_lo: Option<f64>,
    pub t_hi: Option<f64>,
    pub eps_omega: Option<f64>,
    pub eps_r: Option<f64>,
    pub eps_f: Option<f64>,
    pub cost_dt: Option<bool>,
    pub exp_map: Option<ExpMap>,
    pub box_clearance: Option<f64>,
}

impl ContactTimingOverrides {
    /// The defaults with these overrides applied.
    pub fn apply(&self, defaults: ContactTimingSettings) -> ContactTimingSettings {
        let d = defaults;
        ContactTimingSettings {
            knots_per_phase: self.knots_per_phase.unwrap_or(d.knots_per_phase),
            mu: self.mu.unwrap_or(d.mu),
            f_min: self.f_min.unwrap_or(d.f_min),
            f_max: self.f_max.unwrap_or(d.f_max),
            radius: self.radius.unwrap_or(d.radius),
            max_stance_speed: self.max_stance_speed.unwrap_or(d.max_stance_speed),
            t_lo: self.t_lo.unwrap_or(d.t_lo),
            t_hi: self.t_hi.unwrap_or(d.t_hi),
            eps_omega: self.eps_omega.unwrap_or(d.eps_omega),
            eps_r: self.eps_r.unwrap_or(d.eps_r),
            eps_f: self.eps_f.unwrap_or(d.eps_f),
            cost_dt: self.cost_dt.unwrap_or(d.cost_dt),
            exp_map: self.exp_map.unwrap_or(d.exp_map),
            box_clearance: self.box_clearance.unwrap_or(d.box_clearance),
        }
    }
}

/// The paper's Table I row of a jump.
#[derive(Clone, Debug, PartialEq, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct PaperRow {
    /// Optimal phase durations, in 10 ms.
    pub timings_10ms: Vec<f64>,
    /// Solve times of the contact-timing and the full-body optimization (s, MATLAB + CasADi +
    /// IPOPT on the authors' machine).
    pub contact_timing_s: f64,
    pub full_body_s: f64,
}

/// The start box: from the ground (z = 0) up to `height`, over `x` times `y` (world).
#[derive(Clone, Debug, PartialEq)]
pub struct Platform {
    pub height: f64,
    pub x: [f64; 2],
    pub y: [f64; 2],
}

/// A validated jump.
#[derive(Clone, Debug, PartialEq)]
pub struct Jump {
    pub name: String,
    pub summary: String,
    pub robot: String,
    /// An embedded jump's name in `../shared/anchors/nguyen2022/contact_timing.py` (and its
    /// results files).
    pub anchor: Option<&'static str>,
    /// The name [`JumpSpec`] carries (a `&'static str`): an embedded jump's table name; a
    /// file's name, kept for the rest of the program (one small allocation per file read).
    srb_name: &'static str,
    /// Feet in contact per phase (order [`FOOT_NAMES`]).
    pub phases: Vec<Contacts>,
    /// `[T_min, T_max]` of (2j), s.
    pub total_time: (f64, f64),
    /// `[lo, hi]` of each phase's duration (s); `None`: the contact-timing settings' `t_lo`,
    /// `t_hi` for every phase.
    pub phase_time: Option<Vec<(f64, f64)>>,
    /// CoM displacement (world, m).
    pub displacement: Vector3<f64>,
    /// Unit axis and angle (rad) of the base's rotation over the jump.
    pub axis: Vector3<f64>,
    pub angle: f64,
    /// The CoM's rise (m) over the landing feet above the standing pose at touch-down
    /// ([`JumpSpec::landing_extension`]; `[target] landing_extension`, default 0).
    pub landing_extension: f64,
    pub platform: Option<Platform>,
    /// The CoM displacement of the reference script's problem (`[reference]`), where it
    /// differs from the file's target (the script's landings over the start box).
    pub reference_displacement: Option<Vector3<f64>>,
    /// The formulation's settings: defaults with the file's overrides.
    pub contact_timing: ContactTimingSettings,
    pub full_body: FullBodyOverrides,
    pub paper: Option<PaperRow>,
    /// Where the jump came from (a path or `embedded jump NAME`).
    pub origin: String,
}

/// A foot whose start is off the box or whose landing is over it.
#[derive(Clone, Debug, PartialEq)]
pub struct StanceConflict {
    pub foot: &'static str,
    /// `true`: the foot starts off the box top; `false`: it lands over (or within a foot
    /// radius of) the box.
    pub at_start: bool,
    /// The foot's contact point (world, m).
    pub point: Vector3<f64>,
}

impl std::fmt::Display for StanceConflict {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        let (x, y) = (self.point.x, self.point.y);
        if self.at_start {
            write!(f, "{} starts at ({x:.3}, {y:.3}), off the box top", self.foot)
        } else {
            write!(f, "{} lands at ({x:.3}, {y:.3}), over the box or within a foot radius of it", self.foot)
        }
    }
}

impl Jump {
    /// Parses and validates TOML text; `origin` goes into errors.
    pub fn from_toml(text: &str, origin: &str) -> Result<Self, JumpError> {
        let file: JumpFile = toml::from_str(text).map_err(|e| JumpError::Parse { origin: origin.into(), message: e.to_string() })?;
        let name: &'static str = Box::leak(file.name.clone().into_boxed_str());
        Self::validate(file, origin, name, None)
    }

    /// Reads a jump file.
    pub fn load_file(path: impl AsRef<Path>) -> Result<Self, JumpError> {
        let path = path.as_ref();
        let name = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|error| JumpError::Io { path: name.clone(), error })?;
        Self::from_toml(&text, &name)
    }

    /// An embedded jump by name.
    pub fn embedded(name: &str) -> Result<Self, JumpError> {
        let &(key, anchor, text) = EMBEDDED_JUMPS.iter().find(|(n, _, _)| *n == name).ok_or_else(|| JumpError::Unknown {
            name: name.into(),
            known: EMBEDDED_JUMPS.iter().map(|(n, _, _)| *n).collect::<Vec<_>>().join(", "),
        })?;
        let origin = format!("embedded jump {name}");
        let file: JumpFile = toml::from_str(text).map_err(|e| JumpError::Parse { origin: origin.clone(), message: e.to_string() })?;
        if file.name != key {
            return Err(JumpError::Invalid { origin, field: "name".into(), expected: format!("'{key}' (the table's name)"), got: format!("'{}'", file.name) });
        }
        Self::validate(file, &origin, key, Some(anchor))
    }

    /// A file when `spec` ends in `.toml` or names an existing path, else an embedded jump.
    pub fn load(spec: &str) -> Result<Self, JumpError> {
        let path = Path::new(spec);
        if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("toml")) || path.exists() {
            Self::load_file(path)
        } else {
            Self::embedded(spec)
        }
    }

    fn validate(file: JumpFile, origin: &str, srb_name: &'static str, anchor: Option<&'static str>) -> Result<Self, JumpError> {
        let bad = |field: &str, expected: &str, got: String| Err(JumpError::Invalid { origin: origin.into(), field: field.into(), expected: expected.into(), got });
        let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
        let mut phases = Vec::with_capacity(file.phases.len());
        for (i, names) in file.phases.iter().enumerate() {
            let mut contacts = [false; 4];
            for name in names {
                match FOOT_NAMES.iter().position(|f| f == name) {
                    Some(f) if !contacts[f] => contacts[f] = true,
                    Some(_) => return bad(&format!("phases[{i}]"), "each foot at most once", format!("{name} twice")),
                    None => return bad(&format!("phases[{i}]"), "foot names LF, RF, LH, RH", format!("'{name}'")),
                }
            }
            phases.push(contacts);
        }
        let shape = "at least two phases, the first with all four feet, the last a flight phase ([]), none other a flight phase";
        let middle_flight = phases.len() >= 2 && phases[1..phases.len() - 1].iter().any(|c| !c.iter().any(|&f| f));
        if phases.len() < 2 || phases[0] != [true; 4] || phases.last() != Some(&[false; 4]) || middle_flight {
            return bad("phases", shape, format!("{:?}", file.phases));
        }
        let [t_min, t_max] = file.total_time;
        if !(finite(&file.total_time) && t_min > 0.0 && t_min <= t_max) {
            return bad("total_time", "[T_min, T_max] with 0 < T_min <= T_max (s)", format!("{:?}", file.total_time));
        }
        let phase_time = match &file.phase_time {
            None => None,
            Some(bounds) => {
                if bounds.len() != phases.len() {
                    return bad("phase_time", &format!("{} [lo, hi] pairs (one per phase, s)", phases.len()), format!("{bounds:?}"));
                }
                for (i, b) in bounds.iter().enumerate() {
                    if !(finite(b) && b[0] > 0.0 && b[0] <= b[1]) {
                        return bad(&format!("phase_time[{i}]"), "[lo, hi] with 0 < lo <= hi (s)", format!("{b:?}"));
                    }
                }
                let (lo, hi) = (bounds.iter().map(|b| b[0]).sum::<f64>(), bounds.iter().map(|b| b[1]).sum::<f64>());
                if lo > t_max || hi < t_min {
                    return bad("phase_time", &format!("bounds whose sums meet total_time [{t_min}, {t_max}]"), format!("{bounds:?} (sums {lo}, {hi})"));
                }
                Some(bounds.iter().map(|b| (b[0], b[1])).collect())
            }
        };
        let t = &file.target;
        if !finite(&t.displacement) {
            return bad("target.displacement", "three finite numbers (m)", format!("{:?}", t.displacement));
        }
        let axis = Vector3::from(t.axis);
        if !finite(&t.axis) || (axis.norm() - 1.0).abs() > 1e-9 {
            return bad("target.axis", "a unit vector", format!("{:?} (length {})", t.axis, axis.norm()));
        }
        let angle = match (t.angle_deg, t.turns) {
            (Some(deg), None) if deg.is_finite() => deg * PI / 180.0,
            (None, Some(turns)) if turns.is_finite() => turns * 2.0 * PI,
            (Some(_), Some(_)) | (None, None) => return bad("target", "exactly one of `angle_deg` and `turns`", format!("angle_deg {:?}, turns {:?}", t.angle_deg, t.turns)),
            _ => return bad("target.angle_deg / target.turns", "a finite number", format!("angle_deg {:?}, turns {:?}", t.angle_deg, t.turns)),
        };
        let landing_extension = t.landing_extension.unwrap_or(0.0);
        if !(0.0..=MAX_LANDING_EXTENSION).contains(&landing_extension) {
            return bad("target.landing_extension", &format!("a rise within [0, {MAX_LANDING_EXTENSION}] (m)"), landing_extension.to_string());
        }
        let platform = match &file.platform {
            None => None,
            Some(p) => {
                if !(p.height.is_finite() && p.height > 0.0) {
                    return bad("box.height", "a positive height (m)", p.height.to_string());
                }
                for (field, range) in [("box.x", p.x), ("box.y", p.y)] {
                    if !(finite(&range) && range[0] < range[1]) {
                        return bad(field, "[min, max] with min < max (m)", format!("{range:?}"));
                    }
                }
                Some(Platform { height: p.height, x: p.x, y: p.y })
            }
        };
        let box_height = platform.as_ref().map_or(0.0, |p| p.height);
        if (t.displacement[2] + box_height).abs() > 1e-9 {
            return bad("target.displacement[2]", &format!("-box.height = {} (the landing is on the ground, z = 0)", -box_height), t.displacement[2].to_string());
        }
        let reference_displacement = match &file.reference {
            None => None,
            Some(r) if finite(&r.displacement) && (r.displacement[2] + box_height).abs() <= 1e-9 => Some(Vector3::from(r.displacement)),
            Some(r) => return bad("reference.displacement", &format!("three finite numbers (m), the last -box.height = {}", -box_height), format!("{:?}", r.displacement)),
        };
        let contact_timing = file.contact_timing.apply(ContactTimingSettings::default());
        if let Err(ContactTimingError::Setting { field, value, expected }) = contact_timing.validate() {
            return bad(&format!("contact_timing.{field}"), expected, value.to_string());
        }
        if let Some(f) = file.full_body.lift_off_normal_force {
            if !(f.is_finite() && f > 0.0) {
                return bad("full_body.lift_off_normal_force", "a positive force (N)", f.to_string());
            }
        }
        if let Some(m) = file.full_body.airborne_foot_margin {
            if !(m.is_finite() && m >= 0.0) {
                return bad("full_body.airborne_foot_margin", "a non-negative distance (m)", m.to_string());
            }
        }
        if let Some(p) = &file.paper {
            if p.timings_10ms.len() != phases.len() || !finite(&p.timings_10ms) {
                return bad("paper.timings_10ms", &format!("{} finite durations (one per phase)", phases.len()), format!("{:?}", p.timings_10ms));
            }
        }
        Ok(Self {
            name: file.name,
            summary: file.summary,
            robot: file.robot,
            anchor,
            srb_name,
            phases,
            total_time: (t_min, t_max),
            phase_time,
            displacement: Vector3::from(t.displacement),
            axis,
            angle,
            landing_extension,
            platform,
            reference_displacement,
            contact_timing,
            full_body: file.full_body,
            paper: file.paper,
            origin: origin.into(),
        })
    }

    /// Height of the start box (0 on flat ground).
    pub fn box_height(&self) -> f64 {
        self.platform.as_ref().map_or(0.0, |p| p.height)
    }

    /// The jump as the contact-timing formulation takes it.
    pub fn srb(&self) -> JumpSpec {
        JumpSpec {
            name: self.srb_name,
            displacement: self.displacement,
            axis: self.axis,
            angle: self.angle,
            landing_extension: self.landing_extension,
            box_height: self.box_height(),
            clear_of: self.platform.as_ref().map(|p| BoxExtent { x: p.x, y: p.y }),
            phases: self.phases.clone(),
            total_time: self.total_time,
            phase_time: self.phase_time.clone(),
        }
    }

    /// The reference script's problem (`../shared/anchors/nguyen2022/contact_timing.py`):
    /// [`Self::srb`] with the script's own displacement where the file's differs, without
    /// the box-clearance rows and with the script's bounds on every phase (the settings'
    /// `t_lo`, `t_hi`, not the file's `phase_time`): the script has neither, its optimum is
    /// checked like with like.
    pub fn reference_srb(&self) -> JumpSpec {
        JumpSpec { clear_of: None, phase_time: None, landing_extension: 0.0, ..self.reference().srb() }
    }

    /// This jump with the reference script's target (see [`Self::reference_srb`]).
    pub fn reference(&self) -> Jump {
        Jump { displacement: self.reference_displacement.unwrap_or(self.displacement), reference_displacement: None, ..self.clone() }
    }

    /// The ground (z = 0) with the start box.
    pub fn terrain(&self) -> Boxes {
        let boxes = self.platform.iter().map(|p| BoxSpec { x: p.x, y: p.y, top: p.height }).collect();
        // The numbers were checked in `validate`: finite, ordered, the top above the ground.
        Boxes::new(0.0, boxes).unwrap_or_else(|_| Boxes::flat(0.0))
    }

    /// The goal rotation `exp(hat(axis * angle))`.
    pub fn goal_rotation(&self) -> Matrix3<f64> {
        crate::srb::exp_map::exp(ExpMap::Exact, &(self.axis * self.angle))
    }

    /// Feet of the start stance off the box top and feet of the landing stance over the box
    /// (or closer to it than `foot_radius`), with the stances of the contact-timing problem
    /// (the body's nominal feet `params.foot_rel_com` at the start and the goal pose).
    pub fn stance_conflicts(&self, params: &SrbParams, foot_radius: f64) -> Vec<StanceConflict> {
        let Some(p) = &self.platform else { return Vec::new() };
        let h0 = -params.foot_rel_com.iter().map(|f| f[2]).sum::<f64>() / 4.0;
        let com_start = Vector3::new(0.0, 0.0, p.height + h0);
        let com_goal = com_start + self.displacement;
        let rg = self.goal_rotation();
        let distance = |q: &Vector3<f64>| {
            let dx = (p.x[0] - q.x).max(q.x - p.x[1]).max(0.0);
            let dy = (p.y[0] - q.y).max(q.y - p.y[1]).max(0.0);
            dx.hypot(dy)
        };
        let inside = |q: &Vector3<f64>| q.x >= p.x[0] && q.x <= p.x[1] && q.y >= p.y[0] && q.y <= p.y[1];
        let mut conflicts = Vec::new();
        for (f, rel) in params.foot_rel_com.iter().enumerate() {
            let pbar = Vector3::new(rel.x, rel.y, -h0);
            let start = com_start + pbar;
            if !inside(&start) {
                conflicts.push(StanceConflict { foot: FOOT_NAMES[f], at_start: true, point: start });
            }
            let landing = com_goal + rg * pbar;
            if distance(&landing) < foot_radius {
                conflicts.push(StanceConflict { foot: FOOT_NAMES[f], at_start: false, point: landing });
            }
        }
        conflicts
    }
}

/// The seven embedded jumps, in Table I's order.
pub fn embedded_jumps() -> Result<Vec<Jump>, JumpError> {
    EMBEDDED_JUMPS.iter().map(|(name, _, _)| Jump::embedded(name)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    const LATERAL: &str = include_str!("../../jumps/lateral.toml");

    fn error_of(text: &str) -> String {
        Jump::from_toml(text, "test.toml").unwrap_err().to_string()
    }

    #[test]
    fn errors_name_the_file_the_field_and_the_expectation() {
        let e = error_of(&LATERAL.replace("angle_deg = 0.0", "angle_deg = 0.0\ncolour = 1"));
        assert!(e.starts_with("test.toml:") && e.contains("colour"), "{e}");
        let e = error_of(&LATERAL.replace("angle_deg = 0.0", "turns = 1.0\nangle_deg = 0.0"));
        assert!(e.contains("field `target`: expected exactly one of `angle_deg` and `turns`"), "{e}");
        let e = error_of(&LATERAL.replace("\"RH\"], []]", "\"XX\"], []]"));
        assert!(e.contains("field `phases[0]`: expected foot names LF, RF, LH, RH, got 'XX'"), "{e}");
        let e = error_of(&LATERAL.replace("[[\"LF\", \"RF\", \"LH\", \"RH\"], []]", "[[\"LF\", \"RF\", \"LH\", \"RH\"]]"));
        assert!(e.contains("field `phases`: expected at least two phases"), "{e}");
        let e = error_of(&LATERAL.replace("axis = [0.0, 0.0, 1.0]", "axis = [0.0, 0.0, 2.0]"));
        assert!(e.contains("field `target.axis`: expected a unit vector, got [0.0, 0.0, 2.0] (length 2)"), "{e}");
        let e = error_of(&LATERAL.replace("total_time = [0.5, 1.5]", "total_time = [1.5, 0.5]"));
        assert!(e.contains("field `total_time`: expected [T_min, T_max] with 0 < T_min <= T_max"), "{e}");
        let e = error_of(&LATERAL.replace("[paper]", "[box]\nheight = 0.3\nx = [-1.0, 1.0]\ny = [-1.0, 1.0]\n\n[paper]"));
        assert!(e.contains("field `target.displacement[2]`: expected -box.height = -0.3"), "{e}");
        let e = error_of(&LATERAL.replace("[paper]", "[contact_timing]\nmu = -1.0\n\n[paper]"));
        assert!(e.contains("field `contact_timing.mu`: expected > 0, got -1"), "{e}");
        let e = error_of(&LATERAL.replace("[paper]", "[full_body]\nlift_off_normal_force = -1.0\n\n[paper]"));
        assert!(e.contains("field `full_body.lift_off_normal_force`: expected a positive force (N), got -1"), "{e}");
        let e = error_of(&LATERAL.replace("[paper]", "[full_body]\nairborne_foot_margin = -0.01\n\n[paper]"));
        assert!(e.contains("field `full_body.airborne_foot_margin`: expected a non-negative distance (m), got -0.01"), "{e}");
        let e = error_of(&LATERAL.replace("[paper]", "[contact_timing]\nknots = 3\n\n[paper]"));
        assert!(e.contains("knots"), "{e}");
        let e = error_of(&LATERAL.replace("timings_10ms = [50, 28]", "timings_10ms = [50]"));
        assert!(e.contains("field `paper.timings_10ms`: expected 2 finite durations"), "{e}");
        let e = error_of(&LATERAL.replace("total_time = [0.5, 1.5]", "total_time = [0.5, 1.5]\nphase_time = [[0.3, 0.6]]"));
        assert!(e.contains("field `phase_time`: expected 2 [lo, hi] pairs (one per phase, s), got [[0.3, 0.6]]"), "{e}");
        let e = error_of(&LATERAL.replace("total_time = [0.5, 1.5]", "total_time = [0.5, 1.5]\nphase_time = [[0.3, 0.6], [0.4, 0.2]]"));
        assert!(e.contains("field `phase_time[1]`: expected [lo, hi] with 0 < lo <= hi (s), got [0.4, 0.2]"), "{e}");
        let e = error_of(&LATERAL.replace("angle_deg = 0.0", "angle_deg = 0.0\nlanding_extension = 0.2"));
        assert!(e.contains("field `target.landing_extension`: expected a rise within [0, 0.12] (m), got 0.2"), "{e}");
        let e = error_of(&LATERAL.replace("total_time = [0.5, 1.5]", "total_time = [0.5, 1.5]\nphase_time = [[0.1, 0.2], [0.1, 0.2]]"));
        assert!(e.contains("field `phase_time`: expected bounds whose sums meet total_time [0.5, 1.5]"), "{e}");
        let e = Jump::embedded("moonwalk").unwrap_err().to_string();
        assert!(e.contains("'moonwalk'") && e.contains("double_backflip"), "{e}");
    }

    #[test]
    fn overrides_replace_only_the_given_settings() {
        let j = Jump::from_toml(&LATERAL.replace("[paper]", "[contact_timing]\nknots_per_phase = 4\nexp_map = \"taylor4\"\n\n[paper]"), "t").unwrap();
        let expected = ContactTimingSettings { knots_per_phase: 4, exp_map: ExpMap::Taylor4, ..Default::default() };
        assert_eq!(j.contact_timing, expected);
    }

    #[test]
    fn phase_time_bounds_reach_the_jumps_problem_but_not_the_reference_scripts() {
        let j = Jump::from_toml(&LATERAL.replace("total_time = [0.5, 1.5]", "total_time = [0.5, 1.5]\nphase_time = [[0.4, 0.6], [0.25, 0.35]]"), "t").unwrap();
        assert_eq!(j.srb().phase_time, Some(vec![(0.4, 0.6), (0.25, 0.35)]));
        assert_eq!(j.reference_srb().phase_time, None);
        assert_eq!(Jump::from_toml(LATERAL, "t").unwrap().srb().phase_time, None);
    }

    #[test]
    fn landing_extension_reaches_the_jumps_problem_but_not_the_reference_scripts() {
        let j = Jump::from_toml(&LATERAL.replace("angle_deg = 0.0", "angle_deg = 0.0\nlanding_extension = 0.06"), "t").unwrap();
        assert_eq!(j.srb().landing_extension, 0.06);
        assert_eq!(j.reference_srb().landing_extension, 0.0);
        assert_eq!(Jump::from_toml(LATERAL, "t").unwrap().srb().landing_extension, 0.0);
    }
}
