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
//! iteration is two `compute_internal_forces_into` calls (element kernel adding into the
//! node forces, plastic state update) at two configurations, a rigid rotation of 0.3 rad after a
//! stretch of +10⁻³ and of −10⁻³: every element has stress, and a plastic element reverses
//! its flow at every call, so the plastic branch is taken every time. Criterion reports
//! elements/s = tet updates/s. Also printed: model memory per element
//! (`estimate_memory_bytes`) and a check that 1 and 2 threads give bitwise identical
//! forces and plastic states. Results: docs/BENCHMARKS.md.

mod common;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use mufe::driver::summary::estimate_memory_bytes;
use mufe::lanes::NodeForce;
use mufe::solver::forces::{compute_internal_forces_into, ElementScratch};
use std::time::Duration;

/// Sphere radius (m) and seeding (m): 70 µm gives > 10⁵ tets.
const RADIUS: f64 = 1.1e-3;
const SEEDING: f64 = 7.0e-5;

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
    for (law, lines) in common::LAWS {
        let solver = common::sphere_solver("benches/internal_force.rs", lines, RADIUS, SEEDING);
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
        let configurations = [
            common::deformed(&model.x0, 1.0),
            common::deformed(&model.x0, -1.0),
        ];
        let mut scratch = ElementScratch::new(model);
        let mut force = vec![NodeForce::ZERO; nn];

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
