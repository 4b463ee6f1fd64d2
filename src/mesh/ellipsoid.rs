//! Triangulated ellipsoid surfaces with fine patches at the ends of its z axis, for
//! curved non-spherical contact (`mufe validate hertz_ellipsoid` writes them as STL and
//! imports them like any grain surface).
//!
//! The surface is a unit sphere triangulated by [`triangulate_sphere`] (geodesic base,
//! conforming bisection where the size field asks for it, acute triangles, the two poles
//! pinned as vertices) and stretched by diag(A, B, C): every vertex lies exactly on
//! x²/A² + y²/B² + z²/C² = 1 and the tips (0, 0, ±C) are vertices. Near a pole the
//! stretch is A along x and B along y, so the sphere is refined at size/max(A, B) there
//! and the ellipsoid's facets are at most the requested size.

use super::import::Surface;
use super::surface_refine::{triangulate_sphere, Pin};
use super::MeshError;
use crate::math::{norm, sub};

/// Edge lengths of an ellipsoid surface with fine tips.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TipRefinedEllipsoid {
    /// Semi-axes along x, y, z (m).
    pub semi_axes: [f64; 3],
    /// Facet edge away from the tips (m).
    pub seeding: f64,
    /// Facet edge within `tip_radius` of each tip (m).
    pub tip_seeding: f64,
    /// Distance from the tip (m, measured in the plane of the tip) within which
    /// `tip_seeding` holds.
    pub tip_radius: f64,
    /// Growth of the edge length with the distance beyond `tip_radius` (–).
    pub growth: f64,
}

impl TipRefinedEllipsoid {
    /// The closed, outward surface (m), facets ≤ `seeding`, ≤ `tip_seeding` at the tips.
    pub fn surface(&self) -> Result<Surface, MeshError> {
        let [a, b, c] = self.semi_axes;
        let lateral = a.max(b);
        let stretch = lateral.max(c);
        // sizes on the unit sphere: a unit length near a pole becomes ≤ max(A, B)
        let base = self.seeding / stretch;
        let (tip, reach) = (self.tip_seeding / lateral, self.tip_radius / lateral);
        let growth = self.growth;
        let size = move |u: [f64; 3]| {
            let d = norm(sub(u, [0.0, 0.0, 1.0])).min(norm(sub(u, [0.0, 0.0, -1.0])));
            (tip + growth * (d - reach).max(0.0)).min(base)
        };
        let pins = [
            Pin {
                direction: [0.0, 0.0, 1.0],
                field: "tip +z".into(),
            },
            Pin {
                direction: [0.0, 0.0, -1.0],
                field: "tip −z".into(),
            },
        ];
        let sphere = triangulate_sphere(1.0, base, size, &pins, "ellipsoid surface")?;
        Ok(Surface {
            points: sphere
                .points
                .iter()
                .map(|u| [a * u[0], b * u[1], c * u[2]])
                .collect(),
            facets: sphere.triangles,
        })
    }
}

/// Semi-axes (A, B, C) of the origin-centred, axis-aligned ellipsoid through `points`
/// (least squares on x²/A² + y²/B² + z²/C² = 1) and the largest |residual| of that
/// equation over the points; `None` when the points do not span an ellipsoid.
pub fn fit_axis_aligned_ellipsoid(points: &[[f64; 3]]) -> Option<([f64; 3], f64)> {
    let mut m = nalgebra::Matrix3::<f64>::zeros();
    let mut rhs = nalgebra::Vector3::<f64>::zeros();
    for p in points {
        let q = nalgebra::Vector3::new(p[0] * p[0], p[1] * p[1], p[2] * p[2]);
        m += q * q.transpose();
        rhs += q;
    }
    let w = m.lu().solve(&rhs)?;
    if !(w.iter().all(|&x| x.is_finite() && x > 0.0)) {
        return None;
    }
    let residual = points
        .iter()
        .map(|p| (p[0] * p[0] * w[0] + p[1] * p[1] * w[1] + p[2] * p[2] * w[2] - 1.0).abs())
        .fold(0.0, f64::max);
    Some(([w[0], w[1], w[2]].map(|x| 1.0 / x.sqrt()), residual))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{cross, dot};

    #[test]
    fn tips_are_vertices_and_fine_and_the_rest_is_coarse() {
        let spec = TipRefinedEllipsoid {
            semi_axes: [1.2e-3, 0.9e-3, 0.7e-3],
            seeding: 2.0e-4,
            tip_seeding: 1.0e-5,
            tip_radius: 2.0e-5,
            growth: 0.2,
        };
        let s = spec.surface().unwrap();
        let ([a, b, c], residual) = fit_axis_aligned_ellipsoid(&s.points).unwrap();
        assert!(residual < 1e-12, "{residual}");
        assert!((a / 1.2e-3 - 1.0).abs() < 1e-12 && (b / 0.9e-3 - 1.0).abs() < 1e-12);
        assert!((c / 0.7e-3 - 1.0).abs() < 1e-12);
        for tip in [[0.0, 0.0, 0.7e-3], [0.0, 0.0, -0.7e-3]] {
            assert!(s.points.iter().any(|p| norm(sub(*p, tip)) < 1e-15));
        }
        // edges: fine near the tips, never longer than the seeding (with the bisection's
        // slack) anywhere
        let (mut near, mut longest) = (0.0_f64, 0.0_f64);
        for f in &s.facets {
            for k in 0..3 {
                let (p, q) = (s.points[f[k] as usize], s.points[f[(k + 1) % 3] as usize]);
                let l = norm(sub(p, q));
                longest = longest.max(l);
                let lateral = p[0].hypot(p[1]).max(q[0].hypot(q[1]));
                if lateral < 2.0e-5 {
                    near = near.max(l);
                }
            }
        }
        assert!(near > 0.0 && near < 1.6e-5, "tip edges up to {near:e}");
        assert!(longest < 1.6 * 2.0e-4, "longest edge {longest:e}");
        // closed and outward: the divergence theorem gives the ellipsoid's volume
        let volume: f64 = s
            .facets
            .iter()
            .map(|f| {
                let [p, q, r] = f.map(|i| s.points[i as usize]);
                dot(p, cross(q, r)) / 6.0
            })
            .sum();
        let exact = 4.0 / 3.0 * std::f64::consts::PI * 1.2e-3 * 0.9e-3 * 0.7e-3;
        assert!(
            volume > 0.97 * exact && volume < exact,
            "{volume:e} vs {exact:e}"
        );
    }

    #[test]
    fn points_off_an_axis_aligned_ellipsoid_show_in_the_residual() {
        let pts: Vec<[f64; 3]> = (0..50)
            .map(|i| {
                let t = i as f64 * 0.37;
                let (u, v) = (t.sin() * 2.9, (1.3 * t).cos());
                [2.0 * u.cos() * v, (u.sin() * v), 0.5 * (1.0 - v * v).sqrt()]
            })
            .collect();
        let (_, residual) = fit_axis_aligned_ellipsoid(&pts).unwrap();
        assert!(residual < 1e-12);
        let mut bent = pts.clone();
        bent[7] = bent[7].map(|c| 1.05 * c);
        assert!(fit_axis_aligned_ellipsoid(&bent).unwrap().1 > 1e-3);
    }
}
