//! Balance repair after METIS.
//!
//! With only a few grains per part (hundreds of ranks for a few thousand
//! grains) METIS often leaves one grain too many on some parts: at 7.8 grains
//! per part a part with 9 grains is 15 % over the mean, and at 2 grains per
//! part one with 3 is 54 % over. The slowest rank sets the step time, so this
//! pass moves grains along chains of neighbouring parts, from the heaviest part
//! to a lighter one, until the heaviest part is within [`BALANCE_TOLERANCE`]
//! of the mean or no improving chain exists.

use std::collections::{BTreeSet, VecDeque};

use crate::graph::GrainGraph;

/// Target max/mean part weight ratio of the repair (METIS' k-way default).
pub const BALANCE_TOLERANCE: f64 = 1.03;

/// Mutable state: the assignment plus per-part weights and sorted members.
struct Assignment<'a> {
    graph: &'a GrainGraph,
    part: &'a mut [u32],
    weights: Vec<u64>,
    members: Vec<Vec<usize>>,
}

impl Assignment<'_> {
    fn move_grain(&mut self, grain: usize, to: usize) {
        let from = self.part[grain] as usize;
        let weight = u64::from(self.graph.vertex_weights()[grain]);
        self.weights[from] -= weight;
        self.weights[to] += weight;
        if let Ok(pos) = self.members[from].binary_search(&grain) {
            self.members[from].remove(pos);
        }
        if let Err(pos) = self.members[to].binary_search(&grain) {
            self.members[to].insert(pos, grain);
        }
        // `to < parts ≤ u32::MAX + 1` because parts were given as u32 ids.
        self.part[grain] = to as u32;
    }

    /// Parts other than `of` that contain a neighbour of a grain of `of`, ascending.
    fn neighbouring_parts(&self, of: usize) -> BTreeSet<usize> {
        let mut found = BTreeSet::new();
        for &grain in &self.members[of] {
            for &neighbour in self.graph.neighbours(grain) {
                let p = self.part[neighbour] as usize;
                if p != of {
                    found.insert(p);
                }
            }
        }
        found
    }

    /// Grain of part `from` with a neighbour in part `to` whose move to `to`
    /// cuts the least edge weight (largest gain; lowest id on ties), skipping
    /// grains in `exclude`.
    fn best_grain_to_move(&self, from: usize, to: usize, exclude: &[usize]) -> Option<usize> {
        let mut best: Option<(i64, usize)> = None;
        for &grain in &self.members[from] {
            if exclude.contains(&grain) {
                continue;
            }
            let mut to_weight = 0i64;
            let mut from_weight = 0i64;
            for (&neighbour, &w) in self
                .graph
                .neighbours(grain)
                .iter()
                .zip(self.graph.neighbour_weights(grain))
            {
                let p = self.part[neighbour] as usize;
                if p == to {
                    to_weight += i64::from(w);
                } else if p == from {
                    from_weight += i64::from(w);
                }
            }
            if to_weight == 0 {
                continue; // not on the boundary with `to`
            }
            let gain = to_weight - from_weight;
            if best.is_none_or(|(best_gain, _)| gain > best_gain) {
                best = Some((gain, grain));
            }
        }
        best.map(|(_, grain)| grain)
    }

    /// Moves one grain along each hop of `path` (`path[0]` = heaviest part).
    /// Keeps the moves if no part on the path ends at or above `max_weight`
    /// unless it got no heavier; otherwise undoes them. Returns whether kept.
    fn try_chain(&mut self, path: &[usize], max_weight: u64) -> bool {
        let before: Vec<u64> = path.iter().map(|&p| self.weights[p]).collect();
        let mut moved: Vec<(usize, usize)> = Vec::new(); // (grain, original part)
        let mut feasible = true;
        for hop in path.windows(2) {
            let exclude: Vec<usize> = moved.iter().map(|&(g, _)| g).collect();
            match self.best_grain_to_move(hop[0], hop[1], &exclude) {
                Some(grain) => {
                    moved.push((grain, hop[0]));
                    self.move_grain(grain, hop[1]);
                }
                None => {
                    feasible = false;
                    break;
                }
            }
        }
        let improves = feasible
            && path
                .iter()
                .zip(&before)
                .skip(1)
                .all(|(&p, &old)| self.weights[p] < max_weight || self.weights[p] <= old);
        if !improves {
            for &(grain, original) in moved.iter().rev() {
                self.move_grain(grain, original);
            }
        }
        improves
    }
}

