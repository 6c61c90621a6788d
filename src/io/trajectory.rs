//! The trajectory file, `trajectory.json`: what every legwork run writes (simulations,
//! optimised motions, planned walks) and what the replay, the plots and the tracking
//! controllers read.
//!
//! ```json
//! {
//!   "metadata": {
//!     "robot": "hyq", "joint_names": ["lf_haa_joint", ...], "foot_names": ["lf_foot", ...],
//!     "dt": 0.001, "units": { "length": "m", ... }, "scenario": "simulate stand",
//!     "legwork_version": "0.1.0", "terrain": { "kind": "plane", ... }
//!   },
//!   "knots": [
//!     { "t": 0.0, "q": [19 numbers], "v": [18], "tau": [12],
//!       "contact_force": [[fx, fy, fz] x 4], "in_contact": [true x 4],
//!       "feedback_gain": [[36 numbers] x 12] (optional) },
//!     ...
//!   ],
//!   "summary": { "final_base_height_m": 0.57, ... }
//! }
//! ```
//!
//! Conventions (those of the whole library): `q = [base position (world), base quaternion
//! (x, y, z, w), joint angles in joint_names order]`, `v = [base linear velocity (base
//! frame), base angular velocity (base frame), joint velocities]`, `tau` the actuated
//! joints' torques in joint_names order, contact forces on the feet in the world frame,
//! feet in foot_names order. Feedback gains (optional) are `tau = tau_ff + K dx` with `dx`
//! the tangent-space state error `[difference(q*, q); v - v*]` (`2 nv` columns).
//!
//! Reading back ([`Trajectory::load_file`], [`Trajectory::from_json`]) checks every field
//! and names the field and the knot of any problem; [`Trajectory::check_against`] also
//! checks the joint and foot names against a robot model.

use crate::model::Model;
use crate::terrain::TerrainSpec;
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::path::Path;

/// Units of every quantity in the file (always SI; written so that a reader need not guess).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Units {
    pub length: String,
    pub angle: String,
    pub time: String,
    pub force: String,
    pub torque: String,
}

impl Default for Units {
    fn default() -> Self {
        Self { length: "m".into(), angle: "rad".into(), time: "s".into(), force: "N".into(), torque: "N m".into() }
    }
}

/// What the file is about.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Metadata {
    /// Robot name: an embedded robot (`hyq`, `a1`) or the name in the robot's file.
    pub robot: String,
    /// Actuated joints, in the order of `q[7..]`, `v[6..]` and `tau`.
    pub joint_names: Vec<String>,
    /// Feet, in the order of `contact_force` and `in_contact`.
    pub foot_names: Vec<String>,
    /// Nominal time between knots (s).
    pub dt: f64,
    pub units: Units,
    /// The task or scenario that produced the file (free text, e.g. `simulate stand`).
    pub scenario: String,
    /// Version of legwork that wrote the file.
    pub legwork_version: String,
    /// The ground the motion was computed on.
    pub terrain: TerrainSpec,
    /// Where each foot's tangential contact spring was attached at the first knot (world
    /// frame; `null` for a foot off the ground), for a replay that starts in the same
    /// state as the plan (optional).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub initial_anchors: Option<Vec<Option<[f64; 3]>>>,
    /// The joints' mechanical stops the motion was computed with (optional; absent: none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub joint_stops: Option<crate::sim::JointLimitParams>,
}

/// One instant of the motion.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Knot {
    pub t: f64,
    pub q: Vec<f64>,
    pub v: Vec<f64>,
    pub tau: Vec<f64>,
    /// Force of the ground on each foot, world frame (N).
    pub contact_force: Vec<[f64; 3]>,
    pub in_contact: Vec<bool>,
    /// Optional feedback gains, one row per actuated joint, `2 nv` columns.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub feedback_gain: Option<Vec<Vec<f64>>>,
}

