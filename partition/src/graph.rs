//! The grain graph: one vertex per grain, one edge per pair of grains that can
//! touch. Stored in the CSR layout METIS expects.

use std::collections::HashMap;

use crate::error::PartitionError;
use crate::grain::{CostModel, GrainInfo};

/// Integer weight given to a grain of mean cost. 1000 keeps the rounding error
/// of a vertex weight below 0.05 % of a mean grain, far below the few-percent
/// imbalance METIS allows.
pub const VERTEX_WEIGHT_RESOLUTION: f64 = 1000.0;

/// Integer weight given to an edge of mean contact cost. Edge weights only
/// steer which edges METIS prefers to cut, so a coarser resolution suffices.
pub const EDGE_WEIGHT_RESOLUTION: f64 = 100.0;

/// Upper bound (before the round-up to at least 1) on the sum of all vertex
/// weights and on the sum of all adjacency weights. METIS adds weights in
/// 32-bit integers; 2^28 leaves a factor of 8 of headroom for its internal
/// sums and imbalance products.
pub const MAX_TOTAL_WEIGHT: f64 = (1u64 << 28) as f64;

/// Grain graph in compressed sparse row (CSR) form.
///
/// The neighbours of grain `i` are `adjncy()[xadj()[i]..xadj()[i + 1]]`, sorted
/// ascending, with matching weights in `adjwgt()`. Every undirected edge is
/// stored twice (once per direction) with the same weight, there are no self
/// loops and no duplicate edges. All integer weights are ≥ 1.
///
/// Two sets of weights are kept: the physical cost estimates (`f64`, cost
/// units per time step, see [`CostModel`]) and their positive integer
/// quantisation that is handed to METIS. `cost ≈ weight × unit`, where the unit
/// is [`GrainGraph::vertex_weight_unit`] or [`GrainGraph::edge_weight_unit`].
#[derive(Debug, Clone, PartialEq)]
pub struct GrainGraph {
    xadj: Vec<usize>,
    adjncy: Vec<usize>,
    adjwgt: Vec<u32>,
    vertex_weights: Vec<u32>,
    vertex_costs: Vec<f64>,
    edge_costs: Vec<f64>,
    vertex_weight_unit: f64,
    edge_weight_unit: f64,
}

