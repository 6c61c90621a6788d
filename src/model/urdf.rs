//! URDF import: builds the same [`Model`] as Pinocchio's
//! `buildModelFromUrdf(path, JointModelFreeFlyer())`.
//!
//! * The root link gets a free flyer named `root_joint` ([`RootJoint::FreeFlyer`]) or is
//!   welded to the world ([`RootJoint::Fixed`]).
//! * The tree is traversed depth first; the children of a link are visited in the order of
//!   their joint names sorted bytewise (urdfdom keeps joints in a `std::map`, and Pinocchio
//!   inherits that order). This is why HyQ's legs come out as LF, LH, RF, RH and A1's as
//!   FL, FR, RL, RR, whatever order the file declares them in.
//! * `revolute`, `prismatic` and `continuous` joints become one-degree-of-freedom joints.
//!   **Deviation from Pinocchio:** a `continuous` joint is a revolute joint with `nq = 1` and
//!   unbounded position limits (Pinocchio uses `nq = 2`, `(cos, sin)`).
//! * `fixed` joints are merged away: the child link's inertia is lumped into the moving
//!   parent body, and the fixed joint and the child link stay as named frames
//!   ([`FrameKind::Fixed`], [`FrameKind::Body`]) placed in the parent joint's frame.
//! * `floating`, `planar` and `spherical` joints are refused. `<mimic>` is ignored (the
//!   joint gets its own coordinate), as are `<dynamics>`, `<calibration>` and
//!   `<safety_controller>`. Meshes are never read.
//! * Joint origins use fixed-axis roll-pitch-yaw `R = Rz(yaw) Ry(pitch) Rx(roll)`; an
//!   `<inertial>` origin rotates the rotational inertia, `I_link = R I R^T`.
//! * Feet: the body frames whose names end in `foot` (any case), ordered LF, RF, LH, RH by
//!   their prefix (`lf`/`fl`, `rf`/`fr`, `lh`/`hl`/`rl`, `rh`/`hr`/`rr`); the radius is the
//!   foot link's first collision sphere, else 0.
//! * [`load_file`] also reads the `<group_state>` poses (e.g. `standing`) of an SRDF next
//!   to the URDF (same stem first, else any `.srdf` in the folder) as reference
//!   configurations; see [`add_srdf_states`].
//!
//! Validation (every problem is an [`UrdfError`] naming the file, the link or joint and
//! the problem, never a panic): malformed XML, unknown or unsupported joint types,
//! duplicate names, joints naming missing links, links with two parents, kinematic loops,
//! several roots, non-finite numbers, negative masses, rotational inertias that are not
//! symmetric positive semi-definite, moving bodies without mass (a moving joint whose child
//! link has no or a zero-mass `<inertial>` and no massive link fixed to it), moving bodies
//! whose lumped inertia fails [`Inertia::validated`], non-unit axes and bad limits.
//! Links carried by fixed joints may be massless (feet, sensors, optical frames), and their
//! individual inertias only need to be positive semi-definite: shipped robots use rank-one
//! placeholders (`1e-6` everywhere) and, for ANYmal C's cameras, tensors that violate the
//! triangle inequality; the check that matters for the dynamics is done on the lumped body.
//!
//! ```no_run
//! let model = legwork::model::urdf::load_file("../shared/robots/a1/a1.urdf").unwrap();
//! assert_eq!((model.nq, model.nv), (19, 18));
//! assert_eq!(model.joints[2].name, "FL_hip_joint");
//! assert!(model.reference_configuration("standing").is_some());
//! ```

use super::{Frame, FrameKind, JointKind, JointLimits, Model, ModelError};
use crate::spatial::{Inertia, Matrix3, Vector3, SE3};
use nalgebra::DVector;
use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};

/// What kind of joint attaches the URDF root link to the world.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RootJoint {
    /// A six-degree-of-freedom free flyer named `root_joint` (legged robots).
    FreeFlyer,
    /// The root link is welded to the world.
    Fixed,
}

/// Name of the free-flyer joint added at the root, as Pinocchio names it.
pub const ROOT_JOINT_NAME: &str = "root_joint";

/// The category of a [`UrdfError`], for programs that react to it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UrdfErrorKind {
    /// The file cannot be read.
    Io,
    /// The text is not well-formed XML or not a URDF document (including values urdf-rs
    /// cannot parse, such as a number that is not a number).
    Xml,
    /// A joint type that URDF does not define, or a joint without a type.
    UnknownJointType,
    /// A joint type URDF defines but legwork does not support (`floating`, `planar`, `spherical`).
    UnsupportedJointType,
    /// Two links or two joints with the same name, or a link or joint without a name.
    DuplicateName,
    /// A joint names a parent or child link that does not exist.
    MissingLink,
    /// A link is the child of two joints.
    TwoParents,
    /// The links form a cycle (no root, or links unreachable from the root).
    KinematicLoop,
    /// The robot has no links, or several root links.
    Root,
    /// A moving body has no mass: missing or zero-mass `<inertial>`.
    MissingInertial,
    /// A negative mass.
    BadMass,
    /// A rotational inertia that is not symmetric positive (semi-)definite or physical.
    BadInertia,
    /// A NaN or infinite number where a finite one is needed.
    NotFinite,
    /// A zero or non-unit joint axis.
    BadAxis,
    /// Missing, inverted or negative joint limits.
    BadLimits,
    /// A problem in an SRDF file.
    Srdf,
    /// The XML nests deeper than [`MAX_XML_DEPTH`] or the kinematic tree is deeper than
    /// [`MAX_TREE_DEPTH`] joints.
    TooDeep,
    /// The model builder refused a joint or frame (e.g. a joint named `root_joint`).
    Model,
}

