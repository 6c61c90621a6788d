//! A human-readable account of a [`Model`]: the kinematic tree, masses, frames, limits,
//! the standing pose and where the feet are in it. `legwork robot info` prints it.
//!
//! ```
//! let model = legwork::model::embedded::load("a1").unwrap();
//! let info = legwork::model::info::RobotInfo::of(&model);
//! assert!((info.total_mass - 13.741).abs() < 1e-9);
//! let text = info.to_string();
//! assert!(text.contains("FL_hip_joint"));
//! ```

use super::description::LEG_ORDER;
use super::{FrameKind, JointKind, Model};
use crate::dynamics::{forward_kinematics, frame_placement, Data};
use nalgebra::Vector3;
use std::fmt;

/// One joint of the tree, with the bodies it moves.
#[derive(Clone, Debug, PartialEq)]
pub struct JointInfo {
    pub name: String,
    /// Depth in the tree (the root joint is 0).
    pub depth: usize,
    /// `free_flyer`, `revolute`, `prismatic`.
    pub kind: &'static str,
    /// Axis in the joint frame (revolute, prismatic).
    pub axis: Option<Vector3<f64>>,
    /// Mass of the (lumped) body the joint moves, kg.
    pub mass: f64,
    /// Names of the body frames merged into that body.
    pub bodies: Vec<String>,
    pub lower: f64,
    pub upper: f64,
    pub velocity: f64,
    pub effort: f64,
}

/// A named frame other than a joint frame.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameInfo {
    pub name: String,
    /// `body`, `fixed`, `operational`.
    pub kind: &'static str,
    pub parent_joint: String,
    /// Origin in the parent joint's frame.
    pub position: Vector3<f64>,
    /// `(leg, radius)` when the frame is a foot; the leg is `LF`, `RF`, `LH`, `RH` for a
    /// four-footed model, else the foot's index.
    pub foot: Option<(String, f64)>,
}

/// A foot in the standing pose.
#[derive(Clone, Debug, PartialEq)]
pub struct FootPosition {
    pub leg: String,
    pub name: String,
    /// Centre of the foot sphere in the world, m.
    pub world: Vector3<f64>,
}

/// The `standing` reference configuration.
#[derive(Clone, Debug, PartialEq)]
pub struct StandingInfo {
    /// Base position in the world (free-flyer models).
    pub base_position: Option<Vector3<f64>>,
    /// Base orientation quaternion `(x, y, z, w)`.
    pub base_quaternion: Option<[f64; 4]>,
    /// Joint values by name, in `q` order.
    pub joints: Vec<(String, f64)>,
    pub feet: Vec<FootPosition>,
}

/// Everything `legwork robot info` shows about a model.
#[derive(Clone, Debug, PartialEq)]
pub struct RobotInfo {
    pub name: String,
    pub nq: usize,
    pub nv: usize,
    /// Joints in depth-first order, the universe left out.
    pub joints: Vec<JointInfo>,
    pub total_mass: f64,
    pub frames: Vec<FrameInfo>,
    pub standing: Option<StandingInfo>,
}

fn leg_label(model: &Model, k: usize) -> String {
    if model.feet.len() == 4 {
        LEG_ORDER[k].to_string()
    } else {
        format!("foot {k}")
    }
}

impl RobotInfo {
    /// Gathers the account of `model` (runs forward kinematics for the standing pose).
    pub fn of(model: &Model) -> RobotInfo {
        let mut depth = vec![0usize; model.njoints()];
        let mut joints = Vec::new();
        for (i, j) in model.joints.iter().enumerate().skip(1) {
            depth[i] = if j.parent == 0 { 0 } else { depth[j.parent] + 1 };
            let axis = match j.kind {
                JointKind::Revolute { axis } | JointKind::Prismatic { axis } => Some(axis),
                _ => None,
            };
            let bodies = model.frames.iter().filter(|f| f.parent_joint == i && f.kind == FrameKind::Body).map(|f| f.name.clone()).collect();
            let one = j.nv == 1;
            joints.push(JointInfo {
                name: j.name.clone(),
                depth: depth[i],
                kind: j.kind.short_name(),
                axis,
                mass: model.inertias[i].mass,
                bodies,
                lower: if one { j.limits.lower[0] } else { f64::NEG_INFINITY },
                upper: if one { j.limits.upper[0] } else { f64::INFINITY },
                velocity: if one { j.limits.velocity[0] } else { f64::INFINITY },
                effort: if one { j.limits.effort[0] } else { f64::INFINITY },
            });
        }
        let frames = model
            .frames
            .iter()
            .enumerate()
            .filter(|(_, f)| f.kind != FrameKind::Joint)
            .map(|(id, f)| FrameInfo {
                name: f.name.clone(),
                kind: match f.kind {
                    FrameKind::Body => "body",
                    FrameKind::Fixed => "fixed",
                    FrameKind::Operational => "operational",
                    FrameKind::Joint => "joint",
                },
                parent_joint: model.joints[f.parent_joint].name.clone(),
                position: f.placement.translation,
                foot: model.feet.iter().position(|foot| foot.frame == id).map(|k| (leg_label(model, k), model.feet[k].radius)),
            })
            .collect();
        let standing = model.reference_configuration("standing").map(|q| {
            let mut data = Data::new(model);
            forward_kinematics(model, &mut data, q);
            let feet = model
                .feet
                .iter()
                .enumerate()
                .map(|(k, f)| FootPosition { leg: leg_label(model, k), name: f.name.clone(), world: frame_placement(model, &mut data, f.frame).translation })
                .collect();
            let ff = model.has_free_flyer();
            StandingInfo {
                base_position: ff.then(|| Vector3::new(q[0], q[1], q[2])),
                base_quaternion: ff.then(|| [q[3], q[4], q[5], q[6]]),
                joints: model.joints.iter().filter(|j| j.nq == 1).map(|j| (j.name.clone(), q[j.idx_q])).collect(),
                feet,
            }
        });
        RobotInfo { name: model.name.clone(), nq: model.nq, nv: model.nv, joints, total_mass: model.total_mass(), frames, standing }
    }
}

