//! How far one closed surface's vertices are inside another: the overlap report of
//! `mufe import` for every pair of grains whose boxes meet.

use crate::math::point_triangle_distance;
use crate::math::{cross, dot, norm, sub};
use crate::mesh::import::{bounding_box, Surface};

/// Vertices of one grain on or inside another.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PairOverlap {
    /// Vertices within the tolerance of the other surface (the shared contact face).
    pub touching: usize,
    /// Vertices deeper inside the other grain than the tolerance.
    pub inside: usize,
    /// Largest depth of those (m).
    pub max_depth: f64,
}

/// Vertices of `a` against the closed surface `b`; `tolerance` (m) separates touching
/// from inside.
pub fn overlap_of(a: &Surface, b: &Surface, tolerance: f64) -> PairOverlap {
    let (lo, hi) = bounding_box(&b.points);
    let mut out = PairOverlap::default();
    for p in &a.points {
        if (0..3).any(|k| p[k] < lo[k] - tolerance || p[k] > hi[k] + tolerance) {
            continue;
        }
        let d = distance_to_surface(*p, b);
        if d <= tolerance {
            out.touching += 1;
        } else if winding_number(*p, b) > 0.5 {
            out.inside += 1;
            out.max_depth = out.max_depth.max(d);
        }
    }
    out
}

/// Whether the axis-aligned boxes of two surfaces meet (grown by `margin`).
pub fn boxes_meet(a: &Surface, b: &Surface, margin: f64) -> bool {
    let (alo, ahi) = bounding_box(&a.points);
    let (blo, bhi) = bounding_box(&b.points);
    (0..3).all(|k| alo[k] <= bhi[k] + margin && blo[k] <= ahi[k] + margin)
}

/// Generalised winding number of a closed surface about `p` (Van Oosterom–Strackee solid
/// angles): 1 inside, 0 outside.
pub fn winding_number(p: [f64; 3], s: &Surface) -> f64 {
    let mut total = 0.0;
    for f in &s.facets {
        let [a, b, c] = f.map(|v| sub(s.points[v as usize], p));
        let (la, lb, lc) = (norm(a), norm(b), norm(c));
        let numerator = dot(a, cross(b, c));
        let denominator = la * lb * lc + dot(a, b) * lc + dot(b, c) * la + dot(c, a) * lb;
        total += 2.0 * numerator.atan2(denominator);
    }
    total / (4.0 * std::f64::consts::PI)
}

/// Smallest distance from `p` to the facets of `s`.
pub fn distance_to_surface(p: [f64; 3], s: &Surface) -> f64 {
    s.facets
        .iter()
        .map(|f| {
            let [a, b, c] = f.map(|v| s.points[v as usize]);
            point_triangle_distance(p, a, b, c)
        })
        .fold(f64::INFINITY, f64::min)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sand::icosphere;

    #[test]
    fn a_sphere_inside_and_beside_another() {
        let unit = icosphere(3);
        assert!((winding_number([0.1, 0.2, 0.0], &unit) - 1.0).abs() < 1e-9);
        assert!(winding_number([1.5, 0.0, 0.0], &unit).abs() < 1e-9);
        let d =
            point_triangle_distance([0.0, 0.0, 2.0], [0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
        assert_eq!(d, 2.0);
        let d =
            point_triangle_distance([2.0, 2.0, 0.0], [0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
        assert!((d - 1.5 * 2f64.sqrt()).abs() < 1e-12);
        // a sphere shifted by 1.5 radii: the vertices within 0.5 of the other's centre
        // region are inside it, about 0.5 deep at most
        let mut moved = unit.clone();
        moved.points.iter_mut().for_each(|p| p[0] += 1.5);
        let o = overlap_of(&moved, &unit, 1e-9);
        assert!(
            o.inside > 0 && o.max_depth > 0.4 && o.max_depth < 0.55,
            "{o:?}"
        );
        moved.points.iter_mut().for_each(|p| p[0] += 1.0);
        assert_eq!(overlap_of(&moved, &unit, 1e-9), PairOverlap::default());
    }
}