/// A URDF (or its SRDF) that cannot become a model. `Display` gives `file: message`; the
/// message names the link or joint at fault.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{file}: {message}")]
pub struct UrdfError {
    /// The file (or source name) at fault.
    pub file: String,
    /// What went wrong, as a category.
    pub kind: UrdfErrorKind,
    /// What went wrong, naming the link or joint.
    pub message: String,
}

impl UrdfError {
    fn new(file: &str, kind: UrdfErrorKind, message: impl Into<String>) -> Self {
        Self { file: file.to_string(), kind, message: message.into() }
    }
}

/// Loads a URDF file with a free-flyer root (and the SRDF reference poses beside it).
pub fn load_file(path: impl AsRef<Path>) -> Result<Model, UrdfError> {
    load_file_with_root(path, RootJoint::FreeFlyer)
}

/// Loads a URDF file with the given root joint, then adds the `<group_state>`s of the SRDF
/// beside it as reference configurations: `<stem>.srdf` if it exists, otherwise the first
/// `.srdf` of the folder (in name order) that has a `group_state`.
pub fn load_file_with_root(path: impl AsRef<Path>, root: RootJoint) -> Result<Model, UrdfError> {
    let path = path.as_ref();
    let file = path.display().to_string();
    let xml = std::fs::read_to_string(path).map_err(|e| UrdfError::new(&file, UrdfErrorKind::Io, format!("cannot read: {e}")))?;
    let mut model = from_str(&xml, &file, root)?;
    for srdf in srdf_candidates(path) {
        let name = srdf.display().to_string();
        let text = std::fs::read_to_string(&srdf)
            .map_err(|e| UrdfError::new(&name, UrdfErrorKind::Io, format!("cannot read: {e}")))?;
        if !add_srdf_states(&mut model, &text, &name)?.is_empty() {
            break;
        }
    }
    Ok(model)
}

/// The SRDF files that may describe the URDF at `path`, best first.
fn srdf_candidates(path: &Path) -> Vec<PathBuf> {
    let same_stem = path.with_extension("srdf");
    if same_stem.is_file() {
        return vec![same_stem];
    }
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let mut found: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|entries| {
            entries
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.is_file() && p.extension().is_some_and(|x| x.eq_ignore_ascii_case("srdf")))
                .collect()
        })
        .unwrap_or_default();
    found.sort();
    found
}

/// Builds a model from URDF text; `source` names the file in errors.
pub fn from_str(xml: &str, source: &str, root: RootJoint) -> Result<Model, UrdfError> {
    let dom = parse_dom(xml, source, "robot")?;
    let scan = prescan(&dom, source)?;
    // The plain URDF 1.0 most files are is read from this DOM; anything else goes to urdf-rs,
    // which builds its own DOM: this one is freed first (a 50 MB URDF's DOM takes a GB) and
    // parsed again only to say where urdf-rs failed.
    if let Some(robot) = super::urdf_dom::robot(&dom) {
        drop(dom);
        return Builder { file: source, robot: &robot, scan: &scan }.build(root);
    }
    drop(dom);
    let robot = match urdf_rs::read_from_string(xml) {
        Ok(r) => r,
        Err(e) => {
            // urdf-rs reports the first value it cannot parse without saying where; find it.
            let dom = parse_dom(xml, source, "robot")?;
            return Err(diagnose(&dom, source).unwrap_or_else(|| {
                UrdfError::new(source, UrdfErrorKind::Xml, format!("not a valid URDF: {e}"))
            }));
        }
    };
    Builder { file: source, robot: &robot, scan: &scan }.build(root)
}

// ---------------------------------------------------------------------------------------
// XML DOM: pre-scan and diagnostics
// ---------------------------------------------------------------------------------------

/// Parses `text` into a DOM whose root element must be `<expected_root>`.
fn parse_dom(text: &str, file: &str, expected_root: &str) -> Result<xml::Element, UrdfError> {
    if let Some(depth) = xml_nesting_beyond(text, MAX_XML_DEPTH) {
        return Err(UrdfError::new(file, UrdfErrorKind::TooDeep, format!("elements nest {depth} deep; a URDF nests about 6 deep, and legwork reads at most {MAX_XML_DEPTH}")));
    }
    let dom: xml::Element = text.parse().map_err(|e: xml::BuilderError| {
        let detail = match e {
            xml::BuilderError::Parser(p) => p.to_string(),
            _ => nesting_problem(text),
        };
        UrdfError::new(file, UrdfErrorKind::Xml, format!("malformed XML: {detail}"))
    })?;
    if dom.name != expected_root {
        return Err(UrdfError::new(
            file,
            UrdfErrorKind::Xml,
            format!("the root element is <{}>, expected <{expected_root}>", dom.name),
        ));
    }
    Ok(dom)
}

/// The first element nesting depth past `limit` in `text`, by a linear scan of its tags
/// (comments, processing instructions, declarations and CDATA skipped), before any parser
/// that recurses on nesting sees it. Malformed text is left to the parser.
fn xml_nesting_beyond(text: &str, limit: usize) -> Option<usize> {
    let bytes = text.as_bytes();
    let mut depth = 0usize;
    let mut i = 0;
    while let Some(offset) = bytes[i..].iter().position(|&b| b == b'<') {
        let start = i + offset;
        let rest = &text[start..];
        // Markup that is not an element: skip to its end.
        let skip_to = |end: &str| rest.find(end).map(|e| start + e + end.len());
        let next = if rest.starts_with("<!--") {
            skip_to("-->")
        } else if rest.starts_with("<![CDATA[") {
            skip_to("]]>")
        } else if rest.starts_with("<?") {
            skip_to("?>")
        } else if rest.starts_with("<!") {
            skip_to(">")
        } else {
            let end = rest.find('>').map(|e| start + e);
            if let Some(end) = end {
                if rest.starts_with("</") {
                    depth = depth.saturating_sub(1);
                } else if bytes[end - 1] != b'/' {
                    depth += 1;
                    if depth > limit {
                        return Some(depth);
                    }
                }
            }
            end.map(|e| e + 1)
        };
        match next {
            Some(n) => i = n,
            None => return None,
        }
    }
    None
}

