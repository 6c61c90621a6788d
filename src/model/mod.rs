//! The robot description: an immutable kinematic tree with a free-flyer (or fixed) base,
//! in Pinocchio's layout.
//!
//! Joint 0 is the universe (the world). Joints are stored in depth-first order, each joint's
//! parent before it, so every recursive algorithm is a plain loop over `1..njoints()`, and the
//! degrees of freedom of a subtree are contiguous in `v`. The configuration `q` and velocity
//! `v` follow Pinocchio: `q = [p, quat (x,y,z,w), joints]`, `v = [v_B, w_B, joints]` with the
//! base twist in the base frame (see `shared/fixtures/README.md`).
//!
//! A [`Model`] never changes once built; all scratch space lives in
//! [`crate::dynamics::Data`], one per thread.
//!
//! ```
//! use legwork::model::{Model, JointKind, JointLimits};
//! use legwork::spatial::{Inertia, SE3};
//! use nalgebra::{Matrix3, Vector3};
//! let mut m = Model::new("pendulum");
//! let j = m.add_joint(0, "hinge", JointKind::revolute(Vector3::y()), SE3::identity(),
//!                     JointLimits::unbounded(1)).unwrap();
//! m.append_body(j, "bob", Inertia::new(1.0, Vector3::new(0.0, 0.0, -1.0), Matrix3::zeros()), SE3::identity());
//! assert_eq!((m.nq, m.nv), (1, 1));
//! ```

pub mod description;
mod load;
pub use load::{is_embedded, load, LoadError};
pub mod embedded;
pub mod info;
pub mod urdf;
mod urdf_dom;

use crate::contact::ContactParams;
use crate::spatial::{Inertia, Motion, SE3};
use nalgebra::{DVector, Vector3};

/// The kind of a joint and its motion subspace.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum JointKind {
    /// The world; only joint 0.
    Universe,
    /// Six degrees of freedom: `nq = 7` (position, quaternion x,y,z,w), `nv = 6` (local twist).
    FreeFlyer,
    /// Rotation about a unit `axis` of the joint frame (URDF `revolute` and `continuous`).
    Revolute { axis: Vector3<f64> },
    /// Translation along a unit `axis` of the joint frame.
    Prismatic { axis: Vector3<f64> },
}

impl JointKind {
    /// A revolute joint; the axis is normalised.
    pub fn revolute(axis: Vector3<f64>) -> Self {
        JointKind::Revolute { axis: axis.normalize() }
    }
    /// A prismatic joint; the axis is normalised.
    pub fn prismatic(axis: Vector3<f64>) -> Self {
        JointKind::Prismatic { axis: axis.normalize() }
    }
    pub fn nq(&self) -> usize {
        match self {
            JointKind::Universe => 0,
            JointKind::FreeFlyer => 7,
            _ => 1,
        }
    }
    pub fn nv(&self) -> usize {
        match self {
            JointKind::Universe => 0,
            JointKind::FreeFlyer => 6,
            _ => 1,
        }
    }
    /// Motion subspace column of a one-degree-of-freedom joint, in the joint frame.
    #[inline]
    pub fn subspace(&self) -> Motion {
        match *self {
            JointKind::Revolute { axis } => Motion::new(Vector3::zeros(), axis),
            JointKind::Prismatic { axis } => Motion::new(axis, Vector3::zeros()),
            _ => Motion::zero(),
        }
    }
    /// Short name, like Pinocchio's `shortname()` without the prefix.
    pub fn short_name(&self) -> &'static str {
        match self {
            JointKind::Universe => "universe",
            JointKind::FreeFlyer => "free_flyer",
            JointKind::Revolute { .. } => "revolute",
            JointKind::Prismatic { .. } => "prismatic",
        }
    }
}

/// Limits of one joint, one entry per configuration coordinate (position) or velocity
/// coordinate (velocity, effort). Unbounded is `f64::INFINITY`.
#[derive(Clone, Debug, PartialEq)]
pub struct JointLimits {
    pub lower: Vec<f64>,
    pub upper: Vec<f64>,
    pub velocity: Vec<f64>,
    pub effort: Vec<f64>,
}

