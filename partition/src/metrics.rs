//! Quality of a partition: load balance, edge cut and the halo (ghost) traffic
//! it implies for the distributed simulation.

use std::fmt;

use crate::error::PartitionError;
use crate::grain::GrainInfo;
use crate::graph::GrainGraph;

/// Bytes sent per ghost surface node per step from owner to ghost holder:
/// position and velocity, 2 × 3 × `f64` = 48 B.
pub const FORWARD_BYTES_PER_GHOST_NODE: u64 = 48;

/// Bytes sent back per ghost surface node per step from ghost holder to owner:
/// the contact force accumulated on the ghost, 3 × `f64` = 24 B.
pub const REVERSE_BYTES_PER_GHOST_NODE: u64 = 24;

/// Forward plus reverse halo bytes per ghost surface node per step (72 B).
pub const HALO_BYTES_PER_GHOST_NODE: u64 =
    FORWARD_BYTES_PER_GHOST_NODE + REVERSE_BYTES_PER_GHOST_NODE;

/// Per-part rows are printed by `Display` only up to this many parts.
const MAX_PART_ROWS_DISPLAYED: usize = 16;

/// How good a partition is for the simulation.
///
/// Weights are the integer METIS weights of the graph (multiply by
/// [`GrainGraph::vertex_weight_unit`] / [`GrainGraph::edge_weight_unit`] for
/// cost units per step).
///
/// Halo model: a part holds a *ghost* copy of every grain of another part that
/// is adjacent in the graph to one of its own grains, and the ghost's whole
/// surface is exchanged every step (a conservative, simple ghosting scheme):
/// [`FORWARD_BYTES_PER_GHOST_NODE`] received plus
/// [`REVERSE_BYTES_PER_GHOST_NODE`] sent back per ghost surface node.
#[derive(Debug, Clone, PartialEq)]
pub struct PartitionMetrics {
    /// Number of parts (MPI ranks).
    pub parts: usize,
    /// Number of grains owned by each part.
    pub grains_per_part: Vec<usize>,
    /// Sum of the vertex weights of each part.
    pub part_weights: Vec<u64>,
    /// Largest part weight.
    pub max_part_weight: u64,
    /// Total vertex weight divided by the number of parts.
    pub mean_part_weight: f64,
    /// `max_part_weight / mean_part_weight`: the slowdown of the slowest rank
    /// relative to a perfect split (1.0 = perfect; defined as 1.0 for zero
    /// total weight).
    pub max_to_mean_ratio: f64,
    /// `max_to_mean_ratio − 1`, e.g. 0.03 = slowest rank has 3 % more work than
    /// the mean. This is METIS' definition of load imbalance minus one.
    pub imbalance: f64,
    /// Sum of the integer weights of edges whose grains lie in different parts
    /// (each undirected edge counted once) — what METIS minimises.
    pub edge_cut: u64,
    /// Number of cut edges (each undirected edge counted once).
    pub cut_edges: usize,
    /// Number of distinct ghost grains each part must hold.
    pub halo_ghost_grains_per_part: Vec<usize>,
    /// Ghost surface nodes per part (sum of `surface_nodes` over its ghosts).
    pub halo_nodes_per_part: Vec<u64>,
    /// Ghost surface nodes summed over all parts.
    pub halo_nodes: u64,
    /// Halo bytes per step each part receives plus sends back:
    /// `halo_nodes_per_part × HALO_BYTES_PER_GHOST_NODE`.
    pub halo_bytes_per_step_per_part: Vec<u64>,
    /// Halo bytes per step over all parts: `halo_nodes × 72`.
    pub halo_bytes_per_step: u64,
    /// Elements owned by each part.
    pub elements_per_part: Vec<usize>,
    /// Edges with both grains in the part (contacts only it evaluates).
    pub internal_edges_per_part: Vec<usize>,
    /// Cut edges with one grain in the part: contacts it evaluates with a ghost, and for
    /// which it sends its own grain's contact zone (each cut edge counts for both parts).
    pub cut_edges_per_part: Vec<usize>,
    /// Distinct other parts each part exchanges ghosts with (messages each way per step).
    pub neighbour_parts_per_part: Vec<usize>,
}

