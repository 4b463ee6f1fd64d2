//! Self-intersection test of a closed triangulated surface, accelerated by a uniform grid
//! of about one facet per cell: each facet is entered in the cells its bounding box
//! touches, and each pair of facets sharing a cell is tested once (in the cell holding the
//! low corner of the overlap of their boxes).
//!
//! Two triangles in general position intersect exactly when an edge of one crosses the
//! other, so the test is six segment–triangle tests with orientation signs, strict beyond
//! a tolerance of 1e-12 × (bounding-box diagonal)³ so that facets meeting along a shared
//! edge or vertex do not count. Neighbours are tested too: facets sharing an edge must
//! not fold onto each other (coplanar, on the same side of the edge), facets sharing a
//! vertex must not have the opposite edge of one cross the other. Coplanar overlaps of
//! facets that share nothing are not detected (they do not occur in scanned or
//! generated grains).

use std::collections::HashMap;

use super::{bounding_box, Surface};
use crate::math::{cross, dot, norm, sub};

/// The first intersecting pair (lowest facet index first), if any.
pub fn first_self_intersection(s: &Surface) -> Option<(usize, usize)> {
    let n = s.facets.len();
    if n < 2 {
        return None;
    }
    let (lo, hi) = bounding_box(&s.points);
    let diag = norm(sub(hi, lo));
    let eps = 1e-12 * diag.powi(3);
    let boxes: Vec<([f64; 3], [f64; 3])> = s
        .facets
        .iter()
        .map(|f| bounding_box(&f.map(|i| s.points[i as usize])))
        .collect();
    // Cell size: about one facet per cell over the box's volume, but no smaller than the
    // mean facet box (else each facet lands in many cells).
    let extent = sub(hi, lo).map(|e| e.max(1e-300));
    let mean_box = boxes.iter().map(|(a, b)| norm(sub(*b, *a))).sum::<f64>() / n as f64;
    let cell = ((extent[0] * extent[1] * extent[2]) / n as f64)
        .cbrt()
        .max(mean_box)
        .max(diag * 1e-6);
    let index =
        |p: [f64; 3]| -> [i64; 3] { [0, 1, 2].map(|k| ((p[k] - lo[k]) / cell).floor() as i64) };
    let mut grid: HashMap<[i64; 3], Vec<u32>> = HashMap::new();
    for (f, (a, b)) in boxes.iter().enumerate() {
        let (i0, i1) = (index(*a), index(*b));
        for x in i0[0]..=i1[0] {
            for y in i0[1]..=i1[1] {
                for z in i0[2]..=i1[2] {
                    grid.entry([x, y, z]).or_default().push(f as u32);
                }
            }
        }
    }
    let mut best: Option<(usize, usize)> = None;
    for (key, list) in &grid {
        for (k, &f) in list.iter().enumerate() {
            for &g in &list[k + 1..] {
                let (f, g) = (f as usize, g as usize);
                let (a, b) = (&boxes[f], &boxes[g]);
                let overlap_lo = [0, 1, 2].map(|k| a.0[k].max(b.0[k]));
                if (0..3).any(|k| overlap_lo[k] > a.1[k].min(b.1[k])) || index(overlap_lo) != *key {
                    continue;
                }
                let pair = (f.min(g), f.max(g));
                if best.is_some_and(|b| pair >= b) {
                    continue;
                }
                if facets_intersect(s, pair.0, pair.1, eps) {
                    best = Some(pair);
                }
            }
        }
    }
    best
}

/// 6 × the signed volume of (a, b, c, d).
fn orient(a: [f64; 3], b: [f64; 3], c: [f64; 3], d: [f64; 3]) -> f64 {
    dot(sub(b, a), cross(sub(c, a), sub(d, a)))
}

/// Whether segment pq crosses the interior of triangle t, strictly beyond `eps`.
fn segment_crosses(p: [f64; 3], q: [f64; 3], t: [[f64; 3]; 3], eps: f64) -> bool {
    let (sp, sq) = (orient(t[0], t[1], t[2], p), orient(t[0], t[1], t[2], q));
    if !((sp > eps && sq < -eps) || (sp < -eps && sq > eps)) {
        return false;
    }
    let s = [
        orient(p, q, t[0], t[1]),
        orient(p, q, t[1], t[2]),
        orient(p, q, t[2], t[0]),
    ];
    s.iter().all(|&v| v > eps) || s.iter().all(|&v| v < -eps)
}

fn facets_intersect(s: &Surface, f: usize, g: usize, eps: f64) -> bool {
    let (ff, gf) = (s.facets[f], s.facets[g]);
    let (a, b) = (
        ff.map(|i| s.points[i as usize]),
        gf.map(|i| s.points[i as usize]),
    );
    let shared: Vec<(usize, usize)> = (0..3)
        .flat_map(|i| (0..3).map(move |j| (i, j)))
        .filter(|&(i, j)| ff[i] == gf[j])
        .collect();
    match shared.len() {
        0 => (0..3).any(|k| {
            segment_crosses(a[k], a[(k + 1) % 3], b, eps)
                || segment_crosses(b[k], b[(k + 1) % 3], a, eps)
        }),
        1 => {
            let (i, j) = shared[0];
            segment_crosses(a[(i + 1) % 3], a[(i + 2) % 3], b, eps)
                || segment_crosses(b[(j + 1) % 3], b[(j + 2) % 3], a, eps)
        }
        2 => {
            // Folded onto each other: g's free corner in f's plane, on f's side of the edge.
            let fi = (0..3).find(|&i| !gf.contains(&ff[i])).unwrap_or(0);
            let gj = (0..3).find(|&j| !ff.contains(&gf[j])).unwrap_or(0);
            let (c, d) = (a[fi], b[gj]);
            let (e0, e1) = (a[(fi + 1) % 3], a[(fi + 2) % 3]);
            if orient(a[0], a[1], a[2], d).abs() > eps {
                return false;
            }
            let normal = cross(sub(a[1], a[0]), sub(a[2], a[0]));
            let side = |x: [f64; 3]| dot(cross(sub(e1, e0), sub(x, e0)), normal);
            side(c) * side(d) > 0.0
        }
        _ => true, // the same three vertices twice
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::import::formats::surface_from_soup;

    #[test]
    fn crossing_and_folded_facets_are_found() {
        let t = |a: [f64; 3], b: [f64; 3], c: [f64; 3]| [a, b, c];
        let crossing = surface_from_soup([
            t([0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0]),
            t([0.5, 0.5, -1.0], [0.5, 0.5, 1.0], [3.0, 3.0, 0.0]),
        ]);
        assert_eq!(first_self_intersection(&crossing), Some((0, 1)));
        let apart = surface_from_soup([
            t([0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0]),
            t([0.5, 0.5, 1.0], [0.5, 0.5, 2.0], [3.0, 3.0, 1.0]),
        ]);
        assert_eq!(first_self_intersection(&apart), None);
        let folded = surface_from_soup([
            t([0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0]),
            t([0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [1.0, 1.0, 0.0]),
        ]);
        assert_eq!(first_self_intersection(&folded), Some((0, 1)));
        let hinge = surface_from_soup([
            t([0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0]),
            t([2.0, 0.0, 0.0], [0.0, 0.0, 0.0], [1.0, -1.0, 0.0]),
        ]);
        assert_eq!(first_self_intersection(&hinge), None);
    }
}
