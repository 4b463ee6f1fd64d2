//! `[[stages]]`: a run as a sequence of loading stages, each with its wall modes and the
//! condition that ends it (the walled triaxial test: isotropic compression, then axial
//! strain at constant lateral stress).
//!
//! ```toml
//! [[stages]]
//! name = "isotropic"
//! walls = { top = { servo = { stress = 5.0e4, area_of = "cell" } }, x_min = ... }
//! until = { stress_held = { tolerance = 0.01, time_constants = 3.0 }, max_time = 2.0e-3 }
//!
//! [[stages]]
//! name = "shear"
//! walls = { top = { strain_rate = 20.0 }, x_min = { servo = { stress = 5.0e4, area_of = "cell" } }, ... }
//! until = { failure = { drop = 0.05, strain_margin = 2.0e-3 }, axial_strain = 0.02, max_time = 2.0e-3 }
//! ```
//! Walls not listed in a stage are fixed. The run ends when the last stage ends (or at
//! `simulation.duration`, whichever comes first).

use super::checker::{validate_servo, Checker};
use super::{normal_axis, Scene, ServoSpec};
use crate::error::{echo, InputError};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// One loading stage.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StageSpec {
    /// Shown in the progress line and the summary; an identifier.
    pub name: String,
    /// Mode of each wall by wall name; walls not listed are fixed during the stage.
    #[serde(default)]
    pub walls: BTreeMap<String, WallModeSpec>,
    /// Mode of each periodic cell axis (`x`, `y`, `z`) in the same terms as a wall's:
    /// shortening of the axis instead of the wall's advance, the cell's homogenised stress
    /// instead of the wall's (`crate::boundary::stages`); axes not listed are fixed.
    #[serde(default)]
    pub cell: BTreeMap<String, WallModeSpec>,
    /// What ends the stage.
    pub until: UntilSpec,
    /// Mass-proportional damping during the stage (1/s), in place of
    /// `simulation.damping`: e.g. damping to settle a consolidation stage, none while
    /// shearing (it drags the moving grains and biases the failure).
    #[serde(default)]
    pub damping: Option<f64>,
    /// Gravity during the stage (m/s²), in place of `simulation.gravity`: e.g. a
    /// deposit under a few tens of g, so loose grains settle in a fraction of the time
    /// 1 g takes, before the loading stages run under 1 g.
    #[serde(default)]
    pub gravity: Option<[f64; 3]>,
}

/// How a wall moves during a stage (along its normal; positive = towards the grains).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum WallModeSpec {
    /// Held where it is.
    Fixed,
    /// Stress-controlled, as a wall's own `servo` (see `crate::boundary::servo`).
    Servo(ServoSpec),
    /// Constant speed towards the grains (m/s).
    Velocity(f64),
    /// Constant speed towards the grains of `rate × L0` (1/s), L0 the wall's distance at
    /// t = 0 to the opposite wall (the wall on the same axis facing it): with one moving
    /// wall on an axis, `rate` is that axis' nominal strain rate.
    StrainRate(f64),
    /// Strain rate given by the inertial number I = ε̇ d √(ρ/p) (–): d the diameter and ρ
    /// the density of the spheres of the cell's packing, p the largest servo stress of
    /// the stage. I ≲ 10⁻³ is the quasi-static regime of granular flow; the same I
    /// loads any material and grain size alike.
    InertialNumber(f64),
}

/// End conditions of a stage: it ends when any given condition is met, and at the
/// latest after `max_time`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UntilSpec {
    /// Longest duration of the stage (s).
    pub max_time: f64,
    /// Every stress-controlled wall of the stage within `tolerance` of its target,
    /// continuously for `time_constants` × the largest servo time constant of the stage.
    #[serde(default)]
    pub stress_held: Option<HeldSpec>,
    /// Nominal strain (–, compression positive) of the axis of the stage's moving walls,
    /// counted from the start of the stage.
    #[serde(default)]
    pub axial_strain: Option<f64>,
    /// Failure: the stress ratio σ_axial/σ_lateral has fallen `drop` (relative) below its
    /// peak in this stage, or (with `plateau_strain`) has not risen by 1 % over that much
    /// axial strain (steady sliding without softening); the stage then goes on for
    /// `strain_margin` more axial strain.
    #[serde(default)]
    pub failure: Option<FailureSpec>,
    /// The normal force of a wall (low-pass filtered like the servo's) has reached `force`:
    /// e.g. a wall driven at a constant speed packs loose grains until the opposite wall
    /// carries load.
    #[serde(default)]
    pub wall_force: Option<WallForceSpec>,
}

