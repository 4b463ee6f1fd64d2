//! Tests of the stage sequencer: conditions, caps, servo holds and the stage records.

use super::*;
use crate::scene::parse_scene;

/// One closed FCC cell (R = 1 mm, a = 2√2 mm) in a box of six walls touching it.
fn cell_scene(stages: &str) -> Scene {
    parse_scene("cell.toml", &cell_text(stages), &[])
        .expect("scene parses")
        .scene
}

/// The text of [`cell_scene`].
fn cell_text(stages: &str) -> String {
    let r = 1.0e-3;
    let a = 2.0 * std::f64::consts::SQRT_2 * r;
    let (lo, hi) = (-r, a + r);
    let mut text = format!(
        r#"
[simulation]
duration = 1.0
[materials.glass]
youngs_modulus = 63e9
poisson_ratio = 0.22
density = 2500.0
[[packings]]
name = "cell"
lattice = "fcc"
cells = [1, 1, 1]
faces = "closed"
material = "glass"
sphere = {{ radius = {r:e}, seeding = 5e-4 }}
"#
    );
    for (name, k, sign, p) in [
        ("x_min", 0, 1.0, lo),
        ("x_max", 0, -1.0, hi),
        ("y_min", 1, 1.0, lo),
        ("y_max", 1, -1.0, hi),
        ("bottom", 2, 1.0, lo),
        ("top", 2, -1.0, hi),
    ] {
        let mut point = [0.0; 3];
        let mut normal = [0.0; 3];
        point[k] = p;
        normal[k] = sign;
        text += &format!("[[walls]]\nname = \"{name}\"\npoint = {point:?}\nnormal = {normal:?}\n");
    }
    text += stages;
    text
}

const SERVO: &str = r#"{ servo = { stress = 5.0e4, area_of = "cell" } }"#;

/// Advances the plan with wall forces from `forces(step, measure)` until it finishes
/// or `steps` pass; returns the progress.
fn drive(
    plan: &StagePlan,
    dt: f64,
    steps: usize,
    forces: impl Fn(usize, Option<&CellMeasure>) -> Vec<f64>,
) -> StageProgress {
    let mut p = plan.start();
    let mut kin: Vec<Option<ServoState>> = vec![Some(ServoState::default()); 6];
    for n in 0..steps {
        p.wall_displacements = (kin.iter().zip(&plan.walls))
            .map(|(k, (_, normal))| normal.map(|c| c * k.unwrap().displacement))
            .collect();
        let m = plan.measure(&p.wall_displacements, &p.wall_forces);
        let f = forces(n, m.as_ref());
        plan.advance(&mut p, kin.iter_mut(), &f, (n + 1) as f64 * dt, dt);
        if p.finished {
            break;
        }
    }
    p
}

#[test]
fn a_strain_rate_wall_ends_its_stage_at_the_axial_strain() {
    let scene = cell_scene(
        r#"
[[stages]]
name = "shear"
walls = { top = { strain_rate = 10.0 } }
until = { axial_strain = 0.01, max_time = 1.0 }
"#,
    );
    let plan = StagePlan::build(&scene).expect("staged");
    assert_eq!(plan.axial, 2);
    let dt = 1e-6;
    let p = drive(&plan, dt, 10_000, |_, _| vec![0.0; 6]);
    assert!(p.finished);
    let r = &p.done[0];
    assert_eq!(r.reason, StageEnd::AxialStrain);
    // ε = r t: 0.01 at t = 1 ms (the first step moves nothing: the speed is set after it)
    assert!((r.end - 1.0e-3).abs() <= 2.0 * dt, "ended at {}", r.end);
}

/// A first stage moving the top wall until `wall_force` (the TOML value), then a short
/// hold; `wall` carries 1 N at the steps where `loaded(step)`, every other wall none.
/// Returns the plan and the progress after 20 000 steps of 0.1 µs.
fn wall_force_run(
    wall_force: &str,
    wall: &str,
    loaded: impl Fn(usize) -> bool,
) -> (StagePlan, StageProgress) {
    let scene = cell_scene(&format!(
        "[[stages]]\nname = \"pack\"\nwalls = {{ top = {{ velocity = 0.5 }} }}\n\
         until = {{ wall_force = {wall_force}, max_time = 1.0 }}\n\n\
         [[stages]]\nname = \"hold\"\nuntil = {{ max_time = 1.0e-4 }}\n"
    ));
    let plan = StagePlan::build(&scene).expect("staged");
    let w = scene.walls.iter().position(|x| x.name == wall).unwrap();
    let p = drive(&plan, 1e-7, 20_000, |n, _| {
        let mut f = vec![0.0; 6];
        f[w] = if loaded(n) { 1.0 } else { 0.0 };
        f
    });
    (plan, p)
}