/// Moves grains between neighbouring parts until the heaviest part weighs at
/// most `BALANCE_TOLERANCE × mean` or no chain of single-grain moves can lower
/// it. Each accepted chain takes one grain off a heaviest part and lets no
/// other part reach that weight, so the number of heaviest parts (or the
/// maximum) drops every round and the loop ends. Never empties a part.
/// Deterministic. Returns the number of grains moved.
///
/// `part` must hold ids `< parts` and one entry per graph vertex.
pub(crate) fn repair_balance(graph: &GrainGraph, part: &mut [u32], parts: usize) -> usize {
    let n_grains = graph.n_grains();
    if parts < 2 || part.len() != n_grains || part.iter().any(|&p| p as usize >= parts) {
        return 0;
    }
    let mut weights = vec![0u64; parts];
    let mut members = vec![Vec::new(); parts];
    for (grain, &p) in part.iter().enumerate() {
        weights[p as usize] += u64::from(graph.vertex_weights()[grain]);
        members[p as usize].push(grain);
    }
    let total: u64 = weights.iter().sum();
    let limit = BALANCE_TOLERANCE * total as f64 / parts as f64;
    let lightest_grain = graph
        .vertex_weights()
        .iter()
        .copied()
        .min()
        .map_or(0, u64::from);
    let mut state = Assignment {
        graph,
        part,
        weights,
        members,
    };

    let mut moves = 0;
    // Each round strictly lowers (max weight, parts at max); n rounds is a
    // generous safety bound that is never reached in practice.
    for _ in 0..n_grains {
        let Some((heaviest, &max_weight)) = state
            .weights
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.cmp(b.1).then(b.0.cmp(&a.0)))
        else {
            break;
        };
        if max_weight as f64 <= limit || state.members[heaviest].len() < 2 {
            break;
        }
        // Breadth-first search over the part adjacency graph; try the chain to
        // every part light enough to take a grain, nearest first.
        let mut previous: Vec<Option<usize>> = vec![None; parts];
        let mut visited = vec![false; parts];
        visited[heaviest] = true;
        let mut queue = VecDeque::from([heaviest]);
        let mut improved = false;
        'search: while let Some(current) = queue.pop_front() {
            for next in state.neighbouring_parts(current) {
                if visited[next] {
                    continue;
                }
                visited[next] = true;
                previous[next] = Some(current);
                queue.push_back(next);
                if state.weights[next] + lightest_grain >= max_weight {
                    continue;
                }
                let mut path = vec![next];
                while let Some(p) = previous[path[path.len() - 1]] {
                    path.push(p);
                }
                path.reverse();
                if state.try_chain(&path, max_weight) {
                    moves += path.len() - 1;
                    improved = true;
                    break 'search;
                }
            }
        }
        if !improved {
            break;
        }
    }
    moves
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grain::{CostModel, GrainInfo};

    /// `n` equal grains in a row.
    fn chain_graph(n: usize) -> GrainGraph {
        let grains: Vec<GrainInfo> = (0..n)
            .map(|i| GrainInfo {
                centre: [2.0 * i as f64, 0.0, 0.0],
                bounding_radius: 1.0,
                elements: 10,
                surface_nodes: 10,
            })
            .collect();
        GrainGraph::build(&grains, 0.1, &CostModel::default())
    }

    #[test]
    fn moves_weight_along_a_chain_of_parts() {
        // Parts along a row: 3 | 2 | 2 | 1 grains; mean 2. The heaviest part
        // is not adjacent to the light one, so a 3-hop chain is needed.
        let graph = chain_graph(8);
        let mut part = vec![0, 0, 0, 1, 1, 2, 2, 3];
        let moves = repair_balance(&graph, &mut part, 4);
        let mut count = [0; 4];
        for &p in &part {
            count[p as usize] += 1;
        }
        assert_eq!(count, [2, 2, 2, 2], "{part:?}");
        assert_eq!(moves, 3);
        // Parts stay contiguous runs on a chain.
        assert!(part.windows(2).all(|w| w[0] <= w[1]), "{part:?}");
    }

    #[test]
    fn balanced_or_stuck_inputs_are_left_alone() {
        let graph = chain_graph(6);
        let mut balanced = vec![0, 0, 0, 1, 1, 1];
        assert_eq!(repair_balance(&graph, &mut balanced, 2), 0);
        // A single heavy grain cannot be split.
        let graph = chain_graph(1);
        let mut single = vec![0];
        assert_eq!(repair_balance(&graph, &mut single, 2), 0);
        // Malformed input is ignored rather than panicking.
        let graph = chain_graph(3);
        let mut bad = vec![0, 5, 1];
        assert_eq!(repair_balance(&graph, &mut bad, 2), 0);
    }
}
