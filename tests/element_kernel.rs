//! The fused, coloured internal-force kernel against the plainest possible assembly, and
//! its compiled paths against each other.

use mufe::element::tet_forces;
use mufe::lanes::NodeForce;
use mufe::scene::parse_scene;
use mufe::solver::build_solver;
use mufe::solver::forces::{compute_internal_forces_into, ElementScratch, KernelPath};
use mufe::solver::Solver;

/// Three grains, one per law family: default (Biot), St Venant–Kirchhoff, J2 (yielding).
fn three_law_solver() -> Solver {
    let text = r#"
[simulation]
duration = 1e-6

[materials.glass]
youngs_modulus = 63e9
poisson_ratio = 0.22
density = 2500.0

[materials.svk]
youngs_modulus = 3.1e9
poisson_ratio = 0.37
density = 1200.0
law = "st_venant_kirchhoff"

[materials.steel]
youngs_modulus = 200e9
poisson_ratio = 0.3
density = 7800.0
yield_stress = 2e8
hardening_modulus = 1e9

[[grains]]
name = "biot"
material = "glass"
shape = { sphere = { radius = 1e-3, seeding = 1.2e-4 } }

[[grains]]
name = "svk"
material = "svk"
centre = [3e-3, 0.0, 0.0]
shape = { sphere = { radius = 0.7e-3, seeding = 1.1e-4 } }

[[grains]]
name = "j2"
material = "steel"
centre = [0.0, 3e-3, 0.0]
shape = { block = { size = [1e-3, 1.3e-3, 0.9e-3], divisions = [5, 6, 4] } }
"#;
    build_solver(&parse_scene("element_kernel.toml", text, &[]).unwrap()).unwrap()
}

/// Every node moved by a smooth, large strain (about a per cent: J2 yields, the laws differ).
fn strained(x0: &[[f64; 3]]) -> Vec<[f64; 3]> {
    x0.iter()
        .map(|p| {
            let s = (3e3 * p[0]).sin() + (2e3 * p[1]).cos();
            [
                p[0] * (1.0 + 0.01 * s),
                p[1] - 0.007 * p[2] * s,
                p[2] * (1.0 - 0.003 * s),
            ]
        })
        .collect()
}

#[test]
fn the_kernel_assembles_what_element_by_element_assembly_gives() {
    let solver = three_law_solver();
    let model = &solver.model;
    let x = strained(&model.x0);

    let mut plastic = solver.state.plastic.clone();
    let mut scratch = ElementScratch::new(model);
    let mut force = vec![NodeForce::ZERO; model.num_nodes()];
    let summary = compute_internal_forces_into(model, &x, &mut plastic, &mut scratch, &mut force);
    assert!(summary.bad_element.is_none());
    assert!(summary.plastic_work > 0.0, "the J2 grain must yield");

    // reference: one element after another, straight from `tet_forces`
    let mut expected = vec![[0.0; 3]; model.num_nodes()];
    let mut energy = 0.0;
    let mut plastic_work = 0.0;
    for e in 0..model.owned_elements {
        let t = model.tets[e];
        let slot = model.plastic_slot.get(e).filter(|&&s| s != u32::MAX);
        let point = slot.map(|&s| solver.state.plastic[s as usize]);
        let law = &model.laws[model.tet_law[e] as usize];
        let f = tet_forces(
            &t.map(|n| x[n as usize]),
            &model.tet_reference.get(e),
            law,
            point.as_ref(),
        );
        if let (Some(&s), Some(p)) = (slot, f.point) {
            assert_eq!(
                plastic[s as usize], p,
                "element {e}: committed plastic state"
            );
        }
        for (n, fa) in t.iter().zip(f.nodal) {
            for i in 0..3 {
                expected[*n as usize][i] += fa[i];
            }
        }
        energy += f.strain_energy;
        plastic_work += f.plastic_work;
    }
    let scale = expected
        .iter()
        .flatten()
        .fold(0.0f64, |m, v| m.max(v.abs()));
    for (n, (a, b)) in force.iter().zip(&expected).enumerate() {
        for i in 0..3 {
            // only the order of the sums differs
            assert!(
                (a[i] - b[i]).abs() <= 1e-12 * scale,
                "node {n} axis {i}: {} vs {}",
                a[i],
                b[i]
            );
        }
    }
    assert!((summary.strain_energy - energy).abs() <= 1e-12 * energy);
    assert!((summary.plastic_work - plastic_work).abs() <= 1e-12 * plastic_work);
}

