//! Partition quality, METIS run time and the projected step time of the 2000-grain FCC
//! cell over 2 to 1024 ranks (docs/BENCHMARKS.md, "Projection to cluster scale").
//!
//! Grains: R = 1.1 mm spheres in an FCC block (5 × 10 × 10 unit cells), partitioned as
//! `mufe run` does (ghost margin ¼ R, default cost model, METIS seed 1). The step costs are
//! measured in the paper-resolution run of `jobs/fcc/fcc_2000.toml` on 2 ranks
//! (docs/BENCHMARKS.md, session 38: 2328 elements and 473 surface nodes per grain; per
//! rank and step 27.3 ms forces + 3.05 integrate + 0.27 output over 2 328 000 elements,
//! 8.41 ms contact over 5 424 graph edges, 0.40 ms halo for 483 935 B sent over 397 cut
//! edges); each can be replaced by a flag. The network (latency, bandwidth per rank) is
//! assumed: 2 µs and 12.5 GB/s, an InfiniBand HDR-class link.
//!
//! Run with `cargo run --release -p partition --example fcc_stats [-- --flag value ...]`;
//! flags: --elements-per-grain, --surface-nodes-per-grain, --element-seconds,
//! --integrate-share (of the element work: the walls' non-blocking sum runs behind it),
//! --contact-seconds-per-edge, --halo-bytes-per-cut-edge, --halo-seconds-per-byte,
//! --latency, --bandwidth, --steps.

use std::process::ExitCode;
use std::time::{Duration, Instant};

use partition::{
    fcc_block_cells, fcc_packing, metrics, partition, project_step, CostModel, GrainGraph,
    GrainInfo, PartitionError, Reduction, StepCosts,
};

const GRAIN_COUNT: usize = 2000;
const RADIUS: f64 = 1.1e-3; // m
const PART_COUNTS: [usize; 9] = [2, 8, 16, 32, 64, 128, 256, 512, 1024];
/// `partition` (METIS + balance repair) is timed as the fastest of this many
/// identical runs.
const TIMING_REPEATS: usize = 5;
/// The seed `mufe run` partitions with.
const SEED: i32 = 1;

/// The measured run (see the module doc), each replaceable by `--name value`.
struct Inputs {
    elements_per_grain: f64,
    surface_nodes_per_grain: f64,
    element_seconds: f64,
    integrate_share: f64,
    contact_seconds_per_edge: f64,
    halo_bytes_per_cut_edge: f64,
    halo_seconds_per_byte: f64,
    latency: f64,
    bandwidth: f64,
    steps: f64,
}

impl Inputs {
    fn from_args() -> Result<Self, String> {
        let mut inputs = Self {
            elements_per_grain: 2328.0,
            surface_nodes_per_grain: 473.0,
            element_seconds: (27.3e-3 + 3.05e-3 + 0.27e-3) / 2_328_000.0,
            integrate_share: 3.05 / (27.3 + 3.05 + 0.27),
            contact_seconds_per_edge: 8.41e-3 / 5424.0,
            halo_bytes_per_cut_edge: 483_935.0 / 397.0,
            halo_seconds_per_byte: 0.40e-3 / 483_935.0,
            latency: 2e-6,
            bandwidth: 12.5e9,
            steps: 61_932.0,
        };
        let args: Vec<String> = std::env::args().skip(1).collect();
        for pair in args.chunks(2) {
            let [flag, value] = pair else {
                return Err(format!("'{}' needs a value", pair[0]));
            };
            let value: f64 = value
                .parse()
                .ok()
                .filter(|v: &f64| v.is_finite() && *v > 0.0)
                .ok_or_else(|| format!("{flag}: '{value}' is not a positive number"))?;
            let slot = match flag.as_str() {
                "--elements-per-grain" => &mut inputs.elements_per_grain,
                "--surface-nodes-per-grain" => &mut inputs.surface_nodes_per_grain,
                "--element-seconds" => &mut inputs.element_seconds,
                "--integrate-share" => &mut inputs.integrate_share,
                "--contact-seconds-per-edge" => &mut inputs.contact_seconds_per_edge,
                "--halo-bytes-per-cut-edge" => &mut inputs.halo_bytes_per_cut_edge,
                "--halo-seconds-per-byte" => &mut inputs.halo_seconds_per_byte,
                "--latency" => &mut inputs.latency,
                "--bandwidth" => &mut inputs.bandwidth,
                "--steps" => &mut inputs.steps,
                other => return Err(format!("unknown flag '{other}'")),
            };
            *slot = value;
        }
        if inputs.integrate_share > 1.0 {
            return Err(format!(
                "--integrate-share: {} is more than the whole element work (at most 1)",
                inputs.integrate_share
            ));
        }
        Ok(inputs)
    }
}

fn main() -> ExitCode {
    let inputs = match Inputs::from_args() {
        Ok(inputs) => inputs,
        Err(message) => {
            eprintln!("fcc_stats: {message}");
            return ExitCode::from(2);
        }
    };
    match run(&inputs) {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("fcc_stats: {error}");
            ExitCode::FAILURE
        }
    }
}

