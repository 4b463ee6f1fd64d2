//! The master surface as curved patches: each facet is replaced by its Phong tessellation
//! (Boubekeur & Alexa 2008) with shape factor ½,
//!
//! q(b) = p(b) − ½ Σᵢ bᵢ ((p(b) − pᵢ)·nᵢ) nᵢ,   p(b) = Σᵢ bᵢ pᵢ,
//!
//! where pᵢ are the facet's corners, nᵢ their unit vertex normals (Max's weights, exact on
//! a sphere: [`super::vertex_normals`]) and b the barycentric coordinates. The patch
//! passes through the corners with the tangent planes ⟂ nᵢ there, neighbouring patches
//! share their edge curves (an edge's curve depends only on its two corners), and for a
//! quadratic surface (a sphere at mesh scale) with exact vertex normals the factor ½
//! reproduces the surface to leading order: the flat facet lies h²/(8R) inside a sphere of
//! radius R meshed at edge h, full Phong (factor 1) as far outside.
//!
//! Why: a flat facet's normal is tilted from the body's by up to ~h/(2R). Where a contact is
//! carried by one node or a few (the FCC cell at 50 kPa: contact radii ~1 % of R, a single
//! node pair at each lattice contact), the penetrating node finds the facet leaning in the
//! direction of its tangential offset nearest, so the contact normal tilts *with* the
//! offset and the effective friction angle drops by the tilt: at h = 0.27 R the walled FCC
//! cell failed 27 % below Thornton. On the curved patch the normal at a lattice contact
//! node is its vertex normal (radial for a symmetric fan) and turns continuously, and the
//! penetration is the distance to the patch, so the penalty force along the patch normal is
//! the gradient of the penalty energy with respect to the slave node (the energy ledger
//! stays closed).
//!
//! Creases are kept sharp, and the surface stays continuous across them: a *vertex* is
//! sharp when its vertex normal is more than [`CREASE_DEG`] from the normal of any facet
//! around it (a block's edges and corners: 45°, 54.7°; the coarsest virtual-sand meshes
//! have a few such vertices), and every facet uses its own flat normal at a sharp corner.
//! A corner with the facet's flat normal adds nothing along the facet's edges (the edge
//! lies in the facet's plane), so an edge's curve depends only on the smooth normals of
//! its two ends, which every facet sharing it sees alike; a facet with three sharp corners
//! is flat. (Keeping a facet flat because one corner is sharp, while its neighbour across
//! an edge curves, leaves a step of up to the bulge between them: a node sliding across
//! that edge jumps from outside to several µm inside and the penalty force blows up.)

use crate::math::{add, cross, dot, norm, scale, sub};

/// Phong shape factor: ½ is exact for quadratic surfaces (module docs).
pub const SHAPE_FACTOR: f64 = 0.5;
/// A facet stays flat when a corner's vertex normal is further than this from the facet's
/// normal (degrees): above the tilt of any sphere mesh in use (≤ 20° at MR 0.3), below a
/// block's edges (45°).
pub const CREASE_DEG: f64 = 35.0;
/// Gauss–Newton iterations for the closest patch point (quadratic patch, started at the
/// flat closest point: converged to round-off in 3 on sphere meshes).
const ITERATIONS: usize = 4;

/// A facet's corners and unit vertex normals.
#[derive(Debug, Clone, Copy)]
pub struct Patch {
    pub corners: [[f64; 3]; 3],
    pub normals: [[f64; 3]; 3],
    /// The flat facet's outward unit normal (orients the patch normal).
    pub outward: [f64; 3],
}

/// The closest point of a patch to a query point.
#[derive(Debug, Clone, Copy)]
pub struct PatchPoint {
    /// Barycentric coordinates (in the triangle).
    pub bary: [f64; 3],
    pub point: [f64; 3],
    /// Outward unit normal of the patch at the point.
    pub normal: [f64; 3],
    /// Signed distance along the normal: > 0 inside (penetration), m.
    pub depth: f64,
    /// Distance from the query point (m).
    pub distance: f64,
    /// The edge (k joins corners k and k+1) the point was clamped to, if any.
    pub clamped_edge: Option<usize>,
}

