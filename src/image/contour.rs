//! One closed surface per label: marching tetrahedra on the label's indicator (1 in its
//! voxels, 0 elsewhere) at level ½, over the Kuhn split of every cube of eight voxel
//! centres into six tetrahedra.
//!
//! Why tetrahedra and not marching cubes: the level set of a function linear on each tet
//! is a manifold with no ambiguous cases, and where two labels touch, the indicator of one
//! is one minus the other's on every tet holding only those two, so both grains get the
//! *same* triangles there (a quad is split along the diagonal through its vertex of
//! smallest key, a rule that does not depend on which side is inside). Vertices sit at
//! edge midpoints and are shared through one table keyed by grid edge, so the touching
//! faces of two grains are one set of points: they meet without overlap or gap.
//!
//! Smoothing (Taubin λ|μ, which does not shrink) moves each vertex by the mean of its
//! neighbours over the union of all grains' triangles, so a shared vertex moves the same
//! for both grains and the touching faces stay one surface.

use std::collections::HashMap;

use super::LabelImage;
use crate::math::{add, cross, dot, scale, sub};

/// Surfaces of all labels over one shared vertex table.
#[derive(Debug, Clone, Default)]
pub struct Contours {
    /// Vertex positions (m).
    pub points: Vec<[f64; 3]>,
    /// The vertex is on a grid edge joining two different labels: it belongs to both
    /// grains' surfaces (their contact).
    pub shared: Vec<bool>,
    /// (label, voxels, facets counter-clockwise from outside, into `points`) per label.
    pub grains: Vec<ContourGrain>,
}

#[derive(Debug, Clone)]
pub struct ContourGrain {
    pub label: u32,
    pub voxels: usize,
    pub facets: Vec<[u32; 3]>,
}

/// The six Kuhn tetrahedra of a cube, as corner bit masks (bit a = +1 along axis a): the
/// chains 0 → e_a → e_a + e_b → 7 over the permutations (a, b, c).
const KUHN: [[usize; 4]; 6] = [
    [0, 1, 3, 7],
    [0, 1, 5, 7],
    [0, 2, 3, 7],
    [0, 2, 6, 7],
    [0, 4, 5, 7],
    [0, 4, 6, 7],
];

/// Extracts every label's surface with `spacing` (m per voxel along each axis) and the
/// image origin `origin` (m).
pub fn extract(image: &LabelImage, spacing: [f64; 3], origin: [f64; 3]) -> Contours {
    let mut out = Contours::default();
    let mut table: HashMap<u64, u32> = HashMap::new();
    // Keys index the grid padded by one voxel on every side.
    let dims = image.size.map(|n| n as u64 + 2);
    let key_of = |p: [i64; 3], bits: usize| -> u64 {
        let q = p.map(|c| (c + 1) as u64);
        ((q[0] + dims[0] * (q[1] + dims[1] * q[2])) << 3) | bits as u64
    };
    let position = |p: [i64; 3], q: [i64; 3]| -> [f64; 3] {
        [0, 1, 2].map(|a| origin[a] + spacing[a] * 0.5 * (p[a] + q[a]) as f64)
    };
    for b in image.label_boxes() {
        let mut facets = Vec::new();
        let mut corner = [[0i64; 3]; 8];
        let mut inside = [false; 8];
        for z in b.lo[2] - 1..=b.hi[2] {
            for y in b.lo[1] - 1..=b.hi[1] {
                for x in b.lo[0] - 1..=b.hi[0] {
                    let mut any_in = false;
                    let mut any_out = false;
                    for c in 0..8 {
                        corner[c] = [
                            x + (c & 1) as i64,
                            y + ((c >> 1) & 1) as i64,
                            z + (c >> 2) as i64,
                        ];
                        inside[c] = image.label_at(corner[c]) == b.label;
                        any_in |= inside[c];
                        any_out |= !inside[c];
                    }
                    if !(any_in && any_out) {
                        continue;
                    }
                    for tet in KUHN {
                        emit_tet(
                            &tet,
                            &corner,
                            &inside,
                            &mut |p, q| {
                                // Edges of a Kuhn tet join corners where one dominates the
                                // other: key by the lower corner and the offset bits.
                                let (lo, hi) = if (0..3).all(|a| p[a] <= q[a]) {
                                    (p, q)
                                } else {
                                    (q, p)
                                };
                                let bits = (0..3).filter(|&a| hi[a] > lo[a]).map(|a| 1 << a).sum();
                                let key = key_of(lo, bits);
                                let len = out.points.len() as u32;
                                let id = *table.entry(key).or_insert(len);
                                if id == len {
                                    out.points.push(position(p, q));
                                    let (a, c) = (image.label_at(p), image.label_at(q));
                                    out.shared.push(a != 0 && c != 0 && a != c);
                                }
                                (id, key)
                            },
                            &mut facets,
                        );
                    }
                }
            }
        }
        out.grains.push(ContourGrain {
            label: b.label,
            voxels: b.voxels,
            facets,
        });
    }
    out
}

