//! A height-map terrain: heights on a regular grid, bilinear in between.

use super::{Terrain, TerrainError, TerrainSpec};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The file form of a height map (TOML, or inside a trajectory's JSON):
///
/// ```toml
/// # legwork height map: heights[row][column] is the ground height (m) at
/// # x = origin[0] + column * resolution, y = origin[1] + row * resolution.
/// origin = [-1.0, -1.0]      # m, position of heights[0][0]
/// resolution = 0.04          # m, grid spacing along x and y
/// heights = [
///   [0.0, 0.0, 0.0],         # row 0 (y = -1.0)
///   [0.0, 0.15, 0.0],        # row 1 (y = -0.96)
/// ]
/// ```
///
/// At least 2 rows of at least 2 columns, all rows of one length, every number finite.
/// Unknown fields are errors.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HeightMapFile {
    pub origin: [f64; 2],
    pub resolution: f64,
    pub heights: Vec<Vec<f64>>,
}

/// Heights `h[j][i]` at `(x0 + i r, y0 + j r)`; bilinear inside each cell, the normal from
/// the gradient of the bilinear interpolant, `n = (-h_x, -h_y, 1) / |.|`. Outside the grid
/// the border values extend (the query is clamped to the grid).
///
/// ```
/// use legwork::terrain::{HeightMap, Terrain};
/// // 4 x 3 m of flat ground at 4 cm cells, with a 0.15 m pallet at x in [1, 2.2].
/// let mut map = HeightMap::flat([-1.0, -1.5], 0.04, 101, 76, 0.0);
/// map.set_rect([1.0, 2.2], [-0.4, 0.4], 0.15);
/// assert_eq!(map.height(1.5, 0.0), 0.15);
/// assert_eq!(map.height(0.0, 0.0), 0.0);
/// assert!(map.normal(0.98, 0.0).x < -0.5); // the pallet's edge faces -x
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct HeightMap {
    origin: [f64; 2],
    resolution: f64,
    columns: usize,
    rows: usize,
    /// Row-major: `heights[j * columns + i]`.
    heights: Vec<f64>,
}

impl HeightMap {
    /// A flat map of `columns x rows` points at `height`.
    ///
    /// # Panics
    /// If `resolution` is not positive and finite or the grid is smaller than 2 x 2
    /// (a programming error; files go through [`HeightMap::from_file_data`]).
    pub fn flat(origin: [f64; 2], resolution: f64, columns: usize, rows: usize, height: f64) -> Self {
        assert!(resolution > 0.0 && resolution.is_finite(), "height map resolution must be positive");
        assert!(columns >= 2 && rows >= 2, "a height map needs at least 2 x 2 points");
        Self { origin, resolution, columns, rows, heights: vec![height; columns * rows] }
    }

    /// Sets every grid point with `x` in `x_range` and `y` in `y_range` (inclusive) to
    /// `height`: a box top, a step (a range to the map's edge) or a gap (a low height).
    pub fn set_rect(&mut self, x_range: [f64; 2], y_range: [f64; 2], height: f64) {
        for j in 0..self.rows {
            let y = self.origin[1] + j as f64 * self.resolution;
            if y < y_range[0] - 1e-9 || y > y_range[1] + 1e-9 {
                continue;
            }
            for i in 0..self.columns {
                let x = self.origin[0] + i as f64 * self.resolution;
                if x >= x_range[0] - 1e-9 && x <= x_range[1] + 1e-9 {
                    self.heights[j * self.columns + i] = height;
                }
            }
        }
    }

    /// Grid spacing (m).
    pub fn resolution(&self) -> f64 {
        self.resolution
    }
    /// Position of grid point (0, 0).
    pub fn origin(&self) -> [f64; 2] {
        self.origin
    }
    /// Number of grid points along x and along y.
    pub fn size(&self) -> (usize, usize) {
        (self.columns, self.rows)
    }
    /// Height at grid point `(i, j)`.
    pub fn at(&self, i: usize, j: usize) -> f64 {
        self.heights[j * self.columns + i]
    }
    /// Sets the height at grid point `(i, j)`.
    pub fn set(&mut self, i: usize, j: usize, height: f64) {
        self.heights[j * self.columns + i] = height;
    }

