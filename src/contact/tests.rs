//! Tests of the contact stage on small scenes: detection, forces, friction and walls.

use super::*;
use crate::math::{norm, sub};
use crate::scene::parse_scene;
use crate::solver::build_solver;
use crate::solver::Solver;

const GLASS: &str = r#"
[materials.glass]
youngs_modulus = 63e9
poisson_ratio = 0.22
density = 2500.0
"#;

pub(super) fn solver(text: &str) -> Solver {
    let loaded = parse_scene("test.toml", text, &[]).expect("scene parses");
    build_solver(&loaded).expect("model builds")
}

/// What an evaluation depends on, to the bit.
pub(super) fn result_bits(r: &narrow::PointResult) -> Vec<u64> {
    let mut b = vec![u64::from(r.active), r.gap.to_bits(), r.separation.to_bits()];
    for v in [r.force, r.normal, r.traction, r.weights] {
        b.extend(v.map(f64::to_bits));
    }
    b.extend(r.masters.map(u64::from));
    b
}

/// Contact forces on every node (zero elsewhere) at the solver's current state.
fn contact_forces(s: &mut Solver) -> Vec<[f64; 3]> {
    let mut f = vec![NodeForce::ZERO; s.model.num_nodes()];
    let dt = s.model.dt;
    evaluate(
        &s.model,
        &s.state.x,
        &s.state.v,
        0.0,
        0,
        dt,
        &mut s.state.contact,
        &mut s.scratch.contact,
    )
    .unwrap();
    let _damping_power = add_forces(
        &s.model,
        &s.scratch.contact,
        &mut s.state.contact,
        &s.state.v,
        &mut f,
    );
    f.iter().map(NodeForce::xyz).collect()
}

pub(super) fn pair_scene(first: (&str, &str, [f64; 3]), second: (&str, &str, [f64; 3])) -> String {
    let grain = |(name, shape, c): (&str, &str, [f64; 3])| {
        format!("[[grains]]\nname = \"{name}\"\nmaterial = \"glass\"\nshape = {shape}\ncentre = {c:?}\n")
    };
    format!(
        "[simulation]\nduration = 1e-6\n{GLASS}\n[contact]\nfriction = 0.3\n{}{}",
        grain(first),
        grain(second)
    )
}

/// Two spheres of `radius` meshed at `seeding`, built apart (a model may not start
/// overlapped), then their positions pressed `depth` into each other along x and the
/// contact lists built there with `skin`: the solver and the pressed positions.
pub(super) fn pressed_pair_with_lists(
    radius: f64,
    seeding: f64,
    depth: f64,
    skin: f64,
) -> (Solver, Vec<[f64; 3]>) {
    let sphere = format!("{{ sphere = {{ radius = {radius:e}, seeding = {seeding:e} }} }}");
    let scene = pair_scene(
        ("a", &sphere, [0.0; 3]),
        ("b", &sphere, [2.0 * radius + depth, 0.0, 0.0]),
    );
    let mut solver = solver(&scene);
    let mut x = solver.state.x.clone();
    for n in solver.model.grains[1].nodes.clone() {
        x[n][0] -= 2.0 * depth;
    }
    let scratch = &mut solver.scratch.contact;
    scratch.broad.rebuild(
        &solver.model.contact,
        &x,
        &[],
        &mut scratch.lists,
        &mut DetectionReference::default(),
        skin,
        0,
    );
    (solver, x)
}

