//! Isotropic remeshing of an imported surface to a size field, after Botsch & Kobbelt
//! (2004): a few passes of
//!
//! 1. split every edge longer than 4/3 h at its midpoint,
//! 2. collapse every edge shorter than 4/5 h (shortest first, [`collapse_short_edges`]),
//! 3. flip edges toward valence 6,
//! 4. move every vertex toward the mean of its neighbours within its tangent plane,
//!
//! with every new or moved vertex projected back onto the input surface (closest point,
//! through a bounding-volume tree of its facets). The input is the geometry: a fine scan
//! surface is coarsened onto itself and a coarse CAD surface refined on its own facets.
//! **Sharp features** — edges whose facets meet at more than [`FEATURE_ANGLE_DEG`] — are
//! kept: their vertices never move or go, and their edges are split only along themselves
//! and never flipped or collapsed.
//!
//! **Curvature sizing** ([`CurvatureSizing`]): h ≤ 2·mr·ρ, ρ the smallest principal radius
//! of curvature at the input's vertices (the largest normal curvature 2 n·e/|e|² over
//! their edges e), bounded below by `min_seeding` and graded at `growth` along the
//! surface, so a curved tip gets the facets a sphere of radius ρ gets at mesh ratio mr.

use std::collections::{HashMap, HashSet};

use serde::{Deserialize, Serialize};

use super::zones::SizeField;
use super::Surface;
use crate::math::{add, closest_on_triangle, cross, dot, norm, scale, sub, tangent_basis};
use crate::mesh::collapse::{
    collapse_short_edges, facets_around, quality, ring, CollapseRules, MIN_QUALITY,
};

/// Facets meeting at a larger angle (between their normals) make a sharp feature.
pub const FEATURE_ANGLE_DEG: f64 = 60.0;
/// Remeshing passes (split, collapse, flip, relax).
const PASSES: usize = 6;
const SPLIT_ABOVE: f64 = 4.0 / 3.0;
const COLLAPSE_BELOW: f64 = 0.8;
/// Smallest cosine between a facet's normal before and after a flip or a vertex move.
const MIN_TURN_COSINE: f64 = 0.5;

/// Finer facets where the surface is curved.
///
/// ```toml
/// curvature = { mr = 0.05, min_seeding = 2.0e-5 }
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CurvatureSizing {
    /// Mesh ratio (–): edge ≤ 2·mr·ρ, ρ the local smallest radius of curvature.
    pub mr: f64,
    /// Smallest edge curvature sizing asks for (m); sharp edges (ρ → 0) get this.
    pub min_seeding: f64,
    /// Growth of the edge length with the distance along the surface (–, default 0.3).
    #[serde(default = "default_growth")]
    pub growth: f64,
}

fn default_growth() -> f64 {
    0.3
}

/// The input surface as the geometry the remeshed vertices lie on, with its sizes.
pub struct Reference<'a> {
    s: &'a Surface,
    tree: TriangleTree,
    /// With curvature sizing: the edge length it asks for at each input vertex.
    vertex_size: Option<Vec<f64>>,
    field: SizeField<'a>,
}

impl<'a> Reference<'a> {
    pub fn new(s: &'a Surface, field: SizeField<'a>, curvature: Option<&CurvatureSizing>) -> Self {
        Reference {
            s,
            tree: TriangleTree::new(s),
            vertex_size: curvature.map(|c| curvature_sizes(s, c)),
            field,
        }
    }

    /// The closest point of the input surface: its facet and barycentric coordinates.
    fn closest(&self, x: [f64; 3]) -> (usize, [f64; 3]) {
        self.tree.closest(self.s, x)
    }

    /// The closest point of the input surface.
    fn project(&self, x: [f64; 3]) -> [f64; 3] {
        let (t, w) = self.closest(x);
        let p = self.s.facets[t].map(|v| self.s.points[v as usize]);
        [0, 1, 2].map(|k| w[0] * p[0][k] + w[1] * p[1][k] + w[2] * p[2][k])
    }

