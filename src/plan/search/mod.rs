//! Generic best-first graph search: plain A* (the reference) and ARA* (Likhachev, Gordon
//! and Thrun 2003, "ARA*: Anytime A* with provable bounds on sub-optimality"), the search
//! Winkler 2015 (sec. III-B) runs over the body-action graph.
//!
//! A problem is a [`SearchSpace`]: lattice keys as states, labelled edges with a cost, a
//! heuristic and a goal test. A space is one query: it holds its own goal, so a goal region
//! (a position and yaw tolerance around a continuous goal pose) needs no goal state, and
//! continuous states are discretised by the space into whatever key type it chooses (the
//! body planner's [`LatticeKey`](crate::plan::body::LatticeKey) is `(ix, iy, heading)`).
//!
//! Both searches run in a [`SearchWorkspace`] (node table, open heap, successor buffer)
//! that keeps its memory between queries: once its tables have grown to the problem's size,
//! expanding a state allocates nothing (only the returned paths are new vectors).
//!
//! * [`a_star`]: best-first on `f = g + h`, closed nodes re-opened when a cheaper path
//!   reaches them, so the result is optimal for any admissible `h`.
//! * [`ara_star`]: repeated `ImprovePath` with an inflated heuristic `epsilon * h`, epsilon
//!   lowered between runs and every run reusing the previous one's search effort; each run
//!   publishes a path whose cost is at most `bound * optimal` (`bound <= epsilon`). Its
//!   bound needs a consistent `h` (`h(s) <= c(s, s') + h(s')`, `h = 0` on goals).

mod a_star;
mod ara_star;
#[cfg(test)]
mod tests;

pub use a_star::a_star;
pub use ara_star::{ara_star, AnytimeResult, AraStarConfig, AraStop};

use std::cmp::Ordering;
use std::collections::{BinaryHeap, HashMap};
use std::fmt::Debug;
use std::hash::Hash;
use std::time::{Duration, Instant};

/// One outgoing edge of a state: where it leads, what it is (an action label, e.g. the
/// index of a motion primitive) and its cost (finite, `>= 0`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Edge<S, A> {
    pub to: S,
    pub action: A,
    pub cost: f64,
}

/// A search problem: a directed graph given implicitly by its successor function, a goal
/// test and a heuristic towards the goal.
pub trait SearchSpace {
    /// A node key: a lattice cell for a discretised continuous state. Two keys that compare
    /// equal are one node.
    type State: Copy + Eq + Hash + Debug;
    /// The label of an edge (returned with the path).
    type Action: Copy + Debug;

    /// Appends the edges leaving `state` to `out` (which the search has cleared). Costs must
    /// be finite and non-negative; an infeasible action is simply not appended. Takes
    /// `&mut self` so that a space can cache work shared between edges (the body planner
    /// caches each lattice state's foothold evaluation).
    fn successors(&mut self, state: &Self::State, out: &mut Vec<Edge<Self::State, Self::Action>>);

    /// A lower bound on the cost from `state` to the nearest goal: finite, `>= 0`, zero on
    /// goal states. A* needs it admissible; ARA*'s bound needs it consistent.
    fn heuristic(&self, state: &Self::State) -> f64;

    /// Whether `state` is a goal.
    fn is_goal(&self, state: &Self::State) -> bool;
}

/// When a search must stop, whatever it has found. Checked before every expansion.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SearchLimits {
    /// Wall-clock deadline.
    pub deadline: Option<Instant>,
    /// Maximum node expansions (over all of ARA*'s iterations together).
    pub max_expansions: Option<usize>,
}

impl SearchLimits {
    /// No limit: the search runs until it is done.
    pub fn none() -> Self {
        Self::default()
    }
    /// Stop `budget` from now.
    pub fn time(budget: Duration) -> Self {
        Self { deadline: Some(Instant::now() + budget), max_expansions: None }
    }
    /// Stop after `max` expansions.
    pub fn expansions(max: usize) -> Self {
        Self { deadline: None, max_expansions: Some(max) }
    }
}

/// Which limit stopped a search.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Limit {
    Deadline,
    Expansions,
}

