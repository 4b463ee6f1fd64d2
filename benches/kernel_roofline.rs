//! The internal-force kernel against the machine: tet updates per second of every law
//! beside a STREAM-triad bandwidth measured in the same run, the bytes each law moves per
//! element, the bandwidth ceiling (triad bytes/s ÷ bytes per element), the compute ceiling
//! (the same kernel on one thread on a mesh that fits in L2, times the threads), the compute
//! ceiling as a fraction of the bandwidth ceiling (below 60 %, issue 14's item 1 cannot be
//! met on this machine by moving memory better: the arithmetic alone is slower) and, when
//! given, the ratio to the reference kernel `tetbench`.
//!
//! How to run:  scripts/bench_vs_reference TETBENCH_DIR   (builds and runs tetbench too)
//!         or:  cargo bench --bench kernel_roofline -- [--tetbench UPDATES_PER_S] [--threads N]
//!                  [--seeding M]   (the large mesh's seeding, m; default 7e-5)
//!                  [--law NAME]    (one law only, e.g. biot, to profile it)
//!                  [--passes N]    (no timing: N force passes of each law on the large
//!                                   mesh, for an instruction counter;
//!                                   `scripts/kernel_instructions` runs it under callgrind)
//!                  [--list-laws]   (the laws' names, one a line)
//!
//! Model: one glass sphere R = 1.1 mm at seeding 70 µm (≈ 1.5·10⁵ tets, the mesh of
//! `benches/internal_force.rs`), built the way `mufe run` builds it; one call of
//! `compute_internal_forces_into` per timing, at a rotated (0.3 rad) and stretched (10⁻³)
//! configuration (`common::deformed`), alternating sign so the plastic law reverses its flow on every call.
//! Best of several rounds, like tetbench. Results: docs/BENCHMARKS.md.

mod common;

use mufe::lanes::NodeForce;
use mufe::material::PlasticPoint;
use mufe::solver::forces::{bytes_moved_per_element, compute_internal_forces_into, ElementScratch};
use mufe::solver::Solver;
use std::sync::Mutex;
use std::time::Instant;

const RADIUS: f64 = 1.1e-3;
/// Seeding of the large mesh (≥ 10⁵ tets, ≈ 16 MB: beyond L2, but inside a 32 MiB L3;
/// docs/BENCHMARKS.md, session 21, has the same kernel on a mesh that only DRAM holds).
const SEEDING: f64 = 7.0e-5;
/// Seeding of the in-cache mesh (a few thousand tets, < 1 MiB of model data).
const SEEDING_IN_CACHE: f64 = 2.6e-4;

/// Spread of the triad readings (best ÷ lowest) beyond which the run says that the
/// machine's bandwidth changed while it ran: a run's readings usually agree within 30 %.
const TRIAD_SPREAD_NOTED: f64 = 1.3;

/// One law's glass sphere at one seeding, its two deformed configurations, and what a force
/// pass writes.
struct SpherePasses {
    solver: Solver,
    configurations: [Vec<[f64; 3]>; 2],
    scratch: ElementScratch,
    plastic: Vec<PlasticPoint>,
    force: Vec<NodeForce>,
}

impl SpherePasses {
    /// Built in the pool that will run the passes: the chunk schedule follows its threads.
    fn new(law_lines: &str, seeding: f64) -> Self {
        let solver = common::sphere_solver("kernel_roofline.rs", law_lines, RADIUS, seeding);
        let model = &solver.model;
        Self {
            configurations: [
                common::deformed(&model.x0, 1.0),
                common::deformed(&model.x0, -1.0),
            ],
            scratch: ElementScratch::new(model),
            plastic: solver.state.plastic.clone(),
            force: vec![NodeForce::ZERO; model.num_nodes()],
            solver,
        }
    }

    /// Force pass `k` (the configurations alternate); its plastic work (J).
    fn run(&mut self, k: usize) -> f64 {
        let s = compute_internal_forces_into(
            &self.solver.model,
            &self.configurations[k % 2],
            &mut self.plastic,
            &mut self.scratch,
            &mut self.force,
        );
        assert!(s.bad_element.is_none());
        s.plastic_work
    }
}

/// Tet updates per second of one law on one mesh, best of `rounds`.
fn kernel_rate(law_lines: &str, seeding: f64, rounds: usize) -> (f64, f64, usize, String) {
    let mut passes = SpherePasses::new(law_lines, seeding);
    let ne = passes.solver.model.num_elements();
    let schedule = &passes.scratch.schedule;
    println!(
        "kernel_roofline: {ne} tets in {} chunks of ≤ 512 in {} colours",
        schedule.chunks.len(),
        schedule.colours.len()
    );
    // enough calls per round for ~0.2 s
    let calls = (30_000_000 / ne).clamp(4, 20_000);
    let mut best = f64::INFINITY;
    let mut plastic_branch = 0.0;
    for _ in 0..rounds {
        let t0 = Instant::now();
        for k in 0..calls {
            plastic_branch = passes.run(k);
        }
        best = best.min(t0.elapsed().as_secs_f64());
    }
    let (model, scratch) = (&passes.solver.model, &passes.scratch);
    let bytes = bytes_moved_per_element(model, &scratch.schedule, plastic_branch > 0.0);
    (
        (ne * calls) as f64 / best,
        bytes,
        ne,
        scratch.path.name().to_string(),
    )
}

/// `count` force passes of one law on one thread, untimed, printing what an instruction
/// count is divided by: "law NAME elements N passes P path PATH".
fn run_passes(name: &str, law_lines: &str, seeding: f64, count: usize) {
    let single = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("rayon pool");
    single.install(|| {
        let mut passes = SpherePasses::new(law_lines, seeding);
        (0..count).for_each(|k| {
            passes.run(k);
        });
        println!(
            "law {name} elements {} passes {count} path {}",
            passes.solver.model.num_elements(),
            passes.scratch.path.name()
        );
    });
}