    /// Edge length wanted at x (a point on or near the surface): the zones' field, and
    /// curvature sizing interpolated at the closest input point.
    pub fn size(&self, x: [f64; 3]) -> f64 {
        let zones = self.field.at(x);
        match &self.vertex_size {
            None => zones,
            Some(h) => {
                let (t, w) = self.closest(x);
                let f = self.s.facets[t];
                let curved = (0..3).map(|k| w[k] * h[f[k] as usize]).sum::<f64>();
                zones.min(curved)
            }
        }
    }

    /// The smallest edge the size field asks for anywhere (m).
    pub fn smallest_size(&self) -> f64 {
        let zones = self
            .field
            .zones
            .iter()
            .map(|z| z.seeding)
            .fold(self.field.seeding, f64::min);
        self.vertex_size
            .iter()
            .flatten()
            .copied()
            .fold(zones, f64::min)
    }

    /// Facets the remeshed surface will have (∫ dA / (√3/4 h²) over the input), to refuse
    /// a size field that asks for too many before meshing.
    pub fn expected_facets(&self) -> f64 {
        self.s
            .facets
            .iter()
            .map(|f| {
                let p = f.map(|v| self.s.points[v as usize]);
                let area = 0.5 * norm(cross(sub(p[1], p[0]), sub(p[2], p[0])));
                let centre = scale(add(add(p[0], p[1]), p[2]), 1.0 / 3.0);
                let h = self.size(centre);
                area / (0.25 * 3f64.sqrt() * h * h)
            })
            .sum()
    }
}

/// Remeshes `input` (closed, checked) toward the sizes of `reference` (built on `input`).
pub fn remesh(input: &Surface, reference: &Reference) -> Surface {
    let mut s = input.clone();
    let (mut pinned, mut features) = sharp_features(input);
    let size = |x: [f64; 3]| reference.size(x);
    let max_size = reference.field.seeding;
    for _ in 0..PASSES {
        // 1. split
        let mids = super::refine::split_edges_once(&mut s, |l, mid| l > SPLIT_ABOVE * size(mid));
        pinned.resize(s.points.len(), false);
        let mut ordered: Vec<_> = mids.into_iter().collect();
        ordered.sort_unstable();
        for ((a, b), m) in ordered {
            if features.remove(&(a, b)) {
                pinned[m as usize] = true;
                features.insert((a.min(m), a.max(m)));
                features.insert((b.min(m), b.max(m)));
            } else {
                s.points[m as usize] = reference.project(s.points[m as usize]);
            }
        }
        // 2. collapse
        let rules = CollapseRules {
            size: &size,
            max_size,
            below: COLLAPSE_BELOW,
            above: SPLIT_ABOVE,
            pinned: &pinned,
            absorb_into_pinned: true,
            protected: &|a, b| features.contains(&(a.min(b), a.max(b))),
        };
        let (points, facets, old) = collapse_short_edges(&s.points, &s.facets, &rules);
        let mut new_id = vec![u32::MAX; s.points.len()];
        for (n, &o) in old.iter().enumerate() {
            new_id[o as usize] = n as u32;
        }
        pinned = old.iter().map(|&o| pinned[o as usize]).collect();
        features = features
            .iter()
            .map(|&(a, b)| (new_id[a as usize], new_id[b as usize]))
            .filter(|&(a, b)| a != u32::MAX && b != u32::MAX)
            .map(|(a, b)| (a.min(b), a.max(b)))
            .collect();
        s = Surface { points, facets };
        // 3. flip, 4. relax
        flip_toward_valence_six(&mut s, &pinned, &features);
        relax_tangentially(&mut s, &pinned, reference);
    }
    for _ in 0..ACUTE_SWEEPS {
        if !make_acute(&mut s, &pinned, reference) {
            break;
        }
    }
    s
}

/// Sweeps of [`make_acute`] at most.
const ACUTE_SWEEPS: usize = 8;
/// Largest facet angle left alone (TetGen splits every surface edge whose diametral ball
/// holds a vertex — the edge opposite any angle ≥ 90° — and its splits cascade).
const MAX_ANGLE_DEG: f64 = 85.0;

