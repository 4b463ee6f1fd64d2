//! Sphere mesher: uniform, graded (fine surface band, coarse core) and locally refined
//! (fine patches around chosen surface points, e.g. the expected contacts).

use serde::{Deserialize, Serialize};

use super::surface_refine::{triangulate_sphere, SphereSurface};
use super::tetgen::{tetrahedralize, Region};
use super::{norm, scale, sub, validate, MeshError, TetMesh};

/// TetGen's maximum radius–edge ratio (`-q`). 1.5 gives well-shaped tets without the
/// element-count blow-up of tighter bounds; TetGen's optimisation pass then removes most
/// slivers (which the radius–edge bound alone does not catch).
pub(crate) const RADIUS_EDGE_RATIO: f64 = 1.5;

/// Volume of a regular tet of edge `h` is h³/(6√2); TetGen's Delaunay tets of nominal size h
/// are smaller than regular ones, so the bound is relaxed by this factor.
const VOLUME_SLACK: f64 = 1.5;

/// Maximum tet volume for a zone of nominal edge length `h`.
fn max_tet_volume(h: f64) -> f64 {
    VOLUME_SLACK * h * h * h / (6.0 * std::f64::consts::SQRT_2)
}

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
/// ones (≈ `core_seeding`) inside it. Implemented with an internal spherical facet surface at
/// radius R − band_depth and a TetGen volume bound per region.
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
}

fn default_growth() -> f64 {
    0.3
}

fn invalid(field: impl Into<String>, message: impl Into<String>) -> MeshError {
    MeshError::InvalidSpec { field: field.into(), message: message.into() }
}

fn check_positive(field: &str, v: f64) -> Result<(), MeshError> {
    if !v.is_finite() || v <= 0.0 {
        return Err(invalid(field, format!("must be a positive finite length, got {v}")));
    }
    Ok(())
}

impl SphereMeshSpec {
    /// Uniform mesh of seeding `seeding`.
    pub fn uniform(radius: f64, seeding: f64) -> Self {
        Self { radius, seeding, graded: None, refine: Vec::new() }
    }

    /// Uniform mesh at meshing ratio MR = s/(2R) (the paper's parameter).
    pub fn from_meshing_ratio(radius: f64, meshing_ratio: f64) -> Self {
        Self::uniform(radius, meshing_ratio * 2.0 * radius)
    }

    /// Adds a fine band of `band_depth` over a core of `core_seeding`.
    pub fn with_graded(mut self, band_depth: f64, core_seeding: f64) -> Self {
        self.graded = Some(GradedBand { band_depth, core_seeding });
        self
    }

