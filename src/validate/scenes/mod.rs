//! The validation scenes, generated from the material, radius and friction of the scene as
//! run. `jobs/validation/{hertz,mindlin,torsion,rolling}.toml` are this generator's output
//! for the paper's glass (`mufe validate --write-scenes jobs/validation`, checked by a
//! test); `mufe validate` reads the material, radius and friction from the case scene (the
//! shipped one after `--set`, or `MUFE_VALIDATION_SCENES/<case>.toml`) and regenerates the
//! whole scene from them, so drives, durations, meshes and loads follow the material.
//!
//! Every parameter is dimensionless: lengths in units of the sphere radius R, times in
//! R/c_p (c_p = dilatational wave speed), speeds in c_p, deformation damping in c_p/R, loads
//! by the contact radius a/R they give (Hertz: F = 4E*a³/(3R), E* = E/(1−ν²), for a sphere
//! on a flat and for two identical spheres alike), tangential amplitudes in δt,max (Mindlin's
//! slip displacement at that load). With these a run takes the same number of steps for any
//! material, and every quasi-static ratio (drive speed / c_p, load time / wave transit) is
//! the same. The defaults are the values of the original study on the paper's glass
//! ([`paper`]), each written as its SI value divided by the paper's unit, so the shipped
//! scenes are those of that study.
//!
//! Velocity profiles are trapezoids with raised-cosine ramps (sampled piecewise linearly)
//! so the loading is smooth.

use crate::error::{num, InputError};
use crate::material::ElasticParameters;
use crate::scene::{LoadedScene, ShapeSpec};

mod params;
mod profiles;

pub use params::{HertzEllipsoidParams, HertzParams, Params, TwoSphereParams};
use profiles::{fmt_hist, merge, plate_exponential, plate_ramp, sci, trapezoid, Points};

/// The paper's material and geometry (docs/THEORY.md, Conventions), the origin of the default
/// dimensionless parameters: the shipped scenes are generated for them.
pub mod paper {
    pub const YOUNGS_MODULUS: f64 = 63e9;
    pub const POISSON_RATIO: f64 = 0.22;
    pub const DENSITY: f64 = 2500.0;
    pub const RADIUS: f64 = 1.1e-3;
    pub const FRICTION: f64 = 0.22;
}

/// The scene quantities a case is generated from, as read from the case scene.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneInputs {
    /// File they were read from (for error messages).
    pub file: String,
    /// Name of the grains' material (`glass` in the shipped scenes).
    pub material_name: String,
    pub material: ElasticParameters,
    /// Other fields of the material table (`law = "corotational"`, ...), copied as given.
    pub material_extra: Vec<(String, toml::Value)>,
    /// Sphere radius R (m).
    pub radius: f64,
    /// Coulomb friction coefficient of the contact.
    pub friction: f64,
}

/// Units of the dimensionless parameters for one material and radius.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Units {
    /// R (m).
    pub length: f64,
    /// R/c_p (s).
    pub time: f64,
    /// c_p (m/s).
    pub speed: f64,
    /// E* = E/(1−ν²) (Pa).
    pub e_star: f64,
    /// Shear modulus G (Pa).
    pub shear: f64,
    pub poisson_ratio: f64,
}

impl Units {
    pub fn of(material: &ElasticParameters, radius: f64) -> Self {
        let speed = material.dilatational_wave_speed();
        Self {
            length: radius,
            time: radius / speed,
            speed,
            e_star: material.plane_strain_modulus(),
            shear: material.shear_modulus(),
            poisson_ratio: material.poisson_ratio,
        }
    }

    fn paper() -> Self {
        Self::of(&paper_material(), paper::RADIUS)
    }

    /// Hertz force giving contact radius a = a_over_r·R, sphere on a flat or two identical
    /// spheres: F = 4E*a³/(3R) (N).
    pub fn force_at(&self, a_over_r: f64) -> f64 {
        4.0 / 3.0 * self.e_star * self.length * self.length * a_over_r.powi(3)
    }

