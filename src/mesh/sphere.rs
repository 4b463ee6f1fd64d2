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
mod tests {
    use super::*;
    use crate::math::{add, cross, dot};
    use crate::mesh::{
        extract_surface, facet_normals, quality, surface_node_geometry, tet_volume, SurfaceMesh,
    };
    use std::collections::HashMap;
    use std::f64::consts::PI;

    const R: f64 = 1.1e-3;

    fn mesh_volume(m: &TetMesh) -> f64 {
        m.tets
            .iter()
            .map(|t| tet_volume(&t.map(|i| m.nodes[i as usize])))
            .sum()
    }

    /// Every directed edge exactly once, with its twin: closed, consistently oriented.
    fn assert_closed(s: &SurfaceMesh) {
        let mut directed: HashMap<(u32, u32), u32> = HashMap::new();
        for f in &s.facets {
            for k in 0..3 {
                *directed.entry((f[k], f[(k + 1) % 3])).or_default() += 1;
            }
        }
        for (&(a, b), &n) in &directed {
            assert_eq!(n, 1, "edge ({a},{b}) used {n} times in one direction");
            assert_eq!(
                directed.get(&(b, a)),
                Some(&1),
                "edge ({a},{b}) not shared by exactly 2 facets"
            );
        }
        // Euler characteristic of a sphere.
        let (v, e, f) = (
            s.nodes.len() as i64,
            directed.len() as i64 / 2,
            s.facets.len() as i64,
        );
        assert_eq!(v - e + f, 2);
    }

    /// Surface edges as (midpoint, length).
    fn surface_edges(m: &TetMesh, s: &SurfaceMesh) -> Vec<([f64; 3], f64)> {
        let mut out = Vec::new();
        for f in &s.facets {
            for k in 0..3 {
                let (a, b) = (f[k], f[(k + 1) % 3]);
                if a < b {
                    let (p, q) = (m.nodes[a as usize], m.nodes[b as usize]);
                    out.push((scale(add(p, q), 0.5), norm(sub(q, p))));
                }
            }
        }
        out
    }

    #[test]
    fn uniform_sphere_is_closed_outward_and_has_the_right_volume() {
        let spec = SphereMeshSpec::from_meshing_ratio(R, 0.09);
        let m = mesh_sphere(&spec).unwrap();
        validate(&m).unwrap();
        for t in &m.tets {
            assert!(tet_volume(&t.map(|i| m.nodes[i as usize])) > 0.0);
        }
        let s = extract_surface(&m);
        assert_closed(&s);

        // Divergence theorem: Σ (area vector · centroid)/3 over the facets = enclosed volume,
        // positive only if the facets point outward.
        let v_tets = mesh_volume(&m);
        let v_surf: f64 = s
            .facets
            .iter()
            .map(|f| {
                let [a, b, c] = f.map(|i| m.nodes[i as usize]);
                let area = scale(cross(sub(b, a), sub(c, a)), 0.5);
                dot(area, scale(add(add(a, b), c), 1.0 / 3.0)) / 3.0
            })
            .sum();
        assert!(v_surf > 0.0);
        assert!(
            (v_surf / v_tets - 1.0).abs() < 1e-10,
            "{v_surf} vs {v_tets}"
        );

        // The convex polyhedron lies inside the sphere and contains the ball of radius
        // d_min = R − (largest chord sagitta) = min distance from the centre to a facet plane.
        let normals = facet_normals(&m, &s);
        let d_min = s
            .facets
            .iter()
            .zip(&normals)
            .map(|(f, n)| dot(*n, m.nodes[f[0] as usize]))
            .fold(f64::INFINITY, f64::min);
        let sagitta = R - d_min;
        assert!(sagitta > 0.0 && sagitta < 0.05 * R, "sagitta {sagitta}");
        let (v_in, v_out) = (4.0 / 3.0 * PI * d_min.powi(3), 4.0 / 3.0 * PI * R.powi(3));
        assert!(
            v_tets >= v_in * (1.0 - 1e-12) && v_tets <= v_out * (1.0 + 1e-12),
            "{v_in} ≤ {v_tets} ≤ {v_out}"
        );
        for &n in &s.nodes {
            assert!(norm(m.nodes[n as usize]) <= R * (1.0 + 1e-12));
        }

        // The surface is exactly the triangulated sphere (no TetGen Steiner points): mean
        // edge ≈ seeding, every surface node on the sphere.
        let q = quality(&m);
        assert!(
            (q.mean_surface_edge / spec.seeding - 1.0).abs() < 0.1,
            "{}",
            q.mean_surface_edge
        );
        for &n in &s.nodes {
            assert!((norm(m.nodes[n as usize]) / R - 1.0).abs() < 1e-12);
        }
        assert!(q.min_dihedral_deg > 5.0, "{q}");

        // Node geometry for contact: tributary areas add up to the surface area, normals are
        // unit and outward.
        let g = surface_node_geometry(&m, &s);
        let area: f64 = s
            .facets
            .iter()
            .map(|f| {
                let [a, b, c] = f.map(|i| m.nodes[i as usize]);
                0.5 * norm(cross(sub(b, a), sub(c, a)))
            })
            .sum();
        assert!((g.areas.iter().sum::<f64>() / area - 1.0).abs() < 1e-12);
        assert!(area < 4.0 * PI * R * R && area > 4.0 * PI * d_min * d_min);
        for (k, &n) in s.nodes.iter().enumerate() {
            let x = m.nodes[n as usize];
            assert!((norm(g.normals[k]) - 1.0).abs() < 1e-12);
            assert!(dot(g.normals[k], x) / norm(x) > 0.99);
        }
    }

