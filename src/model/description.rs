//! legwork's own robot description: a short TOML file for a quadruped with three revolute
//! joints per leg (HAA, HFE, KFE), written in terms a robot's data sheet uses (hip
//! positions, segment offsets, link masses) rather than as a general kinematic tree.
//!
//! The embedded robots (`robots/hyq.toml`, `robots/a1.toml`, see [`super::embedded`]) are
//! written in it; [`load_file`] reads one from disk and [`from_str`] from text.
//!
//! # The model it builds
//!
//! * Joint 1 is a free flyer named `root_joint`, carrying the base body.
//! * Then the legs in the order **LF, RF, LH, RH** (left front, right front, left hind,
//!   right hind), each as three revolute joints HAA (hip abduction/adduction), HFE (hip
//!   flexion/extension), KFE (knee flexion/extension), each moving one body: the **hip**,
//!   the **thigh** and the **shank**. So `q = [base position, base quaternion (x,y,z,w),
//!   LF haa, LF hfe, LF kfe, RF haa, ...]`.
//! * Every joint frame is **parallel to the base frame when all joint angles are zero**;
//!   a joint's frame origin sits on its axis. Joint axes, centres of mass and inertias
//!   are therefore written in base-frame directions (x forward, y left, z up).
//! * A foot frame at the centre of each foot sphere, attached to the shank, also parallel
//!   to the base at zero angles; the feet are declared in the order LF, RF, LH, RH.
//! * A `standing` reference configuration, if the file gives one.
//!
//! # Mirroring
//!
//! Each leg segment is written once, for the **LF leg**. The other legs are derived from it:
//!
//! * The hip position on the base (`hip.offset`) is always mirrored: RF gets `(x, -y, z)`,
//!   LH `(-x, y, z)`, RH `(-x, -y, z)`.
//! * Within a leg, a segment's body (centre of mass, inertia) and the position of the next
//!   joint on it (`thigh.offset` lies on the hip, `shank.offset` on the thigh,
//!   `foot.offset` and the foot's mass on the shank) follow that segment's rules `right`
//!   (LF to RF, and LH to RH) and `hind` (LF to LH, and RF to RH). A rule is one of
//!   * `"mirror"` (default): the mirror-image part. Right: reflection `y -> -y`;
//!     hind: reflection `x -> -x`.
//!   * `"same"`: the identical part in the same orientation (e.g. the thighs and calves
//!     of Unitree's robots are the same part front and hind).
//!   * `"turn"`: the identical part turned by 180 degrees about the vertical axis
//!     (`x -> -x, y -> -y`), as HyQ's hind legs are.
//!
//!   A point `p` becomes `D p` and an inertia `I` becomes `D I D`, with `D` the diagonal
//!   matrix of the rule(s).
//! * Anything that must differ otherwise is given per leg: joint axis `signs`, limits and
//!   standing angles accept either one number (all legs) or an array of four numbers in
//!   the order `[LF, RF, LH, RH]`; `offsets` (four vectors) replaces `offset` with
//!   explicit per-leg positions to which no rule is applied.
//!
//! Joint angle conventions are **not** derived by mirroring: the joint axis of leg `k` is
//! `signs[k] * axis`, so the same joint angles can mean mirror-image postures (HyQ's HAA:
//! `signs = [-1, 1, -1, 1]`) or parallel ones (A1's hip: all `+1`).
//!
//! # Fields
//!
//! Units are SI (m, kg, kg m^2, rad, rad/s, N m). Unknown fields are errors. A field
//! without a default is required.
//!
//! Top level:
//!
//! | field | type | meaning |
//! |---|---|---|
//! | `format` | integer | version of this format; must be `1` |
//! | `name` | string | robot name (the model's name) |
//! | `summary` | string, default `""` | one line describing the robot (shown by `legwork robot list`) |
//!
//! `[base]`, the floating base (trunk) and everything rigidly fixed to it:
//!
//! | field | type | meaning |
//! |---|---|---|
//! | `body` | string | name of the base body frame (e.g. `trunk`) |
//! | `mass` | number > 0 | mass |
//! | `com` | `[x, y, z]` | centre of mass in the base frame |
//! | `inertia` | `[ixx, iyy, izz, ixy, ixz, iyz]` | rotational inertia about the centre of mass, base-frame axes (tensor elements, MuJoCo's `fullinertia` order: `ixy` is the matrix element `I[0][1] = -sum m x y`); must be positive definite and physical |
//!
//! `[legs]`:
//!
//! | field | type | meaning |
//! |---|---|---|
//! | `names` | 4 strings | the robot's own names of the legs LF, RF, LH, RH (e.g. `["lf", "rf", "lh", "rh"]` or A1's `["FL", "FR", "RL", "RR"]`); each replaces `{leg}` in the name patterns below |
//!
//! `[hip]` (body moved by the HAA joint), `[thigh]` (by HFE), `[shank]` (by KFE): one
//! section each, with the same fields:
//!
//! | field | type | meaning |
//! |---|---|---|
//! | `joint` | string | joint name pattern, must contain `{leg}` (e.g. `"{leg}_haa_joint"`) |
//! | `body` | string | body name pattern, must contain `{leg}` |
//! | `offset` | `[x, y, z]` | LF leg: position of this joint in the parent frame (hip: in the base frame; thigh: in the hip frame; shank: in the thigh frame); mirrored to the other legs as described above |
//! | `offsets` | 4 x `[x, y, z]` | instead of `offset`: the position for each leg `[LF, RF, LH, RH]`, used as given |
//! | `axis` | `[x, y, z]` | joint axis in the joint frame for a sign of `+1` (normalised) |
//! | `signs` | number or 4 numbers, each `1` or `-1`; default `1` | per-leg sign of the axis |
//! | `lower`, `upper` | number or 4 numbers | position limits, rad (`lower <= upper`; `inf` allowed) |
//! | `velocity` | number or 4 numbers, > 0 | velocity limit, rad/s |
//! | `effort` | number or 4 numbers, > 0 | torque limit, N m |
//! | `mass` | number > 0 | LF body mass |
//! | `com` | `[x, y, z]` | LF body centre of mass in the joint frame |
//! | `inertia` | `[ixx, iyy, izz, ixy, ixz, iyz]` | LF body rotational inertia about its centre of mass (as for the base) |
//! | `right` | `"mirror"`, `"same"` or `"turn"`; default `"mirror"` | how the RF (and RH) segment relates to the LF (and LH) one |
//! | `hind` | same choices; default `"mirror"` | how the LH (and RH) segment relates to the LF (and RF) one |
//!
//! `[foot]`, the foot sphere at the end of the shank (its position and mass follow the
//! shank's rules):
//!
//! | field | type | meaning |
//! |---|---|---|
//! | `frame` | string | foot frame name pattern, must contain `{leg}` |
//! | `offset` / `offsets` | as above | LF: centre of the foot sphere in the shank (KFE joint) frame |
//! | `radius` | number > 0 | foot sphere radius |
//! | `mass` | number > 0, optional | mass of a foot body (omit for a massless foot frame) |
//! | `com` | `[x, y, z]`, default `[0, 0, 0]` | its centre of mass in the foot frame |
//! | `inertia` | as above; required with `mass` | its rotational inertia |
//!
//! `[standing]`, optional, the `standing` reference configuration (base at `(0, 0,
//! base_height)` with identity orientation):
//!
//! | field | type | meaning |
//! |---|---|---|
//! | `base_height` | number | height of the base frame origin above the ground, m |
//! | `hip`, `thigh`, `shank` | number or 4 numbers | HAA, HFE, KFE angles, rad; must be within the limits |
//!
//! `[contact]`, optional, the feet's contact with the ground (shared by the optimizer, the
//! simulator and the MuJoCo export). Every field defaults to the calibration against
//! MuJoCo's default contact for the robot's standing load per foot, `m_f = total mass /
//! number of feet` ([`crate::contact::ContactParams::for_foot_load`], whose documentation says how it
//! was calibrated):
//!
//! | field | type | meaning (default) |
//! |---|---|---|
//! | `alpha` | number > 0 | smoothing penetration, m (0.01) |
//! | `normal_stiffness` | number > 0 | `k_n`, N/m (9000 `m_f`) |
//! | `normal_damping` | number >= 0 | `d_n`, N s/m^2 (4500 `m_f`) |
//! | `tangential_stiffness` | number >= 0 | `k_t`, N/m^2 (2.3e6 `m_f`) |
//! | `tangential_damping` | number >= 0 | `d_t`, N s/m^2 (4500 `m_f`) |
//! | `friction` | number >= 0 | friction coefficient (0.8) |
//! | `max_step` | number > 0 | largest stable integration step, s (0.001) |
//!
//! # Errors
//!
//! A [`DescriptionError`] names the file (for an embedded robot its name, e.g.
//! `hyq.toml`), the line when known, the field (e.g. `thigh.inertia`) and what was
//! expected.
//!
//! ```
//! use legwork::model::description;
//! let err = description::from_str("format = 1\nname = \"x\"\nmass = 3.0\n", "tiny.toml").unwrap_err();
//! assert!(err.to_string().starts_with("tiny.toml:3: mass: unknown field `mass`"), "{err}");
//! ```

