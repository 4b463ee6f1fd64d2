//! Semantic checks of a typed scene. Each failure names the file and the dotted field.

use super::checker::{validate_servo, Checker};
use super::estimate::{estimate_scene, wave_speed, MAX_EXACT_STEPS};
use super::{BoundarySpec, History3, NodeSelector, Scene, ShapeSpec, WallSpec};
use crate::error::{echo, num, InputError};

pub(super) fn validate_scene(file: &str, scene: &Scene) -> Result<(), InputError> {
    let c = Checker { file };
    let s = &scene.simulation;
    c.positive("simulation.duration", s.duration)?;
    c.positive("simulation.dt_safety", s.dt_safety)?;
    if s.dt_safety > 1.0 {
        return Err(c.err(
            "simulation.dt_safety",
            format!("must be ≤ 1, got {}", num(s.dt_safety)),
        ));
    }
    if let Some(t) = s.target_dt {
        c.positive("simulation.target_dt", t)?;
    }
    if let Some(t) = s.dt {
        c.positive("simulation.dt", t)?;
    }
    c.non_negative("simulation.damping", s.damping)?;
    c.non_negative("simulation.deformation_damping", s.deformation_damping)?;
    c.vec3("simulation.gravity", &s.gravity)?;

    for (name, m) in &scene.materials {
        let f = |x: &str| format!("materials.{name}.{x}");
        c.positive(&f("youngs_modulus"), m.youngs_modulus)?;
        c.positive(&f("density"), m.density)?;
        c.finite(&f("poisson_ratio"), m.poisson_ratio)?;
        if !(m.poisson_ratio > -1.0 && m.poisson_ratio < 0.5) {
            return Err(c.err(
                f("poisson_ratio"),
                format!("must be in (−1, 0.5), got {}", num(m.poisson_ratio)),
            ));
        }
        plastic_parameters(&c, &f, m)?;
    }

    if scene.grains.is_empty() {
        return Err(c.err("grains", "the scene has no grains"));
    }
    let mut names = std::collections::BTreeSet::new();
    for (i, g) in scene.grains.iter().enumerate() {
        let f = |x: &str| format!("grains[{i}].{x}");
        if !scene.materials.contains_key(&g.material) {
            return Err(c.err(
                f("material"),
                format!("unknown material '{}'", echo(&g.material)),
            ));
        }
        if !names.insert(g.display_name(i)) {
            return Err(c.err(
                f("name"),
                format!("duplicate grain name '{}'", echo(&g.display_name(i))),
            ));
        }
        c.vec3(&f("centre"), &g.centre)?;
        c.vec3(&f("velocity"), &g.velocity)?;
        c.vec3(&f("angular_velocity"), &g.angular_velocity)?;
        match &g.shape {
            ShapeSpec::Sphere(sp) => {
                sp.validate().map_err(|e| match e {
                    crate::mesh::MeshError::InvalidSpec { field, message } => {
                        c.err(format!("grains[{i}].shape.sphere.{field}"), message)
                    }
                    other => c.err(f("shape.sphere"), other.to_string()),
                })?;
            }
            // Fields and the file itself are checked when the scene is loaded (surfaces.rs).
            ShapeSpec::Surface(_) => {}
            ShapeSpec::Block(b) => {
                for k in 0..3 {
                    c.positive(&format!("grains[{i}].shape.block.size[{k}]"), b.size[k])?;
                    if b.divisions[k] == 0 {
                        return Err(c.err(
                            format!("grains[{i}].shape.block.divisions[{k}]"),
                            "must be ≥ 1",
                        ));
                    }
                }
            }
        }
    }

    for (i, b) in scene.boundaries.iter().enumerate() {
        validate_boundary(&c, scene, i, b)?;
    }

    let ct = &scene.contact;
    c.non_negative("contact.friction", ct.friction)?;
    if let Some(f) = ct.penalty_factor {
        c.positive("contact.penalty_factor", f)?;
    }
    if let Some(m) = ct.margin {
        c.positive("contact.margin", m)?;
    }
    if let Some(z) = ct.damping {
        c.non_negative("contact.damping", z)?;
        if z > 1.0 {
            return Err(c.err(
                "contact.damping",
                format!("must be ≤ 1 (fraction of critical damping), got {}", num(z)),
            ));
        }
    }
    for (i, w) in scene.walls.iter().enumerate() {
        validate_wall(&c, scene, i, w)?;
    }
    super::cell::validate_cell(&c, scene)?;
    super::stages::validate_stages(&c, scene)?;

    c.non_negative(
        "parallel.imbalance_threshold",
        scene.parallel.imbalance_threshold,
    )?;
    if scene.parallel.check_interval == 0 {
        return Err(c.err("parallel.check_interval", "must be ≥ 1 step"));
    }
    let o = &scene.output;
    if o.checkpoint_every == Some(0) {
        return Err(c.err("output.checkpoint_every", "must be ≥ 1 step"));
    }
    if let Some(t) = o.checkpoint_interval {
        c.positive("output.checkpoint_interval", t)?;
    }
    if o.checkpoints_kept == 0 {
        return Err(c.err("output.checkpoints_kept", "must be ≥ 1"));
    }
    if let Some(h) = o.history_interval {
        c.positive("output.history_interval", h)?;
    }
    c.positive("output.flush_interval", o.flush_interval)?;
    if let Some(h) = o.frame_interval {
        c.positive("output.frame_interval", h)?;
    }
    physical_bounds(&c, scene)?;
    initial_overlaps(&c, scene)?;
    Ok(())
}

