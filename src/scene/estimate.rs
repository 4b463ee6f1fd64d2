//! Scale of a scene from its specs alone, before anything is meshed or allocated: elements,
//! nodes, surface triangles, a stable time step, the step count and the memory of a run.
//! Microseconds per distinct shape; every count is checked (no overflow, no NaN).
//!
//! Formulas (V(h) = h³/(6√2) the volume of a regular tet of edge h, A(h) = √3/4·h² the
//! area of an equilateral triangle, B(r) = 4/3·πr³):
//!
//! - **block** nx×ny×nz: exactly 6·nx·ny·nz elements and (nx+1)(ny+1)(nz+1) nodes; the
//!   smallest element size is min(size/divisions).
//! - **sphere** of radius R and seeding s: B(R)/V(s) elements (graded: the band
//!   B(R) − B(R−b) at s and the core B(R−b) at the core seeding rounded to s·2^k, as the
//!   mesher does); 20·n² surface triangles, n = round(1.203 R/s) (the geodesic base).
//!   Each refinement patch (seeding sᵣ, radius r, growth g) adds
//!   ∫₀ᴰ w(d)·[1/V(H(d)) − 1/V(s)] dd elements and ∫₀ᴰ 2πd·[1/A(0.85 H(d)) − 1/A(s)] dd
//!   surface triangles (the element integral × [`PATCH_ELEMENT_FACTOR`]), with H(d) = sᵣ + g·max(0, d − r) the size at distance d from the
//!   patch point, D = min(r + (s − sᵣ)/g, 2R) where H reaches s (2R when g = 0), and
//!   w(d) = 2πd²(1 − d/2R) the area of the sphere of radius d about a surface point that
//!   lies inside the ball (the surface within chord distance d has area πd², hence 2πd).
//!   Surface triangles are bisected until their longest edge is ≤ 1.42 H, which leaves
//!   a mean edge ≈ 0.85 H. Nodes: elements/[`ELEMENTS_PER_NODE`] + surface triangles/2
//!   × [`SURFACE_NODE_SHARE`] (the surface nodes carry fewer tets each). The smallest
//!   element size is min(s, sᵣ).
//! - **time step**: Δt ≈ dt_safety · L / c_p per grain, c_p = √((λ+2G)/ρ) the
//!   dilatational wave speed of its material and L the shape's step length: the smaller of
//!   [`SPHERE_DT_FACTOR`] × seeding and [`PATCH_DT_FACTOR`] × the finest patch for the
//!   smoothed sphere meshes (their worst element is 5–10× shorter in its critical mode than
//!   the seeding), [`SURFACE_DT_FACTOR`] × the smallest size for imported surfaces,
//!   [`BLOCK_DT_FACTOR`] × the cell size for the structured blocks; the smallest over the
//!   grains. The step
//!   used is `simulation.dt`, else `target_dt`, else this estimate; steps = ⌈duration/Δt⌉.
//! - **memory** of a run: [`BYTES_PER_ELEMENT`] per element, [`BYTES_PER_NODE`] per node,
//!   [`BASE_BYTES`] (measured peak RSS of `mufe run`, mesher included), and
//!   [`PLASTIC_BYTES_PER_ELEMENT`] per element of a plastic material.
//!
//! Measured against the built models of every scene in `jobs/` (see docs/INPUT.md).

use super::{MaterialSpec, Scene, ShapeSpec};
use crate::error::InputError;
use crate::mesh::SphereMeshSpec;
use std::collections::BTreeMap;
use std::f64::consts::{PI, SQRT_2};