/// Moves the free vertex at each angle above [`MAX_ANGLE_DEG`] away from the opposite
/// edge, within the facet's plane, to where it sees that edge at ≈ 80°, then onto the
/// input; a move that folds a facet or makes one worse than the quality bound (when it
/// was not already) is not made. Returns whether any vertex moved.
fn make_acute(s: &mut Surface, pinned: &[bool], reference: &Reference) -> bool {
    let cos_max = MAX_ANGLE_DEG.to_radians().cos();
    let around = facets_around(s.points.len(), &s.facets);
    let mut moved_any = false;
    for i in 0..s.facets.len() {
        let f = s.facets[i];
        for k in 0..3 {
            let (c, a, b) = (f[k], f[(k + 1) % 3], f[(k + 2) % 3]);
            if pinned[c as usize] {
                continue;
            }
            let p = |v: u32| s.points[v as usize];
            let (u, w) = (sub(p(a), p(c)), sub(p(b), p(c)));
            if dot(u, w) >= cos_max * norm(u) * norm(w) {
                continue;
            }
            // C moves along the normal to AB through its foot on AB, to ½|AB|/tan 40° from
            // it: the height at which the midpoint's perpendicular sees AB at 80°
            let ab = sub(p(b), p(a));
            let to_c = sub(p(c), scale(add(p(a), p(b)), 0.5));
            let away = sub(to_c, scale(ab, dot(to_c, ab) / dot(ab, ab)));
            let foot = sub(p(c), away);
            let la = norm(away);
            if la == 0.0 {
                continue;
            }
            let height = 0.5 * norm(ab) / 40f64.to_radians().tan();
            let target = add(foot, scale(away, height / la));
            let target = reference.project(target);
            let v = c as usize;
            if move_keeps_facets(s, &around[v], v, target) {
                s.points[v] = target;
                moved_any = true;
            }
        }
    }
    moved_any
}

/// Edges whose facets meet at more than [`FEATURE_ANGLE_DEG`], and their vertices.
fn sharp_features(s: &Surface) -> (Vec<bool>, HashSet<(u32, u32)>) {
    let cos = FEATURE_ANGLE_DEG.to_radians().cos();
    let normals: Vec<[f64; 3]> = s.facets.iter().map(|f| unit_normal(s, *f)).collect();
    let mut pinned = vec![false; s.points.len()];
    let mut features = HashSet::new();
    for g in super::checks::edge_groups(s) {
        if let [(i, _), (j, _)] = g.uses[..] {
            if dot(normals[i], normals[j]) < cos {
                let (a, b) = g.vertices;
                features.insert((a, b));
                pinned[a as usize] = true;
                pinned[b as usize] = true;
            }
        }
    }
    (pinned, features)
}

fn unit_normal(s: &Surface, f: [u32; 3]) -> [f64; 3] {
    let p = f.map(|v| s.points[v as usize]);
    let n = cross(sub(p[1], p[0]), sub(p[2], p[0]));
    let l = norm(n);
    if l > 0.0 {
        scale(n, 1.0 / l)
    } else {
        n
    }
}

