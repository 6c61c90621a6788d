//! Scenario files: the world HyQ walks through and the goal it is given (Winkler 2015,
//! sec. VI: flat ground, one pallet, two stacked pallets, a 35 cm gap, stepping stones, and
//! a pallet placed after the first plan).
//!
//! ```toml
//! name = "pallet"
//! summary = "climb onto a 15 cm pallet and down again"
//! robot = "hyq"                    # optional, default "hyq"
//! start = [0.0, 0.0, 0.0]          # x (m), y (m), yaw (rad) of the base
//! goal = [3.0, 0.0, 0.0]           # x (m), y (m), yaw (rad) to reach
//! time_limit = 60.0                # s of simulated time before the trial counts as failed
//!
//! [world]
//! origin = [-1.0, -1.5]            # m, corner of the world height map
//! size = [5.0, 3.0]                # m, along x and y
//! resolution = 0.02                # m, optional (default 0.02)
//! ground = 0.0                     # m, optional (default 0)
//!
//! [[world.block]]                  # any number; later blocks are drawn over earlier ones
//! name = "pallet"                  # optional, for messages
//! x = [1.0, 2.2]                   # m, extent along x
//! y = [-0.4, 0.4]                  # m, extent along y
//! top = 0.15                       # m, height of its top surface (below ground: a gap)
//! support = true                   # optional (default true); false = no foot may go here
//! appears_at = 1.0                 # s, optional: absent until then (default: always there)
//! ```
//!
//! Every field is checked: unknown fields, NaNs, an empty extent or a world too small for
//! the start and goal are errors naming the file and the field.

use crate::terrain::HeightMap;
use serde::Deserialize;

/// A block of the world: a box top, a gap (a top below the ground, `support = false`) or a
/// stone, optionally appearing at a given time.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BlockSpec {
    #[serde(default)]
    pub name: Option<String>,
    pub x: [f64; 2],
    pub y: [f64; 2],
    pub top: f64,
    #[serde(default = "yes")]
    pub support: bool,
    #[serde(default)]
    pub appears_at: Option<f64>,
}

fn yes() -> bool {
    true
}

fn default_resolution() -> f64 {
    0.02
}

fn default_robot() -> String {
    "hyq".into()
}

/// The world: flat ground with blocks.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WorldSpec {
    pub origin: [f64; 2],
    pub size: [f64; 2],
    #[serde(default = "default_resolution")]
    pub resolution: f64,
    #[serde(default)]
    pub ground: f64,
    #[serde(default, rename = "block")]
    pub blocks: Vec<BlockSpec>,
}

/// A scenario file (see the module docs for the format).
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScenarioSpec {
    pub name: String,
    pub summary: String,
    #[serde(default = "default_robot")]
    pub robot: String,
    pub start: [f64; 3],
    pub goal: [f64; 3],
    pub time_limit: f64,
    pub world: WorldSpec,
}

/// A scenario file that cannot be used; names the file and the field.
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    #[error("{path}: cannot read the scenario: {error}")]
    Io { path: String, error: std::io::Error },
    #[error("{origin}: {message}")]
    Parse { origin: String, message: String },
    #[error("{origin}: field `{field}`: {problem}")]
    Invalid { origin: String, field: String, problem: String },
    #[error("no embedded scenario named '{name}' (embedded scenarios: {known})")]
    UnknownScenario { name: String, known: String },
}

/// The embedded scenarios (Winkler 2015, sec. VI), as `(name, TOML text)`.
pub const EMBEDDED_SCENARIOS: &[(&str, &str)] = &[
    ("flat", include_str!("../../scenarios/flat.toml")),
    ("pallet", include_str!("../../scenarios/pallet.toml")),
    ("two_pallets", include_str!("../../scenarios/two_pallets.toml")),
    ("gap", include_str!("../../scenarios/gap.toml")),
    ("stepping_stones", include_str!("../../scenarios/stepping_stones.toml")),
    ("pallet_appears", include_str!("../../scenarios/pallet_appears.toml")),
];

impl ScenarioSpec {
    /// Parses and checks TOML text; `origin` (a path or `embedded scenario NAME`) goes into
    /// errors.
    pub fn from_toml(text: &str, origin: &str) -> Result<Self, ScenarioError> {
        let spec: ScenarioSpec = toml::from_str(text).map_err(|e| ScenarioError::Parse { origin: origin.into(), message: e.to_string() })?;
        spec.check(origin)?;
        Ok(spec)
    }