use super::{Frame, FrameKind, JointKind, JointLimits, Model, ModelError};
use crate::spatial::{Inertia, Matrix3, Vector3, SE3};
use serde::Deserialize;
use std::fmt;
use std::path::Path;

/// The leg order of every legwork model: left front, right front, left hind, right hind.
pub const LEG_ORDER: [&str; 4] = ["LF", "RF", "LH", "RH"];

/// The format version this module reads.
pub const FORMAT_VERSION: u32 = 1;

/// A description that cannot be read or does not describe a valid robot.
#[derive(Debug, Clone, PartialEq)]
pub struct DescriptionError {
    /// The file (or the embedded name, e.g. `hyq.toml`).
    pub file: String,
    /// 1-based line in the file, when known.
    pub line: Option<usize>,
    /// The field, as a dotted path (`thigh.inertia`); empty when the whole file is at fault.
    pub field: String,
    /// What is wrong and what was expected.
    pub message: String,
}

impl fmt::Display for DescriptionError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file)?;
        if let Some(line) = self.line {
            write!(f, ":{line}")?;
        }
        if !self.field.is_empty() {
            write!(f, ": {}", self.field)?;
        }
        write!(f, ": {}", self.message)
    }
}

impl std::error::Error for DescriptionError {}

/// A number for all four legs, or one per leg in the order `[LF, RF, LH, RH]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PerLeg(pub [f64; 4]);

