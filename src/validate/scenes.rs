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

/// Hertz: one sphere squeezed between two rigid frictionless plates.
#[derive(Debug, Clone, PartialEq)]
pub struct HertzParams {
    /// Plate speed after the ramp (c_p).
    pub v_plate: f64,
    /// Raised-cosine ramp of the plate speed (R/c_p; 0: constant speed from t = 0).
    pub ramp: f64,
    /// Exponential drive when > 0 (then `v_plate` and `ramp` are unused): each plate's
    /// travel from first touch is δ(t) = δ0 (e^{t/τ} − 1), so its speed (δ + δ0)/τ and
    /// acceleration (δ + δ0)/τ² grow with δ and the relative inertia of the contact zone,
    /// ∝ (v²/δ + a)/δ, is uniform over the load range (τ in R/c_p).
    pub tau: f64,
    /// δ0 of the exponential drive (R): the speed at first touch is δ0/τ.
    pub delta0: f64,
    /// Initial gap between each plate and its pole (R).
    pub gap: f64,
    /// Plate travel covered by the duration, as the Hertz contact radius √(δR) it gives (R).
    pub a_end: f64,
    /// Mass scaling of the fine contact elements (R/c_p).
    pub target_dt: f64,
    /// Global surface seeding (R).
    pub seeding: f64,
    /// Seeding of the pole patches as written (R); `mufe validate` sets it from MR.
    pub refine_seeding: f64,
    /// Radius of the fine zone around each pole, chord distance (R).
    pub refine_radius: f64,
    /// Growth of the edge length beyond the fine zone (–).
    pub growth: f64,
    /// Deformation damping (c_p/R).
    pub damping: f64,
    /// History sampling interval (R/c_p).
    pub history_interval: f64,
}

impl Default for HertzParams {
    /// On the paper's glass: an exponential drive δ = δ0 (e^{t/τ} − 1) with δ0 = 0.03 µm
    /// and τ such that the travel to 7.2 µm (F_ref ≈ 55 N) takes 15 µs, target_dt 3 ns,
    /// seeding 150 µm, patches of radius 0.02 R = 22 µm (1.2 × the contact radius at the
    /// window's low end) with growth 0.12, history every 25 ns. The original study's
    /// raised-cosine ramp (0.6 m/s after 6 µs) stays available as `tau = 0` with
    /// `v_plate`, `ramp` (docs/BENCHMARKS.md, "Hertz bias").
    fn default() -> Self {
        let u = Units::paper();
        let (delta0, delta_end, duration): (f64, f64, f64) = (3.0e-8, 7.2e-6, 15.0e-6);
        Self {
            v_plate: 0.6 / u.speed,
            ramp: 6.0e-6 / u.time,
            tau: duration / (1.0 + delta_end / delta0).ln() / u.time,
            delta0: delta0 / u.length,
            gap: 0.0,
            a_end: (delta_end / u.length).sqrt(),
            target_dt: 3.0e-9 / u.time,
            seeding: 1.5e-4 / u.length,
            refine_seeding: 1.0e-5 / u.length,
            refine_radius: 0.02,
            growth: 0.12,
            damping: 0.0,
            history_interval: 2.5e-8 / u.time,
        }
    }
}

/// `hertz_ellipsoid` (an ellipsoid between plates, `super::hertz_ellipsoid`): generator
/// parameters (`--param hertz_ellipsoid.KEY=VALUE`), lengths in R_e, times in
/// R_e/c_p: the same dimensionless drive as the sphere case's (`hertz`).
#[derive(Debug, Clone, PartialEq)]
pub struct HertzEllipsoidParams {
    /// Exponential drive δ = δ0 (e^{t/τ} − 1) of each plate (R_e/c_p, R_e).
    pub tau: f64,
    pub delta0: f64,
    /// Mass scaling of the fine tip elements (R_e/c_p).
    pub target_dt: f64,
    /// Facet edge away from the tips (R_e).
    pub seeding: f64,
    /// Radius of the fine tip patch (R_e) and growth of the edge beyond it (–).
    pub tip_radius: f64,
    pub growth: f64,
    /// History sampling interval (R_e/c_p).
    pub history_interval: f64,
}

impl Default for HertzEllipsoidParams {
    /// The `hertz` case's τ, δ0 and target_dt in units of R_e instead of R; a tip patch of
    /// 1.2 × the major semi-axis at the window's low end (as the sphere's pole patch),
    /// growth 0.12, bulk facets of R_e/7.
    fn default() -> Self {
        let sphere = HertzParams::default();
        Self {
            tau: sphere.tau,
            delta0: sphere.delta0,
            target_dt: sphere.target_dt,
            seeding: 0.14,
            tip_radius: 0.014,
            growth: 0.12,
            history_interval: sphere.history_interval,
        }
    }
}

