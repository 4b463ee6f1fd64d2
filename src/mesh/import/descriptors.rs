//! Shape descriptors of a closed surface: volume, area, equivalent radius, sphericity and
//! the semi-axes of the ellipsoid with the same second moments (from the inertia tensor),
//! with the aspect ratios b/a (elongation) and c/b (flatness), a ≥ b ≥ c.

use super::Surface;
use crate::math::{add, cross, dot, norm, scale, sub};
use std::f64::consts::PI;

#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ShapeDescriptors {
    /// m³
    pub volume: f64,
    /// m²
    pub area: f64,
    /// Radius of the sphere of the same volume (m).
    pub equivalent_radius: f64,
    /// Area of the equal-volume sphere over the area (1 for a sphere, < 1 otherwise).
    pub sphericity: f64,
    /// Semi-axes a ≥ b ≥ c of the equal-moment ellipsoid (m).
    pub axes: [f64; 3],
    /// Volume centroid (m, in the surface's frame).
    pub centroid: [f64; 3],
}

impl ShapeDescriptors {
    /// Computes the descriptors by summing over the tets spanned by the origin and each
    /// facet (exact for the polyhedron).
    pub fn of(s: &Surface) -> ShapeDescriptors {
        let (mut volume, mut area, mut first) = (0.0, 0.0, [0.0; 3]);
        let mut second = [[0.0; 3]; 3];
        for f in &s.facets {
            let [a, b, c] = f.map(|i| s.points[i as usize]);
            let v = dot(a, cross(b, c)) / 6.0;
            area += 0.5 * norm(cross(sub(b, a), sub(c, a)));
            volume += v;
            let sum = add(add(a, b), c);
            first = add(first, scale(sum, v / 4.0));
            // ∫ x xᵀ dV over a tet with a corner at the origin: V/20 (Σ pᵢpᵢᵀ + (Σpᵢ)(Σpᵢ)ᵀ).
            for i in 0..3 {
                for j in 0..3 {
                    second[i][j] +=
                        v / 20.0 * (a[i] * a[j] + b[i] * b[j] + c[i] * c[j] + sum[i] * sum[j]);
                }
            }
        }
        let centroid = scale(first, 1.0 / volume);
        let cov =
            nalgebra::Matrix3::from_fn(|i, j| second[i][j] / volume - centroid[i] * centroid[j]);
        // A solid ellipsoid of semi-axes (a, b, c) has covariance diag(a², b², c²)/5.
        let mut axes = nalgebra::SymmetricEigen::new(cov)
            .eigenvalues
            .map(|l| (5.0 * l.max(0.0)).sqrt());
        axes.as_mut_slice().sort_by(|x, y| y.total_cmp(x));
        let equivalent_radius = (3.0 * volume / (4.0 * PI)).cbrt();
        ShapeDescriptors {
            volume,
            area,
            equivalent_radius,
            sphericity: 4.0 * PI * equivalent_radius * equivalent_radius / area,
            axes: [axes[0], axes[1], axes[2]],
            centroid,
        }
    }

    /// b/a.
    pub fn elongation(&self) -> f64 {
        self.axes[1] / self.axes[0]
    }

    /// c/b.
    pub fn flatness(&self) -> f64 {
        self.axes[2] / self.axes[1]
    }
}

impl std::fmt::Display for ShapeDescriptors {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "volume {:.4e} m³, equivalent radius {:.4e} m, sphericity {:.3}, semi-axes {:.3e} ≥ {:.3e} ≥ {:.3e} m, b/a {:.3}, c/b {:.3}",
            self.volume,
            self.equivalent_radius,
            self.sphericity,
            self.axes[0],
            self.axes[1],
            self.axes[2],
            self.elongation(),
            self.flatness()
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::import::checks::tests::cube;

    #[test]
    fn cube_descriptors() {
        let d = ShapeDescriptors::of(&cube());
        assert!((d.volume - 1.0).abs() < 1e-12 && (d.area - 6.0).abs() < 1e-12);
        assert!(d.centroid.iter().all(|c| (c - 0.5).abs() < 1e-12));
        // cube covariance 1/12 per axis → semi-axes √(5/12)
        assert!(d
            .axes
            .iter()
            .all(|a| (a - (5.0f64 / 12.0).sqrt()).abs() < 1e-12));
        assert!((d.sphericity - (PI.cbrt() * 6f64.powf(2.0 / 3.0) / 6.0)).abs() < 1e-12);
    }
}