impl PerLeg {
    /// The value for leg `k` (0 = LF, 1 = RF, 2 = LH, 3 = RH).
    pub fn get(&self, k: usize) -> f64 {
        self.0[k]
    }
}

impl<'de> Deserialize<'de> for PerLeg {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> serde::de::Visitor<'de> for V {
            type Value = PerLeg;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a number (all legs) or an array of 4 numbers [LF, RF, LH, RH]")
            }
            fn visit_f64<E: serde::de::Error>(self, v: f64) -> Result<PerLeg, E> {
                Ok(PerLeg([v; 4]))
            }
            fn visit_i64<E: serde::de::Error>(self, v: i64) -> Result<PerLeg, E> {
                Ok(PerLeg([v as f64; 4]))
            }
            fn visit_u64<E: serde::de::Error>(self, v: u64) -> Result<PerLeg, E> {
                Ok(PerLeg([v as f64; 4]))
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(self, mut seq: A) -> Result<PerLeg, A::Error> {
                let mut out = [0.0; 4];
                for (k, slot) in out.iter_mut().enumerate() {
                    *slot = seq.next_element()?.ok_or_else(|| serde::de::Error::invalid_length(k, &self))?;
                }
                if seq.next_element::<f64>()?.is_some() {
                    return Err(serde::de::Error::invalid_length(5, &self));
                }
                Ok(PerLeg(out))
            }
        }
        d.deserialize_any(V)
    }
}