/// Critical-step factor of the smoothed sphere meshes without refinement patches:
/// Δt_crit ≈ k·h/c_p for the seeding h (a regular tet gives 0.565). Since the edge removal
/// of `mesh::improve` a lone sphere's elements step at 0.25–0.29 (`tests/mesh_stable_step.rs`)
/// and the contact springs of touching grains at ~0.4× that; this value between the two
/// puts the step count within 0.89–1.46× of the real one on the jobs (docs/INPUT.md),
/// over-estimating single grains (the safe side).
pub const SPHERE_DT_FACTOR: f64 = 0.18;
/// The same, relative to the seeding of the finest refinement patch, whose transition to
/// the interior lattice leaves the worst elements (measured 0.09–0.19 on the jobs; also
/// relative to the seeding of a graded mesh, for its band-to-core transition). A patch
/// of radius 0 is a single fine point: with a pinned node its size counts as
/// √(patch seeding × seeding); without one it leaves the worst element to the seeding.
pub const PATCH_DT_FACTOR: f64 = 0.1;
/// The same for meshes of imported surfaces (not smoothed).
pub const SURFACE_DT_FACTOR: f64 = 0.1;
/// Critical-step factor of the structured block meshes (measured 0.51 on cubes).
pub const BLOCK_DT_FACTOR: f64 = 0.5;
/// Elements per interior node of the meshes (measured 5.6–6.3).
pub const ELEMENTS_PER_NODE: f64 = 6.0;
/// Extra nodes per surface node (surface nodes have about half the tets of inner ones).
pub const SURFACE_NODE_SHARE: f64 = 0.5;
/// Measured peak memory of a run per element, per node, and fixed (bytes).
pub const BYTES_PER_ELEMENT: u64 = 250;
pub const BYTES_PER_NODE: u64 = 200;
pub const BASE_BYTES: u64 = 40 << 20;
/// Extra per element of a plastic material: its plastic state (εᵖ, α) and slot index.
pub const PLASTIC_BYTES_PER_ELEMENT: u64 = 60;
/// Steps above which `check`/`run` refuse the scene unless `--force` is given.
pub const MAX_STEPS: u64 = 1_000_000_000;
/// Steps above which a scene is refused outright: beyond 2⁵³ steps the step count and
/// the time t = n·Δt are no longer exact in double precision.
pub const MAX_EXACT_STEPS: f64 = 9_007_199_254_740_992.0;
/// Mean surface edge after bisection, in units of the requested size.
const BISECTED_EDGE: f64 = 0.85;
/// Refinement patches: TetGen's transition from the fine surface to the interior
/// lattice adds elements over the size-field integral (measured 1.1–1.6× on the jobs).
pub const PATCH_ELEMENT_FACTOR: f64 = 1.35;
/// Quadrature intervals per patch integral.
const QUADRATURE: usize = 256;

/// Estimated mesh size of one grain shape.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShapeEstimate {
    pub elements: u64,
    pub nodes: u64,
    pub surface_triangles: u64,
    /// Smallest nominal element edge (m).
    pub min_size: f64,
    /// Length the stable step scales with: Δt ≈ step_length/c_p (m).
    pub step_length: f64,
    /// The field (below `shape.`) that drives the element count.
    pub driver: &'static str,
    /// Index of the refinement patch that drives the count, if one does.
    pub driver_patch: Option<usize>,
}

/// Estimated scale of a whole scene.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneEstimate {
    pub elements: u64,
    pub nodes: u64,
    pub surface_triangles: u64,
    pub per_grain: Vec<ShapeEstimate>,
    /// Estimated stable step (s), dt_safety included, and the grain that sets it.
    pub dt_stable: f64,
    pub critical_grain: usize,
    /// The step that will be used (s) and the field that sets it.
    pub dt: f64,
    pub dt_field: &'static str,
    /// ⌈duration/dt⌉ as a float (may exceed any integer type; checked by the caller).
    pub steps: f64,
    /// Peak memory of a run (bytes).
    pub memory_bytes: u64,
    /// `simulation.duration` (s).
    pub duration: f64,
}

impl SceneEstimate {
    /// The step count as an integer (saturating; the hard bound keeps it ≤ 2⁵³).
    pub fn steps_u64(&self) -> u64 {
        if self.steps.is_finite() && self.steps < 1.8e19 {
            self.steps as u64
        } else {
            u64::MAX
        }
    }

    /// The field that drives the element (and memory) count: the grain with most
    /// elements when it holds at least half of them, else `grains` (their number).
    pub fn size_driver(&self) -> String {
        let Some((i, g)) = self
            .per_grain
            .iter()
            .enumerate()
            .max_by_key(|(_, g)| g.elements)
        else {
            return "grains".into();
        };
        if g.elements.saturating_mul(2) < self.elements {
            return "grains".into();
        }
        match g.driver_patch {
            Some(k) => format!("grains[{i}].shape.sphere.refine[{k}].{}", g.driver),
            None => format!("grains[{i}].shape.{}", g.driver),
        }
    }

    /// One line for `check`: the estimate made before meshing.
    pub fn summary(&self) -> String {
        format!(
            "estimate before meshing: {} elements, {} nodes, {} surface triangles, Δt {:.3e} s ({}), {} steps, memory {:.1} MiB",
            self.elements,
            self.nodes,
            self.surface_triangles,
            self.dt,
            if self.dt_field == "simulation.duration" {
                "estimated stable step"
            } else {
                self.dt_field
            },
            self.steps_u64(),
            self.memory_bytes as f64 / 1048576.0
        )
    }
}

