//! MuJoCo's MJCF from legwork's own [`Model`] and a [`TerrainSpec`].
//!
//! One MuJoCo body per legwork joint (legwork lumps the links merged through fixed joints
//! into their joint's body, [`Model::inertias`]), nested as the kinematic tree, in
//! legwork's depth-first order, so MuJoCo's `qpos` / `qvel` / actuator order is legwork's
//! joint order. Each body sits at its joint's placement in the parent joint's frame; its
//! `inertial` is the lumped inertia (centre of mass and `fullinertia` about it, in the
//! joint frame's axes). The base has a free joint; revolute and prismatic joints are
//! `hinge` / `slide` joints with their `range` (`limited` where legwork's limits are
//! finite). Every actuated joint has a torque `motor` with `ctrlrange` and `forcerange` at
//! its effort limit. The foot spheres are the robot's only collision geoms (the capsules
//! drawn along the links are visual: `contype = conaffinity = 0`); a foot collides with
//! the ground and not with another foot. Friction is the contact model's (legwork's
//! robot's contact model, [`Model::contact`]) on the feet and the ground alike, so
//! MuJoCo's pairwise maximum is that number. Nothing else is set: no armature, no joint
//! damping (legwork's model has neither), MuJoCo's default contact parameters
//! (`solref`, `solimp`), its default integrator, the given time step.
//!
//! Conventions: MuJoCo's free-joint `qpos` quaternion is `(w, x, y, z)`, legwork's (and
//! Pinocchio's) `(x, y, z, w)`; MuJoCo's free-joint `qvel` has the linear velocity in the
//! world frame and the angular velocity in the body frame, legwork's both in the base
//! frame. [`mujoco_qpos`] and [`mujoco_qvel`] convert.
//!
//! Terrain: a plane is a MuJoCo `plane` through `(0, 0, elevation)` with the plane's
//! normal as its z axis; a height map is an `hfield` on the same grid (MuJoCo draws two
//! triangles per cell where legwork interpolates bilinearly, so the two agree at the grid
//! points and on flat cells, and differ by less than the cell's twist elsewhere; and
//! MuJoCo's field ends at the grid's border, where legwork's extends the border heights;
//! and MuJoCo stores the field's data in single precision, 6e-8 of the height span). Boxes
//! on the ground are a plane and one `box` geom per box, from the ground to its top (MuJoCo's
//! boxes have sides a foot can hit; legwork's terrain is a height function, see
//! [`crate::terrain::Boxes`]).
//!
//! Numbers are written with Rust's shortest round-trip formatting: the file holds the
//! model's `f64`s exactly.

use crate::model::{JointKind, Model};
use crate::spatial::SE3;
use crate::terrain::{HeightMapFile, TerrainSpec};
use nalgebra::{DVector, Rotation3, UnitQuaternion, Vector3};
use std::fmt::Write;

/// Settings of the export.
#[derive(Clone, Debug, PartialEq)]
pub struct MjcfSettings {
    /// MuJoCo's physics time step (s). Default 0.001 (1 ms, issue 16's set-up).
    pub timestep: f64,
    /// Sliding friction coefficient of the feet and the ground; `None` (the default): the
    /// robot's contact model's, [`Model::contact`]'s `friction` (0.8 for HyQ and A1).
    pub friction: Option<f64>,
    /// Radius of the visual capsules drawn along the links (m). Default 0.02.
    pub visual_radius: f64,
    /// Depth of a height field's base below its lowest point (m; MuJoCo's `hfield` `size[3]`,
    /// which must be positive). Default 0.1.
    pub hfield_base_depth: f64,
}

impl Default for MjcfSettings {
    fn default() -> Self {
        Self { timestep: 0.001, friction: None, visual_radius: 0.02, hfield_base_depth: 0.1 }
    }
}

/// Why a model or terrain cannot be written as MJCF; names the joint, field or setting.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MjcfError {
    #[error("setting `{field}`: expected {expected}, got {value}")]
    Setting { field: &'static str, expected: &'static str, value: f64 },
    #[error("joint '{joint}': {problem} (MuJoCo needs every moving body to have a positive mass and a physical inertia)")]
    Inertia { joint: String, problem: String },
    #[error("joint '{joint}': {problem}")]
    Joint { joint: String, problem: String },
    #[error("robot '{robot}' has no joints")]
    Empty { robot: String },
    #[error("terrain field `{field}`: {problem}")]
    Terrain { field: String, problem: String },
    #[error("configuration: {0}")]
    Configuration(String),
}

