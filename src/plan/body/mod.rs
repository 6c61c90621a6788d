//! The body action planner of Winkler 2015 sec. III-B: from the current body state
//! `s = (x, y, theta)` to a goal state, the sequence of motion primitives (eq. (1)) of least
//! accumulated action cost (eq. (2)), searched with ARA* over a lattice.
//!
//! * [`LatticeKey`]: states on a lattice anchored at the start pose, 4 cm cells (the
//!   paper's map resolution, "roughly the dimensions of the robot's foot") and 36 headings of
//!   10 deg; HyQ's crawl primitives in [`hyq_crawl_primitives`].
//! * [`ActionCost`]: the four terms of eq. (2) from a [`TerrainCostField`] and the robot's
//!   [`NominalStance`] (computed from the model's `standing` pose).
//! * [`BodyPlanner::plan`]: ARA* (anytime, every improved plan with its sub-optimality
//!   bound); [`BodyPlanner::plan_optimal`]: A*, the reference.
//!
//! ```
//! use legwork::plan::body::{BodyPlanner, BodyPlannerConfig, BodyPose};
//! use legwork::plan::{search::SearchLimits, TerrainCostField};
//!
//! /// Flat ground, every cell a perfect foothold.
//! struct Flat;
//! impl TerrainCostField for Flat {
//!     fn cost(&self, _x: f64, _y: f64) -> f64 { 0.0 }
//!     fn height(&self, _x: f64, _y: f64) -> f64 { 0.0 }
//!     fn resolution(&self) -> f64 { 0.04 }
//! }
//!
//! let model = legwork::model::embedded::load("hyq").unwrap();
//! let mut planner = BodyPlanner::for_model(&model, BodyPlannerConfig::default()).unwrap();
//! let start = BodyPose { x: 0.0, y: 0.0, yaw: 0.0 };
//! let goal = BodyPose { x: 1.0, y: 0.0, yaw: 0.0 };
//! let plans = planner.plan(&Flat, start, goal, &SearchLimits::none()).unwrap();
//! let best = plans.best();
//! // Two 0.44 m long strides and one 0.12 m short step reach x = 1.00, for a difficulty of
//! // 1.2 + 1.2 + 0.6 = 3.0 (two 0.36 m strides and a 0.24 m step, to 0.96, would cost 3.2).
//! assert_eq!(best.steps.len(), 3);
//! assert!((best.poses.last().unwrap().x - 1.0).abs() < 1e-9);
//! assert!((best.cost - 3.0).abs() < 1e-9);
//! assert_eq!(best.bound, 1.0);
//! ```

mod action_cost;
mod lattice;
mod space;
mod stance;
#[cfg(test)]
mod tests;

pub use action_cost::{ActionCost, ActionCostWeights, Foothold, StanceTerrain, MAX_BEST_CELLS};
pub use lattice::{hyq_crawl_primitives, wrap_angle, LatticeKey, MotionPrimitive};
pub use stance::NominalStance;

use crate::model::description::LEG_ORDER;
use crate::model::Model;
use crate::plan::search::{a_star, ara_star, AraStarConfig, AraStop, Limit, SearchError, SearchLimits, SearchWorkspace, Solution};
use crate::plan::TerrainCostField;
use action_cost::{NoFoothold, TerrainProbe};
use lattice::Lattice;
use space::{BodyLatticeSpace, GoalRegion, StanceCache};
use std::time::Duration;

/// A body state `s = (x, y, theta)` (m, m, rad).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BodyPose {
    pub x: f64,
    pub y: f64,
    pub yaw: f64,
}

