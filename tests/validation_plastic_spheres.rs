//! Quick version of `plastic_spheres` (two elastic–plastic spheres loaded to 55 δc and
//! unloaded, docs/THEORY.md §6) for the shipped glass and for a steel-like grain nobody
//! tuned the case for: the case builds its mesh and drive from the material as run, so the
//! same criteria must hold for both. Asserted at the quick meshing ratio:
//! - the F–δ distance from Jackson–Green over 1 ≤ δ* ≤ 50 within the quick target
//!   (1.5 × 10 %);
//! - first yield (first step with plastic work) within the quick first-yield tolerance of
//!   Pc (1.5 × 10 %; the full sweep's finest MR meets 10 %, docs/BENCHMARKS.md);
//! - the area of the F–δ loop equal to ALLPD + ALLSE + ALLVD at the end within 2 %;
//! - the spheres separated on unloading.
//!
//! Run time: several minutes in release on 2 cores (about 110 000 elements, 10 500 steps
//! per material; measured in docs/BENCHMARKS.md, "plastic_spheres"). Run with
//! `cargo test --release --test validation_plastic_spheres`.

use mufe::validate::plastic_spheres::{first_yield_tolerance, LOOP_TOLERANCE};
#[path = "common/quick_case.rs"]
mod quick_case;

fn run_quick(label: &str, sets: &[String]) {
    for o in quick_case::run_quick("plastic_spheres", label, sets) {
        let (d, mr) = (&o.details, o.mr);
        let get = |k: &str| d[k].as_f64().unwrap_or(f64::NAN);
        let yield_error = get("first_yield_error");
        assert!(
            yield_error <= first_yield_tolerance(true),
            "{label}, MR {mr}: first yield at F = {:.3} Pc, off by more than {:.0}%",
            get("first_yield_force_over_pc"),
            100.0 * first_yield_tolerance(true)
        );
        let loop_error = get("loop_balance_error");
        assert!(
            loop_error <= LOOP_TOLERANCE,
            "{label}, MR {mr}: loop area {:e} J vs ledger {:e} J ({:.2}%)",
            get("loop_area_j"),
            get("ledger_dissipated_or_locked_j"),
            100.0 * loop_error
        );
        assert!(
            get("residual_interference_m") > 0.0,
            "{label}, MR {mr}: the spheres did not separate on unloading"
        );
    }
}

#[test]
fn plastic_spheres_quick_glass() {
    run_quick("shipped glass", &[]);
}

#[test]
fn plastic_spheres_quick_steel_like() {
    let m = |field: &str, v: &str| format!("materials.glass.{field}={v}");
    run_quick(
        "steel-like (E = 210 GPa, ν = 0.3, σy = 250 MPa, H = E/1000)",
        &[
            m("youngs_modulus", "2.1e11"),
            m("poisson_ratio", "0.3"),
            m("density", "7850.0"),
            m("yield_stress", "2.5e8"),
            m("hardening_modulus", "2.1e8"),
        ],
    );
}