/// How a segment of one leg relates to the same segment of another leg.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Rule {
    /// The mirror-image part (reflection `y -> -y` for right legs, `x -> -x` for hind legs).
    #[default]
    Mirror,
    /// The identical part in the same orientation.
    Same,
    /// The identical part turned by 180 degrees about the vertical axis.
    Turn,
}

/// `[base]`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BaseSection {
    pub body: String,
    pub mass: f64,
    pub com: [f64; 3],
    pub inertia: [f64; 6],
}

/// `[legs]`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LegsSection {
    pub names: [String; 4],
}

/// `[hip]`, `[thigh]`, `[shank]`: a joint and the body it moves.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SegmentSection {
    pub joint: String,
    pub body: String,
    pub offset: Option<[f64; 3]>,
    pub offsets: Option<[[f64; 3]; 4]>,
    pub axis: [f64; 3],
    #[serde(default = "PerLeg::ones")]
    pub signs: PerLeg,
    pub lower: PerLeg,
    pub upper: PerLeg,
    pub velocity: PerLeg,
    pub effort: PerLeg,
    pub mass: f64,
    pub com: [f64; 3],
    pub inertia: [f64; 6],
    #[serde(default)]
    pub right: Rule,
    #[serde(default)]
    pub hind: Rule,
}

impl PerLeg {
    fn ones() -> PerLeg {
        PerLeg([1.0; 4])
    }
}

/// `[foot]`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FootSection {
    pub frame: String,
    pub offset: Option<[f64; 3]>,
    pub offsets: Option<[[f64; 3]; 4]>,
    pub radius: f64,
    pub mass: Option<f64>,
    #[serde(default)]
    pub com: [f64; 3],
    pub inertia: Option<[f64; 6]>,
}

/// `[standing]`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StandingSection {
    pub base_height: f64,
    pub hip: PerLeg,
    pub thigh: PerLeg,
    pub shank: PerLeg,
}

/// `[contact]`: any of [`crate::contact::ContactParams`]'s fields.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ContactSection {
    pub alpha: Option<f64>,
    pub normal_stiffness: Option<f64>,
    pub normal_damping: Option<f64>,
    pub tangential_stiffness: Option<f64>,
    pub tangential_damping: Option<f64>,
    pub friction: Option<f64>,
    pub max_step: Option<f64>,
}

/// A parsed description file (fields as written; see the module documentation).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Description {
    pub format: u32,
    pub name: String,
    #[serde(default)]
    pub summary: String,
    pub base: BaseSection,
    pub legs: LegsSection,
    pub hip: SegmentSection,
    pub thigh: SegmentSection,
    pub shank: SegmentSection,
    pub foot: FootSection,
    pub standing: Option<StandingSection>,
    /// `[contact]`: the feet's contact with the ground (absent fields: the calibration for
    /// the robot's foot load, [`crate::contact::ContactParams::for_foot_load`]).
    #[serde(default)]
    pub contact: ContactSection,
    /// The file it was read from (for error messages); not a TOML field.
    #[serde(skip)]
    pub file: String,
}

/// Reads and builds a description file.
pub fn load_file(path: impl AsRef<Path>) -> Result<Model, DescriptionError> {
    let path = path.as_ref();
    let file = path.display().to_string();
    let src = std::fs::read_to_string(path)
        .map_err(|e| DescriptionError { file: file.clone(), line: None, field: String::new(), message: format!("cannot read: {e}") })?;
    from_str(&src, &file)
}

/// Builds a model from description text; `file` names the source in errors.
pub fn from_str(src: &str, file: &str) -> Result<Model, DescriptionError> {
    parse(src, file)?.build()
}

/// Parses description text without building the model; `file` names the source in errors.
pub fn parse(src: &str, file: &str) -> Result<Description, DescriptionError> {
    let mut d: Description = toml::from_str(src).map_err(|e| toml_error(src, file, &e))?;
    d.file = file.to_string();
    Ok(d)
}

