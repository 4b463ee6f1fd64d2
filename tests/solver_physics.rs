//! Physics of the explicit solver on one rank: patch test, objectivity, energy
//! conservation, wave speed, stability and thread determinism. Every reference value is
//! computed from its formula for the material the test uses.

use mufe::lanes::NodeForce;
use mufe::material::{ElasticParameters, StVenantKirchhoff};
use mufe::scene::parse_scene;
use mufe::solver::build_solver;
use mufe::solver::forces::{compute_internal_forces_into, ElementScratch};
use mufe::solver::Solver;

const GLASS: &str = r#"
[materials.glass]
youngs_modulus = 63e9
poisson_ratio = 0.22
density = 2500.0
"#;

fn solver_from(text: &str) -> Solver {
    let loaded = parse_scene("test.toml", text, &[]).expect("scene parses");
    build_solver(&loaded).expect("model builds")
}

fn sphere_scene(extra_grain: &str, extra: &str, seeding: f64) -> String {
    format!(
        r#"
[simulation]
duration = 1.0
{GLASS}
[[grains]]
name = "s"
material = "glass"
shape = {{ sphere = {{ radius = 1.1e-3, seeding = {seeding} }} }}
{extra_grain}
{extra}
"#
    )
}

/// Deterministic pseudo-random numbers in [-1, 1] (no dependency, reproducible).
fn lcg(seed: &mut u64) -> f64 {
    *seed = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    ((*seed >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
}

/// Patch test: a linear displacement field x = (I + A)X on any mesh gives every element
/// the same F, hence the exact uniform stress, and zero resultant at interior nodes.
fn assert_patch_test(mut solver: Solver, label: &str) {
    let a = [
        [1.0e-4, 3.0e-5, -2.0e-5],
        [-1.0e-5, -5.0e-5, 4.0e-5],
        [2.0e-5, 1.0e-5, 7.0e-5],
    ];
    let model = &solver.model;
    let x: Vec<[f64; 3]> = model
        .x0
        .iter()
        .map(|p| {
            let mut q = *p;
            for i in 0..3 {
                for j in 0..3 {
                    q[i] += a[i][j] * p[j];
                }
            }
            q
        })
        .collect();
    let mut scratch = ElementScratch::new(model);
    let mut force = vec![NodeForce::ZERO; model.num_nodes()];
    compute_internal_forces_into(model, &x, &mut [], &mut scratch, &mut force);

    // exact stress for the uniform F
    let f_exact = [
        1.0 + a[0][0],
        a[0][1],
        a[0][2],
        a[1][0],
        1.0 + a[1][1],
        a[1][2],
        a[2][0],
        a[2][1],
        1.0 + a[2][2],
    ];
    let law = StVenantKirchhoff::new(&ElasticParameters::paper_glass());
    let (p_exact, _) = law.first_piola_and_energy(&f_exact);
    let p_scale = p_exact.iter().map(|v| v.abs()).fold(0.0, f64::max);
    for (e, t) in model.tets.iter().enumerate() {
        let xe = t.map(|n| x[n as usize]);
        let f = mufe::element::deformation_gradient(&xe, &model.tet_reference.get(e).dm_inv);
        let (p, _) = law.first_piola_and_energy(&f);
        for k in 0..9 {
            assert!(
                (p[k] - p_exact[k]).abs() < 1e-9 * p_scale,
                "{label}: element {e} stress {k}: {} vs {}",
                p[k],
                p_exact[k]
            );
        }
    }
    // interior nodes: Σ of element forces vanishes (relative to one element's force)
    let surface: std::collections::BTreeSet<u32> = model
        .grains
        .iter()
        .flat_map(|g| g.surface.nodes.iter().copied())
        .collect();
    let typical = force
        .iter()
        .map(|f| (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt())
        .fold(0.0, f64::max);
    let mut interior = 0;
    for (n, f) in force.iter().enumerate() {
        if !surface.contains(&(n as u32)) {
            interior += 1;
            let norm = (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt();
            assert!(
                norm < 1e-9 * typical,
                "{label}: interior node {n} force {norm} vs boundary {typical}"
            );
        }
    }
    assert!(interior > 0, "{label}: mesh has interior nodes");
    solver.state.x = x;
}

#[test]
fn patch_test_on_sphere_and_distorted_block() {
    assert_patch_test(solver_from(&sphere_scene("", "", 3e-4)), "sphere");
    // A block whose interior nodes are moved randomly: still exact.
    let text = format!(
        "[simulation]\nduration = 1.0\n{GLASS}\n[[grains]]\nname = \"b\"\nmaterial = \"glass\"\nshape = {{ block = {{ size = [1e-3, 1e-3, 1e-3], divisions = [5, 5, 5] }} }}\n"
    );
    let loaded = parse_scene("block.toml", &text, &[]).unwrap();
    let mut solver = build_solver(&loaded).unwrap();
    // distort interior nodes, then rebuild the reference data from the distorted mesh
    let h = 1e-3 / 5.0;
    let mut seed = 7;
    let surface: std::collections::BTreeSet<u32> = solver.model.grains[0]
        .surface
        .nodes
        .iter()
        .copied()
        .collect();
    for (n, p) in solver.model.x0.iter_mut().enumerate() {
        if !surface.contains(&(n as u32)) {
            for c in p.iter_mut() {
                *c += 0.25 * h * lcg(&mut seed);
            }
        }
    }
    for (e, t) in solver.model.tets.clone().iter().enumerate() {
        let reference = mufe::element::TetReference::new(t.map(|n| solver.model.x0[n as usize]))
            .expect("distorted tet stays valid");
        solver.model.tet_reference.set(e, reference);
    }
    assert_patch_test(solver, "distorted block");
}

fn max_von_mises(solver: &Solver) -> f64 {
    mufe::driver::frames::element_fields(solver)
        .von_mises
        .into_iter()
        .fold(0.0, f64::max)
}

#[test]
fn rigid_rotation_by_90_degrees_leaves_zero_stress() {
    let p = ElasticParameters::paper_glass();
    for increments in [1u64, 7, 400] {
        // rotate about an oblique axis through the centre by exactly 90° in `increments` steps
        let dt = 1e-9;
        let t_end = increments as f64 * dt;
        let axis = [1.0 / 3f64.sqrt(); 3];
        let w = std::f64::consts::FRAC_PI_2 / t_end;
        let extra = format!(
            "[[boundaries]]\nname = \"spin\"\ngrain = \"s\"\nselect = \"all\"\ncentre = [0.0, 0.0, 0.0]\nangular_velocity = {{ times = [0.0], values = [[{}, {}, {}]] }}\n",
            w * axis[0],
            w * axis[1],
            w * axis[2]
        );
        let text = sphere_scene("", &extra, 3e-4).replace(
            "duration = 1.0",
            &format!("duration = {t_end:e}\ndt = {dt:e}"),
        );
        let mut solver = solver_from(&text);
        for _ in 0..increments {
            solver.step().unwrap();
        }
        // the grain really turned by 90°: a node at (R,0,0)-ish moved far
        let moved = solver
            .state
            .x
            .iter()
            .zip(&solver.model.x0)
            .map(|(x, x0)| {
                ((x[0] - x0[0]).powi(2) + (x[1] - x0[1]).powi(2) + (x[2] - x0[2]).powi(2)).sqrt()
            })
            .fold(0.0, f64::max);
        assert!(moved > 1.0e-3, "rotation happened ({moved} m)");
        let vm = max_von_mises(&solver);
        assert!(
            vm < 1e-12 * p.youngs_modulus,
            "{increments} increments: von Mises {vm} Pa"
        );
        assert!(
            solver.state.energy.strain() < 1e-20,
            "strain energy {}",
            solver.state.energy.strain()
        );
    }
}

#[test]
fn free_spin_at_1000_rad_per_s_is_objective_and_conserves_angular_momentum() {
    let p = ElasticParameters::paper_glass();
    let omega = 1000.0;
    let r = 1.1e-3;
    let grain = format!("angular_velocity = [0.0, 0.0, {omega}]");
    let mut solver = solver_from(&sphere_scene(&grain, "", 3.5e-4));
    let l0 = solver.angular_momentum();
    let l0n = (l0[0] * l0[0] + l0[1] * l0[1] + l0[2] * l0[2]).sqrt();
    let bound_ratio = 10.0 * p.density * omega * omega * r * r / p.youngs_modulus;
    let mut max_ratio_first_half: f64 = 0.0;
    let mut max_ratio_second_half: f64 = 0.0;
    let steps = 10_000;
    for k in 0..steps {
        solver.step().unwrap();
        let e = &solver.state.energy;
        let ratio = e.strain() / e.kinetic;
        assert!(
            ratio < bound_ratio,
            "step {k}: U/KE = {ratio:e} ≥ 10ρω²R²/E = {bound_ratio:e}"
        );
        if k < steps / 2 {
            max_ratio_first_half = max_ratio_first_half.max(ratio);
        } else {
            max_ratio_second_half = max_ratio_second_half.max(ratio);
        }
    }
    // no growth: the second half never exceeds the first half's peak by more than 10 %
    assert!(
        max_ratio_second_half <= 1.1 * max_ratio_first_half,
        "{max_ratio_second_half:e} vs {max_ratio_first_half:e}"
    );
    let l = solver.angular_momentum();
    let dl = ((l[0] - l0[0]).powi(2) + (l[1] - l0[1]).powi(2) + (l[2] - l0[2]).powi(2)).sqrt();
    assert!(dl / l0n < 1e-8, "angular momentum drift {:e}", dl / l0n);
    // it really spun: total angle ω·t
    assert!(omega * solver.state.time > 1e-4);
}

#[test]
fn free_vibration_conserves_energy_over_1e5_steps() {
    let mut solver = solver_from(&sphere_scene("", "", 5.5e-4));
    // smooth, non-rigid initial velocity field: a breathing + shearing mode
    let r = 1.1e-3;
    let v0 = 0.05;
    for (v, x) in solver.state.v.iter_mut().zip(&solver.model.x0) {
        *v = [
            v0 * x[0] / r,
            -0.5 * v0 * x[1] / r,
            v0 * (x[0] * x[1]) / (r * r),
        ];
    }
    let mut e0 = None;
    let mut max_dev: f64 = 0.0;
    let mut max_strain: f64 = 0.0;
    for _ in 0..100_000 {
        solver.step().unwrap();
        let e = &solver.state.energy;
        let total = e.kinetic + e.strain();
        let e0v = *e0.get_or_insert(total);
        max_dev = max_dev.max((total - e0v).abs() / e0v);
        max_strain = max_strain.max(e.strain());
    }
    assert!(max_dev < 1e-3, "energy deviation {max_dev:e}");
    // it really vibrated: energy moved into strain
    assert!(
        max_strain > 0.1 * e0.unwrap(),
        "strain energy peak {max_strain:e} vs total {:e}",
        e0.unwrap()
    );
}

#[test]
fn confined_pulse_travels_at_the_dilatational_speed() {
    let p = ElasticParameters::paper_glass();
    let cp = p.dilatational_wave_speed();
    let (length, cells, h) = (0.1, 200usize, 0.1 / 200.0);
    let pulse = 20.0 * h / cp; // half-sine of 20 elements' transit time
    let peak_v = 0.01;
    // half-sine velocity history sampled finely (piecewise linear)
    let n = 40;
    let mut times = Vec::new();
    let mut values = Vec::new();
    for k in 0..=n {
        let t = pulse * k as f64 / n as f64;
        times.push(format!("{t:e}"));
        values.push(format!(
            "[{:e}, 0.0, 0.0]",
            peak_v * (std::f64::consts::PI * t / pulse).sin()
        ));
    }
    times.push(format!("{:e}", 1.01 * pulse));
    values.push("[0.0, 0.0, 0.0]".into());
    let duration = 0.8 * length / cp;
    let text = format!(
        r#"
[simulation]
duration = {duration:e}
{GLASS}
[[grains]]
name = "bar"
material = "glass"
shape = {{ block = {{ size = [{length}, {h}, {h}], divisions = [{cells}, 1, 1] }} }}

[[boundaries]]
name = "lateral"
grain = "bar"
select = "all"
components = [false, true, true]

[[boundaries]]
name = "hammer"
grain = "bar"
select = {{ beyond_plane = {{ point = [{hp:e}, 0.0, 0.0], normal = [-1.0, 0.0, 0.0] }} }}
components = [true, false, false]
velocity = {{ times = [{t}], values = [{v}] }}
"#,
        hp = 0.5 * h,
        t = times.join(", "),
        v = values.join(", ")
    );
    let mut solver = solver_from(&text);
    let stations = [0.2 * length, 0.6 * length];
    let nodes: Vec<Vec<usize>> = stations
        .iter()
        .map(|xs| {
            (0..solver.model.num_nodes())
                .filter(|&i| (solver.model.x0[i][0] - xs).abs() < 0.5 * h)
                .collect()
        })
        .collect();
    // centroid in time of the velocity signal at each station
    let mut moments = [[0.0f64; 2]; 2];
    let steps = (duration / solver.model.dt) as u64;
    for _ in 0..steps {
        solver.step().unwrap();
        let t = solver.state.time;
        for (s, ns) in nodes.iter().enumerate() {
            let v: f64 = ns.iter().map(|&i| solver.state.v[i][0]).sum::<f64>() / ns.len() as f64;
            moments[s][0] += v;
            moments[s][1] += v * t;
        }
    }
    let arrival: Vec<f64> = moments.iter().map(|m| m[1] / m[0]).collect();
    let speed = (stations[1] - stations[0]) / (arrival[1] - arrival[0]);
    let err = (speed - cp).abs() / cp;
    assert!(
        err < 0.02,
        "pulse speed {speed:.1} m/s vs c_p {cp:.1} m/s ({:.2} %)",
        100.0 * err
    );
}

#[test]
fn run_at_stable_step_is_stable_and_blow_up_is_reported() {
    // at the reported stable step: bounded energy over many steps with a rough initial field
    let mut solver = solver_from(&sphere_scene("", "", 3e-4));
    let mut seed = 11;
    for v in solver.state.v.iter_mut() {
        *v = [
            0.01 * lcg(&mut seed),
            0.01 * lcg(&mut seed),
            0.01 * lcg(&mut seed),
        ];
    }
    let ke0: f64 = solver
        .state
        .v
        .iter()
        .zip(&solver.model.mass)
        .map(|(v, m)| 0.5 * m * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]))
        .sum();
    for _ in 0..5000 {
        solver.step().expect("stable at the reported step");
    }
    let e = &solver.state.energy;
    assert!(
        e.kinetic + e.strain() < 1.05 * ke0,
        "energy grew: {} vs {}",
        e.kinetic + e.strain(),
        ke0
    );

    // beyond it: detected and named
    let mut solver = solver_from(&sphere_scene("", "", 3e-4));
    let mut seed = 5;
    for v in solver.state.v.iter_mut() {
        *v = [
            1e-3 * lcg(&mut seed),
            1e-3 * lcg(&mut seed),
            1e-3 * lcg(&mut seed),
        ];
    }
    solver.model.dt *= 8.0;
    let mut err = None;
    for _ in 0..20_000 {
        if let Err(e) = solver.step() {
            err = Some(e.to_string());
            break;
        }
    }
    let msg = err.expect("blow-up detected");
    assert!(msg.contains("blow-up at t ="), "{msg}");
    assert!(msg.contains("step"), "{msg}");
    assert!(msg.contains("element"), "{msg}");
}

#[test]
fn one_and_two_threads_are_bitwise_identical() {
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let mut solver = solver_from(&sphere_scene(
                "velocity = [0.5, 0.0, 0.0]\nangular_velocity = [100.0, 2000.0, 0.0]",
                "",
                8e-5,
            ));
            let mut seed = 3;
            for v in solver.state.v.iter_mut() {
                v[0] += 0.01 * lcg(&mut seed);
            }
            for _ in 0..300 {
                solver.step().unwrap();
            }
            (
                solver.state.x.clone(),
                solver.state.v.clone(),
                solver.state.energy.clone(),
            )
        })
    };
    let (x1, v1, e1) = run(1);
    let (x2, v2, e2) = run(2);
    assert!(
        x1.len() > mufe::solver::forces::NODE_CHUNK,
        "mesh large enough for several node chunks: {} nodes",
        x1.len()
    );
    assert!(x1 == x2, "positions differ");
    assert!(v1 == v2, "velocities differ");
    assert_eq!(e1, e2);
}

