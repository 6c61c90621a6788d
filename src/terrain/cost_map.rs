//! The robot's terrain map and terrain cost map: Winkler 2015 sec. III-A, simulated on board.
//!
//! The paper builds a 3D occupancy grid at 4 cm x 4 cm x 2 cm from an RGBD sensor on a
//! scanning pan & tilt unit, and computes a terrain cost `c_t` per cell from geometric
//! features, "locally re-computed (in a 2.5 m x 5 m area around the robot) whenever a change
//! in the map is detected". Here:
//!
//! * **Map**: a 2.5D grid of 4 cm x 4 cm cells (configurable) over a fixed rectangle of the
//!   world, each cell holding a fused height estimate, its variance and its number of
//!   observations (0 = unknown). Cell `(i, j)` covers
//!   `[x0 + i r, x0 + (i + 1) r) x [y0 + j r, y0 + (j + 1) r)`; its centre is where it is
//!   sampled and what [`TerrainMap::cell_center`] returns.
//! * **Sensor** ([`TerrainMap::observe`]): the pan & tilt unit sweeps around the robot, so the
//!   default footprint is the disk of radius 2.5 m around the robot (the paper's 2.5 m x 5 m
//!   update area); a field of view below 2 pi makes it a wedge centred on the robot's
//!   heading. Every cell whose centre lies in the footprint gets one sample: the world's
//!   height at the centre plus Gaussian noise of standard deviation `noise_sigma`. There
//!   is no occlusion (the sensor sees every top surface in range).
//! * **Fusion**: a scalar Kalman filter per cell on a static height: measurement variance
//!   `s^2`, innovation `nu = z - h`, `S = P + s^2`, `h += (P / S) nu`, `P = P s^2 / S`, which
//!   is the running mean (`P = s^2 / n` after `n` observations). So that a new obstacle is
//!   not averaged away (the paper's Fig. 4: a pallet placed in front of the robot after the
//!   first plan), an observation with `|nu| > k sqrt(S)` resets the cell to it (`h = z`,
//!   `P = s^2`, `n = 1`); `k = change_threshold_sigmas`, default 5, a false reset once in
//!   1.7 million observations of an unchanged cell.
//! * **Cost**: per cell from its neighbourhood, in [`super::cost_features`]; after an
//!   observation only the cells whose neighbourhood holds an observed cell are recomputed
//!   (the bounding box of the observed cells grown by the feature and gap radii), which
//!   gives exactly what a full recompute gives because a cell's cost depends on nothing
//!   else.
//!
//! Noise comes from any [`rand::Rng`]; the tests and benchmarks seed
//! `rand::rngs::Xoshiro256PlusPlus` (rand's small, fast, seedable generator), and the
//! Gaussian is drawn by Box-Muller ([`standard_normal`]) so no distribution crate is needed.

use super::cost_features::{assess_cell, CellAssessment, CostParams, GridView, WindowFit};
use super::{HeightMap, Terrain, TerrainSpec};
use rand::Rng;
use serde::{Deserialize, Serialize};
use std::f64::consts::{PI, TAU};

/// The simulated height sensor (module documentation above).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SensorConfig {
    /// m. Cells whose centre lies within this distance of the robot are observed. Default 2.5.
    pub range: f64,
    /// rad, in `(0, 2 pi]`. Full angle of the footprint, centred on the robot's heading;
    /// `2 pi` (default) is the whole disk swept by the pan & tilt unit.
    pub field_of_view: f64,
    /// m. Standard deviation of the Gaussian noise of each height sample. Default 0.01.
    pub noise_sigma: f64,
}

impl Default for SensorConfig {
    fn default() -> Self {
        Self { range: 2.5, field_of_view: TAU, noise_sigma: 0.01 }
    }
}

/// Configuration of a [`TerrainMap`]; every field has a default (an 8 m x 4 m map at the
/// paper's 4 cm cells).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TerrainMapConfig {
    /// m. World position of the map's lower-left corner (`x0`, `y0`). Default (-1, -2).
    pub origin: [f64; 2],
    /// m. Extent along x and y; rounded up to whole cells. Default (8, 4).
    pub size: [f64; 2],
    /// m. Cell side. Default 0.04 (Winkler 2015 sec. III-A: "roughly matches the dimensions
    /// of the robot's foot").
    pub resolution: f64,
    pub sensor: SensorConfig,
    /// `k`: an observation more than `k` innovation standard deviations from a cell's
    /// estimate resets the cell (the world changed there). Default 5.
    pub change_threshold_sigmas: f64,
    pub cost: CostParams,
}

impl Default for TerrainMapConfig {
    fn default() -> Self {
        Self {
            origin: [-1.0, -2.0],
            size: [8.0, 4.0],
            resolution: 0.04,
            sensor: SensorConfig::default(),
            change_threshold_sigmas: 5.0,
            cost: CostParams::default(),
        }
    }
}

/// The most cells a map may have (a 200 m x 200 m map at 4 cm cells).
pub const MAX_CELLS: usize = 25_000_000;
/// The largest `n` of [`TerrainMap::best_costs_around`] (its buffer lives on the stack).
pub const MAX_BEST_COSTS: usize = 64;

/// Problems with a terrain map's configuration or arguments; each names the field.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum TerrainMapError {
    #[error("terrain map configuration: field `{field}`: expected {expected}, got {got}")]
    InvalidConfig { field: &'static str, expected: &'static str, got: String },
    #[error("terrain map: argument `{argument}`: expected {expected}, got {got}")]
    InvalidArgument { argument: &'static str, expected: &'static str, got: String },
    #[error("terrain map: the world's height at ({x}, {y}) is {height}, expected a finite number")]
    NonFiniteWorld { x: f64, y: f64, height: f64 },
}

/// An inclusive rectangle of cells `i_min..=i_max` x `j_min..=j_max`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CellRect {
    pub i_min: usize,
    pub i_max: usize,
    pub j_min: usize,
    pub j_max: usize,
}

