//! The body state lattice and its motion primitives (Winkler 2015 eq. (1)).
//!
//! States `s = (x, y, theta)` are discretised on a lattice anchored at the start pose:
//! `x = x0 + ix * cell`, `y = y0 + iy * cell`, `theta = theta0 + heading * (2 pi / headings)`.
//! Anchoring at the start puts the start exactly on the lattice (no snapping), and
//! re-planning from the robot's current pose re-anchors. A primitive `a = (dx, dy, dtheta)`
//! is given in the body frame; for each heading it is rotated into the world and its end
//! rounded to the nearest cell once per query, so every state reached is exactly a lattice
//! point and a key `(ix, iy, heading)` identifies it (the lattice planner of SBPL does the
//! same). The rounding moves an end by at most half a cell along each axis (2 cm at 4 cm).

use super::BodyPose;
use std::f64::consts::PI;

/// A lattice state: cell indices from the start pose and heading index.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct LatticeKey {
    pub ix: i32,
    pub iy: i32,
    pub heading: u16,
}

/// One feasible action `a = (dx, dy, dyaw)` of Winkler 2015 eq. (1), in the body frame at
/// the start of the action, with its difficulty `c_a` (eq. (2): "sideways steps are more
/// difficult than forward ones").
#[derive(Clone, Debug, PartialEq)]
pub struct MotionPrimitive {
    pub name: String,
    /// Forward (m).
    pub dx: f64,
    /// Left (m).
    pub dy: f64,
    /// Counter-clockwise (rad); a multiple of the lattice's heading step.
    pub dyaw: f64,
    /// `c_a` (> 0).
    pub difficulty: f64,
}

impl MotionPrimitive {
    pub fn new(name: &str, dx: f64, dy: f64, dyaw_degrees: f64, difficulty: f64) -> Self {
        Self { name: name.into(), dx, dy, dyaw: dyaw_degrees.to_radians(), difficulty }
    }
}

/// HyQ's crawl actions, chosen for a 4 cm / 10 deg lattice (every length a whole number of
/// cells, every turn a whole number of headings).
///
/// One action is one crawl cycle: each leg swings once, and the body moves by the action.
/// Sizes from HyQ's standing pose (feet at +-0.37 m, +-0.32 m under hips 0.58 m high, thigh
/// and shank 0.35 m each): a foot reaches about +-0.15 m fore-aft around its nominal point
/// with the knee well inside its range, so a full step of 0.24 m swings each foot from 0.12 m
/// behind to 0.12 m ahead of it; sideways the hip abduction allows less, 0.12 m. Turning 20
/// deg in place moves each foot (0.49 m from the centre) by 0.17 m, a step of the same size.
/// The short forward step (0.12 m) places the feet before gaps and near the goal.
///
/// `stride` is the long step that crosses a 35 cm gap (Winkler 2015 sec. VI: "a gap of 35
/// cm, which is approximately half the robot's body length"): each foot moves 0.36 m, to
/// 0.18 m either side of its nominal point, within HyQ's reach at its walking height.
/// `long_stride` (0.44 m, feet to 0.22 m either side: the leg 0.62 m long, knee flexed about
/// 55 deg) is the cruising step where the terrain allows it.
///
/// Difficulties `c_a` per action; per metre: long stride 2.7, stride 3.1, forward_long 4.1,
/// forward 4.2, short forward 5.0, forward with a turn 5.5, diagonal 6.5, sideways and
/// backward 10 (the robot sees and steps best forward). A cycle takes about the same time
/// whatever its length, so the long steps are the cheap ones per metre; a cycle's cost still
/// grows a little with its length, for the reach it asks of the legs.
pub fn hyq_crawl_primitives() -> Vec<MotionPrimitive> {
    vec![
        MotionPrimitive::new("long_stride", 0.44, 0.0, 0.0, 1.2),
        MotionPrimitive::new("stride", 0.36, 0.0, 0.0, 1.1),
        MotionPrimitive::new("forward_long", 0.28, 0.0, 0.0, 1.15),
        MotionPrimitive::new("forward", 0.24, 0.0, 0.0, 1.0),
        MotionPrimitive::new("forward_short", 0.12, 0.0, 0.0, 0.6),
        MotionPrimitive::new("diagonal_left", 0.16, 0.12, 0.0, 1.3),
        MotionPrimitive::new("diagonal_right", 0.16, -0.12, 0.0, 1.3),
        MotionPrimitive::new("left", 0.0, 0.12, 0.0, 1.2),
        MotionPrimitive::new("right", 0.0, -0.12, 0.0, 1.2),
        MotionPrimitive::new("backward", -0.12, 0.0, 0.0, 1.2),
        MotionPrimitive::new("turn_left", 0.0, 0.0, 20.0, 1.0),
        MotionPrimitive::new("turn_right", 0.0, 0.0, -20.0, 1.0),
        MotionPrimitive::new("turn_left_small", 0.0, 0.0, 10.0, 0.7),
        MotionPrimitive::new("turn_right_small", 0.0, 0.0, -10.0, 0.7),
        MotionPrimitive::new("forward_turn_left", 0.20, 0.0, 10.0, 1.1),
        MotionPrimitive::new("forward_turn_right", 0.20, 0.0, -10.0, 1.1),
    ]
}