/// Says where the elements of `text` stop nesting properly (a closing tag that does not
/// match, or the end of the text with elements still open), naming the innermost enclosing
/// element that has a `name` attribute.
fn nesting_problem(text: &str) -> String {
    let mut parser = xml::Parser::new();
    parser.feed_str(text);
    // (tag, name attribute)
    let mut stack: Vec<(String, Option<String>)> = Vec::new();
    let inside = |stack: &[(String, Option<String>)]| {
        stack
            .iter()
            .rev()
            .find_map(|(tag, name)| name.as_ref().map(|n| format!(" inside {tag} '{n}'")))
            .unwrap_or_default()
    };
    let mut seen_root = false;
    for event in parser {
        match event {
            Ok(xml::Event::ElementStart(t)) => {
                seen_root = true;
                let name = t.attributes.iter().find(|((k, ns), _)| k == "name" && ns.is_none()).map(|(_, v)| v.clone());
                stack.push((t.name, name));
            }
            Ok(xml::Event::ElementEnd(t)) => match stack.pop() {
                Some((open, _)) if open == t.name => {
                    if stack.is_empty() {
                        return "elements are not properly nested".into();
                    }
                }
                Some((open, name)) => {
                    let at = inside(&stack);
                    let open_name = name.map(|n| format!(" name=\"{n}\"")).unwrap_or_default();
                    return format!("</{}> closes <{open}{open_name}>{at}", t.name);
                }
                None => return format!("</{}> closes nothing", t.name),
            },
            Ok(_) => {}
            Err(e) => return e.to_string(),
        }
    }
    match stack.last() {
        Some((open, _)) => format!("the text ends before </{open}>{}", inside(&stack)),
        None if seen_root => "elements are not properly nested".into(),
        None => "no XML element found".into(),
    }
}

pub(super) fn child_elements<'a>(e: &'a xml::Element) -> impl Iterator<Item = &'a xml::Element> + 'a {
    e.children.iter().filter_map(|c| match c {
        xml::Xml::ElementNode(el) => Some(el),
        _ => None,
    })
}

fn first_child<'a>(e: &'a xml::Element, name: &str) -> Option<&'a xml::Element> {
    child_elements(e).find(|c| c.name == name)
}

pub(super) fn attr<'a>(e: &'a xml::Element, name: &str) -> Option<&'a str> {
    e.get_attribute(name, None)
}

/// What the DOM tells that urdf-rs's structures do not.
struct Scan {
    /// Links that have an `<inertial>` element.
    has_inertial: HashSet<String>,
    /// Joints that have a `<limit>` element.
    has_limit: HashSet<String>,
}

/// Checks joint types (naming the joint, which urdf-rs cannot do) and records which links
/// have an `<inertial>` and which joints a `<limit>`.
fn prescan(dom: &xml::Element, file: &str) -> Result<Scan, UrdfError> {
    let mut scan = Scan { has_inertial: HashSet::new(), has_limit: HashSet::new() };
    for (k, e) in child_elements(dom).enumerate() {
        match e.name.as_str() {
            "link" => {
                let name = attr(e, "name").ok_or_else(|| {
                    UrdfError::new(file, UrdfErrorKind::DuplicateName, format!("<link> number {} has no name", k + 1))
                })?;
                if first_child(e, "inertial").is_some() {
                    scan.has_inertial.insert(name.to_string());
                }
            }
            "joint" => {
                let name = attr(e, "name").ok_or_else(|| {
                    UrdfError::new(file, UrdfErrorKind::DuplicateName, format!("<joint> number {} has no name", k + 1))
                })?;
                match attr(e, "type") {
                    None => {
                        return Err(UrdfError::new(file, UrdfErrorKind::UnknownJointType, format!("joint '{name}' has no type")))
                    }
                    Some("revolute" | "continuous" | "prismatic" | "fixed") => {}
                    Some(t @ ("floating" | "planar" | "spherical")) => {
                        return Err(UrdfError::new(
                            file,
                            UrdfErrorKind::UnsupportedJointType,
                            format!("joint '{name}': type '{t}' is not supported (only revolute, continuous, prismatic and fixed)"),
                        ))
                    }
                    Some(t) => {
                        return Err(UrdfError::new(
                            file,
                            UrdfErrorKind::UnknownJointType,
                            format!("joint '{name}': unknown joint type '{t}'"),
                        ))
                    }
                }
                if first_child(e, "limit").is_some() {
                    scan.has_limit.insert(name.to_string());
                }
            }
            _ => {}
        }
    }
    Ok(scan)
}

type NumberCheck<'a> = (String, &'a xml::Element, &'static str, usize, bool);

/// The `xyz` and `rpy` checks of the `<origin>` of `el`, if any.
fn origin_checks<'a>(parent: &str, el: &'a xml::Element) -> Vec<NumberCheck<'a>> {
    match first_child(el, "origin") {
        Some(o) => vec![(format!("{parent}<origin>"), o, "xyz", 3, false), (format!("{parent}<origin>"), o, "rpy", 3, false)],
        None => vec![],
    }
}