    /// Contact radius over R at force F (inverse of [`Units::force_at`]).
    pub fn a_over_r(&self, force: f64) -> f64 {
        (3.0 * force / (4.0 * self.e_star * self.length * self.length)).cbrt()
    }

    /// Mindlin's slip displacement δt,max = 3μN(2−ν)/(8Ga) of two identical spheres at the
    /// load of contact radius a_over_r·R (m).
    pub fn slip_displacement(&self, mu: f64, a_over_r: f64) -> f64 {
        let a = a_over_r * self.length;
        3.0 * mu * self.force_at(a_over_r) * (2.0 - self.poisson_ratio) / (8.0 * self.shear * a)
    }
}

fn paper_material() -> ElasticParameters {
    ElasticParameters {
        youngs_modulus: paper::YOUNGS_MODULUS,
        poisson_ratio: paper::POISSON_RATIO,
        density: paper::DENSITY,
    }
}

impl SceneInputs {
    /// The paper's glass sphere (the shipped scenes).
    pub fn paper() -> Self {
        Self {
            file: "jobs/validation".into(),
            material_name: "glass".into(),
            material: paper_material(),
            material_extra: Vec::new(),
            radius: paper::RADIUS,
            friction: paper::FRICTION,
        }
    }

    pub fn units(&self) -> Units {
        Units::of(&self.material, self.radius)
    }

    /// Reads material, radius and friction from a loaded case scene (after overrides).
    /// Every grain must be a sphere of the same radius and material (`grains` = 1 for
    /// Hertz, 2 for the two-sphere cases); the tangential cases need friction > 0.
    pub fn from_scene(
        case: &str,
        loaded: &LoadedScene,
        overrides: &[String],
    ) -> Result<Self, InputError> {
        let file = loaded.path.clone();
        let scene = &loaded.scene;
        let grains = if case == "hertz" { 1 } else { 2 };
        if scene.grains.len() != grains {
            return Err(InputError::new(
                &file,
                "grains",
                format!(
                    "the {case} case needs {grains} sphere(s), the scene has {} grains",
                    scene.grains.len()
                ),
            ));
        }
        let g0 = &scene.grains[0];
        let sphere_radius = |i: usize| -> Result<f64, InputError> {
            match &scene.grains[i].shape {
                ShapeSpec::Sphere(s) => Ok(s.radius),
                _ => Err(InputError::new(
                    &file,
                    format!("grains[{i}].shape"),
                    format!("the {case} case needs sphere grains"),
                )),
            }
        };
        let radius = sphere_radius(0)?;
        for i in 1..grains {
            let r = sphere_radius(i)?;
            if r != radius {
                return Err(with_override_note(
                    InputError::new(
                        &file,
                        format!("grains[{i}].shape.sphere.radius"),
                        format!(
                            "the {case} case needs identical spheres: radius {} ≠ grains[0]'s {}",
                            num(r),
                            num(radius)
                        ),
                    ),
                    overrides,
                ));
            }
            if scene.grains[i].material != g0.material {
                return Err(InputError::new(
                    &file,
                    format!("grains[{i}].material"),
                    format!(
                        "the {case} case needs one material for both spheres ('{}' ≠ '{}')",
                        scene.grains[i].material, g0.material
                    ),
                ));
            }
        }
        let m = &scene.materials[&g0.material];
        let friction = scene.contact.friction;
        if case != "hertz" && friction <= 0.0 {
            return Err(with_override_note(
                InputError::new(
                    &file,
                    "contact.friction",
                    format!(
                        "the {case} case needs friction > 0 (its drive and reference scale \
                         with μ), got {}",
                        num(friction)
                    ),
                ),
                overrides,
            ));
        }
        let material_extra = loaded.material_extra_fields(&g0.material);
        Ok(Self {
            file,
            material_name: g0.material.clone(),
            material: ElasticParameters {
                youngs_modulus: m.youngs_modulus,
                poisson_ratio: m.poisson_ratio,
                density: m.density,
            },
            material_extra,
            radius,
            friction,
        })
    }

