//! urdf-rs's `Robot` read straight from legwork's XML DOM, for the plain URDF 1.0 most files
//! are. urdf-rs's own reader re-sorts the text's links and joints through a second DOM,
//! formats it back to text and deserializes that with serde-xml-rs: two thirds of a 48 MB
//! URDF's import. This reader takes the DOM the importer has already built, field by field
//! as urdf-rs 0.10 reads it (the same defaults, number parsing and vector rules), and gives
//! up (`None`) on anything it does not take exactly as urdf-rs would: a `version` attribute,
//! materials, `<mimic>`, `<calibration>`, `<safety_controller>`, a repeated or missing
//! element, an attribute in another form. The importer then lets urdf-rs read the text.

use super::urdf::{attr, child_elements as elements};
use urdf_rs::{Axis, Collision, Dynamics, Geometry, Inertia, Inertial, Joint, JointLimit, JointType, Link, LinkName, Mass, Pose, Robot, Vec3, Visual};

/// The robot, or `None` for urdf-rs to read.
pub(super) fn robot(dom: &xml::Element) -> Option<Robot> {
    if dom.name != "robot" || dom.get_attribute("version", None).is_some() {
        return None;
    }
    no_text(dom)?;
    strict_names(dom)?;
    let mut links = Vec::new();
    let mut joints = Vec::new();
    for e in elements(dom) {
        match e.name.as_str() {
            "link" => links.push(link(e)?),
            "joint" => joints.push(joint(e)?),
            "material" => return None,
            // urdf-rs drops the robot's other children (gazebo, transmission, ...).
            _ => {}
        }
    }
    Some(Robot { name: attr(dom, "name").unwrap_or_default().to_string(), version: None, links, joints, materials: Vec::new() })
}

/// `Some(())` if every element and attribute name below `e` is a plain XML name: the XML
/// reader legwork's DOM comes from takes some names xml-rs (inside urdf-rs) refuses, and
/// those files must get urdf-rs's answer. Nesting is bounded by the importer (64).
fn strict_names(e: &xml::Element) -> Option<()> {
    let plain = |name: &str| {
        let mut chars = name.chars();
        chars.next().is_some_and(|c| c.is_ascii_alphabetic() || c == '_') && chars.all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.'))
    };
    if !plain(&e.name) || e.ns.is_some() || e.attributes.keys().any(|(name, ns)| ns.is_some() || !plain(name)) {
        return None;
    }
    elements(e).try_for_each(strict_names)
}

/// `Some(())` if `e` holds elements only: serde-xml-rs reads text inside an element as a
/// value (inside `<geometry>`, as the shape), so text sends the file to urdf-rs.
fn no_text(e: &xml::Element) -> Option<()> {
    let text = e.children.iter().any(|c| match c {
        xml::Xml::CharacterNode(t) => !t.trim().is_empty(),
        xml::Xml::CDATANode(_) => true,
        _ => false,
    });
    (!text).then_some(())
}

/// The one child called `name`: `Some(None)` if absent, `None` if repeated.
fn single<'a>(e: &'a xml::Element, name: &str) -> Option<Option<&'a xml::Element>> {
    let mut found = elements(e).filter(|c| c.name == name);
    let first = found.next();
    if found.next().is_some() {
        return None;
    }
    Some(first)
}

/// urdf-rs's `de_f64`: the trimmed text parsed as `f64`.
fn number(e: &xml::Element, name: &str) -> Option<f64> {
    attr(e, name)?.trim().parse().ok()
}

/// A number with urdf-rs's default when the attribute is absent.
fn number_or(e: &xml::Element, name: &str, default: f64) -> Option<f64> {
    match attr(e, name) {
        None => Some(default),
        Some(_) => number(e, name),
    }
}

/// urdf-rs's `Vec3`: the whitespace-separated tokens that parse as numbers, exactly three.
fn vec3(text: &str) -> Option<Vec3> {
    let values: Vec<f64> = text.split_whitespace().filter_map(|s| s.parse().ok()).collect();
    <[f64; 3]>::try_from(values).ok().map(Vec3)
}

