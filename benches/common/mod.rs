//! What the kernel benchmarks share: the glass-sphere scene, its solver and its deformed
//! configurations.

/// (name, extra material lines) of the laws compared: the default `biot`,
/// `st_venant_kirchhoff`, `corotational`, and J2 on the Biot law in its elastic branch (σy
/// far above any stress) and its plastic branch (σy = 10 MPa, far below).
pub const LAWS: [(&str, &str); 5] = [
    ("biot", ""),
    ("st_venant_kirchhoff", "law = \"st_venant_kirchhoff\""),
    ("corotational", "law = \"corotational\""),
    ("j2_elastic", "yield_stress = 1e10\nhardening_modulus = 1e9"),
    ("j2_plastic", "yield_stress = 1e7\nhardening_modulus = 1e9"),
];

/// A scene of one glass sphere of radius `radius` meshed at `seeding` (m), its material
/// extended by `law_lines` (the law, yield stress, …).
pub fn sphere_scene(law_lines: &str, radius: f64, seeding: f64) -> String {
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
shape = {{ sphere = {{ radius = {radius:e}, seeding = {seeding:e} }} }}
"#
    )
}

/// The solver of [`sphere_scene`], built through the real scene path (`parse_scene` +
/// `build_solver`); `bench` names the benchmark in error messages.
pub fn sphere_solver(
    bench: &str,
    law_lines: &str,
    radius: f64,
    seeding: f64,
) -> mufe::solver::Solver {
    let text = sphere_scene(law_lines, radius, seeding);
    let loaded = mufe::scene::parse_scene(bench, &text, &[]).expect("benchmark scene");
    mufe::solver::build_solver(&loaded).expect("benchmark model")
}

/// x = Q (I + ε) X: rotation 0.3 rad about (1, 1, 1)/√3 after a stretch
/// ε = sign·diag(1, −0.3, −0.3)·10⁻³.
pub fn deformed(x0: &[[f64; 3]], sign: f64) -> Vec<[f64; 3]> {
    let q = mufe::boundary::rotation_from_vector([0.3 / 3f64.sqrt(); 3]);
    let stretch = [1.0 + sign * 1e-3, 1.0 - sign * 3e-4, 1.0 - sign * 3e-4];
    x0.iter()
        .map(|p| {
            let y = [p[0] * stretch[0], p[1] * stretch[1], p[2] * stretch[2]];
            [0, 1, 2].map(|i| q[3 * i] * y[0] + q[3 * i + 1] * y[1] + q[3 * i + 2] * y[2])
        })
        .collect()
}
