//! The body-action graph `G = (S, A)` of Winkler 2015 sec. III-B (Fig. 3) as a
//! [`SearchSpace`]: lattice states, one edge per feasible primitive, eq. (2) as edge cost.

use super::action_cost::{ActionCost, ActionCostWeights, StanceTerrain, TerrainProbe};
use super::lattice::{wrap_angle, Lattice, LatticeKey, MotionPrimitive};
use super::{BodyPlannerConfig, BodyPose};
use crate::plan::search::{Edge, SearchSpace};
use crate::plan::TerrainCostField;
use std::collections::HashMap;

/// Each lattice state's terrain evaluation, computed once per query: every state is the
/// target of up to one edge per primitive, and `c_t_bar` and `c_po` depend on the target only.
/// The hash table holds small entries (key and index); the evaluations lie in one vector.
#[derive(Default)]
pub(super) struct StanceCache {
    index: HashMap<LatticeKey, u32, foldhash::fast::FixedState>,
    terrains: Vec<StanceTerrain>,
}

/// Index of a state with no foothold for some leg.
const INFEASIBLE: u32 = u32::MAX;

impl StanceCache {
    pub fn clear(&mut self) {
        self.index.clear();
        self.terrains.clear();
    }
}

/// The goal region and the heuristic's rates.
#[derive(Clone, Copy, Debug)]
pub(super) struct GoalRegion {
    pub pose: BodyPose,
    pub position_tolerance: f64,
    pub yaw_tolerance: f64,
    /// Lower bound on the cost per metre of any primitive: `min_a w_a c_a / |d(a)|`, `|d(a)|`
    /// the largest translation of `a` over the headings.
    pub cost_per_metre: f64,
    /// Lower bound on the cost per radian of any turning primitive.
    pub cost_per_radian: f64,
}

impl GoalRegion {
    /// The rates of the heuristic for these primitives on this lattice. Every term of eq. (2)
    /// is non-negative, so an action costs at least `w_a c_a`; the terrain part is bounded
    /// below by zero since the map may hold zero-cost cells anywhere ahead.
    pub fn rates(lattice: &Lattice, primitives: &[MotionPrimitive], weights: &ActionCostWeights) -> (f64, f64) {
        let mut per_metre = f64::INFINITY;
        let mut per_radian = f64::INFINITY;
        for (p, primitive) in primitives.iter().enumerate() {
            let least_cost = weights.difficulty * primitive.difficulty;
            let translation = lattice.max_translation(p);
            if translation > 0.0 {
                per_metre = per_metre.min(least_cost / translation);
            }
            let turn = f64::from(lattice.step(0, p).dheading.unsigned_abs()) * lattice.heading_step();
            if turn > 0.0 {
                per_radian = per_radian.min(least_cost / turn);
            }
        }
        (per_metre, per_radian)
    }

    /// Position error beyond the tolerance (m) and yaw error beyond the tolerance (rad).
    fn remaining(&self, pose: &BodyPose) -> (f64, f64) {
        let (dx, dy) = (pose.x - self.pose.x, pose.y - self.pose.y);
        let distance = (dx * dx + dy * dy).sqrt();
        let yaw = wrap_angle(pose.yaw - self.pose.yaw).abs();
        ((distance - self.position_tolerance).max(0.0), (yaw - self.yaw_tolerance).max(0.0))
    }

    pub fn contains(&self, pose: &BodyPose) -> bool {
        self.remaining(pose) == (0.0, 0.0)
    }

    /// Winkler 2015 sec. III-B, `h(s) = c_bar F(|g - s|)`: the distance still to cover times
    /// the least cost per metre, and likewise for the yaw; the larger of the two. Each part
    /// changes along an action by at most what that action covers, which costs at least the
    /// rate times it, so `h` is consistent (and zero on the goal region).
    pub fn heuristic(&self, pose: &BodyPose) -> f64 {
        let (distance, yaw) = self.remaining(pose);
        let by_distance = if distance > 0.0 { self.cost_per_metre * distance } else { 0.0 };
        let by_yaw = if yaw > 0.0 { self.cost_per_radian * yaw } else { 0.0 };
        by_distance.max(by_yaw)
    }
}

/// One query's graph: the lattice, the map, the cost settings and the goal.
pub(super) struct BodyLatticeSpace<'a, F: ?Sized> {
    pub field: &'a F,
    pub lattice: &'a Lattice,
    pub probe: &'a TerrainProbe,
    pub config: &'a BodyPlannerConfig,
    pub goal: GoalRegion,
    pub cache: &'a mut StanceCache,
}

impl<F: TerrainCostField + ?Sized> BodyLatticeSpace<'_, F> {
    /// Where the terrain at a lattice state lies in the cache (evaluated on first use),
    /// `None` when a leg has no foothold there.
    fn cached(&mut self, key: LatticeKey) -> Option<usize> {
        let slot = match self.cache.index.get(&key) {
            Some(&slot) => slot,
            None => {
                let slot = match self.probe.stance_terrain(self.field, &self.lattice.pose(key)) {
                    // Fewer than 2^32 - 1 states fit in memory long before the index overflows.
                    Ok(terrain) if self.cache.terrains.len() < INFEASIBLE as usize => {
                        self.cache.terrains.push(terrain);
                        (self.cache.terrains.len() - 1) as u32
                    }
                    _ => INFEASIBLE,
                };
                self.cache.index.insert(key, slot);
                slot
            }
        };
        (slot != INFEASIBLE).then_some(slot as usize)
    }

    /// The terrain at a lattice state (cached), `None` when a leg has no foothold there.
    pub fn stance_terrain(&mut self, key: LatticeKey) -> Option<StanceTerrain> {
        self.cached(key).map(|slot| self.cache.terrains[slot])
    }

    /// Eq. (2) for `primitive` from a state with terrain `before` to one with terrain
    /// `after`; `None` when the ground under a swing is unknown.
    pub fn action_cost(&self, primitive: usize, before: &StanceTerrain, after: &StanceTerrain) -> Option<ActionCost> {
        let rise = self.probe.swing_rise(self.field, before, after)?;
        Some(ActionCost::of_action(self.config, primitive, after, rise))
    }
}

impl<F: TerrainCostField + ?Sized> SearchSpace for BodyLatticeSpace<'_, F> {
    type State = LatticeKey;
    type Action = usize;

    fn successors(&mut self, state: &LatticeKey, out: &mut Vec<Edge<LatticeKey, usize>>) {
        let Some(before) = self.cached(*state) else { return };
        for primitive in 0..self.config.primitives.len() {
            let to = self.lattice.successor(*state, primitive);
            let Some(after) = self.cached(to) else { continue };
            let terrains = &self.cache.terrains;
            if let Some(cost) = self.action_cost(primitive, &terrains[before], &terrains[after]) {
                out.push(Edge { to, action: primitive, cost: cost.total });
            }
        }
    }

    fn heuristic(&self, state: &LatticeKey) -> f64 {
        self.goal.heuristic(&self.lattice.pose(*state))
    }

    fn is_goal(&self, state: &LatticeKey) -> bool {
        self.goal.contains(&self.lattice.pose(*state))
    }
}