impl JointLimits {
    /// No position, velocity or effort bound, for a joint with `nv` degrees of freedom
    /// (and `nq = nv`, or 7 for a free flyer with `nv = 6`).
    pub fn unbounded(nv: usize) -> Self {
        let nq = if nv == 6 { 7 } else { nv };
        Self {
            lower: vec![f64::NEG_INFINITY; nq],
            upper: vec![f64::INFINITY; nq],
            velocity: vec![f64::INFINITY; nv],
            effort: vec![f64::INFINITY; nv],
        }
    }
    /// Limits of a one-degree-of-freedom joint.
    pub fn new(lower: f64, upper: f64, velocity: f64, effort: f64) -> Self {
        Self { lower: vec![lower], upper: vec![upper], velocity: vec![velocity], effort: vec![effort] }
    }
}

/// One joint of the tree.
#[derive(Clone, Debug, PartialEq)]
pub struct Joint {
    pub name: String,
    pub kind: JointKind,
    /// Index of the parent joint (0 = universe).
    pub parent: usize,
    /// Pose of this joint's frame in the parent joint's frame at zero joint value.
    pub placement: SE3,
    pub idx_q: usize,
    pub nq: usize,
    pub idx_v: usize,
    pub nv: usize,
    pub limits: JointLimits,
}

/// What a frame marks.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum FrameKind {
    /// The frame of a joint.
    Joint,
    /// A body (URDF link) attached to a joint, including links merged through fixed joints.
    Body,
    /// The frame of a fixed joint that was merged away.
    Fixed,
    /// A user-defined operational frame.
    Operational,
}

/// A named frame rigidly attached to a joint.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    pub name: String,
    pub kind: FrameKind,
    /// The joint the frame moves with.
    pub parent_joint: usize,
    /// Pose of the frame in the parent joint's frame.
    pub placement: SE3,
}

/// A foot: a frame at the centre of the foot sphere, and the sphere's radius.
#[derive(Clone, Debug, PartialEq)]
pub struct Foot {
    pub name: String,
    pub frame: usize,
    pub radius: f64,
}

