//! Reading `results.h5` back in tests.
//!
//! Use from a test file with `#[path = "common/results.rs"] mod results;`.
#![allow(dead_code)]

use std::path::Path;

/// All `/history` series of a results file, by name (sorted).
pub fn history(path: &Path) -> Vec<(String, Vec<f64>)> {
    let f = hdf5::File::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let g = f.group("history").unwrap();
    let mut names = g.member_names().unwrap();
    names.sort();
    names
        .into_iter()
        .map(|n| (n.clone(), g.dataset(&n).unwrap().read_raw::<f64>().unwrap()))
        .collect()
}

/// The series `name` of a [`history`] (panics naming it when missing).
pub fn column<'a>(h: &'a [(String, Vec<f64>)], name: &str) -> &'a [f64] {
    &h.iter()
        .find(|(n, _)| n == name)
        .unwrap_or_else(|| panic!("/history/{name} missing"))
        .1
}

/// Asserts that two histories have the same columns and rows, every value within 1e-10 of
/// its column's largest magnitude in `a` (`energy_balance` against `balance_scale` too: a
/// drift near zero is measured against the energies in play). `what` names `b` in failures.
pub fn assert_same_history(
    a: &[(String, Vec<f64>)],
    b: &[(String, Vec<f64>)],
    balance_scale: f64,
    what: &str,
) {
    assert_eq!(a.len(), b.len(), "same columns");
    for ((name, x), (name_b, y)) in a.iter().zip(b) {
        assert_eq!(name, name_b);
        assert_eq!(x.len(), y.len(), "{name}: rows on {what}");
        let scale = x.iter().map(|v| v.abs()).fold(0.0, f64::max).max(1e-300);
        let scale = if name == "energy_balance" {
            scale.max(balance_scale)
        } else {
            scale
        };
        for (i, (u, v)) in x.iter().zip(y).enumerate() {
            assert!(
                (u - v).abs() <= 1e-10 * scale,
                "/history/{name}[{i}]: {what} {v:e}, 1 rank {u:e}"
            );
        }
    }
}

/// Every stage-2 row of a triaxial cell holds σx and σy within `tolerance` (relative) of
/// `sigma3`.
pub fn assert_lateral_stress_held(h: &[(String, Vec<f64>)], sigma3: f64, tolerance: f64) {
    let stage = column(h, "stage");
    for (i, _) in stage.iter().enumerate().filter(|(_, &s)| s == 2.0) {
        for a in ["sigma_x", "sigma_y"] {
            let s = column(h, a)[i];
            assert!(
                (s / sigma3 - 1.0).abs() <= tolerance,
                "{a} = {s:.4e} Pa at row {i}"
            );
        }
    }
}

/// The largest stress ratio of the stage-2 rows.
pub fn stage2_peak_ratio(h: &[(String, Vec<f64>)]) -> f64 {
    let stage = column(h, "stage");
    (column(h, "stress_ratio").iter().zip(stage))
        .filter(|(_, &s)| s == 2.0)
        .map(|(r, _)| *r)
        .fold(0.0, f64::max)
}

/// The stdout of a two-stage triaxial run says that stage 1 held its stress and stage 2
/// ended at failure.
pub fn assert_held_then_failed(stdout: &str) {
    assert!(
        stdout.contains("stage 'isotropic' done") && stdout.contains("ended by stress held"),
        "stage 1 did not hold the stress:\n{stdout}"
    );
    assert!(
        stdout.contains("stage 'shear' done") && stdout.contains("ended by failure + margin"),
        "no failure detected in stage 2:\n{stdout}"
    );
}

/// Runs `scripts/check_results_layout.py` on `path` with the conditions `expect` (comma
/// separated, e.g. "staged,cell"; "" for the unconditional objects only) and fails with
/// its report when the file does not match docs/RESULTS.md.
pub fn assert_matches_documented_layout(path: &Path, expect: &str) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let check = std::process::Command::new(root.join("scripts/h5python"))
        .arg(root.join("scripts/check_results_layout.py"))
        .arg(path)
        .args(["--expect", expect])
        .output()
        .expect("scripts/h5python runs");
    assert!(
        check.status.success(),
        "{}{}",
        String::from_utf8_lossy(&check.stdout),
        String::from_utf8_lossy(&check.stderr)
    );
}