/// Settings of the body planner (defaults in parentheses).
#[derive(Clone, Debug, PartialEq)]
pub struct BodyPlannerConfig {
    /// Lattice cell (0.04 m, the map's resolution in the paper).
    pub cell_size: f64,
    /// Headings per turn (36: 10 deg).
    pub headings: u16,
    /// The action set `A` ([`hyq_crawl_primitives`]).
    pub primitives: Vec<MotionPrimitive>,
    /// `w` of eq. (2).
    pub weights: ActionCostWeights,
    /// Radius of the cells searched around each nominal foothold (0.08 m: the footstep
    /// planner's search area; two cells of 4 cm).
    pub foothold_radius: f64,
    /// `n`, the best cells averaged per leg for `c_t_bar` (4, at most [`MAX_BEST_CELLS`]).
    pub best_cells: usize,
    /// Swing rise that counts as `c_pc = 1` (0.10 m, about a swing's clearance).
    pub swing_rise_scale: f64,
    /// Footprint-plane tilt that counts as `c_po = 1` (20 deg).
    pub tilt_scale: f64,
    /// Goal region: distance (0.05 m) and yaw (10 deg) from the goal pose.
    pub goal_position_tolerance: f64,
    pub goal_yaw_tolerance: f64,
    /// ARA*'s inflation schedule (3 down to 1 by 0.5).
    pub search: AraStarConfig,
}

impl Default for BodyPlannerConfig {
    fn default() -> Self {
        Self {
            cell_size: 0.04,
            headings: 36,
            primitives: hyq_crawl_primitives(),
            weights: ActionCostWeights::default(),
            foothold_radius: 0.08,
            best_cells: 4,
            swing_rise_scale: 0.10,
            tilt_scale: 20f64.to_radians(),
            goal_position_tolerance: 0.05,
            goal_yaw_tolerance: 10f64.to_radians(),
            search: AraStarConfig::default(),
        }
    }
}

