//! The walled FCC triaxial cell of `mufe validate thornton_walls`, generated from the
//! material, sphere radius R and confining stress σ3 of the case scene
//! (`jobs/validation/thornton_walls.toml` is this generator's output for the paper's glass
//! at 50 kPa, checked by a test).
//!
//! A closed block of n × n × n cubic FCC cells (n = 3: 172 spheres, the rigid-sphere DEM
//! baseline's block of docs/THEORY.md §9), touching spheres, a node at every lattice
//! contact and wall point, six rigid frictionless walls touching the outer spheres.
//! Stage 1 compresses it isotropically to σ3 (five servo walls, the bottom fixed) until
//! every servo holds its tolerance (mass damping on); stage 2 drives the top wall at the
//! inertial number I, undamped, with the four lateral walls servo-held at σ3 until failure (a drop below the peak
//! ratio, or a plateau: steady sliding) plus a strain margin.
//!
//! Every parameter is dimensionless: lengths in R, times in R/c_p, damping in c_p/R, the
//! loading by I = ε̇ d √(ρ/σ3); so another material or size is loaded alike.

use crate::error::{num, InputError};
use crate::material::ElasticParameters;
use crate::scene::stages::WallModeSpec;
use crate::scene::LoadedScene;

/// Generator parameters (dimensionless; `--param thornton_walls.KEY=VALUE`).
#[derive(Debug, Clone, PartialEq)]
pub struct ThorntonParams {
    /// Cubic cells per side of the closed block (3: 172 spheres).
    pub cells: f64,
    /// Surface seeding away from the contacts / R.
    pub seeding: f64,
    /// Seeding at the lattice contacts and wall points / R.
    pub contact_seeding: f64,
    /// Mass-scaled step / (R/c_p).
    pub target_dt: f64,
    /// Mass-proportional damping / (c_p/R) in stage 1 (consolidation).
    pub damping: f64,
    /// The same in stage 2 (shearing): 0, since damping drags the moving grains and adds
    /// ~1.2 % to the peak per halving (docs/BENCHMARKS.md).
    pub shear_damping: f64,
    /// Inertial number of the axial loading.
    pub inertial_number: f64,
    /// Relative drop below the peak ratio that counts as failure.
    pub drop: f64,
    /// Axial strain without a 1 % rise of the ratio that counts as failure.
    pub plateau_strain: f64,
    /// Axial strain run on after failure.
    pub strain_margin: f64,
    /// Stage 1: servo tolerance (relative) and hold (servo time constants).
    pub tolerance: f64,
    pub hold: f64,
    /// Servo loop time constant in periods of the cell's rigid mode on its wall stiffness
    /// (the servo spec's `periods`): ½ lets the lateral walls follow the dilation at
    /// failure (src/boundary/servo.rs).
    pub servo_periods: f64,
    /// Longest stage durations / (R/c_p).
    pub isotropic_max_time: f64,
    pub shear_max_time: f64,
    /// History interval / (R/c_p).
    pub history_interval: f64,
}

/// R/c_p of the paper's glass (R = 1.1 mm; E = 63 GPa, ν = 0.22, ρ = 2500 kg/m³: c_p =
/// 5 364 m/s), the unit the defaults are written in (each default is its SI value on that
/// glass divided by this).
fn paper_time() -> f64 {
    let glass = ElasticParameters {
        youngs_modulus: 63e9,
        poisson_ratio: 0.22,
        density: 2500.0,
    };
    1.1e-3 / glass.dilatational_wave_speed()
}

impl Default for ThorntonParams {
    fn default() -> Self {
        let paper_time = paper_time();
        Self {
            cells: 3.0,
            seeding: 6.0e-4 / 1.1e-3,
            contact_seeding: 3.0e-4 / 1.1e-3,
            target_dt: 1.5e-8 / paper_time,
            damping: 1.0e5 * paper_time,
            shear_damping: 0.0,
            inertial_number: 1.0e-4,
            drop: 0.05,
            plateau_strain: 2.0e-5,
            strain_margin: 1.0e-5,
            tolerance: 0.01,
            hold: 1.0,
            servo_periods: 0.5,
            isotropic_max_time: 1.5e-3 / paper_time,
            shear_max_time: 2.0e-3 / paper_time,
            history_interval: 5.0e-6 / paper_time,
        }
    }
}

