//! Sphere mesher: uniform, graded (fine surface band, coarse core) and locally refined
//! (fine patches around chosen surface points, e.g. the expected contacts).

use serde::{Deserialize, Serialize};

use super::surface_refine::triangulate_sphere;
use super::tetgen::{tetrahedralize, Region};
use super::{norm, scale, sub, validate, MeshError, TetMesh};

/// TetGen's maximum radius–edge ratio (`-q`). With the interior seeded by a lattice TetGen
/// rarely needs to refine; 1.5 keeps the transition zones (skin, band/core gap, refinement
/// patches) well shaped.
pub(crate) const RADIUS_EDGE_RATIO: f64 = 1.5;

/// BCC lattice constant in units of the nominal edge length: the Delaunay tets of a BCC
/// lattice (Sommerville tets, dihedral angles 60° and 90°) have edges a and a·√3/2, so
/// a = 1.07 h gives a mean edge ≈ h.
const LATTICE_FACTOR: f64 = 1.07;

/// No lattice point closer than `SKIN_DEPTH × seeding` to the surface: the layer of tets on
/// the surface triangles is left to TetGen (a regular tet is 0.82 h high). Interior points
/// much closer than that would sit inside the surface triangles' diametral balls, where
/// TetGen would split the surface instead of keeping the requested seeding.
const SKIN_DEPTH: f64 = 0.7;

/// Graded meshes: below the band the interior size grows by this much per unit depth until
/// it reaches the core size (a gentle ramp keeps the 2:1 lattice transitions well shaped).
const CORE_GROWTH: f64 = 0.5;

/// Safety bound on tet volume (× the regular tet of the coarsest nominal size): never
/// active on a lattice-seeded ball, it only prevents huge elements should TetGen leave a gap.
const VOLUME_SAFETY: f64 = 4.0;

/// Volume of a regular tet of edge `h`.
fn regular_tet_volume(h: f64) -> f64 {
    h * h * h / (6.0 * std::f64::consts::SQRT_2)
}