impl HertzEllipsoidParams {
    fn fields(&mut self) -> Vec<(&'static str, &mut f64)> {
        vec![
            ("tau", &mut self.tau),
            ("delta0", &mut self.delta0),
            ("target_dt", &mut self.target_dt),
            ("seeding", &mut self.seeding),
            ("tip_radius", &mut self.tip_radius),
            ("growth", &mut self.growth),
            ("history_interval", &mut self.history_interval),
        ]
    }
}

/// Two identical spheres touching at the origin (Mindlin, torsion, rolling).
#[derive(Debug, Clone, PartialEq)]
pub struct TwoSphereParams {
    /// Nominal normal load, as its Hertz contact radius (R).
    pub a_over_r: f64,
    /// Fraction of the Hertz approach at that load the drive moves down: the held parts at
    /// ±clamp·R make the pair stiffer than two half-spaces, and this brings the measured N
    /// close to the nominal one.
    pub approach_scale: f64,
    /// Normal approach speed (c_p), its ramps (R/c_p) and the rest after it (R/c_p).
    pub vn: f64,
    pub n_ramp: f64,
    pub settle: f64,
    /// Mindlin: tangential speed (δt,max per R/c_p, so the legs take the same time for any
    /// μ and material), amplitude (δt,max) and reversals (1: unload to −amplitude; 2: then
    /// reload to +amplitude).
    pub vt: f64,
    pub amplitude: f64,
    pub reversals: f64,
    /// Torsion: final G a² β/(μN) per sphere.
    pub twist_param: f64,
    /// Torsion and rolling: constant-speed time of the case motion (R/c_p).
    pub cruise: f64,
    /// Raised-cosine ramps of the case motion (R/c_p).
    pub t_ramp: f64,
    /// Time after the case motion (R/c_p).
    pub tail: f64,
    /// Mass scaling of the fine contact elements (R/c_p).
    pub target_dt: f64,
    /// Deformation damping (c_p/R).
    pub damping: f64,
    /// Global seeding (R), patch seeding as written (R), patch radius (R), growth (–).
    pub seeding: f64,
    pub refine_seeding: f64,
    pub refine_radius: f64,
    pub growth: f64,
    /// History sampling interval (R/c_p).
    pub history_interval: f64,
    /// Held/driven parts: beyond the planes at ∓clamp·R from the contact (1 = the far
    /// hemispheres). See docs/BENCHMARKS.md (Validation) for its effect.
    pub clamp: f64,
}

impl TwoSphereParams {
    /// Parameters shared by the three cases on the paper's glass: approach at 1 m/s (5 N)
    /// or 4 m/s (70 N) with 2 µs ramps, 2 µs rest, target_dt 2 ns, damping 2×10⁶ 1/s,
    /// seeding 275 µm, history every 20 ns, clamp R/2, 0.2 µs tail.
    fn paper_common(force: f64, vn: f64, refine_radius: f64, growth: f64) -> Self {
        let u = Units::paper();
        Self {
            a_over_r: u.a_over_r(force),
            approach_scale: 0.92,
            vn: vn / u.speed,
            n_ramp: 2.0e-6 / u.time,
            settle: 2.0e-6 / u.time,
            vt: 0.0,
            amplitude: 0.0,
            reversals: 0.0,
            twist_param: 0.0,
            cruise: 0.0,
            t_ramp: 2.0e-6 / u.time,
            tail: 0.2e-6 / u.time,
            target_dt: 2.0e-9 / u.time,
            damping: 2.0e6 * u.time,
            seeding: 2.75e-4 / u.length,
            refine_seeding: 1.0e-5 / u.length,
            refine_radius: refine_radius / u.length,
            growth,
            history_interval: 2.0e-8 / u.time,
            clamp: 0.5,
        }
    }

    /// Mindlin on the paper's glass: N = 5 N, 0.4 m/s tangential with 1.5 µs ramps to
    /// ±1.2 δt,max and back (two reversals), patch 20 µm with growth 0.15.
    pub fn mindlin() -> Self {
        let u = Units::paper();
        let mut p = Self::paper_common(5.0, 1.0, 2.0e-5, 0.15);
        let dtmax = u.slip_displacement(paper::FRICTION, p.a_over_r);
        p.vt = 0.4 / (dtmax / u.time);
        p.t_ramp = 1.5e-6 / u.time;
        p.amplitude = 1.2;
        p.reversals = 2.0;
        p
    }

