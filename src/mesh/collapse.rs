//! Edge collapse on a closed triangulated surface, shortest edge first: the one coarsening
//! step of the label-image decimation (`image::decimate`) and of the surface remesher
//! (`import::remesh`).
//!
//! An edge shorter than `below` × h(midpoint) is collapsed when the surface stays a
//! manifold (the link condition: its ends share exactly the two opposite vertices, which
//! keep valence ≥ 3), no facet turns by more than 45°, none gets worse than the quality
//! bound [`MIN_QUALITY`] (unless it already was) and no edge grows beyond `above` × h.
//! The merged vertex goes to the midpoint, or stays on a pinned end.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use crate::math::{add, cross, dot, norm, scale, sub};

/// Smallest facet quality 4√3 A / Σ l² (1 for an equilateral triangle) a collapse may
/// create.
pub const MIN_QUALITY: f64 = 0.3;
/// Smallest cosine between a facet's normal before and after a collapse.
const MIN_TURN_COSINE: f64 = std::f64::consts::FRAC_1_SQRT_2;

/// What may collapse, and how far.
pub struct CollapseRules<'a> {
    /// Edge length wanted at a point (m).
    pub size: &'a dyn Fn([f64; 3]) -> f64,
    /// Largest value `size` takes (lets the shortest-first loop stop early).
    pub max_size: f64,
    /// Collapse edges shorter than `below` × size.
    pub below: f64,
    /// No edge may become longer than `above` × size.
    pub above: f64,
    /// Pinned vertices never move and never go.
    pub pinned: &'a [bool],
    /// Whether a pinned vertex may absorb a free neighbour (the edge collapses onto it);
    /// otherwise an edge with a pinned end stays, with its facets.
    pub absorb_into_pinned: bool,
    /// Edges that never collapse (sharp features), whatever their ends.
    pub protected: &'a dyn Fn(u32, u32) -> bool,
}

/// Collapses short edges of (`points`, `facets`) by `rules`; returns the compacted points
/// and facets and, per new vertex, its old index.
pub fn collapse_short_edges(
    points: &[[f64; 3]],
    facets: &[[u32; 3]],
    rules: &CollapseRules,
) -> (Vec<[f64; 3]>, Vec<[u32; 3]>, Vec<u32>) {
    let mut points = points.to_vec();
    let mut facets = facets.to_vec();
    let mut facet_alive = vec![true; facets.len()];
    let mut vertex_alive = vec![true; points.len()];
    let mut around = facets_around(points.len(), &facets);
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
    let pinned = |v: u32| rules.pinned[v as usize];
    let mut ring_a = Vec::new();
    let mut ring_b = Vec::new();
    while let Some(Reverse((bits, a, b))) = heap.pop() {
        let l = f64::from_bits(bits);
        if l >= rules.below * rules.max_size {
            break;
        }
        if !(vertex_alive[a as usize] && vertex_alive[b as usize])
            || key(length(&points, a, b)) != bits
        {
            continue;
        }
        let mid = scale(add(points[a as usize], points[b as usize]), 0.5);
        if l >= rules.below * (rules.size)(mid) || (rules.protected)(a, b) {
            continue;
        }
        let (keep, gone, target) = match (pinned(a), pinned(b)) {
            (false, false) => (a, b, mid),
            (true, true) => continue,
            _ if !rules.absorb_into_pinned => continue,
            (true, false) => (a, b, points[a as usize]),
            (false, true) => (b, a, points[b as usize]),
        };
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
                let short = [p0, p1, p2].iter().zip([p1, p2, p0].iter()).all(|(x, y)| {
                    norm(sub(*x, *y)) <= rules.above * (rules.size)(scale(add(*x, *y), 0.5))
                });
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
    super::compact_cells(&points, alive)
}

/// The facets around each of `vertices` vertices.
pub fn facets_around(vertices: usize, facets: &[[u32; 3]]) -> Vec<Vec<u32>> {
    let mut around: Vec<Vec<u32>> = vec![Vec::new(); vertices];
    for (f, tri) in facets.iter().enumerate() {
        for &v in tri {
            around[v as usize].push(f as u32);
        }
    }
    around
}

/// Vertices joined to `v` by an edge of the facets `around` it.
pub fn ring(facets: &[[u32; 3]], around: &[u32], v: u32, out: &mut Vec<u32>) {
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
pub fn quality(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> f64 {
    let area2 = norm(cross(sub(b, a), sub(c, a)));
    let sum = dot(sub(b, a), sub(b, a)) + dot(sub(c, b), sub(c, b)) + dot(sub(a, c), sub(a, c));
    if sum > 0.0 {
        2.0 * 3f64.sqrt() * area2 / sum
    } else {
        0.0
    }
}