/// Finds the element urdf-rs failed on: a missing required child or attribute, or a
/// number that does not parse. `None` when nothing specific is found.
fn diagnose(dom: &xml::Element, file: &str) -> Option<UrdfError> {
    let bad = |what: String| Some(UrdfError::new(file, UrdfErrorKind::Xml, what));
    for e in child_elements(dom) {
        let owner = match (e.name.as_str(), attr(e, "name")) {
            ("link", Some(n)) => format!("link '{n}'"),
            ("joint", Some(n)) => format!("joint '{n}'"),
            _ => continue,
        };
        // (context, element, attribute, how many numbers, required)
        let mut checks: Vec<NumberCheck<'_>> = Vec::new();
        if e.name == "link" {
            if let Some(inertial) = first_child(e, "inertial") {
                checks.extend(origin_checks("<inertial> ", inertial));
                match first_child(inertial, "mass") {
                    Some(m) => checks.push(("<mass>".into(), m, "value", 1, true)),
                    None => return bad(format!("{owner}: <inertial> has no <mass>")),
                }
                match first_child(inertial, "inertia") {
                    Some(i) => {
                        for a in ["ixx", "ixy", "ixz", "iyy", "iyz", "izz"] {
                            checks.push(("<inertia>".into(), i, a, 1, true));
                        }
                    }
                    None => return bad(format!("{owner}: <inertial> has no <inertia>")),
                }
            }
            for tag in ["visual", "collision"] {
                for v in child_elements(e).filter(|c| c.name == tag) {
                    checks.extend(origin_checks(&format!("<{tag}> "), v));
                    let Some(g) = first_child(v, "geometry") else {
                        return bad(format!("{owner}: <{tag}> has no <geometry>"));
                    };
                    if g.children.iter().any(|c| matches!(c, xml::Xml::CharacterNode(t) | xml::Xml::CDATANode(t) if !t.trim().is_empty())) {
                        return bad(format!("{owner}: <{tag}> <geometry> contains text: {:?}", g.content_str().trim()));
                    }
                    let shapes: Vec<&xml::Element> = child_elements(g).collect();
                    let [shape] = shapes.as_slice() else {
                        return bad(format!("{owner}: a <{tag}> <geometry> needs exactly one shape, it has {}", shapes.len()));
                    };
                    let attrs: &[(&'static str, usize, bool)] = match shape.name.as_str() {
                        "sphere" => &[("radius", 1, true)],
                        "box" => &[("size", 3, true)],
                        "cylinder" | "capsule" => &[("radius", 1, true), ("length", 1, true)],
                        "mesh" => &[("scale", 3, false)],
                        other => return bad(format!("{owner}: <{tag}> has an unknown geometry <{other}>")),
                    };
                    if shape.name == "mesh" && attr(shape, "filename").is_none() {
                        return bad(format!("{owner}: <{tag}> <mesh> has no filename"));
                    }
                    for (a, n, required) in attrs {
                        checks.push((format!("<{}>", shape.name), shape, a, *n, *required));
                    }
                    if let Some(m) = first_child(v, "material") {
                        if attr(m, "name").is_none() {
                            return bad(format!("{owner}: <{tag}> <material> has no name"));
                        }
                        if let Some(c) = first_child(m, "color") {
                            checks.push(("<material> <color>".into(), c, "rgba", 4, true));
                        }
                    }
                }
            }
        } else {
            checks.extend(origin_checks("", e));
            for tag in ["parent", "child"] {
                match first_child(e, tag) {
                    Some(p) if attr(p, "link").is_some() => {}
                    _ => return bad(format!("{owner}: missing <{tag} link=\"...\"/>")),
                }
            }
            if let Some(a) = first_child(e, "axis") {
                checks.push(("<axis>".into(), a, "xyz", 3, true));
            }
            if let Some(l) = first_child(e, "limit") {
                checks.push(("<limit>".into(), l, "velocity", 1, true));
                for a in ["lower", "upper", "effort"] {
                    checks.push(("<limit>".into(), l, a, 1, false));
                }
            }
            if let Some(sc) = first_child(e, "safety_controller") {
                checks.push(("<safety_controller>".into(), sc, "k_velocity", 1, true));
                for a in ["soft_lower_limit", "soft_upper_limit", "k_position"] {
                    checks.push(("<safety_controller>".into(), sc, a, 1, false));
                }
            }
            if let Some(d) = first_child(e, "dynamics") {
                for a in ["damping", "friction"] {
                    checks.push(("<dynamics>".into(), d, a, 1, false));
                }
            }
            if let Some(m) = first_child(e, "mimic") {
                if attr(m, "joint").is_none() {
                    return bad(format!("{owner}: <mimic> has no joint"));
                }
                for a in ["multiplier", "offset"] {
                    checks.push(("<mimic>".into(), m, a, 1, false));
                }
            }
        }
        for (ctx, el, a, n, required) in checks {
            match attr(el, a) {
                None if required => return bad(format!("{owner}: {ctx} has no '{a}' attribute")),
                None => {}
                Some(text) => {
                    let parsed: Vec<Result<f64, _>> = text.split_whitespace().map(str::parse::<f64>).collect();
                    if parsed.len() != n || parsed.iter().any(|p| p.is_err()) {
                        let what = if n == 1 { "a number".to_string() } else { format!("{n} numbers") };
                        return bad(format!("{owner}: {ctx} {a}=\"{text}\" is not {what}"));
                    }
                }
            }
        }
    }
    None
}

// ---------------------------------------------------------------------------------------
// Model construction
// ---------------------------------------------------------------------------------------

struct Builder<'a> {
    file: &'a str,
    robot: &'a urdf_rs::Robot,
    scan: &'a Scan,
}

/// A joint still to be added: URDF joint index, the model joint its parent link moves
/// with, and the parent link's pose in that joint's frame.
struct Pending {
    joint: usize,
    parent_joint: usize,
    parent_placement: SE3,
    /// Joints (fixed ones included) from the root link to this joint's child.
    depth: usize,
}

/// The deepest kinematic tree legwork imports, in joints from the root link (fixed joints
/// included). A quadruped's legs are 3-7 joints deep, a humanoid's fingers about 15;
/// the dynamics keep each joint's path to the root, so depth costs memory and time.
pub const MAX_TREE_DEPTH: usize = 256;