/// The dilatational (P-) wave speed c_p = √((λ+2G)/ρ) of a material (m/s); NaN or ∞
/// for meaningless constants.
pub fn wave_speed(m: &MaterialSpec) -> f64 {
    let (e, nu, rho) = (m.youngs_modulus, m.poisson_ratio, m.density);
    let modulus = e * (1.0 - nu) / ((1.0 + nu) * (1.0 - 2.0 * nu)); // λ + 2G
    (modulus / rho).sqrt()
}

fn regular_tet_volume(h: f64) -> f64 {
    h * h * h / (6.0 * SQRT_2)
}

fn triangle_area(h: f64) -> f64 {
    0.25 * 3f64.sqrt() * h * h
}

fn ball(r: f64) -> f64 {
    4.0 / 3.0 * PI * r * r * r
}

/// A non-negative finite float as a count, or `None` if it does not fit in 2⁶³.
fn to_count(x: f64) -> Option<u64> {
    if (0.0..9.2e18).contains(&x) {
        Some(x.ceil() as u64)
    } else {
        None
    }
}

/// Trapezoid rule of `f` over [a, b] on a grid refined towards `a` (geometric when a > 0).
fn integrate(a: f64, b: f64, f: impl Fn(f64) -> f64) -> f64 {
    if b.is_nan() || a.is_nan() || b <= a {
        return 0.0;
    }
    let n = QUADRATURE;
    let grid = |i: usize| {
        let t = i as f64 / n as f64;
        // quadratic clustering at the start, where 1/H³ is steepest
        a + (b - a) * t * t
    };
    let mut sum = 0.0;
    let (mut x0, mut f0) = (a, f(a));
    for i in 1..=n {
        let x1 = grid(i);
        let f1 = f(x1);
        sum += 0.5 * (f0 + f1) * (x1 - x0);
        (x0, f0) = (x1, f1);
    }
    sum
}

/// Estimated counts of a sphere mesh (see the module documentation). `None` on overflow.
pub fn sphere_estimate(s: &SphereMeshSpec) -> Option<ShapeEstimate> {
    let big_r = s.radius;
    let h = s.seeding;
    let (mut elements, mut driver) = match &s.graded {
        None => (ball(big_r) / regular_tet_volume(h), "sphere.seeding"),
        Some(g) => {
            let k = (g.core_seeding / h).log2().round().clamp(0.0, 60.0);
            let core_h = h * 2f64.powf(k);
            let inner = (big_r - g.band_depth).max(0.0);
            let band = (ball(big_r) - ball(inner)) / regular_tet_volume(h);
            let core = ball(inner) / regular_tet_volume(core_h);
            (
                band + core,
                if core > band {
                    "sphere.graded.core_seeding"
                } else {
                    "sphere.seeding"
                },
            )
        }
    };
    let n = crate::mesh::surface_refine::geodesic_frequency(big_r, h) as f64;
    let mut triangles = 20.0 * n * n;
    let mut min_size = h;
    // a graded band's transition to the coarse core is as bad as a patch's
    let mut step_length = if s.graded.is_some() {
        PATCH_DT_FACTOR * h
    } else {
        SPHERE_DT_FACTOR * h
    };
    let mut driver_patch = None;
    let mut largest_patch = 0.0;
    let (element_overlap, triangle_overlap) = patch_overlap(s);
    for (k, p) in s.refine.iter().enumerate() {
        let (sr, r, g) = (p.seeding, p.radius, p.growth);
        min_size = min_size.min(sr);
        let fine = match (r > 0.0, p.node) {
            (true, _) => Some(sr),
            (false, true) => Some((sr * h).sqrt()),
            (false, false) => None,
        };
        if let Some(fine) = fine {
            step_length = step_length.min(PATCH_DT_FACTOR * fine);
        }
        let (de, dt, reach) = patch_excess(sr, r, g, h, big_r);
        let de = PATCH_ELEMENT_FACTOR * de * element_overlap;
        elements += de.max(0.0);
        triangles += dt.max(0.0) * triangle_overlap;
        if de > largest_patch {
            largest_patch = de;
            if de > 0.5 * elements {
                driver_patch = Some(k);
                driver = if reach >= 2.0 * big_r {
                    "growth"
                } else {
                    "seeding"
                };
            }
        }
    }
    let nodes = elements / ELEMENTS_PER_NODE + SURFACE_NODE_SHARE * triangles / 2.0;
    Some(ShapeEstimate {
        elements: to_count(elements)?,
        nodes: to_count(nodes)?,
        surface_triangles: to_count(triangles)?,
        min_size,
        step_length,
        driver,
        driver_patch,
    })
}