/// The MJCF document of `model` standing on `terrain`, with a `standing` keyframe when the
/// model has a `standing` reference configuration (its base as stored there).
///
/// ```
/// use legwork::export::{mjcf_model, MjcfSettings};
/// use legwork::terrain::TerrainSpec;
/// let model = legwork::model::embedded::load("hyq").unwrap();
/// let xml = mjcf_model(&model, &TerrainSpec::flat(), &MjcfSettings::default()).unwrap();
/// assert!(xml.contains("<freejoint name=\"root_joint\"/>"));
/// assert_eq!(xml.matches("<motor ").count(), 12);
/// ```
pub fn mjcf_model(model: &Model, terrain: &TerrainSpec, settings: &MjcfSettings) -> Result<String, MjcfError> {
    check_settings(settings)?;
    let friction = settings.friction.unwrap_or(model.contact.friction);
    if model.njoints() < 2 {
        return Err(MjcfError::Empty { robot: model.name.clone() });
    }
    let mut xml = String::new();
    let g = model.gravity.v;
    // `write!` into a String cannot fail; the results are ignored.
    let _ = writeln!(xml, "<mujoco model=\"{}\">", escape(&model.name));
    let _ = writeln!(xml, "  <!-- Written by legwork {} from its own model of '{}' (legwork export mjcf). -->", env!("CARGO_PKG_VERSION"), escape(&model.name));
    let _ = writeln!(xml, "  <compiler angle=\"radian\" autolimits=\"false\" inertiafromgeom=\"false\"/>");
    let _ = writeln!(xml, "  <option timestep=\"{}\" gravity=\"{}\"/>", num(settings.timestep), vec3(&g));
    if let TerrainSpec::HeightMap(file) = terrain {
        let field = HeightField::of(file)?;
        let _ = writeln!(xml, "  <asset>");
        let _ = writeln!(xml, "    <hfield name=\"terrain\" nrow=\"{}\" ncol=\"{}\" size=\"{} {} {} {}\" elevation=\"{}\"/>", field.rows, field.columns, num(field.radius[0]), num(field.radius[1]), num(field.top), num(settings.hfield_base_depth), field.elevation.iter().map(|&x| num(x)).collect::<Vec<_>>().join(" "));
        let _ = writeln!(xml, "  </asset>");
    }
    let _ = writeln!(xml, "  <worldbody>");
    write_terrain(&mut xml, terrain, friction)?;
    for child in children(model, 0) {
        write_body(&mut xml, model, child, 2, settings, friction)?;
    }
    let _ = writeln!(xml, "  </worldbody>");
    let actuated: Vec<_> = model.actuated_joints().collect();
    if !actuated.is_empty() {
        let _ = writeln!(xml, "  <actuator>");
        for j in actuated {
            let e = j.limits.effort[0];
            let limits = if e.is_finite() {
                format!(" ctrllimited=\"true\" ctrlrange=\"{} {}\" forcelimited=\"true\" forcerange=\"{} {}\"", num(-e), num(e), num(-e), num(e))
            } else {
                " ctrllimited=\"false\" forcelimited=\"false\"".to_string()
            };
            let _ = writeln!(xml, "    <motor name=\"{}\" joint=\"{}\" gear=\"1\"{limits}/>", escape(&j.name), escape(&j.name));
        }
        let _ = writeln!(xml, "  </actuator>");
    }
    if let Some(q) = model.reference_configuration("standing") {
        let qpos = mujoco_qpos(model, q)?;
        let _ = writeln!(xml, "  <keyframe>");
        let _ = writeln!(xml, "    <key name=\"standing\" qpos=\"{}\"/>", qpos.iter().map(|&x| num(x)).collect::<Vec<_>>().join(" "));
        let _ = writeln!(xml, "  </keyframe>");
    }
    let _ = writeln!(xml, "</mujoco>");
    Ok(xml)
}