impl CellRect {
    /// The rectangle of the one cell `(i, j)`.
    pub fn cell(i: usize, j: usize) -> Self {
        Self { i_min: i, i_max: i, j_min: j, j_max: j }
    }
    /// Grows the rectangle to hold cell `(i, j)`.
    pub fn include(&mut self, i: usize, j: usize) {
        self.i_min = self.i_min.min(i);
        self.i_max = self.i_max.max(i);
        self.j_min = self.j_min.min(j);
        self.j_max = self.j_max.max(j);
    }
    /// Whether cell `(i, j)` lies inside.
    pub fn contains(&self, i: usize, j: usize) -> bool {
        (self.i_min..=self.i_max).contains(&i) && (self.j_min..=self.j_max).contains(&j)
    }
    /// Number of cells.
    pub fn cell_count(&self) -> usize {
        (self.i_max - self.i_min + 1) * (self.j_max - self.j_min + 1)
    }
    /// The rectangle grown by `margin` cells on every side, clipped to a `columns x rows` grid.
    fn grown(&self, margin: usize, columns: usize, rows: usize) -> Self {
        Self {
            i_min: self.i_min.saturating_sub(margin),
            i_max: (self.i_max + margin).min(columns - 1),
            j_min: self.j_min.saturating_sub(margin),
            j_max: (self.j_max + margin).min(rows - 1),
        }
    }
}

fn include(rect: &mut Option<CellRect>, i: usize, j: usize) {
    match rect {
        Some(r) => r.include(i, j),
        None => *rect = Some(CellRect::cell(i, j)),
    }
}

/// What one [`TerrainMap::observe`] changed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MapUpdate {
    /// Cells observed (each one's height estimate changed).
    pub observed_cells: usize,
    /// Bounding box of the observed cells.
    pub observed: Option<CellRect>,
    /// Observed cells that were unknown before.
    pub newly_known_cells: usize,
    /// Cells reset because an observation disagreed with the estimate by more than `k`
    /// sigma: where the world changed.
    pub reset_cells: usize,
    /// Bounding box of the reset cells.
    pub reset: Option<CellRect>,
    /// The cells whose cost was recomputed.
    pub cost_region: Option<CellRect>,
}

impl MapUpdate {
    /// Whether the world was seen to change (a reason to re-plan, as the paper's Fig. 4).
    pub fn world_changed(&self) -> bool {
        self.reset_cells > 0
    }
}

/// One cell of the map, as [`TerrainMap::cells`] yields it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CellView {
    pub i: usize,
    pub j: usize,
    /// World position of the cell's centre (m).
    pub center: [f64; 2],
    /// Fused height estimate (m), `None` while unknown.
    pub height: Option<f64>,
    /// Variance of the height estimate (m^2), `None` while unknown.
    pub variance: Option<f64>,
    pub observations: u32,
    /// Terrain cost `c_t` in `[0, 1]`.
    pub cost: f64,
}

/// The on-board terrain map and cost map (module documentation above).
///
/// ```
/// use legwork::terrain::{HeightMap, TerrainMap, TerrainMapConfig};
/// use rand::{rngs::Xoshiro256PlusPlus, SeedableRng};
/// // The world: flat ground with a 0.15 m pallet.
/// let mut world = HeightMap::flat([-2.0, -3.0], 0.04, 301, 151, 0.0);
/// world.set_rect([1.0, 2.2], [-0.4, 0.4], 0.15);
/// let mut map = TerrainMap::new(TerrainMapConfig::default()).unwrap();
/// let mut rng = Xoshiro256PlusPlus::seed_from_u64(1);
/// for _ in 0..10 {
///     map.observe(&world, [0.0, 0.0], 0.0, &mut rng).unwrap();
/// }
/// assert!((map.height(1.6, 0.0) - 0.15).abs() < 0.02);
/// assert!(map.cost(1.6, 0.0) < 0.2); // the pallet's top
/// assert!(map.cost(1.0, 0.0) > 0.9); // its edge
/// assert_eq!(map.cost(-0.99, 1.9), 1.0); // the map's border: never fully observed
/// ```
#[derive(Clone, Debug)]
pub struct TerrainMap {
    config: TerrainMapConfig,
    columns: usize,
    rows: usize,
    /// Row-major (`j * columns + i`) cell data; heights are NaN while unknown.
    heights: Vec<f64>,
    variances: Vec<f64>,
    observations: Vec<u32>,
    costs: Vec<f64>,
    fit: WindowFit,
    /// Workspace of [`TerrainMap::observe`]: (cell index, noisy height) of one sweep.
    samples: Vec<(usize, f64)>,
}

fn invalid(field: &'static str, expected: &'static str, got: impl ToString) -> TerrainMapError {
    TerrainMapError::InvalidConfig { field, expected, got: got.to_string() }
}

fn bad_argument(argument: &'static str, expected: &'static str, got: impl ToString) -> TerrainMapError {
    TerrainMapError::InvalidArgument { argument, expected, got: got.to_string() }
}

impl TerrainMap {
    /// An all-unknown map (every cost 1). Checks every number of `config`.
    pub fn new(config: TerrainMapConfig) -> Result<Self, TerrainMapError> {
        let positive = |field, value: f64| {
            if value > 0.0 && value.is_finite() {
                Ok(())
            } else {
                Err(invalid(field, "a finite number > 0", value))
            }
        };
        positive("resolution", config.resolution)?;
        for (field, value) in [("origin[0]", config.origin[0]), ("origin[1]", config.origin[1])] {
            if !value.is_finite() {
                return Err(invalid(field, "a finite position (m)", value));
            }
        }
        positive("size[0]", config.size[0])?;
        positive("size[1]", config.size[1])?;
        positive("sensor.range", config.sensor.range)?;
        positive("sensor.noise_sigma", config.sensor.noise_sigma)?;
        positive("change_threshold_sigmas", config.change_threshold_sigmas)?;
        let fov = config.sensor.field_of_view;
        if !(fov > 0.0 && fov <= TAU) {
            return Err(invalid("sensor.field_of_view", "an angle in (0, 2 pi] (rad)", fov));
        }
        config.cost.validate().map_err(|(field, expected, got)| invalid(field, expected, got))?;
        // Whole cells covering the region (the 1e-9 keeps 8 m / 0.04 m at 200, not 201).
        let cells_along = |size: f64| (size / config.resolution - 1e-9).ceil().max(1.0);
        let (columns, rows) = (cells_along(config.size[0]), cells_along(config.size[1]));
        if columns < 2.0 || rows < 2.0 {
            return Err(invalid("size", "at least 2 x 2 cells", format!("{columns} x {rows}")));
        }
        if columns * rows > MAX_CELLS as f64 {
            return Err(invalid("size", "at most 25,000,000 cells", format!("{columns} x {rows}")));
        }
        let (columns, rows) = (columns as usize, rows as usize);
        let n = columns * rows;
        Ok(Self {
            config,
            columns,
            rows,
            heights: vec![f64::NAN; n],
            variances: vec![f64::NAN; n],
            observations: vec![0; n],
            costs: vec![1.0; n],
            fit: WindowFit::new(config.cost.window_radius_cells, config.resolution),
            samples: Vec::new(),
        })
    }

