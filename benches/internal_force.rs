//! Internal-force throughput (tet updates per second) with 1 and 2 threads.
//!
//! How to run:  cargo bench --bench internal_force
//!   (shorter: cargo bench --bench internal_force -- --measurement-time 3 --warm-up-time 1;
//!    one thread count: cargo bench --bench internal_force -- 2_threads)
//!
//! Model: one glass sphere, R = 1.1 mm, uniform seeding 70 µm (≈ 1.5·10⁵ tets), built
//! through the real scene path (`parse_scene` + `build_solver`), deformed by a rigid
//! rotation of 0.3 rad plus a 10⁻³ stretch so every element has stress. One iteration is
//! one `compute_internal_forces_into` call (element kernel + node gather), run inside a
//! local rayon pool of 1 or 2 threads; criterion reports elements/s = tet updates/s.
//! Also printed: model memory per element (`estimate_memory_bytes`) and a check that 1
//! and 2 threads give bitwise identical forces. Results: docs/BENCHMARKS.md.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use mufe::driver::summary::estimate_memory_bytes;
use mufe::scene::parse_scene;
use mufe::solver::build_solver;
use mufe::solver::forces::{compute_internal_forces_into, ElementScratch};
use std::time::Duration;

/// Sphere radius (m) and seeding (m): 70 µm gives > 10⁵ tets.
const RADIUS: f64 = 1.1e-3;
const SEEDING: f64 = 7.0e-5;

fn scene_text() -> String {
    format!(
        r#"
[simulation]
duration = 1e-6

[materials.glass]
youngs_modulus = 63e9
poisson_ratio = 0.22
density = 2500.0

[[grains]]
name = "sphere"
material = "glass"
shape = {{ sphere = {{ radius = {RADIUS:e}, seeding = {SEEDING:e} }} }}
"#
    )
}

/// x = Q (I + ε) X: rotation 0.3 rad about (1, 1, 1)/√3 after a stretch ε = diag(1, −0.3, −0.3)·10⁻³.
fn deformed(x0: &[[f64; 3]]) -> Vec<[f64; 3]> {
    let (s, c) = 0.3f64.sin_cos();
    let u = [1.0 / 3f64.sqrt(); 3];
    let mut q = [[0.0; 3]; 3];
    for (i, row) in q.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            let delta = if i == j { 1.0 } else { 0.0 };
            let cross = match (i, j) {
                (0, 1) => -u[2],
                (1, 0) => u[2],
                (0, 2) => u[1],
                (2, 0) => -u[1],
                (1, 2) => -u[0],
                (2, 1) => u[0],
                _ => 0.0,
            };
            *v = c * delta + s * cross + (1.0 - c) * u[i] * u[j];
        }
    }
    let stretch = [1.0 + 1e-3, 1.0 - 3e-4, 1.0 - 3e-4];
    x0.iter()
        .map(|p| {
            let y = [p[0] * stretch[0], p[1] * stretch[1], p[2] * stretch[2]];
            [0, 1, 2].map(|i| q[i][0] * y[0] + q[i][1] * y[1] + q[i][2] * y[2])
        })
        .collect()
}

fn internal_force(c: &mut Criterion) {
    let loaded = parse_scene("benches/internal_force.rs", &scene_text(), &[]).expect("scene");
    let solver = build_solver(&loaded).expect("model");
    let model = &solver.model;
    let (ne, nn) = (model.num_elements(), model.num_nodes());
    assert!(ne >= 100_000, "benchmark mesh has only {ne} tets");
    let bytes = estimate_memory_bytes(model);
    println!(
        "internal_force: sphere R = {RADIUS:e} m, seeding {SEEDING:e} m: {ne} tets, {nn} nodes; \
         model memory {:.1} MiB = {:.0} bytes/element",
        bytes as f64 / 1048576.0,
        bytes as f64 / ne as f64
    );

    let x = deformed(&model.x0);
    let mut scratch = ElementScratch::new(model);
    let mut force = vec![[0.0; 3]; nn];

    // 1 vs 2 threads must agree bitwise (fixed chunks + incidence gather).
    let pools: Vec<(usize, rayon::ThreadPool)> = [1, 2]
        .into_iter()
        .map(|t| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(t)
                .build()
                .expect("rayon pool");
            (t, pool)
        })
        .collect();
    let mut results = Vec::new();
    for (_, pool) in &pools {
        let summary =
            pool.install(|| compute_internal_forces_into(model, &x, &mut scratch, &mut force));
        assert!(summary.bad_element.is_none());
        results.push((summary.strain_energy.to_bits(), force.clone()));
    }
    assert!(
        results[0] == results[1],
        "1 and 2 threads give different forces"
    );
    println!(
        "internal_force: strain energy {:.6e} J, 1 and 2 threads bitwise identical",
        f64::from_bits(results[0].0)
    );

    let mut group = c.benchmark_group("internal_force");
    group.throughput(Throughput::Elements(ne as u64));
    for (threads, pool) in &pools {
        group.bench_with_input(
            BenchmarkId::new("sphere_150k_tets", format!("{threads}_threads")),
            threads,
            |b, _| {
                b.iter(|| {
                    pool.install(|| {
                        compute_internal_forces_into(model, &x, &mut scratch, &mut force)
                    })
                })
            },
        );
    }
    group.finish();
}

// Defaults (60 samples, 10 s per thread count); command-line flags such as
// `--measurement-time 3 --warm-up-time 1` override them.
criterion_group! {
    name = benches;
    config = Criterion::default()
        .sample_size(60)
        .measurement_time(Duration::from_secs(10));
    targets = internal_force
}
criterion_main!(benches);
