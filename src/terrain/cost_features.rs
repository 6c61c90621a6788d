//! The terrain cost of one cell from geometric features of its neighbourhood: Winkler 2015
//! sec. III-A, "the standard deviation of height values, the slope and the curvature of the
//! cell in question", combined as `c_t(x, y) = w^T c(x, y)`, the features as in its
//! reference [1] (Kalakrishnan et al. 2010, terrain templates over a window around the
//! foothold).
//!
//! Every feature comes from the `(2R + 1) x (2R + 1)` window of cells centred on the cell
//! (default `R = 2`: 5 x 5 cells = 20 cm x 20 cm at 4 cm cells, HyQ's foot plus its
//! placement error):
//!
//! * `height_std`: the standard deviation of the window's heights (m), as the paper says.
//! * `slope`: the angle (rad) between the vertical and the normal of the least-squares plane
//!   `z = a + b x + c y` through the window, `atan(sqrt(b^2 + c^2))`.
//! * `curvature`: the largest principal curvature magnitude (1/m) of the least-squares
//!   quadratic `z = a + b x + c y + d x^2 + e x y + f y^2`, in the small-slope form
//!   `max |eig([[2d, e], [e, 2f]])| = |d + f| + sqrt((d - f)^2 + e^2)`.
//!
//! On a regular window both fits are fixed linear filters of the heights (the rows of the
//! design matrix's pseudo-inverse, computed once: [`WindowFit`]); on a symmetric window the
//! plane's `b, c` equal the quadratic's, so one set of filters gives both.
//!
//! The cost is the weighted mean of the features, each divided by a saturation value and
//! clipped at 1, so it lies in `[0, 1]` and depends on the window alone (no map-wide
//! normalisation, which would make a local recompute differ from a full one). Three hard rules
//! make a cell forbidden (cost 1) whatever its features:
//!
//! * unknown: a cell of the window has no observation (or lies outside the map);
//! * step: the window's heights span more than `max_step_height` (the lip of a gap, a wall);
//! * gap: the cell lies more than `max_step_height` below the highest known cell within
//!   `gap_radius_cells` along x and y: the floor of a trench narrower than about
//!   `2 * gap_radius_cells` cells, or the foot of a wall too high to step on.

use nalgebra::{DMatrix, SMatrix};
use serde::{Deserialize, Serialize};

/// Weights `w` of the features in `c_t = w^T c` (Winkler 2015 sec. III-A). Only their
/// ratios matter: the cost divides by their sum.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FeatureWeights {
    pub height_std: f64,
    pub slope: f64,
    pub curvature: f64,
}

impl Default for FeatureWeights {
    /// Slope weighs most (0.4): it decides whether the foot's force stays inside the friction
    /// cone; roughness (height spread) and curvature (an edge or a corner the foot rolls off)
    /// share the rest (0.3 each). The paper gives no numbers.
    fn default() -> Self {
        Self { height_std: 0.3, slope: 0.4, curvature: 0.3 }
    }
}

/// The feature value at which each feature's cost reaches 1 (and stays there).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FeatureSaturation {
    /// m. 5 cm: a third of a 15 cm pallet's height spread over one foot window.
    pub height_std: f64,
    /// rad. 0.5 rad (29 deg): the friction cone's half-angle for mu = 0.55, below HyQ's
    /// rubber feet on wood (mu about 0.7) with a margin.
    pub slope: f64,
    /// 1/m. 10 /m: the surface bends with a radius of 10 cm or less, five times HyQ's foot
    /// radius: an edge.
    pub curvature: f64,
}

impl Default for FeatureSaturation {
    fn default() -> Self {
        Self { height_std: 0.05, slope: 0.5, curvature: 10.0 }
    }
}

/// How a cell's terrain cost is computed (module documentation above).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CostParams {
    /// `R`: the feature window is `(2R + 1) x (2R + 1)` cells, `1 <= R <= 5`. Default 2.
    pub window_radius_cells: usize,
    pub weights: FeatureWeights,
    pub saturation: FeatureSaturation,
    /// m. A window whose heights span more, or a cell this much below its surroundings, is
    /// forbidden. Default 0.2 m: a 15 cm pallet is climbable, the lip of a deep gap is not.
    pub max_step_height: f64,
    /// Cells along x and y searched for the higher ground around a gap's floor (0 turns the
    /// gap rule off). Default 6 (24 cm at 4 cm cells): every cell inside a 35 cm gap sees
    /// a lip.
    pub gap_radius_cells: usize,
}