/// Why the body planner returned no plan; each names what was wrong.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum BodyPlanError {
    #[error("body planner settings: `{field}`: {problem}")]
    InvalidConfig { field: String, problem: String },
    #[error("nominal stance: {0}")]
    InvalidStance(String),
    #[error("terrain cost field: resolution {0} (expected finite and > 0)")]
    InvalidFieldResolution(f64),
    #[error("{which} pose: `{field}` = {value} (expected a finite number)")]
    InvalidPose { which: &'static str, field: &'static str, value: f64 },
    #[error("start pose is on forbidden terrain: leg {leg} has no usable cell within the foothold radius of ({x:.3}, {y:.3})")]
    StartForbidden { leg: &'static str, x: f64, y: f64 },
    #[error("goal pose is on forbidden terrain: leg {leg} has no usable cell within the foothold radius of ({x:.3}, {y:.3})")]
    GoalForbidden { leg: &'static str, x: f64, y: f64 },
    #[error("leg {leg} has no usable cell within the foothold radius of ({x:.3}, {y:.3})")]
    NoFoothold { leg: &'static str, x: f64, y: f64 },
    #[error("the ground under a swing of action {primitive} is unknown (height not finite)")]
    UnknownSwingGround { primitive: usize },
    #[error("no body path to the goal: every reachable lattice state was expanded ({expansions} expansions)")]
    NoPath { expansions: usize },
    #[error("no body path found before the {limit:?} limit ({expansions} expansions)")]
    NoPlanWithinLimits { limit: Limit, expansions: usize },
    #[error("search: {0}")]
    Search(SearchError),
}

impl From<SearchError> for BodyPlanError {
    fn from(e: SearchError) -> Self {
        match e {
            SearchError::NoPath { expansions } => BodyPlanError::NoPath { expansions },
            SearchError::LimitBeforeFirstSolution { limit, expansions } => BodyPlanError::NoPlanWithinLimits { limit, expansions },
            other => BodyPlanError::Search(other),
        }
    }
}

/// One action of a plan.
#[derive(Clone, Debug, PartialEq)]
pub struct BodyStep {
    /// Index into the planner's primitives.
    pub primitive: usize,
    pub from: BodyPose,
    pub to: BodyPose,
    /// Eq. (2), term by term.
    pub cost: ActionCost,
    /// The cheapest cell around each leg's nominal foothold after the action (LF, RF, LH,
    /// RH), where the footstep planner may start its search.
    pub footholds: [Foothold; 4],
}

/// A sequence of body actions from the start to the goal region.
#[derive(Clone, Debug, PartialEq)]
pub struct BodyPlan {
    /// Start first, then the pose after each step.
    pub poses: Vec<BodyPose>,
    pub steps: Vec<BodyStep>,
    /// Sum of the steps' `cost.total`.
    pub cost: f64,
    /// Heuristic inflation this plan was found with (1 for A*).
    pub epsilon: f64,
    /// `cost <= bound * optimal cost` on this lattice.
    pub bound: f64,
    /// Expansions and time from the start of the query until this plan was found.
    pub expansions: usize,
    pub elapsed: Duration,
}

/// Every plan ARA* published (bounds decreasing) and why it stopped.
#[derive(Clone, Debug, PartialEq)]
pub struct AnytimeBodyPlan {
    /// Never empty.
    pub plans: Vec<BodyPlan>,
    pub stop: AraStop,
    pub expansions: usize,
    pub elapsed: Duration,
}

impl AnytimeBodyPlan {
    /// The cheapest plan (the latest among equals).
    pub fn best(&self) -> &BodyPlan {
        let mut best = &self.plans[0];
        for plan in &self.plans[1..] {
            if plan.cost <= best.cost {
                best = plan;
            }
        }
        best
    }
}

/// The body action planner with its reusable memory (search workspace, per-state terrain
/// cache, lattice tables): keep one and call [`plan`](Self::plan) again to re-plan.
pub struct BodyPlanner {
    config: BodyPlannerConfig,
    stance: NominalStance,
    probe: TerrainProbe,
    lattice: Lattice,
    workspace: SearchWorkspace<LatticeKey, usize>,
    cache: StanceCache,
}

impl BodyPlanner {
    /// Checks the settings and the stance.
    pub fn new(config: BodyPlannerConfig, stance: NominalStance) -> Result<Self, BodyPlanError> {
        validate(&config)?;
        let plane_rows = stance
            .plane_fit_rows()
            .ok_or_else(|| BodyPlanError::InvalidStance("the four feet lie on one line: no plane fits them".into()))?;
        let probe = TerrainProbe::new(stance, plane_rows, config.best_cells);
        let mut lattice = Lattice::new(config.cell_size, config.headings);
        lattice.anchor(BodyPose { x: 0.0, y: 0.0, yaw: 0.0 }, &config.primitives);
        let (per_metre, per_radian) = GoalRegion::rates(&lattice, &config.primitives, &config.weights);
        if !per_metre.is_finite() {
            return Err(invalid("primitives".into(), "expected at least one primitive that translates the body".into()));
        }
        if config.headings > 1 && !per_radian.is_finite() {
            return Err(invalid("primitives".into(), "expected at least one primitive that turns the body".into()));
        }
        let workspace = SearchWorkspace::new();
        let cache = StanceCache::default();
        Ok(Self { config, stance, probe, lattice, workspace, cache })
    }

    /// A planner with `model`'s nominal stance ([`NominalStance::from_model`]).
    pub fn for_model(model: &Model, config: BodyPlannerConfig) -> Result<Self, BodyPlanError> {
        Self::new(config, NominalStance::from_model(model)?)
    }

    pub fn config(&self) -> &BodyPlannerConfig {
        &self.config
    }

    pub fn stance(&self) -> &NominalStance {
        &self.stance
    }

    /// Lattice states generated by the last query.
    pub fn generated_states(&self) -> usize {
        self.workspace.generated()
    }

    /// The terrain under a body pose: `c_t_bar`, the footprint tilt and each leg's best
    /// foothold, or the leg that has none.
    pub fn stance_terrain<F: TerrainCostField + ?Sized>(&mut self, field: &F, pose: BodyPose) -> Result<StanceTerrain, BodyPlanError> {
        self.prepare_probe(field)?;
        self.probe.stance_terrain(field, &pose).map_err(|e| BodyPlanError::NoFoothold { leg: LEG_ORDER[e.leg], x: e.x, y: e.y })
    }

    /// Eq. (2) for one action from `from` (to the lattice end of `primitive`, anchored at
    /// `from`), term by term; for re-checking a plan on an updated map. Errors when a leg has
    /// no foothold after the action or the ground under a swing is unknown.
    pub fn action_cost<F: TerrainCostField + ?Sized>(
        &mut self,
        field: &F,
        from: BodyPose,
        primitive: usize,
    ) -> Result<ActionCost, BodyPlanError> {
        check_pose("from", &from)?;
        if primitive >= self.config.primitives.len() {
            return Err(invalid("primitive".into(), format!("{primitive} (the planner has {} primitives)", self.config.primitives.len())));
        }
        self.prepare_probe(field)?;
        self.lattice.anchor(from, &self.config.primitives);
        let to = self.lattice.pose(self.lattice.successor(LatticeKey { ix: 0, iy: 0, heading: 0 }, primitive));
        let no_foothold = |e: NoFoothold| BodyPlanError::NoFoothold { leg: LEG_ORDER[e.leg], x: e.x, y: e.y };
        let before = self.probe.stance_terrain(field, &from).map_err(no_foothold)?;
        let after = self.probe.stance_terrain(field, &to).map_err(no_foothold)?;
        let rise = self.probe.swing_rise(field, &before, &after).ok_or(BodyPlanError::UnknownSwingGround { primitive })?;
        Ok(ActionCost::of_action(&self.config, primitive, &after, rise))
    }

    /// Anytime plan (ARA*) from `start` to within the goal tolerance of `goal`: every plan
    /// found while `limits` allow, each at most `bound` times the optimal cost on the lattice.
    pub fn plan<F: TerrainCostField + ?Sized>(
        &mut self,
        field: &F,
        start: BodyPose,
        goal: BodyPose,
        limits: &SearchLimits,
    ) -> Result<AnytimeBodyPlan, BodyPlanError> {
        let search = self.config.search;
        self.query(field, start, goal, |space, start_key, workspace| {
            let result = ara_star(space, start_key, &search, limits, workspace)?;
            let plans = result.solutions.iter().map(|s| to_body_plan(space, s)).collect();
            Ok(AnytimeBodyPlan { plans, stop: result.stop, expansions: result.expansions, elapsed: result.elapsed })
        })
    }

    /// The optimal plan on the lattice (A*), the reference for [`plan`](Self::plan).
    pub fn plan_optimal<F: TerrainCostField + ?Sized>(
        &mut self,
        field: &F,
        start: BodyPose,
        goal: BodyPose,
        limits: &SearchLimits,
    ) -> Result<BodyPlan, BodyPlanError> {
        self.query(field, start, goal, |space, start_key, workspace| {
            let solution = a_star(space, start_key, limits, workspace)?;
            Ok(to_body_plan(space, &solution))
        })
    }

    fn prepare_probe<F: TerrainCostField + ?Sized>(&mut self, field: &F) -> Result<(), BodyPlanError> {
        let resolution = field.resolution();
        if !(resolution.is_finite() && resolution > 0.0) {
            return Err(BodyPlanError::InvalidFieldResolution(resolution));
        }
        self.probe.prepare(resolution, self.config.foothold_radius);
        Ok(())
    }

    /// The checks and set-up shared by both searches: poses finite, start and goal on usable
    /// terrain, lattice anchored at the start, terrain cache emptied (the map may have
    /// changed since the last query).
    fn query<F, R>(
        &mut self,
        field: &F,
        start: BodyPose,
        goal: BodyPose,
        search: impl FnOnce(&mut BodyLatticeSpace<'_, F>, LatticeKey, &mut SearchWorkspace<LatticeKey, usize>) -> Result<R, SearchError>,
    ) -> Result<R, BodyPlanError>
    where
        F: TerrainCostField + ?Sized,
    {
        check_pose("start", &start)?;
        check_pose("goal", &goal)?;
        self.prepare_probe(field)?;
        let at = |e: NoFoothold| (LEG_ORDER[e.leg], e.x, e.y);
        if let Err(e) = self.probe.stance_terrain(field, &start) {
            let (leg, x, y) = at(e);
            return Err(BodyPlanError::StartForbidden { leg, x, y });
        }
        if let Err(e) = self.probe.stance_terrain(field, &goal) {
            let (leg, x, y) = at(e);
            return Err(BodyPlanError::GoalForbidden { leg, x, y });
        }
        self.lattice.anchor(start, &self.config.primitives);
        self.cache.clear();
        let (cost_per_metre, cost_per_radian) = GoalRegion::rates(&self.lattice, &self.config.primitives, &self.config.weights);
        let goal = GoalRegion {
            pose: goal,
            position_tolerance: self.config.goal_position_tolerance,
            yaw_tolerance: self.config.goal_yaw_tolerance,
            cost_per_metre,
            // One heading: the yaw never changes, so it cannot be asked for.
            cost_per_radian: if cost_per_radian.is_finite() { cost_per_radian } else { 0.0 },
        };
        let mut space =
            BodyLatticeSpace { field, lattice: &self.lattice, probe: &self.probe, config: &self.config, goal, cache: &mut self.cache };
        let start_key = LatticeKey { ix: 0, iy: 0, heading: 0 };
        Ok(search(&mut space, start_key, &mut self.workspace)?)
    }
}

/// A search path as body poses and steps with their cost terms (re-evaluated from the
/// cache, the same numbers the search summed).
fn to_body_plan<F: TerrainCostField + ?Sized>(space: &mut BodyLatticeSpace<'_, F>, solution: &Solution<LatticeKey, usize>) -> BodyPlan {
    let poses: Vec<BodyPose> = solution.states.iter().map(|&k| space.lattice.pose(k)).collect();
    let mut steps = Vec::with_capacity(solution.actions.len());
    for (i, &primitive) in solution.actions.iter().enumerate() {
        let (from, to) = (solution.states[i], solution.states[i + 1]);
        // Unreachable `else`: both states were evaluated and found usable (and cached) when
        // the search took this edge, and the swing check is deterministic.
        let (Some(before), Some(after)) = (space.stance_terrain(from), space.stance_terrain(to)) else { continue };
        let Some(cost) = space.action_cost(primitive, &before, &after) else { continue };
        steps.push(BodyStep { primitive, from: poses[i], to: poses[i + 1], cost, footholds: after.footholds });
    }
    BodyPlan {
        poses,
        steps,
        cost: solution.cost,
        epsilon: solution.epsilon,
        bound: solution.bound,
        expansions: solution.expansions,
        elapsed: solution.elapsed,
    }
}

fn check_pose(which: &'static str, pose: &BodyPose) -> Result<(), BodyPlanError> {
    for (field, value) in [("x", pose.x), ("y", pose.y), ("yaw", pose.yaw)] {
        if !value.is_finite() {
            return Err(BodyPlanError::InvalidPose { which, field, value });
        }
    }
    Ok(())
}

fn invalid(field: String, problem: String) -> BodyPlanError {
    BodyPlanError::InvalidConfig { field, problem }
}

fn validate(config: &BodyPlannerConfig) -> Result<(), BodyPlanError> {
    let positive = |field: &str, value: f64| {
        if value.is_finite() && value > 0.0 {
            Ok(())
        } else {
            Err(invalid(field.into(), format!("{value} (expected finite and > 0)")))
        }
    };
    let non_negative = |field: &str, value: f64| {
        if value.is_finite() && value >= 0.0 {
            Ok(())
        } else {
            Err(invalid(field.into(), format!("{value} (expected finite and >= 0)")))
        }
    };
    positive("cell_size", config.cell_size)?;
    if config.headings == 0 {
        return Err(invalid("headings".into(), "0 (expected at least 1)".into()));
    }
    let heading_step = 2.0 * std::f64::consts::PI / f64::from(config.headings);
    let w = &config.weights;
    non_negative("weights.terrain", w.terrain)?;
    positive("weights.difficulty", w.difficulty)?;
    non_negative("weights.swing_collision", w.swing_collision)?;
    non_negative("weights.orientation", w.orientation)?;
    non_negative("foothold_radius", config.foothold_radius)?;
    if !(1..=MAX_BEST_CELLS).contains(&config.best_cells) {
        return Err(invalid("best_cells".into(), format!("{} (expected 1 to {MAX_BEST_CELLS})", config.best_cells)));
    }
    positive("swing_rise_scale", config.swing_rise_scale)?;
    positive("tilt_scale", config.tilt_scale)?;
    // The goal region must hold a lattice point whatever the goal: a cell's half-diagonal,
    // half a heading step.
    let least_position = config.cell_size * std::f64::consts::FRAC_1_SQRT_2;
    if !(config.goal_position_tolerance.is_finite() && config.goal_position_tolerance >= least_position) {
        return Err(invalid(
            "goal_position_tolerance".into(),
            format!("{} (expected at least half a cell's diagonal, {least_position:.4} m)", config.goal_position_tolerance),
        ));
    }
    if !(config.goal_yaw_tolerance.is_finite() && config.goal_yaw_tolerance >= heading_step / 2.0) {
        return Err(invalid(
            "goal_yaw_tolerance".into(),
            format!("{} (expected at least half a heading step, {:.4} rad)", config.goal_yaw_tolerance, heading_step / 2.0),
        ));
    }
    config.search.validate().map_err(|e| match e {
        SearchError::InvalidConfig { field, problem } => invalid(format!("search.{field}"), problem),
        other => invalid("search".into(), other.to_string()),
    })?;
    if config.primitives.is_empty() {
        return Err(invalid("primitives".into(), "empty (expected at least one motion primitive)".into()));
    }
    for (p, primitive) in config.primitives.iter().enumerate() {
        let field = |name: &str| format!("primitives[{p}] ({}).{name}", primitive.name);
        for (name, value) in [("dx", primitive.dx), ("dy", primitive.dy), ("dyaw", primitive.dyaw)] {
            if !value.is_finite() {
                return Err(invalid(field(name), format!("{value} (expected a finite number)")));
            }
        }
        let turns = primitive.dyaw / heading_step;
        if (turns - turns.round()).abs() > 1e-6 {
            return Err(invalid(
                field("dyaw"),
                format!("{} rad (expected a multiple of the heading step {heading_step:.6} rad)", primitive.dyaw),
            ));
        }
        // At heading 0 the lattice step is (dx, dy) in cells: a length between two cells would
        // be rounded silently (0.42 m becomes 0.44 m on 4 cm cells).
        for (name, value) in [("dx", primitive.dx), ("dy", primitive.dy)] {
            let cells = value / config.cell_size;
            if (cells - cells.round()).abs() > 1e-6 {
                return Err(invalid(field(name), format!("{value} m (expected a multiple of the cell size {} m)", config.cell_size)));
            }
        }
        positive(&field("difficulty"), primitive.difficulty)?;
        // A move of at least one cell ends in another cell at every heading (rounding both
        // components to zero needs a length below half a cell's diagonal); shorter moves
        // would be lost or kept depending on the heading.
        let length = primitive.dx.hypot(primitive.dy);
        let no_op = length == 0.0 && turns.round() == 0.0;
        if no_op || (length > 0.0 && length < config.cell_size) {
            return Err(invalid(
                format!("primitives[{p}] ({})", primitive.name),
                format!(
                    "moves {length} m, turns {} rad (expected a move of 0 or at least one cell, {} m, and not neither)",
                    primitive.dyaw, config.cell_size
                ),
            ));
        }
    }
    Ok(())
}