impl ThorntonParams {
    /// Name and slot of every parameter (for `--param`).
    pub fn fields(&mut self) -> Vec<(&'static str, &mut f64)> {
        vec![
            ("cells", &mut self.cells),
            ("seeding", &mut self.seeding),
            ("contact_seeding", &mut self.contact_seeding),
            ("target_dt", &mut self.target_dt),
            ("damping", &mut self.damping),
            ("shear_damping", &mut self.shear_damping),
            ("inertial_number", &mut self.inertial_number),
            ("drop", &mut self.drop),
            ("plateau_strain", &mut self.plateau_strain),
            ("strain_margin", &mut self.strain_margin),
            ("tolerance", &mut self.tolerance),
            ("hold", &mut self.hold),
            ("servo_periods", &mut self.servo_periods),
            ("isotropic_max_time", &mut self.isotropic_max_time),
            ("shear_max_time", &mut self.shear_max_time),
            ("history_interval", &mut self.history_interval),
        ]
    }

    /// Cubic cells per side (≥ 1).
    pub fn cell_count(&self) -> usize {
        self.cells.round().max(1.0) as usize
    }
}

/// What the cell is generated from, as read from the case scene.
#[derive(Debug, Clone, PartialEq)]
pub struct ThorntonInputs {
    pub file: String,
    pub material_name: String,
    pub material: ElasticParameters,
    /// Other fields of the material table (`yield_stress`, `law`, ...), copied as given.
    pub material_extra: Vec<(String, toml::Value)>,
    /// Sphere radius R (m).
    pub radius: f64,
    /// Confining stress σ3 (Pa): the servo target of the first stage.
    pub confining_stress: f64,
}

impl ThorntonInputs {
    /// Reads the packing's material and radius and the first stage's servo stress.
    pub fn from_scene(loaded: &LoadedScene) -> Result<Self, InputError> {
        let file = loaded.path.clone();
        let scene = &loaded.scene;
        let need = |field: &str, what: &str| {
            InputError::new(
                &file,
                field,
                format!("the thornton_walls case needs {what}"),
            )
        };
        let packing = scene
            .packings
            .first()
            .ok_or_else(|| need("packings", "one FCC packing"))?;
        let confining_stress = scene
            .stages
            .first()
            .and_then(|s| {
                s.walls
                    .values()
                    .chain(s.cell.values())
                    .find_map(|m| match m {
                        WallModeSpec::Servo(spec) => Some(spec.stress),
                        _ => None,
                    })
            })
            .ok_or_else(|| {
                need(
                    "stages[0]",
                    "a servo wall or cell axis in the first stage (σ3)",
                )
            })?;
        if confining_stress <= 0.0 {
            return Err(InputError::new(
                &file,
                "stages[0].walls",
                format!("σ3 must be > 0, got {}", num(confining_stress)),
            ));
        }
        let m = scene
            .materials
            .get(&packing.material)
            .ok_or_else(|| need("packings[0].material", "a defined material"))?;
        let material_extra = loaded.material_extra_fields(&packing.material);
        Ok(Self {
            file,
            material_name: packing.material.clone(),
            material: ElasticParameters {
                youngs_modulus: m.youngs_modulus,
                poisson_ratio: m.poisson_ratio,
                density: m.density,
            },
            material_extra,
            radius: packing.sphere.radius,
            confining_stress,
        })
    }
}

impl ThorntonParams {
    /// Defaults of the periodic cell of `mufe validate thornton`: one cubic cell of 4
    /// spheres (the cell-count study in docs/BENCHMARKS.md: 2 and 3 cells move the peak
    /// by less than the target), contacts meshed at R/7.3 (coarser contacts tilt the
    /// contact normal and raise the peak: +4.9 % at R/3.7); the rest as the walled cell.
    pub fn periodic() -> Self {
        Self {
            cells: 1.0,
            contact_seeding: 1.5e-4 / 1.1e-3,
            ..Self::default()
        }
    }
}