fn check_settings(s: &MjcfSettings) -> Result<(), MjcfError> {
    let positive = [("timestep", s.timestep), ("visual_radius", s.visual_radius), ("hfield_base_depth", s.hfield_base_depth)];
    for (field, value) in positive {
        if !(value.is_finite() && value > 0.0) {
            return Err(MjcfError::Setting { field, expected: "a finite number > 0", value });
        }
    }
    if let Some(friction) = s.friction {
        if !(friction.is_finite() && friction >= 0.0) {
            return Err(MjcfError::Setting { field: "friction", expected: "a finite number >= 0", value: friction });
        }
    }
    Ok(())
}

/// MuJoCo's `qpos` of legwork's `q`: the base quaternion reordered `(x, y, z, w)` ->
/// `(w, x, y, z)`, everything else as it is.
pub fn mujoco_qpos(model: &Model, q: &DVector<f64>) -> Result<Vec<f64>, MjcfError> {
    model.check_configuration(q).map_err(|e| MjcfError::Configuration(e.to_string()))?;
    let mut out = q.as_slice().to_vec();
    if model.has_free_flyer() {
        let i = model.joints[1].idx_q;
        let (x, y, z, w) = (q[i + 3], q[i + 4], q[i + 5], q[i + 6]);
        out[i + 3..i + 7].copy_from_slice(&[w, x, y, z]);
    }
    Ok(out)
}

/// MuJoCo's `qvel` of legwork's `(q, v)`: the base's linear velocity rotated from the base
/// frame into the world frame (`R v_B`), its angular velocity kept in the base frame.
pub fn mujoco_qvel(model: &Model, q: &DVector<f64>, v: &DVector<f64>) -> Result<Vec<f64>, MjcfError> {
    model.check_configuration(q).map_err(|e| MjcfError::Configuration(e.to_string()))?;
    model.check_tangent("v", v).map_err(|e| MjcfError::Configuration(e.to_string()))?;
    let mut out = v.as_slice().to_vec();
    if model.has_free_flyer() {
        let (iq, iv) = (model.joints[1].idx_q, model.joints[1].idx_v);
        let r = crate::dynamics::base_orientation(&q.as_slice()[iq..]).to_rotation_matrix().into_inner();
        let world = r * Vector3::new(v[iv], v[iv + 1], v[iv + 2]);
        out[iv..iv + 3].copy_from_slice(world.as_slice());
    }
    Ok(out)
}

/// The joints whose parent is `parent`, in depth-first order.
fn children(model: &Model, parent: usize) -> impl Iterator<Item = usize> + '_ {
    (1..model.njoints()).filter(move |&i| model.joints[i].parent == parent)
}

/// The MuJoCo body name of joint `i`: its first body frame (the URDF link), else the
/// joint's name with `_body`.
fn body_name(model: &Model, i: usize) -> String {
    model
        .frames
        .iter()
        .find(|f| f.parent_joint == i && f.kind == crate::model::FrameKind::Body)
        .map(|f| f.name.clone())
        .unwrap_or_else(|| format!("{}_body", model.joints[i].name))
}

