//! Coarsening a voxel-fine surface to the seeding by edge collapse, shortest edge first.
//!
//! An edge shorter than [`COLLAPSE_BELOW`] × the seeding is collapsed to its midpoint
//! when the surface stays a manifold (the link condition: the ends
//! share exactly the two opposite vertices), no facet turns by more than 45°, none gets
//! worse than the quality bound [`MIN_QUALITY`] (unless it already was), and no edge grows
//! beyond the seeding. Locked vertices — those a grain shares with a touching grain, and
//! those near them — take part in no collapse and never move: the contact face keeps its
//! voxel-fine, coincident triangles on both grains, and the free surfaces of two grains
//! cannot be pushed through each other next to it.
//! Finally the free vertices move along their normals by the one distance that gives back
//! the volume collapse took away.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use crate::math::{add, cross, dot, norm, scale, sub};
use crate::mesh::import::checks::signed_volume;
use crate::mesh::import::Surface;

/// Edges shorter than this fraction of the seeding are collapsed.
pub const COLLAPSE_BELOW: f64 = 0.6;
/// Smallest facet quality 4√3 A / Σ l² (1 for an equilateral triangle) a collapse may
/// create.
pub const MIN_QUALITY: f64 = 0.3;
/// Smallest cosine between a facet's normal before and after a collapse.
const MIN_TURN_COSINE: f64 = std::f64::consts::FRAC_1_SQRT_2;

/// Collapses `s` toward edges of `seeding`; `locked[i]`: vertex i stays, with its facets.
/// Returns the compacted surface and its lock flags.
pub fn decimate(s: &Surface, locked: &[bool], seeding: f64) -> (Surface, Vec<bool>) {
    let volume = signed_volume(s);
    let mut points = s.points.clone();
    let mut facets = s.facets.clone();
    let mut facet_alive = vec![true; facets.len()];
    let mut vertex_alive = vec![true; points.len()];
    let mut around: Vec<Vec<u32>> = vec![Vec::new(); points.len()];
    for (f, tri) in facets.iter().enumerate() {
        for &v in tri {
            around[v as usize].push(f as u32);
        }
    }
    let length = |p: &[[f64; 3]], a: u32, b: u32| norm(sub(p[a as usize], p[b as usize]));
    let key = |l: f64| l.to_bits(); // lengths ≥ 0: bit order is numeric order
    let mut heap = BinaryHeap::new();
    for tri in &facets {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            if a < b {
                heap.push(Reverse((key(length(&points, a, b)), a, b)));
            }
        }
    }
    let below = COLLAPSE_BELOW * seeding;
    let mut ring_a = Vec::new();
    let mut ring_b = Vec::new();
    while let Some(Reverse((bits, a, b))) = heap.pop() {
        let l = f64::from_bits(bits);
        if l >= below {
            break;
        }
        if !(vertex_alive[a as usize] && vertex_alive[b as usize])
            || key(length(&points, a, b)) != bits
        {
            continue;
        }
        if locked[a as usize] || locked[b as usize] {
            continue;
        }
        let (keep, gone) = (a, b);
        let target = scale(add(points[a as usize], points[b as usize]), 0.5);
        ring(&facets, &around[keep as usize], keep, &mut ring_a);
        ring(&facets, &around[gone as usize], gone, &mut ring_b);
        if !ring_a.contains(&gone) {
            continue; // the edge no longer exists
        }
        let common: Vec<u32> = ring_a
            .iter()
            .copied()
            .filter(|v| ring_b.contains(v))
            .collect();
        let both: Vec<u32> = around[gone as usize]
            .iter()
            .copied()
            .filter(|&f| facets[f as usize].contains(&keep))
            .collect();
        if common.len() != 2 || both.len() != 2 {
            continue;
        }
        // The opposite vertices lose an edge: keep them at valence ≥ 3.
        if common.iter().any(|&v| around[v as usize].len() < 4) {
            continue;
        }
        let acceptable = around[keep as usize]
            .iter()
            .chain(around[gone as usize].iter())
            .filter(|f| !both.contains(f))
            .all(|&f| {
                let old = facets[f as usize];
                let new = old.map(|v| if v == gone { keep } else { v });
                let at = |v: u32| {
                    if v == keep {
                        target
                    } else {
                        points[v as usize]
                    }
                };
                let (p0, p1, p2) = (at(new[0]), at(new[1]), at(new[2]));
                let o = old.map(|v| points[v as usize]);
                let n_old = cross(sub(o[1], o[0]), sub(o[2], o[0]));
                let n_new = cross(sub(p1, p0), sub(p2, p0));
                let turned = dot(n_old, n_new) >= MIN_TURN_COSINE * norm(n_old) * norm(n_new);
                let q_new = quality(p0, p1, p2);
                let good = q_new >= MIN_QUALITY || q_new >= quality(o[0], o[1], o[2]);
                let short = [p0, p1, p2]
                    .iter()
                    .zip([p1, p2, p0].iter())
                    .all(|(x, y)| norm(sub(*x, *y)) <= seeding);
                turned && good && short && norm(n_new) > 0.0
            });
        if !acceptable {
            continue;
        }
        for &f in &both {
            facet_alive[f as usize] = false;
            for v in facets[f as usize] {
                around[v as usize].retain(|&g| g != f);
            }
        }
        let moved: Vec<u32> = std::mem::take(&mut around[gone as usize]);
        for f in moved {
            for v in facets[f as usize].iter_mut() {
                if *v == gone {
                    *v = keep;
                }
            }
            around[keep as usize].push(f);
        }
        vertex_alive[gone as usize] = false;
        points[keep as usize] = target;
        ring(&facets, &around[keep as usize], keep, &mut ring_a);
        for &v in &ring_a {
            let (x, y) = (keep.min(v), keep.max(v));
            heap.push(Reverse((key(length(&points, x, y)), x, y)));
        }
    }

    let alive = facets
        .iter()
        .zip(&facet_alive)
        .filter(|(_, &a)| a)
        .map(|(f, _)| *f);
    let (points, facets, old) = crate::mesh::compact_cells(&points, alive);
    let mut out = Surface { points, facets };
    let out_locked: Vec<bool> = old.iter().map(|&v| locked[v as usize]).collect();
    restore_volume(&mut out, &out_locked, volume);
    (out, out_locked)
}

