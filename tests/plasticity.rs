//! J2 plasticity through the real model path: objectivity of a yielded grain under rigid
//! rotation, the energy ledger against the stress work of a strain cycle, the exploding-
//! increment guard, and the ledger of a run with plastic impacts.

use mufe::driver::frames::element_fields;
use mufe::lanes::NodeForce;
use mufe::material::{cauchy_from_first_piola, PlasticPoint};
use mufe::scene::parse_scene;
use mufe::solver::forces::{compute_internal_forces_into, ElementScratch, MAX_PLASTIC_INCREMENT};
use mufe::solver::{build_solver, element_response, Solver};

/// Steel-like J2 material (SI): E, ν, ρ, σy, H.
const E: f64 = 2.1e11;
const NU: f64 = 0.3;
const SIGMA_Y: f64 = 2.5e8;
const H: f64 = 2.0e9;

/// A 1 mm cube of 2×2×2 cells (48 tets) of the steel-like J2 material.
fn cube_solver(yield_stress: f64, hardening: f64) -> Solver {
    let text = format!(
        r#"
[simulation]
duration = 1e-6

[materials.steel]
youngs_modulus = {E:e}
poisson_ratio = {NU}
density = 7850.0
yield_stress = {yield_stress:e}
hardening_modulus = {hardening:e}

[[grains]]
name = "cube"
material = "steel"
centre = [-0.5e-3, -0.5e-3, -0.5e-3]
shape = {{ block = {{ size = [1e-3, 1e-3, 1e-3], divisions = [2, 2, 2] }} }}
"#
    );
    let loaded = parse_scene("tests/plasticity.rs", &text, &[]).expect("scene");
    build_solver(&loaded).expect("model")
}

fn mat_vec(a: &[f64; 9], x: &[f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|i| a[3 * i] * x[0] + a[3 * i + 1] * x[1] + a[3 * i + 2] * x[2])
}

fn mat_mul(a: &[f64; 9], b: &[f64; 9]) -> [f64; 9] {
    let mut c = [0.0; 9];
    for i in 0..3 {
        for j in 0..3 {
            c[3 * i + j] = (0..3).map(|k| a[3 * i + k] * b[3 * k + j]).sum();
        }
    }
    c
}

/// Rotation by `angle` about the unit vector `u` (Rodrigues).
fn rotation(u: [f64; 3], angle: f64) -> [f64; 9] {
    let (s, c) = angle.sin_cos();
    let mut r = [0.0; 9];
    for i in 0..3 {
        for j in 0..3 {
            let cross = match (i, j) {
                (0, 1) => -u[2],
                (1, 0) => u[2],
                (0, 2) => u[1],
                (2, 0) => -u[1],
                (1, 2) => -u[0],
                (2, 1) => u[0],
                _ => 0.0,
            };
            r[3 * i + j] = c * if i == j { 1.0 } else { 0.0 } + s * cross + (1.0 - c) * u[i] * u[j];
        }
    }
    r
}

/// Positions under the homogeneous map x = A X.
fn mapped(solver: &Solver, a: &[f64; 9]) -> Vec<[f64; 3]> {
    solver.model.x0.iter().map(|p| mat_vec(a, p)).collect()
}

/// Evaluates the internal forces at x (committing the plastic state); returns (ALLSE,
/// plastic work of the evaluation).
fn evaluate(solver: &mut Solver, scratch: &mut ElementScratch, x: &[[f64; 3]]) -> (f64, f64) {
    let mut force = vec![NodeForce::ZERO; solver.model.num_nodes()];
    let s = compute_internal_forces_into(
        &solver.model,
        x,
        &mut solver.state.plastic,
        scratch,
        &mut force,
    );
    assert!(s.bad_element.is_none(), "{:?}", s.bad_element);
    (s.strain_energy, s.plastic_work)
}

/// A shear plus stretch of amplitude `k` (a few times the yield strain at k = 1).
fn deformation(k: f64) -> [f64; 9] {
    let d = 4e-3 * k;
    [
        1.0 + d,
        0.8 * d,
        0.0,
        0.3 * d,
        1.0 - 0.4 * d,
        0.5 * d,
        0.0,
        0.2 * d,
        1.0 - 0.2 * d,
    ]
}

