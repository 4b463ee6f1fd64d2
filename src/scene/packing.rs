//! Lattice packings (`[[packings]]`): a block of identical spheres written in a few lines
//! and expanded into `scene.grains` before the semantic checks, so everything downstream
//! (estimate, meshing, contact, overlap checks) sees ordinary grains.
//!
//! FCC convention: cubic cells of edge a = 2√2·R·(1+gap) with the cube axes along x, y, z,
//! so nearest neighbours sit at 2R(1+gap) along the 12 ⟨110⟩ directions. Sites are
//! integer points (i, j, l) of a half-cell grid (spacing a/2) with i+j+l even, at
//! `origin + (a/2)·(i, j, l)`. Open faces: 0 ≤ i ≤ 2n−1 (4 sites per cell, 4nmk);
//! closed faces: 0 ≤ i ≤ 2n, so every outer face is a complete (001) lattice plane.
//! Grain order: z layer by z layer, then y, x fastest; names `<packing>_<index>`.
//!
//! Every sphere gets the same mesh spec (one mesh for the whole packing): refinement
//! patches at the 12 contact directions, and with `axis_patches` at the 6 ⟨100⟩
//! directions where flat walls touch; with `contact_nodes` (the default) each patch has a
//! surface node exactly at its centre, so at gap 0 neighbours touch node on node and walls
//! at the lattice span ± R touch the axis nodes.

use super::{GrainSpec, Scene, ShapeSpec};
use crate::error::{echo, num, InputError};
use crate::mesh::{GradedBand, LocalRefinement, MeshError, SphereMeshSpec};
use serde::{Deserialize, Serialize};
use std::ops::Range;

/// Most grains all packings of a scene may generate. Each generated grain carries its own
/// copy of the mesh spec (~1 kB with 18 patches), so this bounds the memory spent before
/// the estimate and guard see the scene; 40× the paper's largest block (2426).
pub const MAX_PACKING_GRAINS: usize = 100_000;

/// Relative gap bounds: below −1 % the spheres overlap by more than any faceting
/// tolerance (the overlap check would refuse it anyway); above +50 % they are no longer
/// a packing.
pub const GAP_RANGE: (f64, f64) = (-0.01, 0.5);

/// One lattice block of identical spheres.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PackingSpec {
    /// Prefix of the grain names and name of the grain sets.
    pub name: String,
    pub lattice: Lattice,
    /// Cubic unit cells along x, y, z (≥ 1 each).
    pub cells: [i64; 3],
    pub faces: Faces,
    /// Key into `materials`.
    pub material: String,
    /// Centre of the first sphere (m).
    #[serde(default)]
    pub origin: [f64; 3],
    /// Gap between nearest neighbours as a fraction of the diameter (–); negative overlaps.
    #[serde(default)]
    pub gap: f64,
    pub sphere: PackingSphere,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Lattice {
    Fcc,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Faces {
    /// 4 spheres per cell; opposite faces are (001) planes of opposite parity.
    Open,
    /// Every lattice site of the closed box [0, n]×[0, m]×[0, k] cells.
    Closed,
}

/// The sphere template of a packing (lengths in m).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PackingSphere {
    pub radius: f64,
    /// Surface seeding away from the patches.
    pub seeding: f64,
    #[serde(default)]
    pub graded: Option<GradedBand>,
    /// Seeding at each lattice contact; absent: no patches (uniform surface).
    #[serde(default)]
    pub contact_seeding: Option<f64>,
    /// Chord radius of the zone meshed at `contact_seeding` (default 0: the point only).
    #[serde(default)]
    pub contact_radius: f64,
    /// Growth of the edge length away from the zone (default 0.3).
    #[serde(default = "default_growth")]
    pub contact_growth: f64,
    /// Also refine at the 6 ⟨100⟩ points where walls along the cube axes touch.
    #[serde(default)]
    pub axis_patches: bool,
    /// A surface node exactly at the centre of every patch (default true), so that
    /// touching neighbours and walls at the span ± R start in contact: without it the
    /// meshes start apart by up to their faceting sag (contact_seeding)²/8R, several times
    /// the Hertz overlap at tens of kPa, and differently at each contact.
    #[serde(default = "default_contact_nodes")]
    pub contact_nodes: bool,
}

fn default_growth() -> f64 {
    0.3
}

fn default_contact_nodes() -> bool {
    true
}