    /// Dotted path of a field of the grains' material (`materials.glass.poisson_ratio`).
    pub fn material_field(&self, field: &str) -> String {
        format!("materials.{}.{field}", self.material_name)
    }

    pub(crate) fn material_block(&self) -> String {
        let m = &self.material;
        let mut s = format!(
            "[materials.{}]\nyoungs_modulus = {}\npoisson_ratio = {:?}\ndensity = {:?}\n",
            self.material_name,
            sci(m.youngs_modulus, 6),
            m.poisson_ratio,
            m.density
        );
        for (k, v) in &self.material_extra {
            s.push_str(&format!("{k} = {v}\n"));
        }
        s
    }
}

/// Appends "(value from --set …)" when an override set the field (or a parent of it).
pub fn with_override_note(mut e: InputError, overrides: &[String]) -> InputError {
    let culprit = overrides.iter().rev().find(|o| {
        let path = o.split_once('=').map_or(o.as_str(), |(p, _)| p).trim();
        let path = path.replace(['"', '\''], "");
        e.item == path || e.item.starts_with(&format!("{path}."))
    });
    if let Some(o) = culprit {
        e.message = format!("{} (value from --set {})", e.message, crate::error::echo(o));
    }
    e
}

pub(super) fn invalid(inputs: &SceneInputs, case: &str, message: String) -> InputError {
    InputError::new(
        &inputs.file,
        format!("validation case {case}"),
        format!(
            "{message}: the generated scene is invalid for E = {} Pa, ν = {}, ρ = {} kg/m³, \
             R = {} m, μ = {}",
            num(inputs.material.youngs_modulus),
            num(inputs.material.poisson_ratio),
            num(inputs.material.density),
            num(inputs.radius),
            num(inputs.friction)
        ),
    )
}

