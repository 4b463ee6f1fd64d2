//! Quick versions of the elastic–plastic validation cases, for the shipped material and for
//! materials nobody tuned the cases for: each case builds its drive from the material as
//! run, so the same targets must hold for a steel-like and a soft-rock grain.

#[path = "common/quick_case.rs"]
mod quick_case;

/// (label, `--set` overrides of the case scene's material).
fn materials() -> Vec<(&'static str, Vec<String>)> {
    let m = |field: &str, v: &str| format!("materials.glass.{field}={v}");
    vec![
        ("shipped", vec![]),
        (
            "steel-like",
            vec![
                m("youngs_modulus", "2.1e11"),
                m("poisson_ratio", "0.3"),
                m("density", "7850.0"),
                m("yield_stress", "2.5e8"),
                m("hardening_modulus", "2.0e9"),
            ],
        ),
        (
            "soft rock, perfectly plastic",
            vec![
                m("youngs_modulus", "5.0e9"),
                m("poisson_ratio", "0.25"),
                m("density", "2200.0"),
                m("yield_stress", "2.0e7"),
                m("hardening_modulus", "0.0"),
            ],
        ),
    ]
}

fn run_quick(name: &str) {
    // one thread: these models are tiny and step-bound
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    for (label, sets) in materials() {
        for o in pool.install(|| quick_case::run_quick(name, label, &sets)) {
            if let (Some(fe), Some(exact)) = (
                o.details
                    .get("plastic_dissipation_J")
                    .and_then(|v| v.as_f64()),
                o.details
                    .get("exact_plastic_work_J")
                    .and_then(|v| v.as_f64()),
            ) {
                assert!(
                    (fe - exact).abs() <= 1e-4 * exact,
                    "{name}, {label}: ALLPD {fe:e} J vs exact plastic work {exact:e} J"
                );
            }
        }
    }
}

#[test]
fn plastic_cube_quick_for_three_materials() {
    run_quick("plastic_cube");
}

/// `mufe validate` keeps each run's results: `DIR/<case>/mr_<MR>/results.h5` (the whole
/// energy ledger in `/history`, written by the same output as `mufe run`) and
/// `energy.png`, and reports the balance drift of every run in the table and the JSON.
#[test]
fn validate_keeps_each_runs_results_and_energy_plot() {
    let out = std::env::temp_dir().join(format!("mufe_validate_keeps_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_mufe"))
        .args([
            "validate",
            "plastic_cube",
            "--quick",
            "--threads",
            "1",
            "--out",
        ])
        .arg(&out)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(stdout.contains("balance"), "{stdout}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("validation.json")).unwrap())
            .unwrap();
    let runs = json.as_array().unwrap();
    assert!(!runs.is_empty());
    for run in runs {
        let mr = run["mr"].as_f64().unwrap();
        let dir = out.join("plastic_cube").join(format!("mr_{mr:.4}"));
        let path = dir.join("results.h5");
        assert_eq!(
            run["details"]["results_h5"].as_str(),
            Some(path.display().to_string().as_str())
        );
        assert!(dir.join("energy.png").is_file(), "{}", dir.display());
        let f = hdf5::File::open(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let column = |name: &str| -> Vec<f64> {
            f.dataset(&format!("history/{name}"))
                .unwrap_or_else(|e| panic!("history/{name}: {e}"))
                .read_raw()
                .unwrap()
        };
        let allpd = column("plastic_dissipation");
        let last = *allpd.last().unwrap();
        let reported = run["details"]["plastic_dissipation_J"].as_f64().unwrap();
        assert!(
            last > 0.0 && (last - reported).abs() <= 1e-12 * reported,
            "ALLPD in results.h5 {last:e} J vs the case's {reported:e} J"
        );
        let balance = run["details"]["energy_balance_error"].as_f64().unwrap();
        assert!(balance <= mufe::validate::record::BALANCE_TOLERANCE);
        assert!(column("energy_balance").iter().all(|v| v.is_finite()));
    }
    let _ = std::fs::remove_dir_all(&out);
}