/// A path from the start to a goal state.
#[derive(Clone, Debug, PartialEq)]
pub struct Solution<S, A> {
    /// Start first, goal last (`actions.len() + 1` states).
    pub states: Vec<S>,
    /// `actions[i]` leads from `states[i]` to `states[i + 1]`.
    pub actions: Vec<A>,
    /// `edge_costs[i]` is the cost of `actions[i]`.
    pub edge_costs: Vec<f64>,
    /// The sum of `edge_costs`.
    pub cost: f64,
    /// The heuristic inflation this path was found with (1 for A*).
    pub epsilon: f64,
    /// Proven sub-optimality: `cost <= bound * optimal cost` (ARA*'s `epsilon'`; 1 for A*).
    pub bound: f64,
    /// Expansions from the start of the query until this path was found.
    pub expansions: usize,
    /// Time from the start of the query until this path was found.
    pub elapsed: Duration,
}

/// Why a search returned no path.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SearchError {
    #[error("no path: every state reachable from the start was expanded ({expansions} expansions) and none is a goal")]
    NoPath { expansions: usize },
    #[error("the search stopped at its {limit:?} limit after {expansions} expansions, before reaching a goal")]
    LimitBeforeFirstSolution { limit: Limit, expansions: usize },
    #[error("edge {from} -> {to}: cost {cost} (expected finite and >= 0)")]
    InvalidEdgeCost { from: String, to: String, cost: f64 },
    #[error("heuristic at {state}: {value} (expected finite and >= 0)")]
    InvalidHeuristic { state: String, value: f64 },
    #[error("search settings: `{field}`: {problem}")]
    InvalidConfig { field: &'static str, problem: String },
    #[error("more than {max} states were generated (node indices are 32-bit)")]
    TooManyStates { max: usize },
}

/// Index of a node in the workspace's table.
type NodeId = u32;
const NO_PARENT: NodeId = NodeId::MAX;

/// Book-keeping of one generated state.
#[derive(Clone, Debug)]
struct Node<S, A> {
    state: S,
    /// Cost of the best path found so far.
    g: f64,
    /// Heuristic, evaluated once when the node is generated.
    h: f64,
    /// Predecessor on that path, the edge's label and cost.
    parent: NodeId,
    action: Option<A>,
    edge_cost: f64,
    /// The iteration in which the node was last expanded (0: never). A node is in CLOSED
    /// when this equals the current iteration, so emptying CLOSED is `iteration += 1`.
    closed_in: u32,
    in_open: bool,
    /// In ARA*'s INCONS list: improved while in CLOSED, waiting for the next iteration.
    in_incons: bool,
    /// The space's goal test, evaluated once.
    is_goal: bool,
}

/// An entry of the open heap. Entries are not removed when a node's `g` improves; a new one
/// is pushed and the old one is skipped when it surfaces (its `g` no longer matches).
/// Keys and `g` are non-negative (validated costs and heuristic, `epsilon >= 1`), so they
/// are stored as their bit patterns, which order like the numbers and compare faster.
#[derive(Clone, Copy, Debug)]
struct OpenEntry {
    key: u64,
    g: u64,
    node: NodeId,
}

/// The bit pattern of a non-negative float (`-0.0` taken as `+0.0`), ordered like the float.
fn order_bits(x: f64) -> u64 {
    (x + 0.0).to_bits()
}

impl PartialEq for OpenEntry {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}
impl Eq for OpenEntry {}
impl PartialOrd for OpenEntry {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for OpenEntry {
    /// `BinaryHeap` is a max-heap: the smallest key is the greatest entry. Among equal keys
    /// the larger `g` (the deeper node, nearer the goal) first, then the lower node id, so
    /// the expansion order is deterministic.
    fn cmp(&self, other: &Self) -> Ordering {
        other.key.cmp(&self.key).then(self.g.cmp(&other.g)).then(other.node.cmp(&self.node))
    }
}

/// Memory shared by successive searches: the node table and its index, the open heap and
/// the successor buffer (OPEN, CLOSED and INCONS membership are flags on the nodes). [`a_star`] and [`ara_star`] clear it at the start
/// of a query and keep the capacity.
pub struct SearchWorkspace<S, A> {
    index: HashMap<S, NodeId, foldhash::fast::FixedState>,
    nodes: Vec<Node<S, A>>,
    open: BinaryHeap<OpenEntry>,
    successors: Vec<Edge<S, A>>,
    expansions: usize,
}

impl<S: Copy + Eq + Hash + Debug, A: Copy + Debug> Default for SearchWorkspace<S, A> {
    fn default() -> Self {
        Self::new()
    }
}

impl<S: Copy + Eq + Hash + Debug, A: Copy + Debug> SearchWorkspace<S, A> {
    pub fn new() -> Self {
        Self {
            index: HashMap::with_hasher(foldhash::fast::FixedState::default()),
            nodes: Vec::new(),
            open: BinaryHeap::new(),
            successors: Vec::new(),
            expansions: 0,
        }
    }

