//! The action cost of Winkler 2015 eq. (2), `c(s, a) = w^T c(s, a)`, and the terrain
//! evaluation of a body pose that its terms read.

use super::stance::NominalStance;
use super::{BodyPlannerConfig, BodyPose};
use crate::plan::TerrainCostField;

/// At most this many best cells are averaged per leg (the `n` of `c_t`).
pub const MAX_BEST_CELLS: usize = 16;

/// The weights `w` of eq. (2) (defaults in parentheses). A weight of one term against
/// another is what the paper leaves to tuning; these make one unit of difficulty (a forward
/// step) worth a quarter of a fully bad foothold average, a swing rise of one
/// `swing_rise_scale` or a tilt of one `tilt_scale` half of it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ActionCostWeights {
    /// `w_t` on `c_t_bar` (4).
    pub terrain: f64,
    /// `w_a` on `c_a` (1; > 0, since it is what makes every action cost something).
    pub difficulty: f64,
    /// `w_pc` on `c_pc` (2).
    pub swing_collision: f64,
    /// `w_po` on `c_po` (2).
    pub orientation: f64,
}

impl Default for ActionCostWeights {
    fn default() -> Self {
        Self { terrain: 4.0, difficulty: 1.0, swing_collision: 2.0, orientation: 2.0 }
    }
}

/// The four terms of `c(s, a)` (Winkler 2015 eq. (2)) and their weighted sum.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ActionCost {
    /// `c_t_bar`: the mean over the legs of the mean of the `n` best terrain costs around the
    /// leg's nominal foothold after the action, in `[0, 1]`.
    pub terrain: f64,
    /// `c_a`: the primitive's difficulty.
    pub difficulty: f64,
    /// `c_pc`: the largest rise of the ground above both ends of a swing, over all legs,
    /// divided by `swing_rise_scale`.
    pub swing_collision: f64,
    /// `c_po`: the tilt of the plane through the footholds after the action, divided by
    /// `tilt_scale`.
    pub orientation: f64,
    /// `w^T c`.
    pub total: f64,
}

impl ActionCost {
    /// Eq. (2): `c(s, a) = w_t c_t_bar + w_a c_a + w_pc c_pc + w_po c_po`.
    pub fn weighted(terrain: f64, difficulty: f64, swing_collision: f64, orientation: f64, w: &ActionCostWeights) -> Self {
        let total = w.terrain * terrain + w.difficulty * difficulty + w.swing_collision * swing_collision + w.orientation * orientation;
        Self { terrain, difficulty, swing_collision, orientation, total }
    }

    /// The terms of `primitive` ending on terrain `after`, with the swings rising `rise` (m)
    /// above their ends, normalised and weighted as `config` says.
    pub(super) fn of_action(config: &BodyPlannerConfig, primitive: usize, after: &StanceTerrain, rise: f64) -> Self {
        Self::weighted(
            after.mean_best_cost,
            config.primitives[primitive].difficulty,
            rise / config.swing_rise_scale,
            after.tilt / config.tilt_scale,
            &config.weights,
        )
    }
}

/// The best foothold found around one leg's nominal foothold.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Foothold {
    pub x: f64,
    pub y: f64,
    pub height: f64,
    /// Terrain cost of the cell, in `[0, 1)`.
    pub cost: f64,
}

/// What the terrain offers the four legs at one body pose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StanceTerrain {
    /// `c_t_bar` of the pose (see [`ActionCost::terrain`]).
    pub mean_best_cost: f64,
    /// Tilt (rad) of the least-squares plane through the four best footholds' heights.
    pub tilt: f64,
    /// Per leg (LF, RF, LH, RH) the cheapest cell around its nominal foothold, the nearest
    /// to the nominal point among equals: a hint for the footstep planner.
    pub footholds: [Foothold; 4],
}

/// A pose with a leg that has no usable cell around its nominal foothold.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NoFoothold {
    /// Leg index (LF, RF, LH, RH).
    pub leg: usize,
    /// The nominal foothold.
    pub x: f64,
    pub y: f64,
}

/// Reads the terrain for the cost terms: the window of cells around each nominal foothold,
/// the plane fit and the swing paths. Holds only per-query tables (no allocation per call).
#[derive(Clone, Debug)]
pub(super) struct TerrainProbe {
    stance: NominalStance,
    plane_rows: [[f64; 4]; 3],
    best_cells: usize,
    /// Offsets of the cells searched around a nominal foothold, nearest first.
    window: Vec<[f64; 2]>,
    resolution: f64,
}

/// A cell's terrain cost as the planner uses it: NaN is unknown, hence forbidden (1).
fn sanitized_cost(cost: f64) -> f64 {
    if cost.is_nan() {
        1.0
    } else {
        cost.clamp(0.0, 1.0)
    }
}

impl TerrainProbe {
    pub fn new(stance: NominalStance, plane_rows: [[f64; 4]; 3], best_cells: usize) -> Self {
        Self { stance, plane_rows, best_cells, window: Vec::new(), resolution: 0.0 }
    }

    /// Lays out the search window for a map of cell size `resolution`: every offset on the
    /// map's grid within `radius` of the nominal foothold, nearest first.
    pub fn prepare(&mut self, resolution: f64, radius: f64) {
        self.resolution = resolution;
        self.window.clear();
        let reach = (radius / resolution + 1e-9).floor() as i32;
        for j in -reach..=reach {
            for i in -reach..=reach {
                let offset = [f64::from(i) * resolution, f64::from(j) * resolution];
                if offset[0].hypot(offset[1]) <= radius + 1e-9 * resolution {
                    self.window.push(offset);
                }
            }
        }
        // Stable: equal distances keep the row-major order, so the choice is deterministic.
        self.window.sort_by(|a, b| a[0].hypot(a[1]).total_cmp(&b[0].hypot(b[1])));
    }