/// The unit vertex normal along `vertex_normal` (any length) of a vertex whose
/// surrounding facets have the normals `facet_normals` (any lengths, e.g. area normals), or
/// `None` when the vertex is sharp: some facet's normal is more than [`CREASE_DEG`] from it,
/// or it or a facet's normal is zero (a degenerate facet).
#[inline(always)]
pub fn smooth_vertex_normal(
    vertex_normal: [f64; 3],
    facet_normals: impl IntoIterator<Item = [f64; 3]>,
) -> Option<[f64; 3]> {
    let l = norm(vertex_normal);
    if l == 0.0 {
        return None;
    }
    let n = scale(vertex_normal, 1.0 / l);
    let cos_crease = CREASE_DEG.to_radians().cos();
    // cos(n, f) ≥ cos_crease without normalising f
    let cos2 = cos_crease * cos_crease;
    facet_normals
        .into_iter()
        .all(|f| {
            let d = dot(n, f);
            d > 0.0 && d * d >= cos2 * dot(f, f)
        })
        .then_some(n)
}

impl Patch {
    /// The patch of a facet, or `None` when it is flat (every corner sharp).
    /// `smooth_normal(k)` is the unit vertex normal at corner k, or `None` at a sharp
    /// corner (see [`smooth_vertex_normal`]), where the facet's own `flat_normal` is used.
    #[inline(always)]
    pub fn of_facet(
        corners: [[f64; 3]; 3],
        flat_normal: [f64; 3],
        smooth_normal: impl Fn(usize) -> Option<[f64; 3]>,
    ) -> Option<Self> {
        let mut normals = [flat_normal; 3];
        let mut any_smooth = false;
        for (k, n) in normals.iter_mut().enumerate() {
            if let Some(v) = smooth_normal(k) {
                *n = v;
                any_smooth = true;
            }
        }
        any_smooth.then_some(Self {
            corners,
            normals,
            outward: flat_normal,
        })
    }

    /// Bound of the patch's distance from the flat facet (m): ½ max |(pⱼ − pᵢ)·nᵢ|.
    #[inline(always)]
    pub fn bulge_bound(&self) -> f64 {
        let mut m = 0.0f64;
        for i in 0..3 {
            for j in 0..3 {
                m = m.max(dot(sub(self.corners[j], self.corners[i]), self.normals[i]).abs());
            }
        }
        SHAPE_FACTOR * m
    }

    /// Point and tangents ∂q/∂u, ∂q/∂v at b = (1−u−v, u, v).
    #[inline(always)]
    fn eval(&self, u: f64, v: f64) -> ([f64; 3], [f64; 3], [f64; 3]) {
        let [p0, p1, p2] = self.corners;
        let b = [1.0 - u - v, u, v];
        let (db_du, db_dv) = ([-1.0, 1.0, 0.0], [-1.0, 0.0, 1.0]);
        let p = add(add(scale(p0, b[0]), scale(p1, b[1])), scale(p2, b[2]));
        let (e1, e2) = (sub(p1, p0), sub(p2, p0));
        let (mut q, mut qu, mut qv) = (p, e1, e2);
        for i in 0..3 {
            let n = self.normals[i];
            let h = dot(sub(p, self.corners[i]), n);
            q = sub(q, scale(n, SHAPE_FACTOR * b[i] * h));
            qu = sub(
                qu,
                scale(n, SHAPE_FACTOR * (db_du[i] * h + b[i] * dot(e1, n))),
            );
            qv = sub(
                qv,
                scale(n, SHAPE_FACTOR * (db_dv[i] * h + b[i] * dot(e2, n))),
            );
        }
        (q, qu, qv)
    }