fn write_body(xml: &mut String, model: &Model, i: usize, depth: usize, settings: &MjcfSettings, friction: f64) -> Result<(), MjcfError> {
    let joint = &model.joints[i];
    let pad = "  ".repeat(depth);
    let _ = writeln!(xml, "{pad}<body name=\"{}\" {}>", escape(&body_name(model, i)), pose(&joint.placement));
    write_inertial(xml, model, i, &pad)?;
    match joint.kind {
        JointKind::FreeFlyer => {
            let _ = writeln!(xml, "{pad}  <freejoint name=\"{}\"/>", escape(&joint.name));
        }
        JointKind::Revolute { axis } | JointKind::Prismatic { axis } => {
            let kind = if matches!(joint.kind, JointKind::Revolute { .. }) { "hinge" } else { "slide" };
            let (lo, hi) = (joint.limits.lower[0], joint.limits.upper[0]);
            let limits = match (lo.is_finite(), hi.is_finite()) {
                (true, true) => format!(" limited=\"true\" range=\"{} {}\"", num(lo), num(hi)),
                (false, false) => " limited=\"false\"".to_string(),
                _ => return Err(MjcfError::Joint { joint: joint.name.clone(), problem: format!("MJCF has no one-sided joint range: [{lo}, {hi}]") }),
            };
            let _ = writeln!(xml, "{pad}  <joint name=\"{}\" type=\"{kind}\" pos=\"0 0 0\" axis=\"{}\"{limits}/>", escape(&joint.name), vec3(&axis));
        }
        JointKind::Universe => {}
    }
    // Visual capsules from this joint to each child joint and to each foot on it.
    let mut ends: Vec<Vector3<f64>> = children(model, i).map(|c| model.joints[c].placement.translation).collect();
    let feet: Vec<_> = model.feet.iter().filter(|f| model.frames[f.frame].parent_joint == i).collect();
    ends.extend(feet.iter().map(|f| model.frames[f.frame].placement.translation));
    for end in ends.iter().filter(|e| e.norm() > 1e-6) {
        let _ = writeln!(xml, "{pad}  <geom type=\"capsule\" fromto=\"0 0 0 {}\" size=\"{}\" contype=\"0\" conaffinity=\"0\" group=\"1\"/>", vec3(end), num(settings.visual_radius));
    }
    for foot in feet {
        let p = model.frames[foot.frame].placement.translation;
        if !(foot.radius.is_finite() && foot.radius > 0.0) {
            return Err(MjcfError::Joint { joint: joint.name.clone(), problem: format!("foot '{}' has radius {}, expected a positive number of metres", foot.name, foot.radius) });
        }
        // contype 1, conaffinity 0: a foot collides with the ground (conaffinity 1), not
        // with another foot, as in legwork's contact model.
        let _ = writeln!(xml, "{pad}  <geom name=\"{}\" type=\"sphere\" size=\"{}\" pos=\"{}\" friction=\"{} 0.005 0.0001\" contype=\"1\" conaffinity=\"0\" condim=\"3\" group=\"0\"/>", escape(&foot.name), num(foot.radius), vec3(&p), num(friction));
    }
    for child in children(model, i) {
        write_body(xml, model, child, depth + 1, settings, friction)?;
    }
    let _ = writeln!(xml, "{pad}</body>");
    Ok(())
}

/// The lumped inertia of joint `i`'s body: mass, centre of mass and the rotational inertia
/// about it in the joint frame's axes (MuJoCo diagonalises `fullinertia` itself).
fn write_inertial(xml: &mut String, model: &Model, i: usize, pad: &str) -> Result<(), MjcfError> {
    let inertia = &model.inertias[i];
    let joint = &model.joints[i].name;
    let bad = |problem: String| MjcfError::Inertia { joint: joint.clone(), problem };
    if !(inertia.mass.is_finite() && inertia.mass > 0.0) {
        return Err(bad(format!("body mass {} kg, expected a positive number", inertia.mass)));
    }
    let c = &inertia.inertia_com;
    if !c.iter().all(|x| x.is_finite()) || (c - c.transpose()).norm() > 1e-12 * c.norm().max(f64::MIN_POSITIVE) {
        return Err(bad("rotational inertia is not finite and symmetric".into()));
    }
    let mut e: Vec<f64> = nalgebra::SymmetricEigen::new(*c).eigenvalues.iter().copied().collect();
    e.sort_by(|a, b| a.total_cmp(b));
    if e[0] <= 0.0 {
        return Err(bad(format!("rotational inertia is not positive definite (principal moments {e:?})")));
    }
    // MuJoCo refuses principal moments that break the triangle inequality (unless its
    // `balanceinertia` is on, which would change the model).
    if e[0] + e[1] < e[2] {
        return Err(bad(format!("principal moments {e:?} break the triangle inequality")));
    }
    let _ = writeln!(
        xml,
        "{pad}  <inertial pos=\"{}\" mass=\"{}\" fullinertia=\"{} {} {} {} {} {}\"/>",
        vec3(&inertia.com),
        num(inertia.mass),
        num(c[(0, 0)]),
        num(c[(1, 1)]),
        num(c[(2, 2)]),
        num(c[(0, 1)]),
        num(c[(0, 2)]),
        num(c[(1, 2)])
    );
    Ok(())
}

