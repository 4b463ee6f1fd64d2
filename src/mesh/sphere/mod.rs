//! Sphere mesher: uniform, graded (fine surface band, coarse core) and locally refined
//! (fine patches around chosen surface points, e.g. the expected contacts).
//!
//! How a sphere is meshed (see [`mesh_sphere`]):
//! 1. the surface is triangulated by [`triangulate_sphere`] with the spec's sizing function
//!    (geodesic base, longest-edge bisection in refinement patches, made acute);
//! 2. the interior is seeded with nested body-centred cubic (BCC) lattices following a 3D
//!    size field (the seeding; the core size below a graded band; the patch formula near
//!    refinement points), kept a skin depth below the surface and out of the surface
//!    triangles' and edges' diametral balls;
//! 3. TetGen tetrahedralises the closed surface with the lattice points as isolated PLC
//!    vertices, refining only where its radius–edge bound requires (in the skin and at the
//!    lattice level transitions) and optimising dihedral angles.
//!
//! Why not TetGen's volume bounds and internal facet spheres for the grading? Tried first:
//! volume-driven Steiner points near the surface fall inside the surface triangles'
//! diametral balls and TetGen splits the surface (≈ 3× the requested facets at MR 0.045),
//! and internal facets get split too. Seeding the interior ourselves keeps the surface
//! exactly as triangulated (the requested MR), gives Sommerville tets (dihedral 60°/90°)
//! inside, and is about twice as fast.

use serde::{Deserialize, Serialize};

use super::lattice::{
    add_nested_bcc, lattice_rotation, mat_vec, transpose, Aabb, DiametralBalls, BALL_MARGIN,
    LATTICE_FACTOR, SKIN_DEPTH,
};
use super::surface_refine::{triangulate_sphere, Pin};
use super::tetgen::{tetrahedralize, Region};
use super::{validate, MeshError, TetMesh};
use crate::error::num;
use crate::math::{norm, scale, sub};

/// TetGen's maximum radius–edge ratio (`-q`). The lattice-seeded interior rarely needs
/// refinement. Measured on R = 1.1 mm, MR 0.09/0.045/0.023 × uniform/graded/patch: at 2.0
/// the surface is never split and the minimum dihedral angle (set mostly by TetGen's
/// optimisation pass) is 6.6–8.5°; at 1.5 TetGen's refinement of the skin under refinement
/// patches inserts points that encroach surface triangles (+10–30 % surface facets, edges
/// down to 1/5 of the seeding) and the minimum dihedral angle drops to 3.9–6.5°.
pub(crate) const RADIUS_EDGE_RATIO: f64 = 2.0;

/// Graded meshes: below the band the interior size grows by this much per unit depth until
/// it reaches the core size.
const CORE_GROWTH: f64 = 1.0;

/// A tet mesh of a sphere centred at the origin (grain frame). All lengths in metres.
///
/// TOML example (R = 1.1 mm, MR = 0.045, graded, refined at the north pole):
/// ```toml
/// radius = 1.1e-3
/// seeding = 9.9e-5
/// graded = { band_depth = 3.0e-4, core_seeding = 2.75e-4 }
/// refine = [ { direction = [0, 0, 1], seeding = 2.5e-5, radius = 1e-4 } ]
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SphereMeshSpec {
    /// Sphere radius R (m).
    pub radius: f64,
    /// Seeding distance s (m): target edge length on the surface away from refinement zones.
    /// The meshing ratio of the paper is MR = s/(2R).
    pub seeding: f64,
    /// Fine band under the surface and coarse core; `None` = the interior is meshed at
    /// about `seeding` everywhere (uniform).
    #[serde(default)]
    pub graded: Option<GradedBand>,
    /// Local refinement zones on the surface; the interior grades naturally from them.
    #[serde(default)]
    pub refine: Vec<LocalRefinement>,
}

