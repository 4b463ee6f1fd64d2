//! Quick versions of the four analytic validation cases (`mufe validate --quick`): coarse
//! meshes at the contact and looser documented tolerances (`Case::target(true)`, see
//! docs/BENCHMARKS.md, "Validation"). Each case runs its quick meshing ratio and must stay
//! within its quick tolerance; the full sweep is `mufe validate`.
//!
//! Run time: about a minute per case in release on 2 cores (`cargo test --release --test
//! validation_quick`); the dev profile (opt-level 1) is slower.

#[path = "common/quick_case.rs"]
mod quick_case;

fn run_quick(name: &str) {
    quick_case::run_quick(name, "shipped glass", &[]);
}

#[test]
fn hertz_quick() {
    run_quick("hertz");
}

#[test]
fn mindlin_quick() {
    run_quick("mindlin");
}

#[test]
fn torsion_quick() {
    run_quick("torsion");
}

#[test]
fn rolling_quick() {
    run_quick("rolling");
}

/// The full tangential cycle: Masing branches and the loop area against the ledger.
#[test]
fn mindlin_cyclic_quick() {
    for o in quick_case::run_quick("mindlin_cyclic", "shipped glass", &[]) {
        let loop_error = o.details["loop_balance_error"].as_f64().unwrap();
        assert!(
            loop_error <= mufe::validate::mindlin_cyclic::LOOP_TOLERANCE,
            "loop area vs ΔALLFD + ΔALLVD: {:.2}%",
            100.0 * loop_error
        );
    }
}