    /// The full cycle of `mindlin_cyclic`: as [`Self::mindlin`], to ±0.8 δt,max (partial
    /// slip throughout, Q*/μN = 0.91) and back twice, at 3/4 of its tangential speed (the
    /// shorter legs still fit their ramps).
    pub fn mindlin_cyclic() -> Self {
        let mut p = Self::mindlin();
        p.amplitude = 0.8;
        p.vt *= 0.75;
        p
    }

    /// Torsion on the paper's glass: N = 70 N, relative twist to G a² β/(μN) = 0.6 (c/a ≈
    /// 0.1) in 9 µs, patch 110 µm with growth 0.3.
    pub fn torsion() -> Self {
        let u = Units::paper();
        let mut p = Self::paper_common(70.0, 4.0, 1.1e-4, 0.3);
        p.twist_param = 0.6;
        p.cruise = 5.0e-6 / u.time;
        p
    }

    /// Rolling on the paper's glass: N = 70 N, rotation to 1.5 θ_slip in 9 µs, patch
    /// 110 µm with growth 0.3.
    pub fn rolling() -> Self {
        let u = Units::paper();
        let mut p = Self::paper_common(70.0, 4.0, 1.1e-4, 0.3);
        p.amplitude = 1.5;
        p.cruise = 5.0e-6 / u.time;
        p
    }
}

/// The generator parameters of all four cases (`mufe validate --param CASE.KEY=VALUE`).
#[derive(Debug, Clone, PartialEq)]
pub struct Params {
    pub hertz: HertzParams,
    pub mindlin: TwoSphereParams,
    pub mindlin_cyclic: TwoSphereParams,
    pub torsion: TwoSphereParams,
    pub rolling: TwoSphereParams,
    pub thornton_walls: super::thornton_scene::ThorntonParams,
    pub thornton: super::thornton_scene::ThorntonParams,
    pub hertz_ellipsoid: HertzEllipsoidParams,
}

impl Default for Params {
    fn default() -> Self {
        Self {
            hertz: HertzParams::default(),
            mindlin: TwoSphereParams::mindlin(),
            mindlin_cyclic: TwoSphereParams::mindlin_cyclic(),
            torsion: TwoSphereParams::torsion(),
            rolling: TwoSphereParams::rolling(),
            thornton_walls: Default::default(),
            thornton: super::thornton_scene::ThorntonParams::periodic(),
            hertz_ellipsoid: Default::default(),
        }
    }
}

impl HertzParams {
    fn fields(&mut self) -> Vec<(&'static str, &mut f64)> {
        vec![
            ("v_plate", &mut self.v_plate),
            ("ramp", &mut self.ramp),
            ("tau", &mut self.tau),
            ("delta0", &mut self.delta0),
            ("gap", &mut self.gap),
            ("a_end", &mut self.a_end),
            ("target_dt", &mut self.target_dt),
            ("seeding", &mut self.seeding),
            ("refine_seeding", &mut self.refine_seeding),
            ("refine_radius", &mut self.refine_radius),
            ("growth", &mut self.growth),
            ("damping", &mut self.damping),
            ("history_interval", &mut self.history_interval),
        ]
    }
}

impl TwoSphereParams {
    fn fields(&mut self) -> Vec<(&'static str, &mut f64)> {
        vec![
            ("a_over_r", &mut self.a_over_r),
            ("approach_scale", &mut self.approach_scale),
            ("vn", &mut self.vn),
            ("n_ramp", &mut self.n_ramp),
            ("settle", &mut self.settle),
            ("vt", &mut self.vt),
            ("amplitude", &mut self.amplitude),
            ("reversals", &mut self.reversals),
            ("twist_param", &mut self.twist_param),
            ("cruise", &mut self.cruise),
            ("t_ramp", &mut self.t_ramp),
            ("tail", &mut self.tail),
            ("target_dt", &mut self.target_dt),
            ("damping", &mut self.damping),
            ("seeding", &mut self.seeding),
            ("refine_seeding", &mut self.refine_seeding),
            ("refine_radius", &mut self.refine_radius),
            ("growth", &mut self.growth),
            ("history_interval", &mut self.history_interval),
            ("clamp", &mut self.clamp),
        ]
    }
}