impl GrainGraph {
    /// Builds the contact graph of `grains`.
    ///
    /// * **Vertex weight** of grain `i`: its work per step,
    ///   `cost.grain_cost(i)` = `cost_per_element · elements +
    ///   cost_per_surface_node · surface_nodes`, quantised to integers so that a
    ///   grain of mean cost weighs [`VERTEX_WEIGHT_RESOLUTION`] (scaled down if
    ///   the total would exceed [`MAX_TOTAL_WEIGHT`]), rounded, at least 1.
    /// * **Edge** `i–j` whenever `|c_i − c_j| ≤ r_i + r_j + contact_margin`
    ///   (bounding spheres closer than the margin, in metres).
    /// * **Edge weight**: the expected contact work of the pair,
    ///   `cost_per_contact_node · min(s_i·f_i, s_j·f_j)`, where `s` is the
    ///   surface-node count and `f_i` the fraction of grain `i`'s bounding
    ///   sphere surface that lies within `r_j + contact_margin` of `c_j`
    ///   (spherical-cap area, `((r_j+h)² − (d−r_i)²) / (4 r_i d)` clamped to
    ///   [0, 1]). Assuming surface nodes are spread evenly, `s_i·f_i` is the
    ///   number of grain `i`'s nodes inside the contact zone; the smaller side
    ///   bounds the number of node–surface pairs that are searched and
    ///   exchanged when the edge is cut. For touching equal spheres with
    ///   `h = 0.1 R` this is 2.6 % of the surface. Quantised like the vertex
    ///   weights, with a mean edge at [`EDGE_WEIGHT_RESOLUTION`], at least 1.
    ///
    /// Neighbour search hashes grain centres into cubic cells of edge
    /// `2·r_max + margin` (slightly enlarged against round-off), so only the 27
    /// surrounding cells are searched: O(n) for grains of similar size.
    ///
    /// This function never fails. Grains with a non-finite centre or a
    /// negative/non-finite radius get no edges; a negative or NaN margin counts
    /// as 0; non-finite or negative costs count as 0. When all costs of a kind
    /// are 0 the corresponding weights are all 1. Use
    /// [`GrainGraph::try_build`] to reject such input instead.
    pub fn build(grains: &[GrainInfo], contact_margin: f64, cost: &CostModel) -> GrainGraph {
        let margin = if contact_margin >= 0.0 {
            contact_margin
        } else {
            0.0
        };
        let vertex_costs: Vec<f64> = grains.iter().map(|g| cost.grain_cost(g)).collect();

        let pairs = find_contact_pairs(grains, margin);

        // CSR assembly: count degrees, prefix-sum, scatter both directions.
        let n = grains.len();
        let mut degree = vec![0usize; n];
        for &(i, j) in &pairs {
            degree[i] += 1;
            degree[j] += 1;
        }
        let mut xadj = Vec::with_capacity(n + 1);
        xadj.push(0);
        for d in &degree {
            let last = xadj[xadj.len() - 1];
            xadj.push(last + d);
        }
        let n_entries = xadj[n];
        let mut adjncy = vec![0usize; n_entries];
        let mut edge_costs = vec![0.0f64; n_entries];
        let mut cursor: Vec<usize> = xadj[..n].to_vec();
        for &(i, j) in &pairs {
            let pair_cost =
                cost.cost_per_contact_node * expected_contact_nodes(&grains[i], &grains[j], margin);
            for (from, to) in [(i, j), (j, i)] {
                adjncy[cursor[from]] = to;
                edge_costs[cursor[from]] = pair_cost;
                cursor[from] += 1;
            }
        }
        // Sort every row by neighbour index so the layout does not depend on
        // the hash-grid traversal order.
        for i in 0..n {
            let row = xadj[i]..xadj[i + 1];
            let mut entries: Vec<(usize, f64)> = adjncy[row.clone()]
                .iter()
                .copied()
                .zip(edge_costs[row.clone()].iter().copied())
                .collect();
            entries.sort_by_key(|&(neighbour, _)| neighbour);
            for (k, (neighbour, c)) in row.zip(entries) {
                adjncy[k] = neighbour;
                edge_costs[k] = c;
            }
        }

        let (vertex_weights, vertex_weight_unit) =
            quantise(&vertex_costs, VERTEX_WEIGHT_RESOLUTION);
        let (adjwgt, edge_weight_unit) = quantise(&edge_costs, EDGE_WEIGHT_RESOLUTION);

        GrainGraph {
            xadj,
            adjncy,
            adjwgt,
            vertex_weights,
            vertex_costs,
            edge_costs,
            vertex_weight_unit,
            edge_weight_unit,
        }
    }

    /// Like [`GrainGraph::build`], but first checks every grain
    /// ([`GrainInfo::validate`]), the margin (finite, ≥ 0) and the cost model
    /// ([`CostModel::validate`]) and returns the first problem found.
    pub fn try_build(
        grains: &[GrainInfo],
        contact_margin: f64,
        cost: &CostModel,
    ) -> Result<GrainGraph, PartitionError> {
        for (index, grain) in grains.iter().enumerate() {
            grain.validate(index)?;
        }
        if !contact_margin.is_finite() || contact_margin < 0.0 {
            return Err(PartitionError::InvalidInput(format!(
                "contact margin {contact_margin} must be finite and non-negative"
            )));
        }
        cost.validate()?;
        Ok(Self::build(grains, contact_margin, cost))
    }

