//! METIS call: grain graph → part (MPI rank) of every grain.

use std::sync::Mutex;

use metis::option::Seed;
use metis::Idx;

use crate::error::PartitionError;
use crate::graph::GrainGraph;
use crate::rebalance::repair_balance;

/// Up to this many parts, multilevel recursive bisection is used; above it,
/// multilevel k-way. The METIS manual recommends recursive bisection for small
/// part counts (it balances tighter: 0.1 % tolerance per bisection against
/// k-way's 3 %) and k-way for large ones (faster, lower cut).
pub const MAX_PARTS_FOR_RECURSIVE_BISECTION: usize = 8;

/// Serialises METIS calls. The vendored METIS seeds and draws from the C
/// library's process-global `srand`/`rand` state, so two concurrent calls would
/// perturb each other's random sequence and lose determinism.
static METIS_LOCK: Mutex<()> = Mutex::new(());

/// Splits the grains of `graph` into `parts` parts of nearly equal total vertex
/// weight while minimising the weight of cut edges.
///
/// Returns `part[grain]` in `0..parts`. `parts == 1` puts every grain in part 0
/// without calling METIS. `seed` is passed to METIS' random number generator,
/// so the result is deterministic for a given graph, part count and seed.
///
/// If k-way leaves a part empty (possible when `parts` approaches the number of
/// grains) the partition is recomputed with recursive bisection, which
/// normally fills every part; an empty part is only returned if that fails too.
///
/// METIS may exceed its balance tolerance when parts hold only a few grains
/// (e.g. 9 grains on some parts at 7.8 per part = 15 % imbalance). The result
/// is therefore post-processed by a deterministic repair that moves boundary
/// grains along chains of neighbouring parts until the heaviest part is within
/// [`BALANCE_TOLERANCE`](crate::BALANCE_TOLERANCE) (3 %) of the mean or no
/// such move exists; it never empties a part and prefers the grains whose move
/// cuts the least edge weight.
///
/// Calls through this function are serialised by a process-wide lock, because
/// METIS draws random numbers from libc's global `rand()` state. Other code
/// calling `srand`/`rand` on another thread at the same time could still change
/// the result, so partition before starting such threads.
///
/// # Errors
/// `parts == 0` or `parts > graph.n_grains()`
/// ([`PartitionError::InvalidPartCount`]), a graph whose sizes or weight sums do
/// not fit METIS' 32-bit integers ([`PartitionError::TooLarge`]), or a METIS
/// failure ([`PartitionError::Metis`]).
pub fn partition(graph: &GrainGraph, parts: usize, seed: i32) -> Result<Vec<u32>, PartitionError> {
    let n_grains = graph.n_grains();
    if parts == 0 || parts > n_grains.max(1) {
        return Err(PartitionError::InvalidPartCount {
            parts,
            grains: n_grains,
        });
    }
    if parts == 1 {
        return Ok(vec![0; n_grains]);
    }

    let xadj = to_idx_vec(graph.xadj(), "adjacency offset")?;
    let adjncy = to_idx_vec(graph.adjncy(), "neighbour index")?;
    let adjwgt = to_idx_vec(graph.adjwgt(), "edge weight")?;
    let vertex_weights = to_idx_vec(graph.vertex_weights(), "vertex weight")?;
    check_sum_fits(graph.vertex_weights(), "total vertex weight")?;
    check_sum_fits(graph.adjwgt(), "total edge weight")?;
    let n_parts = to_idx(parts, "number of parts")?;

    let run = |recursive: bool| -> Result<Vec<Idx>, PartitionError> {
        let mut part: Vec<Idx> = vec![0; n_grains];
        // A poisoned lock only means another METIS call panicked; the guarded
        // state is METIS' own and is re-seeded by every call.
        let _guard = METIS_LOCK
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner());
        let metis_graph = metis::Graph::new(1, n_parts, &xadj, &adjncy)
            .map_err(|e| PartitionError::Metis(e.to_string()))?
            .set_vwgt(&vertex_weights)
            .set_adjwgt(&adjwgt)
            .set_option(Seed(seed));
        let result = if recursive {
            metis_graph.part_recursive(&mut part)
        } else {
            metis_graph.part_kway(&mut part)
        };
        result.map_err(|e| PartitionError::Metis(e.to_string()))?;
        Ok(part)
    };

    let mut part = run(parts <= MAX_PARTS_FOR_RECURSIVE_BISECTION)?;
    if parts > MAX_PARTS_FOR_RECURSIVE_BISECTION && has_empty_part(&part, parts) {
        let fallback = run(true)?;
        if !has_empty_part(&fallback, parts) {
            part = fallback;
        }
    }

    let mut part: Vec<u32> = part
        .into_iter()
        .enumerate()
        .map(|(grain, p)| match u32::try_from(p) {
            Ok(p) if (p as usize) < parts => Ok(p),
            _ => Err(PartitionError::Metis(format!(
                "returned part {p} for grain {grain}, outside 0..{parts}"
            ))),
        })
        .collect::<Result<_, _>>()?;
    repair_balance(graph, &mut part, parts);
    Ok(part)
}