#[test]
fn a_wall_force_ends_the_stage_once_the_filtered_force_reaches_it() {
    let dt = 1e-7;
    // the bottom wall is loaded from step 1000 on, with 1 N
    let (plan, p) = wall_force_run(r#"{ wall = "bottom", force = 0.2 }"#, "bottom", |n| {
        n >= 1000
    });
    let r = &p.done[0];
    assert_eq!(r.reason, StageEnd::WallForce);
    // after the filter's delay, well before the time limit
    assert!(
        r.end > 1000.0 * dt && r.end < 1000.0 * dt + 5.0 * plan.filter_time + 10.0 * dt,
        "{}",
        r.end
    );
    assert_eq!(p.done.len(), 2);
    // an unknown wall is an input error naming the field
    let bad = parse_scene(
        "cell.toml",
        &cell_text(
            "[[stages]]\nname = \"p\"\nuntil = { wall_force = { wall = \"floor\", force = 1.0 }, max_time = 1.0 }\n",
        ),
        &[],
    )
    .unwrap_err();
    assert!(
        bad.to_string().contains("stages[0].until.wall_force.wall"),
        "{bad}"
    );
}

#[test]
fn a_wall_force_with_hold_ignores_a_spike_and_ends_once_the_force_stays() {
    let dt = 1e-7;
    // an impact: 1 N for 100 steps (10 µs < hold) at step 1000; then 1 N from step 5000
    let (plan, p) = wall_force_run(
        r#"{ wall = "top", force = 0.2, hold = 5.0e-5 }"#,
        "top",
        |n| (1000..1100).contains(&n) || n >= 5000,
    );
    let r = &p.done[0];
    assert_eq!(r.reason, StageEnd::WallForce);
    let held_from = 5000.0 * dt + plan.filter_time;
    assert!(
        r.end >= 5000.0 * dt + 5.0e-5
            && r.end < held_from + 5.0e-5 + 5.0 * plan.filter_time + 10.0 * dt,
        "{}",
        r.end
    );
}

#[test]
fn the_stress_ratio_is_undefined_while_the_lateral_walls_only_graze() {
    let scene = cell_scene(&format!(
        r#"
[[stages]]
name = "shear"
walls = {{ top = {{ strain_rate = 10.0 }}, x_min = {SERVO}, x_max = {SERVO}, y_min = {SERVO}, y_max = {SERVO} }}
until = {{ max_time = 1.0 }}
"#
    ));
    let plan = StagePlan::build(&scene).expect("staged");
    let u = vec![[0.0; 3]; 6];
    let ratio = |lateral: f64| {
        plan.measure(&u, &[lateral, lateral, lateral, lateral, 1.0, 1.0])
            .expect("cell")
            .ratio
    };
    // equal areas at the start: σ1/σ3 is the force ratio
    assert!((ratio(0.25) - 4.0).abs() < 1e-12);
    assert!(
        (ratio(2.0 * RATIO_LATERAL_FLOOR) - 0.5 / RATIO_LATERAL_FLOOR).abs()
            < 1e-6 / RATIO_LATERAL_FLOOR
    );
    assert_eq!(ratio(1e-9), 0.0);
    assert_eq!(ratio(0.0), 0.0);
}

/// One shearing stage: the top wall at a strain rate, the lateral walls servo-held,
/// ended by a 5 % drop below the peak and 2e-3 more strain.
fn failure_stage_plan() -> StagePlan {
    let scene = cell_scene(&format!(
        r#"
[[stages]]
name = "shear"
walls = {{ top = {{ strain_rate = 10.0 }}, x_min = {SERVO}, x_max = {SERVO}, y_min = {SERVO}, y_max = {SERVO} }}
until = {{ failure = {{ drop = 0.05, strain_margin = 0.002 }}, max_time = 1.0 }}
"#
    ));
    StagePlan::build(&scene).expect("staged")
}

