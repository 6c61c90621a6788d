//! Flat ground with axis-aligned boxes on it: the platforms of Nguyen 2022's jumps (a 0.4 m,
//! 0.9 m and 2 m box). The edges are exact: the height steps from the ground to a box's top
//! at its border, with no ramp (a height map's bilinear cells would put one there).
//!
//! The surface is a height function, as every [`Terrain`]: a box's top and the ground are
//! its faces, a box's vertical sides are not surfaces a foot can touch from the side (a foot
//! sphere pressing against a wall below the top has the ground under its centre). MuJoCo's
//! box geoms do have those sides (see [`crate::export::mjcf_model`]).

use super::{Terrain, TerrainSpec};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// One box: from the ground up to `top` (world z, m), over `x[0]..x[1]` times `y[0]..y[1]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoxSpec {
    pub x: [f64; 2],
    pub y: [f64; 2],
    pub top: f64,
}

impl BoxSpec {
    /// Whether `(x, y)` is over the box (its border included: the top is closed).
    fn covers(&self, x: f64, y: f64) -> bool {
        x >= self.x[0] && x <= self.x[1] && y >= self.y[0] && y <= self.y[1]
    }

    /// Horizontal distance from `(x, y)` to the box's footprint (0 over it).
    pub fn distance(&self, x: f64, y: f64) -> f64 {
        let dx = (self.x[0] - x).max(x - self.x[1]).max(0.0);
        let dy = (self.y[0] - y).max(y - self.y[1]).max(0.0);
        dx.hypot(dy)
    }
}

/// The ground plane `z = ground` with boxes standing on it.
///
/// ```
/// use legwork::terrain::{BoxSpec, Boxes, Terrain};
/// let t = Boxes::new(0.0, vec![BoxSpec { x: [-0.5, 0.5], y: [-0.5, 0.15], top: 0.4 }]).unwrap();
/// assert_eq!(t.height(0.0, 0.15), 0.4);
/// assert_eq!(t.height(0.0, 0.1500001), 0.0);
/// // A foot of radius 0.02 beside the edge could touch the top: the bound is the top.
/// assert_eq!(t.highest_near(0.0, 0.16, 0.02), 0.4);
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct Boxes {
    ground: f64,
    boxes: Vec<BoxSpec>,
}

impl Boxes {
    /// Flat ground and no box.
    pub fn flat(ground: f64) -> Self {
        Self { ground, boxes: Vec::new() }
    }

    /// Checks the numbers: finite, each extent `[min, max]` with `min < max`, each top above
    /// the ground. The error names the field (`boxes[i].x`, ...).
    pub fn new(ground: f64, boxes: Vec<BoxSpec>) -> Result<Self, (String, String)> {
        if !ground.is_finite() {
            return Err(("ground".into(), format!("expected a finite height, got {ground}")));
        }
        for (i, b) in boxes.iter().enumerate() {
            for (name, r) in [("x", b.x), ("y", b.y)] {
                if !(r[0].is_finite() && r[1].is_finite() && r[0] < r[1]) {
                    return Err((format!("boxes[{i}].{name}"), format!("expected [min, max] with min < max, got {r:?}")));
                }
            }
            if !(b.top.is_finite() && b.top > ground) {
                return Err((format!("boxes[{i}].top"), format!("expected a finite height above the ground ({ground}), got {}", b.top)));
            }
        }
        Ok(Self { ground, boxes })
    }

    /// The ground's height.
    pub fn ground(&self) -> f64 {
        self.ground
    }

    /// The boxes.
    pub fn boxes(&self) -> &[BoxSpec] {
        &self.boxes
    }
}