impl PartitionMetrics {
    /// Largest number of ghost grains held by one part (0 if there are none).
    pub fn max_ghost_grains(&self) -> usize {
        self.halo_ghost_grains_per_part
            .iter()
            .copied()
            .max()
            .unwrap_or(0)
    }

    /// Mean number of ghost grains per part.
    pub fn mean_ghost_grains(&self) -> f64 {
        let total: usize = self.halo_ghost_grains_per_part.iter().sum();
        total as f64 / self.parts.max(1) as f64
    }

    /// Largest halo traffic of one part, bytes per step.
    pub fn max_halo_bytes_per_part(&self) -> u64 {
        self.halo_bytes_per_step_per_part
            .iter()
            .copied()
            .max()
            .unwrap_or(0)
    }
}

/// Measures the partition `part` (as returned by [`crate::partition`]) of
/// `graph`, which must have been built from `grains`.
///
/// # Errors
/// [`PartitionError::InvalidInput`] if `parts` is 0, if `grains` or `part` do
/// not have one entry per graph vertex, or if a part id is ≥ `parts`.
pub fn metrics(
    graph: &GrainGraph,
    grains: &[GrainInfo],
    part: &[u32],
    parts: usize,
) -> Result<PartitionMetrics, PartitionError> {
    let n_grains = graph.n_grains();
    let invalid = |message: String| Err(PartitionError::InvalidInput(message));
    if parts == 0 {
        return invalid("metrics need at least 1 part".into());
    }
    if grains.len() != n_grains {
        return invalid(format!(
            "{} grains given for a graph of {n_grains} grains",
            grains.len()
        ));
    }
    if part.len() != n_grains {
        return invalid(format!(
            "partition has {} entries for {n_grains} grains",
            part.len()
        ));
    }
    if let Some((grain, &p)) = part.iter().enumerate().find(|(_, &p)| p as usize >= parts) {
        return invalid(format!("grain {grain} is in part {p}, outside 0..{parts}"));
    }

    let mut grains_per_part = vec![0usize; parts];
    let mut part_weights = vec![0u64; parts];
    let mut elements_per_part = vec![0usize; parts];
    for (grain, &p) in part.iter().enumerate() {
        grains_per_part[p as usize] += 1;
        elements_per_part[p as usize] += grains[grain].elements;
        part_weights[p as usize] += u64::from(graph.vertex_weights()[grain]);
    }
    let max_part_weight = part_weights.iter().copied().max().unwrap_or(0);
    let total_weight: u64 = part_weights.iter().sum();
    let mean_part_weight = total_weight as f64 / parts as f64;
    let max_to_mean_ratio = if total_weight > 0 {
        max_part_weight as f64 / mean_part_weight
    } else {
        1.0
    };

    // Cut edges, and (part, ghost grain) pairs for every cut adjacency entry.
    let mut edge_cut = 0u64;
    let mut cut_edges = 0usize;
    let mut ghosts: Vec<(u32, usize)> = Vec::new();
    let mut internal_edges_per_part = vec![0usize; parts];
    let mut cut_edges_per_part = vec![0usize; parts];
    let mut neighbour_parts: Vec<(u32, u32)> = Vec::new();
    for grain in 0..n_grains {
        let own = part[grain];
        for (&neighbour, &weight) in graph
            .neighbours(grain)
            .iter()
            .zip(graph.neighbour_weights(grain))
        {
            if part[neighbour] == own {
                if grain < neighbour {
                    internal_edges_per_part[own as usize] += 1;
                }
                continue;
            }
            ghosts.push((own, neighbour));
            cut_edges_per_part[own as usize] += 1;
            neighbour_parts.push((own, part[neighbour]));
            if grain < neighbour {
                edge_cut += u64::from(weight);
                cut_edges += 1;
            }
        }
    }
    ghosts.sort_unstable();
    ghosts.dedup();
    neighbour_parts.sort_unstable();
    neighbour_parts.dedup();
    let mut neighbour_parts_per_part = vec![0usize; parts];
    for &(p, _) in &neighbour_parts {
        neighbour_parts_per_part[p as usize] += 1;
    }

    let mut halo_ghost_grains_per_part = vec![0usize; parts];
    let mut halo_nodes_per_part = vec![0u64; parts];
    for &(p, ghost) in &ghosts {
        halo_ghost_grains_per_part[p as usize] += 1;
        halo_nodes_per_part[p as usize] += grains[ghost].surface_nodes as u64;
    }
    let halo_nodes = halo_nodes_per_part.iter().sum();
    let halo_bytes_per_step_per_part = halo_nodes_per_part
        .iter()
        .map(|&nodes| nodes * HALO_BYTES_PER_GHOST_NODE)
        .collect();

    Ok(PartitionMetrics {
        parts,
        grains_per_part,
        part_weights,
        max_part_weight,
        mean_part_weight,
        max_to_mean_ratio,
        imbalance: max_to_mean_ratio - 1.0,
        edge_cut,
        cut_edges,
        halo_ghost_grains_per_part,
        halo_nodes_per_part,
        halo_nodes,
        halo_bytes_per_step_per_part,
        halo_bytes_per_step: halo_nodes * HALO_BYTES_PER_GHOST_NODE,
        elements_per_part,
        internal_edges_per_part,
        cut_edges_per_part,
        neighbour_parts_per_part,
    })
}

