//! A* and ARA* on seeded random grids (4- and 8-connected, random obstacles and cell costs),
//! against a dense Dijkstra written independently of the workspace.

use super::*;
use std::collections::BinaryHeap;

/// xorshift64*: deterministic U(0, 1).
struct Rng(u64);
impl Rng {
    fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    }
    fn below(&mut self, n: usize) -> usize {
        ((self.uniform() * n as f64) as usize).min(n - 1)
    }
}

const FOUR: [(i32, i32); 4] = [(1, 0), (0, 1), (-1, 0), (0, -1)];
const EIGHT: [(i32, i32); 8] = [(1, 0), (1, 1), (0, 1), (-1, 1), (-1, 0), (-1, -1), (0, -1), (1, -1)];

/// A grid whose cells are blocked (`None`) or have a cost in [1, 5]; a move costs its length
/// times the mean of the two cells' costs.
#[derive(Clone, Debug)]
struct Grid {
    width: i32,
    height: i32,
    cells: Vec<Option<f64>>,
    eight_connected: bool,
    start: (i32, i32),
    goal: (i32, i32),
    min_cell_cost: f64,
}

impl Grid {
    fn random(rng: &mut Rng) -> Grid {
        let width = 5 + rng.below(36) as i32;
        let height = 5 + rng.below(36) as i32;
        let density = 0.45 * rng.uniform();
        let eight_connected = rng.uniform() < 0.5;
        let mut cells: Vec<Option<f64>> =
            (0..width * height).map(|_| if rng.uniform() < density { None } else { Some(1.0 + 4.0 * rng.uniform()) }).collect();
        let free_cell = |rng: &mut Rng, cells: &mut Vec<Option<f64>>| {
            let (x, y) = (rng.below(width as usize) as i32, rng.below(height as usize) as i32);
            let i = (y * width + x) as usize;
            cells[i] = cells[i].or(Some(1.0 + 4.0 * rng.uniform()));
            (x, y)
        };
        let start = free_cell(rng, &mut cells);
        let goal = free_cell(rng, &mut cells);
        let min_cell_cost = cells.iter().flatten().copied().fold(f64::INFINITY, f64::min);
        Grid { width, height, cells, eight_connected, start, goal, min_cell_cost }
    }

    fn cell(&self, (x, y): (i32, i32)) -> Option<f64> {
        if x < 0 || y < 0 || x >= self.width || y >= self.height {
            return None;
        }
        self.cells[(y * self.width + x) as usize]
    }

    fn moves(&self) -> &'static [(i32, i32)] {
        if self.eight_connected {
            &EIGHT
        } else {
            &FOUR
        }
    }

    /// Octile (8-connected) or Manhattan (4-connected) distance times the cheapest cell:
    /// each move of length `l` costs at least `l * min_cell_cost` and changes this distance by
    /// at most `l`, so the heuristic is consistent.
    fn distance_heuristic(&self, (x, y): (i32, i32)) -> f64 {
        let (dx, dy) = ((x - self.goal.0).abs() as f64, (y - self.goal.1).abs() as f64);
        let distance = if self.eight_connected { dx.max(dy) + (2f64.sqrt() - 1.0) * dx.min(dy) } else { dx + dy };
        self.min_cell_cost * distance
    }

    /// Optimal cost from every cell to the goal (Dijkstra backwards; moves are symmetric).
    fn cost_to_goal(&self) -> Vec<f64> {
        let mut dist = vec![f64::INFINITY; self.cells.len()];
        let mut heap = BinaryHeap::new();
        let index = |(x, y): (i32, i32)| (y * self.width + x) as usize;
        dist[index(self.goal)] = 0.0;
        // Non-negative floats order like their bit patterns.
        heap.push(std::cmp::Reverse((0f64.to_bits(), self.goal)));
        while let Some(std::cmp::Reverse((d, s))) = heap.pop() {
            let d = f64::from_bits(d);
            if d > dist[index(s)] {
                continue;
            }
            let mut out = Vec::new();
            self.clone().successors(&s, &mut out);
            for e in out {
                let nd = d + e.cost;
                if nd < dist[index(e.to)] {
                    dist[index(e.to)] = nd;
                    heap.push(std::cmp::Reverse((nd.to_bits(), e.to)));
                }
            }
        }
        dist
    }

    fn optimal_cost(&self) -> f64 {
        self.cost_to_goal()[(self.start.1 * self.width + self.start.0) as usize]
    }
}

