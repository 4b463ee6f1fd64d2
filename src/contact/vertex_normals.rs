//! Normals at the master surface's vertices: the angle-weighted pseudo-normal that decides
//! inside/outside at a vertex (Bærentzen & Aanæs 2005) and the smooth unit normal of the
//! curved patches (see [`super::patch`]).
//!
//! Both are sums over the facets around a vertex, with an `acos` per facet, and the narrow
//! phase needs them at the three corners of the closest facet of every evaluated slave node
//! (and at the corners of its neighbour across an edge): [`vertex_normals`] computes both
//! at once, each facet normal once.
//!
//! A per-step memo of these sums was measured and dropped: in a dense FCC packing each
//! master vertex is asked for by one or two evaluations per step, and emptying the memo
//! every step cost more than the repeats it saved.

use super::patch::smooth_vertex_normal;
use super::ContactModel;
use crate::math::{add, cross, dot, norm, scale, sub};

/// Unit normal of triangle (a, b, c) oriented by (b−a)×(c−a); zero for a degenerate one.
#[inline]
pub fn triangle_normal(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> [f64; 3] {
    let n = cross(sub(b, a), sub(c, a));
    let l = norm(n);
    if l > 0.0 {
        scale(n, 1.0 / l)
    } else {
        [0.0; 3]
    }
}

/// Unit normal of facet `f` at positions `x`.
#[inline]
pub fn facet_normal(cm: &ContactModel, x: &[[f64; 3]], f: usize) -> [f64; 3] {
    let [a, b, c] = cm.facet[f].map(|n| x[n as usize]);
    triangle_normal(a, b, c)
}

/// The facets around surface vertex `s` (flat surface index).
#[inline]
fn facets_around(cm: &ContactModel, s: usize) -> &[u32] {
    &cm.vertex_facets[cm.vertex_facet_offsets[s] as usize..cm.vertex_facet_offsets[s + 1] as usize]
}

/// Facets around a vertex whose normals [`vertex_normals`] keeps on the stack; a vertex of
/// higher valence computes the rest twice.
const KEPT_NORMALS: usize = 16;

/// θ_f n_f of facet `f` at model node `vnode` (θ_f the facet's angle there), `None` when an
/// edge at the vertex is degenerate; and the facet's unit normal n_f.
#[inline]
fn weighted_facet_normal(
    cm: &ContactModel,
    x: &[[f64; 3]],
    vnode: u32,
    f: usize,
) -> (Option<[f64; 3]>, [f64; 3]) {
    let tri = cm.facet[f];
    let n = facet_normal(cm, x, f);
    let j = tri.iter().position(|&v| v == vnode).unwrap_or(0);
    let p = x[tri[j] as usize];
    let e1 = sub(x[tri[(j + 1) % 3] as usize], p);
    let e2 = sub(x[tri[(j + 2) % 3] as usize], p);
    let (l1, l2) = (norm(e1), norm(e2));
    if l1 == 0.0 || l2 == 0.0 {
        return (None, n);
    }
    let angle = (dot(e1, e2) / (l1 * l2)).clamp(-1.0, 1.0).acos();
    (Some(scale(n, angle)), n)
}

/// The pseudo-normal at model node `vnode` and its smooth unit normal (`None` at a
/// crease, see [`smooth_vertex_normal`]), each facet normal computed once.
pub fn vertex_normals(cm: &ContactModel, x: &[[f64; 3]], vnode: u32) -> VertexNormal {
    let s = cm.surface_index[vnode as usize] as usize;
    let around = facets_around(cm, s);
    let mut kept = [[0.0; 3]; KEPT_NORMALS];
    let mut pseudo = [0.0; 3];
    for (i, &f) in around.iter().enumerate() {
        let (weighted, n) = weighted_facet_normal(cm, x, vnode, f as usize);
        if let Some(w) = weighted {
            pseudo = add(pseudo, w);
        }
        if i < KEPT_NORMALS {
            kept[i] = n;
        }
    }
    let normal_of = |(i, &f): (usize, &u32)| {
        if i < KEPT_NORMALS {
            kept[i]
        } else {
            facet_normal(cm, x, f as usize)
        }
    };
    VertexNormal {
        pseudo,
        smooth: smooth_vertex_normal(pseudo, around.iter().enumerate().map(normal_of)),
    }
}

/// Both normals of one vertex.
#[derive(Debug, Clone, Copy, Default)]
pub struct VertexNormal {
    /// Σ θ_f n_f over the facets around the vertex (not normalised): decides inside or
    /// outside when the closest point is the vertex.
    pub pseudo: [f64; 3],
    /// Unit normal of the curved patches there, `None` at a crease.
    pub smooth: Option<[f64; 3]>,
}