/// Turns a TOML/serde error into one that names the line and the field (the key path is
/// found from the error's location in the text).
fn toml_error(src: &str, file: &str, e: &toml::de::Error) -> DescriptionError {
    let (line, field) = match e.span() {
        Some(span) => locate(src, span.start),
        None => (None, String::new()),
    };
    let message = e.message().trim().to_string();
    DescriptionError { file: file.to_string(), line, field, message }
}

/// The 1-based line of byte `pos` and the dotted key path of the entry there: the
/// enclosing `[section]` and the key of the `key = value` line the value starts on.
fn locate(src: &str, pos: usize) -> (Option<usize>, String) {
    let pos = pos.min(src.len());
    let lines: Vec<&str> = src[..pos].split('\n').collect();
    let line_no = lines.len();
    let all_lines: Vec<&str> = src.lines().collect();
    let mut key = None;
    let mut section = String::new();
    // Walk back from the error's line: the first `key =` line (for a value spanning
    // several lines) gives the key, the first `[header]` gives the section.
    for i in (0..line_no.min(all_lines.len().max(1))).rev() {
        let text = all_lines.get(i).copied().unwrap_or("").trim();
        if let Some(h) = header_name(text) {
            section = h;
            if key.is_none() && i + 1 == line_no {
                // The error points at the header itself (e.g. a missing field).
                return (Some(line_no), section);
            }
            break;
        }
        if key.is_none() {
            if let Some(k) = key_name(text) {
                key = Some(k);
            }
        }
    }
    let field = match (section.is_empty(), key) {
        (true, Some(k)) => k,
        (false, Some(k)) => format!("{section}.{k}"),
        (_, None) => section,
    };
    (Some(line_no), field)
}

fn header_name(line: &str) -> Option<String> {
    let line = line.split('#').next().unwrap_or("").trim();
    let inner = line.strip_prefix("[[").and_then(|l| l.strip_suffix("]]")).or_else(|| line.strip_prefix('[').and_then(|l| l.strip_suffix(']')))?;
    let name = inner.trim();
    if !name.is_empty() && name.chars().all(|c| c.is_ascii_alphanumeric() || "_-.\"' ".contains(c)) {
        Some(name.to_string())
    } else {
        None
    }
}

fn key_name(line: &str) -> Option<String> {
    let (k, _) = line.split_once('=')?;
    let k = k.trim();
    if !k.is_empty() && k.chars().all(|c| c.is_ascii_alphanumeric() || "_-.\"".contains(c)) {
        Some(k.trim_matches('"').to_string())
    } else {
        None
    }
}

/// The diagonal matrix of a rule for a right leg and/or a hind leg.
fn rule_diag(rule: Rule, right: bool) -> Vector3<f64> {
    match (rule, right) {
        (Rule::Same, _) => Vector3::new(1.0, 1.0, 1.0),
        (Rule::Turn, _) => Vector3::new(-1.0, -1.0, 1.0),
        (Rule::Mirror, true) => Vector3::new(1.0, -1.0, 1.0),
        (Rule::Mirror, false) => Vector3::new(-1.0, 1.0, 1.0),
    }
}

fn is_right(leg: usize) -> bool {
    leg == 1 || leg == 3
}

fn is_hind(leg: usize) -> bool {
    leg >= 2
}

/// `D` for leg `leg` of a segment with rules `right` and `hind`.
fn leg_diag(right: Rule, hind: Rule, leg: usize) -> Vector3<f64> {
    let mut d = Vector3::new(1.0, 1.0, 1.0);
    if is_right(leg) {
        d.component_mul_assign(&rule_diag(right, true));
    }
    if is_hind(leg) {
        d.component_mul_assign(&rule_diag(hind, false));
    }
    d
}

fn inertia_matrix(i: &[f64; 6]) -> Matrix3<f64> {
    let [xx, yy, zz, xy, xz, yz] = *i;
    Matrix3::new(xx, xy, xz, xy, yy, yz, xz, yz, zz)
}

fn v3(a: &[f64; 3]) -> Vector3<f64> {
    Vector3::new(a[0], a[1], a[2])
}