/// Elements and surface triangles a refinement patch (seeding `sr` within `r`, growth `g`)
/// adds to a mesh of seeding `h` on a body of radius `big_r` (the integrals of the module
/// docs, before [`PATCH_ELEMENT_FACTOR`]), and the distance at which its size reaches `h`.
fn patch_excess(sr: f64, r: f64, g: f64, h: f64, big_r: f64) -> (f64, f64, f64) {
    let reach = if g > 0.0 {
        r + (h - sr) / g
    } else {
        f64::INFINITY
    };
    let d_max = reach.min(2.0 * big_r);
    let size = |d: f64| (sr + g * (d - r).max(0.0)).min(h);
    let shell = |d: f64| 2.0 * PI * d * d * (1.0 - d / (2.0 * big_r)).max(0.0);
    let vol_density = |d: f64| 1.0 / regular_tet_volume(size(d)) - 1.0 / regular_tet_volume(h);
    let area_density = |d: f64| {
        1.0 / triangle_area(BISECTED_EDGE * size(d)) - 1.0 / triangle_area(BISECTED_EDGE * h)
    };
    let r_in = r.min(d_max);
    let de = integrate(0.0, r_in, |d| shell(d) * vol_density(d))
        + integrate(r_in, d_max, |d| shell(d) * vol_density(d));
    let dt = integrate(0.0, r_in, |d| 2.0 * PI * d * area_density(d))
        + integrate(r_in, d_max, |d| 2.0 * PI * d * area_density(d));
    (de, dt, reach)
}

/// Share of the patches' summed excess (elements, surface triangles) that remains when
/// they overlap: the excess of their combined size field (the smallest size wins, as in
/// the mesher) over the sum of each one's alone, both by the same quadrature (shells ×
/// Fibonacci directions in the ball, Fibonacci points on the surface). 1 for a single
/// patch or patches far apart.
fn patch_overlap(s: &SphereMeshSpec) -> (f64, f64) {
    const DIRECTIONS: usize = 600;
    const SHELLS: usize = 48;
    if s.refine.len() < 2 {
        return (1.0, 1.0);
    }
    let big_r = s.radius;
    let h = s.seeding;
    let centres: Vec<[f64; 3]> = s
        .refine
        .iter()
        .map(|p| {
            let l = p.direction.iter().map(|c| c * c).sum::<f64>().sqrt();
            p.direction.map(|c| big_r * c / l)
        })
        .collect();
    let size_of = |k: usize, x: [f64; 3]| {
        let p = &s.refine[k];
        let d = (0..3)
            .map(|i| (x[i] - centres[k][i]).powi(2))
            .sum::<f64>()
            .sqrt();
        (p.seeding + p.growth * (d - p.radius).max(0.0)).min(h)
    };
    let golden = PI * (3.0 - 5f64.sqrt());
    let direction = |j: usize, n: usize| {
        let z = 1.0 - 2.0 * (j as f64 + 0.5) / n as f64;
        let r = (1.0 - z * z).sqrt();
        let phi = golden * j as f64;
        [r * phi.cos(), r * phi.sin(), z]
    };
    let (mut comb_v, mut sum_v, mut comb_a, mut sum_a) = (0.0, 0.0, 0.0, 0.0);
    let base_v = 1.0 / regular_tet_volume(h);
    let base_a = 1.0 / triangle_area(BISECTED_EDGE * h);
    for j in 0..DIRECTIONS {
        let u = direction(j, DIRECTIONS);
        for shell in 0..SHELLS {
            let r = big_r * (shell as f64 + 0.5) / SHELLS as f64;
            let x = u.map(|c| c * r);
            let w = r * r; // ∝ volume of the sample (4π r² Δr / DIRECTIONS)
            let mut smallest = h;
            for k in 0..centres.len() {
                let hk = size_of(k, x);
                smallest = smallest.min(hk);
                sum_v += w * (1.0 / regular_tet_volume(hk) - base_v);
            }
            comb_v += w * (1.0 / regular_tet_volume(smallest) - base_v);
        }
        let x = u.map(|c| c * big_r);
        let mut smallest = h;
        for k in 0..centres.len() {
            let hk = size_of(k, x);
            smallest = smallest.min(hk);
            sum_a += 1.0 / triangle_area(BISECTED_EDGE * hk) - base_a;
        }
        comb_a += 1.0 / triangle_area(BISECTED_EDGE * smallest) - base_a;
    }
    let share = |comb: f64, sum: f64| {
        if sum > 0.0 {
            (comb / sum).clamp(0.0, 1.0)
        } else {
            1.0
        }
    };
    (share(comb_v, sum_v), share(comb_a, sum_a))
}