/// Where a packing's spheres are, for the stages that need the block's geometry.
#[derive(Debug, Clone, PartialEq)]
pub struct PackingGeometry {
    /// Indices of its grains in `scene.grains`.
    pub grains: Range<usize>,
    pub radius: f64,
    /// Cube edge a (m).
    pub lattice_constant: f64,
    /// Min and max sphere centre per axis (the lattice span, m).
    pub span_min: [f64; 3],
    pub span_max: [f64; 3],
    /// The block's bounding box: the span ± R (m).
    pub bounds_min: [f64; 3],
    pub bounds_max: [f64; 3],
}

/// Names of the face sets, in axis order (min, max).
pub const FACES: [[&str; 2]; 3] = [["x_min", "x_max"], ["y_min", "y_max"], ["z_min", "z_max"]];

impl PackingSpec {
    fn cells_usize(&self) -> [usize; 3] {
        self.cells.map(|c| c.max(0) as usize)
    }

    /// Largest half-cell index per axis.
    fn top(&self) -> [usize; 3] {
        let extra = usize::from(self.faces == Faces::Closed);
        self.cells_usize().map(|c| 2 * c + extra - 1)
    }

    /// Number of spheres: 4nmk open; closed (n+1)(m+1)(k+1) + nm(k+1) + n(m+1)k + (n+1)mk
    /// (corners, then the three face-centre sublattices). `None` on overflow.
    pub fn count(&self) -> Option<usize> {
        let [n, m, k] = self.cells_usize();
        let mul = |a: usize, b: usize, c: usize| a.checked_mul(b)?.checked_mul(c);
        match self.faces {
            Faces::Open => mul(n, m, k)?.checked_mul(4),
            Faces::Closed => mul(n + 1, m + 1, k + 1)?
                .checked_add(mul(n, m, k + 1)?)?
                .checked_add(mul(n, m + 1, k)?)?
                .checked_add(mul(n + 1, m, k)?),
        }
    }

    pub fn lattice_constant(&self) -> f64 {
        2.0 * std::f64::consts::SQRT_2 * self.sphere.radius * (1.0 + self.gap)
    }

    /// Half-cell indices of the sites in grain order (z, then y, x fastest).
    pub fn sites(&self) -> Vec<[usize; 3]> {
        let t = self.top();
        let mut out = Vec::with_capacity(self.count().unwrap_or(0));
        for l in 0..=t[2] {
            for j in 0..=t[1] {
                for i in (0..=t[0]).filter(|i| (i + j + l) % 2 == 0) {
                    out.push([i, j, l]);
                }
            }
        }
        out
    }

    fn centre(&self, site: [usize; 3]) -> [f64; 3] {
        let h = 0.5 * self.lattice_constant();
        [0, 1, 2].map(|k| self.origin[k] + h * site[k] as f64)
    }

    /// The one mesh spec every sphere of the packing gets.
    pub fn sphere_spec(&self) -> SphereMeshSpec {
        let s = &self.sphere;
        let mut refine = Vec::new();
        if let Some(seeding) = s.contact_seeding {
            refine = crate::mesh::fcc_contact_directions(s.axis_patches)
                .into_iter()
                .map(|direction| LocalRefinement {
                    direction,
                    seeding,
                    radius: s.contact_radius,
                    growth: s.contact_growth,
                    node: s.contact_nodes,
                })
                .collect();
        }
        SphereMeshSpec {
            radius: s.radius,
            seeding: s.seeding,
            graded: s.graded.clone(),
            refine,
        }
    }

    /// Where the packing's grains are once expanded starting at grain `first`.
    pub fn geometry(&self, first: usize) -> PackingGeometry {
        let r = self.sphere.radius;
        let span_min = self.centre([0, 0, 0]);
        let span_max = self.centre(self.top());
        PackingGeometry {
            grains: first..first + self.count().unwrap_or(0),
            radius: r,
            lattice_constant: self.lattice_constant(),
            span_min,
            span_max,
            bounds_min: span_min.map(|x| x - r),
            bounds_max: span_max.map(|x| x + r),
        }
    }