/// Per input vertex: min(2·mr·ρ, …) graded at `growth` along edges, ≥ `min_seeding`.
/// The curvatures come from a least-squares fit of the shape operator S to the normal
/// curvatures 2 n·e/|e|² along the vertex's edges e (tᵀ S t, t the edge's direction in
/// the tangent plane); ρ = 1 / max |eigenvalue of S|.
fn curvature_sizes(s: &Surface, c: &CurvatureSizing) -> Vec<f64> {
    let normals = s.vertex_normals();
    // normal equations of the fit, per vertex: Σ r rᵀ (6 entries) and Σ r κ, r = (u², 2uw, w²)
    let mut lhs = vec![[0.0f64; 6]; s.points.len()];
    let mut rhs = vec![[0.0f64; 3]; s.points.len()];
    let mut largest = vec![0.0f64; s.points.len()];
    for f in &s.facets {
        for k in 0..3 {
            let (a, b) = (f[k] as usize, f[(k + 1) % 3] as usize);
            for (v, w) in [(a, b), (b, a)] {
                let ln = norm(normals[v]);
                let e = sub(s.points[w], s.points[v]);
                let l2 = dot(e, e);
                if ln == 0.0 || l2 == 0.0 {
                    continue;
                }
                let n = scale(normals[v], 1.0 / ln);
                let kappa = 2.0 * dot(n, e) / l2;
                largest[v] = largest[v].max(kappa.abs());
                let (u_axis, w_axis) = tangent_basis(n);
                let t = sub(e, scale(n, dot(n, e)));
                let lt = norm(t);
                if lt == 0.0 {
                    continue;
                }
                let (cu, cw) = (dot(t, u_axis) / lt, dot(t, w_axis) / lt);
                let r = [cu * cu, 2.0 * cu * cw, cw * cw];
                let m = &mut lhs[v];
                let mut i = 0;
                for p in 0..3 {
                    for q in p..3 {
                        m[i] += r[p] * r[q];
                        i += 1;
                    }
                }
                for p in 0..3 {
                    rhs[v][p] += r[p] * kappa;
                }
            }
        }
    }
    let kappa: Vec<f64> = (0..s.points.len())
        .map(|v| {
            let m = lhs[v];
            let full = [m[0], m[1], m[2], m[1], m[3], m[4], m[2], m[4], m[5]];
            let det = crate::math::det3(&full);
            if det.abs() < 1e-9 * (m[0] + m[3] + m[5]).powi(3) {
                return largest[v]; // too few edge directions to fit: the largest sample
            }
            let solve = |col: usize| {
                let mut a = full;
                for row in 0..3 {
                    a[3 * row + col] = rhs[v][row];
                }
                crate::math::det3(&a) / det
            };
            let (sa, sb, sc) = (solve(0), solve(1), solve(2));
            let mean = 0.5 * (sa + sc);
            let radius = (0.25 * (sa - sc).powi(2) + sb * sb).sqrt();
            mean.abs() + radius
        })
        .collect();
    let mut h: Vec<f64> = kappa
        .iter()
        .map(|&k| (2.0 * c.mr / k).max(c.min_seeding))
        .collect();
    // grade: h(v) ≤ h(u) + growth·|uv| (Bellman–Ford sweeps until nothing changes)
    loop {
        let mut changed = false;
        for f in &s.facets {
            for k in 0..3 {
                let (a, b) = (f[k] as usize, f[(k + 1) % 3] as usize);
                let l = norm(sub(s.points[a], s.points[b]));
                for (x, y) in [(a, b), (b, a)] {
                    let bound = h[y] + c.growth * l;
                    if h[x] > bound * (1.0 + 1e-12) {
                        h[x] = bound;
                        changed = true;
                    }
                }
            }
        }
        if !changed {
            return h;
        }
    }
}