/// Hybrid mesh: fine elements (≈ `seeding`) in a surface band `band_depth` deep, coarser
/// ones (≈ `core_seeding`) inside it. Below the band the element size grows by
/// `CORE_GROWTH` (1.0) per unit depth up to the core size, which is `core_seeding` rounded
/// to `seeding` × a power of two (the interior lattices are nested 2:1), i.e. within a
/// factor √2 of the request.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GradedBand {
    /// Depth of the fine band below the surface (m); at least `seeding`, less than R.
    pub band_depth: f64,
    /// Nominal edge length in the core (m); at least `seeding`.
    pub core_seeding: f64,
}

/// A fine patch on the surface around the point `radius_of_sphere · direction/|direction|`.
///
/// Surface sizing: h(x) = min(seeding, minᵢ(sᵢ + gᵢ·max(0, dᵢ(x) − rᵢ))), dᵢ the chord
/// distance from x to point i.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LocalRefinement {
    /// Direction from the centre to the patch centre (any length > 0; normalised).
    pub direction: [f64; 3],
    /// Edge length at the patch (m).
    pub seeding: f64,
    /// Radius of the zone where `seeding` holds (chord distance, m).
    pub radius: f64,
    /// Dimensionless growth rate: the edge length grows by `growth` × distance beyond the
    /// zone (default 0.3).
    #[serde(default = "default_growth")]
    pub growth: f64,
    /// Put a surface node exactly at the patch centre (default false). Without it the
    /// nearest node lies up to about half an edge away and the surface there is a facet
    /// sagging up to h²/(8R) inside the sphere, so a sphere or a wall placed to touch at
    /// the centre starts that far away (more than the Hertz overlap at low loads).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub node: bool,
}

/// Smallest meaningful growth of a refinement patch: at 0.01 the size has grown by only
/// 1 % of the distance, so the fine zone of any useful patch already covers the grain.
pub const MIN_GROWTH: f64 = 0.01;
/// Largest meaningful growth: the edge length may grow at most as fast as the distance
/// (as the interior does, `CORE_GROWTH`); above, the surface bisection cannot follow the
/// size field (the mesh no longer changes with the value) and transitions are abrupt.
pub const MAX_GROWTH: f64 = 1.0;

fn default_growth() -> f64 {
    0.3
}

fn invalid(field: impl Into<String>, message: impl Into<String>) -> MeshError {
    MeshError::InvalidSpec {
        field: field.into(),
        message: message.into(),
    }
}

fn check_positive(field: &str, v: f64) -> Result<(), MeshError> {
    if !v.is_finite() || v <= 0.0 {
        return Err(invalid(
            field,
            format!("must be a positive finite length, got {}", num(v)),
        ));
    }
    Ok(())
}

impl SphereMeshSpec {
    /// Uniform mesh of seeding `seeding`.
    pub fn uniform(radius: f64, seeding: f64) -> Self {
        Self {
            radius,
            seeding,
            graded: None,
            refine: Vec::new(),
        }
    }

    /// Uniform mesh at meshing ratio MR = s/(2R) (the paper's parameter).
    pub fn from_meshing_ratio(radius: f64, meshing_ratio: f64) -> Self {
        Self::uniform(radius, meshing_ratio * 2.0 * radius)
    }

    /// Adds a fine band of `band_depth` over a core of `core_seeding`.
    pub fn with_graded(mut self, band_depth: f64, core_seeding: f64) -> Self {
        self.graded = Some(GradedBand {
            band_depth,
            core_seeding,
        });
        self
    }

    /// Adds a local refinement patch (growth 0.3).
    pub fn with_refinement(mut self, direction: [f64; 3], seeding: f64, radius: f64) -> Self {
        self.refine.push(LocalRefinement {
            direction,
            seeding,
            radius,
            growth: default_growth(),
            node: false,
        });
        self
    }