/// The integrator's travel bounds the surface motion between exact measures and lets
/// the narrow phase skip a node found outside until the travel since can have closed
/// its gap: two spheres, one spinning, collide; with both bounds the run is the one
/// that measures every step and evaluates every entry within reach, to the bit; each
/// bound covers the measure, most steps skip the measure, and fewer entries are
/// evaluated.
#[test]
fn travel_bounds_leave_the_run_unchanged() {
    let (radius, seeding) = (1.0e-3, 3.0e-4);
    let sphere = format!("{{ sphere = {{ radius = {radius:e}, seeding = {seeding:e} }} }}");
    // a closes on b at 3 m/s along a cube diagonal, where |v| = √3 |v|∞ makes the
    // travel bound tight head-on (a skip 5× too long then misses contact; 2× does not:
    // the nodes around the contact point close obliquely); b spins about z at 50 rad/s
    // (rim speed 0.05 m/s), which spreads its nodes' motion
    let d = 1.0 / 3f64.sqrt();
    let (ca, cb) = ([0.0; 3], [(2.0 * radius + 1e-6) * d; 3]);
    let scene = pair_scene(("a", &sphere, ca), ("b", &sphere, cb));
    let (mut every, mut measured) = (solver(&scene), solver(&scene));
    measured.scratch.contact.broad.bound_by_travel(1);
    let dt = every.model.dt;
    // until 150 steps in contact (the faceted spheres meet a little later than their
    // 1 µm gap alone says)
    let limit = (1e-4 / 3.0 / dt) as usize;
    for s in [&mut every, &mut measured] {
        for n in s.model.grains[0].nodes.clone() {
            s.state.v[n] = [3.0 * d; 3];
        }
        for n in s.model.grains[1].nodes.clone() {
            let r = sub(s.state.x[n], cb);
            s.state.v[n] = [-50.0 * r[1], 50.0 * r[0], 0.0];
        }
    }
    let (mut touching, mut evaluated, mut steps) = (0, [0, 0], 0);
    while touching < 150 && steps < limit {
        steps += 1;
        every.step().unwrap();
        measured.step().unwrap();
        evaluated[0] += every.scratch.contact.results.len();
        evaluated[1] += measured.scratch.contact.results.len();
        let (b, m) = (
            &every.scratch.contact.broad,
            &measured.scratch.contact.broad,
        );
        assert!(
            b.moved >= m.moved,
            "bound {:e} < measure {:e}",
            b.moved,
            m.moved
        );
        let closing = |br: &broad::BroadPhase| br.motion[0].closing_with(&br.motion[1]);
        assert!(closing(b) >= closing(m));
        touching += usize::from(every.state.contact.stats.points > 0);
    }
    assert_eq!(
        touching, 150,
        "the spheres touched in {touching} of {steps} steps"
    );
    assert!(
        evaluated[0] < evaluated[1],
        "entries evaluated with and without skipping: {evaluated:?}"
    );
    assert_eq!(every.state.x, measured.state.x);
    assert_eq!(every.state.v, measured.state.v);
    let (n_every, n_measured) = (
        every.scratch.contact.broad.motion_measures(),
        measured.scratch.contact.broad.motion_measures(),
    );
    // every step but the first, which builds the lists
    assert_eq!(n_measured as usize, steps - 1);
    assert!(
        n_every * 8 < n_measured,
        "{n_every} measures of {n_measured}"
    );
}