fn vec3_or(e: &xml::Element, name: &str, default: [f64; 3]) -> Option<Vec3> {
    match attr(e, name) {
        None => Some(Vec3(default)),
        Some(text) => vec3(text),
    }
}

fn pose(e: Option<&xml::Element>) -> Option<Pose> {
    if let Some(o) = e {
        no_text(o)?;
    }
    match e {
        None => Some(Pose::default()),
        Some(o) if attr(o, "quat_xyzw").is_some() => None,
        Some(o) => Some(Pose { xyz: vec3_or(o, "xyz", [0.0; 3])?, rpy: vec3_or(o, "rpy", [0.0; 3])? }),
    }
}

fn geometry(e: &xml::Element) -> Option<Geometry> {
    no_text(e)?;
    let mut shapes = elements(e);
    let shape = shapes.next()?;
    if shapes.next().is_some() {
        return None;
    }
    no_text(shape)?;
    Some(match shape.name.as_str() {
        "box" => Geometry::Box { size: vec3(attr(shape, "size")?)? },
        "cylinder" => Geometry::Cylinder { radius: number(shape, "radius")?, length: number(shape, "length")? },
        "capsule" => Geometry::Capsule { radius: number(shape, "radius")?, length: number(shape, "length")? },
        "sphere" => Geometry::Sphere { radius: number(shape, "radius")? },
        "mesh" => Geometry::Mesh {
            filename: attr(shape, "filename")?.to_string(),
            scale: match attr(shape, "scale") {
                None => None,
                Some(text) => Some(vec3(text)?),
            },
        },
        _ => return None,
    })
}

fn link(e: &xml::Element) -> Option<Link> {
    no_text(e)?;
    let inertial = match single(e, "inertial")? {
        None => Inertial::default(),
        Some(i) => {
            no_text(i)?;
            let mass = single(i, "mass")??;
            let inertia = single(i, "inertia")??;
            no_text(mass)?;
            no_text(inertia)?;
            let n = |name| number(inertia, name);
            Inertial {
                origin: pose(single(i, "origin")?)?,
                mass: Mass { value: number(mass, "value")? },
                inertia: Inertia { ixx: n("ixx")?, ixy: n("ixy")?, ixz: n("ixz")?, iyy: n("iyy")?, iyz: n("iyz")?, izz: n("izz")? },
            }
        }
    };
    let mut visual = Vec::new();
    let mut collision = Vec::new();
    for c in elements(e) {
        match c.name.as_str() {
            "visual" => {
                no_text(c)?;
                if single(c, "material")?.is_some() {
                    return None;
                }
                visual.push(Visual { name: attr(c, "name").map(str::to_string), origin: pose(single(c, "origin")?)?, geometry: geometry(single(c, "geometry")??)?, material: None });
            }
            "collision" => collision.push({
                no_text(c)?;
                Collision { name: attr(c, "name").map(str::to_string), origin: pose(single(c, "origin")?)?, geometry: geometry(single(c, "geometry")??)? }
            }),
            _ => {}
        }
    }
    Some(Link { name: attr(e, "name")?.to_string(), inertial, visual, collision })
}