/// See [`UntilSpec::wall_force`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WallForceSpec {
    /// Name of the wall.
    pub wall: String,
    /// Normal force (N), > 0, compressive (the wall pushing on the grains).
    pub force: f64,
    /// Time the force must stay at or above `force` (s), default 0: an impact's spike
    /// does not end the stage, a wall that keeps pushing does.
    #[serde(default)]
    pub hold: f64,
}

/// See [`UntilSpec::stress_held`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HeldSpec {
    /// Relative stress error bound (–), e.g. 0.01.
    pub tolerance: f64,
    /// Hold time in servo time constants (–).
    #[serde(default = "default_hold_time_constants")]
    pub time_constants: f64,
}

fn default_hold_time_constants() -> f64 {
    2.0
}

/// See [`UntilSpec::failure`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FailureSpec {
    /// Relative drop of the stress ratio below its peak that counts as failure (–).
    pub drop: f64,
    /// Axial strain run on after failure is detected (–).
    #[serde(default)]
    pub strain_margin: f64,
    /// Axial strain over which a ratio that has not risen by 1 % counts as failure (–).
    #[serde(default)]
    pub plateau_strain: Option<f64>,
}

/// The lower and upper wall of each coordinate axis: the wall whose normal is +eₖ and the
/// one whose normal is −eₖ (indices into `scene.walls`), when both exist.
pub fn wall_pairs(scene: &Scene) -> [Option<(usize, usize)>; 3] {
    let along = |k: usize, sign: f64| {
        scene
            .walls
            .iter()
            .position(|w| normal_axis(w.normal) == Some(k) && w.normal[k].signum() == sign)
    };
    [0, 1, 2].map(|k| along(k, 1.0).zip(along(k, -1.0)))
}

/// Axis (0..3) a wall's normal lies along, and whether the axis has an opposite wall.
fn opposite_exists(scene: &Scene, wall: usize) -> bool {
    normal_axis(scene.walls[wall].normal)
        .is_some_and(|k| wall_pairs(scene)[k].is_some_and(|(lo, hi)| lo == wall || hi == wall))
}