/// Plate speed: raised-cosine ramp to `v_plate`, then constant; the plates start `gap`
/// The Hertz scene for the given material and radius.
pub fn hertz(inputs: &SceneInputs, p: &HertzParams) -> Result<String, InputError> {
    let u = inputs.units();
    let r = inputs.radius;
    let v_plate = p.v_plate * u.speed;
    let ramp = p.ramp * u.time;
    let gap = p.gap.max(0.0) * r;
    let delta_end = p.a_end * p.a_end * r;
    if !(v_plate > 0.0 && ramp >= 0.0 && delta_end > 0.0) {
        return Err(invalid(
            inputs,
            "hertz",
            "v_plate and a_end must be > 0 and ramp ≥ 0".into(),
        ));
    }
    let (up, duration, motion) = if p.tau > 0.0 {
        plate_exponential(inputs, p, delta_end)?
    } else {
        plate_ramp(inputs, p, v_plate, ramp, gap, delta_end)?
    };
    let damping = if p.damping > 0.0 {
        format!(
            "\n# damps vibration relative to the sphere's rigid motion\ndeformation_damping = {}",
            sci(p.damping / u.time, 3)
        )
    } else {
        String::new()
    };
    let refine: Vec<String> = ["1.0", "-1.0"]
        .iter()
        .map(|d| {
            format!(
                "    {{ direction = [0.0, 0.0, {d}], seeding = {}, radius = {}, growth = {:?} }},",
                sci(p.refine_seeding * r, 4),
                sci(p.refine_radius * r, 4),
                p.growth
            )
        })
        .collect();
    let down: Points = up.iter().map(|&(t, v)| (t, -v)).collect();
    let u_force = |a: f64| u.force_at(a);
    Ok(format!(
        r#"# Hertz normal contact: a sphere squeezed between two rigid frictionless plates
# (docs/THEORY.md §1, finite-sphere reference). Both plates approach the centre plane at the
# same speed, starting {gap_um:.2} µm from the poles, so δ = approach of each plate from
# first touch and F = plate force. The travel reaches the Hertz contact radius
# a/R = {a_end:.4} (F ≈ {f_end:.4} N). Plate speed:
# {motion}.
#
# How to run:  mufe validate hertz            (sweep of meshing ratios, plots, JSON)
#              mufe run jobs/validation/hertz.toml --out out/hertz   (one run)
# Generated by `mufe validate --write-scenes DIR` (src/validate/scenes/, edit there) for
# the material and radius below; `mufe validate` regenerates the scene from the material,
# radius and friction of this file (after --set), with drives, times and meshes scaled by
# R and R/c_p. Meshing: fine seeding only around the two poles (refine[0], refine[1]);
# `mufe validate` sets their seeding from the meshing ratio at the contact, MR = s/(2R).

[simulation]
duration = {duration}
# mass scaling of the fine contact elements only; quasi-static (KE/IE is reported)
target_dt = {target_dt}{damping}

{material}
[[grains]]
name = "sphere"
material = "{mat}"
centre = [0.0, 0.0, 0.0]
shape = {{ sphere = {{ radius = {radius}, seeding = {seeding}, refine = [
{refine}
] }} }}

[contact]
friction = 0.0

[[walls]]
name = "top"
point = [0.0, 0.0, {top}]
normal = [0.0, 0.0, -1.0]
velocity = {v_top}

[[walls]]
name = "bottom"
point = [0.0, 0.0, {bottom}]
normal = [0.0, 0.0, 1.0]
velocity = {v_bottom}

[output]
history_interval = {history}
frames = false
"#,
        gap_um = gap * 1e6,
        a_end = p.a_end,
        f_end = u_force(p.a_end),
        duration = sci(duration, 6),
        target_dt = sci(p.target_dt * u.time, 3),
        material = inputs.material_block(),
        mat = inputs.material_name,
        radius = sci(r, 6),
        seeding = sci(p.seeding * r, 4),
        refine = refine.join("\n"),
        top = sci(r + gap, 9),
        bottom = sci(-r - gap, 9),
        v_top = fmt_hist(&down, 2),
        v_bottom = fmt_hist(&up, 2),
        history = sci(p.history_interval * u.time, 3),
    ))
}

/// Which two-sphere case a scene is for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TwoSphereKind {
    Mindlin,
    MindlinCyclic,
    Torsion,
    Rolling,
}