    #[test]
    fn local_refinement_is_fine_at_the_point_and_coarse_elsewhere() {
        let s = R / 4.0;
        let fine = s / 4.0;
        let dir = [1.0, 1.0, 0.0];
        let spec = SphereMeshSpec::uniform(R, s).with_refinement(dir, fine, 0.1 * R);
        let m = mesh_sphere(&spec).unwrap();
        validate(&m).unwrap();
        let surf = extract_surface(&m);
        assert_closed(&surf);
        let point = scale(dir, R / norm(dir));
        let edges = surface_edges(&m, &surf);
        let near: Vec<f64> = edges
            .iter()
            .filter(|(c, _)| norm(sub(*c, point)) < 0.1 * R)
            .map(|e| e.1)
            .collect();
        let far: Vec<f64> = edges
            .iter()
            .filter(|(c, _)| norm(sub(*c, point)) > 1.5 * R)
            .map(|e| e.1)
            .collect();
        assert!(near.len() >= 6 && !far.is_empty());
        let near_max = near.iter().cloned().fold(0.0, f64::max);
        let far_mean = far.iter().sum::<f64>() / far.len() as f64;
        assert!(near_max <= 1.5 * fine, "near {near_max} vs {fine}");
        assert!(
            far_mean > 3.0 * fine && (far_mean / s - 1.0).abs() < 0.15,
            "far mean {far_mean}"
        );
        let q = quality(&m);
        assert!(q.min_dihedral_deg > 5.0, "{q}");
        // TetGen kept the surface exactly as triangulated (no Steiner points on it).
        assert_eq!(
            q.surface_facets,
            unit_surface(&spec).unwrap().triangles.len()
        );
        // Much cheaper than meshing the whole sphere at the fine seeding.
        let uniform_fine = mesh_sphere(&SphereMeshSpec::uniform(R, fine)).unwrap();
        assert!(
            5 * m.tets.len() < uniform_fine.tets.len(),
            "refined {} vs uniform fine {}",
            m.tets.len(),
            uniform_fine.tets.len()
        );
        // Two calls give bitwise identical meshes.
        assert_eq!(mesh_sphere(&spec).unwrap(), m);
    }