/// The figures a run reports, in insertion order (`name: number or text`).
pub type Summary = serde_json::Map<String, serde_json::Value>;

/// A whole motion: metadata, knots, summary.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Trajectory {
    pub metadata: Metadata,
    pub knots: Vec<Knot>,
    #[serde(default)]
    pub summary: Summary,
}

/// A trajectory file that cannot be read or is inconsistent; names the file, the field and
/// (where there is one) the knot.
#[derive(Debug, thiserror::Error)]
pub enum TrajectoryError {
    #[error("{path}: {error}")]
    Io { path: String, error: std::io::Error },
    #[error("{origin}: {path}: {message}")]
    Parse { origin: String, path: String, message: String },
    #[error("{origin}: {field}: {problem}")]
    Invalid { origin: String, field: String, problem: String },
}

/// How far from the origin a trajectory's base may be (m). At 10 km a double still resolves
/// 2e-12 m; the bound is there to refuse numbers that are not a motion (1e300), not to
/// limit one.
pub const MAX_BASE_DISTANCE: f64 = 1e4;

impl Trajectory {
    /// An empty trajectory for `model` (joint and foot names taken from it).
    pub fn new(model: &Model, scenario: impl Into<String>, dt: f64, terrain: TerrainSpec) -> Self {
        Self {
            metadata: Metadata {
                robot: model.name.clone(),
                joint_names: model.actuated_joint_names().into_iter().map(String::from).collect(),
                foot_names: model.feet.iter().map(|f| f.name.clone()).collect(),
                dt,
                units: Units::default(),
                scenario: scenario.into(),
                legwork_version: env!("CARGO_PKG_VERSION").into(),
                terrain,
                initial_anchors: None,
                joint_stops: None,
            },
            knots: Vec::new(),
            summary: Summary::new(),
        }
    }

    /// Duration from the first to the last knot.
    pub fn duration(&self) -> f64 {
        match (self.knots.first(), self.knots.last()) {
            (Some(a), Some(b)) => b.t - a.t,
            _ => 0.0,
        }
    }

    /// Parses and validates JSON text; `origin` (a path) goes into error messages.
    pub fn from_json(text: &str, origin: &str) -> Result<Self, TrajectoryError> {
        let de = &mut serde_json::Deserializer::from_str(text);
        let traj: Trajectory = serde_path_to_error::deserialize(de).map_err(|e| TrajectoryError::Parse {
            origin: origin.into(),
            path: e.path().to_string(),
            message: e.inner().to_string(),
        })?;
        traj.validate(origin)?;
        Ok(traj)
    }