/// A thin skin changes what is evaluated, never the run: two spheres close slowly on
/// each other, so that the first skin check thins the skin, then ten times faster, so
/// that the thin lists are rebuilt on the way, and stay in contact; the run equals, to
/// the bit, the one whose skin stays at the margin, with fewer candidate facets.
#[test]
fn a_thin_skin_leaves_the_run_unchanged() {
    let (radius, seeding) = (1.0e-3, 3.0e-4);
    let sphere = format!("{{ sphere = {{ radius = {radius:e}, seeding = {seeding:e} }} }}");
    let gap = 1e-5;
    let (ca, cb) = ([0.0; 3], [2.0 * radius + gap, 0.0, 0.0]);
    let scene = pair_scene(("a", &sphere, ca), ("b", &sphere, cb));
    let (mut thin, mut fixed) = (solver(&scene), solver(&scene));
    fixed.scratch.contact.broad.fixed_skin = true;
    let dt = thin.model.dt;
    let check = broad::SKIN_CHECK_EVERY;
    // a tenth of the gap by the first check, then ten times as fast
    let slow = 0.1 * gap / (check as f64 * dt);
    let push = |s: &mut crate::solver::Solver, speed: f64| {
        for n in s.model.grains[0].nodes.clone() {
            s.state.v[n] = [speed, 0.0, 0.0];
        }
        // the kick is energy from outside the ledger: not a blow-up
        s.state.supplied_energy = f64::MAX;
    };
    push(&mut thin, slow);
    push(&mut fixed, slow);
    let margin = thin.model.contact.margin;
    let (mut touching, mut steps, mut candidates) = (0, 0, [0, 0]);
    let mut skin_at_check = 0.0;
    while touching < 200 && steps < 4 * check {
        steps += 1;
        thin.step().unwrap();
        fixed.step().unwrap();
        // the check is at the evaluation of step `check`, in the step after it
        if steps == check + 1 {
            skin_at_check = thin.state.contact.stats.skin;
            push(&mut thin, 10.0 * slow);
            push(&mut fixed, 10.0 * slow);
        }
        for (c, s) in candidates.iter_mut().zip([&thin, &fixed]) {
            *c = s.scratch.contact.lists.candidate_facets.len();
        }
        touching += usize::from(thin.state.contact.stats.points > 0);
    }
    assert_eq!(touching, 200, "touched in {touching} of {steps} steps");
    assert!(
        skin_at_check < 0.25 * margin,
        "skin {skin_at_check:e}, margin {margin:e}"
    );
    let rebuilds = [&thin, &fixed].map(|s| s.state.contact.stats.rebuilds);
    assert!(
        rebuilds[0] >= 3 && rebuilds[1] == 1,
        "rebuilds {rebuilds:?}"
    );
    assert_eq!(fixed.state.contact.stats.skin, margin);
    assert!(
        candidates[0] * 3 < candidates[1] * 2,
        "candidate facets with the thin and the fixed skin: {candidates:?}"
    );
    assert_eq!(thin.state.x, fixed.state.x);
    assert_eq!(thin.state.v, fixed.state.v);
    assert_eq!(thin.state.contact.history, fixed.state.contact.history);
}

/// The motion each surface reports since the rebuild: a translation is all shift, a
/// rotation about the grain's centre by θ spreads the nodes by up to 2θR from the
/// first node's displacement.
#[test]
fn surface_motion_separates_translation_from_rotation() {
    let (radius, seeding) = (1.0e-3, 2.5e-4);
    let sphere = format!("{{ sphere = {{ radius = {radius:e}, seeding = {seeding:e} }} }}");
    let (ca, cb) = ([0.0; 3], [2.0 * radius + 1e-5, 0.0, 0.0]);
    let mut s = solver(&pair_scene(("a", &sphere, ca), ("b", &sphere, cb)));
    contact_forces(&mut s); // the first evaluation rebuilds: motion at rest
    assert!(s
        .scratch
        .contact
        .broad
        .motion
        .iter()
        .all(|m| *m == broad::SurfaceMotion::AT_REST));
    let (shift, theta) = ([3e-6, -1e-6, 2e-6], 1e-3_f64);
    for n in s.model.grains[0].nodes.clone() {
        s.state.x[n] = crate::math::add(s.state.x[n], shift);
    }
    for n in s.model.grains[1].nodes.clone() {
        let [x, y, z] = sub(s.state.x[n], cb);
        let (c, sn) = (theta.cos(), theta.sin());
        s.state.x[n] = [cb[0] + c * x - sn * y, cb[1] + sn * x + c * y, cb[2] + z];
    }
    let dt = s.model.dt;
    needs_rebuild(
        &s.model,
        &s.state.x,
        0.0,
        0,
        dt,
        &s.state.contact,
        &mut s.scratch.contact,
    );
    let [a, b] = [0, 1].map(|g| s.scratch.contact.broad.motion[g]);
    for i in 0..3 {
        assert!((a.shift[i] - shift[i]).abs() < 1e-18, "{:?}", a.shift);
    }
    assert!(
        a.spread < 1e-18,
        "a translation spreads nothing: {:e}",
        a.spread
    );
    // the nodes move by θR at most (equator), their differences by up to 2θR
    assert!(
        norm(b.shift) <= theta * radius * (1.0 + 1e-9),
        "{:?}",
        b.shift
    );
    assert!(b.spread > theta * radius && b.spread <= 2.0 * theta * radius * (1.0 + 1e-9));
    let moved = s.scratch.contact.broad.moved;
    assert!(
        (moved - norm(shift)).abs() < 1e-15,
        "largest displacement {moved:e}"
    );
    // together they closed at most what each rule allows, and less than 2 × moved here
    let closing = a.closing_with(&b);
    assert!(closing < 2.0 * moved, "{closing:e} vs {:e}", 2.0 * moved);
}