#[test]
fn every_vector_path_gives_the_portable_forces_bit_for_bit() {
    let solver = three_law_solver();
    let model = &solver.model;
    let x = strained(&model.x0);
    let detected = KernelPath::detect();
    println!("element kernel path on this machine: {}", detected.name());
    let run = |path: KernelPath| {
        let mut plastic = solver.state.plastic.clone();
        let mut scratch = ElementScratch::new(model);
        scratch.path = path;
        let mut force = vec![NodeForce::ZERO; model.num_nodes()];
        let s = compute_internal_forces_into(model, &x, &mut plastic, &mut scratch, &mut force);
        (
            force,
            plastic,
            s.strain_energy.to_bits(),
            s.plastic_work.to_bits(),
        )
    };
    let portable = run(KernelPath::Portable);
    if std::env::var("MUFE_KERNEL").is_err() && cfg!(target_arch = "x86_64") {
        // every x86-64 CPU this code is run on since 2015 has AVX2
        assert!(KernelPath::Avx2.is_supported());
        assert_ne!(detected, KernelPath::Portable);
    }
    let mut compared = 0;
    for path in [KernelPath::Avx2, KernelPath::Avx512] {
        if path.is_supported() {
            assert!(run(path) == portable, "{} differs", path.name());
            compared += 1;
        } else {
            println!(
                "no {} on this CPU: that path is never taken here",
                path.name()
            );
        }
    }
    assert!(compared > 0 || !cfg!(target_arch = "x86_64"));
}

/// Seconds for 20 force passes of a 10⁵-element-class sphere on one thread, best of five
/// rounds interleaved between the paths (a disturbance hits them alike).
fn best_times_of(paths: &[KernelPath]) -> (usize, Vec<f64>) {
    let text = r#"
[simulation]
duration = 1e-6
[materials.glass]
youngs_modulus = 63e9
poisson_ratio = 0.22
density = 2500.0
[[grains]]
name = "sphere"
material = "glass"
shape = { sphere = { radius = 1e-3, seeding = 1e-4 } }
"#;
    let solver = build_solver(&parse_scene("element_kernel.toml", text, &[]).unwrap()).unwrap();
    let model = &solver.model;
    let x = strained(&model.x0);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let mut force = vec![NodeForce::ZERO; model.num_nodes()];
    let mut time_of = |path: KernelPath| {
        let mut scratch = ElementScratch::new(model);
        scratch.path = path;
        let t0 = std::time::Instant::now();
        pool.install(|| {
            for _ in 0..20 {
                compute_internal_forces_into(model, &x, &mut [], &mut scratch, &mut force);
            }
        });
        t0.elapsed().as_secs_f64()
    };
    let mut best = vec![f64::INFINITY; paths.len()];
    for _ in 0..5 {
        for (b, p) in best.iter_mut().zip(paths) {
            *b = b.min(time_of(*p));
        }
    }
    (model.num_elements(), best)
}

#[test]
fn the_vector_paths_are_faster_than_the_portable_one() {
    // A ratio measured in one run (absolute speeds differ between machines): the lane
    // kernel loses its speed silently when some step of it stops inlining into the vector
    // function, and this catches it. Measured 2.2–2.5× for AVX2 (docs/BENCHMARKS.md).
    let paths: Vec<KernelPath> = [KernelPath::Avx2, KernelPath::Avx512]
        .into_iter()
        .filter(|p| p.is_supported())
        .collect();
    if paths.is_empty() {
        println!("no vector path on this machine: nothing to compare");
        return;
    }
    let mut all = vec![KernelPath::Portable];
    all.extend(&paths);
    let (elements, best) = best_times_of(&all);
    for (path, t) in paths.iter().zip(&best[1..]) {
        let speedup = best[0] / t;
        println!(
            "{elements} elements: portable {:.4} s, {} {t:.4} s per 20 calls: {speedup:.2}×",
            best[0],
            path.name()
        );
        assert!(
            speedup > 1.5,
            "the {} kernel is only {speedup:.2}× the portable one",
            path.name()
        );
    }
}
