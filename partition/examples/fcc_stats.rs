//! Partition quality and METIS run time for a 2000-grain FCC sample over a
//! range of rank counts.
//!
//! Grains: R = 1.1 mm spheres in an FCC block (5 × 10 × 10 unit cells), each
//! meshed with a graded mesh estimated at 8000 tetrahedra and 1500 surface
//! nodes; contact margin 0.1 R; default cost model.
//!
//! Run with `cargo run --release -p partition --example fcc_stats`.

use std::process::ExitCode;
use std::time::{Duration, Instant};

use partition::{
    fcc_block_cells, fcc_packing, metrics, partition, CostModel, GrainGraph, GrainInfo,
    PartitionError, HALO_BYTES_PER_GHOST_NODE,
};

const GRAIN_COUNT: usize = 2000;
const RADIUS: f64 = 1.1e-3; // m
const ELEMENTS_PER_GRAIN: usize = 8000;
const SURFACE_NODES_PER_GRAIN: usize = 1500;
const PART_COUNTS: [usize; 8] = [8, 16, 32, 64, 128, 256, 512, 1024];
/// `partition` (METIS + balance repair) is timed as the fastest of this many
/// identical runs.
const TIMING_REPEATS: usize = 5;
const SEED: i32 = 0;

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("fcc_stats: {error}");
            ExitCode::FAILURE
        }
    }
}

fn run() -> Result<(), PartitionError> {
    let grains: Vec<GrainInfo> = fcc_packing(GRAIN_COUNT, RADIUS)
        .into_iter()
        .map(|centre| GrainInfo {
            centre,
            bounding_radius: RADIUS,
            elements: ELEMENTS_PER_GRAIN,
            surface_nodes: SURFACE_NODES_PER_GRAIN,
        })
        .collect();
    let margin = 0.1 * RADIUS;
    let cost = CostModel::default();

    let build_start = Instant::now();
    let graph = GrainGraph::build(&grains, margin, &cost);
    let build_time = build_start.elapsed();

    let cells = fcc_block_cells(GRAIN_COUNT).unwrap_or([0; 3]);
    println!(
        "FCC sample: {} grains ({} x {} x {} cells), R = {:.2} mm, margin = {:.3} mm",
        grains.len(),
        cells[0],
        cells[1],
        cells[2],
        RADIUS * 1e3,
        margin * 1e3
    );
    println!(
        "grain graph: {} contacts, mean degree {:.2}, built in {:.2} ms",
        graph.n_edges(),
        2.0 * graph.n_edges() as f64 / graph.n_grains() as f64,
        ms(build_time)
    );
    println!(
        "per grain: {} elements, {} surface nodes, cost {} units/step (vertex weight {}); \
         contact edge weight {} ({:.1} cost units)",
        ELEMENTS_PER_GRAIN,
        SURFACE_NODES_PER_GRAIN,
        cost.grain_cost(&grains[0]),
        graph.vertex_weights()[0],
        graph.adjwgt()[0],
        graph.edge_costs()[0]
    );
    println!(
        "halo: whole surface of each ghost grain, {HALO_BYTES_PER_GHOST_NODE} B per ghost node per step \
         (48 B x,v forward + 24 B force back)\n\
         METIS ms = wall time of partition() (METIS + balance repair), best of {TIMING_REPEATS}"
    );
    println!();
    println!(
        "{:>5} {:>10} {:>9} {:>9} {:>11} {:>12} {:>14} {:>14} {:>10}",
        "parts",
        "imbalance",
        "edge cut",
        "cut edges",
        "ghosts max",
        "ghosts mean",
        "halo MB/step",
        "max/part MB",
        "METIS ms"
    );

    for parts in PART_COUNTS {
        let mut best_time = Duration::MAX;
        let mut part = Vec::new();
        for _ in 0..TIMING_REPEATS {
            let start = Instant::now();
            part = partition(&graph, parts, SEED)?;
            best_time = best_time.min(start.elapsed());
        }
        let quality = metrics(&graph, &grains, &part, parts)?;
        let empty_parts = quality.grains_per_part.iter().filter(|&&n| n == 0).count();
        println!(
            "{:>5} {:>9.2}% {:>9} {:>9} {:>11} {:>12.1} {:>14.3} {:>14.3} {:>10.2}{}",
            parts,
            100.0 * quality.imbalance,
            quality.edge_cut,
            quality.cut_edges,
            quality.max_ghost_grains(),
            quality.mean_ghost_grains(),
            quality.halo_bytes_per_step as f64 / 1e6,
            quality.max_halo_bytes_per_part() as f64 / 1e6,
            ms(best_time),
            if empty_parts > 0 {
                format!("  ({empty_parts} empty parts)")
            } else {
                String::new()
            }
        );
    }

    println!();
    let part = partition(&graph, 8, SEED)?;
    println!("{}", metrics(&graph, &grains, &part, 8)?);
    Ok(())
}

fn ms(duration: Duration) -> f64 {
    duration.as_secs_f64() * 1e3
}