#[test]
fn deformation_damping_removes_vibration_but_not_rigid_motion() {
    // A spinning, translating, vibrating sphere: damping relative to the rigid-body motion
    // must leave linear and angular momentum untouched, remove the vibration, and account
    // the removed energy as damping dissipation.
    let grain = "velocity = [0.3, 0.0, 0.0]\nangular_velocity = [0.0, 0.0, 500.0]";
    let text = sphere_scene(grain, "", 4e-4).replace(
        "duration = 1.0",
        "duration = 1.0\ndeformation_damping = 3e6",
    );
    let mut solver = solver_from(&text);
    let r = 1.1e-3;
    for (v, x) in solver.state.v.iter_mut().zip(&solver.model.x0) {
        v[0] += 0.05 * x[0] / r;
        v[2] -= 0.05 * x[2] / r;
    }
    let p0 = solver.linear_momentum();
    let l0 = solver.angular_momentum();
    let mut strain_peak: f64 = 0.0;
    for k in 0..4000 {
        solver.step().unwrap();
        if k < 200 {
            strain_peak = strain_peak.max(solver.state.energy.strain());
        }
    }
    let p = solver.linear_momentum();
    let l = solver.angular_momentum();
    let rel = |a: [f64; 3], b: [f64; 3]| {
        let d = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
        d / (b[0] * b[0] + b[1] * b[1] + b[2] * b[2]).sqrt()
    };
    assert!(rel(p, p0) < 1e-10, "linear momentum drift {:e}", rel(p, p0));
    assert!(rel(l, l0) < 1e-8, "angular momentum drift {:e}", rel(l, l0));
    let e = &solver.state.energy;
    assert!(
        e.strain() < 1e-3 * strain_peak,
        "vibration not damped: {} vs peak {}",
        e.strain(),
        strain_peak
    );
    assert!(e.damping_dissipation() > 0.0);
    assert!(
        e.relative_balance_error() < 1e-3,
        "balance {:e}",
        e.relative_balance_error()
    );
}