/// Emits the triangles of one tet (vertex ids from `vertex(p, q)` for the edge p–q).
fn emit_tet(
    tet: &[usize; 4],
    corner: &[[i64; 3]; 8],
    inside: &[bool; 8],
    vertex: &mut impl FnMut([i64; 3], [i64; 3]) -> (u32, u64),
    facets: &mut Vec<[u32; 3]>,
) {
    let ins: Vec<usize> = tet.iter().copied().filter(|&c| inside[c]).collect();
    let outs: Vec<usize> = tet.iter().copied().filter(|&c| !inside[c]).collect();
    if ins.is_empty() || outs.is_empty() {
        return;
    }
    let mean = |cs: &[usize]| {
        let mut m = [0.0; 3];
        for &c in cs {
            m = add(m, corner[c].map(|x| x as f64));
        }
        scale(m, 1.0 / cs.len() as f64)
    };
    // Outward in grid units: inside corners → outside corners (the level plane separates
    // them, so this crosses it outward).
    let outward = sub(mean(&outs), mean(&ins));
    let mid = |a: usize, b: usize| add(corner[a].map(|x| x as f64), corner[b].map(|x| x as f64));
    let mut push = |t: [(u32, [f64; 3]); 3]| {
        let n = cross(sub(t[1].1, t[0].1), sub(t[2].1, t[0].1));
        if dot(n, outward) >= 0.0 {
            facets.push([t[0].0, t[1].0, t[2].0]);
        } else {
            facets.push([t[0].0, t[2].0, t[1].0]);
        }
    };
    let mut v = |a: usize, b: usize| (vertex(corner[a], corner[b]), mid(a, b));
    match ins.len() {
        1 | 3 => {
            let (apex, others) = if ins.len() == 1 {
                (ins[0], &outs)
            } else {
                (outs[0], &ins)
            };
            let t = [0, 1, 2].map(|k| {
                let ((id, _), p) = v(apex, others[k]);
                (id, p)
            });
            push(t);
        }
        _ => {
            let cycle = [
                (ins[0], outs[0]),
                (ins[0], outs[1]),
                (ins[1], outs[1]),
                (ins[1], outs[0]),
            ];
            let q = cycle.map(|(a, b)| v(a, b));
            let m = (0..4).min_by_key(|&k| q[k].0 .1).unwrap_or(0);
            let at = |k: usize| {
                let ((id, _), p) = q[(m + k) % 4];
                (id, p)
            };
            push([at(0), at(1), at(2)]);
            push([at(0), at(2), at(3)]);
        }
    }
}