impl Description {
    fn err(&self, field: impl Into<String>, message: impl Into<String>) -> DescriptionError {
        DescriptionError { file: self.file.clone(), line: None, field: field.into(), message: message.into() }
    }

    fn model_err(&self, field: &str, e: ModelError) -> DescriptionError {
        self.err(field, e.to_string())
    }

    fn check_vec(&self, field: &str, v: &[f64]) -> Result<(), DescriptionError> {
        match v.iter().find(|x| !x.is_finite()) {
            Some(x) => Err(self.err(field, format!("expected finite numbers, got {x}"))),
            None => Ok(()),
        }
    }

    fn inertia(&self, field: &str, mass: f64, com: &[f64; 3], inertia: &[f64; 6]) -> Result<Inertia, DescriptionError> {
        if !mass.is_finite() || mass <= 0.0 {
            return Err(self.err(format!("{field}.mass"), format!("expected a finite positive mass in kg, got {mass}")));
        }
        self.check_vec(&format!("{field}.com"), com)?;
        self.check_vec(&format!("{field}.inertia"), inertia)?;
        Inertia::validated(mass, v3(com), inertia_matrix(inertia)).map_err(|e| {
            self.err(
                format!("{field}.inertia"),
                format!("expected [ixx, iyy, izz, ixy, ixz, iyz] of a physical rigid body (positive definite, triangle inequality): {e}"),
            )
        })
    }

    fn pattern(&self, field: &str, pattern: &str, leg: usize) -> Result<String, DescriptionError> {
        if !pattern.contains("{leg}") {
            return Err(self.err(field, format!("expected a name pattern containing {{leg}} so the four legs get distinct names, got \"{pattern}\"")));
        }
        Ok(pattern.replace("{leg}", &self.legs.names[leg]))
    }

    /// Offset of `section` for `leg`: from `offsets`, or `offset` transformed by `d`.
    fn offset(&self, section: &str, offset: &Option<[f64; 3]>, offsets: &Option<[[f64; 3]; 4]>, leg: usize, d: Vector3<f64>) -> Result<Vector3<f64>, DescriptionError> {
        match (offset, offsets) {
            (Some(o), None) => {
                self.check_vec(&format!("{section}.offset"), o)?;
                Ok(v3(o).component_mul(&d))
            }
            (None, Some(os)) => {
                self.check_vec(&format!("{section}.offsets"), os.as_flattened())?;
                Ok(v3(&os[leg]))
            }
            (Some(_), Some(_)) => Err(self.err(format!("{section}.offsets"), "give either `offset` (LF, mirrored) or `offsets` (one per leg), not both")),
            (None, None) => Err(self.err(format!("{section}.offset"), "missing: expected `offset = [x, y, z]` (LF, mirrored) or `offsets` (4 vectors, LF, RF, LH, RH)")),
        }
    }

    fn limits(&self, name: &str, s: &SegmentSection, leg: usize) -> Result<JointLimits, DescriptionError> {
        let (lo, hi, vel, eff) = (s.lower.get(leg), s.upper.get(leg), s.velocity.get(leg), s.effort.get(leg));
        let leg_name = LEG_ORDER[leg];
        if lo.is_nan() || hi.is_nan() || lo > hi {
            return Err(self.err(format!("{name}.lower"), format!("expected lower <= upper, got [{lo}, {hi}] for leg {leg_name}")));
        }
        if vel.is_nan() || vel <= 0.0 {
            return Err(self.err(format!("{name}.velocity"), format!("expected a positive velocity limit in rad/s, got {vel} for leg {leg_name}")));
        }
        if eff.is_nan() || eff <= 0.0 {
            return Err(self.err(format!("{name}.effort"), format!("expected a positive effort limit in N m, got {eff} for leg {leg_name}")));
        }
        Ok(JointLimits::new(lo, hi, vel, eff))
    }