    /// Leg `leg`'s nominal foothold in the world at `pose`.
    pub fn nominal_foothold(&self, pose: &BodyPose, leg: usize) -> [f64; 2] {
        let (sin, cos) = pose.yaw.sin_cos();
        let f = self.stance.feet[leg];
        [pose.x + cos * f.x - sin * f.y, pose.y + sin * f.x + cos * f.y]
    }

    /// `c_t_bar` (Winkler 2015 eq. (2): "the average of the best n terrain costs around each
    /// leg after performing action a"), the best footholds and the tilt of the plane through
    /// them. A cell is usable when its cost is below 1 and its height finite; a leg with fewer
    /// than `n` usable cells counts the missing ones at 1, a leg with none makes the pose
    /// infeasible.
    pub fn stance_terrain<F: TerrainCostField + ?Sized>(&self, field: &F, pose: &BodyPose) -> Result<StanceTerrain, NoFoothold> {
        let mut footholds = [Foothold { x: 0.0, y: 0.0, height: 0.0, cost: 0.0 }; 4];
        let mut sum_of_leg_means = 0.0;
        for (leg, foothold) in footholds.iter_mut().enumerate() {
            let [nx, ny] = self.nominal_foothold(pose, leg);
            let mut best = [0.0; MAX_BEST_CELLS];
            let mut found = 0usize;
            let mut chosen: Option<Foothold> = None;
            for [ox, oy] in &self.window {
                let (x, y) = (nx + ox, ny + oy);
                let (cost, height) = field.cost_and_height(x, y);
                let cost = sanitized_cost(cost);
                if cost >= 1.0 || !height.is_finite() {
                    continue;
                }
                if chosen.is_none_or(|c| cost < c.cost) {
                    chosen = Some(Foothold { x, y, height, cost });
                }
                insert_sorted(&mut best, &mut found, self.best_cells, cost);
            }
            let Some(chosen) = chosen else {
                return Err(NoFoothold { leg, x: nx, y: ny });
            };
            *foothold = chosen;
            let missing = (self.best_cells - found) as f64;
            sum_of_leg_means += (best[..found].iter().sum::<f64>() + missing) / self.best_cells as f64;
        }
        let heights = footholds.map(|f| f.height);
        let dot = |row: &[f64; 4]| row.iter().zip(&heights).map(|(r, z)| r * z).sum::<f64>();
        let (slope_x, slope_y) = (dot(&self.plane_rows[1]), dot(&self.plane_rows[2]));
        Ok(StanceTerrain { mean_best_cost: sum_of_leg_means / 4.0, tilt: (slope_x * slope_x + slope_y * slope_y).sqrt().atan(), footholds })
    }

    /// The largest rise of the ground above a swing's two ends, over the four legs: each foot
    /// swings on the straight line from its foothold before the action to the one after it,
    /// sampled at the map's resolution; ground higher than both ends is what a swing at a
    /// fixed clearance over the ends would hit (Winkler 2015 eq. (2), `c_pc`). `None` when
    /// the ground under a swing is unknown (height not finite).
    pub fn swing_rise<F: TerrainCostField + ?Sized>(&self, field: &F, before: &StanceTerrain, after: &StanceTerrain) -> Option<f64> {
        let mut rise = 0.0f64;
        for (from, to) in before.footholds.iter().zip(&after.footholds) {
            let (dx, dy) = (to.x - from.x, to.y - from.y);
            let intervals = ((dx * dx + dy * dy).sqrt() / self.resolution).ceil().max(1.0) as usize;
            let ends = from.height.max(to.height);
            for k in 1..intervals {
                let t = k as f64 / intervals as f64;
                let h = field.height(from.x + t * dx, from.y + t * dy);
                if !h.is_finite() {
                    return None;
                }
                rise = rise.max(h - ends);
            }
        }
        Some(rise)
    }
}

/// Inserts `value` into the ascending `best[..*len]`, keeping at most `capacity` values.
fn insert_sorted(best: &mut [f64; MAX_BEST_CELLS], len: &mut usize, capacity: usize, value: f64) {
    if *len == capacity && value >= best[capacity - 1] {
        return;
    }
    let mut i = (*len).min(capacity - 1);
    if *len < capacity {
        *len += 1;
    }
    while i > 0 && best[i - 1] > value {
        best[i] = best[i - 1];
        i -= 1;
    }
    best[i] = value;
}

#[cfg(test)]
mod tests {
    use super::insert_sorted;

    #[test]
    fn insert_sorted_keeps_the_n_smallest_in_order() {
        let values = [0.5, 0.1, 0.9, 0.3, 0.3, 0.0, 0.7, 0.2];
        for capacity in 1..=values.len() {
            let (mut best, mut len) = ([0.0; super::MAX_BEST_CELLS], 0);
            for v in values {
                insert_sorted(&mut best, &mut len, capacity, v);
            }
            let mut expected = values.to_vec();
            expected.sort_by(f64::total_cmp);
            expected.truncate(capacity);
            assert_eq!(&best[..len], &expected[..]);
        }
    }
}