fn tuning(name: &str, default: f64) -> f64 {
    std::env::var(name).ok().and_then(|v| v.parse().ok()).unwrap_or(default)
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
/// gives a bitwise identical mesh. Tets are positively oriented.
///
/// 1. The surface is triangulated by [`triangulate_sphere`] with the spec's sizing function.
/// 2. The interior is seeded with points of a body-centred cubic lattice (spacing ≈ seeding;
///    for graded meshes a fine lattice in the band and a coarse one in the core), kept
///    `SKIN_DEPTH·s` below the surface.
/// 3. TetGen tetrahedralises surface + points (the points are isolated PLC vertices) and only
///    refines where the radius–edge bound requires it: in the skin, in the band/core gap
///    and under refinement patches, where the interior grades naturally from the surface.
///
/// Seeding the interior ourselves instead of giving TetGen volume bounds keeps the surface
/// exactly as triangulated (volume-driven Steiner points near the surface make TetGen split
/// surface triangles, ≈ 3× the requested facets at MR 0.045), gives well-shaped lattice tets
/// inside, and is ~2× faster.
///
/// The work is done at unit radius (TetGen's tolerances are relative and its volume bounds go
/// through text) and scaled back by R.
pub fn mesh_sphere(spec: &SphereMeshSpec) -> Result<TetMesh, MeshError> {
    mesh_sphere_with_ratio(spec, RADIUS_EDGE_RATIO)
}

/// [`mesh_sphere`] with an explicit TetGen radius–edge bound.
pub(crate) fn mesh_sphere_with_ratio(spec: &SphereMeshSpec, radius_edge_ratio: f64) -> Result<TetMesh, MeshError> {
    spec.validate()?;
    let big_r = spec.radius;
    let inv = 1.0 / big_r;

    // Unit-sphere sizing function: the spec's formula with all lengths divided by R.
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
    let surface = triangulate_sphere(1.0, s, size, "seeding")?;
    if std::env::var("MUFE_DEBUG").is_ok() {
        let mut lo = f64::MAX;
        let mut hmin = f64::MAX;
        for t in &surface.triangles {
            for k in 0..3 {
                let l = norm(sub(surface.points[t[k] as usize], surface.points[t[(k + 1) % 3] as usize]));
                lo = lo.min(l);
            }
        }
        for p in &surface.points { hmin = hmin.min(size(*p)); }
        let mut maxang: f64 = 0.0; let mut nobt = 0; let mut nenc = 0;
        for t in &surface.triangles {
            let p = t.map(|i| surface.points[i as usize]);
            for k in 0..3 {
                let e1 = sub(p[(k + 1) % 3], p[k]);
                let e2 = sub(p[(k + 2) % 3], p[k]);
                let a = (super::dot(e1, e2) / (norm(e1) * norm(e2))).acos().to_degrees();
                maxang = maxang.max(a);
                if a > 89.0 { nobt += 1; }
                if a > 90.0 { nenc += 1; }
            }
        }
        eprintln!("max angle {maxang:.2}, >89: {nobt}, >90: {nenc}");
        eprintln!("surface: {} tris, {} pts, min edge {:.3e} (unit), min size {:.3e}", surface.triangles.len(), surface.points.len(), lo, hmin);
    }
    let mut points = surface.points;
    let facets = surface.triangles;

    let lattice = tuning("MUFE_LF", LATTICE_FACTOR);
    let skin = tuning("MUFE_SKIN", SKIN_DEPTH);
    let growth = tuning("MUFE_GROWTH", CORE_GROWTH);
    // Interior size field H(p): the patches' formula with 3D distances, under a background
    // of s (uniform) or s in the band growing to the core size below it (graded). Nested
    // BCC lattices of constant a·2^(C−ℓ) fill the places where H ≈ s·2^(C−ℓ): level 0 is the
    // core (C = log₂(core/s) rounded, 0 if not graded), level C the seeding, levels above
    // C the refinement patches.
    let (band, coarse_levels) = match &spec.graded {
        None => (1.0, 0u32),
        Some(g) => (g.band_depth * inv, (g.core_seeding / spec.seeding).log2().round().max(0.0) as u32),
    };
    let core = s * (1u64 << coarse_levels) as f64;
    let fine_levels = refine
        .iter()
        .map(|&(_, sr, _, _)| (s / sr).log2().round().max(0.0) as u32)
        .max()
        .unwrap_or(0);
    let field = |p: [f64; 3]| {
        let depth = 1.0 - norm(p);
        let mut h = core.min(s + growth * (depth - band).max(0.0));
        for &(c, sr, rr, g) in &refine {
            h = h.min(sr + g * (norm(sub(p, c)) - rr).max(0.0));
        }
        h
    };
    let whole: Vec<Aabb> = vec![([-1.0; 3], [1.0; 3])];
    let mut boxes = vec![whole.clone(); coarse_levels as usize + 1];
    let rot_t = transpose(&rotation(1));
    for l in 1..=fine_levels {
        // Where the size is below the level's threshold: balls around the patches.
        let threshold = s * 2f64.powf(0.5 - l as f64);
        let mut level_boxes = Vec::new();
        for &(p, sr, rr, g) in &refine {
            if sr > threshold {
                continue;
            }
            if g == 0.0 {
                level_boxes = whole.clone();
                break;
            }
            let reach = rr + (threshold - sr) / g;
            let c = mat_vec(&rot_t, p);
            level_boxes.push((c.map(|x| (x - reach).max(-1.0)), c.map(|x| (x + reach).min(1.0))));
        }
        boxes.push(level_boxes);
    }
    let top = (coarse_levels + fine_levels) as f64;
    add_nested_bcc(
        lattice * core,
        &boxes,
        |p| {
            let h = field(p);
            if 1.0 - norm(p) < skin * h {
                return None;
            }
            Some((coarse_levels as f64 + (s / h).log2().round()).clamp(0.0, top) as u32)
        },
        &mut points,
    );
    let coarsest = core;

    // Interior points must stay out of the surface triangles' diametral balls: TetGen
    // (with -q) splits any subface whose ball holds a vertex, and the splits cascade.
    let n_surface = facets.iter().flatten().map(|&i| i as usize + 1).max().unwrap_or(0);
    let guard = DiametralBalls::new(&points[..n_surface], &facets, tuning("MUFE_MARGIN", BALL_MARGIN));
    let mut k = n_surface;
    for i in n_surface..points.len() {
        if !guard.encroaches(points[i]) {
            points[k] = points[i];
            k += 1;
        }
    }
    points.truncate(k);
    if std::env::var("MUFE_NOLAT").is_ok() {
        points.truncate(n_surface);
    }

    let regions =
        [Region { point: [0.0; 3], marker: 1, max_volume: Some(VOLUME_SAFETY * regular_tet_volume(coarsest)) }];

    let mut mesh = tetrahedralize(&points, &facets, &regions, radius_edge_ratio)?;
    for p in mesh.nodes.iter_mut() {
        *p = scale(*p, big_r);
    }
    validate(&mesh)?;
    Ok(mesh)
}

/// Relative margin around the surface triangles' diametral balls kept free of lattice points.
const BALL_MARGIN: f64 = 0.15;

/// The diametral balls (circumscribed balls centred in the triangle's plane) of the surface
/// triangles, bucketed on a uniform grid of cell ≥ the largest inflated radius so that a
/// query checks 27 cells.
struct DiametralBalls {
    cell: f64,
    grid: std::collections::HashMap<[i64; 3], Vec<u32>>,
    balls: Vec<([f64; 3], f64)>,
}

impl DiametralBalls {
    fn new(points: &[[f64; 3]], facets: &[[u32; 3]], margin: f64) -> Self {
        let mut balls: Vec<([f64; 3], f64)> = facets
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| points[i as usize]);
                let (ab, ac) = (sub(b, a), sub(c, a));
                let n = super::cross(ab, ac);
                let num = super::add(
                    scale(super::cross(n, ab), super::dot(ac, ac)),
                    scale(super::cross(ac, n), super::dot(ab, ab)),
                );
                let off = scale(num, 0.5 / super::dot(n, n));
                let r = (1.0 + margin) * norm(off);
                (super::add(a, off), r * r)
            })
            .collect();
        // Segment (edge) diametral balls: each edge once, from the facet where it ascends.
        for t in facets {
            for k in 0..3 {
                let (i, j) = (t[k], t[(k + 1) % 3]);
                if i < j {
                    let (a, b) = (points[i as usize], points[j as usize]);
                    let r = 0.5 * (1.0 + margin) * norm(sub(b, a));
                    balls.push((scale(super::add(a, b), 0.5), r * r));
                }
            }
        }
        let cell = balls.iter().map(|b| b.1).fold(0.0, f64::max).sqrt().max(1e-9);
        let mut grid: std::collections::HashMap<[i64; 3], Vec<u32>> = std::collections::HashMap::new();
        for (i, b) in balls.iter().enumerate() {
            grid.entry(b.0.map(|x| (x / cell).floor() as i64)).or_default().push(i as u32);
        }
        Self { cell, grid, balls }
    }

    /// True if `p` lies inside an (inflated) diametral ball.
    fn encroaches(&self, p: [f64; 3]) -> bool {
        let c = p.map(|x| (x / self.cell).floor() as i64);
        for di in -1..=1 {
            for dj in -1..=1 {
                for dk in -1..=1 {
                    if let Some(list) = self.grid.get(&[c[0] + di, c[1] + dj, c[2] + dk]) {
                        for &i in list {
                            let (centre, r2) = self.balls[i as usize];
                            let d = sub(p, centre);
                            if super::dot(d, d) < r2 {
                                return true;
                            }
                        }
                    }
                }
            }
        }
        false
    }
}