/// The deepest XML nesting legwork reads. A URDF nests about 6 deep
/// (`robot/link/visual/geometry/mesh`); the XML parser recurses on nesting.
pub const MAX_XML_DEPTH: usize = 64;

impl Builder<'_> {
    fn err(&self, kind: UrdfErrorKind, message: impl Into<String>) -> UrdfError {
        UrdfError::new(self.file, kind, message)
    }

    fn build(&self, root: RootJoint) -> Result<Model, UrdfError> {
        let robot = self.robot;
        let links = &robot.links;
        let joints = &robot.joints;
        if links.is_empty() {
            return Err(self.err(UrdfErrorKind::Root, "the robot has no links"));
        }
        let mut link_index: HashMap<&str, usize> = HashMap::with_capacity(links.len());
        for (k, l) in links.iter().enumerate() {
            if link_index.insert(l.name.as_str(), k).is_some() {
                return Err(self.err(UrdfErrorKind::DuplicateName, format!("two links are named '{}'", l.name)));
            }
        }
        let mut joint_names: HashSet<&str> = HashSet::with_capacity(joints.len());
        for j in joints {
            if !joint_names.insert(j.name.as_str()) {
                return Err(self.err(UrdfErrorKind::DuplicateName, format!("two joints are named '{}'", j.name)));
            }
        }
        // Topology: each link has at most one parent joint.
        let mut parent_of: Vec<Option<usize>> = vec![None; links.len()];
        let mut children: Vec<Vec<usize>> = vec![Vec::new(); links.len()];
        for (k, j) in joints.iter().enumerate() {
            let find = |which: &str, name: &str| {
                link_index.get(name).copied().ok_or_else(|| {
                    self.err(UrdfErrorKind::MissingLink, format!("joint '{}': {which} link '{name}' does not exist", j.name))
                })
            };
            let p = find("parent", &j.parent.link)?;
            let c = find("child", &j.child.link)?;
            if let Some(prev) = parent_of[c] {
                return Err(self.err(
                    UrdfErrorKind::TwoParents,
                    format!("link '{}' has two parents: joints '{}' and '{}'", links[c].name, joints[prev].name, j.name),
                ));
            }
            parent_of[c] = Some(k);
            children[p].push(k);
        }
        for ch in &mut children {
            // urdfdom's std::map order: joint names compared bytewise.
            ch.sort_by(|a, b| joints[*a].name.as_bytes().cmp(joints[*b].name.as_bytes()));
        }
        let roots: Vec<usize> = (0..links.len()).filter(|&l| parent_of[l].is_none()).collect();
        let root_link = match roots.as_slice() {
            [] => {
                return Err(self.err(
                    UrdfErrorKind::KinematicLoop,
                    format!("every link has a parent joint, so there is no root: kinematic loop through link '{}'", links[0].name),
                ))
            }
            [r] => *r,
            _ => {
                let names: Vec<&str> = roots.iter().map(|&r| links[r].name.as_str()).collect();
                return Err(self.err(
                    UrdfErrorKind::Root,
                    format!("several root links ({}); a URDF must be a single tree", names.join(", ")),
                ));
            }
        };

        let mut model = Model::new(robot.name.clone());
        let mut moving: Vec<(usize, usize)> = Vec::new(); // (model joint, URDF joint)
        let root_joint = match root {
            RootJoint::FreeFlyer => model
                .add_joint(0, ROOT_JOINT_NAME, JointKind::FreeFlyer, SE3::identity(), JointLimits::unbounded(6))
                .map_err(|e| self.model_err(ROOT_JOINT_NAME, e))?,
            RootJoint::Fixed => 0,
        };
        self.attach_link(&mut model, root_link, root_joint, SE3::identity())?;
        let mut visited = 1usize;

        // Depth-first, pre-order, children in joint-name order (explicit stack: no recursion
        // limit on deep chains).
        let mut stack: Vec<Pending> = children[root_link]
            .iter()
            .rev()
            .map(|&k| Pending { joint: k, parent_joint: root_joint, parent_placement: SE3::identity(), depth: 1 })
            .collect();
        while let Some(Pending { joint: k, parent_joint, parent_placement, depth }) = stack.pop() {
            let j = &joints[k];
            if depth > MAX_TREE_DEPTH {
                return Err(self.err(
                    UrdfErrorKind::TooDeep,
                    format!("joint '{}' is {depth} joints from the root link; legwork imports trees at most {MAX_TREE_DEPTH} joints deep", j.name),
                ));
            }
            let child = link_index[j.child.link.as_str()];
            visited += 1;
            let origin = self.pose(&j.origin, &format!("joint '{}': <origin>", j.name))?;
            self.check_unused_numbers(j)?;
            let placement = parent_placement * origin;
            let (carrier, child_placement) = match j.joint_type {
                urdf_rs::JointType::Fixed => {
                    model
                        .add_frame(Frame { name: j.name.clone(), kind: FrameKind::Fixed, parent_joint, placement })
                        .map_err(|e| self.model_err(&j.name, e))?;
                    self.attach_link(&mut model, child, parent_joint, placement)?;
                    (parent_joint, placement)
                }
                urdf_rs::JointType::Revolute | urdf_rs::JointType::Continuous | urdf_rs::JointType::Prismatic => {
                    let axis = self.axis(j)?;
                    let kind = if j.joint_type == urdf_rs::JointType::Prismatic {
                        JointKind::prismatic(axis)
                    } else {
                        JointKind::revolute(axis)
                    };
                    let limits = self.limits(j)?;
                    let id = model.add_joint(parent_joint, j.name.clone(), kind, placement, limits).map_err(|e| self.model_err(&j.name, e))?;
                    self.attach_link(&mut model, child, id, SE3::identity())?;
                    moving.push((id, k));
                    (id, SE3::identity())
                }
                ref t => {
                    return Err(self.err(
                        UrdfErrorKind::UnsupportedJointType,
                        format!("joint '{}': type {t:?} is not supported", j.name),
                    ))
                }
            };
            for &c in children[child].iter().rev() {
                stack.push(Pending { joint: c, parent_joint: carrier, parent_placement: child_placement, depth: depth + 1 });
            }
        }
        if visited < links.len() {
            let lost: Vec<&str> = (0..links.len())
                .filter(|&l| l != root_link && !Self::reaches(l, root_link, &parent_of, joints, &link_index, links.len()))
                .map(|l| links[l].name.as_str())
                .collect();
            return Err(self.err(
                UrdfErrorKind::KinematicLoop,
                format!("kinematic loop: links {} are not reachable from the root link '{}'", lost.join(", "), links[root_link].name),
            ));
        }

        // Every moving body needs a mass and a physical lumped inertia.
        if root == RootJoint::FreeFlyer {
            self.check_body(&model, root_joint, ROOT_JOINT_NAME, &links[root_link].name)?;
        }
        for &(id, k) in &moving {
            self.check_body(&model, id, &joints[k].name, &joints[k].child.link)?;
        }
        self.declare_feet(&mut model, &link_index)?;
        // A URDF says nothing of contact: the calibration for the robot's foot load.
        model.contact = model.calibrated_contact();
        Ok(model)
    }

    /// Whether following parents from `link` reaches `root` (false inside a loop).
    fn reaches(
        link: usize,
        root: usize,
        parent_of: &[Option<usize>],
        joints: &[urdf_rs::Joint],
        link_index: &HashMap<&str, usize>,
        n: usize,
    ) -> bool {
        let mut l = link;
        for _ in 0..=n {
            if l == root {
                return true;
            }
            match parent_of[l] {
                Some(j) => l = link_index[joints[j].parent.link.as_str()],
                None => return false,
            }
        }
        false
    }

    fn model_err(&self, joint: &str, e: ModelError) -> UrdfError {
        self.err(UrdfErrorKind::Model, format!("joint '{joint}': {e}"))
    }

    /// A URDF `<origin>` as a transform, refusing non-finite values.
    fn pose(&self, p: &urdf_rs::Pose, what: &str) -> Result<SE3, UrdfError> {
        if !p.xyz.iter().chain(p.rpy.iter()).all(|x| x.is_finite()) {
            return Err(self.err(
                UrdfErrorKind::NotFinite,
                format!("{what} is not finite (xyz {:?}, rpy {:?})", p.xyz.0, p.rpy.0),
            ));
        }
        Ok(SE3::from_rpy_xyz(p.rpy.0, p.xyz.0))
    }

    /// The joint elements the model does not use (`<dynamics>`, `<mimic>`,
    /// `<safety_controller>`, `<calibration>`) must still hold finite numbers.
    fn check_unused_numbers(&self, j: &urdf_rs::Joint) -> Result<(), UrdfError> {
        let mut values: Vec<(&str, f64)> = Vec::new();
        if let Some(d) = &j.dynamics {
            values.extend([("<dynamics> damping", d.damping), ("<dynamics> friction", d.friction)]);
        }
        if let Some(m) = &j.mimic {
            values.extend(m.multiplier.map(|x| ("<mimic> multiplier", x)));
            values.extend(m.offset.map(|x| ("<mimic> offset", x)));
        }
        if let Some(c) = &j.safety_controller {
            values.extend([
                ("<safety_controller> soft_lower_limit", c.soft_lower_limit),
                ("<safety_controller> soft_upper_limit", c.soft_upper_limit),
                ("<safety_controller> k_position", c.k_position),
                ("<safety_controller> k_velocity", c.k_velocity),
            ]);
        }
        if let Some(c) = &j.calibration {
            values.extend(c.rising.map(|x| ("<calibration> rising", x)));
            values.extend(c.falling.map(|x| ("<calibration> falling", x)));
        }
        match values.into_iter().find(|(_, x)| !x.is_finite()) {
            Some((what, x)) => Err(self.err(UrdfErrorKind::NotFinite, format!("joint '{}': {what} = {x} is not finite", j.name))),
            None => Ok(()),
        }
    }

    fn axis(&self, j: &urdf_rs::Joint) -> Result<Vector3<f64>, UrdfError> {
        let a = Vector3::from(j.axis.xyz.0);
        if !a.iter().all(|x| x.is_finite()) {
            return Err(self.err(UrdfErrorKind::NotFinite, format!("joint '{}': axis {:?} is not finite", j.name, j.axis.xyz.0)));
        }
        let n = a.norm();
        // Allow rounding in hand-written axes ("0 0.7071 0.7071"); anything else is a mistake.
        if (n - 1.0).abs() > 1e-3 {
            let what = if n == 0.0 { "is zero".to_string() } else { format!("is not a unit vector (norm {n})") };
            return Err(self.err(UrdfErrorKind::BadAxis, format!("joint '{}': axis {:?} {what}", j.name, j.axis.xyz.0)));
        }
        Ok(a / n)
    }

    fn limits(&self, j: &urdf_rs::Joint) -> Result<JointLimits, UrdfError> {
        let l = &j.limit;
        let has_limit = self.scan.has_limit.contains(&j.name);
        for (what, x) in [("lower", l.lower), ("upper", l.upper), ("velocity", l.velocity), ("effort", l.effort)] {
            if x.is_nan() {
                return Err(self.err(UrdfErrorKind::NotFinite, format!("joint '{}': <limit> {what} is NaN", j.name)));
            }
        }
        for (what, x) in [("velocity", l.velocity), ("effort", l.effort)] {
            if x < 0.0 {
                return Err(self.err(UrdfErrorKind::BadLimits, format!("joint '{}': <limit> {what} = {x} is negative", j.name)));
            }
        }
        if j.joint_type == urdf_rs::JointType::Continuous {
            let (velocity, effort) = if has_limit { (l.velocity, l.effort) } else { (f64::INFINITY, f64::INFINITY) };
            return Ok(JointLimits::new(f64::NEG_INFINITY, f64::INFINITY, velocity, effort));
        }
        if !has_limit {
            return Err(self.err(
                UrdfErrorKind::BadLimits,
                format!("joint '{}': a {:?} joint needs a <limit> (lower, upper, effort, velocity)", j.name, j.joint_type),
            ));
        }
        if l.lower > l.upper {
            return Err(self.err(
                UrdfErrorKind::BadLimits,
                format!("joint '{}': <limit> lower {} is above upper {}", j.name, l.lower, l.upper),
            ));
        }
        Ok(JointLimits::new(l.lower, l.upper, l.velocity, l.effort))
    }

    /// The inertia of a link in its own frame, `None` when it has no `<inertial>` or a
    /// zero mass and zero rotational inertia.
    fn link_inertia(&self, link: &urdf_rs::Link) -> Result<Option<Inertia>, UrdfError> {
        if !self.scan.has_inertial.contains(&link.name) {
            return Ok(None);
        }
        let name = &link.name;
        let ine = &link.inertial;
        let m = ine.mass.value;
        let t = &ine.inertia;
        let values = [m, t.ixx, t.ixy, t.ixz, t.iyy, t.iyz, t.izz];
        if !values.iter().all(|x| x.is_finite()) {
            return Err(self.err(
                UrdfErrorKind::NotFinite,
                format!("link '{name}': <inertial> mass or inertia is not finite (mass {m}, inertia {:?})", &values[1..]),
            ));
        }
        if m < 0.0 {
            return Err(self.err(UrdfErrorKind::BadMass, format!("link '{name}': mass {m} is negative")));
        }
        let origin = self.pose(&ine.origin, &format!("link '{name}': <inertial> <origin>"))?;
        let i_com = Matrix3::new(t.ixx, t.ixy, t.ixz, t.ixy, t.iyy, t.iyz, t.ixz, t.iyz, t.izz);
        if m == 0.0 && i_com.iter().all(|x| *x == 0.0) {
            return Ok(None);
        }
        let eig = nalgebra::SymmetricEigen::new(i_com).eigenvalues;
        let scale = eig.amax();
        if eig.min() < -1e-12 * scale {
            return Err(self.err(
                UrdfErrorKind::BadInertia,
                format!(
                    "link '{name}': rotational inertia is not positive semi-definite (eigenvalues {:?})",
                    eig.as_slice()
                ),
            ));
        }
        let r = origin.rotation;
        Ok(Some(Inertia::new(m, origin.translation, r * i_com * r.transpose())))
    }

    /// Adds the body frame of `link` to model joint `joint` at `placement`, lumping its
    /// inertia into the joint's body (not into the universe: a fixed-base root link and
    /// what is welded to it do not move). Also checks the link's other numbers.
    fn attach_link(&self, model: &mut Model, link: usize, joint: usize, placement: SE3) -> Result<(), UrdfError> {
        let l = &self.robot.links[link];
        let inertia = self.link_inertia(l)?;
        for (k, v) in l.visual.iter().enumerate() {
            self.pose(&v.origin, &format!("link '{}': <visual> {} <origin>", l.name, k + 1))?;
            self.geometry(&v.geometry, &l.name)?;
        }
        for (k, c) in l.collision.iter().enumerate() {
            self.pose(&c.origin, &format!("link '{}': <collision> {} <origin>", l.name, k + 1))?;
            self.geometry(&c.geometry, &l.name)?;
        }
        if joint == 0 {
            model
                .add_frame(Frame { name: l.name.clone(), kind: FrameKind::Body, parent_joint: 0, placement })
                .map_err(|e| self.err(UrdfErrorKind::Model, format!("link '{}': {e}", l.name)))?;
        } else {
            model.append_body(joint, l.name.clone(), inertia.unwrap_or_else(Inertia::zero), placement);
        }
        Ok(())
    }

    fn geometry(&self, g: &urdf_rs::Geometry, link: &str) -> Result<(), UrdfError> {
        let values: Vec<f64> = match g {
            urdf_rs::Geometry::Box { size } => size.0.to_vec(),
            urdf_rs::Geometry::Cylinder { radius, length } | urdf_rs::Geometry::Capsule { radius, length } => {
                vec![*radius, *length]
            }
            urdf_rs::Geometry::Sphere { radius } => vec![*radius],
            urdf_rs::Geometry::Mesh { scale, .. } => scale.map(|s| s.0.to_vec()).unwrap_or_default(),
        };
        if values.iter().any(|x| !x.is_finite()) {
            return Err(self.err(UrdfErrorKind::NotFinite, format!("link '{link}': geometry {g:?} is not finite")));
        }
        Ok(())
    }

    /// The lumped body of a moving joint must have a mass and a physical inertia.
    fn check_body(&self, model: &Model, id: usize, joint: &str, link: &str) -> Result<(), UrdfError> {
        let b = &model.inertias[id];
        if b.mass <= 0.0 {
            return Err(self.err(
                UrdfErrorKind::MissingInertial,
                format!(
                    "joint '{joint}' moves link '{link}', which has no mass (missing or zero-mass <inertial>) and no massive link fixed to it"
                ),
            ));
        }
        Inertia::validated(b.mass, b.com, b.inertia_com).map_err(|e| {
            self.err(
                UrdfErrorKind::BadInertia,
                format!("joint '{joint}': the body of link '{link}' (with the links fixed to it) has an unphysical inertia: {e}"),
            )
        })?;
        Ok(())
    }

    /// Declares as feet the body frames whose names end in `foot`.
    fn declare_feet(&self, model: &mut Model, link_index: &HashMap<&str, usize>) -> Result<(), UrdfError> {
        let mut feet: Vec<(usize, String, f64)> = Vec::new();
        for f in &model.frames {
            if f.kind != FrameKind::Body || !f.name.to_ascii_lowercase().ends_with("foot") {
                continue;
            }
            let Some(&l) = link_index.get(f.name.as_str()) else { continue };
            let radius = self.robot.links[l]
                .collision
                .iter()
                .find_map(|c| match c.geometry {
                    urdf_rs::Geometry::Sphere { radius } => Some(radius),
                    _ => None,
                })
                .unwrap_or(0.0);
            if radius.is_nan() || radius < 0.0 {
                return Err(self.err(UrdfErrorKind::NotFinite, format!("link '{}': foot sphere radius {radius} is not valid", f.name)));
            }
            feet.push((foot_rank(&f.name), f.name.clone(), radius));
        }
        if feet.is_empty() {
            return Ok(());
        }
        feet.sort_by_key(|f| f.0); // stable: unknown prefixes keep frame order, last
        let names: Vec<&str> = feet.iter().map(|f| f.1.as_str()).collect();
        model.set_feet(&names, 0.0).map_err(|e| self.err(UrdfErrorKind::Model, format!("feet: {e}")))?;
        for (foot, (_, _, r)) in model.feet.iter_mut().zip(&feet) {
            foot.radius = *r;
        }
        Ok(())
    }
}