impl SearchSpace for Grid {
    type State = (i32, i32);
    type Action = u8;
    fn successors(&mut self, state: &(i32, i32), out: &mut Vec<Edge<(i32, i32), u8>>) {
        let Some(here) = self.cell(*state) else { return };
        for (k, &(dx, dy)) in self.moves().iter().enumerate() {
            let to = (state.0 + dx, state.1 + dy);
            if let Some(there) = self.cell(to) {
                let length = ((dx * dx + dy * dy) as f64).sqrt();
                out.push(Edge { to, action: k as u8, cost: length * 0.5 * (here + there) });
            }
        }
    }
    fn heuristic(&self, state: &(i32, i32)) -> f64 {
        self.distance_heuristic(*state)
    }
    fn is_goal(&self, state: &(i32, i32)) -> bool {
        *state == self.goal
    }
}

/// The path starts at the start, ends on the goal, every step is an edge of the grid with
/// the recorded action and cost, and the costs add up.
fn assert_valid_path(grid: &Grid, solution: &Solution<(i32, i32), u8>) {
    assert_eq!(solution.states.first(), Some(&grid.start));
    assert_eq!(solution.states.last(), Some(&grid.goal));
    assert_eq!(solution.actions.len() + 1, solution.states.len());
    assert_eq!(solution.edge_costs.len(), solution.actions.len());
    let mut total = 0.0;
    for i in 0..solution.actions.len() {
        let mut out = Vec::new();
        grid.clone().successors(&solution.states[i], &mut out);
        let edge = out.iter().find(|e| e.to == solution.states[i + 1]).expect("consecutive states are successors");
        assert_eq!(edge.action, solution.actions[i]);
        assert_eq!(edge.cost, solution.edge_costs[i]);
        total += edge.cost;
    }
    assert!((total - solution.cost).abs() <= 1e-9 * (1.0 + total), "{total} vs {}", solution.cost);
}

fn tolerance(cost: f64) -> f64 {
    1e-9 * (1.0 + cost)
}

#[test]
fn a_star_and_ara_star_at_epsilon_one_match_dijkstra_on_random_grids() {
    let mut rng = Rng(0x5eed_1234_abcd);
    let mut ws = SearchWorkspace::new();
    let (mut solved, mut unreachable) = (0, 0);
    let exact = AraStarConfig { initial_epsilon: 1.0, epsilon_step: 0.5, final_epsilon: 1.0 };
    for _ in 0..300 {
        let mut grid = Grid::random(&mut rng);
        let start = grid.start;
        let optimal = grid.optimal_cost();
        let a = a_star(&mut grid, start, &SearchLimits::none(), &mut ws);
        let ara = ara_star(&mut grid, start, &exact, &SearchLimits::none(), &mut ws);
        if optimal.is_infinite() {
            unreachable += 1;
            assert!(matches!(a, Err(SearchError::NoPath { .. })), "{a:?}");
            assert!(matches!(ara, Err(SearchError::NoPath { .. })), "{ara:?}");
            continue;
        }
        solved += 1;
        let a = a.unwrap();
        assert!((a.cost - optimal).abs() <= tolerance(optimal), "A* {} vs Dijkstra {optimal}", a.cost);
        assert_valid_path(&grid, &a);
        let ara = ara.unwrap();
        assert_eq!(ara.solutions.len(), 1);
        assert_eq!(ara.stop, AraStop::Converged);
        let only = &ara.solutions[0];
        assert_eq!((only.epsilon, only.bound), (1.0, 1.0));
        assert!((only.cost - a.cost).abs() <= tolerance(optimal), "ARA*(1) {} vs A* {}", only.cost, a.cost);
        assert_valid_path(&grid, only);
    }
    // Both branches are exercised.
    assert!(solved > 150 && unreachable > 10, "solved {solved}, unreachable {unreachable}");
}

#[test]
fn every_ara_star_solution_is_within_its_bound_of_the_optimum() {
    let mut rng = Rng(0xa5a5_0101_7777);
    let mut ws = SearchWorkspace::new();
    let config = AraStarConfig { initial_epsilon: 4.0, epsilon_step: 0.75, final_epsilon: 1.0 };
    let (mut improved, mut solved) = (0, 0);
    for _ in 0..300 {
        let mut grid = Grid::random(&mut rng);
        let start = grid.start;
        let optimal = grid.optimal_cost();
        if optimal.is_infinite() {
            continue;
        }
        solved += 1;
        let result = ara_star(&mut grid, start, &config, &SearchLimits::none(), &mut ws).unwrap();
        assert_eq!(result.stop, AraStop::Converged);
        let mut epsilon = f64::INFINITY;
        for s in &result.solutions {
            assert_valid_path(&grid, s);
            assert!(s.epsilon < epsilon, "epsilon decreases from run to run");
            epsilon = s.epsilon;
            assert!(1.0 <= s.bound && s.bound <= s.epsilon, "bound {} for epsilon {}", s.bound, s.epsilon);
            assert!(s.cost <= s.bound * optimal + tolerance(optimal), "cost {} > {} * {optimal}", s.cost, s.bound);
        }
        let last = result.solutions.last().unwrap();
        assert_eq!(last.bound, 1.0);
        assert!((last.cost - optimal).abs() <= tolerance(optimal), "final {} vs optimal {optimal}", last.cost);
        assert_eq!(result.best().cost, result.solutions.iter().map(|s| s.cost).fold(f64::INFINITY, f64::min));
        if result.solutions[0].cost > optimal + tolerance(optimal) {
            improved += 1;
        }
    }
    // The inflated first run is really sub-optimal on some grids, so the bound is exercised.
    assert!(improved > 10 && solved > 150, "improved {improved} of {solved}");
}

