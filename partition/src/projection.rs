//! A step's wall time on many ranks, projected from a partition's statistics and costs
//! measured in a run on few: the cluster-scale estimate of docs/BENCHMARKS.md
//! ("Projection to cluster scale").
//!
//! Model, per part p of the partition (each rank holds one):
//!
//! - compute_p = elements_p · t_element + (internal_p + cut_p) · t_edge: element work, and
//!   contact work for every graph edge the rank evaluates (a cut edge is evaluated on both
//!   of its ranks);
//! - halo_p = cut_p · b · t_byte + neighbours_p · α + cut_p · b / β: packing and unpacking
//!   the b bytes sent per cut edge (as measured, shared-memory transfer included), one
//!   message per neighbour part, and the bytes over the network;
//! - reductions = Σ over the all-reduces of n values, once every k steps:
//!   (2⌈log₂ P⌉ α + 2 (P − 1)/P · 8n / β) / k (reduce-scatter then all-gather, the
//!   large-message algorithm), less, for a non-blocking one, the share s of the slowest
//!   part's element work it runs behind (mufe's walls' sum: the integrator's share),
//!   at least zero.
//!
//! The step takes max_p(compute_p + halo_p) + reductions: every all-reduce waits for the
//! slowest rank. α and β are the network's, assumed; everything else is measured.

use crate::metrics::PartitionMetrics;

/// What one step costs, from a measured run, and the network it is projected onto.
#[derive(Debug, Clone, PartialEq)]
pub struct StepCosts {
    /// Element work per owned element per step on one core (s): internal forces,
    /// integration, output.
    pub element_seconds: f64,
    /// Contact work per graph edge a rank evaluates per step (s).
    pub contact_seconds_per_edge: f64,
    /// Halo bytes a rank sends per step for each cut edge of its grains (B).
    pub halo_bytes_per_cut_edge: f64,
    /// Packing, sending and unpacking one halo byte as measured (s/B).
    pub halo_seconds_per_byte: f64,
    /// The all-reduces of a run.
    pub reductions: Vec<Reduction>,
    /// Network latency per message (s), assumed.
    pub latency: f64,
    /// Network bandwidth per rank (B/s), assumed.
    pub bandwidth: f64,
}

/// An all-reduce of `values` f64, once every `every_steps` steps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reduction {
    pub values: usize,
    pub every_steps: f64,
    /// The share of a part's element work that runs while the all-reduce is in flight
    /// (0: blocking).
    pub hidden_behind: f64,
}

/// One step on the partition's ranks (s).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepProjection {
    /// Element and contact work of the part whose compute + halo is largest.
    pub compute: f64,
    /// That part's halo time.
    pub halo: f64,
    /// The step's all-reduces.
    pub reductions: f64,
    /// compute + halo + reductions.
    pub total: f64,
    /// Bytes the busiest part sends per step.
    pub max_halo_bytes: f64,
}