    /// Adds a local refinement patch (growth 0.3) with a surface node at its centre.
    pub fn with_node_refinement(mut self, direction: [f64; 3], seeding: f64, radius: f64) -> Self {
        self = self.with_refinement(direction, seeding, radius);
        if let Some(r) = self.refine.last_mut() {
            r.node = true;
        }
        self
    }

    /// Meshing ratio MR = seeding/(2·radius).
    pub fn meshing_ratio(&self) -> f64 {
        self.seeding / (2.0 * self.radius)
    }

    /// Checks every field; the error names the first bad field and why.
    pub fn validate(&self) -> Result<(), MeshError> {
        check_positive("radius", self.radius)?;
        check_positive("seeding", self.seeding)?;
        if self.seeding < 1e-4 * self.radius {
            return Err(invalid(
                "seeding",
                format!(
                    "{} is below 1e-4 × radius {}: too fine to mesh (~1e12 elements)",
                    num(self.seeding),
                    num(self.radius)
                ),
            ));
        }
        if self.seeding > self.radius {
            return Err(invalid(
                "seeding",
                format!(
                    "{} is larger than the radius {} (meshing ratio > 0.5)",
                    num(self.seeding),
                    num(self.radius)
                ),
            ));
        }
        if let Some(g) = &self.graded {
            check_positive("graded.band_depth", g.band_depth)?;
            check_positive("graded.core_seeding", g.core_seeding)?;
            if g.band_depth >= self.radius {
                return Err(invalid(
                    "graded.band_depth",
                    format!(
                        "{} must be smaller than the radius {}",
                        num(g.band_depth),
                        num(self.radius)
                    ),
                ));
            }
            if g.band_depth < self.seeding {
                return Err(invalid(
                    "graded.band_depth",
                    format!(
                        "{} must be at least one surface element deep (≥ seeding {})",
                        num(g.band_depth),
                        num(self.seeding)
                    ),
                ));
            }
            if g.core_seeding < self.seeding {
                return Err(invalid(
                    "graded.core_seeding",
                    format!(
                        "{} must not be finer than the surface seeding {}",
                        num(g.core_seeding),
                        num(self.seeding)
                    ),
                ));
            }
            if g.core_seeding > self.radius {
                return Err(invalid(
                    "graded.core_seeding",
                    format!(
                        "{} is larger than the radius {}",
                        num(g.core_seeding),
                        num(self.radius)
                    ),
                ));
            }
        }
        for (i, r) in self.refine.iter().enumerate() {
            let f = |name: &str| format!("refine[{i}].{name}");
            let d = r.direction;
            if !d.iter().all(|x| x.is_finite()) || norm(d) == 0.0 {
                return Err(invalid(
                    f("direction"),
                    format!("must be a finite non-zero vector, got {d:?}"),
                ));
            }
            check_positive(&f("seeding"), r.seeding)?;
            if r.seeding > self.seeding {
                return Err(invalid(
                    f("seeding"),
                    format!(
                        "{} is coarser than the global seeding {}: no refinement",
                        num(r.seeding),
                        num(self.seeding)
                    ),
                ));
            }
            if r.seeding < 1e-4 * self.radius {
                return Err(invalid(
                    f("seeding"),
                    format!(
                        "{} is below 1e-4 × radius {}: too fine to mesh",
                        num(r.seeding),
                        num(self.radius)
                    ),
                ));
            }
            if !r.radius.is_finite() || r.radius < 0.0 {
                return Err(invalid(
                    f("radius"),
                    format!("must be a finite length ≥ 0, got {}", num(r.radius)),
                ));
            }
            if r.radius > 2.0 * self.radius {
                return Err(invalid(
                    f("radius"),
                    format!(
                        "{} exceeds the sphere's diameter {}: the zone would cover the whole sphere (use seeding instead)",
                        num(r.radius),
                        num(2.0 * self.radius)
                    ),
                ));
            }
            if !(MIN_GROWTH..=MAX_GROWTH).contains(&r.growth) {
                return Err(invalid(
                    f("growth"),
                    format!(
                        "must be in [{MIN_GROWTH}, {MAX_GROWTH}], got {}: below, the fine zone spreads over the whole grain (use a finer seeding instead); above, the size would grow faster than the distance and bisection cannot follow it",
                        num(r.growth)
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The surface sizing function h(x) (m) at a point x of the sphere surface (m).
    pub fn surface_size(&self, x: [f64; 3]) -> f64 {
        let mut h = self.seeding;
        for r in &self.refine {
            let p = scale(r.direction, self.radius / norm(r.direction));
            let d = norm(sub(x, p));
            h = h.min(r.seeding + r.growth * (d - r.radius).max(0.0));
        }
        h
    }
}

/// The 12 ⟨110⟩ directions (an FCC sphere's nearest neighbours, cube axes along x, y, z),
/// then with `axes` the 6 ⟨100⟩ ones (where walls normal to the cube axes touch it).
pub fn fcc_contact_directions(axes: bool) -> Vec<[f64; 3]> {
    let mut dirs = Vec::with_capacity(18);
    for (a, b) in [(0, 1), (0, 2), (1, 2)] {
        for (sa, sb) in [(1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)] {
            let mut d = [0.0; 3];
            (d[a], d[b]) = (sa, sb);
            dirs.push(d);
        }
    }
    if axes {
        for k in 0..3 {
            for sign in [1.0, -1.0] {
                let mut d = [0.0; 3];
                d[k] = sign;
                dirs.push(d);
            }
        }
    }
    dirs
}

/// Meshes the sphere described by `spec` (validated first). Deterministic: the same spec
/// gives a bitwise identical mesh. Tets are positively oriented and pass [`validate`].
/// See the module documentation for the method.
///
/// The work is done at unit radius (TetGen's tolerances are relative and its numeric
/// switches go through text) and scaled back by R.
///
/// Measured (R = 1.1 mm, release build of the library, TetGen at -O2): see
/// `tests::mesh_size_table` (run with `--ignored --nocapture`).
pub fn mesh_sphere(spec: &SphereMeshSpec) -> Result<TetMesh, MeshError> {
    spec.validate()?;
    let big_r = spec.radius;
    let inv = 1.0 / big_r;

    let patches = unit_patches(spec);
    let s = spec.seeding * inv;
    let patch_size = |x: [f64; 3]| patch_size(&patches, x);
    let surface = unit_surface(spec)?;
    let n_surface = surface.points.len();
    let mut points = surface.points;
    let facets = surface.triangles;

    // Interior size field H(p): the patch formula with 3D distances, under a background of s
    // (uniform) or s in the band growing to the core size below it (graded). Nested BCC
    // lattices of constant a·2^(C−ℓ) fill the places where H ≈ s·2^(C−ℓ): level 0 is the core
    // (C = log₂(core/s) rounded; 0 if not graded), level C the seeding, the levels above C
    // the refinement patches.
    let (band, coarse_levels) = match &spec.graded {
        None => (1.0, 0u32),
        Some(g) => (
            g.band_depth * inv,
            (g.core_seeding / spec.seeding).log2().round().max(0.0) as u32,
        ),
    };
    let core = s * (1u64 << coarse_levels) as f64;
    let fine_levels = patches
        .iter()
        .map(|&(_, sr, _, _)| (s / sr).log2().round().max(0.0) as u32)
        .max()
        .unwrap_or(0);
    let field = |p: [f64; 3]| {
        let depth = 1.0 - norm(p);
        core.min(s + CORE_GROWTH * (depth - band).max(0.0))
            .min(patch_size(p))
    };
    let whole: Vec<Aabb> = vec![([-1.0; 3], [1.0; 3])];
    let mut boxes = vec![whole.clone(); coarse_levels as usize + 1];
    let rot_t = transpose(&lattice_rotation());
    for l in 1..=fine_levels {
        // Where H is below the level's threshold s·2^(½−l): balls around the patches.
        let threshold = s * 2f64.powf(0.5 - l as f64);
        let mut level_boxes = Vec::new();
        for &(p, sr, rr, g) in &patches {
            if sr > threshold {
                continue;
            }
            if g == 0.0 {
                level_boxes = whole.clone();
                break;
            }
            let reach = rr + (threshold - sr) / g;
            let c = mat_vec(&rot_t, p);
            level_boxes.push((
                c.map(|x| (x - reach).max(-1.0)),
                c.map(|x| (x + reach).min(1.0)),
            ));
        }
        boxes.push(level_boxes);
    }
    let top = (coarse_levels + fine_levels) as f64;
    add_nested_bcc(
        LATTICE_FACTOR * core,
        &boxes,
        |p| {
            let h = field(p);
            if 1.0 - norm(p) < SKIN_DEPTH * h {
                return None;
            }
            Some((coarse_levels as f64 + (s / h).log2().round()).clamp(0.0, top) as u32)
        },
        &mut points,
    );

    // Lattice points must stay out of the surface triangles' and edges' diametral balls.
    let guard = DiametralBalls::new(&points[..n_surface], &facets, BALL_MARGIN);
    let mut kept = n_surface;
    for i in n_surface..points.len() {
        if !guard.encroaches(points[i]) {
            points[kept] = points[i];
            kept += 1;
        }
    }
    points.truncate(kept);

    // No volume bound: TetGen also splits every surface triangle whose area^1.5 exceeds the
    // bound of the adjacent region (`checkfac4split`), which at any useful value cuts the
    // larger surface triangles; the lattice sets the interior size instead.
    let regions = [Region {
        point: [0.0; 3],
        marker: 1,
        max_volume: None,
    }];
    let mut mesh = tetrahedralize(&points, &facets, &regions, RADIUS_EDGE_RATIO, None)?;
    super::improve::improve_off_surface(&mut mesh);
    for p in mesh.nodes.iter_mut() {
        *p = scale(*p, big_r);
    }
    validate(&mesh)?;
    Ok(mesh)
}

/// The refinement patches at unit radius: (unit direction, seeding, radius, growth).
fn unit_patches(spec: &SphereMeshSpec) -> Vec<([f64; 3], f64, f64, f64)> {
    let inv = 1.0 / spec.radius;
    spec.refine
        .iter()
        .map(|r| {
            (
                scale(r.direction, 1.0 / norm(r.direction)),
                r.seeding * inv,
                r.radius * inv,
                r.growth,
            )
        })
        .collect()
}

/// minᵢ(sᵢ + gᵢ·max(0, |x − pᵢ| − rᵢ)) over the patches (∞ without patches).
fn patch_size(patches: &[([f64; 3], f64, f64, f64)], x: [f64; 3]) -> f64 {
    let mut h = f64::INFINITY;
    for &(p, sr, rr, g) in patches {
        h = h.min(sr + g * (norm(sub(x, p)) - rr).max(0.0));
    }
    h
}

/// The surface triangulation of `spec` on the unit sphere (what [`mesh_sphere`] hands to
/// TetGen, before scaling by R).
pub(crate) fn unit_surface(
    spec: &SphereMeshSpec,
) -> Result<super::surface_refine::SphereSurface, MeshError> {
    let patches = unit_patches(spec);
    let s = spec.seeding / spec.radius;
    let pins: Vec<Pin> = spec
        .refine
        .iter()
        .enumerate()
        .filter(|(_, r)| r.node)
        .map(|(i, r)| Pin {
            direction: r.direction,
            field: format!("refine[{i}].node"),
        })
        .collect();
    triangulate_sphere(1.0, s, |x| s.min(patch_size(&patches, x)), &pins, "seeding")
}

#[cfg(test)]
mod tests;
