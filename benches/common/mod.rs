//! What the kernel benchmarks share: the glass-sphere scene and its deformed
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

/// x = Q (I + ε) X: rotation 0.3 rad about (1, 1, 1)/√3 after a stretch
/// ε = sign·diag(1, −0.3, −0.3)·10⁻³.
pub fn deformed(x0: &[[f64; 3]], sign: f64) -> Vec<[f64; 3]> {
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