/// Flips edges that bring their four vertices closer to valence 6 (pinned vertices do not
/// count), when the two new facets are not folded and not much worse than the old ones.
fn flip_toward_valence_six(s: &mut Surface, pinned: &[bool], features: &HashSet<(u32, u32)>) {
    let mut valence = vec![0i64; s.points.len()];
    let mut edges: HashMap<(u32, u32), [u32; 2]> = HashMap::new();
    for (i, f) in s.facets.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (f[k], f[(k + 1) % 3]);
            if a < b {
                valence[a as usize] += 1;
                valence[b as usize] += 1;
            }
            let pair = edges.entry((a.min(b), a.max(b))).or_insert([u32::MAX; 2]);
            if let Some(x) = pair.iter_mut().find(|x| **x == u32::MAX) {
                *x = i as u32;
            }
        }
    }
    let mut keys: Vec<(u32, u32)> = edges.keys().copied().collect();
    keys.sort_unstable();
    let deviation = |v: u32, val: i64| {
        if pinned[v as usize] {
            0
        } else {
            (val - 6).pow(2)
        }
    };
    for key in keys {
        if features.contains(&key) {
            continue;
        }
        let Some(&[f1, f2]) = edges.get(&key) else {
            continue;
        };
        if f1 == u32::MAX || f2 == u32::MAX {
            continue;
        }
        // orient: f1 = (a, b, c) with a→b, f2 holds b→a with third vertex d
        let t1 = s.facets[f1 as usize];
        let k1 = (0..3)
            .find(|&k| {
                let (x, y) = (t1[k], t1[(k + 1) % 3]);
                (x.min(y), x.max(y)) == key
            })
            .unwrap_or(0);
        let (a, b, c) = (t1[k1], t1[(k1 + 1) % 3], t1[(k1 + 2) % 3]);
        let t2 = s.facets[f2 as usize];
        let Some(&d) = t2.iter().find(|&&v| v != a && v != b) else {
            continue;
        };
        if c == d || edges.contains_key(&(c.min(d), c.max(d))) {
            continue;
        }
        let [va, vb, vc, vd] = [a, b, c, d].map(|v| valence[v as usize]);
        let before = deviation(a, va) + deviation(b, vb) + deviation(c, vc) + deviation(d, vd);
        let after = deviation(a, va - 1)
            + deviation(b, vb - 1)
            + deviation(c, vc + 1)
            + deviation(d, vd + 1);
        if after >= before {
            continue;
        }
        let (n1, n2) = (unit_normal(s, [a, d, c]), unit_normal(s, [d, b, c]));
        let old = [t1, t2];
        let old_normal = add(unit_normal(s, t1), unit_normal(s, t2));
        let p = |v: u32| s.points[v as usize];
        let q_old = old
            .iter()
            .map(|t| quality(p(t[0]), p(t[1]), p(t[2])))
            .fold(f64::INFINITY, f64::min);
        let q_new = [[a, d, c], [d, b, c]]
            .iter()
            .map(|t| quality(p(t[0]), p(t[1]), p(t[2])))
            .fold(f64::INFINITY, f64::min);
        let folded = [n1, n2]
            .iter()
            .any(|n| dot(*n, old_normal) < MIN_TURN_COSINE * norm(old_normal))
            || dot(n1, n2) < MIN_TURN_COSINE;
        if folded || q_new < 0.5 * q_old.min(2.0 * MIN_QUALITY) {
            continue;
        }
        s.facets[f1 as usize] = [a, d, c];
        s.facets[f2 as usize] = [d, b, c];
        edges.remove(&key);
        edges.insert((c.min(d), c.max(d)), [f1, f2]);
        // b–c moved from f1 to f2, a–d from f2 to f1
        for (e, from, to) in [((b, c), f1, f2), ((a, d), f2, f1)] {
            if let Some(pair) = edges.get_mut(&(e.0.min(e.1), e.0.max(e.1))) {
                pair.iter_mut()
                    .filter(|x| **x == from)
                    .for_each(|x| *x = to);
            }
        }
        valence[a as usize] -= 1;
        valence[b as usize] -= 1;
        valence[c as usize] += 1;
        valence[d as usize] += 1;
    }
}

/// Moves every free vertex to the mean of its neighbours within its tangent plane, then
/// onto the input surface; a move that folds a facet or makes one worse than the quality
/// bound (when it was not already) is not made.
fn relax_tangentially(s: &mut Surface, pinned: &[bool], reference: &Reference) {
    let normals = s.vertex_normals();
    let around = facets_around(s.points.len(), &s.facets);
    let mut neighbours = Vec::new();
    for v in 0..s.points.len() {
        if pinned[v] || around[v].is_empty() {
            continue;
        }
        ring(&s.facets, &around[v], v as u32, &mut neighbours);
        let p = s.points[v];
        let mean = scale(
            neighbours
                .iter()
                .fold([0.0; 3], |acc, &w| add(acc, s.points[w as usize])),
            1.0 / neighbours.len() as f64,
        );
        let n = normals[v];
        let ln = norm(n);
        if ln == 0.0 {
            continue;
        }
        let n = scale(n, 1.0 / ln);
        let d = sub(mean, p);
        let moved = reference.project(add(p, sub(d, scale(n, dot(n, d)))));
        if move_keeps_facets(s, &around[v], v, moved) {
            s.points[v] = moved;
        }
    }
}

/// Whether moving vertex `v` to `target` leaves each facet `around` it unfolded (turned
/// by less than 60°), not degenerate, and not worse than the quality bound unless it
/// already was.
fn move_keeps_facets(s: &Surface, around: &[u32], v: usize, target: [f64; 3]) -> bool {
    around.iter().all(|&f| {
        let t = s.facets[f as usize];
        let o = t.map(|w| s.points[w as usize]);
        let q = t.map(|w| {
            if w as usize == v {
                target
            } else {
                s.points[w as usize]
            }
        });
        let n_old = cross(sub(o[1], o[0]), sub(o[2], o[0]));
        let n_new = cross(sub(q[1], q[0]), sub(q[2], q[0]));
        let q_new = quality(q[0], q[1], q[2]);
        dot(n_old, n_new) >= MIN_TURN_COSINE * norm(n_old) * norm(n_new)
            && norm(n_new) > 0.0
            && (q_new >= MIN_QUALITY || q_new >= quality(o[0], o[1], o[2]))
    })
}

