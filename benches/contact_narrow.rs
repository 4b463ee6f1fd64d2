//! The contact stage's narrow phase (`mufe::contact::evaluate`) on a block of the paper's
//! FCC packing with every lattice contact loaded, beside the internal-force pass on the
//! same model in the same run: how many element updates one evaluated contact entry costs,
//! with its data in cache and with the caches emptied first (as the element stage leaves
//! them in a step).
//!
//! How to run:  cargo bench --bench contact_narrow
//!   (shorter: cargo bench --bench contact_narrow -- --measurement-time 3 --warm-up-time 1)
//!
//! Scene: `jobs/fcc/fcc_2000.toml` cut to 3×3×2 cubic cells, at the paper's contact
//! resolution (99 µm surface edges at the contacts, 400 µm elsewhere: the mesh of the
//! paper-resolution run in docs/BENCHMARKS.md), built through the real scene path. Each
//! grain is moved rigidly towards the block's centre so that every lattice contact
//! overlaps by δ = [`OVERLAP_PER_RADIUS`]·R, the order of the isotropic stage's contacts at
//! 50 kPa (Hertz: δ/R* = (3F/(4E*R*²))^{2/3}, R* = R/2, a few 10⁻⁴ for F ≈ σ₃(2R)²): one
//! node pair or a few per contact, as in the run. The walls are kept (their contacts are
//! not part of `evaluate`). One `evaluate` is one step's worth: detection check, the
//! entries within reach, the friction history.
//! Results: docs/BENCHMARKS.md ("The contact narrow phase in isolation").

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use mufe::contact::ContactState;
use mufe::lanes::NodeForce;
use mufe::math::centroid;
use mufe::solver::forces::{compute_internal_forces_into, ElementScratch};
use std::hint::black_box;
use std::time::{Duration, Instant};

/// Overlap of each lattice contact over the sphere radius (see the module docs).
const OVERLAP_PER_RADIUS: f64 = 1.0e-4;
/// Bytes streamed between two timed calls of the cold variant: twice the largest L3 of the
/// machines in docs/BENCHMARKS.md (32 MiB).
const EVICT_BYTES: usize = 64 << 20;

fn block_solver() -> mufe::solver::Solver {
    let file = "jobs/fcc/fcc_2000.toml";
    let text = std::fs::read_to_string(file).expect("the FCC job file");
    let overrides = [
        "packings[0].cells=[3, 3, 2]",
        "packings[0].sphere={radius=1.1e-3, seeding=4e-4, contact_seeding=9.9e-5, contact_growth=0.5, axis_patches=true}",
    ]
    .map(String::from);
    let loaded = mufe::scene::parse_scene(file, &text, &overrides).expect("block scene");
    mufe::solver::build_solver(&loaded).expect("block model")
}

/// Positions with every grain moved rigidly towards the centroid of the grain centres by
/// the fraction that makes neighbours touching at 2R overlap by δ = `overlap_per_radius`·R:
/// every centre offset shrinks by δ/(2R).
fn compressed(model: &mufe::model::Model, overlap_per_radius: f64) -> Vec<[f64; 3]> {
    let centres: Vec<[f64; 3]> = (model.grains.iter())
        .map(|g| centroid(&model.x0[g.nodes.clone()]))
        .collect();
    let block = centroid(&centres);
    let shrink = 0.5 * overlap_per_radius;
    let mut x = model.x0.clone();
    for (g, c) in model.grains.iter().zip(&centres) {
        let shift = [0, 1, 2].map(|i| -shrink * (c[i] - block[i]));
        for p in &mut x[g.nodes.clone()] {
            (0..3).for_each(|i| p[i] += shift[i]);
        }
    }
    x
}

/// Streams `buffer` (read and write), emptying the caches of everything else.
fn evict(buffer: &mut [u64]) {
    for line in buffer.chunks_exact_mut(8) {
        line[0] = line[0].wrapping_add(1);
    }
    black_box(&buffer[0]);
}

/// Calls `f` until `duration` has passed: a warm-up as long as criterion's, after which
/// the machine runs at the speed criterion measures.
fn repeat_for(duration: Duration, mut f: impl FnMut()) {
    let start = Instant::now();
    while start.elapsed() < duration {
        f();
    }
}

