//! The validation cases for materials and friction other than the paper's glass: every case
//! generates its drive, loads and meshes from the scene as run (`--set` overrides) and
//! evaluates its reference for that material, so the quick cases must pass their quick
//! tolerances unchanged for
//! - a steel-like grain (E = 210 GPa, ν = 0.30, ρ = 7850 kg/m³) with μ = 0.5, and
//! - a soft rock (E = 5 GPa, ν = 0.25, ρ = 2200 kg/m³) with the shipped μ = 0.22,
//!
//! at the quick meshing ratios (`Case::default_mrs(true)`). Before the scenes were generated
//! from the material, steel gave 263 % (Hertz) and 40 % (Mindlin) "errors".
//!
//! Run time: about as long as `validation_quick` (the same meshes and step counts: the
//! scenes are dimensionless in R and R/c_p), ≈ 2 min for the eight runs on 2 cores
//! (`cargo test --release --test validation_materials`).

use std::process::Command;

#[path = "common/quick_case.rs"]
mod quick_case;

const STEEL: [&str; 4] = [
    "materials.glass.youngs_modulus=2.1e11",
    "materials.glass.poisson_ratio=0.3",
    "materials.glass.density=7850",
    "contact.friction=0.5",
];

const ROCK: [&str; 3] = [
    "materials.glass.youngs_modulus=5e9",
    "materials.glass.poisson_ratio=0.25",
    "materials.glass.density=2200",
];

/// The quick case for a material; the outcome must report the Young's modulus it was run with.
fn run_quick(name: &str, label: &str, sets: &[&str]) {
    let sets = quick_case::sets(sets);
    let expect_e: f64 = sets[0].split('=').nth(1).unwrap().parse().unwrap();
    for o in quick_case::run_quick(name, label, &sets) {
        assert_eq!(
            o.details["scene"]["youngs_modulus_pa"].as_f64(),
            Some(expect_e)
        );
    }
}

#[test]
fn hertz_steel() {
    run_quick("hertz", "steel", &STEEL);
}

#[test]
fn hertz_soft_rock() {
    run_quick("hertz", "soft rock", &ROCK);
}

#[test]
fn mindlin_steel_mu_05() {
    run_quick("mindlin", "steel, μ = 0.5", &STEEL);
}

#[test]
fn mindlin_soft_rock() {
    run_quick("mindlin", "soft rock", &ROCK);
}

#[test]
fn mindlin_cyclic_steel_mu_05() {
    let sets = quick_case::sets(&STEEL);
    for o in quick_case::run_quick("mindlin_cyclic", "steel, μ = 0.5", &sets) {
        let loop_error = o.details["loop_balance_error"].as_f64().unwrap();
        assert!(
            loop_error <= mufe::validate::mindlin_cyclic::LOOP_TOLERANCE,
            "loop area vs ΔALLFD + ΔALLVD: {:.2}%",
            100.0 * loop_error
        );
    }
}

#[test]
fn torsion_steel_mu_05() {
    run_quick("torsion", "steel, μ = 0.5", &STEEL);
}

#[test]
fn torsion_soft_rock() {
    run_quick("torsion", "soft rock", &ROCK);
}

#[test]
fn rolling_steel_mu_05() {
    run_quick("rolling", "steel, μ = 0.5", &STEEL);
}

#[test]
fn rolling_soft_rock() {
    run_quick("rolling", "soft rock", &ROCK);
}

/// A Poisson ratio outside the finite-sphere table is refused before meshing: exit 2, one
/// line naming the scene file and the material field, and the --set that gave it.
#[test]
fn hertz_poisson_ratio_outside_the_reference_table_exits_2() {
    let dir = std::env::temp_dir().join(format!(
        "mufe_validation_materials_nu_{}",
        std::process::id()
    ));
    let out = Command::new(env!("CARGO_BIN_EXE_mufe"))
        .args([
            "validate",
            "hertz",
            "--quick",
            "--out",
            &dir.display().to_string(),
            "--set",
            "materials.glass.poisson_ratio=-0.2",
        ])
        .env_remove("MUFE_VALIDATION_SCENES")
        .output()
        .expect("mufe runs");
    let _ = std::fs::remove_dir_all(&dir);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
    for part in [
        "jobs/validation/hertz.toml",
        "materials.glass.poisson_ratio",
        "-0.2",
        "--set materials.glass.poisson_ratio=-0.2",
    ] {
        assert!(stderr.contains(part), "'{part}' missing from: {stderr}");
    }
}

/// A tangential case without friction cannot scale its drive: exit 2 naming the field.
#[test]
fn tangential_case_without_friction_exits_2() {
    let dir = std::env::temp_dir().join(format!(
        "mufe_validation_materials_mu_{}",
        std::process::id()
    ));
    let out = Command::new(env!("CARGO_BIN_EXE_mufe"))
        .args([
            "validate",
            "torsion",
            "--write-scenes",
            &dir.display().to_string(),
            "--set",
            "contact.friction=0",
        ])
        .env_remove("MUFE_VALIDATION_SCENES")
        .output()
        .expect("mufe runs");
    let _ = std::fs::remove_dir_all(&dir);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("jobs/validation/torsion.toml: contact.friction:"),
        "{stderr}"
    );
}