/// Problems building or querying a model.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ModelError {
    #[error("parent joint {parent} does not exist (model has {njoints} joints)")]
    NoSuchParent { parent: usize, njoints: usize },
    #[error("joint '{name}': parent '{parent}' is not on the current depth-first branch; add joints in depth-first order")]
    NotDepthFirst { name: String, parent: String },
    #[error("a joint named '{0}' already exists")]
    DuplicateJoint(String),
    #[error("a frame named '{0}' already exists")]
    DuplicateFrame(String),
    #[error("a free-flyer joint can only be the first joint, attached to the universe")]
    FreeFlyerNotRoot,
    #[error("joint '{name}': {problem}")]
    BadJoint { name: String, problem: String },
    #[error("no joint named '{0}'")]
    NoSuchJoint(String),
    #[error("no frame named '{0}'")]
    NoSuchFrame(String),
    #[error("{what}: expected length {expected}, got {got}")]
    Length { what: &'static str, expected: usize, got: usize },
    #[error("{what}: element {index} is not finite ({value})")]
    NotFinite { what: &'static str, index: usize, value: f64 },
}

/// The immutable kinematic and inertial description of a robot.
#[derive(Clone, Debug)]
pub struct Model {
    pub name: String,
    /// Dimension of the configuration vector.
    pub nq: usize,
    /// Dimension of the velocity vector.
    pub nv: usize,
    /// Joints, index 0 = universe, depth-first.
    pub joints: Vec<Joint>,
    /// Body inertia of each joint, in the joint frame (fixed-jointed links merged in).
    pub inertias: Vec<Inertia>,
    /// Named frames (joints, bodies, merged fixed joints, feet).
    pub frames: Vec<Frame>,
    /// The feet, in the order LF, RF, LH, RH where the model knows them.
    pub feet: Vec<Foot>,
    /// Spatial gravity acceleration in the world frame (linear part `[0, 0, -9.81]`).
    pub gravity: Motion,
    /// Named reference configurations (e.g. `standing`).
    pub reference_configurations: Vec<(String, DVector<f64>)>,
    /// The feet's contact with the ground: one model for the optimizer, the simulator and
    /// the MuJoCo export ([`ContactParams`]; a description's `[contact]` section, or the
    /// calibration for the robot's foot load, [`Model::calibrated_contact`]).
    pub contact: ContactParams,
    /// `last_subtree_joint[i]`: the last joint of the subtree rooted at `i` (depth-first).
    pub last_subtree_joint: Vec<usize>,
    /// Number of velocity coordinates in the subtree rooted at each joint.
    pub nv_subtree: Vec<usize>,
    /// For each velocity index, the joint it belongs to.
    pub joint_of_dof: Vec<usize>,
    /// For each velocity index `k`, the previous velocity index on the path to the root
    /// (`usize::MAX` at the root): the sparsity pattern of `M` (Featherstone 2008, §6.5).
    pub dof_parent: Vec<usize>,
    /// The frames' (name, kind) pairs, for [`Model::add_frame`]'s uniqueness test in constant
    /// time (a URDF with 200,000 links must not take a quadratic scan).
    frame_keys: std::collections::HashSet<(String, FrameKind)>,
}

/// Standard gravity, m/s^2.
pub const STANDARD_GRAVITY: f64 = 9.81;

impl Model {
    /// An empty model: the universe only.
    pub fn new(name: impl Into<String>) -> Self {
        let universe = Joint {
            name: "universe".into(),
            kind: JointKind::Universe,
            parent: 0,
            placement: SE3::identity(),
            idx_q: 0,
            nq: 0,
            idx_v: 0,
            nv: 0,
            limits: JointLimits::unbounded(0),
        };
        Self {
            name: name.into(),
            nq: 0,
            nv: 0,
            joints: vec![universe],
            inertias: vec![Inertia::zero()],
            frames: vec![Frame { name: "universe".into(), kind: FrameKind::Joint, parent_joint: 0, placement: SE3::identity() }],
            feet: Vec::new(),
            gravity: Motion::new(Vector3::new(0.0, 0.0, -STANDARD_GRAVITY), Vector3::zeros()),
            reference_configurations: Vec::new(),
            // Set by the builders once the masses and feet are known.
            contact: ContactParams::default(),
            last_subtree_joint: vec![0],
            nv_subtree: vec![0],
            joint_of_dof: Vec::new(),
            dof_parent: Vec::new(),
            frame_keys: [("universe".to_string(), FrameKind::Joint)].into_iter().collect(),
        }
    }

    /// Number of joints including the universe.
    pub fn njoints(&self) -> usize {
        self.joints.len()
    }

    /// True when joint 1 is a free flyer.
    pub fn has_free_flyer(&self) -> bool {
        self.joints.len() > 1 && self.joints[1].kind == JointKind::FreeFlyer
    }

    /// Adds a joint under `parent` and returns its index. Joints must come in depth-first
    /// order: `parent` is the last joint added or one of its ancestors.
    pub fn add_joint(
        &mut self,
        parent: usize,
        name: impl Into<String>,
        kind: JointKind,
        placement: SE3,
        limits: JointLimits,
    ) -> Result<usize, ModelError> {
        let name = name.into();
        let n = self.joints.len();
        if parent >= n {
            return Err(ModelError::NoSuchParent { parent, njoints: n });
        }
        if self.joints.iter().any(|j| j.name == name) {
            return Err(ModelError::DuplicateJoint(name));
        }
        if kind == JointKind::Universe {
            return Err(ModelError::BadJoint { name, problem: "the universe cannot be added".into() });
        }
        if kind == JointKind::FreeFlyer && (parent != 0 || n != 1) {
            return Err(ModelError::FreeFlyerNotRoot);
        }
        if let JointKind::Revolute { axis } | JointKind::Prismatic { axis } = kind {
            if !axis.iter().all(|x| x.is_finite()) || (axis.norm() - 1.0).abs() > 1e-9 {
                return Err(ModelError::BadJoint { name, problem: format!("axis {:?} is not a unit vector", axis.as_slice()) });
            }
        }
        if !placement.is_finite() {
            return Err(ModelError::BadJoint { name, problem: "placement is not finite".into() });
        }
        // Depth-first: the parent must be an ancestor of (or equal to) the last joint.
        let mut a = n - 1;
        while a != parent && a != 0 {
            a = self.joints[a].parent;
        }
        if a != parent {
            return Err(ModelError::NotDepthFirst { name, parent: self.joints[parent].name.clone() });
        }
        let (nq, nv) = (kind.nq(), kind.nv());
        if limits.lower.len() != nq || limits.upper.len() != nq || limits.velocity.len() != nv || limits.effort.len() != nv {
            return Err(ModelError::BadJoint { name, problem: format!("limits must have {nq} position and {nv} velocity/effort entries") });
        }
        for (lo, hi) in limits.lower.iter().zip(&limits.upper) {
            if lo.is_nan() || hi.is_nan() || lo > hi {
                return Err(ModelError::BadJoint { name, problem: format!("position limits [{lo}, {hi}] are not an interval") });
            }
        }
        if limits.velocity.iter().chain(&limits.effort).any(|x| x.is_nan() || *x < 0.0) {
            return Err(ModelError::BadJoint { name, problem: "velocity and effort limits must be non-negative".into() });
        }
        let joint = Joint { name: name.clone(), kind, parent, placement, idx_q: self.nq, nq, idx_v: self.nv, nv, limits };
        self.nq += nq;
        self.nv += nv;
        self.joints.push(joint);
        self.inertias.push(Inertia::zero());
        self.frame_keys.insert((name.clone(), FrameKind::Joint));
        self.frames.push(Frame { name, kind: FrameKind::Joint, parent_joint: n, placement: SE3::identity() });
        self.extend_topology(n);
        Ok(n)
    }

    /// Attaches a body with `inertia` (given in the body's own frame) to `joint`, the body
    /// frame sitting at `placement` in the joint frame; its inertia is lumped into the joint's
    /// body and a body frame named `name` is added.
    pub fn append_body(&mut self, joint: usize, name: impl Into<String>, inertia: Inertia, placement: SE3) -> usize {
        self.inertias[joint] = self.inertias[joint] + inertia.transformed(&placement);
        let name = name.into();
        self.frame_keys.insert((name.clone(), FrameKind::Body));
        self.frames.push(Frame { name, kind: FrameKind::Body, parent_joint: joint, placement });
        self.frames.len() - 1
    }

    /// Adds a named frame; names are unique.
    pub fn add_frame(&mut self, frame: Frame) -> Result<usize, ModelError> {
        if !self.frame_keys.insert((frame.name.clone(), frame.kind)) {
            return Err(ModelError::DuplicateFrame(frame.name));
        }
        self.frames.push(frame);
        Ok(self.frames.len() - 1)
    }

    /// Declares the feet by frame name (any order; LF, RF, LH, RH by convention).
    pub fn set_feet(&mut self, names: &[&str], radius: f64) -> Result<(), ModelError> {
        let mut feet = Vec::with_capacity(names.len());
        for n in names {
            let frame = self.frame_id(n)?;
            feet.push(Foot { name: (*n).to_string(), frame, radius });
        }
        self.feet = feet;
        Ok(())
    }

    /// Extends the topology by joint `n`, just added as the last joint in depth-first order:
    /// its own subtree is itself, and every ancestor's subtree (the universe's included) now
    /// ends at `n` and holds its velocities. O(depth), so building a model is linear in its
    /// size for a bounded depth.
    fn extend_topology(&mut self, n: usize) {
        let joint = &self.joints[n];
        let (nv, idx_v, parent) = (joint.nv, joint.idx_v, joint.parent);
        self.last_subtree_joint.push(n);
        self.nv_subtree.push(nv);
        let mut a = parent;
        loop {
            self.last_subtree_joint[a] = n;
            self.nv_subtree[a] += nv;
            if a == 0 {
                break;
            }
            a = self.joints[a].parent;
        }
        let parent_last_dof = if parent > 0 { Some(self.joints[parent].idx_v + self.joints[parent].nv - 1) } else { None };
        for k in 0..nv {
            self.joint_of_dof.push(n);
            self.dof_parent.push(if k > 0 { idx_v + k - 1 } else { parent_last_dof.unwrap_or(usize::MAX) });
        }
    }

    /// Index of the joint called `name`.
    pub fn joint_id(&self, name: &str) -> Result<usize, ModelError> {
        self.joints.iter().position(|j| j.name == name).ok_or_else(|| ModelError::NoSuchJoint(name.into()))
    }

    /// Index of the frame called `name` (body frames first, then any kind).
    pub fn frame_id(&self, name: &str) -> Result<usize, ModelError> {
        self.frames
            .iter()
            .position(|f| f.name == name && f.kind == FrameKind::Body)
            .or_else(|| self.frames.iter().position(|f| f.name == name))
            .ok_or_else(|| ModelError::NoSuchFrame(name.into()))
    }

    /// The calibrated contact ([`ContactParams::for_foot_load`]) for this robot's standing
    /// load per foot, `total mass / number of feet` (the total mass on one foot if the model
    /// has no feet).
    pub fn calibrated_contact(&self) -> ContactParams {
        ContactParams::for_foot_load(self.total_mass() / self.feet.len().max(1) as f64)
    }

    /// Total mass of the robot, kg.
    pub fn total_mass(&self) -> f64 {
        self.inertias.iter().map(|i| i.mass).sum()
    }

    /// The neutral configuration: base at the origin with identity orientation, joints at 0.
    pub fn neutral(&self) -> DVector<f64> {
        let mut q = DVector::zeros(self.nq);
        if self.has_free_flyer() {
            q[6] = 1.0;
        }
        q
    }

    /// A named reference configuration (`standing`, ...).
    pub fn reference_configuration(&self, name: &str) -> Option<&DVector<f64>> {
        self.reference_configurations.iter().find(|(n, _)| n == name).map(|(_, q)| q)
    }

    /// The actuated (non-base) joints in `v` order: every joint but the universe and the free
    /// flyer (one degree of freedom each: revolute or prismatic).
    pub fn actuated_joints(&self) -> impl Iterator<Item = &Joint> {
        self.joints.iter().skip(1).filter(|j| j.kind != JointKind::FreeFlyer)
    }

    /// Names of the actuated (non-base) joints in `v` order.
    pub fn actuated_joint_names(&self) -> Vec<&str> {
        self.actuated_joints().map(|j| j.name.as_str()).collect()
    }

    /// Index into `q` of the one-dimensional joint `name`.
    pub fn q_index(&self, name: &str) -> Result<usize, ModelError> {
        let j = &self.joints[self.joint_id(name)?];
        if j.nq != 1 {
            return Err(ModelError::BadJoint { name: name.into(), problem: "has more than one coordinate".into() });
        }
        Ok(j.idx_q)
    }

    /// Index into `v` of the one-degree-of-freedom joint `name`.
    pub fn v_index(&self, name: &str) -> Result<usize, ModelError> {
        let j = &self.joints[self.joint_id(name)?];
        if j.nv != 1 {
            return Err(ModelError::BadJoint { name: name.into(), problem: "has more than one degree of freedom".into() });
        }
        Ok(j.idx_v)
    }

    /// A configuration built from the neutral one with joint values set by name.
    ///
    /// ```
    /// let model = legwork::model::embedded::load("a1").unwrap();
    /// let q = model.configuration_from_named(&[("FL_calf_joint", -1.8)]).unwrap();
    /// assert_eq!(q[model.q_index("FL_calf_joint").unwrap()], -1.8);
    /// ```
    pub fn configuration_from_named(&self, values: &[(&str, f64)]) -> Result<DVector<f64>, ModelError> {
        let mut q = self.neutral();
        for (name, value) in values {
            q[self.q_index(name)?] = *value;
        }
        Ok(q)
    }

    /// Checks that `q` has length `nq`, is finite and, for a free flyer, has a non-zero
    /// quaternion. Algorithms assume this and do not re-check.
    pub fn check_configuration(&self, q: &DVector<f64>) -> Result<(), ModelError> {
        check_vector("q", q, self.nq)?;
        if self.has_free_flyer() {
            let n = q.rows(3, 4).norm();
            if n < 1e-9 {
                return Err(ModelError::BadJoint { name: self.joints[1].name.clone(), problem: "quaternion is zero".into() });
            }
        }
        Ok(())
    }

    /// Checks that `v` (or `tau`, `a`) has length `nv` and is finite.
    pub fn check_tangent(&self, what: &'static str, v: &DVector<f64>) -> Result<(), ModelError> {
        check_vector(what, v, self.nv)
    }
}

fn check_vector(what: &'static str, x: &DVector<f64>, n: usize) -> Result<(), ModelError> {
    if x.len() != n {
        return Err(ModelError::Length { what, expected: n, got: x.len() });
    }
    if let Some((index, value)) = x.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(ModelError::NotFinite { what, index, value: *value });
    }
    Ok(())
}