    /// The configuration the map was built with.
    pub fn config(&self) -> &TerrainMapConfig {
        &self.config
    }
    /// Cell side (m).
    pub fn resolution(&self) -> f64 {
        self.config.resolution
    }
    /// World position of the map's lower-left corner (m).
    pub fn origin(&self) -> [f64; 2] {
        self.config.origin
    }
    /// Number of cells along x and along y.
    pub fn size(&self) -> (usize, usize) {
        (self.columns, self.rows)
    }

    /// One sensor sweep from the robot at `robot_xy` heading `yaw` (module documentation):
    /// samples the world's height with noise in every cell of the footprint, fuses the
    /// samples (resetting the cells where the world changed), then recomputes the cost of the
    /// cells whose neighbourhood changed. Allocates nothing once the workspace has grown to
    /// one sweep. On error the map is unchanged.
    pub fn observe<R: Rng + ?Sized>(
        &mut self,
        world: &dyn Terrain,
        robot_xy: [f64; 2],
        yaw: f64,
        rng: &mut R,
    ) -> Result<MapUpdate, TerrainMapError> {
        for (argument, value) in [("robot_xy[0]", robot_xy[0]), ("robot_xy[1]", robot_xy[1]), ("yaw", yaw)] {
            if !value.is_finite() {
                return Err(bad_argument(argument, "a finite number", value));
            }
        }
        let mut update = MapUpdate::default();
        let sensor = self.config.sensor;
        let Some(footprint) = self.cells_in_disk(robot_xy, sensor.range) else {
            return Ok(update);
        };
        // Sample everything first, so that a bad world leaves the map unchanged.
        let mut samples = std::mem::take(&mut self.samples);
        samples.clear();
        for j in footprint.j_min..=footprint.j_max {
            for i in footprint.i_min..=footprint.i_max {
                let [x, y] = self.cell_center(i, j);
                let (dx, dy) = (x - robot_xy[0], y - robot_xy[1]);
                if dx * dx + dy * dy > sensor.range * sensor.range {
                    continue;
                }
                if sensor.field_of_view < TAU {
                    let bearing = (dy.atan2(dx) - yaw + PI).rem_euclid(TAU) - PI;
                    if bearing.abs() > 0.5 * sensor.field_of_view {
                        continue;
                    }
                }
                let height = world.height(x, y);
                if !height.is_finite() {
                    self.samples = samples;
                    return Err(TerrainMapError::NonFiniteWorld { x, y, height });
                }
                samples.push((j * self.columns + i, height + sensor.noise_sigma * standard_normal(rng)));
            }
        }
        let measurement_variance = sensor.noise_sigma * sensor.noise_sigma;
        let gate = self.config.change_threshold_sigmas * self.config.change_threshold_sigmas;
        for &(index, z) in &samples {
            let (i, j) = (index % self.columns, index / self.columns);
            update.observed_cells += 1;
            include(&mut update.observed, i, j);
            let n = self.observations[index];
            let innovation = z - self.heights[index];
            let innovation_variance = self.variances[index] + measurement_variance;
            if n == 0 || innovation * innovation > gate * innovation_variance {
                if n == 0 {
                    update.newly_known_cells += 1;
                } else {
                    update.reset_cells += 1;
                    include(&mut update.reset, i, j);
                }
                self.heights[index] = z;
                self.variances[index] = measurement_variance;
                self.observations[index] = 1;
            } else {
                // Scalar Kalman update on a static height (= the running mean).
                let gain = self.variances[index] / innovation_variance;
                self.heights[index] += gain * innovation;
                self.variances[index] *= measurement_variance / innovation_variance;
                self.observations[index] = n.saturating_add(1);
            }
        }
        self.samples = samples;
        update.cost_region = update.observed.map(|observed| self.recompute_costs_around(observed));
        Ok(update)
    }

    /// Recomputes the cost of every cell whose neighbourhood (feature window and gap search)
    /// meets `changed`; returns the recomputed rectangle.
    pub fn recompute_costs_around(&mut self, changed: CellRect) -> CellRect {
        let params = &self.config.cost;
        let margin = params.window_radius_cells.max(params.gap_radius_cells);
        let region = changed.grown(margin, self.columns, self.rows);
        self.recompute_costs_in(region);
        region
    }

    /// Recomputes the cost of every cell of the map.
    pub fn recompute_all_costs(&mut self) {
        self.recompute_costs_in(CellRect { i_min: 0, i_max: self.columns - 1, j_min: 0, j_max: self.rows - 1 });
    }

    fn recompute_costs_in(&mut self, region: CellRect) {
        let grid = GridView {
            heights: &self.heights,
            observations: &self.observations,
            columns: self.columns,
            rows: self.rows,
        };
        for j in region.j_min..=region.j_max.min(self.rows - 1) {
            for i in region.i_min..=region.i_max.min(self.columns - 1) {
                self.costs[j * self.columns + i] = assess_cell(grid, &self.fit, &self.config.cost, i, j).cost();
            }
        }
    }

    /// Why cell `(i, j)` costs what it costs: its features, or the rule that forbids it
    /// (computed afresh; [`TerrainMap::cost`] reads the stored cost). `None` off the map.
    pub fn assess(&self, i: usize, j: usize) -> Option<CellAssessment> {
        if i >= self.columns || j >= self.rows {
            return None;
        }
        let grid = GridView {
            heights: &self.heights,
            observations: &self.observations,
            columns: self.columns,
            rows: self.rows,
        };
        Some(assess_cell(grid, &self.fit, &self.config.cost, i, j))
    }

    /// The cell containing `(x, y)`; `None` off the map (or for a NaN position).
    pub fn cell_at(&self, x: f64, y: f64) -> Option<(usize, usize)> {
        let gx = (x - self.config.origin[0]) / self.config.resolution;
        let gy = (y - self.config.origin[1]) / self.config.resolution;
        if !(gx >= 0.0 && gy >= 0.0 && gx < self.columns as f64 && gy < self.rows as f64) {
            return None;
        }
        Some(((gx as usize).min(self.columns - 1), (gy as usize).min(self.rows - 1)))
    }

    /// World position of the centre of cell `(i, j)` (m).
    pub fn cell_center(&self, i: usize, j: usize) -> [f64; 2] {
        let r = self.config.resolution;
        [self.config.origin[0] + (i as f64 + 0.5) * r, self.config.origin[1] + (j as f64 + 0.5) * r]
    }