/// Exact counts of a block mesh. `None` on overflow.
pub fn block_estimate(size: [f64; 3], divisions: [usize; 3]) -> Option<ShapeEstimate> {
    let d = divisions.map(|x| x as u64);
    let cells = d[0].checked_mul(d[1])?.checked_mul(d[2])?;
    let elements = cells.checked_mul(6)?;
    let nodes = (d[0].checked_add(1)?)
        .checked_mul(d[1].checked_add(1)?)?
        .checked_mul(d[2].checked_add(1)?)?;
    let inner = d[0].saturating_sub(1) * d[1].saturating_sub(1) * d[2].saturating_sub(1);
    let surface_nodes = nodes - inner;
    let min_size = (0..3)
        .map(|k| size[k] / divisions[k].max(1) as f64)
        .fold(f64::INFINITY, f64::min);
    Some(ShapeEstimate {
        elements,
        nodes,
        surface_triangles: surface_nodes.checked_mul(2)?,
        min_size,
        step_length: BLOCK_DT_FACTOR * min_size,
        driver: "block.divisions",
        driver_patch: None,
    })
}

/// Estimate of one shape. `None` on overflow.
pub fn shape_estimate(shape: &ShapeSpec) -> Option<ShapeEstimate> {
    match shape {
        ShapeSpec::Sphere(s) => sphere_estimate(s),
        ShapeSpec::Block(b) => block_estimate(b.size, b.divisions),
        ShapeSpec::Surface(s) => surface_estimate(s),
    }
}

/// Elements of TetGen's fill of a surface per V/V(h) (measured 3.5 on 20 virtual sand
/// grains at seeding r_eq/5: the `q` bound and the subdivided surface give tets smaller
/// than the regular tet of the seeding; docs/SHAPES.md).
const SURFACE_FILL_FACTOR: f64 = 3.5;
/// Elements of the surface layer per surface triangle (fitted: 27 virtual sand grains of
/// 320 facets at seeding r_eq/2, `jobs/shapes/scene.toml`, where the fill alone gives half
/// the count, within 0.9×; 20 grains of 1280 facets at r_eq/2.5 within 1.2×).
const SURFACE_LAYER_PER_TRIANGLE: f64 = 2.5;
/// Elements per facet of a file finer than the seeding (measured 3.3 on 20 virtual sand
/// grains of 1280 facets at seeding r_eq/2.5).
const SURFACE_ELEMENTS_PER_FACET: f64 = 3.4;

/// Surface shapes, from the geometry checked at load: an MSH volume mesh exactly; else
/// the volume over a regular tet of the seeding, the surface at the seeding or the file's
/// facets, whichever is finer, and the shortest edge of the file or the seeding.
fn surface_estimate(s: &crate::mesh::import::SurfaceSpec) -> Option<ShapeEstimate> {
    let g = s.geometry.as_ref()?;
    if let Some((elements, nodes)) = g.volume_mesh {
        return Some(ShapeEstimate {
            elements: elements as u64,
            nodes: nodes as u64,
            surface_triangles: g.facets as u64,
            min_size: g.min_edge,
            step_length: SURFACE_DT_FACTOR * g.min_edge,
            driver: "surface.file",
            driver_patch: None,
        });
    }
    let h = s.seeding;
    if let Some((facets, smallest)) = g.remeshed {
        return remeshed_estimate(s, g, facets, smallest);
    }
    let mut triangles = (2.0 * g.descriptors.area / (3f64.sqrt() * h * h / 2.0))
        .max(g.facets as f64)
        .ceil();
    // The fill plus TetGen's layer on the surface triangles (it dominates small grains);
    // a file finer than the seeding drives the count: TetGen grades from its facets.
    let mut elements = (SURFACE_FILL_FACTOR * g.descriptors.volume / regular_tet_volume(h)
        + SURFACE_LAYER_PER_TRIANGLE * triangles)
        .max(SURFACE_ELEMENTS_PER_FACET * g.facets as f64)
        .ceil();
    let min_size = s
        .refine
        .iter()
        .map(|z| z.seeding)
        .fold(h.min(g.min_edge), f64::min);
    let (de, dt) = zone_excess(s, g);
    elements += de;
    triangles += dt;
    if !(elements < 9e18 && triangles < 9e18) {
        return None;
    }
    Some(ShapeEstimate {
        elements: elements.max(1.0) as u64,
        nodes: (elements / ELEMENTS_PER_NODE + SURFACE_NODE_SHARE * triangles / 2.0) as u64 + 4,
        surface_triangles: triangles as u64,
        min_size,
        step_length: SURFACE_DT_FACTOR * min_size,
        driver: if s.refine.is_empty() {
            "surface.seeding"
        } else {
            "surface.refine"
        },
        driver_patch: None,
    })
}

