//! Midpoint subdivision of a coarse surface until every edge is at most the seeding, so
//! the volume mesh resolves the boundary at the requested size. Edges longer than the
//! target are split at their midpoints (a decision per edge, so neighbours agree and the
//! surface stays conforming); each facet is then cut by the pattern of its split edges
//! (1 → 2, 3 or 4 triangles; a quad left by two splits is cut along its shorter diagonal).
//! Midpoints lie on the flat facets: the geometry is unchanged, no curvature is added.

use std::collections::HashMap;

use super::Surface;
use crate::math::{add, norm, scale, sub};

/// Splits every edge longer than the size `h` (at its midpoint) there until none is;
/// `None` if that would exceed `max_facets`.
pub fn subdivide_to(
    s: &Surface,
    h: impl Fn([f64; 3]) -> f64,
    max_facets: usize,
) -> Option<Surface> {
    let mut s = s.clone();
    loop {
        if split_edges_once(&mut s, |length, mid| length > h(mid)).is_empty() {
            return Some(s);
        }
        if s.facets.len() > max_facets {
            return None;
        }
    }
}

/// Splits at its midpoint every edge for which `split(length, midpoint)` holds, and cuts
/// the facets by the pattern of their split edges; returns the new vertex of each split
/// edge (keyed by its ends, lower index first).
pub fn split_edges_once(
    s: &mut Surface,
    split: impl Fn(f64, [f64; 3]) -> bool,
) -> HashMap<(u32, u32), u32> {
    let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
    let len = |s: &Surface, a: u32, b: u32| norm(sub(s.points[a as usize], s.points[b as usize]));
    for i in 0..s.facets.len() {
        let f = s.facets[i];
        for k in 0..3 {
            let (a, b) = (f[k], f[(k + 1) % 3]);
            let key = (a.min(b), a.max(b));
            let p = scale(add(s.points[a as usize], s.points[b as usize]), 0.5);
            if !mid.contains_key(&key) && split(len(s, a, b), p) {
                s.points.push(p);
                mid.insert(key, (s.points.len() - 1) as u32);
            }
        }
    }
    if mid.is_empty() {
        return mid;
    }
    {
        let mut facets = Vec::with_capacity(2 * s.facets.len());
        for f in &s.facets {
            let m = |k: usize| {
                let (a, b) = (f[k], f[(k + 1) % 3]);
                mid.get(&(a.min(b), a.max(b))).copied()
            };
            let splits = [m(0), m(1), m(2)];
            match splits.iter().filter(|x| x.is_some()).count() {
                0 => facets.push(*f),
                1 => {
                    // Rotate so the split edge is f[k]–f[k+1].
                    let k = (0..3).find(|&k| splits[k].is_some()).unwrap_or(0);
                    let (a, b, c, x) =
                        (f[k], f[(k + 1) % 3], f[(k + 2) % 3], splits[k].unwrap_or(0));
                    facets.extend([[a, x, c], [x, b, c]]);
                }
                2 => {
                    // Rotate so the unsplit edge is f[k+2]–f[k]: splits on a–b (x) and b–c (y).
                    let k = (0..3).find(|&k| splits[(k + 2) % 3].is_none()).unwrap_or(0);
                    let (a, b, c) = (f[k], f[(k + 1) % 3], f[(k + 2) % 3]);
                    let (x, y) = (splits[k].unwrap_or(0), splits[(k + 1) % 3].unwrap_or(0));
                    facets.push([x, b, y]);
                    if len(s, a, y) <= len(s, x, c) {
                        facets.extend([[a, x, y], [a, y, c]]);
                    } else {
                        facets.extend([[a, x, c], [x, y, c]]);
                    }
                }
                _ => {
                    let [x, y, z] = splits.map(|v| v.unwrap_or(0));
                    facets.extend([[f[0], x, z], [x, f[1], y], [z, y, f[2]], [x, y, z]]);
                }
            }
        }
        s.facets = facets;
    }
    mid
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::import::checks::{check, signed_volume, tests::cube};

    #[test]
    fn subdivided_cube_is_closed_with_short_edges_and_same_volume() {
        let s = subdivide_to(&cube(), |_| 0.3, 1_000_000).unwrap();
        check(&s).unwrap();
        assert!((signed_volume(&s) - 1.0).abs() < 1e-12);
        for f in &s.facets {
            for k in 0..3 {
                assert!(
                    norm(sub(
                        s.points[f[k] as usize],
                        s.points[f[(k + 1) % 3] as usize]
                    )) <= 0.3
                );
            }
        }
        assert!(subdivide_to(&cube(), |_| 1e-3, 1000).is_none());
        // a size field: fine near one corner only
        let corner = |x: [f64; 3]| if norm(x) < 0.8 { 0.05 } else { 1.0 };
        let graded = subdivide_to(&cube(), corner, 1_000_000).unwrap();
        let uniform = subdivide_to(&cube(), |_| 0.05, 1_000_000).unwrap();
        check(&graded).unwrap();
        assert!((signed_volume(&graded) - 1.0).abs() < 1e-12);
        assert!(
            graded.facets.len() > 48 && 2 * graded.facets.len() < uniform.facets.len(),
            "{} graded, {} uniform",
            graded.facets.len(),
            uniform.facets.len()
        );
        for f in &graded.facets {
            for k in 0..3 {
                let (p, q) = (
                    graded.points[f[k] as usize],
                    graded.points[f[(k + 1) % 3] as usize],
                );
                assert!(norm(sub(p, q)) <= corner(scale(add(p, q), 0.5)));
            }
        }
    }
}
