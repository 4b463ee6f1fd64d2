//! Local refinement of an imported surface grain around given points (`refine = [...]` of
//! a surface shape): fine facets *and* fine elements below them.
//!
//! The size field is h(x) = min(seeding, minᵢ(sᵢ + gᵢ·max(0, |x − pᵢ| − rᵢ))), as for the
//! sphere's patches but with 3-D distances. The surface is remeshed to it (on the file's
//! facets: refining a coarse file adds no curvature, so a curved contact needs a file that
//! is already fine there), and the interior is seeded with the sphere mesher's nested BCC
//! lattices ([`super::super::lattice`]) — at the seeding over the whole body, finer within
//! reach of each point — kept a skin depth below the surface and out of the surface's
//! diametral balls. Without the interior
//! points TetGen grades from the fine facets as fast as its radius–edge bound allows:
//! elements as large as their depth below the surface, which made a 10–20 µm Hertz contact
//! ~30 % too stiff (`mufe validate hertz_ellipsoid`, docs/BENCHMARKS.md).

use serde::{Deserialize, Serialize};

use super::Surface;
use crate::math::{norm, point_triangle_distance, sub};
use crate::mesh::lattice::{
    add_nested_bcc, lattice_rotation, mat_vec, transpose, Aabb, DiametralBalls, BALL_MARGIN,
    LATTICE_FACTOR, SKIN_DEPTH,
};

/// A zone of finer elements around a point of an imported shape.
///
/// ```toml
/// refine = [{ point = [0.0, 0.0, 7.5e-4], seeding = 2e-6, radius = 1.5e-5, growth = 0.12 }]
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SurfaceRefinement {
    /// Centre of the zone in the grain frame (m, after units and scale, relative to the
    /// grain's origin, before rotation): usually a point of the surface where a contact
    /// will be.
    pub point: [f64; 3],
    /// Element edge within `radius` of the point (m).
    pub seeding: f64,
    /// Radius of the zone where `seeding` holds (m).
    pub radius: f64,
    /// Growth of the edge length with the distance beyond the zone (–, default 0.3).
    #[serde(default = "default_growth")]
    pub growth: f64,
}

fn default_growth() -> f64 {
    0.3
}

/// The size field of the zones under a global seeding.
#[derive(Debug, Clone, Copy)]
pub struct SizeField<'a> {
    pub seeding: f64,
    pub zones: &'a [SurfaceRefinement],
}

impl SizeField<'_> {
    /// Edge length wanted at x (m).
    pub fn at(&self, x: [f64; 3]) -> f64 {
        self.zones.iter().fold(self.seeding, |h, z| {
            h.min(z.seeding + z.growth * (norm(sub(x, z.point)) - z.radius).max(0.0))
        })
    }

    /// Distance from a zone's point within which its size is below `h`.
    fn reach(z: &SurfaceRefinement, h: f64) -> f64 {
        z.radius + ((h - z.seeding) / z.growth).max(0.0)
    }
}

/// Triangles bucketed on a uniform grid, for "is any facet within r of p" and "is p
/// inside" (parity of the crossings of a ray along +x).
struct SurfaceQuery<'a> {
    s: &'a Surface,
    cell: f64,
    grid: std::collections::HashMap<[i64; 3], Vec<u32>>,
    /// (y, z) columns of cells for the ray casts.
    columns: std::collections::HashMap<[i64; 2], Vec<u32>>,
}