/// Position of a foot in the order LF, RF, LH, RH from its name's two-letter prefix
/// (`lf`/`fl`, `rf`/`fr`, `lh`/`hl`/`rl`, `rh`/`hr`/`rr`, any case); 4 when unknown.
pub fn foot_rank(name: &str) -> usize {
    let lower = name.to_ascii_lowercase();
    let b = lower.as_bytes();
    if b.len() < 3 || b[2].is_ascii_alphabetic() && !lower[2..].starts_with("foot") {
        return 4;
    }
    match &lower[..2] {
        "lf" | "fl" => 0,
        "rf" | "fr" => 1,
        "lh" | "hl" | "rl" => 2,
        "rh" | "hr" | "rr" => 3,
        _ => 4,
    }
}

// ---------------------------------------------------------------------------------------
// SRDF
// ---------------------------------------------------------------------------------------

/// Adds every `<group_state>` of an SRDF as a reference configuration of `model` (replacing
/// one of the same name) and returns their names. Joints not listed stay at the neutral
/// value; the free flyer takes the 7 values `x y z qx qy qz qw` (quaternion normalised).
/// Joints of the URDF that were merged away (fixed), and `root_joint` when the model has
/// a fixed base, are skipped, as Pinocchio does; any other unknown joint is an error. `source` names the SRDF file in errors.
pub fn add_srdf_states(model: &mut Model, srdf: &str, source: &str) -> Result<Vec<String>, UrdfError> {
    let err = |m: String| UrdfError::new(source, UrdfErrorKind::Srdf, m);
    let dom = parse_dom(srdf, source, "robot")?;
    let mut added = Vec::new();
    let mut states: Vec<(String, DVector<f64>)> = Vec::new();
    for gs in child_elements(&dom).filter(|e| e.name == "group_state") {
        let state = attr(gs, "name").ok_or_else(|| err("a <group_state> has no name".into()))?.to_string();
        let mut q = model.neutral();
        for j in child_elements(gs).filter(|e| e.name == "joint") {
            let name = attr(j, "name").ok_or_else(|| err(format!("group_state '{state}': a <joint> has no name")))?;
            let text = attr(j, "value").ok_or_else(|| err(format!("group_state '{state}': joint '{name}' has no value")))?;
            let values: Vec<f64> = text
                .split_whitespace()
                .map(str::parse::<f64>)
                .collect::<Result<_, _>>()
                .map_err(|_| err(format!("group_state '{state}': joint '{name}': value \"{text}\" is not a list of numbers")))?;
            if let Some(bad) = values.iter().find(|x| !x.is_finite()) {
                return Err(err(format!("group_state '{state}': joint '{name}': value {bad} is not finite")));
            }
            let Ok(id) = model.joint_id(name) else {
                // Merged fixed joints, and the free flyer of a fixed-base model, are skipped.
                if name == ROOT_JOINT_NAME || model.frames.iter().any(|f| f.kind == FrameKind::Fixed && f.name == name) {
                    continue;
                }
                return Err(err(format!("group_state '{state}': joint '{name}' is not in the model")));
            };
            let jt = &model.joints[id];
            if values.len() != jt.nq {
                return Err(err(format!(
                    "group_state '{state}': joint '{name}' needs {} value(s), got {}",
                    jt.nq,
                    values.len()
                )));
            }
            if jt.kind == JointKind::FreeFlyer {
                let n = (values[3..7].iter().map(|x| x * x).sum::<f64>()).sqrt();
                if n < 1e-9 {
                    return Err(err(format!("group_state '{state}': joint '{name}': the quaternion is zero")));
                }
                q.as_mut_slice()[jt.idx_q..jt.idx_q + 3].copy_from_slice(&values[..3]);
                for k in 0..4 {
                    q[jt.idx_q + 3 + k] = values[3 + k] / n;
                }
            } else {
                q.as_mut_slice()[jt.idx_q..jt.idx_q + jt.nq].copy_from_slice(&values);
            }
        }
        states.push((state, q));
    }
    for (name, q) in states {
        model.reference_configurations.retain(|(n, _)| *n != name);
        model.reference_configurations.push((name.clone(), q));
        added.push(name);
    }
    Ok(added)
}
