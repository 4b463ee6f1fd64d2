//! Semantic checks of a typed scene. Each failure names the file and the dotted field.

use super::{BoundarySpec, History3, NodeSelector, Scene, ShapeSpec, WallSpec};
use crate::error::InputError;

struct Checker<'a> {
    file: &'a str,
}

impl Checker<'_> {
    fn err(&self, field: impl Into<String>, msg: impl Into<String>) -> InputError {
        InputError::new(self.file, field, msg)
    }

    fn finite(&self, field: &str, v: f64) -> Result<(), InputError> {
        if v.is_finite() {
            Ok(())
        } else {
            Err(self.err(field, format!("must be a finite number, got {v}")))
        }
    }

    fn positive(&self, field: &str, v: f64) -> Result<(), InputError> {
        self.finite(field, v)?;
        if v > 0.0 {
            Ok(())
        } else {
            Err(self.err(field, format!("must be > 0, got {v}")))
        }
    }

    fn non_negative(&self, field: &str, v: f64) -> Result<(), InputError> {
        self.finite(field, v)?;
        if v >= 0.0 {
            Ok(())
        } else {
            Err(self.err(field, format!("must be ≥ 0, got {v}")))
        }
    }

    fn vec3(&self, field: &str, v: &[f64; 3]) -> Result<(), InputError> {
        for (i, c) in v.iter().enumerate() {
            self.finite(&format!("{field}[{i}]"), *c)?;
        }
        Ok(())
    }

    fn nonzero_vec3(&self, field: &str, v: &[f64; 3]) -> Result<(), InputError> {
        self.vec3(field, v)?;
        if v.iter().map(|c| c * c).sum::<f64>() == 0.0 {
            return Err(self.err(field, "must not be the zero vector"));
        }
        Ok(())
    }

    /// Names used in history column names: letters, digits and `_` only.
    fn identifier(&self, field: &str, name: &str) -> Result<(), InputError> {
        if name.is_empty()
            || !name
                .chars()
                .all(|ch| ch.is_ascii_alphanumeric() || ch == '_')
        {
            return Err(self.err(field, "must be a non-empty identifier (letters, digits, _)"));
        }
        Ok(())
    }

    /// A translation given by at most one of a velocity and a displacement history.
    /// `prefix` ends with '.' (e.g. `walls[0].`).
    fn translation(
        &self,
        prefix: &str,
        velocity: &Option<History3>,
        displacement: &Option<History3>,
    ) -> Result<(), InputError> {
        if velocity.is_some() && displacement.is_some() {
            return Err(self.err(
                format!("{prefix}velocity"),
                "give either velocity or displacement, not both",
            ));
        }
        if let Some(h) = velocity {
            self.history(&format!("{prefix}velocity"), h)?;
        }
        if let Some(h) = displacement {
            self.history(&format!("{prefix}displacement"), h)?;
        }
        Ok(())
    }

    fn history(&self, field: &str, h: &History3) -> Result<(), InputError> {
        if h.times.is_empty() {
            return Err(self.err(format!("{field}.times"), "needs at least one time"));
        }
        if h.times.len() != h.values.len() {
            return Err(self.err(
                field,
                format!("{} times but {} values", h.times.len(), h.values.len()),
            ));
        }
        for (i, t) in h.times.iter().enumerate() {
            self.non_negative(&format!("{field}.times[{i}]"), *t)?;
            if i > 0 && *t <= h.times[i - 1] {
                return Err(self.err(
                    format!("{field}.times[{i}]"),
                    format!(
                        "times must increase strictly, got {t} after {}",
                        h.times[i - 1]
                    ),
                ));
            }
        }
        for (i, v) in h.values.iter().enumerate() {
            self.vec3(&format!("{field}.values[{i}]"), v)?;
        }
        Ok(())
    }
}

pub(super) fn validate_scene(file: &str, scene: &Scene) -> Result<(), InputError> {
    let c = Checker { file };
    let s = &scene.simulation;
    c.positive("simulation.duration", s.duration)?;
    c.positive("simulation.dt_safety", s.dt_safety)?;
    if s.dt_safety > 1.0 {
        return Err(c.err(
            "simulation.dt_safety",
            format!("must be ≤ 1, got {}", s.dt_safety),
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
                format!("must be in (−1, 0.5), got {}", m.poisson_ratio),
            ));
        }
    }

    if scene.grains.is_empty() {
        return Err(c.err("grains", "the scene has no grains"));
    }
    let mut names = std::collections::BTreeSet::new();
    for (i, g) in scene.grains.iter().enumerate() {
        let f = |x: &str| format!("grains[{i}].{x}");
        if !scene.materials.contains_key(&g.material) {
            return Err(c.err(f("material"), format!("unknown material '{}'", g.material)));
        }
        if !names.insert(g.display_name(i)) {
            return Err(c.err(
                f("name"),
                format!("duplicate grain name '{}'", g.display_name(i)),
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
                format!("must be ≤ 1 (fraction of critical damping), got {z}"),
            ));
        }
    }
    for (i, w) in scene.walls.iter().enumerate() {
        validate_wall(&c, scene, i, w)?;
    }

    c.non_negative(
        "parallel.imbalance_threshold",
        scene.parallel.imbalance_threshold,
    )?;
    if scene.parallel.check_interval == 0 {
        return Err(c.err("parallel.check_interval", "must be ≥ 1 step"));
    }
    let o = &scene.output;
    if let Some(h) = o.history_interval {
        c.positive("output.history_interval", h)?;
    }
    if let Some(h) = o.frame_interval {
        c.positive("output.frame_interval", h)?;
    }
    Ok(())
}

fn validate_boundary(
    c: &Checker,
    scene: &Scene,
    i: usize,
    b: &BoundarySpec,
) -> Result<(), InputError> {
    let f = |x: &str| format!("boundaries[{i}].{x}");
    c.identifier(&f("name"), &b.name)?;
    if !scene
        .grains
        .iter()
        .enumerate()
        .any(|(k, g)| g.display_name(k) == b.grain)
    {
        return Err(c.err(f("grain"), format!("no grain named '{}'", b.grain)));
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
        return Err(c.err(f("name"), format!("duplicate wall name '{}'", w.name)));
    }
    if scene.boundaries.iter().any(|b| b.name == w.name) {
        return Err(c.err(
            f("name"),
            format!("'{}' is already the name of a boundary", w.name),
        ));
    }
    c.vec3(&f("point"), &w.point)?;
    c.nonzero_vec3(&f("normal"), &w.normal)?;
    c.non_negative(&f("friction"), w.friction)?;
    c.translation(&f(""), &w.velocity, &w.displacement)?;
    Ok(())
}