/// Swapping the order of two grains in the scene swaps master and slave roles of the
/// passes: the contact forces on every node must stay the same (up to summation order).
#[test]
fn two_pass_contact_does_not_depend_on_grain_order() {
    let sphere = "{ sphere = { radius = 1.0e-3, seeding = 2.5e-4 } }";
    let block = "{ block = { size = [1.0e-3, 1.0e-3, 5.0e-4], divisions = [5, 4, 3] } }";
    // block spans z ∈ [0, 0.5 mm] from its corner at the origin; sphere centre above
    // its top face, shifted off the block's nodes so that contact is node-on-facet
    let a = ("ball", sphere, [4.3e-4, 4.7e-4, 1.5e-3 + 1e-7]);
    let b = ("slab", block, [0.0; 3]);
    let mut s1 = solver(&pair_scene(a, b));
    let mut s2 = solver(&pair_scene(b, a));
    // Push the sphere 25 µm (3 × the facet sagitta) into the block (and give it a sideways velocity so that
    // friction acts), identically in both solvers.
    let press = |s: &mut Solver, grain: usize| {
        let g = s.model.grains[grain].nodes.clone();
        for n in g {
            s.state.x[n][2] -= 2.5e-5;
            s.state.v[n] = [0.3, 0.1, 0.0];
        }
    };
    press(&mut s1, 0);
    press(&mut s2, 1);
    let f1 = contact_forces(&mut s1);
    let f2 = contact_forces(&mut s2);
    let (n_ball, n_slab) = (
        s1.model.grains[0].nodes.len(),
        s1.model.grains[1].nodes.len(),
    );
    assert!(
        s1.state.contact.stats.points > 4,
        "{:?}",
        s1.state.contact.stats
    );
    assert_eq!(s1.state.contact.stats.points, s2.state.contact.stats.points);
    let scale = f1.iter().map(|f| norm(*f)).fold(0.0, f64::max);
    assert!(scale > 0.0);
    // node k of the ball: index k in s1, n_slab + k in s2; slab: n_ball + k vs k
    for k in 0..n_ball {
        let d = norm(sub(f1[k], f2[n_slab + k]));
        assert!(
            d <= 1e-12 * scale,
            "ball node {k}: {:?} vs {:?}",
            f1[k],
            f2[n_slab + k]
        );
    }
    for k in 0..n_slab {
        let d = norm(sub(f1[n_ball + k], f2[k]));
        assert!(d <= 1e-12 * scale, "slab node {k}");
    }
    // action = reaction, and the resultant pushes the ball up
    let gf = &s1.state.contact.stats.grain_force;
    assert!(
        norm([
            gf[0][0] + gf[1][0],
            gf[0][1] + gf[1][1],
            gf[0][2] + gf[1][2]
        ]) < 1e-12 * norm(gf[0])
    );
    assert!(gf[0][2] > 0.0);
    assert!(!s1.state.contact.history.is_empty());
    assert_eq!(
        s1.state.contact.history.len(),
        s2.state.contact.history.len()
    );
    assert!(
        (s1.state.contact.stats.energy - s2.state.contact.stats.energy).abs()
            <= 1e-12 * s1.state.contact.stats.energy
    );
}