    #[test]
    fn node_patches_put_a_surface_node_exactly_at_their_centres() {
        // The FCC cell's sphere: patches at the 12 ⟨110⟩ contacts and the 6 ⟨100⟩ wall points.
        let dirs = fcc_contact_directions(true);
        let (plain, pinned) = dirs.iter().fold(
            (
                SphereMeshSpec::uniform(R, 4.5e-4),
                SphereMeshSpec::uniform(R, 4.5e-4),
            ),
            |(a, b), &d| {
                (
                    a.with_refinement(d, 2e-4, 0.0),
                    b.with_node_refinement(d, 2e-4, 0.0),
                )
            },
        );
        let nearest_surface_node = |m: &TetMesh, s: &SurfaceMesh, x: [f64; 3]| {
            s.nodes
                .iter()
                .map(|&n| norm(sub(m.nodes[n as usize], x)))
                .fold(f64::INFINITY, f64::min)
        };
        let m = mesh_sphere(&pinned).unwrap();
        validate(&m).unwrap();
        let surf = extract_surface(&m);
        assert_closed(&surf);
        let m0 = mesh_sphere(&plain).unwrap();
        let surf0 = extract_surface(&m0);
        let mut missed_without = 0;
        for d in &dirs {
            let centre = scale(*d, R / norm(*d));
            let off = nearest_surface_node(&m, &surf, centre);
            assert!(off <= 1e-12 * R, "{d:?}: nearest node {off} m away");
            if nearest_surface_node(&m0, &surf0, centre) > 1e-3 * R {
                missed_without += 1;
            }
        }
        assert!(missed_without > 0, "the plain mesh already has every node");
        let q = quality(&m);
        assert!(q.min_dihedral_deg > 5.0, "{q}");
        // Acute surface: TetGen had no surface edge to split.
        assert_eq!(
            q.surface_facets,
            unit_surface(&pinned).unwrap().triangles.len()
        );
        assert_eq!(mesh_sphere(&pinned).unwrap(), m);
        // Plain patches serialise as before the option existed.
        assert!(!serde_json::to_string(&plain).unwrap().contains("node"));
        let text = "radius = 1.0\nseeding = 0.1\nrefine = [ { direction = [0, 0, 1], seeding = 0.05, radius = 0.0, node = true } ]";
        assert!(toml::from_str::<SphereMeshSpec>(text).unwrap().refine[0].node);
    }

    #[test]
    fn two_node_patches_closer_than_an_edge_are_refused_naming_the_second() {
        let spec = SphereMeshSpec::uniform(R, 4.5e-4)
            .with_node_refinement([0.0, 0.0, 1.0], 2e-4, 0.0)
            .with_node_refinement([0.0, 0.02, 1.0], 2e-4, 0.0);
        match mesh_sphere(&spec) {
            Err(MeshError::InvalidSpec { field, .. }) => assert_eq!(field, "refine[1].node"),
            other => panic!("expected an InvalidSpec error, got {other:?}"),
        }
    }

