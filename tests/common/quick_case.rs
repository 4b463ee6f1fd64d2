//! Runs a validation case at its quick meshing ratios (`Case::default_mrs(true)`) for one
//! material, as `mufe validate --quick` would but without writing files, and asserts what
//! every case must meet: its documented error metric within the quick target, the energy
//! ledger closed within `BALANCE_TOLERANCE` over the whole run, a curve to plot, and the
//! case's own verdict. Returns the outcomes for case-specific checks.
//!
//! Use from a test file with `#[path = "common/quick_case.rs"] mod quick_case;`.
#![allow(dead_code)]

use mufe::validate::record::BALANCE_TOLERANCE;
use mufe::validate::runner::{balance_error, CaseOutcome};
use mufe::validate::scenes::Params;
use mufe::validate::select_cases;

/// `label` names the material in messages; `sets` are `--set` overrides of the case scene.
pub fn run_quick(name: &str, label: &str, sets: &[String]) -> Vec<CaseOutcome> {
    let cases = select_cases(&[name.to_string()]).expect("known case");
    let case = &cases[0];
    let target = case.target(true);
    let mut outcomes = Vec::new();
    for mr in case.default_mrs(true) {
        let t0 = std::time::Instant::now();
        let o = case
            .run(mr, true, sets, &Params::default(), None)
            .unwrap_or_else(|e| panic!("{name} ({label}) at MR {mr}: {e}"));
        let balance = balance_error(&o);
        println!(
            "{name} ({label}): MR {mr}, {} elements, {} steps, {:.1} s, error {:.3e} (quick target {:.1e}), balance {:.2e}, details {}",
            o.elements,
            o.steps,
            t0.elapsed().as_secs_f64(),
            o.error,
            target,
            balance,
            serde_json::Value::Object(o.details.clone())
        );
        assert!(
            o.error.is_finite() && o.error <= target,
            "{name} ({label}) at MR {mr}: error {:.3e} above the quick target {:.1e}",
            o.error,
            target
        );
        assert!(
            balance <= BALANCE_TOLERANCE,
            "{name} ({label}) at MR {mr}: energy balance drifted by {:.2}% of the largest term",
            100.0 * balance
        );
        assert!(
            o.curve.len() > 20,
            "{name} ({label}): too few samples on the curve"
        );
        assert!(
            o.pass,
            "{name} ({label}) at MR {mr}: the case reports a failure"
        );
        outcomes.push(o);
    }
    outcomes
}

/// `--set` overrides from string literals.
pub fn sets(list: &[&str]) -> Vec<String> {
    list.iter().map(|s| s.to_string()).collect()
}