    /// Positions (in grain order) of the spheres whose centre lies on the outer lattice
    /// plane `face` (one of [`FACES`]).
    pub fn face(&self, face: &str) -> Option<Vec<usize>> {
        let (axis, side) = (0..3)
            .flat_map(|a| (0..2).map(move |s| (a, s)))
            .find(|&(a, s)| FACES[a][s] == face)?;
        let want = if side == 0 { 0 } else { self.top()[axis] };
        let sites = self.sites();
        Some(
            (0..sites.len())
                .filter(|&g| sites[g][axis] == want)
                .collect(),
        )
    }
}

impl Scene {
    /// Geometry of each packing, in `packings` order (after expansion by `parse_scene`).
    pub fn packing_geometry(&self) -> Vec<PackingGeometry> {
        self.packings
            .iter()
            .zip(&self.packing_grains)
            .map(|(pk, r)| pk.geometry(r.start))
            .collect()
    }

    /// Grain indices of a named set: a packing (`fcc`), one of its outer lattice planes
    /// (`fcc.x_min` … `fcc.z_max`), or a single grain by name.
    pub fn grain_set(&self, name: &str) -> Option<Vec<usize>> {
        for (pk, r) in self.packings.iter().zip(&self.packing_grains) {
            if name == pk.name {
                return Some(r.clone().collect());
            }
            if let Some(face) = name
                .strip_prefix(pk.name.as_str())
                .and_then(|f| f.strip_prefix('.'))
            {
                let local = pk.face(face)?;
                return Some(local.into_iter().map(|g| r.start + g).collect());
            }
        }
        (0..self.grains.len())
            .find(|&i| self.grains[i].display_name(i) == name)
            .map(|i| vec![i])
    }
}

/// Checks the packings (each bad field named `packings[i].…`) and appends their grains to
/// `scene.grains`, recording each packing's grain range.
pub(super) fn expand(file: &str, scene: &mut Scene) -> Result<(), InputError> {
    let err = |field: String, msg: String| InputError::new(file, field, msg);
    let mut total = 0usize;
    for (p, pk) in scene.packings.iter().enumerate() {
        let f = |x: &str| format!("packings[{p}].{x}");
        check_name(scene, p).map_err(|m| err(f("name"), m))?;
        if let Some(k) = pk.cells.iter().position(|&c| c < 1) {
            return Err(err(
                f("cells"),
                format!("cells[{k}] must be ≥ 1, got {}", pk.cells[k]),
            ));
        }
        if !scene.materials.contains_key(&pk.material) {
            return Err(err(
                f("material"),
                format!("unknown material '{}'", echo(&pk.material)),
            ));
        }
        for (k, x) in pk.origin.iter().enumerate() {
            if !x.is_finite() {
                return Err(err(
                    format!("packings[{p}].origin[{k}]"),
                    format!("must be a finite number, got {}", num(*x)),
                ));
            }
        }
        let (lo, hi) = GAP_RANGE;
        if !(pk.gap > lo && pk.gap < hi) {
            return Err(err(
                f("gap"),
                format!(
                    "must be in ({lo}, {hi}) (fraction of the diameter), got {}",
                    num(pk.gap)
                ),
            ));
        }
        pk.sphere_spec()
            .validate()
            .map_err(|e| sphere_error(file, p, e))?;
        total = pk
            .count()
            .and_then(|c| total.checked_add(c))
            .filter(|&t| t <= MAX_PACKING_GRAINS)
            .ok_or_else(|| {
                err(
                    f("cells"),
                    format!(
                        "{:?} cells of {:?} faces give more than {MAX_PACKING_GRAINS} grains (over all packings)",
                        pk.cells, pk.faces
                    ),
                )
            })?;
    }
    let mut ranges = Vec::with_capacity(scene.packings.len());
    let mut grains = Vec::with_capacity(total);
    let first = scene.grains.len();
    for pk in &scene.packings {
        let shape = ShapeSpec::Sphere(pk.sphere_spec());
        let start = first + grains.len();
        for (g, site) in pk.sites().into_iter().enumerate() {
            grains.push(GrainSpec {
                name: Some(format!("{}_{g}", pk.name)),
                material: pk.material.clone(),
                shape: shape.clone(),
                centre: pk.centre(site),
                velocity: [0.0; 3],
                angular_velocity: [0.0; 3],
            });
        }
        ranges.push(start..first + grains.len());
    }
    scene.grains.extend(grains);
    scene.packing_grains = ranges;
    Ok(())
}