    fn check(&self) -> Result<(), DescriptionError> {
        if self.format != FORMAT_VERSION {
            return Err(self.err("format", format!("expected {FORMAT_VERSION} (the only version this legwork reads), got {}", self.format)));
        }
        if self.name.trim().is_empty() {
            return Err(self.err("name", "expected a non-empty robot name"));
        }
        if self.base.body.trim().is_empty() {
            return Err(self.err("base.body", "expected a non-empty body name"));
        }
        for (k, n) in self.legs.names.iter().enumerate() {
            if n.trim().is_empty() {
                return Err(self.err("legs.names", format!("expected a non-empty name for leg {}", LEG_ORDER[k])));
            }
            if self.legs.names[..k].contains(n) {
                return Err(self.err("legs.names", format!("expected 4 distinct names, \"{n}\" appears twice")));
            }
        }
        for (name, s) in self.segments() {
            self.check_vec(&format!("{name}.axis"), &s.axis)?;
            if v3(&s.axis).norm() < 1e-9 {
                return Err(self.err(format!("{name}.axis"), "expected a non-zero axis vector"));
            }
            for (k, sign) in s.signs.0.iter().enumerate() {
                if *sign != 1.0 && *sign != -1.0 {
                    return Err(self.err(format!("{name}.signs"), format!("expected 1 or -1, got {sign} for leg {}", LEG_ORDER[k])));
                }
            }
        }
        let r = self.foot.radius;
        if !r.is_finite() || r <= 0.0 {
            return Err(self.err("foot.radius", format!("expected a finite positive radius in m, got {r}")));
        }
        if self.foot.mass.is_none() && self.foot.inertia.is_some() {
            return Err(self.err("foot.inertia", "given without `foot.mass`: give both, or neither for a massless foot frame"));
        }
        Ok(())
    }

    /// The `[contact]` section over the calibration for the robot's foot load.
    fn contact(&self, model: &Model) -> Result<crate::contact::ContactParams, DescriptionError> {
        let c = &self.contact;
        let mut p = model.calibrated_contact();
        for (value, field) in [
            (c.alpha, &mut p.alpha),
            (c.normal_stiffness, &mut p.normal_stiffness),
            (c.normal_damping, &mut p.normal_damping),
            (c.tangential_stiffness, &mut p.tangential_stiffness),
            (c.tangential_damping, &mut p.tangential_damping),
            (c.friction, &mut p.friction),
            (c.max_step, &mut p.max_step),
        ] {
            if let Some(v) = value {
                *field = v;
            }
        }
        p.validate().map_err(|e| self.err(format!("contact.{}", e.field), format!("expected {}, got {}", e.expected, e.value)))?;
        Ok(p)
    }