#[test]
fn a_yielded_grain_turned_rigidly_by_90_degrees_keeps_its_plastic_strain_and_turns_its_stress() {
    let mut solver = cube_solver(SIGMA_Y, H);
    let mut scratch = ElementScratch::new(&solver.model);
    let ne = solver.model.num_elements();
    assert_eq!(solver.state.plastic.len(), ne, "every element is plastic");
    for k in 1..=20 {
        let f = deformation(k as f64 / 20.0);
        let x = mapped(&solver, &f);
        evaluate(&mut solver, &mut scratch, &x);
    }
    let f_yield = deformation(1.0);
    let x_yield = mapped(&solver, &f_yield);
    let yielded: Vec<PlasticPoint> = solver.state.plastic.clone();
    let alpha_max = yielded.iter().map(|p| p.equivalent).fold(0.0, f64::max);
    assert!(alpha_max > 1e-3, "the grain yielded (α = {alpha_max})");
    let stress_before: Vec<[f64; 9]> = (0..ne)
        .map(|e| {
            let (f, r) = element_response(&solver.model, &x_yield, &solver.state.plastic, e);
            cauchy_from_first_piola(&r.first_piola, &f)
        })
        .collect();
    let sigma_scale = stress_before
        .iter()
        .flat_map(|s| s.iter().map(|v| v.abs()))
        .fold(0.0, f64::max);

    let axis = [1.0 / 3f64.sqrt(), -1.0 / 3f64.sqrt(), 1.0 / 3f64.sqrt()];
    for increments in [1usize, 7, 400] {
        solver.state.plastic = yielded.clone();
        let mut work = 0.0;
        let mut r = rotation(axis, 0.0);
        for k in 1..=increments {
            r = rotation(
                axis,
                std::f64::consts::FRAC_PI_2 * k as f64 / increments as f64,
            );
            let x = mapped(&solver, &mat_mul(&r, &f_yield));
            work += evaluate(&mut solver, &mut scratch, &x).1;
        }
        // plastic strain and hardening unchanged to round-off, no dissipation
        for (a, b) in yielded.iter().zip(&solver.state.plastic) {
            assert!((a.equivalent - b.equivalent).abs() <= 1e-12 * alpha_max);
            for c in 0..6 {
                assert!(
                    (a.strain[c] - b.strain[c]).abs() <= 1e-12 * alpha_max,
                    "{increments} increments: εᵖ changed {} → {}",
                    a.strain[c],
                    b.strain[c]
                );
            }
        }
        assert!(
            work.abs() <= 1e-9 * sigma_scale * 1e-9,
            "dissipation {work} J"
        );
        // the Cauchy stress turned with the grain: σ' = R σ Rᵀ
        let x = mapped(&solver, &mat_mul(&r, &f_yield));
        for (e, before) in stress_before.iter().enumerate() {
            let (f, resp) = element_response(&solver.model, &x, &solver.state.plastic, e);
            let after = cauchy_from_first_piola(&resp.first_piola, &f);
            let mut rt = [0.0; 9];
            for i in 0..3 {
                for j in 0..3 {
                    rt[3 * i + j] = r[3 * j + i];
                }
            }
            let expected = mat_mul(&mat_mul(&r, before), &rt);
            for c in 0..9 {
                assert!(
                    (after[c] - expected[c]).abs() <= 1e-10 * sigma_scale,
                    "{increments} increments, element {e}: σ[{c}] = {:e}, expected {:e}",
                    after[c],
                    expected[c]
                );
            }
        }
    }
}

