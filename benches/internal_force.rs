//! Internal-force throughput (tet updates per second) of every material law, side by side
//! in one run, with 1 and 2 threads.
//!
//! How to run:  cargo bench --bench internal_force
//!   (shorter: cargo bench --bench internal_force -- --measurement-time 3 --warm-up-time 1;
//!    one law or thread count: cargo bench --bench internal_force -- biot/2_threads)
//!
//! Model: one glass sphere, R = 1.1 mm, uniform seeding 70 µm (≈ 1.5·10⁵ tets), built
//! through the real scene path (`parse_scene` + `build_solver`). Laws: `biot` (the
//! default), `st_venant_kirchhoff`, `corotational`, and J2 on the Biot law in its elastic
//! branch (σy far above any stress) and its plastic branch (σy = 10 MPa, far below). One
//! iteration is two `compute_internal_forces_into` calls (element kernel + plastic state
//! update + node gather) at two configurations, a rigid rotation of 0.3 rad after a
//! stretch of +10⁻³ and of −10⁻³: every element has stress, and a plastic element reverses
//! its flow at every call, so the plastic branch is taken every time. Criterion reports
//! elements/s = tet updates/s. Also printed: model memory per element
//! (`estimate_memory_bytes`) and a check that 1 and 2 threads give bitwise identical
//! forces and plastic states. Results: docs/BENCHMARKS.md.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use mufe::driver::summary::estimate_memory_bytes;
use mufe::scene::parse_scene;
use mufe::solver::build_solver;
use mufe::solver::forces::{compute_internal_forces_into, ElementScratch};
use std::time::Duration;

/// Sphere radius (m) and seeding (m): 70 µm gives > 10⁵ tets.
const RADIUS: f64 = 1.1e-3;
const SEEDING: f64 = 7.0e-5;

/// (name, extra material lines) of the laws compared.
const LAWS: [(&str, &str); 5] = [
    ("biot", ""),
    ("st_venant_kirchhoff", "law = \"st_venant_kirchhoff\""),
    ("corotational", "law = \"corotational\""),
    ("j2_elastic", "yield_stress = 1e10\nhardening_modulus = 1e9"),
    ("j2_plastic", "yield_stress = 1e7\nhardening_modulus = 1e9"),
];

fn scene_text(law_lines: &str) -> String {
    format!(
        r#"
[simulation]
duration = 1e-6

[materials.glass]
youngs_modulus = 63e9
poisson_ratio = 0.22
density = 2500.0
{law_lines}

[[grains]]
name = "sphere"
material = "glass"
shape = {{ sphere = {{ radius = {RADIUS:e}, seeding = {SEEDING:e} }} }}
"#
    )
}

/// x = Q (I + ε) X: rotation 0.3 rad about (1, 1, 1)/√3 after a stretch
/// ε = sign·diag(1, −0.3, −0.3)·10⁻³.
fn deformed(x0: &[[f64; 3]], sign: f64) -> Vec<[f64; 3]> {
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
    let stretch = [1.0 + sign * 1e-3, 1.0 - sign * 3e-4, 1.0 - sign * 3e-4];
    x0.iter()
        .map(|p| {
            let y = [p[0] * stretch[0], p[1] * stretch[1], p[2] * stretch[2]];
            [0, 1, 2].map(|i| q[i][0] * y[0] + q[i][1] * y[1] + q[i][2] * y[2])
        })
        .collect()
}

fn internal_force(c: &mut Criterion) {
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
    let mut group = c.benchmark_group("internal_force");
    for (law, lines) in LAWS {
        let loaded =
            parse_scene("benches/internal_force.rs", &scene_text(lines), &[]).expect("scene");
        let solver = build_solver(&loaded).expect("model");
        let model = &solver.model;
        let (ne, nn) = (model.num_elements(), model.num_nodes());
        assert!(ne >= 100_000, "benchmark mesh has only {ne} tets");
        let bytes = estimate_memory_bytes(model);
        println!(
            "internal_force/{law}: sphere R = {RADIUS:e} m, seeding {SEEDING:e} m: {ne} tets, {nn} nodes; \
             model memory {:.1} MiB = {:.0} bytes/element",
            bytes as f64 / 1048576.0,
            bytes as f64 / ne as f64
        );
        let configurations = [deformed(&model.x0, 1.0), deformed(&model.x0, -1.0)];
        let mut scratch = ElementScratch::new(model);
        let mut force = vec![[0.0; 3]; nn];

        // 1 vs 2 threads must agree bitwise (fixed chunks + incidence gather), plastic
        // states included.
        let mut results = Vec::new();
        for (_, pool) in &pools {
            let mut plastic = solver.state.plastic.clone();
            let mut energies = Vec::new();
            for x in &configurations {
                let summary = pool.install(|| {
                    compute_internal_forces_into(model, x, &mut plastic, &mut scratch, &mut force)
                });
                assert!(summary.bad_element.is_none());
                energies.push((summary.strain_energy, summary.plastic_work));
            }
            results.push((energies, force.clone(), plastic));
        }
        assert!(
            results[0] == results[1],
            "{law}: 1 and 2 threads give different forces"
        );
        let (energies, _, plastic) = &results[0];
        let yielded = plastic.iter().filter(|p| p.equivalent > 0.0).count();
        println!(
            "internal_force/{law}: strain energy {:.6e} J, plastic work {:.3e} J, {yielded} of {} plastic states yielded; 1 and 2 threads bitwise identical",
            energies[1].0,
            energies[0].1 + energies[1].1,
            plastic.len()
        );
        if law == "j2_plastic" {
            assert_eq!(yielded, ne, "every element must take the plastic branch");
        }

        group.throughput(Throughput::Elements(2 * ne as u64));
        let mut plastic = solver.state.plastic.clone();
        for (threads, pool) in &pools {
            group.bench_with_input(
                BenchmarkId::new(law, format!("{threads}_threads")),
                threads,
                |b, _| {
                    b.iter(|| {
                        pool.install(|| {
                            for x in &configurations {
                                compute_internal_forces_into(
                                    model,
                                    x,
                                    &mut plastic,
                                    &mut scratch,
                                    &mut force,
                                );
                            }
                        })
                    })
                },
            );
        }
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