/// Energy that enters outside the ledger (here: every node kicked after step 3) is what
/// an unstable integration looks like to the check, which runs every
/// `ENERGY_CHECK_EVERY` steps: the run stops at the first checked step after the kick,
/// naming it, and not before.
#[test]
fn energy_from_nowhere_stops_the_run_at_the_next_checked_step() {
    use mufe::solver::step::ENERGY_CHECK_EVERY;
    let mut solver = solver_from(&sphere_scene("", "", 3e-4));
    for _ in 0..3 {
        solver.step().expect("at rest");
    }
    for v in solver.state.v.iter_mut() {
        *v = [1.0, 0.0, 0.0];
    }
    let mut failed = None;
    for _ in 0..3 * ENERGY_CHECK_EVERY {
        if let Err(e) = solver.step() {
            failed = Some(e.to_string());
            break;
        }
    }
    let message = failed.expect("the kick is caught");
    assert!(message.contains("energy exploded"), "{message}");
    assert!(
        message.contains(&format!("(step {ENERGY_CHECK_EVERY})")),
        "{message}"
    );
    assert_eq!(solver.state.step, ENERGY_CHECK_EVERY);
}

#[test]
fn a_scene_at_rest_does_not_trip_the_blow_up_check() {
    // A sphere at rest and a plate approaching it across a 0.1 µm gap: until they touch no
    // work is supplied and KE + U is round-off (~1e-28 J), which the check must not
    // mistake for an explosion (it once stopped such a run at step 25).
    let wall = "[[walls]]\nname = \"plate\"\npoint = [0.0, 0.0, 1.1001e-3]\nnormal = [0.0, 0.0, -1.0]\nvelocity = { times = [0.0], values = [[0.0, 0.0, -0.5]] }\n";
    let mut solver = solver_from(&sphere_scene("", wall, 3e-4));
    for _ in 0..500 {
        solver.step().expect("no false blow-up at rest");
    }
    assert!(
        solver.state.energy.strain() > 0.0,
        "the plate reached the sphere"
    );
}