/// A block dropped on a fixed frictionless wall stops on it without penetrating, and at
/// rest the wall carries the block's weight.
#[test]
fn block_dropped_on_a_wall_stops_with_zero_penetration() {
    let text = format!(
        r#"
[simulation]
duration = 1e-4
gravity = [0.0, 0.0, -2.0e5]
damping = 2.0e5
{GLASS}
[[grains]]
name = "cube"
material = "glass"
shape = {{ block = {{ size = [4.0e-4, 4.0e-4, 4.0e-4], divisions = [2, 2, 2] }} }}
centre = [0.0, 0.0, 2.0e-6]
velocity = [0.0, 0.0, -0.5]

[[walls]]
name = "floor"
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
"#
    );
    let mut s = solver(&text);
    let weight = s.model.total_physical_mass() * 2.0e5;
    let mut lowest = f64::INFINITY;
    let mut touched = false;
    let steps = (1e-4 / s.model.dt) as usize;
    for _ in 0..steps {
        s.step().unwrap();
        for x in &s.state.x {
            lowest = lowest.min(x[2]);
        }
        touched |= s.state.contact.walls[0].contacts > 0;
    }
    assert!(touched);
    assert!(lowest >= -1e-18, "penetration {lowest:e}");
    // at rest on the wall: bottom nodes exactly on it, wall force = weight
    let bottom = s.state.x.iter().map(|x| x[2]).fold(f64::INFINITY, f64::min);
    assert!(bottom.abs() < 1e-18, "{bottom:e}");
    let fz = s.state.contact.walls[0].force[2];
    assert!(
        (fz - weight).abs() < 1e-3 * weight,
        "wall force {fz} vs weight {weight}"
    );
    let vmax = s.state.v.iter().map(|v| norm(*v)).fold(0.0, f64::max);
    assert!(vmax < 1e-3, "{vmax}");
}

/// A wall moving at constant velocity catches a free block and pushes it: the wall's
/// recorded displacement follows its history, no node ever gets behind it, the impulse of
/// the recorded wall force equals the block's momentum, and the wall's work closes the
/// energy balance.
#[test]
fn moving_wall_pushes_a_block() {
    let vw = 0.2;
    let text = format!(
        r#"
[simulation]
duration = 2e-5
{GLASS}
[[grains]]
name = "cube"
material = "glass"
shape = {{ block = {{ size = [3.0e-4, 3.0e-4, 3.0e-4], divisions = [2, 2, 2] }} }}

[[walls]]
name = "pusher"
point = [0.0, 0.0, -1.0e-6]
normal = [0.0, 0.0, 1.0]
velocity = {{ times = [0.0], values = [[0.0, 0.0, {vw}]] }}
"#
    );
    let mut s = solver(&text);
    let dt = s.model.dt;
    let steps = (2e-5 / dt) as usize;
    let mut impulse = 0.0;
    let mut worst_balance: f64 = 0.0;
    for _ in 0..steps {
        let t = s.state.time;
        s.step().unwrap();
        let w = &s.state.contact.walls[0];
        assert!(
            (w.displacement[2] - vw * t).abs() < 1e-12 * (1.0 + vw * t),
            "{:?}",
            w.displacement
        );
        impulse += w.force[2] * dt;
        // before the wall first does work every energy is round-off (≈ 10⁻³² J, the
        // stress of F = I to the last bit), and a ratio of round-offs means nothing
        if s.state.energy.external_work() > 0.0 {
            worst_balance = worst_balance.max(s.state.energy.relative_balance_error());
        }
        let wall_z = -1.0e-6 + vw * s.state.time;
        let lowest = s.state.x.iter().map(|x| x[2]).fold(f64::INFINITY, f64::min);
        assert!(lowest >= wall_z - 1e-15, "node behind the moving wall");
    }
    let p = s.linear_momentum()[2];
    let m = s.model.total_physical_mass();
    assert!(
        (impulse - p).abs() < 1e-9 * m * vw,
        "impulse {impulse} vs momentum {p}"
    );
    // hit by a rigid paddle, the elastic block leaves at between v_w and 2 v_w
    assert!(
        p / m > vw && p / m < 2.0 * vw,
        "block velocity {} vs wall {vw}",
        p / m
    );
    assert!(worst_balance < 1e-4, "{worst_balance}");
    assert!(s.state.energy.external_work() > 0.0);
}