    /// Adds a local refinement patch (growth 0.3).
    pub fn with_refinement(mut self, direction: [f64; 3], seeding: f64, radius: f64) -> Self {
        self.refine.push(LocalRefinement { direction, seeding, radius, growth: default_growth() });
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
        if self.seeding > self.radius {
            return Err(invalid(
                "seeding",
                format!("{} is larger than the radius {} (meshing ratio > 0.5)", self.seeding, self.radius),
            ));
        }
        if let Some(g) = &self.graded {
            check_positive("graded.band_depth", g.band_depth)?;
            check_positive("graded.core_seeding", g.core_seeding)?;
            if g.band_depth >= self.radius {
                return Err(invalid(
                    "graded.band_depth",
                    format!("{} must be smaller than the radius {}", g.band_depth, self.radius),
                ));
            }
            if g.band_depth < self.seeding {
                return Err(invalid(
                    "graded.band_depth",
                    format!(
                        "{} must be at least one surface element deep (≥ seeding {})",
                        g.band_depth, self.seeding
                    ),
                ));
            }
            if g.core_seeding < self.seeding {
                return Err(invalid(
                    "graded.core_seeding",
                    format!("{} must not be finer than the surface seeding {}", g.core_seeding, self.seeding),
                ));
            }
            if g.core_seeding > self.radius {
                return Err(invalid(
                    "graded.core_seeding",
                    format!("{} is larger than the radius {}", g.core_seeding, self.radius),
                ));
            }
        }
        for (i, r) in self.refine.iter().enumerate() {
            let f = |name: &str| format!("refine[{i}].{name}");
            let d = r.direction;
            if !d.iter().all(|x| x.is_finite()) || norm(d) == 0.0 {
                return Err(invalid(f("direction"), format!("must be a finite non-zero vector, got {d:?}")));
            }
            check_positive(&f("seeding"), r.seeding)?;
            if r.seeding > self.seeding {
                return Err(invalid(
                    f("seeding"),
                    format!("{} is coarser than the global seeding {}: no refinement", r.seeding, self.seeding),
                ));
            }
            if r.seeding < 1e-4 * self.radius {
                return Err(invalid(
                    f("seeding"),
                    format!("{} is below 1e-4 × radius {}: too fine to mesh", r.seeding, self.radius),
                ));
            }
            if !r.radius.is_finite() || r.radius < 0.0 {
                return Err(invalid(f("radius"), format!("must be a finite length ≥ 0, got {}", r.radius)));
            }
            if !r.growth.is_finite() || r.growth < 0.0 {
                return Err(invalid(f("growth"), format!("must be finite and ≥ 0, got {}", r.growth)));
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

/// Meshes the sphere described by `spec` (validated first). Deterministic: the same spec
/// gives a bitwise identical mesh. Tets are positively oriented; TetGen may add Steiner
/// points on the (flat) surface facets.
///
/// The work is done at unit radius (TetGen's tolerances are relative and its volume bounds
/// go through text) and scaled back by R.
pub fn mesh_sphere(spec: &SphereMeshSpec) -> Result<TetMesh, MeshError> {
    spec.validate()?;
    let big_r = spec.radius;
    let inv = 1.0 / big_r;

    // Unit-sphere sizing function: same formula with all lengths divided by R.
    let refine: Vec<([f64; 3], f64, f64, f64)> = spec
        .refine
        .iter()
        .map(|r| (scale(r.direction, 1.0 / norm(r.direction)), r.seeding * inv, r.radius * inv, r.growth))
        .collect();
    let s = spec.seeding * inv;
    let size = |x: [f64; 3]| {
        let mut h = s;
        for &(p, sr, rr, g) in &refine {
            h = h.min(sr + g * (norm(sub(x, p)) - rr).max(0.0));
        }
        h
    };
    let outer = triangulate_sphere(1.0, size, "seeding")?;

    let mut points = outer.points;
    let mut facets = outer.triangles;
    let mut regions = Vec::with_capacity(2);
    match &spec.graded {
        None => regions.push(Region { point: [0.0; 3], marker: 1, max_volume: Some(max_tet_volume(s)) }),
        Some(g) => {
            let band = g.band_depth * inv;
            let core = g.core_seeding * inv;
            let r_in = 1.0 - band;
            // Internal surface at a size between the two zones, resolved at least as finely
            // as an icosahedron allows.
            let h_in = (s * core).sqrt().min(r_in);
            let inner: SphereSurface = triangulate_sphere(r_in, |_| h_in, "graded.core_seeding")?;
            // The outer polyhedron contains the ball of radius min over facets of the facet
            // plane distance; the inner polyhedron lies within r_in. They must not touch.
            let d_min = facets
                .iter()
                .map(|t| plane_distance(t.map(|i| points[i as usize])))
                .fold(f64::INFINITY, f64::min);
            if r_in >= d_min * (1.0 - 1e-9) {
                return Err(invalid(
                    "graded.band_depth",
                    format!("{} is too thin for the surface chords of seeding {}", g.band_depth, spec.seeding),
                ));
            }
            let off = points.len() as u32;
            points.extend_from_slice(&inner.points);
            facets.extend(inner.triangles.iter().map(|t| t.map(|i| i + off)));
            // Band point: along the ray to outer vertex 0 (exactly on the sphere), halfway
            // between the inner sphere and the surface.
            let dir = points[0];
            regions.push(Region { point: scale(dir, r_in + 0.5 * band), marker: 1, max_volume: Some(max_tet_volume(s)) });
            regions.push(Region { point: [0.0; 3], marker: 2, max_volume: Some(max_tet_volume(core)) });
        }
    }

    let mut mesh = tetrahedralize(&points, &facets, &regions, RADIUS_EDGE_RATIO)?;
    for p in mesh.nodes.iter_mut() {
        *p = scale(*p, big_r);
    }
    validate(&mesh)?;
    Ok(mesh)
}

/// Distance from the origin to the plane of triangle `p` (vertices on a sphere about it).
fn plane_distance(p: [[f64; 3]; 3]) -> f64 {
    let n = super::cross(sub(p[1], p[0]), sub(p[2], p[0]));
    super::dot(n, p[0]).abs() / norm(n)
}
