//! What the planners need to know of the terrain: the foothold cost of Winkler 2015
//! sec. III-A and the ground height, at any point of the plane.

/// The terrain cost map as the planners read it (Winkler 2015 sec. III-A: "The terrain cost
/// map quantifies how desirable it is to place a foot at a specific location", `c_t(x, y) =
/// w^T c(x, y)` from height deviation, slope and curvature).
///
/// Implemented by the on-board map; queries outside the mapped area must answer cost 1
/// (unknown is forbidden). The planners treat a cost that is NaN like 1, and a height that
/// is not finite as unknown ground (no foothold there).
pub trait TerrainCostField {
    /// Foothold cost at `(x, y)` in `[0, 1]`: 0 ideal, 1 forbidden or unknown.
    fn cost(&self, x: f64, y: f64) -> f64;
    /// Ground height at `(x, y)` (m).
    fn height(&self, x: f64, y: f64) -> f64;
    /// Cell size of the map (m): the spacing at which the planners sample it.
    fn resolution(&self) -> f64;
    /// Cost and height together: one cell lookup where the map can share it.
    fn cost_and_height(&self, x: f64, y: f64) -> (f64, f64) {
        (self.cost(x, y), self.height(x, y))
    }
    /// The centre of the cell that holds `(x, y)` (default: the point itself). Footholds are
    /// chosen at cell centres: a point near a cell's border may lie beyond the edge the
    /// cell's sample saw.
    fn cell_center(&self, x: f64, y: f64) -> (f64, f64) {
        (x, y)
    }
}

/// The costs of the `(2 radius + 1)^2` cells centred on `(x, y)`, one cell size apart, by
/// columns (x outer, y inner): the ground a foot may end up on around a foothold.
pub fn costs_around(terrain: &dyn TerrainCostField, x: f64, y: f64, radius: usize) -> impl Iterator<Item = f64> + '_ {
    let r = terrain.resolution();
    let k = radius as i64;
    (-k..=k).flat_map(move |i| (-k..=k).map(move |j| terrain.cost(x + i as f64 * r, y + j as f64 * r)))
}

impl<T: TerrainCostField + ?Sized> TerrainCostField for &T {
    fn cost(&self, x: f64, y: f64) -> f64 {
        (**self).cost(x, y)
    }
    fn height(&self, x: f64, y: f64) -> f64 {
        (**self).height(x, y)
    }
    fn resolution(&self) -> f64 {
        (**self).resolution()
    }
    fn cost_and_height(&self, x: f64, y: f64) -> (f64, f64) {
        (**self).cost_and_height(x, y)
    }
    fn cell_center(&self, x: f64, y: f64) -> (f64, f64) {
        (**self).cell_center(x, y)
    }
}

/// The on-board terrain map (Winkler 2015 sec. III-A) is what the planners read.
impl TerrainCostField for crate::terrain::TerrainMap {
    fn cost(&self, x: f64, y: f64) -> f64 {
        crate::terrain::TerrainMap::cost(self, x, y)
    }
    fn height(&self, x: f64, y: f64) -> f64 {
        crate::terrain::TerrainMap::height(self, x, y)
    }
    fn resolution(&self) -> f64 {
        crate::terrain::TerrainMap::resolution(self)
    }
    fn cell_center(&self, x: f64, y: f64) -> (f64, f64) {
        match self.cell_at(x, y) {
            Some((i, j)) => {
                let [cx, cy] = crate::terrain::TerrainMap::cell_center(self, i, j);
                (cx, cy)
            }
            None => (x, y),
        }
    }
}