    /// Wraps an existing CSR graph (e.g. built from an actual contact list).
    ///
    /// Costs are set equal to the weights (units of 1). Checks that `xadj`
    /// starts at 0, is non-decreasing and ends at `adjncy.len()`, that
    /// neighbour indices are in range, that there are no self loops or
    /// duplicate edges, that every edge appears in both directions with the
    /// same weight, and that all weights are ≥ 1. Rows are sorted on the way in.
    pub fn from_csr(
        xadj: Vec<usize>,
        adjncy: Vec<usize>,
        adjwgt: Vec<u32>,
        vertex_weights: Vec<u32>,
    ) -> Result<GrainGraph, PartitionError> {
        let invalid = |message: String| Err(PartitionError::InvalidInput(message));
        if xadj.first() != Some(&0) {
            return invalid("xadj must start with 0".into());
        }
        let n = xadj.len() - 1;
        if xadj.windows(2).any(|w| w[0] > w[1]) {
            return invalid("xadj must be non-decreasing".into());
        }
        if xadj[n] != adjncy.len() {
            return invalid(format!(
                "xadj ends at {} but adjncy has {} entries",
                xadj[n],
                adjncy.len()
            ));
        }
        if adjwgt.len() != adjncy.len() {
            return invalid(format!(
                "adjwgt has {} entries, adjncy has {}",
                adjwgt.len(),
                adjncy.len()
            ));
        }
        if vertex_weights.len() != n {
            return invalid(format!(
                "{} vertex weights for {n} vertices",
                vertex_weights.len()
            ));
        }
        if let Some(v) = vertex_weights.iter().position(|&w| w == 0) {
            return invalid(format!("vertex {v} has weight 0; weights must be ≥ 1"));
        }
        let mut adjncy = adjncy;
        let mut adjwgt = adjwgt;
        for i in 0..n {
            let row = xadj[i]..xadj[i + 1];
            let mut entries: Vec<(usize, u32)> = adjncy[row.clone()]
                .iter()
                .copied()
                .zip(adjwgt[row.clone()].iter().copied())
                .collect();
            entries.sort_unstable();
            for (k, &(j, w)) in entries.iter().enumerate() {
                if j >= n {
                    return invalid(format!(
                        "vertex {i} has neighbour {j}, but there are {n} vertices"
                    ));
                }
                if j == i {
                    return invalid(format!("vertex {i} has a self loop"));
                }
                if w == 0 {
                    return invalid(format!("edge {i}-{j} has weight 0; weights must be ≥ 1"));
                }
                if k > 0 && entries[k - 1].0 == j {
                    return invalid(format!("edge {i}-{j} appears twice"));
                }
            }
            for (k, (j, w)) in row.zip(entries) {
                adjncy[k] = j;
                adjwgt[k] = w;
            }
        }
        // Symmetry: rows are sorted now, so a binary search finds the reverse edge.
        for i in 0..n {
            for k in xadj[i]..xadj[i + 1] {
                let j = adjncy[k];
                let reverse = &adjncy[xadj[j]..xadj[j + 1]];
                match reverse.binary_search(&i) {
                    Ok(pos) if adjwgt[xadj[j] + pos] == adjwgt[k] => {}
                    Ok(_) => {
                        return invalid(format!(
                            "edge {i}-{j} has different weights in the two directions"
                        ))
                    }
                    Err(_) => return invalid(format!("edge {i}-{j} has no reverse edge {j}-{i}")),
                }
            }
        }
        Ok(GrainGraph {
            vertex_costs: vertex_weights.iter().map(|&w| f64::from(w)).collect(),
            edge_costs: adjwgt.iter().map(|&w| f64::from(w)).collect(),
            xadj,
            adjncy,
            adjwgt,
            vertex_weights,
            vertex_weight_unit: 1.0,
            edge_weight_unit: 1.0,
        })
    }

    /// Number of grains (vertices).
    pub fn n_grains(&self) -> usize {
        self.xadj.len() - 1
    }

    /// Number of undirected edges (grain pairs that can touch).
    pub fn n_edges(&self) -> usize {
        self.adjncy.len() / 2
    }

    /// CSR row offsets, length `n_grains() + 1`.
    pub fn xadj(&self) -> &[usize] {
        &self.xadj
    }

    /// CSR column indices (neighbouring grain ids), length `2 · n_edges()`.
    pub fn adjncy(&self) -> &[usize] {
        &self.adjncy
    }

    /// Integer edge weights handed to METIS, aligned with [`Self::adjncy`].
    pub fn adjwgt(&self) -> &[u32] {
        &self.adjwgt
    }

    /// Integer vertex weights handed to METIS, one per grain.
    pub fn vertex_weights(&self) -> &[u32] {
        &self.vertex_weights
    }

    /// Estimated work per step of each grain, in cost units.
    pub fn vertex_costs(&self) -> &[f64] {
        &self.vertex_costs
    }

