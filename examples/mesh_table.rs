//! Element/node counts, quality and meshing time for the paper's sphere (R = 1.1 mm) at
//! MR = 0.090, 0.045, 0.023: uniform, graded (band 3s, core R/4) and a refined contact patch.
//!
//! How to run: `cargo run --release --example mesh_table`

use mufe::mesh::{mesh_sphere, quality, SphereMeshSpec};

fn main() {
    const R: f64 = 1.1e-3;
    println!("| MR | s (µm) | kind | tets | nodes | surface facets | min/max dihedral (°) | max aspect | time |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for mr in [0.090, 0.045, 0.023] {
        let s = mr * 2.0 * R;
        let specs = [
            ("uniform", SphereMeshSpec::uniform(R, s)),
            (
                "graded",
                SphereMeshSpec::uniform(R, s).with_graded(3.0 * s, R / 4.0),
            ),
            (
                "graded + patch s/4",
                SphereMeshSpec::uniform(R, s)
                    .with_graded(3.0 * s, R / 4.0)
                    .with_refinement([0.0, 0.0, 1.0], s / 4.0, 2.0 * s),
            ),
            (
                "patch s/4",
                SphereMeshSpec::uniform(R, s).with_refinement([0.0, 0.0, 1.0], s / 4.0, 2.0 * s),
            ),
        ];
        for (kind, spec) in specs {
            let t0 = std::time::Instant::now();
            let m = mesh_sphere(&spec).expect("mesh");
            let dt = t0.elapsed();
            let q = quality(&m);
            println!(
                "| {mr:.3} | {:.1} | {kind} | {} | {} | {} | {:.1} / {:.1} | {:.2} | {:.2?} |",
                s * 1e6,
                q.elements,
                q.nodes,
                q.surface_facets,
                q.min_dihedral_deg,
                q.max_dihedral_deg,
                q.max_aspect_ratio,
                dt
            );
        }
    }
}