impl Default for CostParams {
    fn default() -> Self {
        Self {
            window_radius_cells: 2,
            weights: FeatureWeights::default(),
            saturation: FeatureSaturation::default(),
            max_step_height: 0.2,
            gap_radius_cells: 6,
        }
    }
}

/// The largest feature window radius (11 x 11 cells).
pub const MAX_WINDOW_RADIUS_CELLS: usize = 5;
/// The largest gap search radius (cells).
pub const MAX_GAP_RADIUS_CELLS: usize = 50;

impl CostParams {
    /// Checks every number; the error names the field (as `cost.<field>`) and what was
    /// expected.
    pub(crate) fn validate(&self) -> Result<(), (&'static str, &'static str, String)> {
        if !(1..=MAX_WINDOW_RADIUS_CELLS).contains(&self.window_radius_cells) {
            return Err(("cost.window_radius_cells", "an integer from 1 to 5", self.window_radius_cells.to_string()));
        }
        if self.gap_radius_cells > MAX_GAP_RADIUS_CELLS {
            return Err(("cost.gap_radius_cells", "an integer from 0 to 50", self.gap_radius_cells.to_string()));
        }
        let w = &self.weights;
        for (field, value) in [
            ("cost.weights.height_std", w.height_std),
            ("cost.weights.slope", w.slope),
            ("cost.weights.curvature", w.curvature),
        ] {
            if !(value >= 0.0 && value.is_finite()) {
                return Err((field, "a finite weight >= 0", value.to_string()));
            }
        }
        if w.height_std + w.slope + w.curvature <= 0.0 {
            return Err(("cost.weights", "at least one positive weight", "all zero".into()));
        }
        let s = &self.saturation;
        for (field, value) in [
            ("cost.saturation.height_std", s.height_std),
            ("cost.saturation.slope", s.slope),
            ("cost.saturation.curvature", s.curvature),
        ] {
            if !(value > 0.0 && value.is_finite()) {
                return Err((field, "a finite number > 0", value.to_string()));
            }
        }
        if !(self.max_step_height > 0.0 && self.max_step_height.is_finite()) {
            return Err(("cost.max_step_height", "a finite height > 0 (m)", self.max_step_height.to_string()));
        }
        Ok(())
    }

    /// `c_t = w^T c / sum(w)` with each feature scaled by its saturation and clipped at 1
    /// (Winkler 2015 sec. III-A).
    pub fn cost_of(&self, f: &CellFeatures) -> f64 {
        let (w, s) = (&self.weights, &self.saturation);
        let scaled = |value: f64, saturation: f64| (value / saturation).min(1.0);
        (w.height_std * scaled(f.height_std, s.height_std)
            + w.slope * scaled(f.slope, s.slope)
            + w.curvature * scaled(f.curvature, s.curvature))
            / (w.height_std + w.slope + w.curvature)
    }
}

/// The geometric features of one cell (module documentation above).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CellFeatures {
    /// Standard deviation of the window's heights (m).
    pub height_std: f64,
    /// Angle of the fitted plane's normal from the vertical (rad).
    pub slope: f64,
    /// Largest principal curvature magnitude of the fitted quadratic (1/m).
    pub curvature: f64,
}

/// What the cost map concluded about one cell.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CellAssessment {
    /// A cell of the window has no observation or lies off the map: cost 1.
    Unknown,
    /// The window's heights span `height_range` > `max_step_height`: cost 1.
    Step { height_range: f64 },
    /// The cell lies `drop` > `max_step_height` below the highest cell around it: cost 1.
    Gap { drop: f64 },
    /// Features and their weighted cost in `[0, 1]`.
    Scored { features: CellFeatures, cost: f64 },
}

