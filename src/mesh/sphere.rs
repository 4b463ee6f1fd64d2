//! Sphere mesher: uniform, graded (fine surface band, coarse core) and locally refined
//! (fine patches around chosen surface points, e.g. the expected contacts).

use serde::{Deserialize, Serialize};

use super::surface_refine::triangulate_sphere;
use super::tetgen::{tetrahedralize, Region};
use super::{norm, scale, sub, validate, MeshError, TetMesh};

/// TetGen's maximum radius–edge ratio (`-q`). 1.5 gives well-shaped tets without the
/// element-count blow-up of tighter bounds; TetGen's optimisation pass then removes most
/// slivers (which the radius–edge bound alone does not catch).
pub(crate) const RADIUS_EDGE_RATIO: f64 = 1.5;

/// Volume of a regular tet of edge `h` is h³/(6√2); TetGen's Delaunay tets of nominal size h
/// are smaller than regular ones, so the bound is relaxed by this factor.
const VOLUME_SLACK: f64 = 1.5;

/// Depth of the skin layer (no volume bound) under the surface, in seeding units: about the
/// height of one regular tet (0.82 s).
const SKIN_DEPTH: f64 = 0.8;

/// Maximum tet volume for a zone of nominal edge length `h`.
fn max_tet_volume(h: f64) -> f64 {
    let slack = std::env::var("MUFE_SLACK").ok().and_then(|v| v.parse().ok()).unwrap_or(VOLUME_SLACK);
    if slack <= 0.0 { return 1e3; }
    slack * h * h * h / (6.0 * std::f64::consts::SQRT_2)
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
    MeshError::InvalidSpec {
        field: field.into(),
        message: message.into(),
    }
}