#[test]
fn corotational_law_is_objective_in_the_solver() {
    // 90° prescribed rotation in 7 increments and a free spin: zero stress / bounded strain
    // energy, as for the default law.
    let dt = 1e-9;
    let w = std::f64::consts::FRAC_PI_2 / (7.0 * dt);
    let extra = format!(
        "[[boundaries]]\nname = \"spin\"\ngrain = \"s\"\nselect = \"all\"\ncentre = [0.0, 0.0, 0.0]\nangular_velocity = {{ times = [0.0], values = [[0.0, {w}, 0.0]] }}\n"
    );
    let text = sphere_scene("", &extra, 3e-4)
        .replace(
            "duration = 1.0",
            &format!("duration = {:e}\ndt = {dt:e}", 7.0 * dt),
        )
        .replace(
            "density = 2500.0",
            "density = 2500.0\nlaw = \"corotational\"",
        );
    let mut solver = solver_from(&text);
    assert_eq!(
        solver.model.laws[0].kind,
        mufe::material::ElasticLawKind::Corotational
    );
    for _ in 0..7 {
        solver.step().unwrap();
    }
    let vm = max_von_mises(&solver);
    assert!(
        vm < 1e-6 * ElasticParameters::paper_glass().youngs_modulus * 1e-6,
        "von Mises after 90°: {vm} Pa"
    );
}