/// The scene of a two-sphere case for the given material, radius and friction.
pub fn two_sphere(
    kind: TwoSphereKind,
    inputs: &SceneInputs,
    p: &TwoSphereParams,
) -> Result<String, InputError> {
    let name = match kind {
        TwoSphereKind::Mindlin => "mindlin",
        TwoSphereKind::MindlinCyclic => "mindlin_cyclic",
        TwoSphereKind::Torsion => "torsion",
        TwoSphereKind::Rolling => "rolling",
    };
    let fail = |m: String| invalid(inputs, name, m);
    let u = inputs.units();
    let r = inputs.radius;
    let mu = inputs.friction;
    let force = u.force_at(p.a_over_r);
    let a = p.a_over_r * r;
    let dtmax = u.slip_displacement(mu, p.a_over_r);
    // normal approach: two identical spheres, δ = 2a²/R at the nominal load, then rest
    let approach = 2.0 * a * a / r;
    let (normal, t) = trapezoid(
        0.0,
        -p.approach_scale * approach,
        p.vn * u.speed,
        p.n_ramp * u.time,
        "normal approach",
    )
    .map_err(fail)?;
    let t = t + p.settle * u.time;
    let (header, motion, end) = match kind {
        TwoSphereKind::Mindlin | TwoSphereKind::MindlinCyclic => {
            let amp = p.amplitude * dtmax;
            let vt = p.vt * dtmax / u.time;
            let t_ramp = p.t_ramp * u.time;
            let (seg, mut t) = trapezoid(t, amp, vt, t_ramp, "tangential loading").map_err(fail)?;
            let mut tangential: Points = vec![(0.0, 0.0)];
            tangential.extend(seg);
            let reversals = p.reversals.round().max(0.0) as usize;
            for k in 0..reversals {
                let d = if k % 2 == 0 { -2.0 } else { 2.0 } * amp;
                let (seg, t_next) =
                    trapezoid(t, d, vt, t_ramp, "tangential reversal").map_err(fail)?;
                tangential.extend_from_slice(&seg[1..]);
                t = t_next;
            }
            let what = ["", ", unloading", ", unloading, reloading"][reversals.min(2)];
            (
                format!(
                    "Mindlin–Deresiewicz: two spheres, tangential loading at constant N{what} (docs/THEORY.md §2)"
                ),
                drive_block(p, r, &merge(&normal, &tangential), None),
                t,
            )
        }
        TwoSphereKind::Torsion => {
            // relative twist 2β at G a² β/(μN) = twist_param
            let twist = 2.0 * p.twist_param * mu * force / (u.shear * a * a);
            let w_max = twist / ((p.cruise + p.t_ramp) * u.time);
            let (seg, t_end) =
                trapezoid(t, twist, w_max, p.t_ramp * u.time, "twist").map_err(fail)?;
            let mut angular: Points = vec![(0.0, 0.0)];
            angular.extend(seg);
            (
                "Torsion about the contact normal of two spheres vs Lubkin's exact curve (docs/THEORY.md §3)"
                    .to_string(),
                drive_block(p, r, &fmt_hist(&normal, 2), Some(&fmt_hist(&angular, 2))),
                t_end,
            )
        }
        TwoSphereKind::Rolling => {
            let theta_max = p.amplitude * dtmax / r;
            let w_max = theta_max / ((p.cruise + p.t_ramp) * u.time);
            let (seg, t_end) =
                trapezoid(t, theta_max, w_max, p.t_ramp * u.time, "rotation").map_err(fail)?;
            let mut angular: Points = vec![(0.0, 0.0)];
            angular.extend(seg);
            (
                "Rolling: upper sphere rotated about its own fixed centre, moment vs angle (docs/THEORY.md §4)"
                    .to_string(),
                drive_block(p, r, &fmt_hist(&normal, 2), Some(&fmt_hist(&angular, 0))),
                t_end,
            )
        }
    };
    let duration = end + p.tail * u.time;
    let refine = |dir: &str| {
        format!(
            "    {{ direction = [0.0, 0.0, {dir}], seeding = {}, radius = {}, growth = {:?} }},",
            sci(p.refine_seeding * r, 4),
            sci(p.refine_radius * r, 4),
            p.growth
        )
    };
    Ok(format!(
        r#"# {header}
#
# How to run:  mufe validate {name}          (sweep of meshing ratios, plots, JSON)
#              mufe run jobs/validation/{name}.toml --out out/{name}
# Generated by `mufe validate --write-scenes DIR` (src/validate/scenes/, edit there) for
# the material, radius and friction below; `mufe validate` regenerates the scene from
# those of this file (after --set), with drives, times and meshes scaled by R, R/c_p and
# δt,max. Normal force target N = {force:.4} N (a/R = {a_over_r:.4}, contact radius
# {a_um:.1} µm); the reference uses the N measured at the fixed base. `mufe validate` sets
# the seeding of refine[0] from the meshing ratio at the contact, MR = s/(2R).

[simulation]
duration = {duration}
# mass scaling of the fine contact elements only
target_dt = {target_dt}
# damps vibration of each sphere relative to its rigid-body motion (no net force on it)
deformation_damping = {damping}

{material}
[contact]
friction = {mu:?}

[[grains]]
name = "lower"
material = "{mat}"
centre = [0.0, 0.0, {neg_r}]
shape = {{ sphere = {{ radius = {radius}, seeding = {seeding}, refine = [
{refine_up}
] }} }}

[[grains]]
name = "upper"
material = "{mat}"
centre = [0.0, 0.0, {radius}]
shape = {{ sphere = {{ radius = {radius}, seeding = {seeding}, refine = [
{refine_down}
] }} }}

[[boundaries]]
name = "base"
grain = "lower"
select = {{ beyond_plane = {{ point = [0.0, 0.0, {neg_clamp}], normal = [0.0, 0.0, -1.0] }} }}
# moments of the base reaction are taken about the lower sphere's centre
centre = [0.0, 0.0, {neg_r}]

{motion}

[output]
history_interval = {history}
frames = false
"#,
        force = force,
        a_over_r = p.a_over_r,
        a_um = a * 1e6,
        duration = sci(duration, 6),
        target_dt = sci(p.target_dt * u.time, 3),
        damping = sci(p.damping / u.time, 3),
        material = inputs.material_block(),
        mat = inputs.material_name,
        neg_r = sci(-r, 6),
        radius = sci(r, 6),
        seeding = sci(p.seeding * r, 4),
        refine_up = refine("1.0"),
        refine_down = refine("-1.0"),
        neg_clamp = sci(-p.clamp * r, 6),
        history = sci(p.history_interval * u.time, 3),
    ))
}

