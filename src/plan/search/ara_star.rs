//! ARA*, Anytime Repairing A* (Likhachev, Gordon and Thrun 2003, Fig. 3 and 4), the search
//! of Winkler 2015 sec. III-B: "ARA* initially runs an A* search with an inflated
//! heuristic, epsilon h(s), which quickly finds a first sequence of actions. [...] As long
//! as computational time is still available, ARA* repeatedly runs A* search, continuously
//! decreasing the inflation factor epsilon and thereby finding closer to optimal sequences."

use super::{Limit, NodeId, SearchError, SearchLimits, SearchSpace, SearchWorkspace, Solution};
use std::time::{Duration, Instant};

/// The inflation schedule (defaults in parentheses): `epsilon` starts at `initial_epsilon`
/// (3) and is lowered by `epsilon_step` (0.5) after each published path, down to
/// `final_epsilon` (1: the last run proves optimality).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AraStarConfig {
    pub initial_epsilon: f64,
    pub epsilon_step: f64,
    pub final_epsilon: f64,
}

impl Default for AraStarConfig {
    fn default() -> Self {
        Self { initial_epsilon: 3.0, epsilon_step: 0.5, final_epsilon: 1.0 }
    }
}

impl AraStarConfig {
    /// Checks `1 <= final_epsilon <= initial_epsilon` (finite) and `epsilon_step > 0`.
    pub fn validate(&self) -> Result<(), SearchError> {
        let bad = |field, problem: String| Err(SearchError::InvalidConfig { field, problem });
        if !(self.final_epsilon.is_finite() && self.final_epsilon >= 1.0) {
            return bad("final_epsilon", format!("{} (expected finite and >= 1)", self.final_epsilon));
        }
        if !(self.initial_epsilon.is_finite() && self.initial_epsilon >= self.final_epsilon) {
            return bad(
                "initial_epsilon",
                format!("{} (expected finite and >= final_epsilon {})", self.initial_epsilon, self.final_epsilon),
            );
        }
        if !(self.epsilon_step.is_finite() && self.epsilon_step > 0.0) {
            return bad("epsilon_step", format!("{} (expected finite and > 0)", self.epsilon_step));
        }
        Ok(())
    }
}

/// Why ARA* returned.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AraStop {
    /// The run at `final_epsilon` finished, or a path was proven within `final_epsilon` of
    /// optimal earlier (with `final_epsilon = 1`: the last path is optimal).
    Converged,
    /// The deadline or the expansion budget cut an improvement run short; the last
    /// published path stands.
    Limit(Limit),
}

/// Every path ARA* published, in order (bounds decreasing), and how it ended.
#[derive(Clone, Debug, PartialEq)]
pub struct AnytimeResult<S, A> {
    /// Never empty: without a first path ARA* returns an error.
    pub solutions: Vec<Solution<S, A>>,
    pub stop: AraStop,
    pub expansions: usize,
    pub elapsed: Duration,
}

impl<S, A> AnytimeResult<S, A> {
    /// The cheapest published path (the latest among equals, which has the tightest bound).
    pub fn best(&self) -> &Solution<S, A> {
        let mut best = &self.solutions[0];
        for solution in &self.solutions[1..] {
            if solution.cost <= best.cost {
                best = solution;
            }
        }
        best
    }
}

/// Anytime search from `start` to a goal of `space` (Likhachev 2003, Fig. 4 `Main`):
///
/// ```text
/// g(start) = 0; OPEN = {start}; epsilon = initial
/// loop:
///     ImprovePath(epsilon)                        // A* on g + epsilon h, no re-opening
///     epsilon' = min(epsilon, g(goal) / min_{s in OPEN u INCONS} (g(s) + h(s)))
///     publish the path to the goal with bound epsilon'
///     stop if epsilon' <= final or epsilon == final
///     epsilon = max(final, epsilon - step)
///     OPEN = OPEN u INCONS, keyed g + epsilon h; CLOSED = INCONS = {}
/// ```
///
/// A goal region is handled as a virtual goal state whose predecessors are the goal states
/// (edges of cost 0): `g(goal)` is the best `g` of an expanded goal state, and goal states
/// are not expanded further (no path through one goal state to another is cheaper).
///
/// With a consistent heuristic every published path costs at most `bound` times the
/// optimum (the paper's Theorem 2). Stops at `limits` with the paths published so far;
/// errors as [`super::a_star`], plus [`SearchError::InvalidConfig`].
pub fn ara_star<P>(
    space: &mut P,
    start: P::State,
    config: &AraStarConfig,
    limits: &SearchLimits,
    workspace: &mut SearchWorkspace<P::State, P::Action>,
) -> Result<AnytimeResult<P::State, P::Action>, SearchError>
where
    P: SearchSpace + ?Sized,
{
    config.validate()?;
    let started = Instant::now();
    let ws = workspace;
    ws.clear();
    let start_id = ws.node_of(space, start)?;
    let mut epsilon = config.initial_epsilon;
    ws.nodes[start_id as usize].g = 0.0;
    let start_key = epsilon * ws.nodes[start_id as usize].h;
    ws.push_open(start_id, start_key);

    let mut iteration = 1u32;
    let mut goal: Option<(NodeId, f64)> = None;
    let mut solutions = Vec::new();
    loop {
        if let Some(limit) = improve_path(space, ws, epsilon, iteration, &mut goal, limits)? {
            if solutions.is_empty() {
                return Err(SearchError::LimitBeforeFirstSolution { limit, expansions: ws.expansions });
            }
            return Ok(AnytimeResult { solutions, stop: AraStop::Limit(limit), expansions: ws.expansions, elapsed: started.elapsed() });
        }
        let Some((goal_id, goal_g)) = goal else {
            return Err(SearchError::NoPath { expansions: ws.expansions });
        };
        let bound = suboptimality_bound(ws, epsilon, goal_g);
        solutions.push(ws.path_to(goal_id, epsilon, bound, started));
        if bound <= config.final_epsilon || epsilon <= config.final_epsilon {
            return Ok(AnytimeResult { solutions, stop: AraStop::Converged, expansions: ws.expansions, elapsed: started.elapsed() });
        }
        epsilon = (epsilon - config.epsilon_step).max(config.final_epsilon);
        reopen_with_new_keys(ws, epsilon);
        // Emptying CLOSED: a node is closed when `closed_in == iteration`.
        iteration += 1;
    }
}