/// A bounding-volume tree of a surface's facets for closest-point queries.
struct TriangleTree {
    nodes: Vec<TreeNode>,
    order: Vec<u32>,
}

struct TreeNode {
    lo: [f64; 3],
    hi: [f64; 3],
    /// Leaf: facets `order[start..end]`; inner: children `start` and `end`.
    start: u32,
    end: u32,
    leaf: bool,
}

const LEAF_FACETS: usize = 8;

impl TriangleTree {
    fn new(s: &Surface) -> Self {
        let centre = |t: u32| {
            let f = s.facets[t as usize];
            scale(
                add(
                    add(s.points[f[0] as usize], s.points[f[1] as usize]),
                    s.points[f[2] as usize],
                ),
                1.0 / 3.0,
            )
        };
        let mut tree = TriangleTree {
            nodes: Vec::new(),
            order: (0..s.facets.len() as u32).collect(),
        };
        tree.build(s, 0, s.facets.len(), &centre);
        tree
    }

    fn build(
        &mut self,
        s: &Surface,
        start: usize,
        end: usize,
        centre: &dyn Fn(u32) -> [f64; 3],
    ) -> u32 {
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for &t in &self.order[start..end] {
            for v in s.facets[t as usize] {
                let p = s.points[v as usize];
                for k in 0..3 {
                    lo[k] = lo[k].min(p[k]);
                    hi[k] = hi[k].max(p[k]);
                }
            }
        }
        let id = self.nodes.len() as u32;
        self.nodes.push(TreeNode {
            lo,
            hi,
            start: start as u32,
            end: end as u32,
            leaf: true,
        });
        if end - start > LEAF_FACETS {
            let axis = (0..3)
                .max_by(|&a, &b| (hi[a] - lo[a]).total_cmp(&(hi[b] - lo[b])))
                .unwrap_or(0);
            let middle = (start + end) / 2;
            self.order[start..end].select_nth_unstable_by(middle - start, |&x, &y| {
                centre(x)[axis].total_cmp(&centre(y)[axis])
            });
            let left = self.build(s, start, middle, centre);
            let right = self.build(s, middle, end, centre);
            let node = &mut self.nodes[id as usize];
            (node.start, node.end, node.leaf) = (left, right, false);
        }
        id
    }

    /// The facet closest to x and the barycentric coordinates of its closest point.
    fn closest(&self, s: &Surface, x: [f64; 3]) -> (usize, [f64; 3]) {
        let gap2 = |n: u32| -> f64 {
            let node = &self.nodes[n as usize];
            (0..3)
                .map(|k| (node.lo[k] - x[k]).max(x[k] - node.hi[k]).max(0.0).powi(2))
                .sum()
        };
        let mut best = (f64::INFINITY, 0usize, [1.0, 0.0, 0.0]);
        let mut stack = vec![(0u32, 0.0)];
        while let Some((n, gap)) = stack.pop() {
            if gap >= best.0 {
                continue;
            }
            let node = &self.nodes[n as usize];
            if node.leaf {
                for &t in &self.order[node.start as usize..node.end as usize] {
                    let f = s.facets[t as usize];
                    let p = f.map(|v| s.points[v as usize]);
                    let w = closest_on_triangle(x, p[0], p[1], p[2]);
                    let q = [0, 1, 2].map(|k| w[0] * p[0][k] + w[1] * p[1][k] + w[2] * p[2][k]);
                    let d = sub(x, q);
                    let d2 = dot(d, d);
                    if d2 < best.0 {
                        best = (d2, t as usize, w);
                    }
                }
            } else {
                // nearer child on top of the stack
                let (a, b) = ((node.start, gap2(node.start)), (node.end, gap2(node.end)));
                let (near, far) = if a.1 <= b.1 { (a, b) } else { (b, a) };
                stack.push(far);
                stack.push(near);
            }
        }
        (best.1, best.2)
    }
}

#[cfg(test)]
mod tests;
