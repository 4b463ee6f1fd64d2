//! Quick versions of the elastic–plastic validation cases, for the shipped material and for
//! materials nobody tuned the cases for: each case builds its drive from the material as
//! run, so the same targets must hold for a steel-like and a soft-rock grain.

use mufe::validate::select_cases;

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
    let cases = select_cases(&[name.to_string()]).expect("known case");
    let case = &cases[0];
    let target = case.target(true);
    // one thread: these models are tiny and step-bound
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    for (label, sets) in materials() {
        for mr in case.default_mrs(true) {
            let o = pool
                .install(|| {
                    select_cases(&[name.to_string()]).expect("known case")[0].run(
                        mr,
                        true,
                        &sets,
                        &Default::default(),
                    )
                })
                .unwrap_or_else(|e| panic!("{name}, {label}, MR {mr}: {e}"));
            println!(
                "{name}, {label}: MR {mr}, {} elements, {} steps, error {:.3e} (quick target {:.1e}), details {}",
                o.elements,
                o.steps,
                o.error,
                target,
                serde_json::Value::Object(o.details.clone())
            );
            assert!(
                o.error.is_finite() && o.error <= target,
                "{name}, {label}, MR {mr}: error {:.3e} above the quick target {:.1e}",
                o.error,
                target
            );
            let balance = o.details["balance_error"].as_f64().unwrap();
            assert!(balance <= 5e-3, "{name}, {label}: balance error {balance}");
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