/// A number with `d` decimals, without a minus sign on zero.
fn num(x: f64, d: usize) -> String {
    let s = format!("{x:.d$}");
    if s.trim_start_matches('-').chars().all(|c| c == '0' || c == '.') {
        s.trim_start_matches('-').to_string()
    } else {
        s
    }
}

fn vec3(v: &Vector3<f64>, d: usize) -> String {
    format!("({}, {}, {})", num(v.x, d), num(v.y, d), num(v.z, d))
}

fn angle(x: f64) -> String {
    if x.is_infinite() {
        if x > 0.0 { "inf".into() } else { "-inf".into() }
    } else {
        format!("{} ({}°)", num(x, 4), num(x.to_degrees(), 1))
    }
}

fn bound(x: f64) -> String {
    if x.is_infinite() { "inf".into() } else { num(x, 2) }
}

impl fmt::Display for RobotInfo {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let nfeet = self.frames.iter().filter(|fr| fr.foot.is_some()).count();
        writeln!(f, "Robot {}: nq = {}, nv = {}, {} joints, {} feet", self.name, self.nq, self.nv, self.joints.len(), nfeet)?;

        writeln!(f, "\nKinematic tree (joint, type, axis in the joint frame; mass and bodies it moves):")?;
        let width = self.joints.iter().map(|j| 2 * j.depth + j.name.len()).max().unwrap_or(0);
        for j in &self.joints {
            let label = format!("{}{}", "  ".repeat(j.depth), j.name);
            let axis = j.axis.map(|a| format!("axis {}", vec3(&a, 0))).unwrap_or_default();
            writeln!(f, "  {label:<width$}  {:<10} {:<17} {:>9} kg  {}", j.kind, axis, num(j.mass, 3), j.bodies.join(", "))?;
        }
        writeln!(f, "  total mass {} kg", num(self.total_mass, 3))?;

        writeln!(f, "\nFrames (origin in the parent joint's frame, m):")?;
        let width = self.frames.iter().map(|fr| fr.name.len()).max().unwrap_or(0);
        let pwidth = self.frames.iter().map(|fr| fr.parent_joint.len()).max().unwrap_or(0);
        for fr in &self.frames {
            let foot = fr.foot.as_ref().map(|(leg, r)| format!("  <- foot {leg}, radius {r} m")).unwrap_or_default();
            writeln!(f, "  {:<width$}  {:<11} on {:<pwidth$}  {}{foot}", fr.name, fr.kind, fr.parent_joint, vec3(&fr.position, 4))?;
        }

        writeln!(f, "\nLimits (position [rad], velocity [rad/s], effort [N m]):")?;
        let width = self.joints.iter().map(|j| j.name.len()).max().unwrap_or(0);
        for j in self.joints.iter().filter(|j| j.axis.is_some()) {
            writeln!(f, "  {:<width$}  {:>19} .. {:<19}  {:>7}  {:>7}", j.name, angle(j.lower), angle(j.upper), bound(j.velocity), bound(j.effort))?;
        }

        match &self.standing {
            None => writeln!(f, "\nStanding pose: none (the model has no `standing` reference configuration)")?,
            Some(st) => {
                writeln!(f, "\nStanding pose:")?;
                if let (Some(p), Some(qt)) = (&st.base_position, &st.base_quaternion) {
                    writeln!(f, "  base height {} m (base at {}, quaternion (x, y, z, w) ({}, {}, {}, {}))", num(p.z, 4), vec3(p, 4), num(qt[0], 4), num(qt[1], 4), num(qt[2], 4), num(qt[3], 4))?;
                }
                let width = st.joints.iter().map(|(n, _)| n.len()).max().unwrap_or(0);
                for (name, value) in &st.joints {
                    writeln!(f, "  {name:<width$}  {:>17}", angle(*value))?;
                }
                writeln!(f, "\nFeet in the standing pose (centre of the foot sphere in the world, m):")?;
                let width = st.feet.iter().map(|ft| ft.name.len()).max().unwrap_or(0);
                for ft in &st.feet {
                    writeln!(f, "  {:<3} {:<width$}  {}", ft.leg, ft.name, vec3(&ft.world, 4))?;
                }
            }
        }
        Ok(())
    }
}