/// Young's modulus bounds (Pa): softer than any solid below; above, 10× diamond
/// (1.2e12 Pa), the stiffest solid known — and stresses and energies E·ε·V stay finite.
pub const YOUNGS_MODULUS_RANGE: (f64, f64) = (1.0, 1e13);
/// Density bounds (kg/m³): the lightest aerogel is 0.16 kg/m³, the densest element
/// (osmium) 22 590 kg/m³.
pub const DENSITY_RANGE: (f64, f64) = (0.1, 1e5);
/// Prescribed motions (boundaries, walls) may be this many times faster than the fastest
/// wave of the scene's materials (see the check for why).
const PRESCRIBED_SPEED_FACTOR: f64 = 1e3;

/// Largest dilatational wave speed (m/s): 5× the fastest sound in any solid (diamond,
/// 18 km/s).
pub const MAX_WAVE_SPEED: f64 = 1e5;
/// Largest length or coordinate (m): μFE scenes are mm to m across; a km keeps volumes,
/// areas and positions finite and their round-off below 1e-12 m.
pub const MAX_LENGTH: f64 = 1e3;
/// `target_dt` may be at most this many times the estimated stable step: the elements'
/// mass would be scaled by up to its square (10⁶) — dynamics no longer meaningful.
pub const MAX_MASS_SCALING_STEP_RATIO: f64 = 1e3;
/// Mass-proportional damping α may remove at most this fraction of the velocity per step
/// (α·Δt); beyond ~2 the explicit update itself is unstable.
pub const MAX_DAMPING_PER_STEP: f64 = 0.5;

/// J2 parameters: σy in (0, E] (a yield strain above 1 is no metal or rock), H in [0, E]
/// (hardening stiffer than the elastic modulus would make the plastic tangent stiffer than
/// the elastic one), and only on top of the Biot law, whose strain measure J2 splits.
fn plastic_parameters(
    c: &Checker,
    f: &dyn Fn(&str) -> String,
    m: &crate::scene::MaterialSpec,
) -> Result<(), InputError> {
    let Some(sy) = m.yield_stress else {
        if m.hardening_modulus.is_some() {
            return Err(c.err(
                f("hardening_modulus"),
                "is given without yield_stress; set yield_stress (Pa) to make the material plastic",
            ));
        }
        return Ok(());
    };
    c.positive(&f("yield_stress"), sy)?;
    if sy > m.youngs_modulus {
        return Err(c.err(
            f("yield_stress"),
            format!(
                "must not exceed youngs_modulus ({:e} Pa): a yield strain above 1, got {sy:e} Pa",
                m.youngs_modulus
            ),
        ));
    }
    if let Some(h) = m.hardening_modulus {
        c.finite(&f("hardening_modulus"), h)?;
        if !(0.0..=m.youngs_modulus).contains(&h) {
            return Err(c.err(
                f("hardening_modulus"),
                format!(
                    "must be in [0, youngs_modulus = {:e}] Pa, got {h:e} Pa",
                    m.youngs_modulus
                ),
            ));
        }
    }
    if m.law != crate::material::ElasticLawKind::Biot {
        return Err(c.err(
            f("law"),
            "plasticity (yield_stress) works in the strain of law = \"biot\" (the default); remove law or set it to \"biot\"",
        ));
    }
    Ok(())
}