fn joint(e: &xml::Element) -> Option<Joint> {
    no_text(e)?;
    // Every child urdf-rs reads holds elements only.
    for c in elements(e) {
        no_text(c)?;
    }
    for unsupported in ["mimic", "calibration", "safety_controller"] {
        if single(e, unsupported)?.is_some() {
            return None;
        }
    }
    let joint_type = match attr(e, "type")? {
        "revolute" => JointType::Revolute,
        "continuous" => JointType::Continuous,
        "prismatic" => JointType::Prismatic,
        "fixed" => JointType::Fixed,
        "floating" => JointType::Floating,
        "planar" => JointType::Planar,
        "spherical" => JointType::Spherical,
        _ => return None,
    };
    let link_name = |which| Some(LinkName { link: attr(single(e, which)??, "link")?.to_string() });
    let limit = match single(e, "limit")? {
        None => JointLimit::default(),
        // URDF 1.0: acceleration, deceleration and jerk are ignored (infinite), as urdf-rs does.
        Some(l) => JointLimit { lower: number_or(l, "lower", 0.0)?, upper: number_or(l, "upper", 0.0)?, effort: number_or(l, "effort", 0.0)?, velocity: number(l, "velocity")?, ..JointLimit::default() },
    };
    let dynamics = match single(e, "dynamics")? {
        None => None,
        Some(d) => Some(Dynamics { damping: number_or(d, "damping", 0.0)?, friction: number_or(d, "friction", 0.0)? }),
    };
    Some(Joint {
        name: attr(e, "name")?.to_string(),
        joint_type,
        origin: pose(single(e, "origin")?)?,
        parent: link_name("parent")?,
        child: link_name("child")?,
        axis: match single(e, "axis")? {
            None => Axis::default(),
            // urdf-rs requires `xyz` on an `<axis>` (the default is for a missing `<axis>`).
            Some(a) => Axis { xyz: vec3(attr(a, "xyz")?)? },
        },
        limit,
        calibration: None,
        dynamics,
        mimic: None,
        safety_controller: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn shared_urdfs() -> Vec<(String, String)> {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/robots");
        let mut found = Vec::new();
        let mut dirs = vec![root];
        while let Some(dir) = dirs.pop() {
            for entry in std::fs::read_dir(&dir).into_iter().flatten().flatten() {
                let path = entry.path();
                if path.is_dir() {
                    dirs.push(path);
                } else if path.extension().is_some_and(|e| e == "urdf") {
                    found.push((path.display().to_string(), std::fs::read_to_string(&path).unwrap()));
                }
            }
        }
        found
    }

    /// Whenever this reader answers, urdf-rs reads the same text to the same `Robot`.
    fn agrees(text: &str) -> Result<bool, String> {
        let Ok(dom) = text.parse::<xml::Element>() else { return Ok(false) };
        let Some(fast) = robot(&dom) else { return Ok(false) };
        match urdf_rs::read_from_string(text) {
            Ok(slow) if format!("{fast:?}") == format!("{slow:?}") => Ok(true),
            Ok(slow) => Err(format!("differs:\n{fast:?}\n{slow:?}")),
            Err(e) => Err(format!("this reader accepts what urdf-rs refuses ({e})")),
        }
    }

    #[test]
    fn the_shared_robots_read_as_urdf_rs_reads_them() {
        let urdfs = shared_urdfs();
        assert!(!urdfs.is_empty(), "no URDF under ../shared/robots");
        for (path, text) in &urdfs {
            let taken = agrees(text).unwrap_or_else(|e| panic!("{path}: {e}"));
            eprintln!("{path}: {}", if taken { "read from the DOM" } else { "left to urdf-rs" });
        }
        // A generated wide tree, the case this reader is for, is read from the DOM.
        let mut wide = String::from(r#"<robot name="w"><link name="base"><inertial><mass value="1"/><inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial></link>"#);
        for i in 0..50 {
            wide += &format!(r#"<link name="l{i}"><visual><origin xyz="0 0 {i}"/><geometry><sphere radius="0.02"/></geometry></visual></link><joint name="j{i}" type="fixed"><parent link="base"/><child link="l{i}"/></joint>"#);
        }
        wide += "</robot>";
        assert_eq!(agrees(&wide), Ok(true));
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 512, .. ProptestConfig::default() })]

        /// Edited URDFs: this reader never accepts one urdf-rs would refuse or read otherwise.
        #[test]
        fn edited_urdfs_read_as_urdf_rs_reads_them(which in any::<prop::sample::Index>(), edits in prop::collection::vec((any::<prop::sample::Index>(), prop::sample::select(vec![b' ', b'0', b'1', b'-', b'e', b'.', b'x', b'"', b'/', b'<', b'>', b'a', b'n']), 0u8..3), 1..6)) {
            let urdfs = shared_urdfs();
            let mut bytes = urdfs[which.index(urdfs.len())].1.as_bytes().to_vec();
            for (at, byte, op) in edits {
                let i = at.index(bytes.len());
                match op {
                    0 => bytes[i] = byte,
                    1 => { bytes.remove(i); }
                    _ => bytes.insert(i, byte),
                }
            }
            let text = String::from_utf8_lossy(&bytes);
            prop_assert!(agrees(&text).is_ok(), "{:?}", agrees(&text));
        }
    }
}
