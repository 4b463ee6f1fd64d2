//! Quick versions of the four analytic validation cases (`mufe validate --quick`): coarse
//! meshes at the contact and looser documented tolerances (`Case::target(true)`, see
//! docs/BENCHMARKS.md, "Validation"). Each case runs its quick meshing ratio and must stay
//! within its quick tolerance; the full sweep is `mufe validate`.
//!
//! Run time: about a minute per case in release on 2 cores (`cargo test --release --test
//! validation_quick`); the dev profile (opt-level 1) is slower.

use mufe::validate::select_cases;

fn run_quick(name: &str) {
    let cases = select_cases(&[name.to_string()]).expect("known case");
    let case = &cases[0];
    let target = case.target(true);
    for mr in case.default_mrs(true) {
        let t0 = std::time::Instant::now();
        let o = case
            .run(mr, true, &[], &mufe::validate::scenes::Params::default())
            .unwrap_or_else(|e| panic!("{name} at MR {mr}: {e}"));
        println!(
            "{name}: MR {mr}, {} elements, {} steps, {:.1} s, error {:.2}% (quick target {:.1}%), details {}",
            o.elements,
            o.steps,
            t0.elapsed().as_secs_f64(),
            100.0 * o.error,
            100.0 * target,
            serde_json::Value::Object(o.details.clone())
        );
        assert!(
            o.error.is_finite() && o.error <= target,
            "{name} at MR {mr}: error {:.2}% above the quick target {:.1}%",
            100.0 * o.error,
            100.0 * target
        );
        assert!(o.curve.len() > 20, "{name}: too few samples on the curve");
    }
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