    /// Closest patch point to `xs` by Gauss–Newton from the barycentric start `bary`,
    /// clamped to the triangle.
    #[inline(always)]
    pub fn closest(&self, xs: [f64; 3], bary: [f64; 3]) -> PatchPoint {
        let outward = self.outward;
        let (mut u, mut v) = (bary[1], bary[2]);
        let mut clamped = None;
        for _ in 0..ITERATIONS {
            let (q, qu, qv) = self.eval(u, v);
            let r = sub(xs, q);
            let (a11, a12, a22) = (dot(qu, qu), dot(qu, qv), dot(qv, qv));
            let det = a11 * a22 - a12 * a12;
            if det <= 0.0 {
                break;
            }
            let (g1, g2) = (dot(qu, r), dot(qv, r));
            let du = (a22 * g1 - a12 * g2) / det;
            let dv = (a11 * g2 - a12 * g1) / det;
            (u, v, clamped) = clamp_to_triangle(u + du, v + dv);
            if du.abs() + dv.abs() < 1e-13 {
                break;
            }
        }
        let (q, qu, qv) = self.eval(u, v);
        let mut normal = cross(qu, qv);
        let l = norm(normal);
        normal = if l > 0.0 {
            scale(normal, 1.0 / l)
        } else {
            outward
        };
        if dot(normal, outward) < 0.0 {
            normal = scale(normal, -1.0);
        }
        let r = sub(xs, q);
        PatchPoint {
            bary: [1.0 - u - v, u, v],
            point: q,
            normal,
            depth: -dot(r, normal),
            distance: norm(r),
            clamped_edge: clamped,
        }
    }
}