impl CellAssessment {
    /// The terrain cost `c_t` in `[0, 1]`, 1 for forbidden cells.
    pub fn cost(&self) -> f64 {
        match self {
            CellAssessment::Scored { cost, .. } => *cost,
            _ => 1.0,
        }
    }
    /// Whether the cell is forbidden by a hard rule (unknown, step or gap).
    pub fn is_forbidden(&self) -> bool {
        !matches!(self, CellAssessment::Scored { .. })
    }
}

/// The least-squares plane and quadratic over the feature window as fixed linear filters:
/// `coefficient = sum_k filter[k] * h_k`, the rows of `(A^T A)^-1 A^T` for the design matrix
/// `A = [1, x, y, x^2, x y, y^2]` of the window's cell offsets (m).
#[derive(Clone, Debug)]
pub(crate) struct WindowFit {
    radius: usize,
    /// Filters for `b, c, d, e, f` (the constant `a` is not needed), row-major over the
    /// window: index `(dj + R) * (2R + 1) + (di + R)`.
    filters: [Vec<f64>; 5],
}

impl WindowFit {
    pub(crate) fn new(radius: usize, resolution: f64) -> Self {
        let side = 2 * radius + 1;
        let m = side * side;
        let offset = |k: usize| (k as f64 - radius as f64) * resolution;
        let design = DMatrix::from_fn(m, 6, |row, col| {
            let (x, y) = (offset(row % side), offset(row / side));
            [1.0, x, y, x * x, x * y, y * y][col]
        });
        let normal: SMatrix<f64, 6, 6> = (design.transpose() * &design).fixed_view::<6, 6>(0, 0).into_owned();
        // Full rank for any R >= 1 (three distinct offsets per axis); the inverse of a
        // well-conditioned 6 x 6 (the offsets are a few cells) cannot fail.
        let inverse = normal.try_inverse().unwrap_or_else(SMatrix::zeros);
        let pseudo_inverse =
            DMatrix::from_fn(6, m, |row, col| (0..6).map(|k| inverse[(row, k)] * design[(col, k)]).sum());
        let filter = |row: usize| (0..m).map(|col| pseudo_inverse[(row, col)]).collect::<Vec<f64>>();
        Self { radius, filters: [filter(1), filter(2), filter(3), filter(4), filter(5)] }
    }
}

/// A read-only view of the map's grid for [`assess_cell`]: row-major, `index = j * columns + i`.
#[derive(Clone, Copy)]
pub(crate) struct GridView<'a> {
    pub heights: &'a [f64],
    pub observations: &'a [u32],
    pub columns: usize,
    pub rows: usize,
}

/// The features and cost of cell `(i, j)` (module documentation above). Depends only on the
/// cells within `max(R, gap_radius_cells)` of `(i, j)`: that is what makes the local
/// recompute exact. Allocates nothing.
pub(crate) fn assess_cell(grid: GridView, fit: &WindowFit, params: &CostParams, i: usize, j: usize) -> CellAssessment {
    let r = fit.radius;
    if i < r || j < r || i + r >= grid.columns || j + r >= grid.rows {
        return CellAssessment::Unknown;
    }
    let side = 2 * r + 1;
    // First pass: every window cell known, the mean and the range of the heights.
    let (mut sum, mut lowest, mut highest) = (0.0, f64::INFINITY, f64::NEG_INFINITY);
    for jj in j - r..=j + r {
        let row = jj * grid.columns;
        for ii in i - r..=i + r {
            if grid.observations[row + ii] == 0 {
                return CellAssessment::Unknown;
            }
            let h = grid.heights[row + ii];
            sum += h;
            lowest = lowest.min(h);
            highest = highest.max(h);
        }
    }
    if highest - lowest > params.max_step_height {
        return CellAssessment::Step { height_range: highest - lowest };
    }
    let here = grid.heights[j * grid.columns + i];
    if let Some(drop) = drop_below_surroundings(grid, params.gap_radius_cells, i, j, here) {
        if drop > params.max_step_height {
            return CellAssessment::Gap { drop };
        }
    }
    // Second pass: the spread about the mean and the fit coefficients.
    let mean = sum / (side * side) as f64;
    let (mut spread, mut coefficients) = (0.0, [0.0; 5]);
    for (wj, jj) in (j - r..=j + r).enumerate() {
        let row = jj * grid.columns;
        for (wi, ii) in (i - r..=i + r).enumerate() {
            let h = grid.heights[row + ii];
            spread += (h - mean) * (h - mean);
            let k = wj * side + wi;
            for (c, filter) in coefficients.iter_mut().zip(&fit.filters) {
                *c += filter[k] * h;
            }
        }
    }
    let [b, c, d, e, f] = coefficients;
    let features = CellFeatures {
        height_std: (spread / (side * side) as f64).sqrt(),
        slope: b.hypot(c).atan(),
        curvature: (d + f).abs() + (d - f).hypot(e),
    };
    CellAssessment::Scored { features, cost: params.cost_of(&features) }
}

