//! Scene files: TOML parsed with serde (`deny_unknown_fields`), `--set PATH=VALUE`
//! overrides applied to the TOML tree before typing (so they get the same validation),
//! and semantic checks that name the offending field. SI units throughout.

pub mod estimate;
mod overrides;
mod validate;

pub use overrides::apply_override;

use crate::error::InputError;
use crate::mesh::SphereMeshSpec;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

/// A whole scene as run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    pub simulation: Simulation,
    /// Materials by name.
    #[serde(default)]
    pub materials: BTreeMap<String, MaterialSpec>,
    #[serde(default)]
    pub grains: Vec<GrainSpec>,
    /// Prescribed motions of node sets.
    #[serde(default)]
    pub boundaries: Vec<BoundarySpec>,
    /// Grain–grain contact settings (`[contact]`); defaults apply when absent.
    #[serde(default)]
    pub contact: ContactSpec,
    /// Rigid plane walls (`[[walls]]`).
    #[serde(default)]
    pub walls: Vec<WallSpec>,
    #[serde(default)]
    pub output: OutputSpec,
    #[serde(default)]
    pub parallel: ParallelSpec,
}

/// Load balancing under MPI (ignored on one rank).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ParallelSpec {
    /// Re-partition when the load imbalance (max/mean − 1 of the ranks' counted work per
    /// step: elements and contact candidate entries) exceeds this (–).
    #[serde(default = "default_imbalance_threshold")]
    pub imbalance_threshold: f64,
    /// Steps between imbalance checks and ghost re-planning checks.
    #[serde(default = "default_check_interval")]
    pub check_interval: u64,
}

impl Default for ParallelSpec {
    fn default() -> Self {
        Self {
            imbalance_threshold: default_imbalance_threshold(),
            check_interval: default_check_interval(),
        }
    }
}

fn default_imbalance_threshold() -> f64 {
    0.2
}

fn default_check_interval() -> u64 {
    500
}

/// Time integration settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Simulation {
    /// Simulated time (s).
    pub duration: f64,
    /// Fraction of the critical time step used (–), 0 < f ≤ 1.
    #[serde(default = "default_dt_safety")]
    pub dt_safety: f64,
    /// Target time step for mass scaling (s): elements whose stable step is smaller get
    /// their density scaled up to reach it; the added mass is reported.
    #[serde(default)]
    pub target_dt: Option<f64>,
    /// Fixed time step (s), overriding the computed stable step (must not exceed it).
    #[serde(default)]
    pub dt: Option<f64>,
    /// Mass-proportional damping coefficient α (1/s): f = −α m v. Its dissipation is
    /// accounted as `damping_dissipation`.
    #[serde(default)]
    pub damping: f64,
    /// Mass-proportional damping of the velocity relative to each grain's rigid-body motion
    /// (1/s): removes vibration without a net force or moment on any grain, so quasi-static
    /// runs settle without biasing reaction forces. Accounted in `damping_dissipation`.
    #[serde(default)]
    pub deformation_damping: f64,
    /// Body acceleration (m/s²).
    #[serde(default)]
    pub gravity: [f64; 3],
}

fn default_dt_safety() -> f64 {
    0.9
}

/// Grain material: elastic, or elastic–plastic (J2, linear isotropic hardening) when
/// `yield_stress` is given.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialSpec {
    /// Young's modulus E (Pa).
    pub youngs_modulus: f64,
    /// Poisson's ratio ν (–).
    pub poisson_ratio: f64,
    /// Density ρ (kg/m³).
    pub density: f64,
    /// Elastic law: `biot` (default; Hooke's law in the Biot strain to second order),
    /// `st_venant_kirchhoff` or `corotational` (exact polar decomposition; slower).
    #[serde(default)]
    pub law: crate::material::ElasticLawKind,
    /// Initial von Mises yield stress σy (Pa); makes the material elastic–plastic.
    #[serde(default)]
    pub yield_stress: Option<f64>,
    /// Linear isotropic hardening modulus H (Pa): flow stress σy + H·α, α the equivalent
    /// plastic strain (default 0: perfectly plastic).
    #[serde(default)]
    pub hardening_modulus: Option<f64>,
}

/// One grain: a material, a shape to mesh, and its initial placement and motion.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GrainSpec {
    /// Name used by boundary conditions and reports (default `grain<i>`).
    #[serde(default)]
    pub name: Option<String>,
    /// Key into `materials`.
    pub material: String,
    pub shape: ShapeSpec,
    /// Position of the shape's origin (m).
    #[serde(default)]
    pub centre: [f64; 3],
    /// Initial rigid translation velocity (m/s).
    #[serde(default)]
    pub velocity: [f64; 3],
    /// Initial rigid angular velocity about `centre` (rad/s).
    #[serde(default)]
    pub angular_velocity: [f64; 3],
}

/// Shape of a grain, meshed at set-up.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum ShapeSpec {
    /// Sphere mesher (uniform, graded, locally refined), centred on the grain's origin.
    Sphere(SphereMeshSpec),
    /// Structured box split into tetrahedra, spanning [0, size] from the grain's origin.
    Block(BlockSpec),
}