impl Terrain for Boxes {
    /// The highest top over `(x, y)`, or the ground.
    fn height(&self, x: f64, y: f64) -> f64 {
        self.boxes.iter().filter(|b| b.covers(x, y)).fold(self.ground, |h, b| h.max(b.top))
    }
    /// Every face a foot stands on is horizontal.
    fn normal(&self, _x: f64, _y: f64) -> Vector3<f64> {
        Vector3::z()
    }
    /// The highest top of the boxes the disk reaches (its distance to the footprint at most
    /// `radius`), or the ground: exact, the surface reaches that height inside the disk.
    fn highest_near(&self, x: f64, y: f64, radius: f64) -> f64 {
        self.boxes.iter().filter(|b| b.distance(x, y) <= radius).fold(self.ground, |h, b| h.max(b.top))
    }
    fn spec(&self) -> TerrainSpec {
        TerrainSpec::Boxes { ground: self.ground, boxes: self.boxes.clone() }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn two_boxes() -> Boxes {
        // A 0.9 m platform and a 0.3 m step overlapping it on x in [0.4, 0.5].
        Boxes::new(-0.1, vec![BoxSpec { x: [-0.5, 0.5], y: [-0.5, 0.147], top: 0.9 }, BoxSpec { x: [0.4, 1.0], y: [-0.2, 0.2], top: 0.3 }]).unwrap()
    }

    #[test]
    fn height_steps_exactly_at_the_edges() {
        let t = two_boxes();
        assert_eq!(t.height(0.0, 0.0), 0.9);
        assert_eq!(t.height(0.0, 0.147), 0.9);
        assert_eq!(t.height(0.0, 0.147 + 1e-12), -0.1);
        assert_eq!(t.height(0.45, 0.18), 0.3); // over the step only
        assert_eq!(t.height(0.45, 0.1), 0.9); // over both: the higher top
        assert_eq!(t.height(1.0 + 1e-12, 0.0), -0.1);
        assert_eq!(t.height(-3.0, 7.0), -0.1);
        for (x, y) in [(0.0, 0.0), (0.5, 0.147), (2.0, 2.0)] {
            assert_eq!(t.normal(x, y), Vector3::z());
            assert_eq!(t.surface(x, y), (t.height(x, y), Vector3::z()));
        }
    }

    #[test]
    fn highest_near_bounds_the_surface_over_the_disk_and_is_reached() {
        let t = two_boxes();
        let r = 0.02;
        for k in 0..400 {
            let (x, y) = (-0.6 + 0.004 * k as f64, 0.1 + 0.0003 * k as f64);
            let bound = t.highest_near(x, y, r);
            let mut reached = f64::NEG_INFINITY;
            for s in 0..64 {
                let a = s as f64 * std::f64::consts::TAU / 64.0;
                for rr in [0.0, 0.5 * r, r * (1.0 - 1e-9)] {
                    let h = t.height(x + rr * a.cos(), y + rr * a.sin());
                    assert!(h <= bound, "({x}, {y}): {h} > {bound}");
                    reached = reached.max(h);
                }
            }
            // Exact: sampled away from the tangency, the disk reaches the bound.
            let margin = t.boxes().iter().map(|b| (b.distance(x, y) - r).abs()).fold(f64::INFINITY, f64::min);
            if margin > 1e-3 {
                assert_eq!(reached, bound, "({x}, {y})");
            }
        }
        // Beside the platform's edge, 1.9 cm away: the top; 2.1 cm away: the ground.
        assert_eq!(t.highest_near(0.0, 0.166, r), 0.9);
        assert_eq!(t.highest_near(0.0, 0.168, r), -0.1);
        // Diagonal from a corner: the distance is Euclidean, not per axis.
        // 2.12 cm from the platform's corner (1.5 cm per axis): not near it, only over the step.
        assert_eq!(t.highest_near(0.5 + 0.015, 0.147 + 0.015, r), 0.3);
        assert_eq!(t.highest_near(-0.5 - 0.015, 0.147 + 0.015, r), -0.1);
    }

    #[test]
    fn spec_round_trip_and_checks() {
        let t = two_boxes();
        let spec = t.spec();
        let json = serde_json::to_string(&spec).unwrap();
        assert!(json.starts_with("{\"kind\":\"boxes\",\"ground\":-0.1,\"boxes\":[{\"x\":[-0.5,0.5]"), "{json}");
        let back: TerrainSpec = serde_json::from_str(&json).unwrap();
        let built = back.build("test").unwrap();
        assert_eq!(built.spec(), spec);
        assert_eq!(built.height(0.45, 0.18), 0.3);
        let bad = TerrainSpec::Boxes { ground: 0.0, boxes: vec![BoxSpec { x: [1.0, 0.0], y: [0.0, 1.0], top: 1.0 }] };
        let e = bad.build("trajectory.json").err().map(|e| e.to_string()).unwrap_or_default();
        assert_eq!(e, "trajectory.json: field `boxes[0].x`: expected [min, max] with min < max, got [1.0, 0.0]");
        let low = TerrainSpec::Boxes { ground: 0.5, boxes: vec![BoxSpec { x: [0.0, 1.0], y: [0.0, 1.0], top: 0.5 }] };
        assert!(low.build("t").err().is_some_and(|e| e.to_string().contains("boxes[0].top")));
        let unknown = "{\"kind\":\"boxes\",\"ground\":0.0,\"boxes\":[{\"x\":[0,1],\"y\":[0,1],\"top\":1,\"colour\":2}]}";
        assert!(serde_json::from_str::<TerrainSpec>(unknown).unwrap_err().to_string().contains("colour"));
    }
}