fn run(inputs: &Inputs) -> Result<(), PartitionError> {
    let grains: Vec<GrainInfo> = fcc_packing(GRAIN_COUNT, RADIUS)
        .into_iter()
        .map(|centre| GrainInfo {
            centre,
            bounding_radius: RADIUS,
            elements: inputs.elements_per_grain as usize,
            surface_nodes: inputs.surface_nodes_per_grain as usize,
        })
        .collect();
    // `mufe run`'s ghost margin (`model::global::ghost_margin`)
    let margin = 0.25 * RADIUS;
    let graph = GrainGraph::build(&grains, margin, &CostModel::default());
    let cells = fcc_block_cells(GRAIN_COUNT).unwrap_or([0; 3]);
    println!(
        "FCC sample: {} grains ({} x {} x {} cells), R = {:.2} mm, ghost margin {:.3} mm; {} graph edges",
        grains.len(),
        cells[0],
        cells[1],
        cells[2],
        RADIUS * 1e3,
        margin * 1e3,
        graph.n_edges()
    );
    println!(
        "measured per step (one core): {:.3e} s per element ({} per grain), {:.3e} s per contact edge, \
         {:.0} B halo per cut edge at {:.3e} s/B",
        inputs.element_seconds,
        inputs.elements_per_grain,
        inputs.contact_seconds_per_edge,
        inputs.halo_bytes_per_cut_edge,
        inputs.halo_seconds_per_byte
    );
    // mufe's all-reduces: the surface motion per grain (4 values each, and 3 more) every
    // step, the walls' normal force per grain (6 walls) every step, non-blocking while
    // the rank integrates, the energy check's 6 values every
    // `solver::step::ENERGY_CHECK_EVERY` = 16 steps
    let every = |values: usize, steps: f64| Reduction {
        values,
        every_steps: steps,
        hidden_behind: 0.0,
    };
    let behind_integration = |values: usize| Reduction {
        hidden_behind: inputs.integrate_share,
        ..every(values, 1.0)
    };
    // the rebuild decision's values (largest motion, rebuild vote, travel) and the walls
    const REBUILD_VALUES: usize = 3;
    const WALLS: usize = 6;
    let per_grain = [
        every(4 * GRAIN_COUNT + REBUILD_VALUES, 1.0),
        behind_integration(WALLS * GRAIN_COUNT),
    ];
    let energy = every(6, 16.0);
    println!(
        "all-reduces: {} + {} values per step (surface motion per grain, walls' forces per grain), 6 every 16 steps (energy); \
         the walls' sum behind the integrator ({:.1} % of the element work); network assumed: {:.1} µs latency, {:.1} GB/s per rank",
        per_grain[0].values,
        per_grain[1].values,
        100.0 * inputs.integrate_share,
        inputs.latency * 1e6,
        inputs.bandwidth / 1e9
    );
    println!(
        "the last column: the same with the per-grain values exchanged between neighbours in \
         the halo messages; the rebuild decision (3 values) and the walls' totals (6) still \
         need an all-reduce every step"
    );
    let costs = |reductions: Vec<Reduction>| StepCosts {
        element_seconds: inputs.element_seconds,
        contact_seconds_per_edge: inputs.contact_seconds_per_edge,
        halo_bytes_per_cut_edge: inputs.halo_bytes_per_cut_edge,
        halo_seconds_per_byte: inputs.halo_seconds_per_byte,
        reductions,
        latency: inputs.latency,
        bandwidth: inputs.bandwidth,
    };
    let today = costs(vec![per_grain[0], per_grain[1], energy]);
    // what no neighbour exchange can replace: every rank must take the same rebuild
    // decision and move the walls by the same total forces
    let global_only = costs(vec![
        every(REBUILD_VALUES, 1.0),
        behind_integration(WALLS),
        energy,
    ]);
    println!();
    println!(
        "| parts | imbalance | cut edges | cut edges/part max | neighbours max | halo kB/step max | METIS ms \
         | compute ms | halo ms | reduce ms | step ms | run min | efficiency | without per-grain reduce |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    let mut reference: Option<(f64, f64)> = None;
    for parts in PART_COUNTS {
        let mut best_time = Duration::MAX;
        let mut part = Vec::new();
        for _ in 0..TIMING_REPEATS {
            let start = Instant::now();
            part = partition(&graph, parts, SEED)?;
            best_time = best_time.min(start.elapsed());
        }
        let quality = metrics(&graph, &grains, &part, parts)?;
        let step = project_step(&quality, &today);
        let lean = project_step(&quality, &global_only);
        // strong-scaling efficiency against the 2-rank row, the measured configuration
        let (two_ranks, two_ranks_lean) =
            *reference.get_or_insert((2.0 * step.total, 2.0 * lean.total));
        let max = |v: &[usize]| v.iter().copied().max().unwrap_or(0);
        println!(
            "| {parts} | {:.2} % | {} | {} | {} | {:.1} | {:.1} | {:.3} | {:.3} | {:.3} | {:.3} | {:.1} | {:.0} % | {:.0} % |",
            100.0 * quality.imbalance,
            quality.cut_edges,
            max(&quality.cut_edges_per_part),
            max(&quality.neighbour_parts_per_part),
            step.max_halo_bytes / 1e3,
            ms(best_time),
            step.compute * 1e3,
            step.halo * 1e3,
            step.reductions * 1e3,
            step.total * 1e3,
            step.total * inputs.steps / 60.0,
            100.0 * two_ranks / (parts as f64 * step.total),
            100.0 * two_ranks_lean / (parts as f64 * lean.total),
        );
    }
    Ok(())
}

fn ms(duration: Duration) -> f64 {
    duration.as_secs_f64() * 1e3
}