    /// Checks and converts the file form; `origin_name` (a path, a field) goes into errors.
    pub fn from_file_data(file: HeightMapFile, origin_name: &str) -> Result<Self, TerrainError> {
        let bad = |field: String, problem: String| TerrainError::Invalid { origin: origin_name.into(), field, problem };
        if !(file.resolution > 0.0 && file.resolution.is_finite()) {
            return Err(bad("resolution".into(), format!("expected a positive number of metres, got {}", file.resolution)));
        }
        for (k, o) in file.origin.iter().enumerate() {
            if !o.is_finite() {
                return Err(bad(format!("origin[{k}]"), format!("expected a finite number, got {o}")));
            }
        }
        let rows = file.heights.len();
        if rows < 2 {
            return Err(bad("heights".into(), format!("expected at least 2 rows, got {rows}")));
        }
        let columns = file.heights[0].len();
        if columns < 2 {
            return Err(bad("heights[0]".into(), format!("expected at least 2 columns, got {columns}")));
        }
        let mut heights = Vec::with_capacity(rows * columns);
        for (j, row) in file.heights.iter().enumerate() {
            if row.len() != columns {
                return Err(bad(format!("heights[{j}]"), format!("expected {columns} columns (as row 0), got {}", row.len())));
            }
            for (i, h) in row.iter().enumerate() {
                if !h.is_finite() {
                    return Err(bad(format!("heights[{j}][{i}]"), format!("expected a finite height, got {h}")));
                }
                heights.push(*h);
            }
        }
        Ok(Self { origin: file.origin, resolution: file.resolution, columns, rows, heights })
    }

    /// Loads a height map from a TOML file (format in [`HeightMapFile`]).
    pub fn load_file(path: impl AsRef<Path>) -> Result<Self, TerrainError> {
        let path = path.as_ref();
        let name = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|error| TerrainError::Io { path: name.clone(), error })?;
        let file: HeightMapFile =
            toml::from_str(&text).map_err(|e| TerrainError::Parse { path: name.clone(), message: e.to_string() })?;
        Self::from_file_data(file, &name)
    }

    /// The file form of this map.
    pub fn to_file_data(&self) -> HeightMapFile {
        HeightMapFile {
            origin: self.origin,
            resolution: self.resolution,
            heights: self.heights.chunks(self.columns).map(|r| r.to_vec()).collect(),
        }
    }

    /// Cell `(i, j)` and local coordinates `(u, w)` in `[0, 1]` of a query, clamped to the
    /// grid; `inside_x`/`inside_y` say whether the query was within the grid along each axis
    /// (outside, the border extends, so the slope along that axis is zero).
    #[inline]
    fn locate(&self, x: f64, y: f64) -> (usize, usize, f64, f64, bool, bool) {
        let gx = (x - self.origin[0]) / self.resolution;
        let gy = (y - self.origin[1]) / self.resolution;
        let max_x = (self.columns - 1) as f64;
        let max_y = (self.rows - 1) as f64;
        let inside_x = (0.0..=max_x).contains(&gx);
        let inside_y = (0.0..=max_y).contains(&gy);
        let cx = gx.clamp(0.0, max_x);
        let cy = gy.clamp(0.0, max_y);
        let i = (cx.floor() as usize).min(self.columns - 2);
        let j = (cy.floor() as usize).min(self.rows - 2);
        (i, j, cx - i as f64, cy - j as f64, inside_x, inside_y)
    }

    #[inline]
    fn corners(&self, i: usize, j: usize) -> (f64, f64, f64, f64) {
        let c = self.columns;
        (self.heights[j * c + i], self.heights[j * c + i + 1], self.heights[(j + 1) * c + i], self.heights[(j + 1) * c + i + 1])
    }
}