/// A packing name must label history columns and grain sets, and neither it, its face
/// sets nor its generated grain names may be taken by another packing or grain.
fn check_name(scene: &Scene, p: usize) -> Result<(), String> {
    let name = &scene.packings[p].name;
    if name.is_empty() || !name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
        return Err("must be a non-empty identifier (letters, digits, _)".into());
    }
    if scene.packings[..p].iter().any(|o| &o.name == name) {
        return Err(format!("duplicate packing name '{}'", echo(name)));
    }
    let taken = |g: &str| {
        g == name
            || g.strip_prefix(name.as_str()).is_some_and(|rest| {
                rest.strip_prefix('_')
                    .is_some_and(|d| !d.is_empty() && d.bytes().all(|b| b.is_ascii_digit()))
                    || rest
                        .strip_prefix('.')
                        .is_some_and(|f| FACES.iter().flatten().any(|x| *x == f))
            })
    };
    // Another packing's generated names (`a_1_2` for packing `a_1`) or an explicit grain.
    for (i, g) in scene.grains.iter().enumerate() {
        let g = g.display_name(i);
        if taken(&g) {
            return Err(format!(
                "'{}' clashes with grains[{i}] named '{}'",
                echo(name),
                echo(&g)
            ));
        }
    }
    for o in &scene.packings[..p] {
        if o.name.starts_with(&format!("{name}_")) || name.starts_with(&format!("{}_", o.name)) {
            return Err(format!(
                "'{}' and packing '{}' would generate clashing grain names",
                echo(name),
                echo(&o.name)
            ));
        }
    }
    Ok(())
}

/// A mesh-spec error of the generated sphere, named by the packing field the user wrote.
fn sphere_error(file: &str, p: usize, e: MeshError) -> InputError {
    let (field, message) = match e {
        MeshError::InvalidSpec { field, message } => (field, message),
        other => (String::new(), other.to_string()),
    };
    let field = match field.split_once("].") {
        Some((_, "seeding")) => "contact_seeding".to_string(),
        Some((_, "radius")) => "contact_radius".to_string(),
        Some((_, "growth")) => "contact_growth".to_string(),
        Some((_, "node")) => "contact_nodes".to_string(),
        _ => field,
    };
    let item = if field.is_empty() {
        format!("packings[{p}].sphere")
    } else {
        format!("packings[{p}].sphere.{field}")
    };
    InputError::new(file, item, message)
}

/// Renames an error about a generated grain (`grains[i]…`) to the packing field that
/// made it, so the user is pointed at what they wrote.
pub(super) fn blame(scene: &Scene, mut e: InputError) -> InputError {
    let packing_of = |i: usize| scene.packing_grains.iter().position(|r| r.contains(&i));
    let index = |s: &str| -> Option<(usize, usize)> {
        let rest = s.strip_prefix("grains[")?;
        let close = rest.find(']')?;
        Some((rest[..close].parse().ok()?, close + "grains[]".len()))
    };
    if e.item == "grains" {
        // the size driver when no single grain dominates: the biggest packing, if most grains
        let n = scene.grains.len();
        if let Some(p) = scene.packing_grains.iter().position(|r| 2 * r.len() >= n) {
            e.item = format!("packings[{p}].cells");
        }
        return e;
    }
    let Some((i, end)) = index(&e.item) else {
        return e;
    };
    let Some(p) = packing_of(i) else {
        // an explicit grain, maybe overlapping a packing's grain
        if let Some(q) = e.item[end..]
            .strip_prefix(" and ")
            .and_then(index)
            .and_then(|(j, _)| packing_of(j))
        {
            e.item = format!("packings[{q}].origin");
        }
        return e;
    };
    let rest = &e.item[end..];
    e.item = if let Some(other) = rest.strip_prefix(" and ") {
        let q = index(other).and_then(|(j, _)| packing_of(j));
        if q == Some(p) {
            format!("packings[{p}].gap")
        } else {
            format!("packings[{p}].origin")
        }
    } else if let Some(f) = rest.strip_prefix(".shape.sphere") {
        let e2 = MeshError::InvalidSpec {
            field: f.trim_start_matches('.').to_string(),
            message: String::new(),
        };
        sphere_error(&e.file, p, e2).item
    } else if rest.starts_with(".centre") {
        format!("packings[{p}].origin")
    } else {
        format!("packings[{p}]{rest}")
    };
    e
}

#[cfg(test)]
mod tests;
