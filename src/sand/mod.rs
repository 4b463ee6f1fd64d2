//! Virtual sand: a deterministic generator of irregular grains for tests and demos
//! (`mufe sand`). Each grain is a star-shaped surface r(u)·u over the directions u of a
//! geodesic icosphere: an ellipsoid of semi-axes a ≥ b ≥ c (a/b = elongation, b/c =
//! flatness) times 1 + Σₖ Aₖ sin(lₖ π nₖ·u + φₖ), a sum of random plane waves on the unit
//! sphere of "degree" lₖ = 2…7 and amplitude ∝ roughness / lₖ (low degrees round the
//! grain unevenly, high ones roughen it), then scaled to the requested equivalent
//! diameter. A star-shaped surface over a convex triangulation with r > 0 is closed,
//! outward (every facet spans a positive cone from the centre) and never self-intersecting
//! (each facet stays inside its own cone), so the files pass the import checks by
//! construction.

mod box_scene;
mod scene;

pub use box_scene::write_sand_box;
pub use scene::{write_sand, write_sand_image};

use crate::math::{add, norm, scale, SplitMix64};
use crate::mesh::import::{ShapeDescriptors, Surface};

/// Parameters of the generated grains.
#[derive(Debug, Clone, PartialEq)]
pub struct SandParams {
    pub grains: usize,
    pub seed: u64,
    /// a/b ≥ 1.
    pub elongation: f64,
    /// b/c ≥ 1.
    pub flatness: f64,
    /// Relative amplitude of the surface waves, 0 ≤ roughness ≤ 0.3.
    pub roughness: f64,
    /// Equivalent (equal-volume sphere) diameter (m).
    pub size: f64,
    /// Mesh seeding written into the scene (m).
    pub seeding: f64,
    /// Icosphere subdivision level of the surfaces (20·4^level facets).
    pub level: u32,
}

impl Default for SandParams {
    fn default() -> Self {
        SandParams {
            grains: 8,
            seed: 1,
            elongation: 1.4,
            flatness: 1.25,
            roughness: 0.08,
            size: 1e-3,
            seeding: 2e-4,
            level: 3,
        }
    }
}

/// Number of plane waves summed per grain.
const WAVES: usize = 12;

/// The star-shaped grain `index` of a sand: r(u) = ellipsoid(u)·max(1 + waves(u), ½) in
/// the generator's frame, then shifted by the faceted surface's centroid and scaled to the
/// requested size.
pub struct GrainShape {
    waves: Vec<(f64, [f64; 3], f64, f64)>,
    semi_axes: [f64; 3],
    /// Centroid of the faceted surface in the generator's frame.
    centroid: [f64; 3],
    /// Metres per generator unit.
    scale: f64,
}

impl GrainShape {
    pub fn new(p: &SandParams, index: usize) -> Self {
        let mut rng = SplitMix64(
            p.seed.wrapping_mul(0x2545_f491_4f6c_dd1d) ^ (index as u64).wrapping_mul(0x9e37_79b9),
        );
        let waves: Vec<(f64, [f64; 3], f64, f64)> = (0..WAVES)
            .map(|_| {
                let degree = 2.0 + (rng.unit() * 6.0).floor();
                let amplitude = p.roughness * (2.0 * rng.unit() - 1.0) / degree;
                (
                    degree,
                    rng.direction(),
                    2.0 * std::f64::consts::PI * rng.unit(),
                    amplitude,
                )
            })
            .collect();
        let c = 1.0;
        let b = c * p.flatness;
        let a = b * p.elongation;
        let mut shape = GrainShape {
            waves,
            semi_axes: [a, b, c],
            centroid: [0.0; 3],
            scale: 1.0,
        };
        let mut s = icosphere(p.level);
        for u in s.points.iter_mut() {
            *u = scale(*u, shape.radius_along(*u));
        }
        let d = ShapeDescriptors::of(&s);
        shape.centroid = d.centroid;
        shape.scale = 0.5 * p.size / d.equivalent_radius;
        shape
    }