/// Bad `[contact]` and `[[walls]]` input is a one-line error naming the field.
#[test]
fn contact_and_wall_input_errors_name_the_field() {
    let base = format!(
        "[simulation]\nduration = 1e-6\n{GLASS}\n[[grains]]\nname = \"g\"\nmaterial = \"glass\"\nshape = {{ sphere = {{ radius = 1e-3, seeding = 5e-4 }} }}\n"
    );
    let wall = "[[walls]]\nname = \"floor\"\npoint = [0.0, 0.0, -2e-3]\nnormal = [0.0, 0.0, 1.0]\n";
    let cases = [
        ("[contact]\nfriction = -0.1\n", "contact.friction"),
        ("[contact]\npenalty_factor = 0.0\n", "contact.penalty_factor"),
        ("[contact]\nmargin = -1e-6\n", "contact.margin"),
        ("[contact]\ndamping = 1.5\n", "contact.damping"),
        ("[contact]\nstiffness = 1.0\n", "contact"),
        ("[[walls]]\nname = \"floor\"\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 0.0, 0.0]\n", "walls[0].normal"),
        ("[[walls]]\nname = \"a b\"\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 0.0, 1.0]\n", "walls[0].name"),
        ("[[walls]]\nname = \"w\"\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 0.0, 1.0]\nfriction = -1.0\n", "walls[0].friction"),
        ("[[walls]]\nname = \"w\"\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 0.0, 1.0]\nspeed = 1.0\n", "walls"),
        (
            "[[walls]]\nname = \"w\"\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 0.0, 1.0]\nvelocity = { times = [0.0], values = [[0.0, 0.0, 1.0]] }\ndisplacement = { times = [0.0], values = [[0.0, 0.0, 1.0]] }\n",
            "walls[0].velocity",
        ),
    ];
    for (extra, field) in cases {
        let e = parse_scene("s.toml", &format!("{base}{extra}"), &[]).expect_err(extra);
        let line = e.to_string();
        assert!(line.contains(field), "{extra:?}: {line}");
        assert!(!line.contains('\n'), "{line}");
    }
    let dup = format!("{base}{wall}{wall}");
    let e = parse_scene("s.toml", &dup, &[]).expect_err("duplicate");
    assert!(e.to_string().contains("walls[1].name"), "{e}");
    // a valid wall scene builds
    assert!(parse_scene("s.toml", &format!("{base}{wall}"), &[]).is_ok());
}

/// The dampers' power that [`add_forces`] sums beside the forces is [`damping_power`] at
/// the same velocities, to the bit, and not zero: two pressed spheres closing with a spin.
#[test]
fn add_forces_returns_the_damping_power_of_its_velocities() {
    let (mut s, x) = pressed_pair_with_lists(1.0e-3, 3.0e-4, 2.0e-6, 2.0e-5);
    let mut v = vec![[0.0; 3]; s.model.num_nodes()];
    for (g, sign) in [(0, 1.0), (1, -1.0)] {
        for n in s.model.grains[g].nodes.clone() {
            // closing along x, spinning about z (rim speed 0.05 m/s)
            v[n] = [sign * 0.3, -50.0 * x[n][1], 0.0];
        }
    }
    assert!(s.model.contact.damping > 0.0, "default damping");
    let dt = s.model.dt;
    evaluate(
        &s.model,
        &x,
        &v,
        0.0,
        0,
        dt,
        &mut s.state.contact,
        &mut s.scratch.contact,
    )
    .unwrap();
    let mut f = vec![NodeForce::ZERO; s.model.num_nodes()];
    let fused = add_forces(
        &s.model,
        &s.scratch.contact,
        &mut s.state.contact,
        &v,
        &mut f,
    );
    let alone = damping_power(&s.model, &v, &s.scratch.contact);
    assert!(s.state.contact.contacts() > 0);
    assert!(fused < 0.0, "a closing damper resists: {fused:e}");
    assert_eq!(fused.to_bits(), alone.to_bits(), "{fused:e} vs {alone:e}");
}