    /// World rectangle `[[x_min, y_min], [x_max, y_max]]` covered by the cells of `rect` (m).
    pub fn rect_bounds(&self, rect: CellRect) -> [[f64; 2]; 2] {
        let (r, o) = (self.config.resolution, self.config.origin);
        [
            [o[0] + rect.i_min as f64 * r, o[1] + rect.j_min as f64 * r],
            [o[0] + (rect.i_max + 1) as f64 * r, o[1] + (rect.j_max + 1) as f64 * r],
        ]
    }

    /// Terrain cost `c_t` in `[0, 1]` of the cell containing `(x, y)` (nearest cell, not
    /// interpolated: a blend would give a foot half over a gap a cost below 1); 1 off the
    /// map and for unknown or forbidden cells.
    pub fn cost(&self, x: f64, y: f64) -> f64 {
        self.cell_at(x, y).map_or(1.0, |(i, j)| self.costs[j * self.columns + i])
    }

    /// Fused height (m) of the cell containing `(x, y)` (nearest cell); NaN where unknown or
    /// off the map: check [`TerrainMap::is_known`] (or `cost < 1`) first, or use
    /// [`TerrainMap::try_height`].
    pub fn height(&self, x: f64, y: f64) -> f64 {
        self.try_height(x, y).unwrap_or(f64::NAN)
    }

    /// Fused height (m) of the cell containing `(x, y)`; `None` where unknown or off the map.
    pub fn try_height(&self, x: f64, y: f64) -> Option<f64> {
        let (i, j) = self.cell_at(x, y)?;
        let index = j * self.columns + i;
        (self.observations[index] > 0).then(|| self.heights[index])
    }

    /// Whether the cell containing `(x, y)` has been observed.
    pub fn is_known(&self, x: f64, y: f64) -> bool {
        self.cell_at(x, y).is_some_and(|(i, j)| self.observations[j * self.columns + i] > 0)
    }

    /// Cell `(i, j)`; `None` off the map.
    pub fn cell(&self, i: usize, j: usize) -> Option<CellView> {
        if i >= self.columns || j >= self.rows {
            return None;
        }
        let index = j * self.columns + i;
        let known = self.observations[index] > 0;
        Some(CellView {
            i,
            j,
            center: self.cell_center(i, j),
            height: known.then(|| self.heights[index]),
            variance: known.then(|| self.variances[index]),
            observations: self.observations[index],
            cost: self.costs[index],
        })
    }

    /// Every cell, row by row (`j` outer, `i` inner).
    pub fn cells(&self) -> impl Iterator<Item = CellView> + '_ {
        (0..self.rows).flat_map(move |j| (0..self.columns).filter_map(move |i| self.cell(i, j)))
    }

    /// The costs, row-major (`j * columns + i`).
    pub fn costs(&self) -> &[f64] {
        &self.costs
    }

    /// Number of observed cells.
    pub fn known_cells(&self) -> usize {
        self.observations.iter().filter(|&&n| n > 0).count()
    }

    /// The mean of the `n` lowest costs among the map's cells whose centre lies within
    /// `radius` of `(x, y)`: the term "average of the best n terrain costs around each leg"
    /// of Winkler 2015 eq. (2) (sec. III-B). If the disk holds fewer than `n` cells the mean
    /// is over those; if it holds none, the cost of the cell containing `(x, y)` (1 off the
    /// map). `1 <= n <= 64`. Allocates nothing.
    pub fn best_costs_around(&self, x: f64, y: f64, radius: f64, n: usize) -> Result<f64, TerrainMapError> {
        if !(x.is_finite() && y.is_finite()) {
            return Err(bad_argument("(x, y)", "a finite position", format!("({x}, {y})")));
        }
        if !(radius >= 0.0 && radius.is_finite()) {
            return Err(bad_argument("radius", "a finite distance >= 0 (m)", radius));
        }
        if !(1..=MAX_BEST_COSTS).contains(&n) {
            return Err(bad_argument("n", "a count from 1 to 64", n));
        }
        let Some(disk) = self.cells_in_disk([x, y], radius) else {
            return Ok(self.cost(x, y));
        };
        // The n lowest so far, ascending, in best[..kept].
        let mut best = [0.0; MAX_BEST_COSTS];
        let mut kept = 0;
        for j in disk.j_min..=disk.j_max {
            for i in disk.i_min..=disk.i_max {
                let [cx, cy] = self.cell_center(i, j);
                if (cx - x) * (cx - x) + (cy - y) * (cy - y) > radius * radius {
                    continue;
                }
                let cost = self.costs[j * self.columns + i];
                if kept == n && cost >= best[n - 1] {
                    continue;
                }
                let mut k = kept.min(n - 1);
                while k > 0 && best[k - 1] > cost {
                    best[k] = best[k - 1];
                    k -= 1;
                }
                best[k] = cost;
                kept = (kept + 1).min(n);
            }
        }
        if kept == 0 {
            return Ok(self.cost(x, y));
        }
        Ok(best[..kept].iter().sum::<f64>() / kept as f64)
    }

    /// The cells of the map within the bounding box of the disk of `radius` around `center`
    /// (`None` if the box misses the map).
    fn cells_in_disk(&self, center: [f64; 2], radius: f64) -> Option<CellRect> {
        let r = self.config.resolution;
        let index_range = |c: f64, origin: f64, count: usize| {
            // Centres at origin + (k + 1/2) r within [c - radius, c + radius].
            let low = ((c - radius - origin) / r - 0.5).ceil().max(0.0);
            let high = ((c + radius - origin) / r - 0.5).floor().min(count as f64 - 1.0);
            (low <= high).then_some((low as usize, high as usize))
        };
        let (i_min, i_max) = index_range(center[0], self.config.origin[0], self.columns)?;
        let (j_min, j_max) = index_range(center[1], self.config.origin[1], self.rows)?;
        Some(CellRect { i_min, i_max, j_min, j_max })
    }

    /// The map's heights as a [`HeightMap`] whose grid points are the cell centres, unknown
    /// cells at `unknown_height` (for drawing the robot's view in a replay).
    pub fn to_height_map(&self, unknown_height: f64) -> Result<HeightMap, TerrainMapError> {
        if !unknown_height.is_finite() {
            return Err(bad_argument("unknown_height", "a finite height (m)", unknown_height));
        }
        let r = self.config.resolution;
        let origin = [self.config.origin[0] + 0.5 * r, self.config.origin[1] + 0.5 * r];
        let mut map = HeightMap::flat(origin, r, self.columns, self.rows, unknown_height);
        for (index, (&n, &h)) in self.observations.iter().zip(&self.heights).enumerate() {
            if n > 0 {
                map.set(index % self.columns, index / self.columns, h);
            }
        }
        Ok(map)
    }

    /// [`TerrainMap::to_height_map`] as a [`TerrainSpec`] (what trajectory files store).
    pub fn to_terrain_spec(&self, unknown_height: f64) -> Result<TerrainSpec, TerrainMapError> {
        Ok(TerrainSpec::HeightMap(self.to_height_map(unknown_height)?.to_file_data()))
    }
}