impl Terrain for HeightMap {
    /// `h = (1-u)(1-w) h00 + u (1-w) h10 + (1-u) w h01 + u w h11`.
    fn height(&self, x: f64, y: f64) -> f64 {
        let (i, j, u, w, _, _) = self.locate(x, y);
        let (h00, h10, h01, h11) = self.corners(i, j);
        (1.0 - w) * ((1.0 - u) * h00 + u * h10) + w * ((1.0 - u) * h01 + u * h11)
    }
    /// `h_x = ((1-w)(h10 - h00) + w (h11 - h01)) / r`, `h_y = ((1-u)(h01 - h00) + u (h11 - h10)) / r`.
    fn normal(&self, x: f64, y: f64) -> Vector3<f64> {
        self.surface(x, y).1
    }
    fn surface(&self, x: f64, y: f64) -> (f64, Vector3<f64>) {
        let (i, j, u, w, inside_x, inside_y) = self.locate(x, y);
        let (h00, h10, h01, h11) = self.corners(i, j);
        let h = (1.0 - w) * ((1.0 - u) * h00 + u * h10) + w * ((1.0 - u) * h01 + u * h11);
        let hx = if inside_x { ((1.0 - w) * (h10 - h00) + w * (h11 - h01)) / self.resolution } else { 0.0 };
        let hy = if inside_y { ((1.0 - u) * (h01 - h00) + u * (h11 - h10)) / self.resolution } else { 0.0 };
        (h, Vector3::new(-hx, -hy, 1.0).normalize())
    }
    /// The highest grid point of the cells the disk touches (bilinear cells never rise
    /// above their corners).
    fn highest_near(&self, x: f64, y: f64, radius: f64) -> f64 {
        let r = self.resolution;
        let index = |v: f64, o: f64, n: usize| (((v - o) / r).floor().max(0.0) as usize).min(n - 1);
        let (i0, i1) = (index(x - radius, self.origin[0], self.columns), index(x + radius, self.origin[0], self.columns) + 1);
        let (j0, j1) = (index(y - radius, self.origin[1], self.rows), index(y + radius, self.origin[1], self.rows) + 1);
        let mut highest = f64::NEG_INFINITY;
        for j in j0..=j1.min(self.rows - 1) {
            for i in i0..=i1.min(self.columns - 1) {
                highest = highest.max(self.heights[j * self.columns + i]);
            }
        }
        highest
    }
    fn spec(&self) -> TerrainSpec {
        TerrainSpec::HeightMap(self.to_file_data())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bilinear_reproduces_a_plane_and_its_normal() {
        // Heights of the plane z = 0.1 x - 0.2 y + 0.3 at the grid points.
        let mut map = HeightMap::flat([-1.0, -1.0], 0.1, 21, 21, 0.0);
        for j in 0..21 {
            for i in 0..21 {
                let (x, y) = (-1.0 + 0.1 * i as f64, -1.0 + 0.1 * j as f64);
                map.set(i, j, 0.1 * x - 0.2 * y + 0.3);
            }
        }
        let (h, n) = map.surface(0.237, -0.411);
        assert!((h - (0.1 * 0.237 + 0.2 * 0.411 + 0.3)).abs() < 1e-12);
        let expected = Vector3::new(-0.1, 0.2, 1.0).normalize();
        assert!((n - expected).norm() < 1e-12);
        // Outside: the border extends, flat along the clamped axis.
        assert!((map.height(5.0, 0.0) - map.height(1.0, 0.0)).abs() < 1e-12);
        assert!(map.normal(5.0, 0.0).x.abs() < 1e-12);
    }

    #[test]
    fn highest_near_bounds_the_surface_over_the_disk() {
        // A 0.57 m cliff: the pit at -0.5 up to a stone top at 0.07 from x = 0.66.
        let mut map = HeightMap::flat([0.0, -1.0], 0.02, 101, 101, -0.5);
        map.set_rect([0.66, 0.82], [-0.1, 0.1], 0.07);
        for k in 0..200 {
            let (x, y) = (0.55 + 0.002 * k as f64, 0.013 * (k % 7) as f64);
            let bound = map.highest_near(x, y, 0.022);
            for s in 0..16 {
                let a = s as f64 * std::f64::consts::TAU / 16.0;
                for r in [0.0, 0.011, 0.022] {
                    assert!(map.height(x + r * a.cos(), y + r * a.sin()) <= bound + 1e-12, "({x}, {y})");
                }
            }
        }
        // Over the cliff's ramp the bound is the stone top, not the tangent plane's reach.
        assert_eq!(map.highest_near(0.65, 0.0, 0.022), 0.07);
        assert_eq!(map.highest_near(0.3, 0.0, 0.022), -0.5);
    }

    #[test]
    fn file_errors_name_the_field() {
        let bad = HeightMapFile { origin: [0.0, 0.0], resolution: 0.04, heights: vec![vec![0.0, 0.0], vec![0.0]] };
        let e = HeightMap::from_file_data(bad, "map.toml").unwrap_err().to_string();
        assert!(e.contains("map.toml") && e.contains("heights[1]") && e.contains("expected 2 columns"), "{e}");
        let nan = HeightMapFile { origin: [0.0, 0.0], resolution: 0.04, heights: vec![vec![0.0, f64::NAN], vec![0.0, 0.0]] };
        let e = HeightMap::from_file_data(nan, "map.toml").unwrap_err().to_string();
        assert!(e.contains("heights[0][1]"), "{e}");
        let res = HeightMapFile { origin: [0.0, 0.0], resolution: -1.0, heights: vec![vec![0.0; 2]; 2] };
        assert!(HeightMap::from_file_data(res, "m").unwrap_err().to_string().contains("resolution"));
    }

    #[test]
    fn toml_round_trip_and_unknown_fields() {
        let mut map = HeightMap::flat([0.0, 0.0], 0.04, 5, 4, 0.0);
        map.set_rect([0.04, 0.08], [0.0, 0.04], 0.15);
        let text = toml::to_string(&map.to_file_data()).unwrap();
        let back = HeightMap::from_file_data(toml::from_str(&text).unwrap(), "x").unwrap();
        assert_eq!(back, map);
        let unknown = format!("{text}\ncolour = 3\n");
        assert!(toml::from_str::<HeightMapFile>(&unknown).unwrap_err().to_string().contains("colour"));
    }
}