/// Axis-aligned box (min corner, max corner) in the lattice frame.
type Aabb = ([f64; 3], [f64; 3]);

/// Appends points of nested body-centred cubic lattices inside the unit ball. The lattices
/// are rotated by a fixed rotation so that no lattice plane lines up with the icosahedral
/// surface.
///
/// Level ℓ has lattice constant `a0`/2^ℓ and is visited only inside `boxes[ℓ]` (lattice
/// frame; level 0 should cover the ball). `want(p)` rejects a point (`None`) or gives the
/// level of detail wanted at p; a point is kept if it is wanted at a level ≥ the coarsest
/// lattice it belongs to. Since BCC(a) ⊂ BCC(a/2), each point is examined once, at its
/// coarsest level, so the levels form one conforming point set with no duplicates; the
/// BCC Delaunay tets (Sommerville tets) are well shaped and TetGen only repairs the level
/// transitions. Deterministic order.
fn add_nested_bcc<F: Fn([f64; 3]) -> Option<u32>>(
    a0: f64,
    boxes: &[Vec<Aabb>],
    want: F,
    points: &mut Vec<[f64; 3]>,
) {
    let rot = rotation(1);
    let inside = |b: &Aabb, x: [f64; 3]| (0..3).all(|d| x[d] >= b.0[d] && x[d] <= b.1[d]);
    for (l, level_boxes) in boxes.iter().enumerate() {
        // Half-lattice integer coordinates q: lattice-frame point = q · half; BCC points have
        // q all even (cube corners) or all odd (cube centres).
        let half = 0.5 * a0 / (1u64 << l) as f64;
        for (b, bx) in level_boxes.iter().enumerate() {
            let lo = bx.0.map(|c| (c / half).floor() as i64);
            let hi = bx.1.map(|c| (c / half).ceil() as i64);
            for qi in lo[0]..=hi[0] {
                for qj in lo[1]..=hi[1] {
                    for qk in lo[2]..=hi[2] {
                        let q = [qi, qj, qk];
                        let parity = qi.rem_euclid(2);
                        if q.iter().any(|c| c.rem_euclid(2) != parity) {
                            continue;
                        }
                        // Member of the next coarser lattice: q/2 integer with uniform parity.
                        if l > 0 && parity == 0 {
                            let p2 = (qi / 2).rem_euclid(2);
                            if q.iter().all(|c| (c / 2).rem_euclid(2) == p2) {
                                continue;
                            }
                        }
                        let x = q.map(|c| c as f64 * half);
                        if !inside(bx, x) || level_boxes[..b].iter().any(|other| inside(other, x)) {
                            continue;
                        }
                        let p = mat_vec(&rot, x);
                        if super::dot(p, p) >= 1.0 {
                            continue;
                        }
                        if want(p).is_some_and(|w| w as usize >= l) {
                            points.push(p);
                        }
                    }
                }
            }
        }
    }
}

fn transpose(m: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    [[m[0][0], m[1][0], m[2][0]], [m[0][1], m[1][1], m[2][1]], [m[0][2], m[1][2], m[2][2]]]
}

/// A fixed rotation: angle 0.7·k rad about an irrational axis.
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
        let mrs: Vec<f64> = std::env::var("MUFE_MR").unwrap_or("0.09,0.045".into()).split(',').map(|x| x.parse().unwrap()).collect();
        for mr in mrs {
            for &q in &qs {
                for graded in [0, 1, 2] {
                    let s = mr * 2.0 * r;
                    let mut spec = SphereMeshSpec::uniform(r, s);
                    if graded == 1 {
                        spec = spec.with_graded(3.0 * s, r / 4.0);
                    }
                    if graded == 2 {
                        spec = spec.with_refinement([0.0, 0.0, 1.0], s / 4.0, 2.0 * s);
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