/// Elements and surface triangles the `refine` zones add: the sphere's patch integrals on
/// the equal-volume sphere (the zones' lattice is the sphere mesher's; measured within 6 %
/// on jobs/validation/hertz_ellipsoid), rounded up per zone.
fn zone_excess(
    s: &crate::mesh::import::SurfaceSpec,
    g: &crate::mesh::import::SurfaceGeometry,
) -> (f64, f64) {
    s.refine.iter().fold((0.0, 0.0), |(e, t), z| {
        let (de, dt, _) = patch_excess(
            z.seeding,
            z.radius,
            z.growth,
            s.seeding,
            g.descriptors.equivalent_radius,
        );
        (
            e + (PATCH_ELEMENT_FACTOR * de).max(0.0).ceil(),
            t + dt.max(0.0).ceil(),
        )
    })
}

/// A remeshed surface (the default): its facets are the size field's (computed at load,
/// zones and curvature included), its interior the sphere mesher's lattice — V/V(h)
/// elements (measured 0.94–1.04 on virtual sand grains at seeding r_eq/5 and r_eq/10,
/// 0.66 at r_eq/2) — plus, per `refine` zone, the sphere's patch integral for the finer
/// interior, and [`SURFACE_LAYER_PER_TRIANGLE`] elements per facet that curvature sizing
/// adds beyond the seeding's and the zones'.
fn remeshed_estimate(
    s: &crate::mesh::import::SurfaceSpec,
    g: &crate::mesh::import::SurfaceGeometry,
    facets: f64,
    smallest: f64,
) -> Option<ShapeEstimate> {
    let h = s.seeding;
    let (de, dt) = zone_excess(s, g);
    let expected = g.descriptors.area / (0.25 * 3f64.sqrt() * h * h) + dt;
    let elements = g.descriptors.volume / regular_tet_volume(h)
        + de
        + SURFACE_LAYER_PER_TRIANGLE * (facets - expected).max(0.0);
    let triangles = facets.ceil();
    if !(elements < 9e18 && triangles < 9e18) {
        return None;
    }
    Some(ShapeEstimate {
        elements: elements.ceil().max(1.0) as u64,
        nodes: (elements / ELEMENTS_PER_NODE + SURFACE_NODE_SHARE * triangles / 2.0) as u64 + 4,
        surface_triangles: triangles as u64,
        min_size: smallest,
        step_length: SURFACE_DT_FACTOR * smallest,
        driver: match (s.refine.is_empty(), s.curvature.is_some()) {
            (_, true) => "surface.curvature",
            (false, false) => "surface.refine",
            (true, false) => "surface.seeding",
        },
        driver_patch: None,
    })
}