/// Taubin smoothing (λ = 0.5, μ = −0.53) over the union of all grains' edges, `passes`
/// λ|μ pairs; shared vertices move once for every grain they belong to.
pub fn smooth(c: &mut Contours, passes: usize) {
    let n = c.points.len();
    let mut neighbours: Vec<Vec<u32>> = vec![Vec::new(); n];
    for g in &c.grains {
        for f in &g.facets {
            for k in 0..3 {
                let (a, b) = (f[k], f[(k + 1) % 3]);
                neighbours[a as usize].push(b);
                neighbours[b as usize].push(a);
            }
        }
    }
    for list in neighbours.iter_mut() {
        list.sort_unstable();
        list.dedup();
    }
    let mut next = c.points.clone();
    for _ in 0..passes {
        for factor in [0.5, -0.53] {
            for (i, list) in neighbours.iter().enumerate() {
                if list.is_empty() {
                    continue;
                }
                let mut m = [0.0; 3];
                for &j in list {
                    m = add(m, c.points[j as usize]);
                }
                let mean = scale(m, 1.0 / list.len() as f64);
                next[i] = add(c.points[i], scale(sub(mean, c.points[i]), factor));
            }
            std::mem::swap(&mut c.points, &mut next);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::import::checks::{check, signed_volume};
    use crate::mesh::import::Surface;

    /// Two balls of radius r voxels, centres 2d apart, split by the mid-plane.
    pub(crate) fn two_balls(r: f64, d: f64) -> LabelImage {
        let n = (2.0 * (r + d) + 6.0) as usize;
        let mut labels = vec![0; n * n * n];
        let c = n as f64 / 2.0;
        for k in 0..n {
            for j in 0..n {
                for i in 0..n {
                    let p = [i as f64 - c + d, j as f64 - c, k as f64 - c];
                    let q = [p[0] - 2.0 * d, p[1], p[2]];
                    let in1 = dot(p, p) <= r * r;
                    let in2 = dot(q, q) <= r * r;
                    labels[i + n * (j + n * k)] = match (in1, in2) {
                        (true, true) => 1 + u32::from((i as f64) >= c),
                        (true, false) => 1,
                        (false, true) => 2,
                        _ => 0,
                    };
                }
            }
        }
        LabelImage {
            size: [n; 3],
            labels,
            spacing: None,
            origin: [0.0; 3],
        }
    }

    fn surface_of(c: &Contours, g: usize) -> Surface {
        Surface {
            points: c.points.clone(),
            facets: c.grains[g].facets.clone(),
        }
    }

    #[test]
    fn touching_labels_give_closed_surfaces_that_share_their_contact_face() {
        let image = two_balls(8.0, 6.0);
        let mut c = extract(&image, [1.0; 3], [0.0; 3]);
        smooth(&mut c, 10);
        assert_eq!(c.grains.len(), 2);
        let shared = c.shared.iter().filter(|&&s| s).count();
        assert!(shared > 20, "{shared} shared vertices");
        for g in 0..2 {
            let s = surface_of(&c, g);
            // points not referenced by this grain are ignored by the checks' topology
            // but not by the volume: use a compact copy.
            let compact = crate::mesh::import::formats::surface_from_soup(
                s.facets.iter().map(|f| f.map(|i| s.points[i as usize])),
            );
            check(&compact).unwrap();
            let v = signed_volume(&compact);
            let voxels = c.grains[g].voxels as f64;
            assert!(
                (v / voxels - 1.0).abs() < 0.05,
                "volume {v} vs {voxels} voxels"
            );
        }
        // The contact face: every facet made only of shared vertices appears in both
        // grains, reversed.
        let face = |g: usize| {
            let mut f: Vec<[u32; 3]> = c.grains[g]
                .facets
                .iter()
                .filter(|f| f.iter().all(|&i| c.shared[i as usize]))
                .map(|f| {
                    let mut s = *f;
                    s.sort_unstable();
                    s
                })
                .collect();
            f.sort_unstable();
            f
        };
        assert!(!face(0).is_empty());
        assert_eq!(face(0), face(1));
    }
}