/// Magnitudes that are finite but meaningless: they would give infinite or NaN wave
/// speeds, steps, added masses, stresses or energies in the solver.
fn physical_bounds(c: &Checker, scene: &Scene) -> Result<(), InputError> {
    let mut c_max: f64 = 0.0;
    for (name, m) in &scene.materials {
        let f = |x: &str| format!("materials.{}.{x}", echo(name));
        let (lo, hi) = YOUNGS_MODULUS_RANGE;
        if !(lo..=hi).contains(&m.youngs_modulus) {
            return Err(c.err(
                f("youngs_modulus"),
                format!("must be in [{lo:e}, {hi:e}] Pa (1 Pa: softer than any solid; 1e13 Pa: 10× diamond, the stiffest solid), got {:e}", m.youngs_modulus),
            ));
        }
        let (lo, hi) = DENSITY_RANGE;
        if !(lo..=hi).contains(&m.density) {
            return Err(c.err(
                f("density"),
                format!("must be in [{lo:e}, {hi:e}] kg/m³ (lightest aerogel 0.16, osmium 22 590), got {:e}", m.density),
            ));
        }
        let cp = wave_speed(m);
        if cp.is_nan() || cp > MAX_WAVE_SPEED {
            return Err(c.err(
                f("poisson_ratio"),
                format!("with E = {:e} Pa and ρ = {:e} kg/m³ the wave speed √((λ+2G)/ρ) is {cp:.3e} m/s, above {MAX_WAVE_SPEED:e} m/s (5× diamond's): no solid is that stiff", m.youngs_modulus, m.density),
            ));
        }
        c_max = c_max.max(cp);
    }
    let sim = &scene.simulation;
    let speed = |field: String, v: f64, limit: f64, what: &str| {
        if v <= limit {
            Ok(())
        } else {
            Err(c.err(
                field,
                format!("{what} {v:.3e} m/s exceeds the dilatational wave speed {limit:.3e} m/s of the material: no continuum solid moves that fast"),
            ))
        }
    };
    // Prescribed motions are kinematic: driven nodes follow them exactly and no wave has to
    // carry them (a rigid 90° turn in one step is a legitimate objectivity test), so they
    // are held to PRESCRIBED_SPEED_FACTOR × c_p rather than c_p: beyond that a driven node
    // moves by hundreds of element sizes per stable step (Δt ≈ 0.5 h/c_p).
    let prescribed_speed = |field: String, v: f64, what: &str| {
        let limit = PRESCRIBED_SPEED_FACTOR * c_max;
        if v <= limit {
            Ok(())
        } else {
            Err(c.err(
                field,
                format!("{what} {v:.3e} m/s of a prescribed motion exceeds {PRESCRIBED_SPEED_FACTOR:e} × the dilatational wave speed ({limit:.3e} m/s): driven nodes would move by hundreds of elements per step"),
            ))
        }
    };
    let len3 = |v: &[f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    let length = |field: String, v: f64| {
        if v.abs() <= MAX_LENGTH {
            Ok(())
        } else {
            Err(c.err(
                field,
                format!("{v:e} m is beyond {MAX_LENGTH:e} m: far larger than any μFE scene (positions would lose their sub-micrometre resolution)"),
            ))
        }
    };
    let point = |field: &str, p: &[f64; 3]| -> Result<(), InputError> {
        for (k, x) in p.iter().enumerate() {
            length(format!("{field}[{k}]"), *x)?;
        }
        Ok(())
    };
    speed(
        "simulation.gravity".into(),
        len3(&sim.gravity) * sim.duration,
        c_max,
        "the speed gained under gravity over the duration,",
    )?;
    let mut r_min = f64::INFINITY;
    for (i, g) in scene.grains.iter().enumerate() {
        let f = |x: &str| format!("grains[{i}].{x}");
        point(&f("centre"), &g.centre)?;
        let radius = match &g.shape {
            ShapeSpec::Sphere(s) => {
                length(f("shape.sphere.radius"), s.radius)?;
                s.radius
            }
            ShapeSpec::Block(b) => {
                point(&f("shape.block.size"), &b.size)?;
                0.5 * len3(&b.size)
            }
            ShapeSpec::Surface(s) => {
                let r = s.geometry.as_ref().map_or(0.0, |x| x.bounding_radius);
                length(f("shape.surface.scale"), r)?;
                r
            }
        };
        r_min = r_min.min(radius);
        let cp = scene.materials.get(&g.material).map_or(0.0, wave_speed);
        speed(f("velocity"), len3(&g.velocity), cp, "the speed")?;
        speed(
            f("angular_velocity"),
            len3(&g.angular_velocity) * radius,
            cp,
            "the rim speed |ω|·R",
        )?;
    }
    let history_speed = |field: String, h: &History3, displacement: bool| {
        for (k, v) in h.values.iter().enumerate() {
            if displacement {
                point(&format!("{field}.values[{k}]"), v)?;
                if k > 0 {
                    let d = [
                        v[0] - h.values[k - 1][0],
                        v[1] - h.values[k - 1][1],
                        v[2] - h.values[k - 1][2],
                    ];
                    prescribed_speed(
                        format!("{field}.values[{k}]"),
                        len3(&d) / (h.times[k] - h.times[k - 1]),
                        "the implied speed",
                    )?;
                }
            } else {
                prescribed_speed(format!("{field}.values[{k}]"), len3(v), "the speed")?;
            }
        }
        Ok::<(), InputError>(())
    };
    for (i, b) in scene.boundaries.iter().enumerate() {
        let f = |x: &str| format!("boundaries[{i}].{x}");
        if let Some(h) = &b.velocity {
            history_speed(f("velocity"), h, false)?;
        }
        if let Some(h) = &b.displacement {
            history_speed(f("displacement"), h, true)?;
        }
        if let Some(h) = &b.angular_velocity {
            for (k, v) in h.values.iter().enumerate() {
                prescribed_speed(
                    format!("{}.values[{k}]", f("angular_velocity")),
                    len3(v) * r_min,
                    "the rim speed |ω|·R",
                )?;
            }
        }
        if let Some(p) = &b.centre {
            point(&f("centre"), p)?;
        }
        match &b.select {
            NodeSelector::All => {}
            NodeSelector::BeyondPlane { point: p, .. } => {
                point(&f("select.beyond_plane.point"), p)?
            }
            NodeSelector::FartherThan { point: p, distance } => {
                point(&f("select.farther_than.point"), p)?;
                length(f("select.farther_than.distance"), *distance)?;
            }
            NodeSelector::Within { point: p, distance } => {
                point(&f("select.within.point"), p)?;
                length(f("select.within.distance"), *distance)?;
            }
        }
    }
    for (i, w) in scene.walls.iter().enumerate() {
        let f = |x: &str| format!("walls[{i}].{x}");
        point(&f("point"), &w.point)?;
        if let Some(h) = &w.velocity {
            history_speed(f("velocity"), h, false)?;
        }
        if let Some(h) = &w.displacement {
            history_speed(f("displacement"), h, true)?;
        }
        if w.friction > MAX_FRICTION {
            return Err(c.err(f("friction"), format!("must be ≤ {MAX_FRICTION} (no real pair of surfaces has a Coulomb coefficient above a few), got {}", num(w.friction))));
        }
    }
    if scene.contact.friction > MAX_FRICTION {
        return Err(c.err("contact.friction", format!("must be ≤ {MAX_FRICTION} (no real pair of surfaces has a Coulomb coefficient above a few), got {}", num(scene.contact.friction))));
    }
    if let Some(p) = scene.contact.penalty_factor {
        if p > MAX_PENALTY_FACTOR {
            return Err(c.err("contact.penalty_factor", format!("must be ≤ {MAX_PENALTY_FACTOR:e} (the contact springs would set a stable step ~{:.0}× below the elements'), got {p:e}", (p / 20.0).sqrt())));
        }
    }
    if let Some(m) = scene.contact.margin {
        length("contact.margin".into(), m)?;
    }

    // Time: the estimated step count must be countable exactly, mass scaling bounded,
    // damping stable.
    let file = c.file;
    let est = estimate_scene(file, scene)?;
    if est.steps.is_nan() || est.steps > MAX_EXACT_STEPS {
        // Blame the step when it is below a femtosecond (shorter than any elastic wave
        // crossing of a mesh element), else the duration.
        let field = if est.dt < 1e-15 || est.dt_field == "simulation.duration" {
            est.dt_field
        } else {
            "simulation.duration"
        };
        return Err(c.err(
            field,
            format!(
                "duration {:e} s / Δt {:e} s = {:.3e} steps: more than 2^53, where step counts and times are no longer exact (the run could never finish)",
                sim.duration, est.dt, est.steps
            ),
        ));
    }
    if let Some(t) = sim.target_dt {
        if t > sim.duration {
            return Err(c.err(
                "simulation.target_dt",
                format!(
                    "{t:e} s is longer than the whole duration {:e} s",
                    sim.duration
                ),
            ));
        }
        let ratio = t / est.dt_stable;
        if ratio.is_nan() || ratio > MAX_MASS_SCALING_STEP_RATIO {
            return Err(c.err(
                "simulation.target_dt",
                format!(
                    "{t:e} s is {ratio:.3e}× the estimated stable step {:.3e} s (grains[{}]): mass scaling would multiply element masses by up to {:.1e}; at most {MAX_MASS_SCALING_STEP_RATIO:e}× is meaningful",
                    est.dt_stable, est.critical_grain, ratio * ratio
                ),
            ));
        }
    }
    for (field, alpha) in [
        ("simulation.damping", sim.damping),
        ("simulation.deformation_damping", sim.deformation_damping),
    ] {
        if (alpha * est.dt).is_nan() || alpha * est.dt > MAX_DAMPING_PER_STEP {
            return Err(c.err(
                field,
                format!(
                    "{alpha:e} 1/s × Δt {:.3e} s = {:.3e}: the damping would remove more than {MAX_DAMPING_PER_STEP} of the velocity per step (at most {:.3e} 1/s)",
                    est.dt,
                    alpha * est.dt,
                    MAX_DAMPING_PER_STEP / est.dt
                ),
            ));
        }
    }
    Ok(())
}

/// Coulomb friction coefficients above this are refused (rubber on rough rock ~1–2).
pub const MAX_FRICTION: f64 = 10.0;
/// Penalty factors above this are refused (default 20).
pub const MAX_PENALTY_FACTOR: f64 = 1e6;

/// A grain's shape in the world frame for the overlap check.
enum Body {
    Ball {
        centre: [f64; 3],
        radius: f64,
        sag: f64,
    },
    Box {
        lo: [f64; 3],
        hi: [f64; 3],
    },
}

impl Body {
    fn bounds(&self) -> ([f64; 3], [f64; 3]) {
        match self {
            Body::Ball { centre, radius, .. } => {
                (centre.map(|x| x - radius), centre.map(|x| x + radius))
            }
            Body::Box { lo, hi } => (*lo, *hi),
        }
    }
}

/// Grains that start inside each other (identical or near-identical positions): refused
/// when they overlap by more than the solver's tolerance (1e-3 × the smallest surface
/// edge) plus the faceting of the sphere meshes (a sphere mesh lies inside its sphere by
/// up to the sagitta (1.42 s)²/8R). Exact for spheres (distance of centres) and blocks
/// (box intersection); no division, so coincident centres give a finite overlap.
fn initial_overlaps(c: &Checker, scene: &Scene) -> Result<(), InputError> {
    let mut bodies = Vec::with_capacity(scene.grains.len());
    let mut min_edge = f64::INFINITY;
    for g in &scene.grains {
        match &g.shape {
            ShapeSpec::Sphere(s) => {
                let h = s.refine.iter().map(|r| r.seeding).fold(s.seeding, f64::min);
                min_edge = min_edge.min(h);
                let top = 1.42 * s.seeding;
                bodies.push(Body::Ball {
                    centre: g.centre,
                    radius: s.radius,
                    sag: top * top / (8.0 * s.radius),
                });
            }
            // Only the mesh-level check of `mufe run` sees an irregular shape; here it is a
            // point at its centre (which catches nothing but keeps the indices aligned).
            ShapeSpec::Surface(s) => {
                min_edge = min_edge.min(s.seeding);
                bodies.push(Body::Ball {
                    centre: g.centre,
                    radius: 0.0,
                    sag: 0.0,
                });
            }
            ShapeSpec::Block(b) => {
                for k in 0..3 {
                    min_edge = min_edge.min(b.size[k] / b.divisions[k].max(1) as f64);
                }
                bodies.push(Body::Box {
                    lo: g.centre,
                    hi: [
                        g.centre[0] + b.size[0],
                        g.centre[1] + b.size[1],
                        g.centre[2] + b.size[2],
                    ],
                });
            }
        }
    }
    let tol = 1e-3 * min_edge;
    // Sweep along x over boxes sorted by their lower x.
    let bounds: Vec<([f64; 3], [f64; 3])> = bodies.iter().map(Body::bounds).collect();
    let mut order: Vec<usize> = (0..bodies.len()).collect();
    order.sort_by(|&a, &b| bounds[a].0[0].total_cmp(&bounds[b].0[0]).then(a.cmp(&b)));
    for (k, &a) in order.iter().enumerate() {
        for &b in &order[k + 1..] {
            if bounds[b].0[0] > bounds[a].1[0] - tol {
                break;
            }
            let depth = overlap_depth(&bodies[a], &bodies[b]);
            if depth > tol {
                let (i, j) = (a.min(b), a.max(b));
                return Err(c.err(
                    format!("grains[{i}] and grains[{j}]"),
                    format!(
                        "'{}' and '{}' overlap by {depth:.3e} m at t = 0 (centres {:?} and {:?}; tolerance {tol:.3e} m); move them apart",
                        echo(&scene.grains[i].display_name(i)),
                        echo(&scene.grains[j].display_name(j)),
                        scene.grains[i].centre,
                        scene.grains[j].centre
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// How deep two bodies interpenetrate (m), beyond the faceting of sphere meshes; ≤ 0 if
/// they do not.
fn overlap_depth(a: &Body, b: &Body) -> f64 {
    let dist = |p: [f64; 3], q: [f64; 3]| {
        ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
    };
    match (a, b) {
        (
            Body::Ball {
                centre: p,
                radius: ra,
                sag: sa,
            },
            Body::Ball {
                centre: q,
                radius: rb,
                sag: sb,
            },
        ) => ra + rb - dist(*p, *q) - sa - sb,
        (
            Body::Ball {
                centre,
                radius,
                sag,
            },
            Body::Box { lo, hi },
        )
        | (
            Body::Box { lo, hi },
            Body::Ball {
                centre,
                radius,
                sag,
            },
        ) => {
            let nearest = [0, 1, 2].map(|k| centre[k].clamp(lo[k], hi[k]));
            let inside = (0..3).all(|k| centre[k] > lo[k] && centre[k] < hi[k]);
            if inside {
                // centre inside the box: at least the radius plus the depth of the centre
                let d = (0..3)
                    .map(|k| (centre[k] - lo[k]).min(hi[k] - centre[k]))
                    .fold(f64::INFINITY, f64::min);
                radius + d - sag
            } else {
                radius - dist(*centre, nearest) - sag
            }
        }
        (Body::Box { lo: la, hi: ha }, Body::Box { lo: lb, hi: hb }) => (0..3)
            .map(|k| ha[k].min(hb[k]) - la[k].max(lb[k]))
            .fold(f64::INFINITY, f64::min),
    }
}

fn validate_boundary(
    c: &Checker,
    scene: &Scene,
    i: usize,
    b: &BoundarySpec,
) -> Result<(), InputError> {
    let f = |x: &str| format!("boundaries[{i}].{x}");
    c.identifier(&f("name"), &b.name)?;
    if scene.boundaries[..i].iter().any(|o| o.name == b.name) {
        return Err(c.err(
            f("name"),
            format!(
                "duplicate boundary name '{}' (names label the /history columns)",
                echo(&b.name)
            ),
        ));
    }
    if !scene
        .grains
        .iter()
        .enumerate()
        .any(|(k, g)| g.display_name(k) == b.grain)
    {
        return Err(c.err(f("grain"), format!("no grain named '{}'", echo(&b.grain))));
    }
    match &b.select {
        NodeSelector::All => {}
        NodeSelector::BeyondPlane { point, normal } => {
            c.vec3(&f("select.beyond_plane.point"), point)?;
            c.nonzero_vec3(&f("select.beyond_plane.normal"), normal)?;
        }
        NodeSelector::FartherThan { point, distance } => {
            c.vec3(&f("select.farther_than.point"), point)?;
            c.non_negative(&f("select.farther_than.distance"), *distance)?;
        }
        NodeSelector::Within { point, distance } => {
            c.vec3(&f("select.within.point"), point)?;
            c.positive(&f("select.within.distance"), *distance)?;
        }
    }
    c.translation(&f(""), &b.velocity, &b.displacement)?;
    if let Some(h) = &b.angular_velocity {
        c.history(&f("angular_velocity"), h)?;
        if b.components.is_some() {
            return Err(c.err(f("components"), "a partial (components) constraint cannot rotate; drop angular_velocity or components"));
        }
    }
    if let Some(cen) = &b.centre {
        c.vec3(&f("centre"), cen)?;
    }
    if let Some(m) = b.components {
        if !m.iter().any(|x| *x) {
            return Err(c.err(f("components"), "constrains no component"));
        }
    }
    Ok(())
}

fn validate_wall(c: &Checker, scene: &Scene, i: usize, w: &WallSpec) -> Result<(), InputError> {
    let f = |x: &str| format!("walls[{i}].{x}");
    c.identifier(&f("name"), &w.name)?;
    if scene.walls[..i].iter().any(|o| o.name == w.name) {
        return Err(c.err(
            f("name"),
            format!("duplicate wall name '{}'", echo(&w.name)),
        ));
    }
    if scene.boundaries.iter().any(|b| b.name == w.name) {
        return Err(c.err(
            f("name"),
            format!("'{}' is already the name of a boundary", echo(&w.name)),
        ));
    }
    c.vec3(&f("point"), &w.point)?;
    c.nonzero_vec3(&f("normal"), &w.normal)?;
    c.non_negative(&f("friction"), w.friction)?;
    c.translation(&f(""), &w.velocity, &w.displacement)?;
    if let Some(servo) = &w.servo {
        if w.velocity.is_some() || w.displacement.is_some() {
            return Err(c.err(
                f("servo"),
                "give at most one of velocity, displacement and servo",
            ));
        }
        validate_servo(c, scene, &f("servo"), w, servo)?;
    }
    if !scene.stages.is_empty()
        && (w.servo.is_some() || w.velocity.is_some() || w.displacement.is_some())
    {
        return Err(c.err(
            f("servo"),
            "a scene with [[stages]] sets every wall's motion in its stages; drop the wall's own velocity/displacement/servo",
        ));
    }
    Ok(())
}