    /// Radius along the unit vector `u` from the generator's origin (generator units).
    fn radius_along(&self, u: [f64; 3]) -> f64 {
        let [a, b, c] = self.semi_axes;
        let ellipsoid = 1.0 / ((u[0] / a).powi(2) + (u[1] / b).powi(2) + (u[2] / c).powi(2)).sqrt();
        let wave: f64 = self
            .waves
            .iter()
            .map(|&(l, n, phase, amp)| {
                amp * (l * std::f64::consts::PI * crate::math::dot(n, u) + phase).sin()
            })
            .sum();
        ellipsoid * (1.0 + wave).max(0.5)
    }

    /// |x|/r(x/|x|) of a point `x` relative to the grain's centroid (m): < 1 inside the
    /// smooth shape (the faceted surface is its icosphere interpolation).
    pub fn depth_ratio(&self, x: [f64; 3]) -> f64 {
        let g = add(scale(x, 1.0 / self.scale), self.centroid);
        let r = norm(g);
        if r == 0.0 {
            return 0.0;
        }
        r / self.radius_along(scale(g, 1.0 / r))
    }

    /// Largest distance of the smooth shape from the centroid (m), bounded from the
    /// semi-axes and the wave amplitudes.
    pub fn bounding_radius(&self) -> f64 {
        let amplitude: f64 = self.waves.iter().map(|w| w.3.abs()).sum();
        (self.semi_axes[0] * (1.0 + amplitude) + norm(self.centroid)) * self.scale
    }
}

/// The surface of grain `index` (metres, centred on its volume centroid).
pub fn grain_surface(p: &SandParams, index: usize) -> Surface {
    let shape = GrainShape::new(p, index);
    let mut s = icosphere(p.level);
    for u in s.points.iter_mut() {
        let g = scale(*u, shape.radius_along(*u));
        *u = scale(crate::math::sub(g, shape.centroid), shape.scale);
    }
    s
}

/// Geodesic icosphere of the unit sphere, 20·4^level outward facets.
pub fn icosphere(level: u32) -> Surface {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut points: Vec<[f64; 3]> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .iter()
    .map(|p| scale(*p, 1.0 / norm(*p)))
    .collect();
    let mut facets: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..level {
        let mut mid = std::collections::HashMap::new();
        let mut midpoint = |a: u32, b: u32, points: &mut Vec<[f64; 3]>| {
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                let m = add(points[a as usize], points[b as usize]);
                points.push(scale(m, 1.0 / norm(m)));
                (points.len() - 1) as u32
            })
        };
        let mut next = Vec::with_capacity(4 * facets.len());
        for f in &facets {
            let x = midpoint(f[0], f[1], &mut points);
            let y = midpoint(f[1], f[2], &mut points);
            let z = midpoint(f[2], f[0], &mut points);
            next.extend([[f[0], x, z], [x, f[1], y], [z, y, f[2]], [x, y, z]]);
        }
        facets = next;
    }
    Surface { points, facets }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::import::checks::check;

    #[test]
    fn grains_are_valid_deterministic_and_of_the_requested_size() {
        let p = SandParams {
            roughness: 0.2,
            ..SandParams::default()
        };
        let a = grain_surface(&p, 3);
        check(&a).unwrap();
        assert_eq!(a, grain_surface(&p, 3));
        assert_ne!(a, grain_surface(&p, 4));
        let d = ShapeDescriptors::of(&a);
        assert!((d.equivalent_radius - 0.5e-3).abs() < 1e-12);
        assert!(d.centroid.iter().all(|c| c.abs() < 1e-15));
        assert!(d.sphericity < 0.99 && d.elongation() < 0.95, "{d}");
        let ico = icosphere(2);
        assert_eq!(ico.facets.len(), 320);
        check(&ico).unwrap();
    }
}