    pub fn load_file(path: impl AsRef<std::path::Path>) -> Result<Self, ScenarioError> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|error| ScenarioError::Io { path: path.display().to_string(), error })?;
        Self::from_toml(&text, &path.display().to_string())
    }

    /// An embedded scenario by name.
    pub fn embedded(name: &str) -> Result<Self, ScenarioError> {
        let (_, text) = EMBEDDED_SCENARIOS.iter().find(|(n, _)| *n == name).ok_or_else(|| ScenarioError::UnknownScenario {
            name: name.into(),
            known: EMBEDDED_SCENARIOS.iter().map(|(n, _)| *n).collect::<Vec<_>>().join(", "),
        })?;
        Self::from_toml(text, &format!("embedded scenario {name}"))
    }

    /// An embedded name or a path to a TOML file.
    pub fn resolve(name_or_path: &str) -> Result<Self, ScenarioError> {
        if name_or_path.ends_with(".toml") || std::path::Path::new(name_or_path).exists() {
            Self::load_file(name_or_path)
        } else {
            Self::embedded(name_or_path)
        }
    }

    fn check(&self, origin: &str) -> Result<(), ScenarioError> {
        let bad = |field: String, problem: String| ScenarioError::Invalid { origin: origin.into(), field, problem };
        let finite = |field: &str, values: &[f64]| -> Result<(), ScenarioError> {
            match values.iter().position(|v| !v.is_finite()) {
                Some(i) => Err(bad(format!("{field}[{i}]"), format!("expected a finite number, got {}", values[i]))),
                None => Ok(()),
            }
        };
        finite("start", &self.start)?;
        finite("goal", &self.goal)?;
        if !(self.time_limit > 0.0 && self.time_limit.is_finite()) {
            return Err(bad("time_limit".into(), format!("expected a positive number of seconds, got {}", self.time_limit)));
        }
        let w = &self.world;
        finite("world.origin", &w.origin)?;
        finite("world.size", &w.size)?;
        finite("world.ground", &[w.ground])?;
        if !(w.resolution > 0.0 && w.resolution.is_finite() && w.resolution <= 0.1) {
            return Err(bad("world.resolution".into(), format!("expected a cell size in (0, 0.1] m, got {}", w.resolution)));
        }
        for (i, s) in w.size.iter().enumerate() {
            if *s < 2.0 * w.resolution {
                return Err(bad(format!("world.size[{i}]"), format!("expected at least two cells ({} m), got {s}", 2.0 * w.resolution)));
            }
        }
        // The height and cost maps hold every cell: bounded before they are allocated.
        let cells = (w.size[0] / w.resolution + 1.0).round() * (w.size[1] / w.resolution + 1.0).round();
        if cells > crate::terrain::MAX_CELLS as f64 {
            return Err(bad(
                "world.size".into(),
                format!(
                    "expected at most {} map cells at the resolution of {} m (the height and cost maps hold each), got {cells:.3e} for [{}, {}] m",
                    crate::terrain::MAX_CELLS,
                    w.resolution,
                    w.size[0],
                    w.size[1]
                ),
            ));
        }
        // The robot (about 1 m x 0.7 m around its base) must fit inside the world at start
        // and goal.
        let margin = 0.6;
        for (field, p) in [("start", &self.start), ("goal", &self.goal)] {
            let inside = (0..2).all(|a| p[a] - margin >= w.origin[a] && p[a] + margin <= w.origin[a] + w.size[a]);
            if !inside {
                return Err(bad(
                    field.into(),
                    format!("({}, {}) must lie at least {margin} m inside the world [{}, {}] x [{}, {}]", p[0], p[1], w.origin[0], w.origin[0] + w.size[0], w.origin[1], w.origin[1] + w.size[1]),
                ));
            }
        }
        for (k, b) in w.blocks.iter().enumerate() {
            let field = |f: &str| format!("world.block[{k}].{f}");
            finite(&field("x"), &b.x)?;
            finite(&field("y"), &b.y)?;
            finite(&field("top"), &[b.top])?;
            for (axis, r) in [("x", b.x), ("y", b.y)] {
                if r[1] <= r[0] {
                    return Err(bad(field(axis), format!("expected [min, max] with min < max, got [{}, {}]", r[0], r[1])));
                }
            }
            if let Some(t) = b.appears_at {
                if !(t >= 0.0 && t.is_finite()) {
                    return Err(bad(field("appears_at"), format!("expected a time >= 0 s, got {t}")));
                }
            }
        }
        Ok(())
    }

    /// Blocks present at time `t` (in file order).
    pub fn blocks_at(&self, t: f64) -> impl Iterator<Item = &BlockSpec> {
        self.world.blocks.iter().filter(move |b| b.appears_at.is_none_or(|a| a <= t))
    }

    /// The world's height map at time `t`.
    pub fn world_at(&self, t: f64) -> HeightMap {
        let w = &self.world;
        let columns = (w.size[0] / w.resolution).round() as usize + 1;
        let rows = (w.size[1] / w.resolution).round() as usize + 1;
        let mut map = HeightMap::flat(w.origin, w.resolution, columns, rows, w.ground);
        for b in self.blocks_at(t) {
            map.set_rect(b.x, b.y, b.top);
        }
        map
    }

    /// Times at which the world changes (blocks appearing), sorted.
    pub fn change_times(&self) -> Vec<f64> {
        let mut times: Vec<f64> = self.world.blocks.iter().filter_map(|b| b.appears_at).collect();
        times.sort_by(f64::total_cmp);
        times.dedup();
        times
    }

    /// Whether a foot may stand at `(x, y)` at time `t`: the topmost block containing the
    /// point (the last one in file order) decides; the open ground supports.
    pub fn supports(&self, t: f64, x: f64, y: f64) -> bool {
        self.top_block(t, x, y).is_none_or(|(_, b)| b.support)
    }

    /// The name of the block under `(x, y)` at time `t`, or `"ground"`.
    pub fn surface_name(&self, t: f64, x: f64, y: f64) -> String {
        match self.top_block(t, x, y) {
            Some((k, b)) => b.name.clone().unwrap_or_else(|| format!("block {k}")),
            None => "ground".into(),
        }
    }

    /// The last block in file order present at `t` that contains `(x, y)`, with its index.
    fn top_block(&self, t: f64, x: f64, y: f64) -> Option<(usize, &BlockSpec)> {
        let present = |b: &&BlockSpec| b.appears_at.is_none_or(|a| a <= t);
        self.world.blocks.iter().enumerate().rev().filter(|(_, b)| present(b)).find(|(_, b)| x >= b.x[0] && x <= b.x[1] && y >= b.y[0] && y <= b.y[1])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::terrain::Terrain;

    #[test]
    fn every_embedded_scenario_parses_and_builds_its_world() {
        for (name, _) in EMBEDDED_SCENARIOS {
            let s = ScenarioSpec::embedded(name).unwrap();
            assert_eq!(&s.name, name);
            let world = s.world_at(s.time_limit);
            // The start stands on support.
            assert!(s.supports(0.0, s.start[0], s.start[1]), "{name}");
            assert!(world.height(s.goal[0], s.goal[1]).is_finite());
        }
    }

    #[test]
    fn pallet_is_15_cm_and_the_gap_is_35_cm_without_support() {
        let p = ScenarioSpec::embedded("pallet").unwrap();
        let w = p.world_at(0.0);
        let b = &p.world.blocks[0];
        assert_eq!(((b.x[1] - b.x[0]) * 100.0).round(), 120.0);
        assert_eq!(((b.y[1] - b.y[0]) * 100.0).round(), 80.0);
        assert_eq!(w.height(0.5 * (b.x[0] + b.x[1]), 0.0), 0.15);
        let g = ScenarioSpec::embedded("gap").unwrap();
        let gap = g.world.blocks.iter().find(|b| !b.support).unwrap();
        assert!(((gap.x[1] - gap.x[0]) - 0.35).abs() < 1e-12);
        let mid = 0.5 * (gap.x[0] + gap.x[1]);
        assert!(!g.supports(0.0, mid, 0.0));
        assert!(g.supports(0.0, gap.x[0] - 0.05, 0.0));
    }

    #[test]
    fn stones_support_and_the_floor_between_them_does_not() {
        let s = ScenarioSpec::embedded("stepping_stones").unwrap();
        let stone = s.world.blocks.iter().find(|b| b.name.as_deref().is_some_and(|n| n.starts_with("stone"))).unwrap();
        let (cx, cy) = (0.5 * (stone.x[0] + stone.x[1]), 0.5 * (stone.y[0] + stone.y[1]));
        assert!(s.supports(0.0, cx, cy));
        assert!(!s.supports(0.0, cx, cy + 0.2));
        // Stones are 8 cm below the pallets.
        let pallet = s.world.blocks.iter().find(|b| b.name.as_deref() == Some("pallet A")).unwrap();
        assert!((pallet.top - stone.top - 0.08).abs() < 1e-12);
    }

    #[test]
    fn a_block_appears_at_its_time() {
        let s = ScenarioSpec::embedded("pallet_appears").unwrap();
        let t = s.change_times();
        assert_eq!(t.len(), 1);
        let b = &s.world.blocks[0];
        let (cx, cy) = (0.5 * (b.x[0] + b.x[1]), 0.5 * (b.y[0] + b.y[1]));
        assert_eq!(s.world_at(t[0] - 0.01).height(cx, cy), 0.0);
        assert_eq!(s.world_at(t[0]).height(cx, cy), b.top);
    }

    #[test]
    fn bad_files_name_the_field() {
        let good = include_str!("../../scenarios/pallet.toml");
        let cases = [
            (good.replace("time_limit = ", "colour = 1\ntime_limit = "), "colour"),
            (good.replace("top = 0.15", "top = nan"), "world.block[0].top"),
            (good.replace("x = [1.0, 2.2]", "x = [2.2, 1.0]"), "world.block[0].x"),
            (good.replace("goal = [3.0, 0.0, 0.0]", "goal = [30.0, 0.0, 0.0]"), "goal"),
            (good.replace("resolution = 0.02", "resolution = -1.0"), "world.resolution"),
            // 1e7 m squared would be 2.5e17 cells: refused before any map is allocated (it
            // aborted on the allocation).
            (good.replace("size = [5.0, 3.0]", "size = [1e7, 1e7]"), "at most 25000000 map cells"),
        ];
        for (text, field) in cases {
            let e = ScenarioSpec::from_toml(&text, "pallet.toml").unwrap_err().to_string();
            assert!(e.contains("pallet.toml") && e.contains(field), "{e}");
        }
        assert!(ScenarioSpec::embedded("moon").unwrap_err().to_string().contains("flat"));
    }
}