impl<'a> SurfaceQuery<'a> {
    fn new(s: &'a Surface, cell: f64) -> Self {
        let mut grid: std::collections::HashMap<[i64; 3], Vec<u32>> = Default::default();
        let mut columns: std::collections::HashMap<[i64; 2], Vec<u32>> = Default::default();
        for (t, f) in s.facets.iter().enumerate() {
            let pts = f.map(|i| s.points[i as usize]);
            let lo = [0, 1, 2].map(|k| {
                (pts.iter().map(|p| p[k]).fold(f64::INFINITY, f64::min) / cell).floor() as i64
            });
            let hi = [0, 1, 2].map(|k| {
                (pts.iter().map(|p| p[k]).fold(f64::NEG_INFINITY, f64::max) / cell).floor() as i64
            });
            for j in lo[1]..=hi[1] {
                for k in lo[2]..=hi[2] {
                    columns.entry([j, k]).or_default().push(t as u32);
                    for i in lo[0]..=hi[0] {
                        grid.entry([i, j, k]).or_default().push(t as u32);
                    }
                }
            }
        }
        Self {
            s,
            cell,
            grid,
            columns,
        }
    }

    fn triangle(&self, t: u32) -> [[f64; 3]; 3] {
        self.s.facets[t as usize].map(|i| self.s.points[i as usize])
    }

    /// True if a facet lies within `r` of `p`.
    fn near(&self, p: [f64; 3], r: f64) -> bool {
        let lo = p.map(|c| ((c - r) / self.cell).floor() as i64);
        let hi = p.map(|c| ((c + r) / self.cell).floor() as i64);
        for i in lo[0]..=hi[0] {
            for j in lo[1]..=hi[1] {
                for k in lo[2]..=hi[2] {
                    for &t in self.grid.get(&[i, j, k]).map_or(&[][..], |v| &v[..]) {
                        let [a, b, c] = self.triangle(t);
                        if point_triangle_distance(p, a, b, c) < r {
                            return true;
                        }
                    }
                }
            }
        }
        false
    }

    /// Inside the closed surface: an odd number of facets crossed by the ray p + t·x̂, t > 0.
    /// (Lattice points sit at irrational offsets, so rays through edges do not occur in
    /// practice.)
    fn inside(&self, p: [f64; 3]) -> bool {
        let key = [
            (p[1] / self.cell).floor() as i64,
            (p[2] / self.cell).floor() as i64,
        ];
        let mut crossings = 0;
        for &t in self.columns.get(&key).map_or(&[][..], |v| &v[..]) {
            let [a, b, c] = self.triangle(t);
            // barycentric coordinates of (y, z) in the projected triangle
            let det = (b[1] - a[1]) * (c[2] - a[2]) - (c[1] - a[1]) * (b[2] - a[2]);
            if det == 0.0 {
                continue;
            }
            let u = ((p[1] - a[1]) * (c[2] - a[2]) - (c[1] - a[1]) * (p[2] - a[2])) / det;
            let v = ((b[1] - a[1]) * (p[2] - a[2]) - (p[1] - a[1]) * (b[2] - a[2])) / det;
            if u < 0.0 || v < 0.0 || u + v > 1.0 {
                continue;
            }
            let x = a[0] + u * (b[0] - a[0]) + v * (c[0] - a[0]);
            if x > p[0] {
                crossings += 1;
            }
        }
        crossings % 2 == 1
    }
}