/// How far `here` lies below the highest known cell within `radius` cells along x and y of
/// `(i, j)` (clipped to the map); `None` when the gap rule is off.
fn drop_below_surroundings(grid: GridView, radius: usize, i: usize, j: usize, here: f64) -> Option<f64> {
    if radius == 0 {
        return None;
    }
    let mut highest = here;
    for jj in j.saturating_sub(radius)..=(j + radius).min(grid.rows - 1) {
        let row = jj * grid.columns;
        for ii in i.saturating_sub(radius)..=(i + radius).min(grid.columns - 1) {
            if grid.observations[row + ii] > 0 {
                highest = highest.max(grid.heights[row + ii]);
            }
        }
    }
    Some(highest - here)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 21 x 21 grid of `h(x, y)` at cell offsets (m) from its centre cell (10, 10).
    fn grid_of(resolution: f64, h: impl Fn(f64, f64) -> f64) -> (Vec<f64>, Vec<u32>) {
        let n = 21;
        let heights =
            (0..n * n).map(|k| h(((k % n) as f64 - 10.0) * resolution, ((k / n) as f64 - 10.0) * resolution)).collect();
        (heights, vec![1; n * n])
    }

    fn assess(heights: &[f64], observations: &[u32], params: &CostParams, i: usize, j: usize) -> CellAssessment {
        let fit = WindowFit::new(params.window_radius_cells, 0.04);
        assess_cell(GridView { heights, observations, columns: 21, rows: 21 }, &fit, params, i, j)
    }

    #[test]
    fn window_fit_is_exact_on_quadratics() {
        // z = 0.3 + 0.2 x - 0.1 y + 1.5 x^2 - 0.7 x y + 2.5 y^2: the filters return the
        // coefficients exactly (least squares on data the model fits exactly).
        for radius in 1..=MAX_WINDOW_RADIUS_CELLS {
            let fit = WindowFit::new(radius, 0.04);
            let side = 2 * radius + 1;
            let z = |x: f64, y: f64| 0.3 + 0.2 * x - 0.1 * y + 1.5 * x * x - 0.7 * x * y + 2.5 * y * y;
            let heights: Vec<f64> = (0..side * side)
                .map(|k| z(((k % side) as f64 - radius as f64) * 0.04, ((k / side) as f64 - radius as f64) * 0.04))
                .collect();
            let coefficient = |f: &Vec<f64>| f.iter().zip(&heights).map(|(w, h)| w * h).sum::<f64>();
            let got: Vec<f64> = fit.filters.iter().map(coefficient).collect();
            for (g, want) in got.iter().zip([0.2, -0.1, 1.5, -0.7, 2.5]) {
                assert!((g - want).abs() < 1e-9, "radius {radius}: {got:?}");
            }
        }
    }

    #[test]
    fn features_of_a_tilted_plane_and_a_paraboloid_match_closed_forms() {
        let params = CostParams::default();
        // Plane z = 0.3 x + 0.1 y: slope atan(|grad|), zero curvature, and the window's
        // height spread: offsets k r for k in -2..=2 have variance 2 r^2 along each axis, so
        // var(z) = 2 r^2 (0.3^2 + 0.1^2).
        let (h, known) = grid_of(0.04, |x, y| 0.3 * x + 0.1 * y);
        let CellAssessment::Scored { features, cost } = assess(&h, &known, &params, 10, 10) else { panic!() };
        assert!((features.slope - 0.1f64.sqrt().atan()).abs() < 1e-12);
        assert!((features.height_std - 0.04 * (2.0 * 0.1f64).sqrt()).abs() < 1e-12);
        assert!(features.curvature.abs() < 1e-9);
        let expected = (0.3 * (0.04 * 0.2f64.sqrt() / 0.05) + 0.4 * (0.1f64.sqrt().atan() / 0.5)) / 1.0;
        assert!((cost - expected).abs() < 1e-10, "{cost} vs {expected}");
        // Paraboloid z = (k1 x^2 + k2 y^2) / 2: curvature max(|k1|, |k2|) at the apex.
        let (h, known) = grid_of(0.04, |x, y| 0.5 * (4.0 * x * x - 7.0 * y * y));
        let CellAssessment::Scored { features, .. } = assess(&h, &known, &params, 10, 10) else { panic!() };
        assert!((features.curvature - 7.0).abs() < 1e-9, "{features:?}");
        assert!(features.slope.abs() < 1e-12);
        // Rotated by 45 deg (z = k x y, principal curvatures +-k).
        let (h, known) = grid_of(0.04, |x, y| 3.0 * x * y);
        let CellAssessment::Scored { features, .. } = assess(&h, &known, &params, 10, 10) else { panic!() };
        assert!((features.curvature - 3.0).abs() < 1e-9, "{features:?}");
    }

    #[test]
    fn hard_rules_unknown_step_gap() {
        let params = CostParams::default();
        let (h, mut known) = grid_of(0.04, |_, _| 0.0);
        // An unknown cell two cells away is inside the 5 x 5 window; three away is not.
        known[10 * 21 + 12] = 0;
        assert_eq!(assess(&h, &known, &params, 10, 10), CellAssessment::Unknown);
        assert!(!assess(&h, &known, &params, 9, 10).is_forbidden());
        // The map's border: the window would leave the grid.
        assert_eq!(assess(&h, &known, &params, 1, 10), CellAssessment::Unknown);
        // A 0.25 m drop at x > 0.05: the window of cell 10 spans it (step); a floor cell
        // five cells into the low side sees the high side within 6 cells (gap).
        let (h, known) = grid_of(0.04, |x, _| if x > 0.05 { -0.25 } else { 0.0 });
        assert!(
            matches!(assess(&h, &known, &params, 10, 10), CellAssessment::Step { height_range } if (height_range - 0.25).abs() < 1e-12)
        );
        assert!(
            matches!(assess(&h, &known, &params, 17, 10), CellAssessment::Gap { drop } if (drop - 0.25).abs() < 1e-12)
        );
        // One cell further, the high side is 7 cells away: no longer a gap, flat floor.
        assert!(assess(&h, &known, &params, 18, 10).cost() < 1e-9);
        // 0.15 m (climbable) is no step and no gap.
        let (h, known) = grid_of(0.04, |x, _| if x > 0.05 { -0.15 } else { 0.0 });
        assert!(!assess(&h, &known, &params, 10, 10).is_forbidden());
        assert!(assess(&h, &known, &params, 17, 10).cost() < 1e-9);
    }

    #[test]
    fn validation_names_the_field() {
        let bad = |edit: fn(&mut CostParams)| {
            let mut p = CostParams::default();
            edit(&mut p);
            p.validate().unwrap_err().0
        };
        assert_eq!(bad(|p| p.window_radius_cells = 0), "cost.window_radius_cells");
        assert_eq!(bad(|p| p.weights.slope = f64::NAN), "cost.weights.slope");
        assert_eq!(bad(|p| p.weights = FeatureWeights { height_std: 0.0, slope: 0.0, curvature: 0.0 }), "cost.weights");
        assert_eq!(bad(|p| p.saturation.curvature = 0.0), "cost.saturation.curvature");
        assert_eq!(bad(|p| p.max_step_height = f64::INFINITY), "cost.max_step_height");
        assert_eq!(bad(|p| p.gap_radius_cells = 51), "cost.gap_radius_cells");
        assert!(CostParams::default().validate().is_ok());
    }
}