/// The ground geom: a plane (its z axis the plane's normal) or the height field.
fn write_terrain(xml: &mut String, terrain: &TerrainSpec, friction: f64) -> Result<(), MjcfError> {
    let friction = num(friction);
    match terrain {
        TerrainSpec::Plane { elevation, normal } => {
            let n = Vector3::from(*normal);
            if !(elevation.is_finite() && n.iter().all(|x| x.is_finite()) && n.norm() > 0.0 && n.z > 0.0) {
                return Err(MjcfError::Terrain { field: "normal".into(), problem: format!("a plane needs a finite elevation and an upward normal, got {elevation} and {normal:?}") });
            }
            let n = n.normalize();
            let rotation = UnitQuaternion::rotation_between(&Vector3::z(), &n).unwrap_or_else(UnitQuaternion::identity);
            let ground = SE3::new(rotation.to_rotation_matrix().into_inner(), Vector3::new(0.0, 0.0, *elevation));
            let _ = writeln!(xml, "    <geom name=\"ground\" type=\"plane\" size=\"0 0 1\" {} friction=\"{friction} 0.005 0.0001\" contype=\"1\" conaffinity=\"1\" condim=\"3\"/>", pose(&ground));
        }
        TerrainSpec::HeightMap(file) => {
            let field = HeightField::of(file)?;
            let _ = writeln!(xml, "    <geom name=\"ground\" type=\"hfield\" hfield=\"terrain\" pos=\"{}\" friction=\"{friction} 0.005 0.0001\" contype=\"1\" conaffinity=\"1\" condim=\"3\"/>", vec3(&field.centre));
        }
        TerrainSpec::Boxes { ground, boxes } => {
            let checked = crate::terrain::Boxes::new(*ground, boxes.clone()).map_err(|(field, problem)| MjcfError::Terrain { field, problem })?;
            let _ = writeln!(xml, "    <geom name=\"ground\" type=\"plane\" size=\"0 0 1\" pos=\"0 0 {}\" friction=\"{friction} 0.005 0.0001\" contype=\"1\" conaffinity=\"1\" condim=\"3\"/>", num(*ground));
            // A box geom from the ground up to its top: `size` holds half-extents.
            for (i, b) in checked.boxes().iter().enumerate() {
                let centre = Vector3::new(0.5 * (b.x[0] + b.x[1]), 0.5 * (b.y[0] + b.y[1]), 0.5 * (ground + b.top));
                let half = Vector3::new(0.5 * (b.x[1] - b.x[0]), 0.5 * (b.y[1] - b.y[0]), 0.5 * (b.top - ground));
                let _ = writeln!(xml, "    <geom name=\"box{i}\" type=\"box\" pos=\"{}\" size=\"{}\" friction=\"{friction} 0.005 0.0001\" contype=\"1\" conaffinity=\"1\" condim=\"3\" rgba=\"0.62 0.55 0.45 1\"/>", vec3(&centre), vec3(&half));
            }
        }
    }
    Ok(())
}

/// A legwork height map as MuJoCo's `hfield`: the field spans `centre +- radius` in x and
/// y; its elevation data are row-major with MuJoCo's first row at the highest y (legwork's
/// first row is at the lowest y: the rows are written in reverse; checked with MuJoCo's
/// ray casts in tests/mujoco_check.rs), the heights above the lowest one scaled to
/// [0, 1], `top` the scale, and the geom sits at the lowest height. Data already in
/// [0, 1] make MuJoCo's own normalisation a no-op.
struct HeightField {
    rows: usize,
    columns: usize,
    radius: [f64; 2],
    top: f64,
    centre: Vector3<f64>,
    elevation: Vec<f64>,
}

impl HeightField {
    fn of(file: &HeightMapFile) -> Result<Self, MjcfError> {
        let rows = file.heights.len();
        let columns = file.heights.first().map_or(0, |r| r.len());
        if rows < 2 || columns < 2 || file.heights.iter().any(|r| r.len() != columns) {
            return Err(MjcfError::Terrain { field: "heights".into(), problem: format!("expected at least 2 x 2 heights in rows of equal length, got {rows} rows") });
        }
        let positive_resolution = file.resolution.is_finite() && file.resolution > 0.0;
        if !positive_resolution || !file.origin.iter().all(|x| x.is_finite()) {
            return Err(MjcfError::Terrain { field: "resolution".into(), problem: format!("expected a positive resolution and a finite origin, got {} and {:?}", file.resolution, file.origin) });
        }
        let all = file.heights.iter().flatten().copied();
        if let Some(x) = all.clone().find(|x| !x.is_finite()) {
            return Err(MjcfError::Terrain { field: "heights".into(), problem: format!("expected finite heights, got {x}") });
        }
        let low = all.clone().fold(f64::INFINITY, f64::min);
        let high = all.fold(f64::NEG_INFINITY, f64::max);
        // A flat map still needs a positive elevation scale; its data are all zero.
        let top = if high > low { high - low } else { 1.0 };
        let radius = [0.5 * (columns - 1) as f64 * file.resolution, 0.5 * (rows - 1) as f64 * file.resolution];
        let centre = Vector3::new(file.origin[0] + radius[0], file.origin[1] + radius[1], low);
        let elevation = file.heights.iter().rev().flatten().map(|h| (h - low) / top).collect();
        Ok(Self { rows, columns, radius, top, centre, elevation })
    }
}

