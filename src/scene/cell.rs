//! `[cell]`: a periodic cell. Along each periodic axis a grain near one face touches the
//! periodic images of the grains near the opposite face, so the assembly has no
//! boundary there (docs/PERIODIC.md).
//!
//! ```toml
//! [cell]
//! packing = "fcc"                  # the box is the lattice period of an open FCC packing
//! # or: min = [0.0, 0.0, 0.0], max = [4e-3, 4e-3, 4e-3]   # m
//! periodic = [true, true, true]    # default
//! ```
//! The stages drive the periodic axes (`[[stages]] cell = { x = …, y = …, z = … }`) with
//! the same modes as walls: a servo on the cell's homogenised stress, a strain rate, an
//! inertial number, a velocity or fixed.

use super::checker::Checker;
use super::packing::Faces;
use super::{Scene, ShapeSpec};
use crate::error::{echo, num, InputError};
use serde::{Deserialize, Serialize};

/// The periodic cell of a scene.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CellSpec {
    /// Which axes are periodic (x, y, z).
    #[serde(default = "all_axes")]
    pub periodic: [bool; 3],
    /// Name of an open FCC packing whose lattice period is the box: cells × a per axis,
    /// starting a/4 below its first sphere centre. Not with `min`/`max`.
    #[serde(default)]
    pub packing: Option<String>,
    /// Lower and upper corner of the box (m).
    #[serde(default)]
    pub min: Option<[f64; 3]>,
    #[serde(default)]
    pub max: Option<[f64; 3]>,
}

fn all_axes() -> [bool; 3] {
    [true; 3]
}

/// The periodic box of a scene at t = 0 (`crate::model::periodic` adds its images and
/// shifts; the stages read its lengths).
#[derive(Debug, Clone, PartialEq)]
pub struct PeriodicBox {
    pub periodic: [bool; 3],
    /// Lower corner of the box (m): fixed, the box deforms about it.
    pub min: [f64; 3],
    /// Edge lengths at t = 0 (m).
    pub length0: [f64; 3],
}

impl PeriodicBox {
    pub fn of_scene(scene: &Scene) -> Option<Self> {
        let spec = scene.cell.as_ref()?;
        let (min, length0) = spec.box_of(scene);
        Some(Self {
            periodic: spec.periodic,
            min,
            length0,
        })
    }
}

/// Names of the cell axes in `[[stages]] cell = { … }` and history columns.
pub const AXES: [&str; 3] = ["x", "y", "z"];

impl CellSpec {
    /// Lower corner and edge lengths of the box at t = 0 (m), from `packing` or
    /// `min`/`max` (the scene is validated).
    pub fn box_of(&self, scene: &Scene) -> ([f64; 3], [f64; 3]) {
        if let (Some(lo), Some(hi)) = (self.min, self.max) {
            return (lo, [0, 1, 2].map(|k| hi[k] - lo[k]));
        }
        let name = self.packing.as_deref().unwrap_or_default();
        let Some(p) = scene.packings.iter().find(|p| p.name == name) else {
            return ([0.0; 3], [0.0; 3]);
        };
        let a = p.lattice_constant();
        (
            [0, 1, 2].map(|k| p.origin[k] - 0.25 * a),
            [0, 1, 2].map(|k| p.cells[k] as f64 * a),
        )
    }
}

/// Largest bounding radius of a grain of the scene (m): a grain must not reach its own
/// image across the box.
fn largest_grain_radius(scene: &Scene) -> f64 {
    scene
        .grains
        .iter()
        .map(|g| match &g.shape {
            ShapeSpec::Sphere(s) => s.radius,
            ShapeSpec::Block(b) => 0.5 * b.size.iter().map(|s| s * s).sum::<f64>().sqrt(),
            ShapeSpec::Surface(s) => s.geometry.as_ref().map_or(0.0, |x| x.bounding_radius),
        })
        .fold(0.0, f64::max)
}

pub(super) fn validate_cell(c: &Checker, scene: &Scene) -> Result<(), InputError> {
    let Some(cell) = &scene.cell else {
        for (i, st) in scene.stages.iter().enumerate() {
            if !st.cell.is_empty() {
                return Err(c.err(
                    format!("stages[{i}].cell"),
                    "the scene has no [cell]; cell axes can only be driven in a periodic cell",
                ));
            }
        }
        return Ok(());
    };
    if !cell.periodic.iter().any(|&p| p) {
        return Err(c.err("cell.periodic", "no axis is periodic"));
    }
    match (&cell.packing, cell.min, cell.max) {
        (Some(name), None, None) => {
            let Some(p) = scene.packings.iter().find(|p| &p.name == name) else {
                return Err(c.err("cell.packing", format!("no packing named '{}'", echo(name))));
            };
            if p.faces != Faces::Open {
                return Err(c.err(
                    "cell.packing",
                    format!(
                        "packing '{}' has closed faces: its opposite faces repeat one lattice plane, which a periodic cell would double; use faces = \"open\"",
                        echo(name)
                    ),
                ));
            }
        }
        (None, Some(lo), Some(hi)) => {
            c.vec3("cell.min", &lo)?;
            c.vec3("cell.max", &hi)?;
            if let Some(k) = (0..3).find(|&k| hi[k] <= lo[k]) {
                return Err(c.err(
                    format!("cell.max[{k}]"),
                    format!("must be > cell.min[{k}] = {}", num(lo[k])),
                ));
            }
        }
        _ => {
            return Err(c.err(
                "cell",
                "give either packing (an open FCC packing) or both min and max (m)",
            ))
        }
    }
    let (lo, length) = cell.box_of(scene);
    let reach = largest_grain_radius(scene);
    for k in (0..3).filter(|&k| cell.periodic[k]) {
        if length[k] <= 2.0 * reach {
            return Err(c.err(
                "cell",
                format!(
                    "the box is {} m long along {}, not more than a grain's diameter ({} m): a grain would touch its own image",
                    num(length[k]),
                    AXES[k],
                    num(2.0 * reach)
                ),
            ));
        }
        for (i, g) in scene.grains.iter().enumerate() {
            if !(lo[k]..lo[k] + length[k]).contains(&g.centre[k]) {
                return Err(c.err(
                    format!("grains[{i}].centre"),
                    format!(
                        "lies outside the periodic cell along {} ([{}, {}) m)",
                        AXES[k],
                        num(lo[k]),
                        num(lo[k] + length[k])
                    ),
                ));
            }
        }
        if let Some(w) = scene
            .walls
            .iter()
            .position(|w| w.normal[k] != 0.0 && (0..3).all(|j| j == k || w.normal[j] == 0.0))
        {
            return Err(c.err(
                format!("walls[{w}].normal"),
                format!(
                    "is along the periodic axis {}: a periodic axis has no boundary to put a wall on",
                    AXES[k]
                ),
            ));
        }
    }
    for (i, st) in scene.stages.iter().enumerate() {
        for name in st.cell.keys() {
            let Some(k) = AXES.iter().position(|a| a == name) else {
                return Err(c.err(
                    format!("stages[{i}].cell.{name}"),
                    "unknown cell axis; use x, y or z",
                ));
            };
            if !cell.periodic[k] {
                return Err(c.err(
                    format!("stages[{i}].cell.{name}"),
                    format!("axis {name} is not periodic (cell.periodic)"),
                ));
            }
        }
    }
    Ok(())
}