    /// Estimated contact work per step of each edge, in cost units, aligned
    /// with [`Self::adjncy`].
    pub fn edge_costs(&self) -> &[f64] {
        &self.edge_costs
    }

    /// Cost units represented by one unit of integer vertex weight.
    pub fn vertex_weight_unit(&self) -> f64 {
        self.vertex_weight_unit
    }

    /// Cost units represented by one unit of integer edge weight.
    pub fn edge_weight_unit(&self) -> f64 {
        self.edge_weight_unit
    }

    /// Neighbouring grain ids of `grain`, ascending.
    ///
    /// # Panics
    /// If `grain >= n_grains()`.
    pub fn neighbours(&self, grain: usize) -> &[usize] {
        &self.adjncy[self.xadj[grain]..self.xadj[grain + 1]]
    }

    /// Integer weights of the edges listed by [`Self::neighbours`].
    ///
    /// # Panics
    /// If `grain >= n_grains()`.
    pub fn neighbour_weights(&self, grain: usize) -> &[u32] {
        &self.adjwgt[self.xadj[grain]..self.xadj[grain + 1]]
    }

    /// Sum of all integer vertex weights.
    pub fn total_vertex_weight(&self) -> u64 {
        self.vertex_weights.iter().map(|&w| u64::from(w)).sum()
    }
}

/// All pairs `(i, j)`, `i < j`, of grains with valid geometry whose bounding
/// spheres are within `margin` of each other, found with a hashed cell grid.
fn find_contact_pairs(grains: &[GrainInfo], margin: f64) -> Vec<(usize, usize)> {
    let max_radius = grains
        .iter()
        .filter(|g| g.has_valid_geometry())
        .map(|g| g.bounding_radius)
        .fold(0.0f64, f64::max);
    // Any touching pair is at most 2·r_max + margin apart, so with cells at
    // least that large, partners lie in the same or an adjacent cell. The
    // small enlargement keeps that true despite rounding in x / cell_size.
    let mut cell_size = (2.0 * max_radius + margin) * (1.0 + 1e-9);
    if !(cell_size.is_normal() && cell_size.is_finite()) {
        // All radii and the margin are 0 (only coincident centres connect),
        // or the margin is infinite (everything connects): any positive
        // finite cell size then gives correct, if slow, results.
        cell_size = if cell_size.is_infinite() {
            f64::MAX
        } else {
            1.0
        };
    }
    let cell_of = |centre: &[f64; 3]| -> [i64; 3] {
        // `as` saturates, so far-away grains share boundary cells; the exact
        // distance test below keeps the result correct.
        centre.map(|x| (x / cell_size).floor() as i64)
    };

    let mut cells: HashMap<[i64; 3], Vec<usize>> = HashMap::new();
    for (index, grain) in grains.iter().enumerate() {
        if grain.has_valid_geometry() {
            cells.entry(cell_of(&grain.centre)).or_default().push(index);
        }
    }

    let mut pairs = Vec::new();
    for (i, grain) in grains.iter().enumerate() {
        if !grain.has_valid_geometry() {
            continue;
        }
        let home = cell_of(&grain.centre);
        let mut visited: Vec<[i64; 3]> = Vec::with_capacity(27);
        for dx in -1i64..=1 {
            for dy in -1i64..=1 {
                for dz in -1i64..=1 {
                    let cell = [
                        home[0].saturating_add(dx),
                        home[1].saturating_add(dy),
                        home[2].saturating_add(dz),
                    ];
                    // Saturation can map two offsets to the same cell.
                    if visited.contains(&cell) {
                        continue;
                    }
                    visited.push(cell);
                    let Some(members) = cells.get(&cell) else {
                        continue;
                    };
                    for &j in members {
                        if j > i && spheres_within_margin(grain, &grains[j], margin) {
                            pairs.push((i, j));
                        }
                    }
                }
            }
        }
    }
    pairs
}

/// `|c_a − c_b| ≤ r_a + r_b + margin`, compared squared (symmetric in a, b
/// bit for bit, so the graph cannot become asymmetric through round-off).
fn spheres_within_margin(a: &GrainInfo, b: &GrainInfo, margin: f64) -> bool {
    let reach = a.bounding_radius + b.bounding_radius + margin;
    distance_squared(&a.centre, &b.centre) <= reach * reach
}