/// The step time the model above gives for partition `m`.
pub fn project_step(m: &PartitionMetrics, c: &StepCosts) -> StepProjection {
    let mut slowest = (0.0, 0.0);
    let mut slowest_elements: f64 = 0.0;
    let mut max_halo_bytes: f64 = 0.0;
    for p in 0..m.parts {
        let cut = m.cut_edges_per_part[p] as f64;
        let edges = m.internal_edges_per_part[p] as f64 + cut;
        let elements = m.elements_per_part[p] as f64 * c.element_seconds;
        let compute = elements + edges * c.contact_seconds_per_edge;
        let bytes = cut * c.halo_bytes_per_cut_edge;
        let halo = bytes * c.halo_seconds_per_byte
            + m.neighbour_parts_per_part[p] as f64 * c.latency
            + bytes / c.bandwidth;
        if compute + halo > slowest.0 + slowest.1 {
            slowest = (compute, halo);
            slowest_elements = elements;
        }
        max_halo_bytes = max_halo_bytes.max(bytes);
    }
    let reductions = if m.parts > 1 {
        let ranks = m.parts as f64;
        let rounds = (m.parts as f64).log2().ceil();
        c.reductions
            .iter()
            .map(|r| {
                let bytes = 8.0 * r.values as f64;
                let cost =
                    2.0 * rounds * c.latency + 2.0 * (ranks - 1.0) / ranks * bytes / c.bandwidth;
                (cost - r.hidden_behind * slowest_elements).max(0.0) / r.every_steps
            })
            .sum()
    } else {
        0.0
    };
    StepProjection {
        compute: slowest.0,
        halo: slowest.1,
        reductions,
        total: slowest.0 + slowest.1 + reductions,
        max_halo_bytes,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::uniform_grains;
    use crate::{metrics, CostModel, GrainGraph};

    fn costs() -> StepCosts {
        StepCosts {
            element_seconds: 1e-8,
            contact_seconds_per_edge: 1e-6,
            halo_bytes_per_cut_edge: 1000.0,
            halo_seconds_per_byte: 1e-9,
            reductions: vec![
                Reduction {
                    values: 100,
                    every_steps: 1.0,
                    hidden_behind: 0.0,
                },
                Reduction {
                    values: 6,
                    every_steps: 4.0,
                    hidden_behind: 0.0,
                },
            ],
            latency: 2e-6,
            bandwidth: 1e10,
        }
    }

    /// Four grains in a row, 0-1-2-3, of 100 elements each.
    fn chain_metrics(part: &[u32], parts: usize) -> PartitionMetrics {
        let centres: Vec<[f64; 3]> = (0..4).map(|i| [2.0 * i as f64, 0.0, 0.0]).collect();
        let grains = uniform_grains(&centres, 1.0, 100, 10);
        let graph = GrainGraph::build(&grains, 0.1, &CostModel::default());
        metrics(&graph, &grains, part, parts).unwrap()
    }

    #[test]
    fn one_rank_is_its_elements_and_edges_only() {
        let p = project_step(&chain_metrics(&[0; 4], 1), &costs());
        assert_eq!(p.compute, 400.0 * 1e-8 + 3.0 * 1e-6);
        assert_eq!((p.halo, p.reductions, p.max_halo_bytes), (0.0, 0.0, 0.0));
        assert_eq!(p.total, p.compute);
    }

    #[test]
    fn a_split_chain_adds_its_cut_edge_on_both_sides_its_halo_and_the_reductions() {
        let c = costs();
        let p = project_step(&chain_metrics(&[0, 0, 1, 1], 2), &c);
        // each half: 200 elements, its inner edge and the cut edge
        assert_eq!(p.compute, 200.0 * 1e-8 + 2.0 * 1e-6);
        let halo = 1000.0 * 1e-9 + 2e-6 + 1000.0 / 1e10;
        assert!((p.halo - halo).abs() < 1e-18, "{} {halo}", p.halo);
        let reduce = |n: f64| 2.0 * 2e-6 + 2.0 * 0.5 * 8.0 * n / 1e10;
        assert!((p.reductions - reduce(100.0) - reduce(6.0) / 4.0).abs() < 1e-18);
        assert!((p.total - (p.compute + p.halo + p.reductions)).abs() < 1e-18);
        assert_eq!(p.max_halo_bytes, 1000.0);
    }

    #[test]
    fn a_non_blocking_reduction_costs_what_the_element_work_behind_it_does_not_hide() {
        let metrics = chain_metrics(&[0, 0, 1, 1], 2);
        let reduce = |n: f64| 2.0 * 2e-6 + 2.0 * 0.5 * 8.0 * n / 1e10;
        let mut c = costs();
        // a part's element work is 200 × 1e-8 s = 2 µs; a tenth of it hides 0.2 µs
        c.reductions[0].hidden_behind = 0.1;
        let p = project_step(&metrics, &c);
        let hidden = 0.1 * 200.0 * 1e-8;
        let expected = reduce(100.0) - hidden + reduce(6.0) / 4.0;
        assert!((p.reductions - expected).abs() < 1e-18, "{}", p.reductions);
        // hidden entirely, it costs nothing, not less than nothing
        c.reductions[0].hidden_behind = 100.0;
        let p = project_step(&metrics, &c);
        assert!(
            (p.reductions - reduce(6.0) / 4.0).abs() < 1e-18,
            "{}",
            p.reductions
        );
    }

    #[test]
    fn the_slowest_part_sets_the_step() {
        // part 1 holds three grains, part 0 one
        let p = project_step(&chain_metrics(&[0, 1, 1, 1], 2), &costs());
        assert_eq!(p.compute, 300.0 * 1e-8 + 3.0 * 1e-6);
    }
}