impl Params {
    /// Applies `CASE.KEY=VALUE` (dimensionless, in the units documented on the field).
    pub fn set(&mut self, assignment: &str) -> Result<(), InputError> {
        let item = format!("--param {}", crate::error::echo(assignment));
        let bad = |m: String| InputError::new("<command line>", &item, m);
        let (key, value) = assignment
            .split_once('=')
            .ok_or_else(|| bad("expected CASE.KEY=VALUE".into()))?;
        let (case, field) = key
            .trim()
            .split_once('.')
            .ok_or_else(|| bad("expected CASE.KEY=VALUE".into()))?;
        let value: f64 = value
            .trim()
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite())
            .ok_or_else(|| bad(format!("'{}' is not a finite number", value.trim())))?;
        let mut fields = match case {
            "hertz" => self.hertz.fields(),
            "mindlin" => self.mindlin.fields(),
            "mindlin_cyclic" => self.mindlin_cyclic.fields(),
            "torsion" => self.torsion.fields(),
            "rolling" => self.rolling.fields(),
            "thornton_walls" => self.thornton_walls.fields(),
            "thornton" => self.thornton.fields(),
            "hertz_ellipsoid" => self.hertz_ellipsoid.fields(),
            other => {
                return Err(bad(format!(
                    "unknown case '{other}' (known: {})",
                    super::CASE_NAMES.join(", ")
                )))
            }
        };
        let names: Vec<&str> = fields.iter().map(|f| f.0).collect();
        let names = names.join(", ");
        let slot = fields
            .iter_mut()
            .find(|f| f.0 == field.trim())
            .ok_or_else(|| bad(format!("unknown parameter (known: {names})")))?;
        *slot.1 = value;
        Ok(())
    }
}

/// `x` in C/Python `%.{prec}e` style (`7.500000000e-07`): a sign and two exponent digits.
fn sci(x: f64, prec: usize) -> String {
    let s = format!("{x:.prec$e}");
    match s.split_once('e') {
        Some((mant, exp)) => {
            let e: i32 = exp.parse().unwrap_or(0);
            format!("{mant}e{}{:02}", if e < 0 { '-' } else { '+' }, e.abs())
        }
        None => s,
    }
}

/// Points of the raised-cosine ramps.
const RAMP_POINTS: usize = 8;

type Points = Vec<(f64, f64)>;

/// Velocity-time points moving `distance` (signed) from t0 at speed `vmax`: raised-cosine
/// ramps of duration `ramp` up and down, constant speed between. Returns (points, end time).
fn trapezoid(
    t0: f64,
    distance: f64,
    vmax: f64,
    ramp: f64,
    what: &str,
) -> Result<(Points, f64), String> {
    let v = vmax.copysign(distance);
    // each raised-cosine ramp covers v·ramp/2
    let cruise = distance.abs() / vmax - ramp;
    if !(cruise > 0.0 && ramp >= 0.0) {
        return Err(format!(
            "{what}: the motion ({} over ramps of {} s at {}) is too short for its ramps",
            num(distance),
            num(ramp),
            num(vmax)
        ));
    }
    let n = RAMP_POINTS as f64;
    let mut pts: Points = (0..=RAMP_POINTS)
        .map(|k| {
            let k = k as f64;
            (
                t0 + ramp * k / n,
                v * 0.5 * (1.0 - (std::f64::consts::PI * k / n).cos()),
            )
        })
        .collect();
    let t2 = t0 + ramp + cruise;
    pts.extend((0..=RAMP_POINTS).map(|k| {
        let k = k as f64;
        (
            t2 + ramp * k / n,
            v * 0.5 * (1.0 + (std::f64::consts::PI * k / n).cos()),
        )
    }));
    Ok((pts, t2 + ramp))
}

fn fmt_hist(points: &[(f64, f64)], axis: usize) -> String {
    let times: Vec<String> = points.iter().map(|p| sci(p.0, 9)).collect();
    let values: Vec<String> = points
        .iter()
        .map(|p| {
            let mut v = [0.0; 3];
            v[axis] = p.1;
            format!("[{}, {}, {}]", sci(v[0], 6), sci(v[1], 6), sci(v[2], 6))
        })
        .collect();
    format!(
        "{{ times = [{}], values = [{}] }}",
        times.join(", "),
        values.join(", ")
    )
}

/// Piecewise-linear value of a velocity history at t (held constant outside).
fn value_at(pts: &[(f64, f64)], t: f64) -> f64 {
    if t <= pts[0].0 {
        return pts[0].1;
    }
    for w in pts.windows(2) {
        let ((t0, v0), (t1, v1)) = (w[0], w[1]);
        if t0 <= t && t <= t1 {
            return if t1 > t0 {
                v0 + (v1 - v0) * (t - t0) / (t1 - t0)
            } else {
                v1
            };
        }
    }
    pts[pts.len() - 1].1
}