/// A length, time or stress as the generated scenes write it (11 significant digits).
fn sci(v: f64) -> String {
    format!("{v:.10e}")
}

/// The sections both cells share, from `[simulation]` to `[contact]` (ending with the
/// friction line), and the unit of time R/c_p (s).
fn head_sections(inputs: &ThorntonInputs, mu: f64, p: &ThorntonParams) -> (String, f64) {
    let m = &inputs.material;
    let t = inputs.radius / m.dilatational_wave_speed();
    let mut extra = String::new();
    for (k, v) in &inputs.material_extra {
        extra.push_str(&format!("{k} = {v}\n"));
    }
    let text = format!(
        r#"[simulation]
duration = {duration}   # s: a cap; the stages end the run
damping = {damping}   # 1/s: mass-proportional, stage 1 (ALLVD)
target_dt = {target_dt}   # s: mass scaling of the smallest elements

[materials.{mat}]
youngs_modulus = {youngs}   # Pa
poisson_ratio = {nu}   # –
density = {rho}   # kg/m³
{extra}
[contact]
friction = {mu}
"#,
        duration = sci((p.isotropic_max_time + p.shear_max_time) * t),
        damping = sci(p.damping / t),
        target_dt = sci(p.target_dt * t),
        mat = inputs.material_name,
        youngs = sci(m.youngs_modulus),
        nu = num(m.poisson_ratio),
        rho = num(m.density),
    );
    (text, t)
}

/// The two stages around the modes `iso` (stage 1) and `shear` (stage 2) of `group`
/// (`walls` or `cell`), and the `[output]` section.
fn stage_sections(p: &ThorntonParams, t: f64, group: &str, iso: &str, shear: &str) -> String {
    format!(
        r#"[[stages]]
name = "isotropic"
{group} = {{ {iso} }}   # Pa
until = {{ stress_held = {{ tolerance = {tol}, time_constants = {hold} }}, max_time = {iso_max} }}   # –, –, s

[[stages]]
name = "shear"
damping = {shear_damping}   # 1/s: none while shearing
{group} = {{ {shear} }}
until = {{ failure = {{ drop = {drop}, strain_margin = {margin}, plateau_strain = {plateau} }}, max_time = {shear_max} }}

[output]
history_interval = {history}   # s
frame_interval = {duration}   # s: first and last frame only
"#,
        tol = num(p.tolerance),
        hold = num(p.hold),
        iso_max = sci(p.isotropic_max_time * t),
        shear_damping = sci(p.shear_damping / t),
        drop = num(p.drop),
        margin = num(p.strain_margin),
        plateau = num(p.plateau_strain),
        shear_max = sci(p.shear_max_time * t),
        history = sci(p.history_interval * t),
        duration = sci((p.isotropic_max_time + p.shear_max_time) * t),
    )
}

/// The scene text of the periodic cell at friction `mu`: an open block of n × n × n cubic
/// cells (4n³ spheres) repeated along x, y and z, no walls; stage 1 holds the cell's
/// homogenised stress at σ3 on every axis, stage 2 shortens z at the inertial number with
/// σx = σy held.
pub fn thornton_periodic_scene(inputs: &ThorntonInputs, mu: f64, p: &ThorntonParams) -> String {
    let r = inputs.radius;
    let n = p.cell_count();
    let (head, t) = head_sections(inputs, mu, p);
    let sigma = sci(inputs.confining_stress);
    let servo = format!(
        "{{ servo = {{ stress = {sigma}, periods = {} }} }}",
        p.servo_periods
    );
    let inertial = num(p.inertial_number);
    let stages = stage_sections(
        p,
        t,
        "cell",
        &format!("x = {servo}, y = {servo}, z = {servo}"),
        &format!("x = {servo}, y = {servo}, z = {{ inertial_number = {inertial} }}"),
    );
    format!(
        r#"# Periodic FCC triaxial cell of `mufe validate thornton` (src/validate/thornton_scene.rs):
# an open block of {n}×{n}×{n} cubic cells of touching spheres (R = {r} m) repeated along x,
# y and z, no walls; stage 1 isotropic compression of the cell's homogenised stress to
# σ3 = {s3} Pa, stage 2 axial shortening along z at the inertial number I = {inertial}
# with σx = σy = σ3 servo-held, to failure. Generated for the material, radius and σ3 of
# the case scene; every other number is dimensionless in R, R/c_p and c_p/R
# (docs/PERIODIC.md).

{head}
[[packings]]
name = "cell"
lattice = "fcc"
cells = [{n}, {n}, {n}]
faces = "open"
material = "{mat}"
sphere = {{ radius = {r}, seeding = {seeding}, contact_seeding = {contact_seeding} }}   # m

[cell]
packing = "cell"   # the box is the lattice period

{stages}"#,
        s3 = num(inputs.confining_stress),
        r = sci(r),
        mat = inputs.material_name,
        seeding = sci(p.seeding * r),
        contact_seeding = sci(p.contact_seeding * r),
    )
}