/// (u, v) projected onto the triangle u, v ≥ 0, u + v ≤ 1 (nearest in the (u, v) plane),
/// with the edge it lands on (edge 0: v = 0, corners 0–1; edge 1: u + v = 1, corners 1–2;
/// edge 2: u = 0, corners 2–0).
fn clamp_to_triangle(u: f64, v: f64) -> (f64, f64, Option<usize>) {
    if u >= 0.0 && v >= 0.0 && u + v <= 1.0 {
        return (u, v, None);
    }
    let t = (0.5 * (u - v + 1.0)).clamp(0.0, 1.0);
    let candidates = [
        (u.clamp(0.0, 1.0), 0.0, 0),
        (t, 1.0 - t, 1),
        (0.0, v.clamp(0.0, 1.0), 2),
    ];
    let d2 = |c: &(f64, f64, usize)| (c.0 - u).powi(2) + (c.1 - v).powi(2);
    let best = candidates
        .iter()
        .min_by(|a, b| d2(a).total_cmp(&d2(b)))
        .expect("three candidates");
    (best.0, best.1, Some(best.2))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A facet of a sphere of radius r about the origin, corners at polar angle `theta`.
    fn sphere_facet(r: f64, theta: f64) -> Patch {
        let corner = |phi: f64| {
            let d = [
                theta.sin() * phi.cos(),
                theta.sin() * phi.sin(),
                theta.cos(),
            ];
            (scale(d, r), d)
        };
        let c: Vec<_> = [0.0, 2.0944, 4.1888].iter().map(|&p| corner(p)).collect();
        Patch {
            corners: [c[0].0, c[1].0, c[2].0],
            normals: [c[0].1, c[1].1, c[2].1],
            outward: [0.0, 0.0, 1.0],
        }
    }

    #[test]
    fn patch_of_a_sphere_facet_reproduces_the_sphere_far_better_than_the_flat_facet() {
        let r = 1.0;
        let patch = sphere_facet(r, 0.15);
        for (u, v) in [(1.0 / 3.0, 1.0 / 3.0), (0.5, 0.0), (0.2, 0.3), (0.1, 0.7)] {
            let (q, _, _) = patch.eval(u, v);
            let [p0, p1, p2] = patch.corners;
            let b = [1.0 - u - v, u, v];
            let p = add(add(scale(p0, b[0]), scale(p1, b[1])), scale(p2, b[2]));
            let (flat_err, patch_err) = ((norm(p) - r).abs(), (norm(q) - r).abs());
            assert!(flat_err > 1e-3, "{flat_err}");
            assert!(patch_err < 0.02 * flat_err, "{patch_err} vs {flat_err}");
        }
    }

    #[test]
    fn closest_point_gives_the_radial_normal_and_depth_inside_a_sphere_facet() {
        let r = 1.0;
        let theta = 0.15; // corner edge ≈ 0.26 R, the coarse FCC contact fans
        let patch = sphere_facet(r, theta);
        let flat_sag = r - theta.cos() * r; // ≥ the flat facet's depth below the sphere
        let corner = patch.normals[0];
        for (towards, start, depth_tol) in [
            // near a corner (a lattice contact node): the patch is the tangent plane there
            (
                add(scale(corner, 0.98), [0.0, 0.0, 0.02]),
                [0.9, 0.05, 0.05],
                1e-3 * flat_sag,
            ),
            // mid-facet, where the flat facet is furthest from the sphere
            ([0.02, -0.01, 1.0], [1.0 / 3.0; 3], 0.02 * flat_sag),
        ] {
            let dir = scale(towards, 1.0 / norm(towards));
            let xs = scale(dir, r - 1e-4);
            let pp = patch.closest(xs, start);
            assert!(pp.clamped_edge.is_none());
            assert!(dot(pp.normal, dir) > 1.0 - 5e-5, "{:?}", pp.normal);
            assert!((pp.depth - 1e-4).abs() < depth_tol, "{} vs 1e-4", pp.depth);
            // the residual is along the normal: a true closest point
            let r_vec = sub(xs, pp.point);
            assert!(norm(cross(r_vec, pp.normal)) < 1e-9, "{r_vec:?}");
        }
    }

    #[test]
    fn a_flat_facet_is_its_own_patch_and_creases_stay_flat() {
        let flat = [0.0, 0.0, 1.0];
        let corners = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let patch = Patch::of_facet(corners, flat, |_| Some(flat)).expect("smooth");
        let pp = patch.closest([0.2, 0.3, -0.05], [1.0 / 3.0; 3]);
        assert!((pp.depth - 0.05).abs() < 1e-14 && (pp.normal[2] - 1.0).abs() < 1e-14);
        assert!((pp.bary[1] - 0.2).abs() < 1e-12 && (pp.bary[2] - 0.3).abs() < 1e-12);
        // a cube edge: corner normals at 45° to the face
        let edge = {
            let s = std::f64::consts::FRAC_1_SQRT_2;
            [s, 0.0, s]
        };
        assert!(smooth_vertex_normal(scale(edge, 3.0), [flat, [1.0, 0.0, 0.0]]).is_none());
        assert!(smooth_vertex_normal(scale(edge, 3.0), [edge]).is_some());
        assert!(Patch::of_facet(corners, flat, |_| None).is_none());
    }

    /// Two facets sharing the edge p0–p1, at a 40° kink: p1 is sharp, p0 and the far
    /// corners smooth. Both patches trace the same curve along the shared edge, so a node
    /// sliding across it sees a continuous surface.
    #[test]
    fn patches_meet_along_an_edge_with_a_sharp_end() {
        let unit = |v: [f64; 3]| scale(v, 1.0 / norm(v));
        let (p0, p1) = ([0.0, 0.0, 0.0], [1.0, 0.0, 0.0]);
        let kink = 40f64.to_radians();
        let (p2, p3) = (
            [0.4, 1.0, 0.0],
            [0.5, -kink.cos(), -kink.sin()], // folded down across the edge
        );
        let n_a = unit(cross(sub(p1, p0), sub(p2, p0)));
        let n_b = unit(cross(sub(p3, p0), sub(p1, p0)));
        assert!(dot(n_a, [0.0, 0.0, 1.0]) > 0.999 && dot(n_a, n_b) < 0.8);
        let n0 = unit([0.1, 0.2, 1.0]); // smooth, shared by both facets
        let smooth = |k: usize, far: [f64; 3]| match k {
            0 => Some(n0),
            1 => None,
            _ => Some(far),
        };
        let a = Patch::of_facet([p0, p1, p2], n_a, |k| smooth(k, n_a)).expect("curved");
        let b = Patch::of_facet([p0, p1, p3], n_b, |k| smooth(k, n_b)).expect("curved");
        let mut bulge = 0.0f64;
        for t in [0.1, 0.3, 0.5, 0.7, 0.9] {
            // b = (1 − t, t, 0) on both facets: the point t of the way from p0 to p1
            let (qa, _, _) = a.eval(t, 0.0);
            let (qb, _, _) = b.eval(t, 0.0);
            assert!(norm(sub(qa, qb)) < 1e-15, "{qa:?} vs {qb:?} at t = {t}");
            bulge = bulge.max(norm(sub(qa, [t, 0.0, 0.0])));
        }
        // the smooth end does bend the edge: the check above is not between straight lines
        assert!(bulge > 1e-3, "{bulge}");
    }
}