/// `ImprovePath` (Likhachev 2003, Fig. 3): expand states in order of `g + epsilon h` until
/// the goal's `g` is no greater than the smallest key in OPEN. A state whose `g` improves
/// after its expansion in this run goes to INCONS instead of back into OPEN, so no state is
/// expanded twice per run. Returns the limit that stopped it, if one did.
fn improve_path<P>(
    space: &mut P,
    ws: &mut SearchWorkspace<P::State, P::Action>,
    epsilon: f64,
    iteration: u32,
    goal: &mut Option<(NodeId, f64)>,
    limits: &SearchLimits,
) -> Result<Option<Limit>, SearchError>
where
    P: SearchSpace + ?Sized,
{
    while let Some(top) = ws.peek_open() {
        let goal_g = goal.map_or(f64::INFINITY, |(_, g)| g);
        if goal_g <= f64::from_bits(top.key) {
            break;
        }
        if let Some(limit) = ws.limit_reached(limits) {
            return Ok(Some(limit));
        }
        ws.pop_open();
        let id = top.node;
        let g = ws.nodes[id as usize].g;
        ws.nodes[id as usize].closed_in = iteration;
        if ws.nodes[id as usize].is_goal {
            // The virtual goal's only predecessors are goal states (edges of cost 0).
            if g < goal_g {
                *goal = Some((id, g));
            }
            continue;
        }
        ws.expand_into_buffer(space, id)?;
        for k in 0..ws.successors.len() {
            let edge = ws.successors[k];
            let to = ws.node_of(space, edge.to)?;
            let new_g = g + edge.cost;
            let node = &mut ws.nodes[to as usize];
            if new_g < node.g {
                node.g = new_g;
                node.parent = id;
                node.action = Some(edge.action);
                node.edge_cost = edge.cost;
                if node.closed_in != iteration {
                    let key = new_g + epsilon * node.h;
                    ws.push_open(to, key);
                } else {
                    node.in_incons = true;
                }
            }
        }
    }
    Ok(None)
}

/// `epsilon' = min(epsilon, g(goal) / min_{s in OPEN u INCONS} (g(s) + h(s)))` (Likhachev
/// 2003, Fig. 4 lines 06 and 13): every path not yet examined passes through a state of
/// OPEN or INCONS, whose `g + h` bounds its cost from below. With OPEN and INCONS empty the
/// whole reachable graph has been expanded and the path is optimal.
fn suboptimality_bound<S, A>(ws: &SearchWorkspace<S, A>, epsilon: f64, goal_g: f64) -> f64 {
    let lower = ws.nodes.iter().filter(|n| n.in_open || n.in_incons).map(|n| n.g + n.h).fold(f64::INFINITY, f64::min);
    if lower == f64::INFINITY {
        return 1.0;
    }
    if lower <= 0.0 {
        return epsilon;
    }
    // Rounding can put g(goal) a hair below a lower bound it attains; the bound is >= 1.
    (goal_g / lower).clamp(1.0, epsilon.max(1.0))
}

/// Moves INCONS into OPEN and keys every open state with the new `epsilon` (Likhachev 2003,
/// Fig. 4 lines 10-11).
fn reopen_with_new_keys<S, A>(ws: &mut SearchWorkspace<S, A>, epsilon: f64)
where
    S: Copy + Eq + std::hash::Hash + std::fmt::Debug,
    A: Copy + std::fmt::Debug,
{
    ws.open.clear();
    for id in 0..ws.nodes.len() {
        let node = &mut ws.nodes[id];
        if node.in_open || node.in_incons {
            node.in_incons = false;
            let key = node.g + epsilon * node.h;
            ws.push_open(id as NodeId, key);
        }
    }
}