/// Moves the free vertices along their area-weighted normals by the one distance d with
/// V(d) = `volume` to first order (d = ΔV / free area).
fn restore_volume(s: &mut Surface, locked: &[bool], volume: f64) {
    let normals = super::vertex_normals(s);
    let free_area: f64 = s
        .facets
        .iter()
        .map(|f| {
            let p = f.map(|v| s.points[v as usize]);
            let frees = f.iter().filter(|&&v| !locked[v as usize]).count();
            0.5 * norm(cross(sub(p[1], p[0]), sub(p[2], p[0]))) * frees as f64 / 3.0
        })
        .sum();
    if free_area <= 0.0 {
        return;
    }
    let d = (volume - signed_volume(s)) / free_area;
    for (i, p) in s.points.iter_mut().enumerate() {
        let l = norm(normals[i]);
        if !locked[i] && l > 0.0 {
            *p = add(*p, scale(normals[i], d / l));
        }
    }
}

/// Vertices joined to `v` by an edge of the facets `around` it.
fn ring(facets: &[[u32; 3]], around: &[u32], v: u32, out: &mut Vec<u32>) {
    out.clear();
    for &f in around {
        for &w in &facets[f as usize] {
            if w != v && !out.contains(&w) {
                out.push(w);
            }
        }
    }
}

/// 4√3 A / (l₀² + l₁² + l₂²): 1 for an equilateral triangle, 0 for a degenerate one.
fn quality(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> f64 {
    let area2 = norm(cross(sub(b, a), sub(c, a)));
    let sum = dot(sub(b, a), sub(b, a)) + dot(sub(c, b), sub(c, b)) + dot(sub(a, c), sub(a, c));
    if sum > 0.0 {
        2.0 * 3f64.sqrt() * area2 / sum
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::import::checks::check;
    use crate::sand::icosphere;

    #[test]
    fn a_fine_sphere_coarsens_to_the_seeding_keeping_its_volume_and_locks() {
        let s = icosphere(5); // edges ≈ 0.034
        let locked: Vec<bool> = s.points.iter().map(|p| p[2] > 0.9).collect();
        let before = signed_volume(&s);
        let (d, l) = decimate(&s, &locked, 0.2);
        check(&d).unwrap();
        assert!(
            d.facets.len() < s.facets.len() / 8,
            "{} facets",
            d.facets.len()
        );
        assert!((signed_volume(&d) / before - 1.0).abs() < 1e-3);
        // every locked vertex kept, unmoved
        let kept: Vec<[f64; 3]> = (0..d.points.len())
            .filter(|&i| l[i])
            .map(|i| d.points[i])
            .collect();
        assert_eq!(kept.len(), locked.iter().filter(|&&x| x).count());
        assert!(kept.iter().all(|p| s.points.contains(p)));
        let longest = d
            .facets
            .iter()
            .flat_map(|f| (0..3).map(move |k| (f[k], f[(k + 1) % 3])))
            .map(|(a, b)| norm(sub(d.points[a as usize], d.points[b as usize])))
            .fold(0.0, f64::max);
        assert!(longest <= 0.2 * 1.01, "longest edge {longest}");
    }
}