fn distance_squared(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    (0..3).map(|k| (a[k] - b[k]) * (a[k] - b[k])).sum()
}

/// Expected number of surface nodes in the contact zone of a grain pair:
/// the smaller of the two grains' node counts within range of the other.
fn expected_contact_nodes(a: &GrainInfo, b: &GrainInfo, margin: f64) -> f64 {
    let distance = distance_squared(&a.centre, &b.centre).sqrt();
    let nodes_a = a.surface_nodes as f64
        * surface_fraction_in_range(a.bounding_radius, b.bounding_radius + margin, distance);
    let nodes_b = b.surface_nodes as f64
        * surface_fraction_in_range(b.bounding_radius, a.bounding_radius + margin, distance);
    nodes_a.min(nodes_b)
}

/// Fraction of the surface of a sphere of radius `radius` that lies within
/// `range` of a point `distance` away from its centre (spherical-cap area over
/// sphere area).
fn surface_fraction_in_range(radius: f64, range: f64, distance: f64) -> f64 {
    if radius <= 0.0 {
        // A point grain is entirely inside the range (the pair is connected).
        return 1.0;
    }
    if distance <= f64::EPSILON * radius {
        // Concentric: the whole surface is at distance `radius`.
        return if radius <= range { 1.0 } else { 0.0 };
    }
    let gap = distance - radius;
    ((range * range - gap * gap) / (4.0 * radius * distance)).clamp(0.0, 1.0)
}