fn drive_block(p: &TwoSphereParams, r: f64, velocity: &str, angular: Option<&str>) -> String {
    let mut s = format!(
        r#"[[boundaries]]
name = "drive"
grain = "upper"
select = {{ beyond_plane = {{ point = [0.0, 0.0, {}], normal = [0.0, 0.0, 1.0] }} }}
centre = [0.0, 0.0, {}]
velocity = {velocity}"#,
        sci(p.clamp * r, 6),
        sci(r, 6)
    );
    if let Some(w) = angular {
        s.push_str(&format!("\nangular_velocity = {w}"));
    }
    s
}

/// The scene text of a case (`hertz`, `mindlin`, `torsion`, `rolling`).
pub fn case_scene(case: &str, inputs: &SceneInputs, params: &Params) -> Result<String, InputError> {
    match case {
        "hertz" => hertz(inputs, &params.hertz),
        "mindlin" => two_sphere(TwoSphereKind::Mindlin, inputs, &params.mindlin),
        "mindlin_cyclic" => {
            two_sphere(TwoSphereKind::MindlinCyclic, inputs, &params.mindlin_cyclic)
        }
        "torsion" => two_sphere(TwoSphereKind::Torsion, inputs, &params.torsion),
        "rolling" => two_sphere(TwoSphereKind::Rolling, inputs, &params.rolling),
        other => Err(InputError::new(
            "<command line>",
            "CASE",
            format!("unknown validation case '{other}'"),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::parse_scene;

    fn steel() -> SceneInputs {
        SceneInputs {
            material: ElasticParameters {
                youngs_modulus: 210e9,
                poisson_ratio: 0.3,
                density: 7850.0,
            },
            radius: 2.5e-3,
            friction: 0.5,
            ..SceneInputs::paper()
        }
    }

    #[test]
    fn shipped_scenes_are_the_generator_output_for_the_paper_glass() {
        let shipped = [
            ("hertz", crate::validate::hertz::SCENE),
            ("mindlin", crate::validate::two_sphere::MINDLIN_SCENE),
            ("torsion", crate::validate::two_sphere::TORSION_SCENE),
            ("rolling", crate::validate::two_sphere::ROLLING_SCENE),
        ];
        for (name, text) in shipped {
            let generated = case_scene(name, &SceneInputs::paper(), &Params::default()).unwrap();
            assert!(
                generated == text,
                "jobs/validation/{name}.toml differs from the generator's output: rewrite it \
                 with `mufe validate --write-scenes jobs/validation`"
            );
            // and reading the inputs back from it gives the paper's
            let loaded = parse_scene(name, text, &[]).unwrap();
            let back = SceneInputs::from_scene(name, &loaded, &[]).unwrap();
            let paper = SceneInputs::paper();
            assert_eq!(back.material, paper.material);
            assert_eq!(back.radius, paper.radius);
            if name != "hertz" {
                assert_eq!(back.friction, paper.friction);
            }
        }
    }

    /// Integral of a piecewise-linear velocity history (component `axis`) up to its end.
    fn travel(h: &crate::scene::History3, axis: usize) -> f64 {
        h.times
            .windows(2)
            .zip(h.values.windows(2))
            .map(|(t, v)| 0.5 * (t[1] - t[0]) * (v[0][axis] + v[1][axis]))
            .sum()
    }

    #[test]
    fn drives_scale_with_the_material_radius_and_friction() {
        let glass = SceneInputs::paper();
        let steel = steel();
        let params = Params::default();
        let parse = |name: &str, inputs: &SceneInputs| {
            parse_scene(name, &case_scene(name, inputs, &params).unwrap(), &[])
                .unwrap()
                .scene
        };
        let (ug, us) = (glass.units(), steel.units());
        // Hertz: the same δ/R window (a/R), duration and step in units of R/c_p
        let (hg, hs) = (parse("hertz", &glass), parse("hertz", &steel));
        let wall = |s: &crate::scene::Scene| s.walls[1].velocity.clone().unwrap();
        let delta_over_r = |s: &crate::scene::Scene, r: f64| {
            let h = wall(s);
            let v_end = h.values.last().unwrap()[2];
            let t_end = *h.times.last().unwrap();
            (travel(&h, 2) + v_end * (s.simulation.duration - t_end)) / r
        };
        let (dg, ds) = (
            delta_over_r(&hg, glass.radius),
            delta_over_r(&hs, steel.radius),
        );
        assert!((dg / ds - 1.0).abs() < 1e-6, "{dg} vs {ds}");
        // the plates travel to the Hertz contact radius a_end: δ = a²/R (the piecewise-linear
        // exponential speed overestimates the travel by ≈ (Δt/τ)²/12 = 0.1 %)
        assert!((dg / params.hertz.a_end.powi(2) - 1.0).abs() < 3e-3);
        let t_ratio = |s: &crate::scene::Scene, u: &Units| s.simulation.duration / u.time;
        assert!((t_ratio(&hg, &ug) / t_ratio(&hs, &us) - 1.0).abs() < 1e-6);
        let dt_ratio =
            |s: &crate::scene::Scene, u: &Units| s.simulation.target_dt.unwrap() / u.time;
        assert!((dt_ratio(&hg, &ug) / dt_ratio(&hs, &us) - 1.0).abs() < 1e-3);
        let shape = |s: &crate::scene::Scene| match &s.grains[0].shape {
            ShapeSpec::Sphere(sp) => (sp.radius, sp.seeding, sp.refine[0].radius),
            _ => unreachable!(),
        };
        let (sg, ss) = (shape(&hg), shape(&hs));
        assert_eq!(ss.0, steel.radius);
        assert!((sg.1 / sg.0 - ss.1 / ss.0).abs() < 1e-4 * sg.1 / sg.0);
        assert!((sg.2 / sg.0 - ss.2 / ss.0).abs() < 1e-4 * sg.2 / sg.0);

        // Mindlin: normal approach 0.92 × 2a²/R at the same a/R; tangential amplitude
        // 1.2 δt,max of the steel at μ = 0.5; the same duration in R/c_p
        let (mg, ms) = (parse("mindlin", &glass), parse("mindlin", &steel));
        let drive = |s: &crate::scene::Scene| s.boundaries[1].velocity.clone().unwrap();
        let a = params.mindlin.a_over_r;
        for (scene, inputs) in [(&mg, &glass), (&ms, &steel)] {
            let h = drive(scene);
            let dz = travel(&h, 2) / inputs.radius;
            assert!((dz / (-0.92 * 2.0 * a * a) - 1.0).abs() < 1e-3, "{dz}");
            // x: +A, −2A, +2A: the first leg's peak is the amplitude
            let mut x: f64 = 0.0;
            let mut peak: f64 = 0.0;
            for (t, v) in h.times.windows(2).zip(h.values.windows(2)) {
                x += 0.5 * (t[1] - t[0]) * (v[0][0] + v[1][0]);
                peak = peak.max(x);
            }
            let dtmax = inputs.units().slip_displacement(inputs.friction, a);
            assert!((peak / (1.2 * dtmax) - 1.0).abs() < 1e-3, "{peak} {dtmax}");
            assert_eq!(scene.contact.friction, inputs.friction);
            assert_eq!(
                scene.materials["glass"].youngs_modulus,
                inputs.material.youngs_modulus
            );
        }
        assert!((t_ratio(&mg, &ug) / t_ratio(&ms, &us) - 1.0).abs() < 1e-6);
        // the normal force of the drive follows E*R²: the same a/R
        assert!((us.a_over_r(us.force_at(a)) - a).abs() < 1e-12 && us.force_at(a) > ug.force_at(a));

        // torsion and rolling: final twist and angle in their natural units
        for (name, axis) in [("torsion", 2), ("rolling", 0)] {
            let s = parse(name, &steel);
            let w = s.boundaries[1].angular_velocity.clone().unwrap();
            let angle = travel(&w, axis);
            let p = if name == "torsion" {
                &params.torsion
            } else {
                &params.rolling
            };
            let a = p.a_over_r;
            let expect = if name == "torsion" {
                2.0 * p.twist_param * steel.friction * us.force_at(a)
                    / (us.shear * (a * steel.radius).powi(2))
            } else {
                p.amplitude * us.slip_displacement(steel.friction, a) / steel.radius
            };
            assert!(
                (angle / expect - 1.0).abs() < 1e-3,
                "{name}: {angle} vs {expect}"
            );
        }
    }

    #[test]
    fn the_material_law_and_other_material_fields_are_carried() {
        let loaded = parse_scene(
            "hertz",
            crate::validate::hertz::SCENE,
            &["materials.glass.law=\"corotational\"".to_string()],
        )
        .unwrap();
        let inputs = SceneInputs::from_scene("hertz", &loaded, &[]).unwrap();
        let text = hertz(&inputs, &HertzParams::default()).unwrap();
        let scene = parse_scene("hertz", &text, &[]).unwrap().scene;
        assert_eq!(
            scene.materials["glass"].law,
            crate::material::ElasticLawKind::Corotational
        );
    }

    #[test]
    fn params_set_and_refuse() {
        let mut p = Params::default();
        p.set("hertz.v_plate=2e-4").unwrap();
        assert_eq!(p.hertz.v_plate, 2e-4);
        p.set("rolling.clamp = 1").unwrap();
        assert_eq!(p.rolling.clamp, 1.0);
        for bad in [
            "hertz.nope=1",
            "nocase.v=1",
            "hertz.v_plate",
            "hertz.ramp=abc",
            "x=1",
        ] {
            let e = p.set(bad).unwrap_err();
            assert_eq!(e.file, "<command line>", "{bad}");
        }
    }

    #[test]
    fn a_tangential_case_without_friction_is_an_input_error() {
        let loaded = parse_scene(
            "jobs/validation/mindlin.toml",
            crate::validate::two_sphere::MINDLIN_SCENE,
            &["contact.friction=0".to_string()],
        )
        .unwrap();
        let e = SceneInputs::from_scene("mindlin", &loaded, &["contact.friction=0".into()])
            .unwrap_err();
        assert_eq!(e.item, "contact.friction");
        assert!(e.message.contains("--set contact.friction=0"), "{e}");
    }

    #[test]
    fn python_style_exponents() {
        assert_eq!(sci(7.5e-7, 9), "7.500000000e-07");
        assert_eq!(sci(6.3e10, 6), "6.300000e+10");
        assert_eq!(sci(0.0, 6), "0.000000e+00");
        assert_eq!(sci(-0.0, 6), "-0.000000e+00");
    }
}