/// Interior points that make the tets follow the size field: the seeding's lattice over
/// the whole body, finer levels near the zones (`s` the surface as it will be meshed, the
/// same frame as the zones).
pub fn interior_points(s: &Surface, field: SizeField) -> Vec<[f64; 3]> {
    let big = field.seeding;
    let finest = field.zones.iter().map(|z| z.seeding).fold(big, f64::min);
    let levels = (big / finest).log2().round().max(0.0) as u32;
    let rot_t = transpose(&lattice_rotation());
    // level ℓ (size big/2^ℓ) is visited inside the boxes of the balls where h < big·2^(½−ℓ);
    // level 0 over the whole reach of each zone
    let mut boxes: Vec<Vec<Aabb>> = (0..=levels)
        .map(|l| {
            let threshold = if l == 0 {
                big
            } else {
                big * 2f64.powf(0.5 - l as f64)
            };
            field
                .zones
                .iter()
                .filter(|z| z.seeding < threshold)
                .map(|z| {
                    let reach = SizeField::reach(z, threshold);
                    let c = mat_vec(&rot_t, z.point);
                    (c.map(|x| x - reach), c.map(|x| x + reach))
                })
                .collect()
        })
        .collect();
    // the whole body at the seeding: level 0 over the surface's box (lattice frame)
    let corners = s.points.iter().map(|p| mat_vec(&rot_t, *p));
    let (lo, hi) = corners.fold(
        ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]),
        |(lo, hi), c| {
            (
                [0, 1, 2].map(|k| lo[k].min(c[k])),
                [0, 1, 2].map(|k| hi[k].max(c[k])),
            )
        },
    );
    boxes[0] = vec![(lo, hi)];
    let longest = s
        .facets
        .iter()
        .flat_map(|f| (0..3).map(move |k| (f[k], f[(k + 1) % 3])))
        .map(|(a, b)| norm(sub(s.points[a as usize], s.points[b as usize])))
        .fold(0.0, f64::max);
    let query = SurfaceQuery::new(s, longest.max(big).max(1e-300));
    let guard = DiametralBalls::new(&s.points, &s.facets, BALL_MARGIN);
    let mut points = Vec::new();
    add_nested_bcc(
        LATTICE_FACTOR * big,
        &boxes,
        |p| {
            let h = field.at(p);
            if query.near(p, SKIN_DEPTH * h) || guard.encroaches(p) || !query.inside(p) {
                return None;
            }
            Some(((big / h).log2().round()).clamp(0.0, levels as f64) as u32)
        },
        &mut points,
    );
    points
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::import::checks::tests::cube;

    #[test]
    fn inside_and_near_on_a_cube() {
        let s = cube();
        let q = SurfaceQuery::new(&s, 0.5);
        assert!(q.inside([0.31, 0.52, 0.47]));
        assert!(!q.inside([1.31, 0.52, 0.47]));
        assert!(!q.inside([-0.2, 0.52, 0.47]));
        assert!(q.near([0.05, 0.5, 0.5], 0.1) && !q.near([0.5, 0.5, 0.5], 0.3));
    }

    #[test]
    fn zone_points_are_inside_graded_and_clear_of_the_surface() {
        let s = cube();
        let zone = SurfaceRefinement {
            point: [0.5, 0.5, 1.0],
            seeding: 0.02,
            radius: 0.05,
            growth: 0.3,
        };
        let field = SizeField {
            seeding: 0.25,
            zones: std::slice::from_ref(&zone),
        };
        // as `fill` does: the surface is subdivided to the field first (a coarse facet's
        // diametral ball would reach deep inside and keep every lattice point out)
        let fine = super::super::refine::subdivide_to(&s, |x| field.at(x), 1_000_000).unwrap();
        let pts = interior_points(&fine, field);
        assert!(pts.len() > 100, "{}", pts.len());
        for p in &pts {
            assert!(p.iter().all(|&c| c > 0.0 && c < 1.0), "{p:?} outside");
            let h = field.at(*p);
            let depth = [p[0], 1.0 - p[0], p[1], 1.0 - p[1], p[2], 1.0 - p[2]]
                .into_iter()
                .fold(f64::INFINITY, f64::min);
            assert!(
                depth >= SKIN_DEPTH * h * 0.999,
                "{p:?} depth {depth} < skin of h {h}"
            );
        }
        // finer near the point: the nearest neighbour spacing grows with the distance
        let spacing = |c: [f64; 3], r: f64| {
            let near: Vec<&[f64; 3]> = pts.iter().filter(|p| norm(sub(**p, c)) < r).collect();
            near.len()
        };
        let close = spacing([0.5, 0.5, 0.9], 0.05);
        let far = spacing([0.5, 0.5, 0.4], 0.05);
        assert!(
            close > 10 * far.max(1),
            "{close} points near the zone, {far} far"
        );
    }
}
