//! Normals at the master surface's vertices: the smooth unit normal of the curved patches
//! (see [`super::patch`]) and the angle-weighted pseudo-normal that decides inside/outside
//! when a node's closest point is a vertex (Bærentzen & Aanæs 2005).
//!
//! The smooth normal uses Max's weights (Max 1999),
//!
//! n ∝ Σ_f (e₁ × e₂) / (|e₁|² |e₂|²),
//!
//! e₁, e₂ the facet's two edges from the vertex in its orientation order. It is exact when
//! the vertex and its ring lie on a sphere, however irregular the ring: what the Phong
//! patch's shape factor ½ assumes (its leading-order reproduction of a quadratic surface
//! needs exact vertex normals). The angle-weighted normal it replaced is not exact on an
//! irregular ring, and it cost an `acos` and three square roots per facet where this costs
//! one division; the narrow phase needs it at the three corners of every evaluated node's
//! closest facet, so that was the largest part of a contact point's arithmetic
//! (docs/BENCHMARKS.md, session 28).
//!
//! The pseudo-normal keeps the angle weights: only they make the sign test at a vertex
//! exact for any closed mesh. It is needed only when the closest point is a vertex, so it
//! is computed then, not with the smooth normal.
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
    corners_normal(x, cm.facet[f])
}

/// Unit normal of the facet with corners `corners` (model node ids, in its orientation)
/// at positions `x`.
#[inline]
pub fn corners_normal(x: &[[f64; 3]], corners: [u32; 3]) -> [f64; 3] {
    let [a, b, c] = corners.map(|n| x[n as usize]);
    triangle_normal(a, b, c)
}

/// The range of `vertex_facets` and `vertex_fans` that holds the surface vertex at model
/// node `vnode`.
#[inline]
pub(super) fn around(cm: &ContactModel, vnode: u32) -> std::ops::Range<usize> {
    let s = cm.surface_index[vnode as usize] as usize;
    cm.vertex_facet_offsets[s] as usize..cm.vertex_facet_offsets[s + 1] as usize
}

/// The facets around the surface vertex at model node `vnode`.
#[inline]
fn facets_around(cm: &ContactModel, vnode: u32) -> &[u32] {
    &cm.vertex_facets[around(cm, vnode)]
}

/// For each facet around the surface vertex at model node `vnode`, its other two corners
/// in orientation order (see `ContactModel::vertex_fans`).
#[inline]
pub(super) fn fan_around(cm: &ContactModel, vnode: u32) -> &[[u32; 2]] {
    &cm.vertex_fans[around(cm, vnode)]
}

/// Facets around a vertex whose area normals [`smooth_normal`] keeps on the stack for the
/// crease test; a vertex of higher valence computes the rest twice.
const KEPT_NORMALS: usize = 16;

/// The edges e₁, e₂ of a facet from its corner `p` to its other corners `fan` (in the
/// facet's orientation order: e₁ × e₂ is its outward area normal, twice its area long).
#[inline(always)]
fn edges_from(x: &[[f64; 3]], p: [f64; 3], fan: [u32; 2]) -> ([f64; 3], [f64; 3]) {
    (sub(x[fan[0] as usize], p), sub(x[fan[1] as usize], p))
}

/// The smooth unit normal at model node `vnode` (Max's weights, module docs), or `None`
/// at a crease or a degenerate facet (see [`smooth_vertex_normal`]). `fan` is the
/// vertex's [`fan_around`], as a [`super::candidate_facet::CandidateFacet`] holds it.
#[inline(always)]
pub fn smooth_normal(x: &[[f64; 3]], vnode: u32, fan: &[[u32; 2]]) -> Option<[f64; 3]> {
    let p = x[vnode as usize];
    let mut kept = [[0.0; 3]; KEPT_NORMALS];
    let mut sum = [0.0; 3];
    for (i, &corners) in fan.iter().enumerate() {
        let (e1, e2) = edges_from(x, p, corners);
        let weight = dot(e1, e1) * dot(e2, e2);
        if weight == 0.0 {
            return None;
        }
        let area_normal = cross(e1, e2);
        sum = add(sum, scale(area_normal, 1.0 / weight));
        if i < KEPT_NORMALS {
            kept[i] = area_normal;
        }
    }
    let area_normal_of = |(i, &corners): (usize, &[u32; 2])| {
        if i < KEPT_NORMALS {
            kept[i]
        } else {
            let (e1, e2) = edges_from(x, p, corners);
            cross(e1, e2)
        }
    };
    smooth_vertex_normal(sum, fan.iter().enumerate().map(area_normal_of))
}

/// The angle-weighted pseudo-normal Σ θ_f n_f at model node `vnode` (θ_f the angle of
/// facet f there, n_f its unit normal; not normalised). A facet with a degenerate edge at
/// the vertex adds nothing.
pub fn pseudo_normal_at_vertex(cm: &ContactModel, x: &[[f64; 3]], vnode: u32) -> [f64; 3] {
    let mut pseudo = [0.0; 3];
    let p = x[vnode as usize];
    for (&f, &corners) in facets_around(cm, vnode).iter().zip(fan_around(cm, vnode)) {
        let (e1, e2) = edges_from(x, p, corners);
        let (l1, l2) = (norm(e1), norm(e2));
        if l1 == 0.0 || l2 == 0.0 {
            continue;
        }
        let angle = (dot(e1, e2) / (l1 * l2)).clamp(-1.0, 1.0).acos();
        pseudo = add(pseudo, scale(facet_normal(cm, x, f as usize), angle));
    }
    pseudo
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::parse_scene;
    use crate::solver::build_solver;

    /// A sphere mesh's surface vertices lie on the sphere, and its rings are irregular:
    /// Max's normal is radial there to round-off, the angle-weighted one is not (which is
    /// why the curved patches take Max's).
    #[test]
    fn smooth_normals_are_radial_on_a_sphere_mesh() {
        let (radius, centre) = (1.1e-3, [2.0e-4, -1.0e-4, 3.0e-4]);
        let text = format!(
            "[simulation]\nduration = 1e-6\n[materials.glass]\nyoungs_modulus = 63e9\n\
             poisson_ratio = 0.22\ndensity = 2500.0\n[contact]\nfriction = 0.3\n\
             [[grains]]\nname = \"a\"\nmaterial = \"glass\"\n\
             shape = {{ sphere = {{ radius = {radius:e}, seeding = 3.0e-4 }} }}\n\
             centre = {centre:?}\n"
        );
        let loaded = parse_scene("test.toml", &text, &[]).expect("scene parses");
        let s = build_solver(&loaded).expect("model builds");
        let (cm, x) = (&s.model.contact, &s.state.x);
        let unit = |v: [f64; 3]| scale(v, 1.0 / norm(v));
        let (mut max_weights, mut angle_weights) = (0.0f64, 0.0f64);
        for &v in &cm.node {
            let radial = unit(sub(x[v as usize], centre));
            let n = smooth_normal(x, v, fan_around(cm, v)).expect("a sphere has no crease");
            max_weights = max_weights.max(norm(sub(n, radial)));
            let pseudo = unit(pseudo_normal_at_vertex(cm, x, v));
            angle_weights = angle_weights.max(norm(sub(pseudo, radial)));
        }
        assert!(cm.node.len() > 100, "{} surface nodes", cm.node.len());
        assert!(
            max_weights < 1e-12,
            "Max's normal {max_weights:e} from radial"
        );
        assert!(angle_weights > 1e-4, "angle-weighted {angle_weights:e}");
    }
}
