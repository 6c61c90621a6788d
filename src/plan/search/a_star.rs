//! Plain A* (Hart, Nilsson and Raphael 1968), the reference for ARA*'s costs.

use super::{NodeId, SearchError, SearchLimits, SearchSpace, SearchWorkspace, Solution};
use std::time::Instant;

/// The cheapest path from `start` to a goal of `space`, expanding states in order of
/// `f = g + h`.
///
/// A node reached again by a cheaper path is put back into OPEN even when it was expanded
/// already, so the result is optimal for any admissible heuristic (consistency only saves
/// those re-expansions). The search ends when a goal state is taken from OPEN: with
/// `h = 0` on goals its `f` is its cost, which no other open path can undercut.
///
/// Errors: [`SearchError::NoPath`] when OPEN runs empty, [`SearchError::LimitBeforeFirstSolution`]
/// when `limits` stop it first, and the space's invalid numbers.
pub fn a_star<P>(
    space: &mut P,
    start: P::State,
    limits: &SearchLimits,
    workspace: &mut SearchWorkspace<P::State, P::Action>,
) -> Result<Solution<P::State, P::Action>, SearchError>
where
    P: SearchSpace + ?Sized,
{
    let started = Instant::now();
    let ws = workspace;
    ws.clear();
    let start_id = ws.node_of(space, start)?;
    ws.nodes[start_id as usize].g = 0.0;
    let start_h = ws.nodes[start_id as usize].h;
    ws.push_open(start_id, start_h);
    while let Some(id) = ws.pop_open() {
        if ws.nodes[id as usize].is_goal {
            return Ok(ws.path_to(id, 1.0, 1.0, started));
        }
        if let Some(limit) = ws.limit_reached(limits) {
            return Err(SearchError::LimitBeforeFirstSolution { limit, expansions: ws.expansions });
        }
        ws.expand_into_buffer(space, id)?;
        let g = ws.nodes[id as usize].g;
        for k in 0..ws.successors.len() {
            let edge = ws.successors[k];
            let to: NodeId = ws.node_of(space, edge.to)?;
            let new_g = g + edge.cost;
            let node = &mut ws.nodes[to as usize];
            if new_g < node.g {
                node.g = new_g;
                node.parent = id;
                node.action = Some(edge.action);
                node.edge_cost = edge.cost;
                let key = new_g + node.h;
                ws.push_open(to, key);
            }
        }
    }
    Err(SearchError::NoPath { expansions: ws.expansions })
}