/// Normal (z) and tangential (x) velocity histories on one time base.
fn merge(z: &[(f64, f64)], x: &[(f64, f64)]) -> String {
    let mut times: Vec<f64> = z.iter().chain(x.iter()).map(|p| p.0).collect();
    times.sort_by(f64::total_cmp);
    times.dedup();
    let ts: Vec<String> = times.iter().map(|&t| sci(t, 9)).collect();
    let vs: Vec<String> = times
        .iter()
        .map(|&t| {
            format!(
                "[{}, 0.0, {}]",
                sci(value_at(x, t), 6),
                sci(value_at(z, t), 6)
            )
        })
        .collect();
    format!(
        "{{ times = [{}], values = [{}] }}",
        ts.join(", "),
        vs.join(", ")
    )
}

fn invalid(inputs: &SceneInputs, case: &str, message: String) -> InputError {
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
/// away from the poles. Returns (velocity points, duration, description).
fn plate_ramp(
    inputs: &SceneInputs,
    p: &HertzParams,
    v_plate: f64,
    ramp: f64,
    gap: f64,
    delta_end: f64,
) -> Result<(Points, f64, String), InputError> {
    let (up, travel_ramp): (Points, f64) = if ramp > 0.0 {
        let n = RAMP_POINTS as f64;
        (
            (0..=RAMP_POINTS)
                .map(|k| {
                    let k = k as f64;
                    (
                        ramp * k / n,
                        v_plate * 0.5 * (1.0 - (std::f64::consts::PI * k / n).cos()),
                    )
                })
                .collect(),
            0.5 * v_plate * ramp,
        )
    } else {
        (vec![(0.0, v_plate)], 0.0)
    };
    let duration = ramp + (gap + delta_end - travel_ramp) / v_plate;
    if duration <= ramp {
        return Err(invalid(
            inputs,
            "hertz",
            "the plate travel ends inside the speed ramp".into(),
        ));
    }
    let motion = if ramp > 0.0 {
        format!(
            "raised-cosine ramp to {:.4} m/s = {:.3e} c_p over {:.3} µs, then constant",
            v_plate,
            p.v_plate,
            ramp * 1e6
        )
    } else {
        format!(
            "constant {v_plate:.4} m/s = {:.3e} c_p from t = 0",
            p.v_plate
        )
    };
    Ok((up, duration, motion))
}

/// Points of the exponential plate speed.
const EXPONENTIAL_POINTS: usize = 48;

/// Exponential drive: δ(t) = δ0 (e^{t/τ} − 1) from first touch at t = 0 (no gap), speed
/// sampled piecewise linearly. Returns (velocity points, duration, description).
fn plate_exponential(
    inputs: &SceneInputs,
    p: &HertzParams,
    delta_end: f64,
) -> Result<(Points, f64, String), InputError> {
    let u = inputs.units();
    let (tau, delta0) = (p.tau * u.time, p.delta0 * u.length);
    if !(delta0 > 0.0 && delta0 < delta_end && p.gap == 0.0) {
        return Err(invalid(
            inputs,
            "hertz",
            "the exponential drive needs 0 < delta0 < a_end² and gap = 0".into(),
        ));
    }
    let duration = tau * (1.0 + delta_end / delta0).ln();
    let n = EXPONENTIAL_POINTS as f64;
    // the piecewise-linear speed overestimates the travel by ≈ (Δt/τ)²/12 (0.1 % with the
    // defaults): the plates reach δ_end a little before the end of the duration
    let up: Points = (0..=EXPONENTIAL_POINTS)
        .map(|k| {
            let t = duration * k as f64 / n;
            (t, delta0 / tau * (t / tau).exp())
        })
        .collect();
    let motion = format!(
        "exponential, δ = δ0 (e^(t/τ) − 1), τ = {:.4} µs = {:.4} R/c_p, δ0 = {:.4} µm,\n\
         # from {:.3e} to {:.4} m/s",
        tau * 1e6,
        p.tau,
        delta0 * 1e6,
        delta0 / tau,
        (delta_end + delta0) / tau
    );
    Ok((up, duration, motion))
}

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
# Generated by `mufe validate --write-scenes DIR` (src/validate/scenes.rs, edit there) for
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
# Generated by `mufe validate --write-scenes DIR` (src/validate/scenes.rs, edit there) for
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
            ("hertz", super::super::hertz::SCENE),
            ("mindlin", super::super::two_sphere::MINDLIN_SCENE),
            ("torsion", super::super::two_sphere::TORSION_SCENE),
            ("rolling", super::super::two_sphere::ROLLING_SCENE),
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
            super::super::hertz::SCENE,
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
            super::super::two_sphere::MINDLIN_SCENE,
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