/// A rectangular block meshed as nx×ny×nz cubes, each split into 6 tetrahedra.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BlockSpec {
    /// Edge lengths (m).
    pub size: [f64; 3],
    /// Cells along each edge.
    pub divisions: [usize; 3],
}

/// Which nodes of a grain a boundary condition drives (coordinates at t = 0, world frame).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum NodeSelector {
    /// Every node of the grain.
    All,
    /// Nodes with (x − point)·normal ≥ 0.
    BeyondPlane { point: [f64; 3], normal: [f64; 3] },
    /// Nodes farther than `distance` (m) from `point` (e.g. far from a contact).
    FartherThan { point: [f64; 3], distance: f64 },
    /// Nodes within `distance` (m) of `point`.
    Within { point: [f64; 3], distance: f64 },
}

/// A piecewise-linear vector history, held at its last value after the last time.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct History3 {
    /// Strictly increasing times (s), first ≥ 0.
    pub times: Vec<f64>,
    /// One value per time (units of the quantity).
    pub values: Vec<[f64; 3]>,
}

/// A prescribed motion of a node set of one grain: rigid (translation + rotation about a
/// moving centre) or, with `components`, only some translation components.
/// The reaction force and moment are recorded in `/history/<name>_*`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoundarySpec {
    /// Used for history columns, e.g. `top_force_z`.
    pub name: String,
    /// Grain name.
    pub grain: String,
    pub select: NodeSelector,
    /// Translation velocity history (m/s). Exactly one of velocity/displacement, or
    /// neither (held fixed).
    #[serde(default)]
    pub velocity: Option<History3>,
    /// Translation displacement history (m).
    #[serde(default)]
    pub displacement: Option<History3>,
    /// Angular velocity history (rad/s) about `centre` (rigid motions only).
    #[serde(default)]
    pub angular_velocity: Option<History3>,
    /// Centre of rotation at t = 0 (m); default: centroid of the selected nodes.
    #[serde(default)]
    pub centre: Option<[f64; 3]>,
    /// Prescribe only these translation components (others stay free). Absent: all
    /// three, plus rotation.
    #[serde(default)]
    pub components: Option<[bool; 3]>,
}

/// Contact between grain surfaces (`[contact]`). Grains always interact through their
/// surfaces; this table only tunes how. See `crate::contact` for the method.
///
/// ```toml
/// [contact]
/// friction = 0.22        # Coulomb μ between grains (default 0: frictionless)
/// penalty_factor = 20.0  # ε_n = factor × E'/h (default `contact::DEFAULT_PENALTY_FACTOR`)
/// margin = 5e-6          # broad-phase margin (m); default ½ × smallest surface edge
/// damping = 0.05         # normal contact damping, fraction of critical (default 0.05)
/// ```
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ContactSpec {
    /// Coulomb friction coefficient μ between grains (–), ≥ 0.
    #[serde(default)]
    pub friction: f64,
    /// Penalty stiffness factor (–), > 0: ε_n = factor · E' / h with E' = E/(1−ν²) of the
    /// stiffer side and h the local surface edge length. Default
    /// [`crate::contact::DEFAULT_PENALTY_FACTOR`].
    #[serde(default)]
    pub penalty_factor: Option<f64>,
    /// Broad-phase margin (m), > 0: candidate lists are rebuilt when a surface node has
    /// moved more than margin/2. Default ½ × the smallest surface edge of the scene.
    #[serde(default)]
    pub margin: Option<f64>,
    /// Normal contact damping as a fraction ζ of the critical damping of each contact
    /// point's penalty spring (–), 0 ≤ ζ ≤ 1. It suppresses node-level chatter; its
    /// dissipation is reported in ALLVD. Default [`crate::contact::DEFAULT_CONTACT_DAMPING`].
    #[serde(default)]
    pub damping: Option<f64>,
}

/// A rigid plane wall (`[[walls]]`), enforced kinematically (grains land exactly on it).
/// Its force on the grains and its displacement are recorded in
/// `/history/<name>_force_{x,y,z}` and `/history/<name>_displacement_{x,y,z}`.
///
/// ```toml
/// [[walls]]
/// name = "bottom"
/// point = [0.0, 0.0, 0.0]
/// normal = [0.0, 0.0, 1.0]   # points into the region where the grains are
/// friction = 0.0
/// velocity = { times = [0.0], values = [[0.0, 0.0, 0.0]] }
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WallSpec {
    /// Used for history columns, e.g. `bottom_force_z`.
    pub name: String,
    /// A point of the plane at t = 0 (m).
    pub point: [f64; 3],
    /// Plane normal pointing into the region where the grains are (normalised on use).
    pub normal: [f64; 3],
    /// Coulomb friction coefficient μ between wall and grains (–), default 0.
    #[serde(default)]
    pub friction: f64,
    /// Translation velocity history (m/s). At most one of velocity/displacement; neither
    /// means the wall is fixed.
    #[serde(default)]
    pub velocity: Option<History3>,
    /// Translation displacement history (m).
    #[serde(default)]
    pub displacement: Option<History3>,
}

