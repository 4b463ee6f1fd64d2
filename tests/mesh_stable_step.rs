//! The explicit step of a uniform sphere mesh against the regular tetrahedron (issue 14,
//! item 3): the elements' own stable step (exact largest eigenvalue, lumped mass) over
//! 0.565 h/c_p, the value of a regular tet of the nominal edge h = seeding, with
//! c_p = √((λ + 2μ)/ρ) of the material the test uses. Slivers left by TetGen put it at
//! 15–16 %; `mesh::improve` (node smoothing, then edge removal and smoothing again) takes it
//! to 44–51 % (measured: glass MR 0.1 0.505, 0.07 0.467, 0.05 0.482; the polymer 3–5 %
//! lower). The test holds it at ≥ 40 % (the goal from quality alone is 35 %).
//!
//! Selective mass scaling on top (`simulation.target_dt` at 60 % of the regular step) must
//! stay within 0.5 % added mass of the grain (the budget).
//!
//! Three meshing ratios and two materials (glass, and a soft polymer nobody tuned for), so
//! that the bounds are not a property of one mesh.

use mufe::scene::parse_scene;
use mufe::solver::build_solver;

/// P-wave speed √((λ + 2μ)/ρ) (m/s).
fn p_wave_speed(youngs: f64, poisson: f64, density: f64) -> f64 {
    let lambda = youngs * poisson / ((1.0 + poisson) * (1.0 - 2.0 * poisson));
    let mu = youngs / (2.0 * (1.0 + poisson));
    ((lambda + 2.0 * mu) / density).sqrt()
}

/// (elements' stable step over the regular tet's, added mass over the grain's mass with
/// `target_fraction` × the regular step as target, or 0 without).
fn step_and_added_mass(
    radius: f64,
    seeding: f64,
    material: (f64, f64, f64),
    target_fraction: Option<f64>,
) -> (f64, f64) {
    let (youngs, poisson, density) = material;
    let regular = 0.565 * seeding / p_wave_speed(youngs, poisson, density);
    let target = target_fraction
        .map(|f| format!("target_dt = {:e}\n", f * regular))
        .unwrap_or_default();
    let text = format!(
        "[simulation]\nduration = 1e-6\ndt_safety = 1.0\n{target}\
         [materials.m]\nyoungs_modulus = {youngs:e}\npoisson_ratio = {poisson}\ndensity = {density}\n\
         [[grains]]\nmaterial = \"m\"\nshape = {{ sphere = {{ radius = {radius:e}, seeding = {seeding:e} }} }}\n\
         centre = [0.0, 0.0, 0.0]\n"
    );
    let loaded = parse_scene("uniform.toml", &text, &[]).expect("scene parses");
    let solver = build_solver(&loaded).expect("model builds");
    let model = &solver.model;
    let grain_mass: f64 = model.physical_mass.iter().sum();
    (
        model.contact.stable_step.element_dt / regular,
        model.added_mass / grain_mass,
    )
}

const GLASS: (f64, f64, f64) = (63e9, 0.22, 2500.0);
const POLYMER: (f64, f64, f64) = (3.1e9, 0.37, 1180.0);

#[test]
fn uniform_sphere_meshes_step_at_forty_percent_of_a_regular_tet() {
    for (material, name) in [(GLASS, "glass"), (POLYMER, "polymer")] {
        for meshing_ratio in [0.1, 0.07, 0.05] {
            let radius = 1.0e-3;
            let seeding = meshing_ratio * 2.0 * radius;
            let (ratio, _) = step_and_added_mass(radius, seeding, material, None);
            println!("{name}, MR {meshing_ratio}: Δt_elements / (0.565 h/c_p) = {ratio:.3}");
            assert!(
                ratio >= 0.40,
                "{name}, MR {meshing_ratio}: the elements' step is {:.1} % of a regular tet's",
                100.0 * ratio
            );
        }
    }
}

#[test]
fn sixty_percent_of_the_regular_step_costs_under_half_a_percent_of_mass() {
    for (material, name) in [(GLASS, "glass"), (POLYMER, "polymer")] {
        for meshing_ratio in [0.1, 0.05] {
            let radius = 0.7e-3;
            let seeding = meshing_ratio * 2.0 * radius;
            let (_, added) = step_and_added_mass(radius, seeding, material, Some(0.6));
            println!(
                "{name}, MR {meshing_ratio}: added mass at 60 % = {:.3} %",
                100.0 * added
            );
            assert!(
                added > 0.0 && added <= 0.005,
                "{name}, MR {meshing_ratio}: {:.3} % added mass",
                100.0 * added
            );
        }
    }
}