/// STREAM triad a = b + s·c over arrays far beyond the caches: bytes/s counted as
/// STREAM does (24 B per index, no write-allocate), best of 5 after a first pass that
/// faults the pages in. Each thread of the pool streams one fixed part of the arrays, as
/// STREAM's static schedule does (work stealing would interleave the parts).
fn triad_bytes_per_s() -> f64 {
    const N: usize = 1 << 25; // 256 MiB per array
    let b = vec![1.0f64; N];
    let c = vec![2.0f64; N];
    let mut a = vec![0.0f64; N];
    let threads = rayon::current_num_threads();
    let part = N.div_ceil(threads);
    let parts: Vec<Mutex<&mut [f64]>> = a.chunks_mut(part).map(Mutex::new).collect();
    let mut best = f64::INFINITY;
    for round in 0..6 {
        let s = 3.0 + round as f64;
        let t0 = Instant::now();
        rayon::broadcast(|ctx| {
            let mut a = parts[ctx.index()].lock().expect("one part per thread");
            let first = ctx.index() * part;
            let (b, c) = (&b[first..first + a.len()], &c[first..first + a.len()]);
            for ((a, b), c) in a.iter_mut().zip(b).zip(c) {
                *a = b + s * c;
            }
        });
        let t = t0.elapsed().as_secs_f64();
        if round > 0 {
            best = best.min(t);
        }
    }
    drop(parts);
    assert!(a[N / 2] == 1.0 + 8.0 * 2.0);
    (24 * N) as f64 / best
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let value_of = |flag: &str| {
        args.iter()
            .position(|a| a == flag)
            .and_then(|i| args.get(i + 1))
            .map(|v| v.parse::<f64>().expect("a number after the flag"))
    };
    let tetbench = value_of("--tetbench");
    let threads = value_of("--threads").map_or(2, |t| t as usize);
    // 3.3e-5 gives ≈ 1.5·10⁶ tets (≈ 160 MB), a mesh only DRAM holds
    let seeding = value_of("--seeding").unwrap_or(SEEDING);
    // one law only, e.g. to profile it
    let only_law = (args.iter().position(|a| a == "--law")).and_then(|i| args.get(i + 1).cloned());
    if args.iter().any(|a| a == "--list-laws") {
        common::LAWS.iter().for_each(|(name, _)| println!("{name}"));
        return;
    }
    if let Some(passes) = value_of("--passes") {
        for (name, lines) in common::LAWS {
            if only_law.as_ref().is_none_or(|only| only == name) {
                run_passes(name, lines, seeding, passes as usize);
            }
        }
        return;
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("rayon pool");
    let single = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("rayon pool");
    pool.install(|| {
        // This guest's DRAM bandwidth changes by up to 2× from one minute to the next
        // (docs/BENCHMARKS.md, session 39) while the kernel, in L3, does not follow it: the
        // triad is measured before every law and once after, and the ceiling uses the
        // best, the bandwidth the machine has shown it can give.
        let mut triads = vec![triad_bytes_per_s()];
        let mut rows = Vec::new();
        for (name, lines) in common::LAWS {
            if only_law.as_ref().is_some_and(|only| only != name) {
                continue;
            }
            let (rate, bytes, ne, path) = kernel_rate(lines, seeding, 5);
            let (in_cache, _, _, _) = single.install(|| kernel_rate(lines, SEEDING_IN_CACHE, 5));
            rows.push((name, ne, rate, bytes, in_cache * threads as f64, path));
            triads.push(triad_bytes_per_s());
        }
        let triad = triads.iter().copied().fold(0.0, f64::max);
        let each: Vec<String> = triads.iter().map(|t| format!("{:.1}", t / 1e9)).collect();
        println!(
            "kernel_roofline: {threads} threads; STREAM triad {:.1} GB/s (best of {} measurements between the laws: {} GB/s)",
            triad / 1e9,
            triads.len(),
            each.join(", ")
        );
        let lowest = triads.iter().copied().fold(f64::INFINITY, f64::min);
        if triad > TRIAD_SPREAD_NOTED * lowest {
            println!(
                "kernel_roofline: note: the triad readings differ by {:.1}× ({:.1} to {:.1} GB/s): the \
                 machine's bandwidth changed during the run, and the ceilings below use the best \
                 reading (docs/BENCHMARKS.md, session 65)",
                triad / lowest,
                lowest / 1e9,
                triad / 1e9
            );
        }
        if let Some(t) = tetbench {
            println!("kernel_roofline: tetbench grid 30, {threads} threads: {t:.3e} tet updates/s");
        }
        println!(
            "| law | tets | updates/s | bytes/element | bandwidth ceiling | of it | compute ceiling | of it | compute ÷ bandwidth ceiling | vs tetbench | path |"
        );
        println!("|---|---|---|---|---|---|---|---|---|---|---|");
        for (name, ne, rate, bytes, compute, path) in rows {
            let ceiling = triad / bytes;
            let vs = tetbench.map_or("–".to_string(), |t| format!("{:.2}×", rate / t));
            println!(
                "| {name} | {ne} | {rate:.3e} | {bytes:.0} | {ceiling:.3e} | {:.0} % | {compute:.3e} | {:.0} % | {:.0} % | {vs} | {path} |",
                100.0 * rate / ceiling,
                100.0 * rate / compute,
                100.0 * compute / ceiling,
            );
        }
    });
}