/// Estimates a scene whose fields have passed the per-field checks (positive sizes,
/// known materials). An overflowing count is an input error naming the grain's shape.
pub fn estimate_scene(file: &str, scene: &Scene) -> Result<SceneEstimate, InputError> {
    let too_big = |field: String| {
        InputError::new(
            file,
            field,
            "the mesh this asks for has more elements than can be counted (> 9e18); use a coarser mesh",
        )
    };
    let mut cache: BTreeMap<String, ShapeEstimate> = BTreeMap::new();
    let mut per_grain = Vec::with_capacity(scene.grains.len());
    let (mut elements, mut nodes, mut triangles) = (0u64, 0u64, 0u64);
    let mut plastic_elements = 0u64;
    let sim = &scene.simulation;
    let (mut dt_stable, mut critical_grain) = (f64::INFINITY, 0);
    for (i, g) in scene.grains.iter().enumerate() {
        let key = serde_json::to_string(&g.shape).unwrap_or_default();
        let est = match cache.get(&key) {
            Some(e) => *e,
            None => {
                let e = shape_estimate(&g.shape)
                    .ok_or_else(|| too_big(format!("grains[{i}].shape")))?;
                cache.insert(key, e);
                e
            }
        };
        let field = || format!("grains[{i}].shape");
        elements = elements
            .checked_add(est.elements)
            .ok_or_else(|| too_big(field()))?;
        nodes = nodes
            .checked_add(est.nodes)
            .ok_or_else(|| too_big(field()))?;
        triangles = triangles
            .checked_add(est.surface_triangles)
            .ok_or_else(|| too_big(field()))?;
        let c = scene
            .materials
            .get(&g.material)
            .map_or(f64::NAN, wave_speed);
        if scene
            .materials
            .get(&g.material)
            .is_some_and(|m| m.yield_stress.is_some())
        {
            plastic_elements = plastic_elements.saturating_add(est.elements);
        }
        let dt = sim.dt_safety * est.step_length / c;
        if dt < dt_stable {
            (dt_stable, critical_grain) = (dt, i);
        }
        per_grain.push(est);
    }
    let (dt, dt_field) = match (sim.dt, sim.target_dt) {
        (Some(d), _) => (d, "simulation.dt"),
        (None, Some(t)) => (t, "simulation.target_dt"),
        (None, None) => (dt_stable, "simulation.duration"),
    };
    let steps = (sim.duration / dt).ceil();
    let memory_bytes = elements
        .checked_mul(BYTES_PER_ELEMENT)
        .and_then(|e| nodes.checked_mul(BYTES_PER_NODE)?.checked_add(e))
        .and_then(|b| b.checked_add(plastic_elements.checked_mul(PLASTIC_BYTES_PER_ELEMENT)?))
        .and_then(|b| b.checked_add(BASE_BYTES))
        .unwrap_or(u64::MAX);
    Ok(SceneEstimate {
        elements,
        nodes,
        surface_triangles: triangles,
        per_grain,
        dt_stable,
        critical_grain,
        dt,
        dt_field,
        steps,
        memory_bytes,
        duration: sim.duration,
    })
}

/// Memory this machine can give a run (bytes): `MemAvailable` from /proc/meminfo, else
/// `MemTotal`; `None` where there is no /proc/meminfo.
pub fn machine_memory() -> Option<(u64, &'static str)> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let field = |name: &str| -> Option<u64> {
        let line = text.lines().find(|l| l.starts_with(name))?;
        let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
        kb.checked_mul(1024)
    };
    field("MemAvailable:")
        .map(|b| (b, "MemAvailable"))
        .or_else(|| field("MemTotal:").map(|b| (b, "MemTotal")))
}

/// The memory a run may use: this machine's ([`machine_memory`]), lowered by the
/// environment variable `MUFE_MEMORY_LIMIT` (bytes, or with a `K`, `M`, `G` suffix for
/// KiB, MiB, GiB) where set — for shared nodes and CI.
pub fn memory_limit() -> Result<Option<(u64, &'static str)>, InputError> {
    let machine = machine_memory();
    let Some(raw) = std::env::var_os("MUFE_MEMORY_LIMIT") else {
        return Ok(machine);
    };
    let text = raw.to_string_lossy();
    let t = text.trim();
    let (digits, shift) = match t.char_indices().last() {
        Some((i, 'K' | 'k')) => (&t[..i], 10),
        Some((i, 'M' | 'm')) => (&t[..i], 20),
        Some((i, 'G' | 'g')) => (&t[..i], 30),
        _ => (t, 0),
    };
    let bytes = digits
        .trim()
        .parse::<u64>()
        .ok()
        .and_then(|n| n.checked_mul(1u64 << shift))
        .filter(|&b| b > 0)
        .ok_or_else(|| {
            InputError::new(
                "<environment>",
                "MUFE_MEMORY_LIMIT",
                format!(
                    "'{}' is not a positive byte count (e.g. 512M, 2G)",
                    crate::error::echo(t)
                ),
            )
        })?;
    Ok(Some(match machine {
        Some((m, source)) if m < bytes => (m, source),
        _ => (bytes, "MUFE_MEMORY_LIMIT"),
    }))
}