/// Bytes with a decimal SI prefix, e.g. `12.3 MB`.
fn format_bytes(bytes: u64) -> String {
    const PREFIXES: [&str; 5] = ["B", "kB", "MB", "GB", "TB"];
    let mut value = bytes as f64;
    let mut prefix = 0;
    while value >= 1000.0 && prefix + 1 < PREFIXES.len() {
        value /= 1000.0;
        prefix += 1;
    }
    if prefix == 0 {
        format!("{bytes} B")
    } else {
        format!("{value:.2} {}", PREFIXES[prefix])
    }
}

impl fmt::Display for PartitionMetrics {
    /// A short human-readable summary; per-part rows only for ≤ 16 parts.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let n_grains: usize = self.grains_per_part.iter().sum();
        writeln!(
            f,
            "partition of {n_grains} grains into {} parts",
            self.parts
        )?;
        writeln!(
            f,
            "  imbalance          {:>8.3} %   (max/mean part weight {:.4})",
            100.0 * self.imbalance,
            self.max_to_mean_ratio
        )?;
        writeln!(
            f,
            "  edge cut           {:>8}     ({} cut edges)",
            self.edge_cut, self.cut_edges
        )?;
        writeln!(
            f,
            "  ghost grains/part  {:>8}     max, {:.1} mean",
            self.max_ghost_grains(),
            self.mean_ghost_grains()
        )?;
        writeln!(
            f,
            "  halo nodes         {:>8}     ghost surface nodes, all parts",
            self.halo_nodes
        )?;
        write!(
            f,
            "  halo per step      {:>10}   total, {} max per part",
            format_bytes(self.halo_bytes_per_step),
            format_bytes(self.max_halo_bytes_per_part())
        )?;
        if self.parts <= MAX_PART_ROWS_DISPLAYED {
            writeln!(f)?;
            write!(
                f,
                "  {:>5} {:>7} {:>10} {:>7} {:>11} {:>11}",
                "part", "grains", "weight", "ghosts", "halo nodes", "halo bytes"
            )?;
            for p in 0..self.parts {
                writeln!(f)?;
                write!(
                    f,
                    "  {:>5} {:>7} {:>10} {:>7} {:>11} {:>11}",
                    p,
                    self.grains_per_part[p],
                    self.part_weights[p],
                    self.halo_ghost_grains_per_part[p],
                    self.halo_nodes_per_part[p],
                    format_bytes(self.halo_bytes_per_step_per_part[p])
                )?;
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grain::CostModel;

    /// Four grains in a row, 0-1-2-3, touching neighbours only.
    fn chain() -> (Vec<GrainInfo>, GrainGraph) {
        let grains: Vec<GrainInfo> = (0..4)
            .map(|i| GrainInfo {
                centre: [2.0 * i as f64, 0.0, 0.0],
                bounding_radius: 1.0,
                elements: 100,
                surface_nodes: 10 * (i + 1),
            })
            .collect();
        let graph = GrainGraph::build(&grains, 0.1, &CostModel::default());
        (grains, graph)
    }

    #[test]
    fn chain_split_in_the_middle() {
        let (grains, graph) = chain();
        assert_eq!(graph.n_edges(), 3);
        let m = metrics(&graph, &grains, &[0, 0, 1, 1], 2).unwrap();
        assert_eq!(m.cut_edges, 1);
        assert_eq!(m.edge_cut, u64::from(graph.neighbour_weights(1)[1]));
        // Part 0 ghosts grain 2 (30 nodes), part 1 ghosts grain 1 (20 nodes).
        assert_eq!(m.halo_ghost_grains_per_part, vec![1, 1]);
        assert_eq!(m.halo_nodes_per_part, vec![30, 20]);
        assert_eq!(m.halo_nodes, 50);
        assert_eq!(m.halo_bytes_per_step, 50 * 72);
        assert_eq!(m.halo_bytes_per_step_per_part, vec![30 * 72, 20 * 72]);
        assert_eq!(m.grains_per_part, vec![2, 2]);
        assert_eq!(m.elements_per_part, vec![200, 200]);
        assert_eq!(m.internal_edges_per_part, vec![1, 1]);
        assert_eq!(m.cut_edges_per_part, vec![1, 1]);
        assert_eq!(m.neighbour_parts_per_part, vec![1, 1]);
        let expected_ratio = m.max_part_weight as f64 / m.mean_part_weight;
        assert!((m.max_to_mean_ratio - expected_ratio).abs() < 1e-12);
        assert!((m.imbalance - (expected_ratio - 1.0)).abs() < 1e-12);
        let text = m.to_string();
        assert!(text.contains("imbalance"), "{text}");
        assert!(text.contains("cut edges"), "{text}");
    }

    #[test]
    fn alternating_chain_ghosts_are_counted_once_per_part() {
        let (grains, graph) = chain();
        let m = metrics(&graph, &grains, &[0, 1, 0, 1], 2).unwrap();
        assert_eq!(m.cut_edges, 3);
        // Part 0 = {0, 2} ghosts {1, 3}; part 1 = {1, 3} ghosts {0, 2}.
        assert_eq!(m.halo_ghost_grains_per_part, vec![2, 2]);
        assert_eq!(m.halo_nodes_per_part, vec![20 + 40, 10 + 30]);
        // all three edges are cut, and each has one grain in each part
        assert_eq!(m.internal_edges_per_part, vec![0, 0]);
        assert_eq!(m.cut_edges_per_part, vec![3, 3]);
        assert_eq!(m.neighbour_parts_per_part, vec![1, 1]);
    }

    #[test]
    fn single_part_has_no_halo_and_no_imbalance() {
        let (grains, graph) = chain();
        let m = metrics(&graph, &grains, &[0; 4], 1).unwrap();
        assert_eq!(m.edge_cut, 0);
        assert_eq!(m.halo_nodes, 0);
        assert!(m.imbalance.abs() < 1e-12);
        assert_eq!(m.internal_edges_per_part, vec![3]);
        assert_eq!(m.cut_edges_per_part, vec![0]);
        assert_eq!(m.neighbour_parts_per_part, vec![0]);
    }

    #[test]
    fn inconsistent_input_is_an_error() {
        let (grains, graph) = chain();
        assert!(metrics(&graph, &grains, &[0, 0, 1], 2).is_err());
        assert!(metrics(&graph, &grains[..3], &[0, 0, 1, 1], 2).is_err());
        assert!(metrics(&graph, &grains, &[0, 0, 1, 2], 2).is_err());
        assert!(metrics(&graph, &grains, &[0, 0, 0, 0], 0).is_err());
    }

    #[test]
    fn bytes_are_formatted_with_si_prefixes() {
        assert_eq!(format_bytes(999), "999 B");
        assert_eq!(format_bytes(1_500), "1.50 kB");
        assert_eq!(format_bytes(12_340_000), "12.34 MB");
    }
}