/// The scene text of the cell at friction `mu`.
pub fn thornton_walls_scene(inputs: &ThorntonInputs, mu: f64, p: &ThorntonParams) -> String {
    let r = inputs.radius;
    let n = p.cell_count();
    let a = 2.0 * std::f64::consts::SQRT_2 * r;
    let (lo, hi) = (-r, n as f64 * a + r);
    let (head, t) = head_sections(inputs, mu, p);
    let sigma = sci(inputs.confining_stress);
    let periods = p.servo_periods;
    let servo =
        format!("{{ servo = {{ stress = {sigma}, area_of = \"cell\", periods = {periods} }} }}");
    let lateral = format!("x_min = {servo}, x_max = {servo}, y_min = {servo}, y_max = {servo}");
    let inertial = num(p.inertial_number);
    let stages = stage_sections(
        p,
        t,
        "walls",
        &format!("{lateral}, top = {servo}"),
        &format!("{lateral}, top = {{ inertial_number = {inertial} }}"),
    );
    let walls: String = [
        ("x_min", [lo, 0.0, 0.0], [1.0, 0.0, 0.0]),
        ("x_max", [hi, 0.0, 0.0], [-1.0, 0.0, 0.0]),
        ("y_min", [0.0, lo, 0.0], [0.0, 1.0, 0.0]),
        ("y_max", [0.0, hi, 0.0], [0.0, -1.0, 0.0]),
        ("bottom", [0.0, 0.0, lo], [0.0, 0.0, 1.0]),
        ("top", [0.0, 0.0, hi], [0.0, 0.0, -1.0]),
    ]
    .iter()
    .map(|(name, point, normal)| {
        format!(
            "[[walls]]\nname = \"{name}\"\npoint = [{}, {}, {}]   # m\nnormal = [{:.1}, {:.1}, {:.1}]\n\n",
            sci(point[0]),
            sci(point[1]),
            sci(point[2]),
            normal[0],
            normal[1],
            normal[2]
        )
    })
    .collect();
    format!(
        r#"# Walled FCC triaxial cell of `mufe validate thornton_walls` (src/validate/thornton_scene.rs):
# a closed block of {n}×{n}×{n} cubic cells of touching spheres (R = {r} m) between six rigid
# frictionless walls; stage 1 isotropic compression to σ3 = {s3} Pa, stage 2 axial loading at
# the inertial number I = {inertial} with σ2 = σ3 servo-held, to failure. Generated for the
# material, radius and σ3 of the case scene; every other number is dimensionless in
# R, R/c_p and c_p/R (docs/THEORY.md §9).

{head}
[[packings]]
name = "cell"
lattice = "fcc"
cells = [{n}, {n}, {n}]
faces = "closed"
material = "{mat}"
sphere = {{ radius = {r}, seeding = {seeding}, contact_seeding = {contact_seeding}, axis_patches = true }}   # m

{walls}{stages}"#,
        s3 = num(inputs.confining_stress),
        r = sci(r),
        mat = inputs.material_name,
        seeding = sci(p.seeding * r),
        contact_seeding = sci(p.contact_seeding * r),
    )
}