/// What is written and how often.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputSpec {
    /// Interval between `/history` rows (s); default: duration/1000.
    #[serde(default)]
    pub history_interval: Option<f64>,
    /// Interval between `/frames` snapshots (s); absent: first and last frame only.
    #[serde(default)]
    pub frame_interval: Option<f64>,
    /// Write field snapshots at all.
    #[serde(default = "default_true")]
    pub frames: bool,
}

impl Default for OutputSpec {
    fn default() -> Self {
        Self {
            history_interval: None,
            frame_interval: None,
            frames: true,
        }
    }
}

fn default_true() -> bool {
    true
}

/// Scene text plus its parsed form.
#[derive(Debug, Clone)]
pub struct LoadedScene {
    pub path: String,
    /// TOML text after overrides, as run (stored in `/scene`).
    pub text: String,
    pub scene: Scene,
}

/// Reads, overrides, parses and validates a scene file.
pub fn load_scene(path: &Path, overrides: &[String]) -> Result<LoadedScene, InputError> {
    let file = path.display().to_string();
    let text = std::fs::read_to_string(path)
        .map_err(|e| InputError::new(&file, "file", format!("cannot read the scene: {e}")))?;
    parse_scene(&file, &text, overrides)
}

/// Parses scene text (with `--set` overrides) into a validated [`LoadedScene`].
pub fn parse_scene(
    file: &str,
    text: &str,
    overrides: &[String],
) -> Result<LoadedScene, InputError> {
    let table: toml::Table = toml::from_str(text).map_err(|e| {
        let msg = e.message().replace('\n', " ");
        let line = e
            .span()
            .map(|s| text[..s.start.min(text.len())].lines().count().max(1));
        InputError::new(
            file,
            line.map_or_else(|| "scene".to_string(), |l| format!("line {l}")),
            format!("invalid TOML: {msg}"),
        )
    })?;
    let mut value = toml::Value::Table(table);
    for o in overrides {
        check_override_text(o)?;
        apply_override(&mut value, o)
            .map_err(|m| InputError::new("<command line>", format!("--set {o}"), m))?;
    }
    let scene: Scene = serde_path_to_error::deserialize(value.clone())
        .map_err(|e| {
            let path = e.path().to_string();
            let inner = e.into_inner().message().replace('\n', " ");
            serde_error(file, &path, &inner)
        })
        .map_err(|e| blame_override(e, overrides))?;
    validate::validate_scene(file, &scene).map_err(|e| blame_override(e, overrides))?;
    let text = if overrides.is_empty() {
        text.to_string()
    } else {
        toml::to_string(&value).unwrap_or_else(|_| text.to_string())
    };
    Ok(LoadedScene {
        path: file.to_string(),
        text,
        scene,
    })
}

/// A `--set` argument must be one line of printable text: a newline would silently cut
/// the value (TOML stops at it) and control characters cannot be meant.
fn check_override_text(o: &str) -> Result<(), InputError> {
    if let Some(c) = o.chars().find(|c| c.is_control()) {
        let path = o.split_once('=').map_or(o, |(p, _)| p);
        let what = match c {
            '\n' | '\r' => "a line break".to_string(),
            '\t' => "a tab".to_string(),
            c => format!("the control character U+{:04X}", c as u32),
        };
        return Err(InputError::new(
            "<command line>",
            format!("--set {}", crate::error::echo(path.trim())),
            format!("the argument contains {what}; give one value on one line"),
        ));
    }
    Ok(())
}

/// The one-line error for a serde failure at `path` (`.` = the top level): a missing
/// field is named as the field itself (`simulation`, `grains[0].material`).
fn serde_error(file: &str, path: &str, message: &str) -> InputError {
    let parent = if path == "." { "" } else { path };
    if let Some(rest) = message.strip_prefix("missing field `") {
        if let Some(name) = rest.split('`').next() {
            let item = if parent.is_empty() {
                name.to_string()
            } else {
                format!("{parent}.{name}")
            };
            return InputError::new(file, item, "required field is missing");
        }
    }
    let item = if parent.is_empty() { "scene" } else { parent };
    InputError::new(file, item, message)
}

/// When the field an error names was set (or replaced) by a `--set`, says so: the value
/// in the message is then not the one in the file.
fn blame_override(mut e: InputError, overrides: &[String]) -> InputError {
    let Some(item) = overrides::path_segments(&e.item) else {
        return e;
    };
    let culprit = overrides.iter().rev().find(|o| {
        let path = o.split_once('=').map_or(o.as_str(), |(p, _)| p).trim();
        overrides::path_segments(path).is_some_and(|set| {
            let n = set.len().min(item.len());
            n > 0 && set[..n] == item[..n]
        })
    });
    if let Some(o) = culprit {
        e.message = format!("{} (value from --set {o})", e.message);
    }
    e
}

impl GrainSpec {
    /// The grain's name (`grain<i>` when unnamed).
    pub fn display_name(&self, index: usize) -> String {
        self.name.clone().unwrap_or_else(|| format!("grain{index}"))
    }
}