    /// States generated by the last query.
    pub fn generated(&self) -> usize {
        self.nodes.len()
    }

    /// Expansions of the last query.
    pub fn expansions(&self) -> usize {
        self.expansions
    }

    fn clear(&mut self) {
        self.index.clear();
        self.nodes.clear();
        self.open.clear();
        self.successors.clear();
        self.expansions = 0;
    }

    /// The node of `state`, generated (with `g = inf` and its heuristic) if new.
    fn node_of<P>(&mut self, space: &P, state: S) -> Result<NodeId, SearchError>
    where
        P: SearchSpace<State = S, Action = A> + ?Sized,
    {
        if let Some(&id) = self.index.get(&state) {
            return Ok(id);
        }
        let h = space.heuristic(&state);
        if !(h.is_finite() && h >= 0.0) {
            return Err(SearchError::InvalidHeuristic { state: format!("{state:?}"), value: h });
        }
        let id = NodeId::try_from(self.nodes.len())
            .ok()
            .filter(|&id| id != NO_PARENT)
            .ok_or(SearchError::TooManyStates { max: NO_PARENT as usize })?;
        self.nodes.push(Node {
            state,
            g: f64::INFINITY,
            h,
            parent: NO_PARENT,
            action: None,
            edge_cost: 0.0,
            closed_in: 0,
            in_open: false,
            in_incons: false,
            is_goal: space.is_goal(&state),
        });
        self.index.insert(state, id);
        Ok(id)
    }

    fn push_open(&mut self, id: NodeId, key: f64) {
        let node = &mut self.nodes[id as usize];
        node.in_open = true;
        self.open.push(OpenEntry { key: order_bits(key), g: order_bits(node.g), node: id });
    }

    /// Drops stale entries from the top of the heap and returns the live minimum.
    fn peek_open(&mut self) -> Option<OpenEntry> {
        while let Some(&top) = self.open.peek() {
            let node = &self.nodes[top.node as usize];
            if node.in_open && order_bits(node.g) == top.g {
                return Some(top);
            }
            self.open.pop();
        }
        None
    }

    /// Removes and returns the node of smallest key.
    fn pop_open(&mut self) -> Option<NodeId> {
        let top = self.peek_open()?;
        self.open.pop();
        self.nodes[top.node as usize].in_open = false;
        Some(top.node)
    }

    /// Fills the successor buffer of `id`'s state, checking every edge cost.
    fn expand_into_buffer<P>(&mut self, space: &mut P, id: NodeId) -> Result<(), SearchError>
    where
        P: SearchSpace<State = S, Action = A> + ?Sized,
    {
        self.expansions += 1;
        let state = self.nodes[id as usize].state;
        self.successors.clear();
        space.successors(&state, &mut self.successors);
        if let Some(bad) = self.successors.iter().find(|e| !(e.cost.is_finite() && e.cost >= 0.0)) {
            return Err(SearchError::InvalidEdgeCost { from: format!("{state:?}"), to: format!("{:?}", bad.to), cost: bad.cost });
        }
        Ok(())
    }

    /// Which limit, if any, is reached now.
    fn limit_reached(&self, limits: &SearchLimits) -> Option<Limit> {
        if limits.max_expansions.is_some_and(|max| self.expansions >= max) {
            return Some(Limit::Expansions);
        }
        if limits.deadline.is_some_and(|deadline| Instant::now() >= deadline) {
            return Some(Limit::Deadline);
        }
        None
    }

    /// The path to `goal` along the parent pointers. Following a parent strictly lowers `g`
    /// when costs are positive and never raises it, and the walk is bounded by the node count,
    /// so it ends even for zero-cost edges.
    fn path_to(&self, goal: NodeId, epsilon: f64, bound: f64, started: Instant) -> Solution<S, A> {
        let mut states = Vec::new();
        let mut actions = Vec::new();
        let mut edge_costs = Vec::new();
        let mut id = goal;
        loop {
            let node = &self.nodes[id as usize];
            states.push(node.state);
            if node.parent == NO_PARENT || states.len() > self.nodes.len() {
                break;
            }
            // A node with a parent always has the action that reached it.
            if let Some(action) = node.action {
                actions.push(action);
            }
            edge_costs.push(node.edge_cost);
            id = node.parent;
        }
        states.reverse();
        actions.reverse();
        edge_costs.reverse();
        let cost = edge_costs.iter().sum();
        Solution { states, actions, edge_costs, cost, epsilon, bound, expansions: self.expansions, elapsed: started.elapsed() }
    }
}