/// The resource guard of `check`, `run` and `partition`: refuses (one line, exit 2) a
/// scene whose estimated memory exceeds `memory` (bytes, and where that figure comes
/// from) or, with `max_steps`, that needs more steps. `--force` skips it.
pub fn guard(
    file: &str,
    est: &SceneEstimate,
    memory: Option<(u64, &str)>,
    max_steps: Option<u64>,
) -> Result<(), InputError> {
    if let Some((available, source)) = memory {
        if est.memory_bytes > available {
            return Err(InputError::new(
                file,
                est.size_driver(),
                format!(
                    "the scene would need about {:.3e} elements, {:.3e} nodes and {:.1} GiB of memory (estimate before meshing), more than the {:.1} GiB available ({source}); use a coarser mesh, or --force to try anyway",
                    est.elements as f64,
                    est.nodes as f64,
                    est.memory_bytes as f64 / (1u64 << 30) as f64,
                    available as f64 / (1u64 << 30) as f64
                ),
            ));
        }
    }
    if let Some(limit) = max_steps {
        if est.steps.is_nan() || est.steps > limit as f64 {
            return Err(InputError::new(
                file,
                est.dt_field,
                format!(
                    "{:.3e} s / Δt {:.3e} s = {:.3e} steps, more than the limit of {limit:.0e}; use a shorter duration or a larger step, or --force to run anyway",
                    est.duration,
                    est.dt,
                    est.steps
                ),
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uniform_sphere_matches_the_mesher_within_ten_percent() {
        let spec = SphereMeshSpec::uniform(1.1e-3, 2.0e-4);
        let est = sphere_estimate(&spec).unwrap();
        let mesh = crate::mesh::mesh_sphere(&spec).unwrap();
        let ratio = est.elements as f64 / mesh.tets.len() as f64;
        assert!((0.9..1.1).contains(&ratio), "elements ratio {ratio}");
        let ratio = est.nodes as f64 / mesh.nodes.len() as f64;
        assert!((0.8..1.25).contains(&ratio), "nodes ratio {ratio}");
    }

    #[test]
    fn block_counts_are_exact_and_checked() {
        let e = block_estimate([1.0; 3], [4, 3, 2]).unwrap();
        assert_eq!(e.elements, 6 * 24);
        assert_eq!(e.nodes, 5 * 4 * 3);
        assert!(block_estimate([1.0; 3], [usize::MAX, 2, 2]).is_none());
        assert!(block_estimate([1.0; 3], [1 << 30, 1 << 30, 1 << 30]).is_none());
    }

    #[test]
    fn overlapping_patches_are_not_counted_twice() {
        let one =
            SphereMeshSpec::uniform(1.1e-3, 3.0e-4).with_refinement([0.0, 0.0, 1.0], 1e-4, 0.0);
        let twice = one.clone().with_refinement([0.0, 0.0, 1.0], 1e-4, 0.0);
        let (a, b) = (
            sphere_estimate(&one).unwrap(),
            sphere_estimate(&twice).unwrap(),
        );
        let rel = |x: u64, y: u64| (x as f64 / y as f64 - 1.0).abs();
        assert!(
            rel(b.elements, a.elements) < 0.02,
            "{} vs {}",
            b.elements,
            a.elements
        );
        assert!(rel(b.surface_triangles, a.surface_triangles) < 0.02);
        // far apart (opposite poles), each counts in full
        let apart = one.clone().with_refinement([0.0, 0.0, -1.0], 1e-4, 0.0);
        let c = sphere_estimate(&apart).unwrap();
        let base = sphere_estimate(&SphereMeshSpec::uniform(1.1e-3, 3.0e-4)).unwrap();
        let excess = |e: &ShapeEstimate| e.elements as f64 - base.elements as f64;
        assert!((excess(&c) / (2.0 * excess(&a)) - 1.0).abs() < 0.02);
    }

    #[test]
    fn zero_growth_spreads_the_patch_over_the_sphere() {
        let mut spec =
            SphereMeshSpec::uniform(1.1e-3, 1.5e-4).with_refinement([0.0, 0.0, 1.0], 1e-5, 1e-5);
        let graded = sphere_estimate(&spec).unwrap();
        spec.refine[0].growth = 0.0;
        let flat = sphere_estimate(&spec).unwrap();
        let fine = sphere_estimate(&SphereMeshSpec::uniform(1.1e-3, 1e-5)).unwrap();
        assert!(flat.elements > 100 * graded.elements);
        // the whole sphere at the patch seeding, with the patch transition factor
        let ratio = flat.elements as f64 / (PATCH_ELEMENT_FACTOR * fine.elements as f64);
        assert!((0.9..1.1).contains(&ratio), "ratio {ratio}");
        assert_eq!(flat.driver, "growth");
    }
}