fn has_empty_part(part: &[Idx], parts: usize) -> bool {
    let mut used = vec![false; parts];
    for &p in part {
        if let Some(slot) = usize::try_from(p).ok().and_then(|p| used.get_mut(p)) {
            *slot = true;
        }
    }
    used.contains(&false)
}

fn to_idx<T: TryInto<Idx> + Copy + std::fmt::Display>(
    value: T,
    what: &str,
) -> Result<Idx, PartitionError> {
    value
        .try_into()
        .map_err(|_| PartitionError::TooLarge(format!("{what} {value} exceeds {}", Idx::MAX)))
}

fn to_idx_vec<T: TryInto<Idx> + Copy + std::fmt::Display>(
    values: &[T],
    what: &str,
) -> Result<Vec<Idx>, PartitionError> {
    values.iter().map(|&v| to_idx(v, what)).collect()
}

fn check_sum_fits(weights: &[u32], what: &str) -> Result<(), PartitionError> {
    let total: u64 = weights.iter().map(|&w| u64::from(w)).sum();
    if total > Idx::MAX as u64 {
        return Err(PartitionError::TooLarge(format!(
            "{what} {total} exceeds {}",
            Idx::MAX
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grain::{CostModel, GrainInfo};
    use crate::metrics::metrics;
    use crate::packing::fcc_packing;
    use crate::test_support::{polydisperse_grains, uniform_grains, Lcg};

    const RADIUS: f64 = 1.1e-3;

    fn fcc_2000() -> (Vec<GrainInfo>, GrainGraph) {
        let grains = uniform_grains(&fcc_packing(2000, RADIUS), RADIUS, 8000, 1500);
        let graph = GrainGraph::build(&grains, 0.1 * RADIUS, &CostModel::default());
        (grains, graph)
    }

    fn assert_valid_cover(part: &[u32], n_grains: usize, parts: usize) {
        assert_eq!(part.len(), n_grains);
        let mut count = vec![0usize; parts];
        for &p in part {
            assert!((p as usize) < parts, "part {p} out of range 0..{parts}");
            count[p as usize] += 1;
        }
        assert!(
            count.iter().all(|&c| c > 0),
            "empty part among {parts}: {count:?}"
        );
    }

    #[test]
    fn metis_partitions_cover_all_grains_without_empty_parts() {
        let (_, graph) = fcc_2000();
        for parts in [2, 3, 4, 8, 16, 64, 256, 1000] {
            let part = partition(&graph, parts, 0).expect("partition");
            assert_valid_cover(&part, graph.n_grains(), parts);
        }
        let grains = polydisperse_grains(500, 3);
        let graph = GrainGraph::build(&grains, 0.02, &CostModel::default());
        for parts in [2, 5, 12, 40] {
            let part = partition(&graph, parts, 0).expect("partition");
            assert_valid_cover(&part, graph.n_grains(), parts);
        }
    }

    #[test]
    fn two_and_four_way_fcc_partitions_are_balanced_within_five_percent() {
        let (grains, graph) = fcc_2000();
        for parts in [2, 4] {
            let part = partition(&graph, parts, 0).unwrap();
            let m = metrics(&graph, &grains, &part, parts).unwrap();
            assert!(m.imbalance <= 0.05, "{parts}-way imbalance {}", m.imbalance);
            assert!(m.imbalance >= 0.0);
        }
    }

    #[test]
    fn metis_cut_is_much_smaller_than_round_robin_or_random() {
        let (grains, graph) = fcc_2000();
        let mut rng = Lcg::new(99);
        for parts in [2, 4, 16] {
            let metis_part = partition(&graph, parts, 0).unwrap();
            let round_robin: Vec<u32> = (0..grains.len()).map(|i| (i % parts) as u32).collect();
            let random: Vec<u32> = (0..grains.len())
                .map(|_| (rng.next_f64() * parts as f64) as u32)
                .collect();
            let cut = |p: &[u32]| metrics(&graph, &grains, p, parts).unwrap().edge_cut;
            let metis_cut = cut(&metis_part);
            for (name, other) in [("round robin", cut(&round_robin)), ("random", cut(&random))] {
                assert!(
                    metis_cut * 4 < other,
                    "{parts} parts: METIS cut {metis_cut} not much below {name} cut {other}"
                );
            }
        }
    }

    #[test]
    fn many_parts_with_few_grains_each_are_balanced_by_the_repair() {
        // 7.8 and 1.95 grains per part: METIS alone leaves parts with 9 and 3
        // grains (15 % and 54 % imbalance); 8 and 2 (2.4 %) are achievable.
        let (grains, graph) = fcc_2000();
        for parts in [256, 1024] {
            let part = partition(&graph, parts, 0).unwrap();
            assert_valid_cover(&part, graph.n_grains(), parts);
            let m = metrics(&graph, &grains, &part, parts).unwrap();
            assert!(
                m.imbalance <= 0.03,
                "{parts} parts: imbalance {}",
                m.imbalance
            );
        }
    }

    #[test]
    fn concurrent_calls_give_the_same_result() {
        let grains = polydisperse_grains(800, 4);
        let graph = GrainGraph::build(&grains, 0.02, &CostModel::default());
        let reference = partition(&graph, 16, 3).unwrap();
        std::thread::scope(|scope| {
            let handles: Vec<_> = (0..4)
                .map(|_| scope.spawn(|| partition(&graph, 16, 3).unwrap()))
                .collect();
            for handle in handles {
                assert_eq!(handle.join().unwrap(), reference);
            }
        });
    }

    #[test]
    fn partition_is_deterministic_for_a_seed() {
        let grains = polydisperse_grains(800, 9);
        let graph = GrainGraph::build(&grains, 0.02, &CostModel::default());
        for parts in [4, 32] {
            let first = partition(&graph, parts, 7).unwrap();
            let second = partition(&graph, parts, 7).unwrap();
            assert_eq!(first, second, "{parts} parts");
        }
    }

    #[test]
    fn single_part_and_bad_part_counts() {
        let (_, graph) = fcc_2000();
        assert_eq!(partition(&graph, 1, 0).unwrap(), vec![0; 2000]);
        let too_many = partition(&graph, 2001, 0).unwrap_err();
        assert_eq!(
            too_many,
            PartitionError::InvalidPartCount {
                parts: 2001,
                grains: 2000
            }
        );
        assert!(too_many.to_string().contains("2000 grains into 2001 parts"));
        assert!(partition(&graph, 0, 0).is_err());
        // Exactly one grain per part is allowed.
        let part = partition(&graph, 2000, 0).unwrap();
        assert_eq!(part.len(), 2000);

        let empty = GrainGraph::build(&[], 0.0, &CostModel::default());
        assert_eq!(partition(&empty, 1, 0).unwrap(), Vec::<u32>::new());
        assert!(partition(&empty, 2, 0).is_err());
    }

    #[test]
    fn graph_without_edges_is_still_balanced() {
        let grains: Vec<GrainInfo> = (0..100)
            .map(|i| GrainInfo {
                centre: [i as f64 * 10.0, 0.0, 0.0],
                bounding_radius: 1.0,
                elements: 10,
                surface_nodes: 5,
            })
            .collect();
        let graph = GrainGraph::build(&grains, 0.1, &CostModel::default());
        assert_eq!(graph.n_edges(), 0);
        for parts in [2, 4, 10, 20] {
            let part = partition(&graph, parts, 0).unwrap();
            assert_valid_cover(&part, 100, parts);
        }
    }
}