/// A primitive as a lattice step at one heading.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct LatticeStep {
    pub dix: i32,
    pub diy: i32,
    /// Heading change in steps (may be negative).
    pub dheading: i32,
}

/// The lattice of one query: its anchor, resolution and every primitive's step per heading.
#[derive(Clone, Debug)]
pub(super) struct Lattice {
    pub origin: BodyPose,
    pub cell: f64,
    pub headings: u16,
    /// `steps[heading * primitives + p]`.
    pub steps: Vec<LatticeStep>,
    pub primitives: usize,
}

/// `angle` wrapped to `(-pi, pi]`.
pub fn wrap_angle(angle: f64) -> f64 {
    let wrapped = angle.rem_euclid(2.0 * PI);
    if wrapped > PI {
        wrapped - 2.0 * PI
    } else {
        wrapped
    }
}

impl Lattice {
    /// An empty lattice; [`Lattice::anchor`] fills it for a query.
    pub fn new(cell: f64, headings: u16) -> Self {
        Self { origin: BodyPose { x: 0.0, y: 0.0, yaw: 0.0 }, cell, headings, steps: Vec::new(), primitives: 0 }
    }

    pub fn heading_step(&self) -> f64 {
        2.0 * PI / f64::from(self.headings)
    }

    /// Anchors the lattice at `origin` and tabulates the primitives' steps for every heading
    /// (reusing the table's memory).
    pub fn anchor(&mut self, origin: BodyPose, primitives: &[MotionPrimitive]) {
        self.origin = origin;
        self.primitives = primitives.len();
        self.steps.clear();
        let step = self.heading_step();
        for heading in 0..self.headings {
            let yaw = origin.yaw + f64::from(heading) * step;
            let (sin, cos) = yaw.sin_cos();
            for p in primitives {
                let (wx, wy) = (cos * p.dx - sin * p.dy, sin * p.dx + cos * p.dy);
                self.steps.push(LatticeStep {
                    dix: (wx / self.cell).round() as i32,
                    diy: (wy / self.cell).round() as i32,
                    dheading: (p.dyaw / step).round() as i32,
                });
            }
        }
    }

    pub fn step(&self, heading: u16, primitive: usize) -> LatticeStep {
        self.steps[usize::from(heading) * self.primitives + primitive]
    }

    /// The state `primitive` leads to from `key`.
    pub fn successor(&self, key: LatticeKey, primitive: usize) -> LatticeKey {
        let s = self.step(key.heading, primitive);
        let heading = (i32::from(key.heading) + s.dheading).rem_euclid(i32::from(self.headings));
        // `heading` is in [0, headings) and headings fits in u16.
        LatticeKey { ix: key.ix + s.dix, iy: key.iy + s.diy, heading: heading as u16 }
    }

    /// The continuous pose of a lattice state.
    pub fn pose(&self, key: LatticeKey) -> BodyPose {
        BodyPose {
            x: self.origin.x + f64::from(key.ix) * self.cell,
            y: self.origin.y + f64::from(key.iy) * self.cell,
            yaw: wrap_angle(self.origin.yaw + f64::from(key.heading) * self.heading_step()),
        }
    }

    /// The largest distance `primitive` moves the body over all headings (after rounding).
    pub fn max_translation(&self, primitive: usize) -> f64 {
        (0..self.headings)
            .map(|h| {
                let s = self.step(h, primitive);
                self.cell * f64::from(s.dix).hypot(f64::from(s.diy))
            })
            .fold(0.0, f64::max)
    }
}