    #[test]
    fn graded_mesh_has_a_coarse_core_and_the_same_surface() {
        let s = 0.045 * 2.0 * R;
        let uniform = mesh_sphere(&SphereMeshSpec::uniform(R, s)).unwrap();
        let graded =
            mesh_sphere(&SphereMeshSpec::uniform(R, s).with_graded(3.0 * s, R / 4.0)).unwrap();
        validate(&graded).unwrap();
        assert!(
            (graded.tets.len() as f64) < 0.8 * uniform.tets.len() as f64,
            "graded {} vs uniform {}",
            graded.tets.len(),
            uniform.tets.len()
        );
        let (qg, qu) = (quality(&graded), quality(&uniform));
        assert!((qg.mean_surface_edge / s - 1.0).abs() < 0.1, "{qg}");
        assert_eq!(qg.surface_facets, qu.surface_facets);
        assert!(qg.min_dihedral_deg > 5.0, "{qg}");
        // Mean edge of the tets in the inner half of the radius: coarse in the graded mesh.
        let core_edge = |m: &TetMesh| {
            let (mut sum, mut n) = (0.0, 0);
            for t in &m.tets {
                let x = t.map(|i| m.nodes[i as usize]);
                let c = scale(add(add(x[0], x[1]), add(x[2], x[3])), 0.25);
                if norm(c) < 0.5 * R {
                    for (i, j) in [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)] {
                        sum += norm(sub(x[i], x[j]));
                        n += 1;
                    }
                }
            }
            sum / n as f64
        };
        assert!(
            core_edge(&graded) > 1.6 * s,
            "graded core edge {}",
            core_edge(&graded)
        );
        assert!(
            (core_edge(&uniform) / s - 1.0).abs() < 0.2,
            "uniform core edge {}",
            core_edge(&uniform)
        );
    }

    #[test]
    fn spec_errors_name_the_field() {
        let ok = SphereMeshSpec::uniform(R, 1e-4);
        ok.validate().unwrap();
        let field = |spec: SphereMeshSpec| match spec.validate() {
            Err(MeshError::InvalidSpec { field, .. }) => field,
            other => panic!("expected an InvalidSpec error, got {other:?}"),
        };
        assert_eq!(field(SphereMeshSpec::uniform(-1.0, 1e-4)), "radius");
        assert_eq!(field(SphereMeshSpec::uniform(f64::NAN, 1e-4)), "radius");
        assert_eq!(field(SphereMeshSpec::uniform(R, 0.0)), "seeding");
        assert_eq!(field(SphereMeshSpec::uniform(R, f64::INFINITY)), "seeding");
        assert_eq!(field(SphereMeshSpec::uniform(R, 2.0 * R)), "seeding");
        assert_eq!(field(ok.clone().with_graded(R, 2e-4)), "graded.band_depth");
        assert_eq!(
            field(ok.clone().with_graded(0.5e-4, 2e-4)),
            "graded.band_depth"
        );
        assert_eq!(
            field(ok.clone().with_graded(3e-4, 0.5e-4)),
            "graded.core_seeding"
        );
        assert_eq!(
            field(ok.clone().with_graded(3e-4, -1.0)),
            "graded.core_seeding"
        );
        assert_eq!(
            field(ok.clone().with_refinement([0.0; 3], 2e-5, 1e-4)),
            "refine[0].direction"
        );
        assert_eq!(
            field(ok.clone().with_refinement([1.0, 0.0, 0.0], 2e-4, 1e-4)),
            "refine[0].seeding"
        );
        let mut bad = ok
            .clone()
            .with_refinement([1.0, 0.0, 0.0], 2e-5, 1e-4)
            .with_refinement([0.0, 1.0, 0.0], 2e-5, -1.0);
        assert_eq!(field(bad.clone()), "refine[1].radius");
        bad.refine[1].radius = 1e-4;
        bad.refine[1].growth = f64::NAN;
        assert_eq!(field(bad.clone()), "refine[1].growth");
        let e = SphereMeshSpec::uniform(R, -1.0).validate().unwrap_err();
        assert_eq!(
            e.to_string(),
            "seeding: must be a positive finite length, got -1"
        );
        // mesh_sphere validates first.
        assert!(matches!(
            mesh_sphere(&SphereMeshSpec::uniform(R, 0.0)),
            Err(MeshError::InvalidSpec { .. })
        ));
    }

    #[test]
    fn spec_reads_from_toml_with_default_growth() {
        let text = r#"
            radius = 1.1e-3
            seeding = 9.9e-5
            graded = { band_depth = 3.0e-4, core_seeding = 2.75e-4 }
            refine = [ { direction = [0, 0, 2], seeding = 2.5e-5, radius = 1e-4 } ]
        "#;
        let spec: SphereMeshSpec = toml::from_str(text).unwrap();
        assert_eq!(spec.refine[0].growth, 0.3);
        assert_eq!(
            spec.graded,
            Some(GradedBand {
                band_depth: 3.0e-4,
                core_seeding: 2.75e-4
            })
        );
        spec.validate().unwrap();
        assert!((spec.meshing_ratio() - 0.045).abs() < 1e-12);
        // Sizing formula: fine at the point, growing with chord distance beyond the zone.
        assert_eq!(spec.surface_size([0.0, 0.0, R]), 2.5e-5);
        let x = [R * 0.6f64.sin(), 0.0, R * 0.6f64.cos()];
        let d = norm(sub(x, [0.0, 0.0, R]));
        assert!((spec.surface_size(x) - (2.5e-5 + 0.3 * (d - 1e-4)).min(9.9e-5)).abs() < 1e-18);
        assert_eq!(spec.surface_size([0.0, 0.0, -R]), 9.9e-5);
        assert!(
            toml::from_str::<SphereMeshSpec>("radius = 1.0\nseeding = 0.1\nbogus = 1").is_err()
        );
    }
}