#[test]
fn grid_heuristic_is_consistent_and_admissible() {
    let mut rng = Rng(0x0bad_cafe_0042);
    for _ in 0..50 {
        let mut grid = Grid::random(&mut rng);
        let to_goal = grid.cost_to_goal();
        let mut out = Vec::new();
        for y in 0..grid.height {
            for x in 0..grid.width {
                let h = grid.heuristic(&(x, y));
                assert!(h <= to_goal[(y * grid.width + x) as usize] + 1e-12);
                out.clear();
                grid.successors(&(x, y), &mut out);
                for e in &out {
                    assert!(h <= e.cost + grid.heuristic(&e.to) + 1e-12);
                }
            }
        }
        assert_eq!(grid.heuristic(&grid.goal), 0.0);
    }
}

/// A* re-opens closed states, so an admissible but inconsistent heuristic still gives the
/// optimum: `h(s) = u(s) * cost_to_goal(s)` with `u` pseudo-random in [0, 1] per cell.
struct Inconsistent {
    grid: Grid,
    to_goal: Vec<f64>,
    scale: Vec<f64>,
}
impl SearchSpace for Inconsistent {
    type State = (i32, i32);
    type Action = u8;
    fn successors(&mut self, state: &(i32, i32), out: &mut Vec<Edge<(i32, i32), u8>>) {
        self.grid.successors(state, out)
    }
    fn heuristic(&self, &(x, y): &(i32, i32)) -> f64 {
        let i = (y * self.grid.width + x) as usize;
        if self.to_goal[i].is_finite() {
            self.scale[i] * self.to_goal[i]
        } else {
            0.0
        }
    }
    fn is_goal(&self, state: &(i32, i32)) -> bool {
        self.grid.is_goal(state)
    }
}

#[test]
fn a_star_is_optimal_with_an_admissible_inconsistent_heuristic() {
    let mut rng = Rng(0x1234_5678_9abc);
    let mut ws = SearchWorkspace::new();
    let mut checked = 0;
    for _ in 0..200 {
        let grid = Grid::random(&mut rng);
        let to_goal = grid.cost_to_goal();
        let optimal = grid.optimal_cost();
        if optimal.is_infinite() {
            continue;
        }
        checked += 1;
        let scale = (0..grid.cells.len()).map(|_| rng.uniform()).collect();
        let start = grid.start;
        let mut space = Inconsistent { grid, to_goal, scale };
        let path = a_star(&mut space, start, &SearchLimits::none(), &mut ws).unwrap();
        assert!((path.cost - optimal).abs() <= tolerance(optimal), "{} vs {optimal}", path.cost);
        assert_valid_path(&space.grid, &path);
    }
    assert!(checked > 100);
}

#[test]
fn limits_stop_the_search_with_a_clear_result() {
    let mut rng = Rng(77);
    let mut grid = loop {
        let g = Grid::random(&mut rng);
        if g.optimal_cost().is_finite() && g.optimal_cost() > 30.0 {
            break g;
        }
    };
    let start = grid.start;
    let mut ws = SearchWorkspace::new();
    let none = a_star(&mut grid, start, &SearchLimits::expansions(0), &mut ws);
    assert_eq!(none, Err(SearchError::LimitBeforeFirstSolution { limit: Limit::Expansions, expansions: 0 }));
    let past = SearchLimits { deadline: Some(Instant::now()), max_expansions: None };
    let ara = ara_star(&mut grid, start, &AraStarConfig::default(), &past, &mut ws);
    assert_eq!(ara, Err(SearchError::LimitBeforeFirstSolution { limit: Limit::Deadline, expansions: 0 }));

    // Enough for the first (inflated) path, not for the proof of optimality.
    let config = AraStarConfig { initial_epsilon: 5.0, epsilon_step: 0.5, final_epsilon: 1.0 };
    let full = ara_star(&mut grid, start, &config, &SearchLimits::none(), &mut ws).unwrap();
    let first = full.solutions[0].expansions;
    assert!(full.expansions > first + 1);
    let budget = first + (full.expansions - first) / 2;
    let cut = ara_star(&mut grid, start, &config, &SearchLimits::expansions(budget), &mut ws).unwrap();
    assert_eq!(cut.stop, AraStop::Limit(Limit::Expansions));
    assert_eq!(cut.expansions, budget);
    // The published prefix is the same as in the full run (the search is deterministic).
    let key = |s: &Solution<(i32, i32), u8>| (s.states.clone(), s.cost, s.epsilon, s.bound, s.expansions);
    assert!(!cut.solutions.is_empty() && cut.solutions.len() < full.solutions.len());
    for (c, f) in cut.solutions.iter().zip(&full.solutions) {
        assert_eq!(key(c), key(f));
    }
}