    /// Reads and validates a trajectory file.
    pub fn load_file(path: impl AsRef<Path>) -> Result<Self, TrajectoryError> {
        let path = path.as_ref();
        let name = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|error| TrajectoryError::Io { path: name.clone(), error })?;
        Self::from_json(&text, &name)
    }

    /// Writes the file as JSON.
    pub fn save_file(&self, path: impl AsRef<Path>) -> Result<(), TrajectoryError> {
        let path = path.as_ref();
        let io = |error| TrajectoryError::Io { path: path.display().to_string(), error };
        let file = std::fs::File::create(path).map_err(io)?;
        let mut w = std::io::BufWriter::new(file);
        serde_json::to_writer(&mut w, self).map_err(|e| io(e.into()))?;
        w.flush().map_err(io)
    }

    /// Checks the structure: lengths consistent with the metadata, every number finite,
    /// time increasing, quaternions of unit length.
    pub fn validate(&self, origin: &str) -> Result<(), TrajectoryError> {
        let bad = |field: String, problem: String| Err(TrajectoryError::Invalid { origin: origin.into(), field, problem });
        let m = &self.metadata;
        if !(m.dt > 0.0 && m.dt.is_finite()) {
            return bad("metadata.dt".into(), format!("expected a positive time step in seconds, got {}", m.dt));
        }
        if m.units != Units::default() {
            return bad("metadata.units".into(), format!("legwork files are in SI units {:?}, got {:?}", Units::default(), m.units));
        }
        if self.knots.is_empty() {
            return bad("knots".into(), "expected at least one knot".into());
        }
        let nj = m.joint_names.len();
        let nfeet = m.foot_names.len();
        let (nq, nv) = (7 + nj, 6 + nj);
        if let Some(anchors) = &m.initial_anchors {
            if anchors.len() != nfeet {
                return bad("metadata.initial_anchors".into(), format!("expected {nfeet} entries (one per foot in metadata.foot_names), got {}", anchors.len()));
            }
            for (f, a) in anchors.iter().enumerate() {
                if let Some(a) = a {
                    if a.iter().any(|x| !x.is_finite()) {
                        return bad(format!("metadata.initial_anchors[{f}]"), format!("expected a finite point [x, y, z] or null, got {a:?}"));
                    }
                }
            }
        }
        if let Some(stops) = &m.joint_stops {
            stops.validate().map_err(|e| TrajectoryError::Invalid { origin: origin.into(), field: format!("metadata.joint_stops.{}", e.field), problem: format!("expected {}, got {}", e.expected, e.value) })?;
        }
        let mut previous_t = f64::NEG_INFINITY;
        for (k, knot) in self.knots.iter().enumerate() {
            let field = |name: &str| format!("knots[{k}].{name}");
            if !knot.t.is_finite() || knot.t <= previous_t {
                return bad(field("t"), format!("expected a finite time after the previous knot's {previous_t}, got {}", knot.t));
            }
            previous_t = knot.t;
            for (name, values, expected) in [("q", &knot.q, nq), ("v", &knot.v, nv), ("tau", &knot.tau, nj)] {
                if values.len() != expected {
                    return bad(field(name), format!("expected {expected} numbers ({nj} joints in metadata.joint_names), got {}", values.len()));
                }
                if let Some(i) = values.iter().position(|x| !x.is_finite()) {
                    return bad(format!("{}[{i}]", field(name)), format!("expected a finite number, got {}", values[i]));
                }
            }
            if let Some(i) = (0..3).find(|&i| knot.q[i].abs() > MAX_BASE_DISTANCE) {
                return bad(format!("{}[{i}]", field("q")), format!("expected a base position within {MAX_BASE_DISTANCE} m of the origin (a legged robot's motion; farther, the dynamics lose their precision), got {:.3e}", knot.q[i]));
            }
            let quat_norm = knot.q[3..7].iter().map(|x| x * x).sum::<f64>().sqrt();
            if (quat_norm - 1.0).abs() > 1e-6 {
                return bad(format!("{}[3..7]", field("q")), format!("the base quaternion must have unit length, has {quat_norm}"));
            }
            if knot.contact_force.len() != nfeet {
                return bad(field("contact_force"), format!("expected {nfeet} forces (one per foot), got {}", knot.contact_force.len()));
            }
            for (i, f) in knot.contact_force.iter().enumerate() {
                if f.iter().any(|x| !x.is_finite()) {
                    return bad(format!("{}[{i}]", field("contact_force")), format!("expected finite numbers, got {f:?}"));
                }
            }
            if knot.in_contact.len() != nfeet {
                return bad(field("in_contact"), format!("expected {nfeet} flags (one per foot), got {}", knot.in_contact.len()));
            }
            if let Some(gain) = &knot.feedback_gain {
                if gain.len() != nj {
                    return bad(field("feedback_gain"), format!("expected {nj} rows (one per joint), got {}", gain.len()));
                }
                for (r, row) in gain.iter().enumerate() {
                    if row.len() != 2 * nv {
                        return bad(format!("{}[{r}]", field("feedback_gain")), format!("expected {} columns (2 nv), got {}", 2 * nv, row.len()));
                    }
                    if let Some(c) = row.iter().position(|x| !x.is_finite()) {
                        return bad(format!("{}[{r}][{c}]", field("feedback_gain")), format!("expected a finite number, got {}", row[c]));
                    }
                }
            }
        }
        Ok(())
    }

    /// Checks that the file fits `model`: same actuated joints in the same order, same feet.
    pub fn check_against(&self, model: &Model, origin: &str) -> Result<(), TrajectoryError> {
        let bad = |field: String, problem: String| Err(TrajectoryError::Invalid { origin: origin.into(), field, problem });
        let joints = model.actuated_joint_names();
        let m = &self.metadata;
        if m.joint_names.len() != joints.len() {
            return bad("metadata.joint_names".into(), format!("robot '{}' has {} actuated joints, the file {}", model.name, joints.len(), m.joint_names.len()));
        }
        for (i, (ours, theirs)) in joints.iter().zip(&m.joint_names).enumerate() {
            if ours != theirs {
                let problem = if joints.contains(&theirs.as_str()) {
                    format!("joint '{theirs}' is at position {} in robot '{}', expected '{ours}' here", joints.iter().position(|j| j == theirs).unwrap_or(0), model.name)
                } else {
                    format!("robot '{}' has no joint '{theirs}' (its joints: {})", model.name, joints.join(", "))
                };
                return bad(format!("metadata.joint_names[{i}]"), problem);
            }
        }
        let feet: Vec<&str> = model.feet.iter().map(|f| f.name.as_str()).collect();
        if feet.len() != m.foot_names.len() || feet.iter().zip(&m.foot_names).any(|(a, b)| a != b) {
            return bad("metadata.foot_names".into(), format!("robot '{}' has feet {:?}, the file {:?}", model.name, feet, m.foot_names));
        }
        Ok(())
    }

    /// CSV of the same columns, one row per knot: `t`, `q_<name>` (base `q_base_x`, ...,
    /// `q_base_qw`, then joints), `v_<name>`, `tau_<joint>`, `f_<foot>_{x,y,z}`,
    /// `contact_<foot>` (0/1).
    pub fn write_csv(&self, mut out: impl Write) -> std::io::Result<()> {
        let m = &self.metadata;
        let mut header = vec!["t".to_string()];
        header.extend(["x", "y", "z", "qx", "qy", "qz", "qw"].iter().map(|s| format!("q_base_{s}")));
        header.extend(m.joint_names.iter().map(|j| format!("q_{j}")));
        header.extend(["vx", "vy", "vz", "wx", "wy", "wz"].iter().map(|s| format!("v_base_{s}")));
        header.extend(m.joint_names.iter().map(|j| format!("v_{j}")));
        header.extend(m.joint_names.iter().map(|j| format!("tau_{j}")));
        for f in &m.foot_names {
            header.extend(["x", "y", "z"].iter().map(|a| format!("f_{f}_{a}")));
        }
        header.extend(m.foot_names.iter().map(|f| format!("contact_{f}")));
        writeln!(out, "{}", header.join(","))?;
        for k in &self.knots {
            let mut row = vec![k.t];
            row.extend(&k.q);
            row.extend(&k.v);
            row.extend(&k.tau);
            row.extend(k.contact_force.iter().flatten());
            row.extend(k.in_contact.iter().map(|&c| if c { 1.0 } else { 0.0 }));
            let cells: Vec<String> = row.iter().map(|x| format!("{x}")).collect();
            writeln!(out, "{}", cells.join(","))?;
        }
        Ok(())
    }

    /// Writes [`Trajectory::write_csv`] to a file.
    pub fn save_csv(&self, path: impl AsRef<Path>) -> Result<(), TrajectoryError> {
        let path = path.as_ref();
        let io = |error| TrajectoryError::Io { path: path.display().to_string(), error };
        let mut w = std::io::BufWriter::new(std::fs::File::create(path).map_err(io)?);
        self.write_csv(&mut w).map_err(io)?;
        w.flush().map_err(io)
    }
}
