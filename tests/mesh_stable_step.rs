//! The explicit step of a uniform sphere mesh against the regular tetrahedron (issue 14,
//! item 3): the elements' own stable step (exact largest eigenvalue, lumped mass) over
//! 0.565 h/c_p, the value of a regular tet of the nominal edge h = seeding, with
//! c_p = √((λ + 2μ)/ρ) of the material the test uses. Slivers left by TetGen put it at
//! 15–16 %; `mesh::smooth` moves their interior nodes and reaches 30–35 % (measured, glass:
//! MR 0.1 0.350, 0.07 0.339, 0.05 0.303; the polymer 1 % lower). The test holds it at
//! ≥ 28 % (the goal, 35 % at every MR, is not reached below MR 0.1).
//!
//! Three meshing ratios and two materials (glass, and a soft polymer nobody tuned for), so
//! that the bound is not a property of one mesh.

use mufe::scene::parse_scene;
use mufe::solver::build_solver;

/// P-wave speed √((λ + 2μ)/ρ) (m/s).
fn p_wave_speed(youngs: f64, poisson: f64, density: f64) -> f64 {
    let lambda = youngs * poisson / ((1.0 + poisson) * (1.0 - 2.0 * poisson));
    let mu = youngs / (2.0 * (1.0 + poisson));
    ((lambda + 2.0 * mu) / density).sqrt()
}

fn element_step_over_regular(radius: f64, seeding: f64, material: (f64, f64, f64)) -> f64 {
    let (youngs, poisson, density) = material;
    let text = format!(
        "[simulation]\nduration = 1e-6\ndt_safety = 1.0\n\
         [materials.m]\nyoungs_modulus = {youngs:e}\npoisson_ratio = {poisson}\ndensity = {density}\n\
         [[grains]]\nmaterial = \"m\"\nshape = {{ sphere = {{ radius = {radius:e}, seeding = {seeding:e} }} }}\n\
         centre = [0.0, 0.0, 0.0]\n"
    );
    let loaded = parse_scene("uniform.toml", &text, &[]).expect("scene parses");
    let solver = build_solver(&loaded).expect("model builds");
    let dt = solver.model.contact.stable_step.element_dt;
    let regular = 0.565 * seeding / p_wave_speed(youngs, poisson, density);
    dt / regular
}

#[test]
fn uniform_sphere_meshes_keep_the_smoothed_stable_step() {
    let glass = (63e9, 0.22, 2500.0);
    let polymer = (3.1e9, 0.37, 1180.0);
    for (material, name) in [(glass, "glass"), (polymer, "polymer")] {
        for meshing_ratio in [0.1, 0.07, 0.05] {
            let radius = 1.0e-3;
            let seeding = meshing_ratio * 2.0 * radius;
            let ratio = element_step_over_regular(radius, seeding, material);
            println!("{name}, MR {meshing_ratio}: Δt_elements / (0.565 h/c_p) = {ratio:.3}");
            assert!(
                ratio >= 0.28,
                "{name}, MR {meshing_ratio}: the elements' step is {:.1} % of a regular tet's",
                100.0 * ratio
            );
        }
    }
}