#[test]
fn workspace_reuse_gives_the_same_answers_as_a_fresh_workspace() {
    let mut rng = Rng(0xfeed);
    let mut shared = SearchWorkspace::new();
    for _ in 0..40 {
        let mut grid = Grid::random(&mut rng);
        let start = grid.start;
        let reused = ara_star(&mut grid, start, &AraStarConfig::default(), &SearchLimits::none(), &mut shared);
        let fresh = ara_star(&mut grid, start, &AraStarConfig::default(), &SearchLimits::none(), &mut SearchWorkspace::new());
        match (reused, fresh) {
            (Ok(a), Ok(b)) => {
                let strip = |r: AnytimeResult<(i32, i32), u8>| {
                    r.solutions.into_iter().map(|s| (s.states, s.cost, s.bound, s.expansions)).collect::<Vec<_>>()
                };
                assert_eq!(strip(a), strip(b));
            }
            (a, b) => assert_eq!(a.err(), b.err()),
        }
    }
}

#[test]
fn start_on_the_goal_is_a_zero_cost_path() {
    let mut grid = Grid::random(&mut Rng(5));
    grid.start = grid.goal;
    let goal = grid.goal;
    let mut ws = SearchWorkspace::new();
    let a = a_star(&mut grid, goal, &SearchLimits::none(), &mut ws).unwrap();
    assert_eq!((a.states.clone(), a.cost), (vec![grid.goal], 0.0));
    let ara = ara_star(&mut grid, goal, &AraStarConfig::default(), &SearchLimits::none(), &mut ws).unwrap();
    assert_eq!((ara.best().states.clone(), ara.best().cost, ara.stop), (vec![grid.goal], 0.0, AraStop::Converged));
}

/// A space whose edges cost NaN: the search names the edge instead of accepting it.
struct NanEdges;
impl SearchSpace for NanEdges {
    type State = i32;
    type Action = ();
    fn successors(&mut self, state: &i32, out: &mut Vec<Edge<i32, ()>>) {
        out.push(Edge { to: state + 1, action: (), cost: if *state == 2 { f64::NAN } else { 1.0 } });
    }
    fn heuristic(&self, state: &i32) -> f64 {
        if *state == 7 {
            -1.0
        } else {
            0.0
        }
    }
    fn is_goal(&self, state: &i32) -> bool {
        *state == 5
    }
}

#[test]
fn invalid_numbers_and_settings_are_errors() {
    let mut ws = SearchWorkspace::new();
    let err = a_star(&mut NanEdges, 0, &SearchLimits::none(), &mut ws).unwrap_err();
    assert!(matches!(&err, SearchError::InvalidEdgeCost { from, to, cost } if from == "2" && to == "3" && cost.is_nan()), "{err}");
    let err = ara_star(&mut NanEdges, 7, &AraStarConfig::default(), &SearchLimits::none(), &mut ws).unwrap_err();
    assert_eq!(err, SearchError::InvalidHeuristic { state: "7".into(), value: -1.0 });
    for (config, field) in [
        (AraStarConfig { final_epsilon: 0.5, ..Default::default() }, "final_epsilon"),
        (AraStarConfig { initial_epsilon: f64::NAN, ..Default::default() }, "initial_epsilon"),
        (AraStarConfig { initial_epsilon: 0.9, final_epsilon: 1.0, ..Default::default() }, "initial_epsilon"),
        (AraStarConfig { epsilon_step: 0.0, ..Default::default() }, "epsilon_step"),
    ] {
        let err = ara_star(&mut NanEdges, 0, &config, &SearchLimits::none(), &mut ws).unwrap_err();
        assert!(matches!(err, SearchError::InvalidConfig { field: f, .. } if f == field), "{err}");
    }
}