fn check_positive(field: &str, v: f64) -> Result<(), MeshError> {
    if !v.is_finite() || v <= 0.0 {
        return Err(invalid(
            field,
            format!("must be a positive finite length, got {v}"),
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
        });
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
                format!(
                    "{} is larger than the radius {} (meshing ratio > 0.5)",
                    self.seeding, self.radius
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
                        g.band_depth, self.radius
                    ),
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
                    format!(
                        "{} must not be finer than the surface seeding {}",
                        g.core_seeding, self.seeding
                    ),
                ));
            }
            if g.core_seeding > self.radius {
                return Err(invalid(
                    "graded.core_seeding",
                    format!(
                        "{} is larger than the radius {}",
                        g.core_seeding, self.radius
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
                        r.seeding, self.seeding
                    ),
                ));
            }
            if r.seeding < 1e-4 * self.radius {
                return Err(invalid(
                    f("seeding"),
                    format!(
                        "{} is below 1e-4 × radius {}: too fine to mesh",
                        r.seeding, self.radius
                    ),
                ));
            }
            if !r.radius.is_finite() || r.radius < 0.0 {
                return Err(invalid(
                    f("radius"),
                    format!("must be a finite length ≥ 0, got {}", r.radius),
                ));
            }
            if !r.growth.is_finite() || r.growth < 0.0 {
                return Err(invalid(
                    f("growth"),
                    format!("must be finite and ≥ 0, got {}", r.growth),
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

/// Meshes the sphere described by `spec` (validated first). Deterministic: the same spec
/// gives a bitwise identical mesh. Tets are positively oriented; TetGen may add Steiner
/// points on the (flat) surface facets.
///
/// The work is done at unit radius (TetGen's tolerances are relative and its volume bounds
/// go through text) and scaled back by R.
pub fn mesh_sphere(spec: &SphereMeshSpec) -> Result<TetMesh, MeshError> {
    mesh_sphere_with_ratio(spec, RADIUS_EDGE_RATIO)
}

/// [`mesh_sphere`] with an explicit TetGen radius–edge bound.
pub(crate) fn mesh_sphere_with_ratio(spec: &SphereMeshSpec, radius_edge_ratio: f64) -> Result<TetMesh, MeshError> {
    spec.validate()?;
    let big_r = spec.radius;
    let inv = 1.0 / big_r;

    // Unit-sphere sizing function: same formula with all lengths divided by R.
    let refine: Vec<([f64; 3], f64, f64, f64)> = spec
        .refine
        .iter()
        .map(|r| {
            (
                scale(r.direction, 1.0 / norm(r.direction)),
                r.seeding * inv,
                r.radius * inv,
                r.growth,
            )
        })
        .collect();
    let s = spec.seeding * inv;
    let size = |x: [f64; 3]| {
        let mut h = s;
        for &(p, sr, rr, g) in &refine {
            h = h.min(sr + g * (norm(sub(x, p)) - rr).max(0.0));
        }
        h
    };
    let outer = triangulate_sphere(1.0, s, size, "seeding")?;

    // Nested internal spheres (facets of the PLC) split the ball into regions, outermost
    // first: (shell radius, max tet volume of the region inside that shell).
    //
    // The skin between the surface and the first internal shell gets no volume bound:
    // volume-driven Steiner points within ~0.6 s of the surface encroach on the surface
    // triangles' diametral balls and TetGen would split them (measured: ≈ 3× the requested
    // surface facets), so the skin is shaped by the surface and the radius–edge bound only.
    let skin = skin_depth() * s;
    let mut shells: Vec<(f64, f64, Option<f64>, &str)> = Vec::new(); // (radius, size, vol inside, field)
    match &spec.graded {
        None => shells.push((1.0 - skin, s, Some(max_tet_volume(s)), "seeding")),
        Some(g) => {
            let band = g.band_depth * inv;
            let core = g.core_seeding * inv;
            if band > 2.0 * skin {
                shells.push((1.0 - skin, s, Some(max_tet_volume(s)), "graded.band_depth"));
            }
            // Band/core interface at a size between the two zones.
            let r_in = 1.0 - band;
            let h_in = (s * core).sqrt().min(r_in);
            shells.push((r_in, h_in, Some(max_tet_volume(core)), "graded.band_depth"));
        }
    }

    let outer_count = outer.points.len();
    let mut points = outer.points;
    let mut facets = outer.triangles;
    let mut regions = Vec::with_capacity(shells.len() + 1);
    // Polyhedron just outside the next shell: its first vertex (exactly on its sphere) and
    // the radius of the largest ball it contains.
    let mut outer_vertex = points[0];
    let mut outer_radius = 1.0;
    let mut outer_inscribed = inscribed_radius(&points, &facets);
    for (k, &(r, h, vol_inside, field)) in shells.iter().enumerate() {
        if r >= outer_inscribed * (1.0 - 1e-9) {
            return Err(invalid(field, "too thin a layer for the surface chords at this seeding"));
        }
        // Each shell is rotated so its vertices do not line up radially with the ones
        // outside (aligned points make cospherical prisms, i.e. slivers).
        let shell = triangulate_sphere(r, h, |_| h, field)?;
        let rot = rotation(k + 1);
        let off = points.len() as u32;
        let shell_points: Vec<[f64; 3]> = shell.points.iter().map(|&p| mat_vec(&rot, p)).collect();
        // Region between the previous polyhedron and this shell: along the ray to the outer
        // polyhedron's vertex, halfway between the two spheres.
        let volume_above = if k == 0 { None } else { shells[k - 1].2 };
        regions.push(Region {
            point: scale(outer_vertex, 0.5 * (outer_radius + r) / outer_radius),
            marker: k as i32 + 1,
            max_volume: volume_above,
        });
        let shell_facets: Vec<[u32; 3]> = shell.triangles.clone();
        outer_inscribed = inscribed_radius(&shell_points, &shell_facets);
        outer_vertex = shell_points[0];
        outer_radius = r;
        points.extend_from_slice(&shell_points);
        facets.extend(shell_facets.iter().map(|t| t.map(|i| i + off)));
        let _ = vol_inside;
    }
    // Innermost region, around the centre.
    regions.push(Region {
        point: [0.0; 3],
        marker: shells.len() as i32 + 1,
        max_volume: shells.last().and_then(|x| x.2),
    });

    if std::env::var("MUFE_MODE").map(|m| m == "lattice").unwrap_or(false) {
        let nsurf = outer_count;
        points.truncate(nsurf);
        facets.retain(|t| (t[0] as usize) < nsurf);
        regions.clear();
        let rot = rotation(1);
        let mut add_lattice = |a: f64, rmin: f64, rmax: f64, points: &mut Vec<[f64; 3]>| {
            let m = (rmax / a).ceil() as i64 + 1;
            for i in -m..=m {
                for j in -m..=m {
                    for k in -m..=m {
                        for off in [0.0, 0.5] {
                            let p = [(i as f64 + off) * a, (j as f64 + off) * a, (k as f64 + off) * a];
                            let p = mat_vec(&rot, p);
                            let r = norm(p);
                            if r <= rmax && r >= rmin {
                                points.push(p);
                            }
                        }
                    }
                }
            }
        };
        let lf: f64 = std::env::var("MUFE_LF").ok().and_then(|v| v.parse().ok()).unwrap_or(1.07);
        match &spec.graded {
            None => add_lattice(lf * s, 0.0, 1.0 - skin, &mut points),
            Some(g) => {
                let band = g.band_depth * inv;
                let core = g.core_seeding * inv;
                add_lattice(lf * s, 1.0 - band, 1.0 - skin, &mut points);
                add_lattice(lf * core, 0.0, 1.0 - band - 0.5 * core, &mut points);
            }
        }
        regions.push(Region { point: [0.0; 3], marker: 1, max_volume: None });
    }
    let mut mesh = tetrahedralize(&points, &facets, &regions, radius_edge_ratio)?;
    for p in mesh.nodes.iter_mut() {
        *p = scale(*p, big_r);
    }
    validate(&mesh)?;
    Ok(mesh)
}

/// Radius of the largest ball about the origin inside the convex polyhedron `facets`
/// (vertices on a sphere about the origin): the smallest facet-plane distance.
fn inscribed_radius(points: &[[f64; 3]], facets: &[[u32; 3]]) -> f64 {
    facets
        .iter()
        .map(|t| {
            let p = t.map(|i| points[i as usize]);
            let n = super::cross(sub(p[1], p[0]), sub(p[2], p[0]));
            super::dot(n, p[0]).abs() / norm(n)
        })
        .fold(f64::INFINITY, f64::min)
}

/// Depth of the unconstrained skin layer, in units of the seeding.
fn skin_depth() -> f64 {
    std::env::var("MUFE_SKIN").ok().and_then(|v| v.parse().ok()).unwrap_or(SKIN_DEPTH)
}

/// A fixed rotation for internal shell `k`: angle 0.7·k rad about an irrational axis.
fn rotation(k: usize) -> [[f64; 3]; 3] {
    let axis = [1.0, (1.0 + 5f64.sqrt()) / 2.0, std::f64::consts::E];
    let l = norm(axis);
    let [x, y, z] = axis.map(|c| c / l);
    let (sn, c) = (0.7 * k as f64).sin_cos();
    let t = 1.0 - c;
    [
        [t * x * x + c, t * x * y - sn * z, t * x * z + sn * y],
        [t * x * y + sn * z, t * y * y + c, t * y * z - sn * x],
        [t * x * z - sn * y, t * y * z + sn * x, t * z * z + c],
    ]
}

fn mat_vec(m: &[[f64; 3]; 3], v: [f64; 3]) -> [f64; 3] {
    [super::dot(m[0], v), super::dot(m[1], v), super::dot(m[2], v)]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::quality;

    #[test]
    #[ignore]
    fn explore() {
        let r = 1.1e-3;
        let qs: Vec<f64> = std::env::var("MUFE_Q").unwrap().split(',').map(|x| x.parse().unwrap()).collect();
        for mr in [0.09, 0.045] {
            for &q in &qs {
                for graded in [false, true] {
                    let s = mr * 2.0 * r;
                    let mut spec = SphereMeshSpec::uniform(r, s);
                    if graded {
                        spec = spec.with_graded(3.0 * s, r / 4.0);
                    }
                    let t0 = std::time::Instant::now();
                    let m = mesh_sphere_with_ratio(&spec, q).unwrap();
                    let dt = t0.elapsed();
                    let qr = quality(&m);
                    let n = crate::mesh::surface_refine::geodesic_frequency(r, s);
                    eprintln!("MR {mr} q {q} graded {graded}: {:.2?} input tris {} {qr}", dt, 20 * n * n);
                }
            }
        }
    }
}