pub(super) fn validate_stages(c: &Checker, scene: &Scene) -> Result<(), InputError> {
    let pairs = wall_pairs(scene);
    let cell = pairs.iter().all(|p| p.is_some());
    let periodic_box = scene
        .cell
        .as_ref()
        .is_some_and(|c| c.periodic.iter().all(|&p| p));
    for (i, st) in scene.stages.iter().enumerate() {
        let f = |x: &str| format!("stages[{i}].{x}");
        c.identifier(&f("name"), &st.name)?;
        if scene.stages[..i].iter().any(|o| o.name == st.name) {
            return Err(c.err(
                f("name"),
                format!("duplicate stage name '{}'", echo(&st.name)),
            ));
        }
        let mut moving_axes = Vec::new();
        for (name, mode) in &st.walls {
            let field = f(&format!("walls.{name}"));
            let Some(w) = scene.walls.iter().position(|w| &w.name == name) else {
                return Err(c.err(field, format!("no wall named '{}'", echo(name))));
            };
            let wall = &scene.walls[w];
            match mode {
                WallModeSpec::Fixed => {}
                WallModeSpec::Servo(s) => {
                    validate_servo(c, scene, &format!("{field}.servo"), wall, s)?
                }
                WallModeSpec::Velocity(v) => {
                    c.finite(&format!("{field}.velocity"), *v)?;
                    moving_axes.push((normal_axis(wall.normal), field.clone()));
                }
                WallModeSpec::InertialNumber(i) => {
                    c.positive(&format!("{field}.inertial_number"), *i)?;
                    if scene.packings.is_empty()
                        || !st
                            .walls
                            .values()
                            .any(|m| matches!(m, WallModeSpec::Servo(_)))
                        || !opposite_exists(scene, w)
                    {
                        return Err(c.err(
                            format!("{field}.inertial_number"),
                            "needs a packing (for d and ρ), a servo wall in the stage (for p) and an opposite wall (for L0); use strain_rate instead",
                        ));
                    }
                    moving_axes.push((normal_axis(wall.normal), field.clone()));
                }
                WallModeSpec::StrainRate(r) => {
                    c.finite(&format!("{field}.strain_rate"), *r)?;
                    if !opposite_exists(scene, w) {
                        return Err(c.err(
                            format!("{field}.strain_rate"),
                            "needs the wall's normal along a coordinate axis and an opposite wall (normal reversed) to measure L0 against; use velocity instead",
                        ));
                    }
                    moving_axes.push((normal_axis(wall.normal), field.clone()));
                }
            }
        }
        let stage_servo = st
            .walls
            .values()
            .chain(st.cell.values())
            .any(|m| matches!(m, WallModeSpec::Servo(_)));
        for (name, mode) in &st.cell {
            let field = f(&format!("cell.{name}"));
            let k = crate::scene::cell::AXES.iter().position(|a| a == name);
            match mode {
                WallModeSpec::Fixed => {}
                WallModeSpec::Servo(s) => {
                    validate_cell_servo(c, scene, &format!("{field}.servo"), s)?
                }
                WallModeSpec::Velocity(v) => c.finite(&format!("{field}.velocity"), *v)?,
                WallModeSpec::StrainRate(r) => c.finite(&format!("{field}.strain_rate"), *r)?,
                WallModeSpec::InertialNumber(i) => {
                    c.positive(&format!("{field}.inertial_number"), *i)?;
                    if scene.packings.is_empty() || !stage_servo {
                        return Err(c.err(
                            format!("{field}.inertial_number"),
                            "needs a packing (for d and ρ) and a servo-held axis in the stage (for p); use strain_rate instead",
                        ));
                    }
                }
            }
            if !matches!(mode, WallModeSpec::Fixed | WallModeSpec::Servo(_)) {
                moving_axes.push((k, field.clone()));
            }
        }
        let u = &st.until;
        c.positive(&f("until.max_time"), u.max_time)?;
        if let Some(g) = &st.gravity {
            c.vec3(&f("gravity"), g)?;
        }
        if let Some(d) = st.damping {
            c.non_negative(&f("damping"), d)?;
        }
        if let Some(h) = &u.stress_held {
            c.positive(&f("until.stress_held.tolerance"), h.tolerance)?;
            c.non_negative(&f("until.stress_held.time_constants"), h.time_constants)?;
            if !stage_servo {
                return Err(c.err(
                    f("until.stress_held"),
                    "the stage has no servo wall whose stress could be held",
                ));
            }
        }
        let axis_needed = u.axial_strain.is_some() || u.failure.is_some();
        if axis_needed {
            let axes: Vec<Option<usize>> = moving_axes.iter().map(|(a, _)| *a).collect();
            if axes.is_empty() || axes.iter().any(|a| a.is_none() || *a != axes[0]) {
                return Err(c.err(
                    f("until"),
                    "axial_strain and failure need the stage's moving walls or cell axes (velocity, strain_rate or inertial_number) on one coordinate axis, which is then the axial direction",
                ));
            }
            let k = axes[0].unwrap_or(2);
            if pairs[k].is_none() && !periodic_box {
                return Err(c.err(
                    f("until"),
                    "axial_strain and failure need a pair of opposite walls (or a periodic cell) on the axial axis to measure the strain",
                ));
            }
        }
        if let Some(e) = u.axial_strain {
            c.positive(&f("until.axial_strain"), e)?;
        }
        if let Some(wf) = &u.wall_force {
            c.positive(&f("until.wall_force.force"), wf.force)?;
            c.non_negative(&f("until.wall_force.hold"), wf.hold)?;
            if !scene.walls.iter().any(|w| w.name == wf.wall) {
                return Err(c.err(
                    f("until.wall_force.wall"),
                    format!("no wall named '{}'", echo(&wf.wall)),
                ));
            }
        }
        if let Some(fl) = &u.failure {
            c.positive(&f("until.failure.drop"), fl.drop)?;
            c.non_negative(&f("until.failure.strain_margin"), fl.strain_margin)?;
            if let Some(pl) = fl.plateau_strain {
                c.positive(&f("until.failure.plateau_strain"), pl)?;
            }
            if fl.drop >= 1.0 {
                return Err(c.err(
                    f("until.failure.drop"),
                    "must be < 1 (a fraction of the peak)",
                ));
            }
            if !cell && !periodic_box {
                return Err(c.err(
                    f("until.failure"),
                    "needs a closed box of walls (a pair of opposite walls on each coordinate axis) or a cell periodic along every axis to measure the stress ratio",
                ));
            }
        }
    }
    Ok(())
}

/// Checks the servo of a cell axis: it acts on the cell's face, so no area is given.
fn validate_cell_servo(
    c: &Checker,
    scene: &Scene,
    prefix: &str,
    s: &ServoSpec,
) -> Result<(), InputError> {
    if s.area.is_some() || s.area_of.is_some() {
        return Err(c.err(
            format!("{prefix}.area"),
            "a cell axis holds the cell's homogenised stress on its current face; give no area or area_of",
        ));
    }
    let probe = crate::scene::WallSpec {
        name: String::new(),
        point: [0.0; 3],
        normal: [0.0, 0.0, 1.0],
        friction: 0.0,
        velocity: None,
        displacement: None,
        servo: None,
    };
    let with_area = ServoSpec {
        area: Some(1.0),
        ..s.clone()
    };
    validate_servo(c, scene, prefix, &probe, &with_area)
}