    fn segments(&self) -> [(&'static str, &SegmentSection); 3] {
        [("hip", &self.hip), ("thigh", &self.thigh), ("shank", &self.shank)]
    }

    /// Builds the model (see the module documentation for its layout).
    pub fn build(&self) -> Result<Model, DescriptionError> {
        self.check()?;
        let mut model = Model::new(self.name.clone());
        let root = model
            .add_joint(0, "root_joint", JointKind::FreeFlyer, SE3::identity(), JointLimits::unbounded(6))
            .map_err(|e| self.model_err("base", e))?;
        let base_inertia = self.inertia("base", self.base.mass, &self.base.com, &self.base.inertia)?;
        model.append_body(root, self.base.body.clone(), base_inertia, SE3::identity());

        // LF-leg bodies, checked once (the rules preserve validity).
        let body_inertias: Vec<Inertia> = self
            .segments()
            .iter()
            .map(|(name, s)| self.inertia(name, s.mass, &s.com, &s.inertia))
            .collect::<Result<_, _>>()?;
        let foot_inertia = match (self.foot.mass, &self.foot.inertia) {
            (Some(m), Some(i)) => Some(self.inertia("foot", m, &self.foot.com, i)?),
            (Some(_), None) => return Err(self.err("foot.inertia", "missing: a foot with `mass` needs `inertia = [ixx, iyy, izz, ixy, ixz, iyz]`")),
            _ => None,
        };

        let mut names = vec!["root_joint".to_string(), self.base.body.clone()];
        let mut feet = Vec::with_capacity(4);
        for leg in 0..4 {
            let mut parent = root;
            // The segment whose body carries the joint being placed: the base for the hip
            // (always mirrored), else the previous segment.
            let mut carrier_rules = (Rule::Mirror, Rule::Mirror);
            for ((name, s), inertia) in self.segments().into_iter().zip(&body_inertias) {
                let d_place = leg_diag(carrier_rules.0, carrier_rules.1, leg);
                let offset = self.offset(name, &s.offset, &s.offsets, leg, d_place)?;
                let joint_name = self.pattern(&format!("{name}.joint"), &s.joint, leg)?;
                let body_name = self.pattern(&format!("{name}.body"), &s.body, leg)?;
                let axis = v3(&s.axis).normalize() * s.signs.get(leg);
                let limits = self.limits(name, s, leg)?;
                let j = model
                    .add_joint(parent, joint_name.clone(), JointKind::revolute(axis), SE3::new(Matrix3::identity(), offset), limits)
                    .map_err(|e| self.model_err(&format!("{name}.joint"), e))?;
                let d = leg_diag(s.right, s.hind, leg);
                let dm = Matrix3::from_diagonal(&d);
                let body = Inertia::new(inertia.mass, inertia.com.component_mul(&d), dm * inertia.inertia_com * dm);
                model.append_body(j, body_name.clone(), body, SE3::identity());
                names.push(joint_name);
                names.push(body_name);
                parent = j;
                carrier_rules = (s.right, s.hind);
            }
            let d = leg_diag(self.shank.right, self.shank.hind, leg);
            let foot_offset = self.offset("foot", &self.foot.offset, &self.foot.offsets, leg, d)?;
            let foot_name = self.pattern("foot.frame", &self.foot.frame, leg)?;
            let placement = SE3::new(Matrix3::identity(), foot_offset);
            match &foot_inertia {
                Some(fi) => {
                    let dm = Matrix3::from_diagonal(&d);
                    let body = Inertia::new(fi.mass, fi.com.component_mul(&d), dm * fi.inertia_com * dm);
                    model.append_body(parent, foot_name.clone(), body, placement);
                }
                None => {
                    model
                        .add_frame(Frame { name: foot_name.clone(), kind: FrameKind::Body, parent_joint: parent, placement })
                        .map_err(|e| self.model_err("foot.frame", e))?;
                }
            }
            names.push(foot_name.clone());
            feet.push(foot_name);
        }
        for (k, n) in names.iter().enumerate() {
            if names[..k].contains(n) {
                return Err(self.err("", format!("the name \"{n}\" is used twice (joint, body and foot names must be distinct)")));
            }
        }
        let feet_refs: Vec<&str> = feet.iter().map(String::as_str).collect();
        model.set_feet(&feet_refs, self.foot.radius).map_err(|e| self.model_err("foot.frame", e))?;

        if let Some(st) = &self.standing {
            if !st.base_height.is_finite() {
                return Err(self.err("standing.base_height", format!("expected a finite height in m, got {}", st.base_height)));
            }
            let mut q = model.neutral();
            q[2] = st.base_height;
            for (name, s, values) in [("hip", &self.hip, &st.hip), ("thigh", &self.thigh, &st.thigh), ("shank", &self.shank, &st.shank)] {
                for (leg, leg_name) in LEG_ORDER.iter().enumerate() {
                    let v = values.get(leg);
                    let (lo, hi) = (s.lower.get(leg), s.upper.get(leg));
                    if !v.is_finite() || v < lo || v > hi {
                        return Err(self.err(
                            format!("standing.{name}"),
                            format!("expected an angle within the joint limits [{lo}, {hi}] for leg {leg_name}, got {v}"),
                        ));
                    }
                    let jn = s.joint.replace("{leg}", &self.legs.names[leg]);
                    q[model.q_index(&jn).map_err(|e| self.model_err(&format!("standing.{name}"), e))?] = v;
                }
            }
            model.reference_configurations.push(("standing".to_string(), q));
        }
        model.contact = self.contact(&model)?;
        Ok(model)
    }
}