fn contact_narrow(c: &mut Criterion) {
    let solver = block_solver();
    let model = &solver.model;
    let dt = model.dt;
    let x = compressed(model, OVERLAP_PER_RADIUS);
    let v = vec![[0.0; 3]; x.len()];
    let mut state = ContactState::new(model);
    let mut scratch = mufe::contact::ContactScratch::default();
    // the first call builds the lists; the friction history it leaves makes every later
    // call a sticking step, as in the loaded run
    for _ in 0..2 {
        mufe::contact::evaluate(model, &x, &v, 0.0, 0, dt, &mut state, &mut scratch)
            .expect("no tunnelling");
    }
    let entries = scratch.results.len();
    let points = scratch.results.iter().filter(|r| r.active).count();
    let grains = model.grains.len();
    assert!(
        points >= 6 * grains,
        "only {points} active points for {grains} grains: the block is not loaded"
    );
    let elements = model.num_elements();

    // the reference in the same run: one internal-force pass over the same model, 1 thread
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("rayon pool");
    let mut plastic = solver.state.plastic.clone();
    let mut elements_scratch = ElementScratch::new(model);
    let mut force = vec![NodeForce::ZERO; x.len()];
    let mut forces_once = || {
        pool.install(|| {
            compute_internal_forces_into(model, &x, &mut plastic, &mut elements_scratch, &mut force)
        })
    };
    // warmed up as the evaluations below are
    repeat_for(Duration::from_secs(1), || {
        black_box(forces_once());
    });
    const FORCE_PASSES: u32 = 20;
    let t0 = Instant::now();
    for _ in 0..FORCE_PASSES {
        black_box(forces_once());
    }
    let per_pass = t0.elapsed().as_secs_f64() / f64::from(FORCE_PASSES);
    let ns_per_element = 1e9 * per_pass / elements as f64;

    let mut buffer = vec![0u64; EVICT_BYTES / 8];
    let mut time_evaluate = |cold: bool, iters: u64, state: &mut ContactState, scratch: &mut _| {
        let mut total = Duration::ZERO;
        for _ in 0..iters {
            if cold {
                evict(&mut buffer);
            }
            let t0 = Instant::now();
            mufe::contact::evaluate(model, &x, &v, 0.0, 0, dt, state, scratch)
                .expect("no tunnelling");
            total += t0.elapsed();
        }
        total
    };
    const REPEATS: usize = 60;
    for (name, cold) in [("warm", false), ("cold", true)] {
        // as long as criterion's warm-up: after ten calls the printed figures read 30–60 %
        // above criterion's (docs/BENCHMARKS.md, session 65)
        repeat_for(Duration::from_secs(2), || {
            time_evaluate(cold, 10, &mut state, &mut scratch);
        });
        // the median of single calls, like criterion's figures
        let mut calls: Vec<f64> = (0..REPEATS)
            .map(|_| time_evaluate(cold, 1, &mut state, &mut scratch).as_secs_f64())
            .collect();
        calls.sort_by(f64::total_cmp);
        let (t, mean) = (
            calls[REPEATS / 2],
            calls.iter().sum::<f64>() / REPEATS as f64,
        );
        let ns_entry = 1e9 * t / entries as f64;
        println!(
            "contact_narrow/{name}: {grains} grains, {elements} elements, {entries} entries evaluated, \
             {points} active: {:.1} µs per evaluation (median of {REPEATS} calls; mean {:.1}), \
             {ns_entry:.0} ns per entry = {:.1} element updates (internal forces \
             {ns_per_element:.1} ns per element, 1 thread, same run); evaluation = {:.3} × the force pass",
            1e6 * t,
            1e6 * mean,
            ns_entry / ns_per_element,
            t / per_pass
        );
    }

    let mut group = c.benchmark_group("contact_narrow");
    group.throughput(Throughput::Elements(entries as u64));
    group.bench_function("warm", |b| {
        b.iter_custom(|iters| time_evaluate(false, iters, &mut state, &mut scratch))
    });
    group.bench_function("cold", |b| {
        b.iter_custom(|iters| time_evaluate(true, iters, &mut state, &mut scratch))
    });
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20).measurement_time(Duration::from_secs(8));
    targets = contact_narrow
}
criterion_main!(benches);