/// A standard normal sample by the Box-Muller transform,
/// `sqrt(-2 ln u1) cos(2 pi u2)` with `u1` uniform in `(0, 1]` (so the logarithm is finite)
/// and `u2` uniform in `[0, 1)`, each from the top 53 bits of one `u64`.
pub fn standard_normal<R: Rng + ?Sized>(rng: &mut R) -> f64 {
    const SCALE: f64 = 1.0 / (1u64 << 53) as f64;
    let u1 = ((rng.next_u64() >> 11) + 1) as f64 * SCALE;
    let u2 = (rng.next_u64() >> 11) as f64 * SCALE;
    (-2.0 * u1.ln()).sqrt() * (TAU * u2).cos()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::terrain::{Plane, TerrainSpec};
    use nalgebra::Vector3;
    use rand::rngs::Xoshiro256PlusPlus;
    use rand::SeedableRng;

    /// Flat ground with axis-aligned boxes (or trenches, below the ground) whose sides are
    /// exact steps, so a cell centre is on a box or off it, never half way.
    struct Boxes {
        ground: f64,
        /// `([x_min, x_max], [y_min, y_max], top)`, later boxes over earlier ones.
        boxes: Vec<([f64; 2], [f64; 2], f64)>,
    }

    impl Terrain for Boxes {
        fn height(&self, x: f64, y: f64) -> f64 {
            self.boxes
                .iter()
                .rev()
                .find(|(bx, by, _)| x > bx[0] && x < bx[1] && y > by[0] && y < by[1])
                .map_or(self.ground, |b| b.2)
        }
        fn normal(&self, _x: f64, _y: f64) -> Vector3<f64> {
            Vector3::z()
        }
        fn spec(&self) -> TerrainSpec {
            TerrainSpec::flat()
        }
    }

    const PALLET: ([f64; 2], [f64; 2], f64) = ([1.0, 2.2], [-0.4, 0.4], 0.15);

    fn map_with_noise(noise_sigma: f64) -> TerrainMap {
        let mut config = TerrainMapConfig::default();
        config.sensor.noise_sigma = noise_sigma;
        TerrainMap::new(config).unwrap()
    }

    fn rng() -> Xoshiro256PlusPlus {
        Xoshiro256PlusPlus::seed_from_u64(2015)
    }

    /// Distance (cells) from cell centre `x` to the nearest of the box sides `sides` along
    /// one axis, in whole cells: 0 for the cells touching a side.
    fn cells_from(x: f64, sides: [f64; 2], r: f64) -> i64 {
        sides.iter().map(|s| (((x - s).abs() - 0.5 * r) / r).round() as i64).min().unwrap()
    }

    #[test]
    fn flat_ground_costs_nothing_where_known() {
        // Nearly noise-free: every cell whose 5 x 5 window is observed scores ~0; the others
        // (the footprint's rim, the map's border) are unknown, cost 1.
        let mut map = map_with_noise(1e-7);
        let update = map.observe(&Plane::flat(0.3), [1.0, 0.0], 0.0, &mut rng()).unwrap();
        assert_eq!(update.observed_cells, map.known_cells());
        assert_eq!(update.newly_known_cells, update.observed_cells);
        assert_eq!(update.reset_cells, 0);
        let mut scored = 0;
        for cell in map.cells() {
            match map.assess(cell.i, cell.j).unwrap() {
                CellAssessment::Scored { cost, .. } => {
                    scored += 1;
                    assert!(cost < 1e-4, "{cell:?}");
                    assert_eq!(cost, cell.cost);
                }
                CellAssessment::Unknown => assert_eq!(cell.cost, 1.0),
                other => panic!("flat ground: {other:?} at {cell:?}"),
            }
        }
        // Scored = cells whose window is known: the 2.5 m disk's cells (clipped to the map)
        // shrunk by two cells. Thousands of them.
        assert!(scored > 9000, "{scored}");
        // With 1 cm noise and 16 sweeps (2.5 mm left), the known cells still cost little.
        let mut map = map_with_noise(0.01);
        let mut rng = rng();
        for _ in 0..16 {
            map.observe(&Plane::flat(0.3), [1.0, 0.0], 0.0, &mut rng).unwrap();
        }
        let costs: Vec<f64> = map.cells().filter(|c| c.cost < 1.0).map(|c| c.cost).collect();
        let mean = costs.iter().sum::<f64>() / costs.len() as f64;
        assert!(costs.len() > 9000 && mean < 0.08, "{} cells, mean cost {mean}", costs.len());
    }

    #[test]
    fn box_edge_costs_high_and_its_top_low() {
        let world = Boxes { ground: 0.0, boxes: vec![PALLET] };
        let mut map = map_with_noise(1e-6);
        map.observe(&world, [0.5, 0.0], 0.0, &mut rng()).unwrap();
        let r = map.resolution();
        let (mut edge_cells, mut top_cells) = (0, 0);
        for cell in map.cells().filter(|c| c.height.is_some()) {
            let [x, y] = cell.center;
            // Only the straight part of the two x-sides, away from corners, the map's border and
            // the footprint's rim.
            if y.abs() > 0.28 || x < -0.85 || (x - 0.5).hypot(y) > 2.3 {
                continue;
            }
            let from_side = cells_from(x, PALLET.0, r);
            let on_top = x > PALLET.0[0] && x < PALLET.0[1];
            if from_side <= 1 {
                // The 5 x 5 window spans the 0.15 m step: spread 6-7 cm, slope 37-48 deg and
                // curvature 13-27 /m, all saturated, yet the step is climbable: scored, not forbidden.
                edge_cells += 1;
                let assessment = map.assess(cell.i, cell.j).unwrap();
                assert!(!assessment.is_forbidden() && cell.cost > 0.999, "{cell:?} {assessment:?}");
            } else if on_top {
                top_cells += 1;
                assert!(cell.cost < 1e-3 && (cell.height.unwrap() - 0.15).abs() < 1e-5, "{cell:?}");
            } else {
                assert!(cell.cost < 1e-3, "{cell:?}");
            }
        }
        // Two sides x 4 cells across x 14 cells along (centres |y| <= 0.26); the top 26 x 14.
        assert_eq!(edge_cells, 2 * 4 * 14);
        assert_eq!(top_cells, 26 * 14);
    }

    #[test]
    fn a_35_cm_gap_is_forbidden_inside_and_at_its_lips() {
        // A trench 35 cm wide and 1 m deep across the whole map.
        let gap = [1.0, 1.35];
        let world = Boxes { ground: 0.0, boxes: vec![(gap, [-10.0, 10.0], -1.0)] };
        let mut map = map_with_noise(0.005);
        let mut rng = rng();
        for _ in 0..4 {
            map.observe(&world, [1.2, 0.0], 0.0, &mut rng).unwrap();
        }
        let r = map.resolution();
        let mut inside = 0;
        for cell in map.cells().filter(|c| c.center[1].abs() < 1.0) {
            let x = cell.center[0];
            let assessment = map.assess(cell.i, cell.j).unwrap();
            if x > gap[0] && x < gap[1] {
                // The floor: a gap (or, next to the walls, a step).
                inside += 1;
                assert!(matches!(assessment, CellAssessment::Gap { .. } | CellAssessment::Step { .. }), "{cell:?}");
                assert_eq!(cell.cost, 1.0);
            } else if cells_from(x, gap, r) <= 1 {
                // The lips: the window reaches over the edge.
                assert!(matches!(assessment, CellAssessment::Step { height_range } if height_range > 0.99), "{cell:?}");
                assert_eq!(cell.cost, 1.0);
            } else if (x - 1.2).abs() < 1.5 {
                assert!(cell.cost < 0.3, "{cell:?} {assessment:?}");
            }
        }
        assert_eq!(inside, 9 * 50); // 9 cells across (centres 1.02..1.34), 50 rows
    }

    #[test]
    fn noise_averages_out_as_one_over_root_n() {
        let sigma = 0.01;
        let mut map = map_with_noise(sigma);
        let mut rng = rng();
        let world = Plane::flat(0.1);
        let mut resets = 0;
        for n in 1..=64u32 {
            resets += map.observe(&world, [1.0, 0.0], 0.0, &mut rng).unwrap().reset_cells;
            if ![1, 4, 16, 64].contains(&n) {
                continue;
            }
            // Kalman variance sigma^2 / n exactly (cells never reset), and the actual error
            // over ~10,000 cells has RMS sigma / sqrt(n) (to about 1 % sampling error).
            let (mut squared, mut count) = (0.0, 0);
            for cell in map.cells().filter(|c| c.observations == n) {
                let variance = cell.variance.unwrap();
                assert!((variance * n as f64 / (sigma * sigma) - 1.0).abs() < 1e-9, "{cell:?}");
                squared += (cell.height.unwrap() - 0.1).powi(2);
                count += 1;
            }
            let rms = (squared / count as f64).sqrt();
            let ratio = rms * (n as f64).sqrt() / sigma;
            assert!(count > 9000 && (ratio - 1.0).abs() < 0.05, "n = {n}: {count} cells, rms {rms}, ratio {ratio}");
        }
        // k = 5: a false reset once in 1.7 million observations of an unchanged cell.
        assert!(resets <= 3, "{resets} false resets");
    }

    #[test]
    fn an_obstacle_that_appears_resets_its_cells_and_raises_their_cost() {
        let sigma = 0.01;
        let before = Boxes { ground: 0.0, boxes: vec![] };
        let after = Boxes { ground: 0.0, boxes: vec![PALLET] };
        let mut map = map_with_noise(sigma);
        let mut rng = rng();
        for _ in 0..10 {
            map.observe(&before, [0.3, 0.0], 0.0, &mut rng).unwrap();
        }
        let edge = map.cell_at(1.01, 0.0).unwrap();
        let edge_cost_before = map.cell(edge.0, edge.1).unwrap().cost;
        assert!(edge_cost_before < 0.2, "{edge_cost_before}");
        let update = map.observe(&after, [0.3, 0.0], 0.0, &mut rng).unwrap();
        // Exactly the pallet's 30 x 20 cells jumped by 15 sigma, and were reset.
        assert!(update.world_changed());
        assert_eq!(update.reset_cells, 30 * 20);
        let reset = update.reset.unwrap();
        assert_eq!(reset.cell_count(), 30 * 20);
        let bounds = map.rect_bounds(reset);
        for (got, want) in bounds.iter().flatten().zip([1.0, -0.4, 2.2, 0.4]) {
            assert!((got - want).abs() < 1e-9, "{bounds:?}");
        }
        for cell in map.cells().filter(|c| reset.contains(c.i, c.j)) {
            assert_eq!(cell.observations, 1);
            assert!((cell.height.unwrap() - 0.15).abs() < 5.0 * sigma, "{cell:?}");
        }
        // The recomputed region holds the pallet and its surroundings; the edge is now dear.
        assert!(update.cost_region.unwrap().contains(reset.i_min - 6, reset.j_min - 6));
        assert!(map.cell(edge.0, edge.1).unwrap().cost > 0.99);
        // A second sweep of the same world changes nothing.
        assert!(!map.observe(&after, [0.3, 0.0], 0.0, &mut rng).unwrap().world_changed());

        // Why the reset matters: with no change detection (k huge) the pallet is averaged in
        // as one sample among eleven, h = (10 * 0 + 0.15) / 11, up to the noise.
        let config = TerrainMapConfig { change_threshold_sigmas: 1e9, ..*map.config() };
        let mut stubborn = TerrainMap::new(config).unwrap();
        for _ in 0..10 {
            stubborn.observe(&before, [0.3, 0.0], 0.0, &mut rng).unwrap();
        }
        assert!(!stubborn.observe(&after, [0.3, 0.0], 0.0, &mut rng).unwrap().world_changed());
        assert!((stubborn.height(1.6, 0.0) - 0.15 / 11.0).abs() < 4.0 * sigma / 11f64.sqrt());
    }

    #[test]
    fn local_recompute_equals_full_recompute() {
        // A walk with a forward-looking 100 deg wedge of 1.5 m (irregular known regions),
        // over a platform, a gap and 0.3 m posts (whose feet are forbidden by the gap rule up
        // to 6 cells away, so cells outside the footprint change cost), a pallet and a
        // 0.4 m wall appearing half way.
        let mut config = TerrainMapConfig::default();
        config.sensor.range = 1.5;
        config.sensor.field_of_view = 100f64.to_radians();
        let mut map = TerrainMap::new(config).unwrap();
        let mut still =
            Boxes { ground: 0.0, boxes: vec![([3.5, 7.0], [-3.0, 3.0], 0.12), ([5.0, 5.35], [-3.0, 3.0], -1.0)] };
        for k in 0..12 {
            let (x, y) = (-0.7 + 0.6 * k as f64, if k % 2 == 0 { 1.2 } else { -1.3 });
            still.boxes.push(([x, x + 0.2], [y, y + 0.2], 0.3));
        }
        let mut changed = Boxes { ground: 0.0, boxes: still.boxes.clone() };
        changed.boxes.extend([PALLET, ([2.5, 2.7], [-1.0, 1.0], 0.4)]);
        let mut rng = rng();
        let total = map.size().0 * map.size().1;
        for step in 0..16 {
            let s = step as f64;
            let (robot, yaw) = ([-0.5 + 0.4 * s, 0.8 * (0.7 * s).sin()], 0.6 * (0.5 * s).cos());
            let world = if step < 8 { &still } else { &changed };
            let update = map.observe(world, robot, yaw, &mut rng).unwrap();
            assert!(update.cost_region.unwrap().cell_count() < total / 2, "the recompute is local");
            let mut full = map.clone();
            full.recompute_all_costs();
            assert!(full.costs() == map.costs(), "step {step}: local and full recompute differ");
        }

        // The reach of the gap rule: a post grows from 0.1 m to 0.3 m on the rim of a sweep,
        // and the ground beyond it, known from an earlier sweep but not seen now, becomes the
        // foot of a wall up to 6 cells away.
        let mut map = map_with_noise(0.001);
        let post = |top: f64| Boxes { ground: 0.0, boxes: vec![([2.0, 2.2], [-0.1, 0.1], top)] };
        map.observe(&post(0.1), [0.0, 0.0], 0.0, &mut rng).unwrap();
        let update = map.observe(&post(0.3), [-0.3, 0.0], 0.0, &mut rng).unwrap();
        assert_eq!(update.reset_cells, 5 * 5);
        let beyond = map.cell_at(2.35, 0.0).unwrap();
        assert!(!update.observed.unwrap().contains(beyond.0, beyond.1), "the cell is not seen again");
        assert!(matches!(map.assess(beyond.0, beyond.1), Some(CellAssessment::Gap { .. })));
        let mut full = map.clone();
        full.recompute_all_costs();
        assert!(full.costs() == map.costs(), "the post: local and full recompute differ");
    }

    #[test]
    fn a_wedge_sensor_sees_only_ahead() {
        let mut config = TerrainMapConfig::default();
        config.sensor.field_of_view = 90f64.to_radians();
        let mut map = TerrainMap::new(config).unwrap();
        // Heading +y (yaw 90 deg) from (1, -1.5): cells at bearings within 45 deg of +y only.
        map.observe(&Plane::flat(0.0), [1.0, -1.5], 0.5 * PI, &mut rng()).unwrap();
        for cell in map.cells() {
            let (dx, dy) = (cell.center[0] - 1.0, cell.center[1] + 1.5);
            let seen = dx.hypot(dy) <= 2.5 && dy >= dx.abs();
            let clearly = dx.hypot(dy) < 2.45 && (dy - dx.abs()).abs() > 0.03 || dx.hypot(dy) > 2.55;
            if clearly {
                assert_eq!(cell.height.is_some(), seen, "{cell:?}");
            }
        }
        assert!(map.is_known(1.0, 0.0) && !map.is_known(1.0, -1.9) && !map.is_known(3.0, -1.4));
    }

    #[test]
    fn queries_read_the_cell_containing_the_point() {
        let world = Boxes { ground: 0.0, boxes: vec![PALLET] };
        let mut map = map_with_noise(1e-6);
        map.observe(&world, [0.5, 0.0], 0.0, &mut rng()).unwrap();
        // Cell (50, 50) covers [1.0, 1.04) x [0.0, 0.04): on the pallet.
        assert_eq!(map.cell_at(1.0, 0.0), Some((50, 50)));
        assert_eq!(map.cell_at(1.039, 0.039), Some((50, 50)));
        let center = map.cell_center(50, 50);
        assert!((center[0] - 1.02).abs() < 1e-12 && (center[1] - 0.02).abs() < 1e-12, "{center:?}");
        assert!((map.height(1.039, 0.0) - 0.15).abs() < 1e-5 && map.height(0.999, 0.0).abs() < 1e-5);
        assert_eq!(map.cost(1.0, 0.0), map.cell(50, 50).unwrap().cost);
        // Off the map and unknown.
        assert_eq!(map.cell_at(7.0, 0.0), None);
        assert!(map.height(7.0, 0.0).is_nan() && map.try_height(7.0, 0.0).is_none());
        assert_eq!(map.cost(7.0, 0.0), 1.0);
        assert_eq!(map.cost(f64::NAN, 0.0), 1.0);
        assert!(!map.is_known(6.5, 1.9) && map.height(6.5, 1.9).is_nan() && map.cost(6.5, 1.9) == 1.0);
        assert_eq!(map.cells().count(), 200 * 100);
    }

    #[test]
    fn best_costs_around_matches_sorting_the_disk() {
        let world = Boxes { ground: 0.0, boxes: vec![PALLET] };
        let mut map = map_with_noise(0.01);
        map.observe(&world, [0.5, 0.0], 0.0, &mut rng()).unwrap();
        let reference = |x: f64, y: f64, radius: f64, n: usize| {
            let mut costs: Vec<f64> =
                map.cells().filter(|c| (c.center[0] - x).hypot(c.center[1] - y) <= radius).map(|c| c.cost).collect();
            costs.sort_by(f64::total_cmp);
            costs.truncate(n);
            costs.iter().sum::<f64>() / costs.len() as f64
        };
        for &(x, y, radius, n) in
            &[(1.0, 0.0, 0.1, 5), (1.0, 0.4, 0.15, 10), (2.97, 0.0, 0.3, 64), (-0.95, 0.0, 0.2, 7), (0.5, 1.9, 0.12, 1)]
        {
            let got = map.best_costs_around(x, y, radius, n).unwrap();
            let want = reference(x, y, radius, n);
            assert!((got - want).abs() < 1e-12, "({x}, {y}, {radius}, {n}): {got} vs {want}");
        }
        // On the pallet's edge the best 5 of the disk of 0.1 m lie beyond the edge band
        // (the disk holds the cells 2 cells either side): nearly free; the best 1 within
        // 2 cm of the edge is the edge itself.
        assert!(map.best_costs_around(1.0, 0.0, 0.12, 5).unwrap() < 0.25);
        assert!(map.best_costs_around(1.0, 0.0, 0.03, 1).unwrap() > 0.99);
        // A disk holding no centre: the cell containing the point; off the map: 1.
        assert_eq!(map.best_costs_around(1.02, 0.02, 0.001, 3).unwrap(), map.cost(1.02, 0.02));
        assert_eq!(map.best_costs_around(1.0, 0.0, 0.0, 3).unwrap(), map.cost(1.0, 0.0));
        assert_eq!(map.best_costs_around(50.0, 0.0, 0.2, 3).unwrap(), 1.0);
        // Arguments are checked.
        for (result, name) in [
            (map.best_costs_around(1.0, 0.0, 0.1, 0), "`n`"),
            (map.best_costs_around(1.0, 0.0, 0.1, 65), "`n`"),
            (map.best_costs_around(1.0, 0.0, f64::NAN, 3), "`radius`"),
            (map.best_costs_around(f64::NAN, 0.0, 0.1, 3), "`(x, y)`"),
        ] {
            assert!(result.unwrap_err().to_string().contains(name), "{name}");
        }
    }

    #[test]
    fn height_map_conversion_puts_cells_at_grid_points() {
        let world = Boxes { ground: 0.0, boxes: vec![PALLET] };
        let mut map = map_with_noise(1e-6);
        map.observe(&world, [0.5, 0.0], 0.0, &mut rng()).unwrap();
        let heights = map.to_height_map(-0.5).unwrap();
        assert_eq!(heights.size(), map.size());
        for cell in map.cells() {
            let [x, y] = cell.center;
            assert_eq!(heights.at(cell.i, cell.j), cell.height.unwrap_or(-0.5), "{cell:?}");
            assert!((heights.height(x, y) - heights.at(cell.i, cell.j)).abs() < 1e-12, "{cell:?}");
        }
        assert!(matches!(map.to_terrain_spec(0.0).unwrap(), TerrainSpec::HeightMap(f) if f.resolution == 0.04));
        assert!(map.to_height_map(f64::NAN).unwrap_err().to_string().contains("unknown_height"));
    }

    #[test]
    fn bad_configuration_and_arguments_name_the_field() {
        let field_of = |edit: fn(&mut TerrainMapConfig)| {
            let mut config = TerrainMapConfig::default();
            edit(&mut config);
            match TerrainMap::new(config).unwrap_err() {
                TerrainMapError::InvalidConfig { field, .. } => field,
                other => panic!("{other}"),
            }
        };
        assert_eq!(field_of(|c| c.resolution = 0.0), "resolution");
        assert_eq!(field_of(|c| c.resolution = -0.04), "resolution");
        assert_eq!(field_of(|c| c.resolution = f64::NAN), "resolution");
        assert_eq!(field_of(|c| c.origin[1] = f64::INFINITY), "origin[1]");
        assert_eq!(field_of(|c| c.size[0] = f64::NAN), "size[0]");
        assert_eq!(field_of(|c| c.size = [0.04, 4.0]), "size");
        assert_eq!(field_of(|c| c.size = [1e4, 1e4]), "size");
        assert_eq!(field_of(|c| c.sensor.range = 0.0), "sensor.range");
        assert_eq!(field_of(|c| c.sensor.noise_sigma = 0.0), "sensor.noise_sigma");
        assert_eq!(field_of(|c| c.sensor.field_of_view = 7.0), "sensor.field_of_view");
        assert_eq!(field_of(|c| c.change_threshold_sigmas = f64::NAN), "change_threshold_sigmas");
        assert_eq!(field_of(|c| c.cost.saturation.slope = -1.0), "cost.saturation.slope");
        let message =
            TerrainMap::new(TerrainMapConfig { resolution: f64::NAN, ..Default::default() }).unwrap_err().to_string();
        assert!(message.contains("`resolution`") && message.contains("NaN"), "{message}");

        let mut map = TerrainMap::new(TerrainMapConfig::default()).unwrap();
        let error = map.observe(&Plane::flat(0.0), [f64::NAN, 0.0], 0.0, &mut rng()).unwrap_err();
        assert!(error.to_string().contains("robot_xy[0]"), "{error}");
        let error = map.observe(&Plane::flat(0.0), [0.0, 0.0], f64::INFINITY, &mut rng()).unwrap_err();
        assert!(error.to_string().contains("yaw"), "{error}");
        // A world that answers NaN is refused, and the map is left as it was.
        let broken = Boxes { ground: f64::NAN, boxes: vec![PALLET] };
        assert!(matches!(
            map.observe(&broken, [0.5, 0.0], 0.0, &mut rng()),
            Err(TerrainMapError::NonFiniteWorld { .. })
        ));
        assert_eq!(map.known_cells(), 0);
    }

    #[test]
    fn configuration_reads_from_toml_with_defaults_and_refuses_unknown_fields() {
        let config: TerrainMapConfig = toml::from_str("resolution = 0.05\n[sensor]\nrange = 3.0\n").unwrap();
        assert_eq!(config.resolution, 0.05);
        assert_eq!(config.sensor, SensorConfig { range: 3.0, ..SensorConfig::default() });
        assert_eq!(config.cost, CostParams::default());
        let error = toml::from_str::<TerrainMapConfig>("[cost]\nwindow = 3\n").unwrap_err().to_string();
        assert!(error.contains("window"), "{error}");
    }

    #[test]
    fn standard_normal_has_unit_moments() {
        let mut rng = rng();
        let n = 200_000;
        let samples: Vec<f64> = (0..n).map(|_| standard_normal(&mut rng)).collect();
        let mean = samples.iter().sum::<f64>() / n as f64;
        let variance = samples.iter().map(|s| (s - mean).powi(2)).sum::<f64>() / n as f64;
        let beyond_two = samples.iter().filter(|s| s.abs() > 2.0).count() as f64 / n as f64;
        // Standard errors: mean 0.0022, variance 0.0032, tail fraction 0.0005 (P = 0.0455).
        assert!(mean.abs() < 0.01 && (variance - 1.0).abs() < 0.015 && (beyond_two - 0.0455).abs() < 0.003);
    }
}