/// Maps non-negative costs to positive integer weights: a mean cost maps to
/// `resolution` (scaled down if the total would exceed [`MAX_TOTAL_WEIGHT`]),
/// rounded, at least 1. Returns the weights and the cost per weight unit.
/// Non-finite or negative costs count as 0; if all costs are 0 every weight is
/// 1 and the unit is 1.
fn quantise(costs: &[f64], resolution: f64) -> (Vec<u32>, f64) {
    let clean = |c: f64| if c.is_finite() && c > 0.0 { c } else { 0.0 };
    let total: f64 = costs.iter().map(|&c| clean(c)).sum();
    if costs.is_empty() || !(total > 0.0 && total.is_finite()) {
        return (vec![1; costs.len()], 1.0);
    }
    let mean = total / costs.len() as f64;
    let weight_per_cost = (resolution / mean).min(MAX_TOTAL_WEIGHT / total);
    let weights = costs
        .iter()
        .map(|&c| (clean(c) * weight_per_cost).round().max(1.0) as u32)
        .collect();
    (weights, 1.0 / weight_per_cost)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::packing::fcc_packing;
    use crate::test_support::{polydisperse_grains, uniform_grains};

    /// Reference O(n²) neighbour sets.
    fn brute_force_neighbours(grains: &[GrainInfo], margin: f64) -> Vec<Vec<usize>> {
        (0..grains.len())
            .map(|i| {
                (0..grains.len())
                    .filter(|&j| j != i && spheres_within_margin(&grains[i], &grains[j], margin))
                    .collect()
            })
            .collect()
    }

    #[test]
    fn fcc_interior_grains_have_twelve_neighbours() {
        let radius = 1.1e-3;
        let centres = fcc_packing(2000, radius);
        let grains = uniform_grains(&centres, radius, 8000, 1500);
        let graph = GrainGraph::build(&grains, 0.1 * radius, &CostModel::default());

        // A grain is interior when all 12 nearest-neighbour sites, at offsets
        // (±a/2, ±a/2, 0) and permutations, lie inside the block.
        let half_cell = 2.0f64.sqrt() * radius;
        let tol = 1e-9 * radius;
        let lo: Vec<f64> = (0..3)
            .map(|k| centres.iter().map(|c| c[k]).fold(f64::INFINITY, f64::min))
            .collect();
        let hi: Vec<f64> = (0..3)
            .map(|k| {
                centres
                    .iter()
                    .map(|c| c[k])
                    .fold(f64::NEG_INFINITY, f64::max)
            })
            .collect();
        let mut interior = 0;
        for (i, c) in centres.iter().enumerate() {
            let degree = graph.neighbours(i).len();
            assert!(degree <= 12, "grain {i} has {degree} > 12 neighbours");
            let is_interior =
                (0..3).all(|k| c[k] >= lo[k] + half_cell - tol && c[k] <= hi[k] - half_cell + tol);
            if is_interior {
                interior += 1;
                assert_eq!(degree, 12, "interior grain {i} at {c:?}");
            }
        }
        assert!(interior > 500, "only {interior} interior grains");
        // Edge weights are all equal for identical touching grains.
        let first = graph.adjwgt()[0];
        assert!(graph.adjwgt().iter().all(|&w| w == first));
    }

    #[test]
    fn graph_is_symmetric_without_self_loops_or_duplicates() {
        let grains = polydisperse_grains(600, 7);
        let graph = GrainGraph::build(&grains, 0.05, &CostModel::default());
        assert!(
            graph.n_edges() > 600,
            "test graph too sparse: {}",
            graph.n_edges()
        );
        for i in 0..graph.n_grains() {
            let row = graph.neighbours(i);
            assert!(
                row.windows(2).all(|w| w[0] < w[1]),
                "row {i} not strictly sorted"
            );
            for (k, &j) in row.iter().enumerate() {
                assert_ne!(i, j, "self loop at {i}");
                let back = graph
                    .neighbours(j)
                    .binary_search(&i)
                    .expect("missing reverse edge");
                assert_eq!(
                    graph.neighbour_weights(j)[back],
                    graph.neighbour_weights(i)[k]
                );
            }
        }
        // from_csr accepts what build produces.
        let copy = GrainGraph::from_csr(
            graph.xadj().to_vec(),
            graph.adjncy().to_vec(),
            graph.adjwgt().to_vec(),
            graph.vertex_weights().to_vec(),
        )
        .expect("build output is valid CSR");
        assert_eq!(copy.adjncy(), graph.adjncy());
    }

    #[test]
    fn cell_grid_matches_brute_force() {
        for seed in [1, 2, 3] {
            let grains = polydisperse_grains(400, seed);
            for margin in [0.0, 0.02, 0.3] {
                let graph = GrainGraph::build(&grains, margin, &CostModel::default());
                let expected = brute_force_neighbours(&grains, margin);
                for (i, row) in expected.iter().enumerate() {
                    assert_eq!(
                        graph.neighbours(i),
                        row.as_slice(),
                        "seed {seed} margin {margin} grain {i}"
                    );
                }
            }
        }
    }

    #[test]
    fn weights_are_positive_and_follow_the_cost_model() {
        let mut grains = polydisperse_grains(200, 11);
        grains[0].elements = 0;
        grains[0].surface_nodes = 0;
        grains[1].elements = 20_000;
        let cost = CostModel::default();
        let graph = GrainGraph::build(&grains, 0.05, &cost);
        assert!(graph.vertex_weights().iter().all(|&w| w >= 1));
        assert!(graph.adjwgt().iter().all(|&w| w >= 1));
        assert_eq!(
            graph.vertex_weights()[0],
            1,
            "zero-cost grain still weighs 1"
        );
        for (i, g) in grains.iter().enumerate().skip(1) {
            let expected = cost.grain_cost(g) / graph.vertex_weight_unit();
            let got = f64::from(graph.vertex_weights()[i]);
            assert!(
                (got - expected).abs() <= 0.5 + 1e-9,
                "grain {i}: {got} vs {expected}"
            );
        }
        let mean = graph.total_vertex_weight() as f64 / grains.len() as f64;
        assert!(
            (mean - VERTEX_WEIGHT_RESOLUTION).abs() < 5.0,
            "mean weight {mean}"
        );
    }

    #[test]
    fn contact_weight_grows_with_overlap_and_uses_smaller_grain() {
        let make = |x: f64, r: f64, s: usize| GrainInfo {
            centre: [x, 0.0, 0.0],
            bounding_radius: r,
            elements: 100,
            surface_nodes: s,
        };
        let a = make(0.0, 1.0, 1000);
        let touching = make(2.0, 1.0, 1000);
        let overlapping = make(1.8, 1.0, 1000);
        let margin = 0.1;
        let touch_nodes = expected_contact_nodes(&a, &touching, margin);
        // Cap fraction for touching equal spheres: (2·R·h + h²) / (8 R²).
        let expected = 1000.0 * (2.0 * 0.1 + 0.01) / 8.0;
        assert!(
            (touch_nodes - expected).abs() < 1e-9,
            "{touch_nodes} vs {expected}"
        );
        assert!(expected_contact_nodes(&a, &overlapping, margin) > touch_nodes);
        // A coarser partner limits the number of contact nodes.
        let coarse = make(2.0, 1.0, 100);
        assert!((expected_contact_nodes(&a, &coarse, margin) - expected / 10.0).abs() < 1e-9);
        // Symmetric.
        assert_eq!(
            expected_contact_nodes(&a, &coarse, margin),
            expected_contact_nodes(&coarse, &a, margin)
        );
    }

    #[test]
    fn bad_geometry_is_isolated_by_build_and_rejected_by_try_build() {
        let mut grains = polydisperse_grains(50, 5);
        grains[3].centre[1] = f64::NAN;
        grains[4].bounding_radius = -1.0;
        grains[5].centre[0] = f64::INFINITY;
        let graph = GrainGraph::build(&grains, f64::NAN, &CostModel::default());
        assert_eq!(graph.n_grains(), 50);
        for bad in [3, 4, 5] {
            assert!(graph.neighbours(bad).is_empty());
        }
        let err = GrainGraph::try_build(&grains, 0.1, &CostModel::default()).unwrap_err();
        assert!(
            matches!(err, PartitionError::InvalidGrain { grain: 3, .. }),
            "{err}"
        );
        let fine = polydisperse_grains(50, 5);
        assert!(GrainGraph::try_build(&fine, -0.1, &CostModel::default()).is_err());
        let bad_cost = CostModel {
            cost_per_element: f64::NAN,
            ..CostModel::default()
        };
        assert!(GrainGraph::try_build(&fine, 0.1, &bad_cost).is_err());
    }

    #[test]
    fn degenerate_inputs_do_not_panic() {
        let empty = GrainGraph::build(&[], 0.1, &CostModel::default());
        assert_eq!(empty.n_grains(), 0);
        assert_eq!(empty.n_edges(), 0);
        // Zero radii and zero margin: only coincident centres connect.
        let points: Vec<GrainInfo> = [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]
            .iter()
            .map(|&centre| GrainInfo {
                centre,
                bounding_radius: 0.0,
                elements: 0,
                surface_nodes: 0,
            })
            .collect();
        let graph = GrainGraph::build(&points, 0.0, &CostModel::default());
        assert_eq!(graph.neighbours(0), &[1]);
        assert!(graph.neighbours(2).is_empty());
        assert!(graph.vertex_weights().iter().all(|&w| w == 1));
        // Infinite margin connects everything.
        let graph = GrainGraph::build(&points, f64::INFINITY, &CostModel::default());
        assert_eq!(graph.n_edges(), 3);
    }

    #[test]
    fn from_csr_rejects_malformed_graphs() {
        let ok = GrainGraph::from_csr(vec![0, 1, 2], vec![1, 0], vec![3, 3], vec![1, 1]);
        assert!(ok.is_ok());
        let cases = [
            (vec![], vec![], vec![], vec![]),
            (vec![0, 1, 2], vec![1, 0], vec![3, 4], vec![1, 1]),
            (vec![0, 1, 1], vec![1], vec![3], vec![1, 1]),
            (vec![0, 1, 2], vec![0, 1], vec![1, 1], vec![1, 1]),
            (vec![0, 1, 2], vec![1, 5], vec![1, 1], vec![1, 1]),
            (vec![0, 2, 1], vec![1, 0], vec![1, 1], vec![1, 1]),
            (vec![0, 1, 2], vec![1, 0], vec![1, 1], vec![0, 1]),
            (vec![0, 1, 2], vec![1, 0], vec![0, 0], vec![1, 1]),
            (
                vec![0, 2, 4],
                vec![1, 1, 0, 0],
                vec![1, 1, 1, 1],
                vec![1, 1],
            ),
        ];
        for (xadj, adjncy, adjwgt, vwgt) in cases {
            let description = format!("{xadj:?} {adjncy:?} {adjwgt:?} {vwgt:?}");
            assert!(
                GrainGraph::from_csr(xadj, adjncy, adjwgt, vwgt).is_err(),
                "accepted {description}"
            );
        }
    }
}