#[test]
fn failure_is_detected_after_the_peak_and_the_stage_runs_on_for_the_margin() {
    let plan = failure_stage_plan();
    // σ_axial/σ_lateral (forces on equal areas at the start) rises to 3 at ε = 0.004
    // then falls linearly; the lateral walls carry 1 N
    let curve = |eps: f64| {
        if eps < 0.004 {
            1.0 + 500.0 * eps
        } else {
            3.0 - 200.0 * (eps - 0.004)
        }
    };
    let p = drive(&plan, 1e-6, 100_000, |_, m| {
        let eps = m.map_or(0.0, |m| m.strain[2]);
        let area = |k: usize| {
            m.map_or(1.0, |m| {
                let l = m.distance.map(|d| d - 2.0e-3);
                l[(k + 1) % 3] * l[(k + 2) % 3]
            })
        };
        // lateral stress 1 Pa·(1/area) normalised: forces ∝ area so σ_lat = const
        let lat = |k: usize| area(k) / area(0);
        let ax = curve(eps) * area(2) / area(0);
        vec![lat(0), lat(0), lat(1), lat(1), ax, ax]
    });
    let r = &p.done[0];
    assert_eq!(r.reason, StageEnd::Failure);
    let peak = r.peak.expect("peak");
    // the measured forces are low-pass filtered: the curve is seen late by
    // rate × τ_f of strain, and its corner rounded by as much
    let lag = 10.0 * plan.filter_time;
    assert!(lag > 0.0 && lag < 1e-4, "filter lag {lag} in strain");
    assert!(
        (peak.ratio - 3.0).abs() < 500.0 * lag,
        "peak {}",
        peak.ratio
    );
    assert!((peak.axial_strain - 0.004).abs() < 2e-5 + 2.0 * lag);
    let fail = r.failure.expect("failure");
    // 5 % below the peak: 2.85 at ε = 0.004 + 0.15/200
    assert!(
        (fail.axial_strain - 0.00475).abs() < 2e-5 + 2.0 * lag,
        "{fail:?}"
    );
    // the ratio falls linearly over the margin, 2.85 → 2.45: its mean is 2.65
    let residual = r.residual.expect("a post-failure mean");
    assert!(
        (residual - 2.65).abs() < 200.0 * (2.0 * lag + 2e-5),
        "residual {residual}"
    );
    // the strain measured at the end lags r·t by the step before the wall starts
    let end_strain = 10.0 * r.end;
    assert!(
        (end_strain - (fail.axial_strain + 0.002)).abs() < 5e-5,
        "ended at ε = {end_strain}, failure at {}",
        fail.axial_strain
    );
}

#[test]
fn stress_held_ends_the_stage_after_the_hold_time_and_the_next_stage_starts() {
    let scene = cell_scene(&format!(
        r#"
[[stages]]
name = "hold"
walls = {{ top = {SERVO} }}
until = {{ stress_held = {{ tolerance = 0.01, time_constants = 1.0 }}, max_time = 1.0 }}
[[stages]]
name = "rest"
until = {{ max_time = 1.0e-4 }}
"#
    ));
    let plan = StagePlan::build(&scene).expect("staged");
    let (control, tau) = match &plan.stages[0].modes[5] {
        WallMode::Servo { control, .. } => (control.clone(), control.time_constant),
        m => panic!("top is {m:?}"),
    };
    let dt = tau / 1000.0;
    // the top wall pressing a spring of the servo's design stiffness: F = k s
    let mut p = plan.start();
    let mut kin: Vec<Option<ServoState>> = vec![Some(ServoState::default()); 6];
    let mut n = 0;
    let (mut settling, mut holding) = (0, 0);
    while p.index == 0 && n < 100_000 {
        // the progress line says whether the servo holds yet, and for how long
        match plan.waiting_on(&p, n as f64 * dt).as_deref() {
            Some("servos not yet within 1 %") => settling += 1,
            Some(s) if s.starts_with("servos within 1 % for ") => holding += 1,
            other => panic!("step {n}: {other:?}"),
        }
        let s = kin[5].unwrap().displacement;
        let mut f = vec![0.0; 6];
        f[5] = control.stiffness * s;
        p.wall_displacements = vec![[0.0; 3]; 6];
        plan.advance(&mut p, kin.iter_mut(), &f, (n + 1) as f64 * dt, dt);
        n += 1;
    }
    let r = &p.done[0];
    assert_eq!(r.reason, StageEnd::StressHeld);
    // the loop settles within 1 % in a few τ, then holds for one τ
    assert!(
        r.end > tau && r.end < 10.0 * tau,
        "ended at {} (τ = {tau})",
        r.end
    );
    assert_eq!(p.index, 1);
    assert!((p.started_at - r.end).abs() < 1e-15);
    assert!(settling > 0 && holding > 0, "{settling} {holding}");
    // the last stage ends on its time cap only: the ETA needs no condition
    assert_eq!(plan.waiting_on(&p, r.end), None);
}

#[test]
fn the_progress_line_of_a_failure_stage_gives_the_ratio_the_peak_and_the_margin() {
    let plan = failure_stage_plan();
    let mut p = plan.start();
    // equal areas at the start: σ1/σ3 is the force ratio
    p.wall_displacements = vec![[0.0; 3]; 6];
    p.wall_forces = vec![1.0, 1.0, 1.0, 1.0, 2.5, 2.5];
    let said = |p: &StageProgress| plan.waiting_on(p, 0.0).expect("a condition");
    assert_eq!(said(&p), "σ1/σ3 2.500");
    let point = |ratio, axial_strain| RatioPoint {
        ratio,
        time: 0.0,
        axial_strain,
    };
    p.peak = Some(point(3.0, 4e-3));
    assert_eq!(said(&p), "σ1/σ3 2.500, peak 3.000 at axial strain 4.00e-3");
    // failure detected 1e-3 of strain ago: half the 2e-3 margin is run
    p.failure = Some(point(2.85, -1e-3));
    assert_eq!(said(&p), "failed at axial strain -1.00e-3, margin 50 % run");
}