#[test]
fn allse_plus_allpd_equals_the_stress_work_of_a_strain_cycle() {
    // A homogeneous cycle 0 → +1 → −1 → 0 (amplitude a few yield strains), in small steps:
    // the stress work V Σ P:ΔF (trapezoidal) equals ΔALLSE + ALLPD up to the integration
    // error, and the cycle dissipates (ALLPD > 0 while ALLSE returns to a locked-in value).
    let mut solver = cube_solver(SIGMA_Y, H);
    let mut scratch = ElementScratch::new(&solver.model);
    let volume: f64 = solver.model.tet_reference.iter().map(|r| r.volume).sum();
    let n = 4000;
    let path = |s: f64| -> f64 {
        // piecewise linear 0 → 1 → −1 → 0 over s ∈ [0, 1]
        if s < 0.25 {
            4.0 * s
        } else if s < 0.75 {
            1.0 - 4.0 * (s - 0.25)
        } else {
            -1.0 + 4.0 * (s - 0.75)
        }
    };
    let (mut work, mut dissipated) = (0.0, 0.0);
    let mut previous: Option<([f64; 9], [f64; 9])> = None;
    let mut stored = 0.0;
    for k in 0..=n {
        let f = deformation(path(k as f64 / n as f64));
        let x = mapped(&solver, &f);
        let (se, pw) = evaluate(&mut solver, &mut scratch, &x);
        stored = se;
        dissipated += pw;
        // P is uniform: take element 0's
        let (_, r) = element_response(&solver.model, &x, &solver.state.plastic, 0);
        if let Some((f0, p0)) = previous {
            for c in 0..9 {
                work += volume * 0.5 * (p0[c] + r.first_piola[c]) * (f[c] - f0[c]);
            }
        }
        previous = Some((f, r.first_piola));
    }
    assert!(dissipated > 0.0 && stored > 0.0);
    let ledger = stored + dissipated;
    assert!(
        (ledger - work).abs() <= 2e-3 * work.abs(),
        "stress work {work:e} J vs ALLSE + ALLPD {ledger:e} J"
    );
    // the hysteresis is real: more than half of the work was dissipated over the cycle
    assert!(dissipated > 0.5 * work, "{dissipated} of {work}");
}

#[test]
fn an_exploding_plastic_increment_is_reported_with_its_element() {
    let mut solver = cube_solver(1e6, 0.0);
    let mut scratch = ElementScratch::new(&solver.model);
    let mut force = vec![NodeForce::ZERO; solver.model.num_nodes()];
    // a 30 % shear in one evaluation: far more plastic strain than any step can take
    let f = [1.0, 0.3, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
    let x = mapped(&solver, &f);
    let s = compute_internal_forces_into(
        &solver.model,
        &x,
        &mut solver.state.plastic,
        &mut scratch,
        &mut force,
    );
    let bad = s.bad_element.expect("the increment is refused");
    assert_eq!(bad.element, 0, "the lowest-index element is named");
    assert!(bad.plastic_increment > MAX_PLASTIC_INCREMENT);
    assert!(
        bad.describe()
            .contains("equivalent plastic strain in one step"),
        "{}",
        bad.describe()
    );
}

#[test]
fn plastic_impacts_balance_the_ledger_and_fill_the_indices() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("jobs/tests/assembly.toml");
    let sets = [
        "materials.glass.yield_stress=1e8".to_string(),
        "materials.glass.hardening_modulus=1e9".to_string(),
    ];
    let loaded = mufe::scene::load_scene(&path, &sets).unwrap();
    let mut solver = build_solver(&loaded).unwrap();
    for _ in 0..300 {
        solver.step().unwrap();
    }
    let e = &solver.state.energy;
    assert!(
        e.plastic_dissipation > 0.0,
        "grains yield at their contacts"
    );
    assert!(e.friction_dissipation > 0.0);
    assert!(
        e.relative_balance_error() < 5e-3,
        "balance error {}",
        e.relative_balance_error()
    );
    let pi = e.plastic_index();
    assert!(pi > 0.0 && pi < 1.0);
    assert!(
        (pi - e.plastic_dissipation / (e.recoverable_strain + e.plastic_dissipation)).abs() < 1e-15
    );
    // frames carry the equivalent plastic strain of the yielded elements
    let fields = element_fields(&solver);
    let alpha_max = fields
        .equivalent_plastic_strain
        .iter()
        .fold(0.0, |a: f64, b| a.max(*b));
    let state_max = solver
        .state
        .plastic
        .iter()
        .map(|p| p.equivalent)
        .fold(0.0, f64::max);
    assert!(alpha_max >= state_max && state_max > 0.0);
}