/// `pos="x y z" quat="w x y z"` of a placement.
fn pose(m: &SE3) -> String {
    let q = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(m.rotation));
    format!("pos=\"{}\" quat=\"{} {} {} {}\"", vec3(&m.translation), num(q.w), num(q.i), num(q.j), num(q.k))
}

fn vec3(v: &Vector3<f64>) -> String {
    format!("{} {} {}", num(v.x), num(v.y), num(v.z))
}

/// Shortest round-trip decimal form (`-0` written as `0`).
fn num(x: f64) -> String {
    if x == 0.0 {
        "0".into()
    } else {
        format!("{x}")
    }
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;").replace('\'', "&apos;")
}

/// The inertia matrix about the centre of mass back from `fullinertia`'s six numbers.
#[cfg(test)]
fn full_inertia(values: &[f64]) -> nalgebra::Matrix3<f64> {
    nalgebra::Matrix3::new(values[0], values[3], values[4], values[3], values[1], values[5], values[4], values[5], values[2])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::embedded;

    fn attr(e: &xml::Element, name: &str) -> String {
        e.get_attribute(name, None).unwrap_or_else(|| panic!("<{}> has no {name}", e.name)).to_string()
    }
    fn numbers(s: &str) -> Vec<f64> {
        s.split_whitespace().map(|x| x.parse().unwrap()).collect()
    }
    fn parse(text: &str) -> xml::Element {
        text.parse::<xml::Element>().expect("well-formed XML")
    }
    /// Every element named `name` under `e`, depth first.
    fn all<'e>(e: &'e xml::Element, name: &str, out: &mut Vec<&'e xml::Element>) {
        for child in e.children.iter().filter_map(|c| if let xml::Xml::ElementNode(el) = c { Some(el) } else { None }) {
            if child.name == name {
                out.push(child);
            }
            all(child, name, out);
        }
    }
    fn elements<'e>(e: &'e xml::Element, name: &str) -> Vec<&'e xml::Element> {
        let mut out = Vec::new();
        all(e, name, &mut out);
        out
    }

    /// HyQ and A1: the document parses; one body per joint; masses sum to the model's total;
    /// every inertia is positive definite and is the model's, to the last bit; joints,
    /// ranges and motors in legwork's order; the feet are the only colliding geoms.
    #[test]
    fn the_embedded_robots_as_mjcf() {
        for name in ["hyq", "a1"] {
            let model = embedded::load(name).unwrap();
            let text = mjcf_model(&model, &TerrainSpec::flat(), &MjcfSettings::default()).unwrap();
            let root = parse(&text);
            assert_eq!(root.name, "mujoco");
            let bodies = elements(&root, "body");
            assert_eq!(bodies.len(), model.njoints() - 1, "{name}");
            let inertials = elements(&root, "inertial");
            let mass: f64 = inertials.iter().map(|i| attr(i, "mass").parse::<f64>().unwrap()).sum();
            assert!((mass - model.total_mass()).abs() < 1e-12 * model.total_mass(), "{name}: {mass} against {}", model.total_mass());
            for (k, inertial) in inertials.iter().enumerate() {
                let i = &model.inertias[k + 1];
                let full = full_inertia(&numbers(&attr(inertial, "fullinertia")));
                assert_eq!(full, i.inertia_com, "{name} body {k}");
                assert!(full.cholesky().is_some(), "{name} body {k}: not positive definite");
                assert_eq!(numbers(&attr(inertial, "pos")), i.com.as_slice());
            }
            let joints = elements(&root, "joint");
            let actuated: Vec<_> = model.actuated_joints().collect();
            assert_eq!(joints.len(), actuated.len());
            for (j, legwork) in joints.iter().zip(&actuated) {
                assert_eq!(attr(j, "name"), legwork.name);
                assert_eq!(attr(j, "type"), "hinge");
                assert_eq!(numbers(&attr(j, "range")), vec![legwork.limits.lower[0], legwork.limits.upper[0]]);
            }
            assert_eq!(elements(&root, "freejoint").len(), 1);
            let motors = elements(&root, "motor");
            assert_eq!(motors.iter().map(|m| attr(m, "joint")).collect::<Vec<_>>(), model.actuated_joint_names());
            for (m, j) in motors.iter().zip(&actuated) {
                let e = j.limits.effort[0];
                assert_eq!(numbers(&attr(m, "forcerange")), vec![-e, e]);
                assert_eq!(numbers(&attr(m, "ctrlrange")), vec![-e, e]);
            }
            let geoms = elements(&root, "geom");
            let colliding: Vec<_> = geoms.iter().filter(|g| g.get_attribute("contype", None) != Some("0")).collect();
            let names: Vec<String> = colliding.iter().map(|g| attr(g, "name")).collect();
            let mut expected: Vec<String> = vec!["ground".into()];
            expected.extend(model.feet.iter().map(|f| f.name.clone()));
            assert_eq!(names, expected, "{name}");
            for g in colliding.iter().skip(1) {
                assert_eq!(numbers(&attr(g, "size")), vec![model.feet[0].radius]);
                assert_eq!(numbers(&attr(g, "friction"))[0], 0.8);
            }
            // No armature, damping or contact tuning.
            for banned in ["armature", "damping", "solref", "solimp", "margin"] {
                assert!(!text.contains(banned), "{name}: MJCF sets {banned}");
            }
            assert_eq!(numbers(&attr(elements(&root, "option")[0], "timestep")), vec![0.001]);
        }
    }

    /// The standing keyframe is the standing configuration with the quaternion reordered;
    /// the velocity conversion rotates the base's linear velocity into the world.
    #[test]
    fn keyframe_and_state_conversions() {
        let model = embedded::load("hyq").unwrap();
        let q = model.reference_configuration("standing").unwrap().clone();
        let text = mjcf_model(&model, &TerrainSpec::flat(), &MjcfSettings::default()).unwrap();
        let root = parse(&text);
        let key = &elements(&root, "key")[0];
        let qpos = numbers(&attr(key, "qpos"));
        assert_eq!(qpos.len(), model.nq);
        assert_eq!(&qpos[..3], &q.as_slice()[..3]);
        assert_eq!(qpos[3], q[6]);
        assert_eq!(&qpos[4..7], &q.as_slice()[3..6]);
        assert_eq!(&qpos[7..], &q.as_slice()[7..]);
        // Base yawed by 90 degrees: forward in the base frame is +y in the world.
        let mut q = q;
        let yaw = UnitQuaternion::from_euler_angles(0.0, 0.0, std::f64::consts::FRAC_PI_2);
        q.rows_mut(3, 4).copy_from_slice(&[yaw.i, yaw.j, yaw.k, yaw.w]);
        let mut v = DVector::zeros(model.nv);
        v[0] = 1.0;
        v[5] = 0.5;
        let qvel = mujoco_qvel(&model, &q, &v).unwrap();
        assert!((qvel[0]).abs() < 1e-15 && (qvel[1] - 1.0).abs() < 1e-15 && qvel[2].abs() < 1e-15, "{qvel:?}");
        assert_eq!(qvel[5], 0.5);
    }

    /// A tilted plane's geom has the plane's normal as its z axis and passes through
    /// (0, 0, elevation); a height map becomes an hfield on the same grid.
    #[test]
    fn terrains() {
        let model = embedded::load("a1").unwrap();
        let normal = [0.1, -0.2, 1.0];
        let text = mjcf_model(&model, &TerrainSpec::Plane { elevation: 0.3, normal }, &MjcfSettings::default()).unwrap();
        let root = parse(&text);
        let ground = elements(&root, "geom").into_iter().find(|g| g.get_attribute("name", None) == Some("ground")).unwrap();
        assert_eq!(numbers(&attr(ground, "pos")), vec![0.0, 0.0, 0.3]);
        let w = numbers(&attr(ground, "quat"));
        let rotation = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(w[0], w[1], w[2], w[3]));
        let n = Vector3::from(normal).normalize();
        assert!((rotation * Vector3::z() - n).norm() < 1e-15);

        let file = HeightMapFile { origin: [-1.0, -0.5], resolution: 0.5, heights: vec![vec![0.0, 0.0, 0.1], vec![0.0, 0.3, 0.1]] };
        let text = mjcf_model(&model, &TerrainSpec::HeightMap(file), &MjcfSettings::default()).unwrap();
        let root = parse(&text);
        let hfield = &elements(&root, "hfield")[0];
        assert_eq!((attr(hfield, "nrow"), attr(hfield, "ncol")), ("2".into(), "3".into()));
        assert_eq!(numbers(&attr(hfield, "size")), vec![0.5, 0.25, 0.3, 0.1]);
        let e = numbers(&attr(hfield, "elevation"));
        assert_eq!(e.len(), 6);
        // MuJoCo's first row is legwork's last (the highest y).
        assert_eq!((e[0], e[1], e[3], e[4]), (0.0, 1.0, 0.0, 0.0));
        assert!((e[2] - 1.0 / 3.0).abs() < 1e-15 && (e[5] - 1.0 / 3.0).abs() < 1e-15);
        let ground = elements(&root, "geom").into_iter().find(|g| g.get_attribute("name", None) == Some("ground")).unwrap();
        assert_eq!(numbers(&attr(ground, "pos")), vec![-0.5, -0.25, 0.0]);
    }

    /// Boxes on the ground: a plane at the ground's height and one box geom per box, its
    /// centre and half-extents spanning the ground to the top.
    #[test]
    fn boxes_are_box_geoms() {
        use crate::terrain::BoxSpec;
        let model = embedded::load("a1").unwrap();
        let boxes = vec![BoxSpec { x: [-0.5, 0.5], y: [-0.5, 0.147], top: 0.9 }, BoxSpec { x: [1.0, 2.0], y: [0.0, 0.5], top: 0.2 }];
        let text = mjcf_model(&model, &TerrainSpec::Boxes { ground: -0.1, boxes }, &MjcfSettings::default()).unwrap();
        let root = parse(&text);
        let geoms = elements(&root, "geom");
        let named = |n: &str| *geoms.iter().find(|g| g.get_attribute("name", None) == Some(n)).unwrap_or_else(|| panic!("no geom {n}"));
        assert_eq!((attr(named("ground"), "type"), numbers(&attr(named("ground"), "pos"))), ("plane".into(), vec![0.0, 0.0, -0.1]));
        let b0 = named("box0");
        assert_eq!(attr(b0, "type"), "box");
        let close = |a: Vec<f64>, b: [f64; 3]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-15) && a.len() == 3;
        assert!(close(numbers(&attr(b0, "pos")), [0.0, -0.1765, 0.4]), "{}", attr(b0, "pos"));
        assert!(close(numbers(&attr(b0, "size")), [0.5, 0.3235, 0.5]), "{}", attr(b0, "size"));
        assert_eq!(attr(b0, "friction"), attr(named("ground"), "friction"));
        assert!(close(numbers(&attr(named("box1"), "size")), [0.5, 0.25, 0.15]));
        let bad = TerrainSpec::Boxes { ground: 0.0, boxes: vec![BoxSpec { x: [0.0, 1.0], y: [0.0, 1.0], top: -1.0 }] };
        let err = mjcf_model(&model, &bad, &MjcfSettings::default()).unwrap_err();
        assert!(err.to_string().starts_with("terrain field `boxes[0].top`"), "{err}");
    }

    #[test]
    fn bad_settings_and_inertias_are_named() {
        let model = embedded::load("hyq").unwrap();
        let err = mjcf_model(&model, &TerrainSpec::flat(), &MjcfSettings { timestep: 0.0, ..MjcfSettings::default() }).unwrap_err();
        assert!(err.to_string().contains("timestep"), "{err}");
        let mut broken = model.clone();
        broken.inertias[3].inertia_com[(2, 2)] = -1.0;
        let err = mjcf_model(&broken, &TerrainSpec::flat(), &MjcfSettings::default()).unwrap_err();
        assert!(matches!(&err, MjcfError::Inertia { joint, .. } if *joint == model.joints[3].name), "{err}");
    }
}