/// A stage's `gravity` replaces `simulation.gravity` while the stage runs: a free sphere
/// gains exactly g₁·t₁ in the first stage, nothing in a weightless second one, and the
/// ledger books the work of the gravity that acted.
#[test]
fn stage_gravity_acts_only_during_its_stage_and_the_ledger_balances() {
    let (g1, t1, t2) = (-200.0, 2.0e-5, 1.0e-5);
    let stages = format!(
        "[[stages]]\nname = \"heavy\"\ngravity = [0.0, 0.0, {g1:?}]\nuntil = {{ max_time = {t1:e} }}\n\n\
         [[stages]]\nname = \"weightless\"\ngravity = [0.0, 0.0, 0.0]\nuntil = {{ max_time = {t2:e} }}\n"
    );
    let text = sphere_scene("", &stages, 5.5e-4).replace(
        "duration = 1.0",
        "duration = 1.0\ngravity = [0.0, 0.0, -9.81]",
    );
    let mut solver = solver_from(&text);
    let dt = solver.model.dt;
    let mean_vz = |s: &Solver| {
        let (mut p, mut m) = (0.0, 0.0);
        for (v, mass) in s.state.v.iter().zip(&s.model.physical_mass) {
            p += mass * v[2];
            m += mass;
        }
        p / m
    };
    let mut heavy_steps = 0u64;
    while solver.state.time < t1 + t2 - 0.5 * dt {
        let in_heavy = solver.state.stages.index == 0;
        solver.step().unwrap();
        heavy_steps += u64::from(in_heavy);
    }
    let expected = g1 * heavy_steps as f64 * dt;
    let got = mean_vz(&solver);
    assert!(
        (got / expected - 1.0).abs() < 1e-9,
        "v_z {got:e} vs g₁·t₁ = {expected:e} ({heavy_steps} heavy steps)"
    );
    assert!((heavy_steps as f64 * dt - t1).abs() <= 2.0 * dt);
    let e = &solver.state.energy;
    let drift = (e.total() - e.initial_total.unwrap_or(0.0)).abs();
    assert!(
        drift < 1e-9 * e.kinetic,
        "ledger drift {drift:e} vs KE {:e}",
        e.kinetic
    );
}
