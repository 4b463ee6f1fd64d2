//! Closest points on triangles, and which of a slave node's candidate facets is nearest it.
//!
//! - [`closest_point_on_triangle`]: exact closest point with the feature it lies on (face,
//!   edge or vertex) and its barycentric coordinates (Ericson, *Real-Time Collision
//!   Detection* §5.1.5).
//! - [`nearest_candidate`]: the narrow phase's candidate loop in f64 lanes.
//!
//! A loaded contact point has about 15 candidate facets, and the scalar closest-point test
//! branches on the Voronoi region a node falls in, which is data, not a pattern a branch
//! predictor learns. Here four or eight candidates are tested at once with no branches:
//! every region's closest point is computed in every lane and the region is chosen by
//! masks, in the order of Ericson's tests, so that each lane holds the point the scalar
//! test would return. The squared distance is then formed from that point with the same
//! operations, which makes it bit for bit the scalar `dist2`. The nearest candidate is the
//! first with the smallest squared distance, as in the scalar loop, and the caller
//! recomputes its [`Closest`] (feature, barycentric coordinates) with the scalar function:
//! contact results do not depend on the path taken (docs/BENCHMARKS.md, session 25: the
//! candidate loop 2.5–3× faster in cache, the loaded contact stage ≈ 11 % cheaper).

use super::candidate_facet::CandidateFacet;
use super::ContactModel;
use crate::lanes::{build, Lanes};
use crate::math::{add, dot, scale, sub};

/// Which part of a triangle a closest point lies on. Edge k joins corners k and (k+1)%3.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Feature {
    Face,
    Edge(u8),
    Vertex(u8),
}

/// Closest point of a triangle to a query point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Closest {
    pub point: [f64; 3],
    /// Barycentric coordinates of `point` with respect to (a, b, c).
    pub bary: [f64; 3],
    pub feature: Feature,
    /// Squared distance from the query point (m²).
    pub dist2: f64,
}

/// Exact closest point of triangle (a, b, c) to p, with its feature and barycentric
/// coordinates (Voronoi-region tests, no square roots).
#[inline(always)]
pub fn closest_point_on_triangle(p: [f64; 3], a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> Closest {
    let done = |point: [f64; 3], bary: [f64; 3], feature| Closest {
        point,
        bary,
        feature,
        dist2: {
            let d = sub(p, point);
            dot(d, d)
        },
    };
    let ab = sub(b, a);
    let ac = sub(c, a);
    let ap = sub(p, a);
    let d1 = dot(ab, ap);
    let d2 = dot(ac, ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return done(a, [1.0, 0.0, 0.0], Feature::Vertex(0));
    }
    let bp = sub(p, b);
    let d3 = dot(ab, bp);
    let d4 = dot(ac, bp);
    if d3 >= 0.0 && d4 <= d3 {
        return done(b, [0.0, 1.0, 0.0], Feature::Vertex(1));
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return done(add(a, scale(ab, v)), [1.0 - v, v, 0.0], Feature::Edge(0));
    }
    let cp = sub(p, c);
    let d5 = dot(ab, cp);
    let d6 = dot(ac, cp);
    if d6 >= 0.0 && d5 <= d6 {
        return done(c, [0.0, 0.0, 1.0], Feature::Vertex(2));
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return done(add(a, scale(ac, w)), [1.0 - w, 0.0, w], Feature::Edge(2));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return done(
            add(b, scale(sub(c, b), w)),
            [0.0, 1.0 - w, w],
            Feature::Edge(1),
        );
    }
    let denom = 1.0 / (va + vb + vc);
    let v = vb * denom;
    let w = vc * denom;
    done(
        add(a, add(scale(ab, v), scale(ac, w))),
        [1.0 - v - w, v, w],
        Feature::Face,
    )
}

/// Index into `candidates` of the facet nearest `p` (the first of equals), `None` without
/// candidates. Uses the widest lanes the CPU has; the answer is the same on every path.
pub fn nearest_candidate(
    cm: &ContactModel,
    x: &[[f64; 3]],
    p: [f64; 3],
    candidates: &[u32],
) -> Option<usize> {
    nearest_of(x, p, candidates.len(), |i| cm.facet[candidates[i] as usize])
}

/// [`nearest_candidate`] among the facets of `records`.
pub fn nearest_record(x: &[[f64; 3]], p: [f64; 3], records: &[CandidateFacet]) -> Option<usize> {
    nearest_of(x, p, records.len(), |i| records[i].corners)
}

/// [`nearest_candidate`] among `count` triangles, `corner_ids(i)` the model node ids of
/// triangle i's corners.
#[inline(always)]
fn nearest_of(
    x: &[[f64; 3]],
    p: [f64; 3],
    count: usize,
    corner_ids: impl Fn(usize) -> [u32; 3],
) -> Option<usize> {
    if count == 0 {
        return None;
    }
    // indexed, not `map`: the closure must inline into the lane functions (see
    // `crate::lanes::build`)
    let corners = |i: usize| {
        let [a, b, c] = corner_ids(i);
        [x[a as usize], x[b as usize], x[c as usize]]
    };
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx512f")
            && std::arch::is_x86_feature_detected!("avx512vl")
        {
            // SAFETY: the CPU supports AVX-512F and VL (checked above)
            return Some(unsafe { nearest_avx512(p, count, corners) });
        }
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2 (checked above)
            return Some(unsafe { nearest_avx2(p, count, corners) });
        }
    }
    Some(nearest_scalar(p, count, corners))
}

/// The scalar loop over triangles `0..count` (`corners(i)` the corners of triangle i): one
/// branchy closest-point test each.
fn nearest_scalar(p: [f64; 3], count: usize, corners: impl Fn(usize) -> [[f64; 3]; 3]) -> usize {
    let mut best = (0, f64::NAN);
    for i in 0..count {
        let [a, b, c] = corners(i);
        let d2 = closest_point_on_triangle(p, a, b, c).dist2;
        if i == 0 || d2 < best.1 {
            best = (i, d2);
        }
    }
    best.0
}

/// # Safety
/// The CPU must support AVX-512F and VL.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,avx512f,avx512vl")]
unsafe fn nearest_avx512(
    p: [f64; 3],
    count: usize,
    corners: impl Fn(usize) -> [[f64; 3]; 3],
) -> usize {
    nearest_in_lanes::<crate::lanes::F64x8>(p, count, corners)
}

/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn nearest_avx2(
    p: [f64; 3],
    count: usize,
    corners: impl Fn(usize) -> [[f64; 3]; 3],
) -> usize {
    nearest_in_lanes::<crate::lanes::F64x4>(p, count, corners)
}

/// [`nearest_scalar`] `L::WIDTH` triangles at a time; a last partial group repeats its
/// last triangle, whose extra lanes are not compared.
#[inline(always)]
fn nearest_in_lanes<L: Lanes>(
    p: [f64; 3],
    count: usize,
    corners: impl Fn(usize) -> [[f64; 3]; 3],
) -> usize {
    let pl = build(L::splat(0.0), |k| L::splat(p[k]));
    let mut best = (0, f64::NAN);
    for start in (0..count).step_by(L::WIDTH) {
        let mut lanes = [[L::Array::default(); 3]; 3];
        for l in 0..L::WIDTH {
            let triangle = corners((start + l).min(count - 1));
            for (corner, position) in lanes.iter_mut().zip(triangle) {
                for k in 0..3 {
                    corner[k][l] = position[k];
                }
            }
        }
        let zero = [L::splat(0.0); 3];
        let [a, b, c] = build(zero, |j| build(zero[0], |k| L::from_array(lanes[j][k])));
        let d2 = closest_distance2(pl, a, b, c).to_array();
        for l in 0..L::WIDTH.min(count - start) {
            if start + l == 0 || d2[l] < best.1 {
                best = (start + l, d2[l]);
            }
        }
    }
    best.0
}

/// The tests of a Voronoi region are all of the form "value ≤ 0" here, so a condition is
/// a lane value that holds where it is not > 0 (NaN too, where the scalar comparisons are
/// all false: only a position that is already NaN gets there).
///
/// `x ≤ 0`.
#[inline(always)]
fn at_most_zero<L: Lanes>(x: L) -> L {
    x
}

/// `x ≥ 0`, i.e. −x ≤ 0 (−0 and +0 both count as ≥ 0, as in the scalar test).
#[inline(always)]
fn at_least_zero<L: Lanes>(x: L) -> L {
    -x
}

/// `a ≤ b`, i.e. a − b ≤ 0 (exact: a − b is 0 only when a = b).
#[inline(always)]
fn at_most<L: Lanes>(a: L, b: L) -> L {
    a - b
}

/// Per lane: `then` where every condition holds (is not > 0), else `otherwise`.
#[inline(always)]
fn choose<L: Lanes, const N: usize>(conditions: [L; N], then: [L; 3], otherwise: [L; 3]) -> [L; 3] {
    let mut chosen = then;
    for j in (0..N).rev() {
        for k in 0..3 {
            chosen[k] = conditions[j].where_positive(otherwise[k], chosen[k]);
        }
    }
    chosen
}

#[inline(always)]
fn sub3<L: Lanes>(a: [L; 3], b: [L; 3]) -> [L; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

#[inline(always)]
fn dot3<L: Lanes>(a: [L; 3], b: [L; 3]) -> L {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// `origin + direction·t`, per coordinate.
#[inline(always)]
fn along<L: Lanes>(origin: [L; 3], direction: [L; 3], t: L) -> [L; 3] {
    build(t, |k| origin[k] + direction[k] * t)
}

/// Squared distance from `p` to triangle (a, b, c), per lane: the operations of
/// [`closest_point_on_triangle`] for every region, the region picked by its tests
/// (vertex a, vertex b, edge ab, vertex c, edge ac, edge bc, face: the first that holds).
#[inline(always)]
fn closest_distance2<L: Lanes>(p: [L; 3], a: [L; 3], b: [L; 3], c: [L; 3]) -> L {
    let ab = sub3(b, a);
    let ac = sub3(c, a);
    let ap = sub3(p, a);
    let d1 = dot3(ab, ap);
    let d2 = dot3(ac, ap);
    let bp = sub3(p, b);
    let d3 = dot3(ab, bp);
    let d4 = dot3(ac, bp);
    let vc = d1 * d4 - d3 * d2;
    let cp = sub3(p, c);
    let d5 = dot3(ab, cp);
    let d6 = dot3(ac, cp);
    let vb = d5 * d2 - d1 * d6;
    let va = d3 * d6 - d5 * d4;
    // lowest priority first: each later choice overrides where its tests hold
    let denom = L::splat(1.0) / (va + vb + vc);
    let (v, w) = (vb * denom, vc * denom);
    let face = build(v, |k| a[k] + (ab[k] * v + ac[k] * w));
    let (d43, d56) = (d4 - d3, d5 - d6);
    let on_bc = along(b, sub3(c, b), d43 / (d43 + d56));
    let point = choose(
        [at_most_zero(va), at_least_zero(d43), at_least_zero(d56)],
        on_bc,
        face,
    );
    let on_ac = along(a, ac, d2 / (d2 - d6));
    let point = choose(
        [at_most_zero(vb), at_least_zero(d2), at_most_zero(d6)],
        on_ac,
        point,
    );
    let point = choose([at_least_zero(d6), at_most(d5, d6)], c, point);
    let on_ab = along(a, ab, d1 / (d1 - d3));
    let point = choose(
        [at_most_zero(vc), at_least_zero(d1), at_most_zero(d3)],
        on_ab,
        point,
    );
    let point = choose([at_least_zero(d3), at_most(d4, d3)], b, point);
    let point = choose([at_most_zero(d1), at_most_zero(d2)], a, point);
    let d = sub3(p, point);
    dot3(d, d)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lanes::gather;
    use crate::math::norm;

    const A: [f64; 3] = [0.0, 0.0, 0.0];
    const B: [f64; 3] = [1.0, 0.0, 0.0];
    const C: [f64; 3] = [0.0, 1.0, 0.0];

    fn check(p: [f64; 3], point: [f64; 3], feature: Feature) {
        let cl = closest_point_on_triangle(p, A, B, C);
        assert_eq!(cl.feature, feature, "{p:?}");
        for (a, b) in cl.point.iter().zip(&point) {
            assert!((a - b).abs() < 1e-14, "{cl:?}");
        }
        // barycentric coordinates reproduce the point and sum to one
        let q = add(
            add(scale(A, cl.bary[0]), scale(B, cl.bary[1])),
            scale(C, cl.bary[2]),
        );
        for i in 0..3 {
            assert!((q[i] - point[i]).abs() < 1e-14);
        }
        assert!((cl.bary.iter().sum::<f64>() - 1.0).abs() < 1e-14);
        let d = sub(p, point);
        assert!((cl.dist2 - dot(d, d)).abs() < 1e-14);
    }

    #[test]
    fn projection_inside_on_edges_and_vertices() {
        check([0.25, 0.25, -0.3], [0.25, 0.25, 0.0], Feature::Face);
        check([0.5, -0.2, 0.1], [0.5, 0.0, 0.0], Feature::Edge(0));
        check([0.8, 0.8, 0.0], [0.5, 0.5, 0.0], Feature::Edge(1));
        check([-0.3, 0.4, 0.2], [0.0, 0.4, 0.0], Feature::Edge(2));
        check([-1.0, -1.0, 0.5], A, Feature::Vertex(0));
        check([2.0, -0.1, 0.0], B, Feature::Vertex(1));
        check([-0.1, 3.0, -1.0], C, Feature::Vertex(2));
    }

    #[test]
    fn projection_is_continuous_across_a_region_boundary() {
        // Sweep across edge 0 (y = 0): the closest point moves continuously.
        let mut prev: Option<[f64; 3]> = None;
        for k in 0..=200 {
            let y = -0.01 + 0.0001 * k as f64;
            let cl = closest_point_on_triangle([0.4, y, -0.05], A, B, C);
            if let Some(p) = prev {
                assert!(norm(sub(cl.point, p)) <= 1.0001e-4);
            }
            prev = Some(cl.point);
        }
    }

    /// A small deterministic generator (the tests need no crate for it).
    struct Lcg(u64);
    impl Lcg {
        fn next(&mut self) -> f64 {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (self.0 >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        }
        fn point(&mut self, scale: f64) -> [f64; 3] {
            [
                self.next() * scale,
                self.next() * scale,
                self.next() * scale,
            ]
        }
    }

    /// Triangles and query points that reach every region, with degenerate triangles
    /// (a repeated corner, collinear corners) and points on the triangle's own corners.
    fn cases() -> Vec<([f64; 3], [[f64; 3]; 3])> {
        let mut rng = Lcg(7);
        let mut out = Vec::new();
        for i in 0..4000 {
            let a = rng.point(1.0);
            let mut b = rng.point(1.0);
            let mut c = rng.point(1.0);
            match i % 10 {
                0 => b = a,
                1 => c = [0, 1, 2].map(|k| 2.0 * b[k] - a[k]),
                _ => {}
            }
            let p = match i % 7 {
                0 => a,
                1 => [0, 1, 2].map(|k| 0.5 * (b[k] + c[k])),
                _ => rng.point(3.0),
            };
            out.push((p, [a, b, c]));
            if i % 13 == 0 {
                c = b;
                out.push((p, [a, b, c]));
            }
        }
        out
    }

    #[test]
    fn the_cases_reach_every_region() {
        let mut seen = std::collections::HashSet::new();
        for (p, [a, b, c]) in cases() {
            seen.insert(format!(
                "{:?}",
                closest_point_on_triangle(p, a, b, c).feature
            ));
        }
        assert_eq!(seen.len(), 7, "{seen:?}");
    }

    /// Every lane gives the scalar function's squared distance, bit for bit.
    fn lanes_give_the_scalar_distance<L: Lanes>() {
        let cases = cases();
        for group in cases.chunks(L::WIDTH) {
            let lane = |l: usize| group[l.min(group.len() - 1)];
            let p = [0, 1, 2].map(|k| gather::<L>(|l| lane(l).0[k]));
            let corner = |j: usize| [0, 1, 2].map(|k| gather::<L>(|l| lane(l).1[j][k]));
            let d2 = closest_distance2(p, corner(0), corner(1), corner(2)).to_array();
            for l in 0..L::WIDTH {
                let (q, [a, b, c]) = lane(l);
                let scalar = closest_point_on_triangle(q, a, b, c).dist2;
                assert_eq!(d2[l].to_bits(), scalar.to_bits(), "{q:?} {a:?} {b:?} {c:?}");
            }
        }
    }

    /// The lane loop picks the scalar loop's candidate: the first of the nearest, also
    /// with ties (repeated triangles) and a partial last group.
    fn lanes_pick_the_scalar_candidate<L: Lanes>() {
        let cases = cases();
        let mut rng = Lcg(11);
        for count in 1..=19 {
            for trial in 0..40 {
                let p = rng.point(2.0);
                let picks: Vec<usize> = (0..count)
                    .map(|_| ((rng.next() + 0.5) * cases.len() as f64) as usize % cases.len())
                    .map(|k| if trial % 3 == 0 && k % 2 == 0 { 0 } else { k })
                    .collect();
                let corners = |i: usize| cases[picks[i]].1;
                assert_eq!(
                    nearest_in_lanes::<L>(p, count, corners),
                    nearest_scalar(p, count, corners),
                    "{count} candidates, trial {trial}"
                );
            }
        }
    }

    #[test]
    fn one_lane_gives_the_scalar_distance() {
        lanes_give_the_scalar_distance::<f64>();
        lanes_pick_the_scalar_candidate::<f64>();
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx2_lanes_give_the_scalar_distance() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            panic!("this test needs an AVX2 CPU: the contact's fast path could not be checked");
        }
        // SAFETY: AVX2 is present (checked above)
        #[target_feature(enable = "avx2")]
        unsafe fn run() {
            lanes_give_the_scalar_distance::<crate::lanes::F64x4>();
            lanes_pick_the_scalar_candidate::<crate::lanes::F64x4>();
        }
        unsafe { run() }
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx512_lanes_give_the_scalar_distance() {
        if !(std::arch::is_x86_feature_detected!("avx512f")
            && std::arch::is_x86_feature_detected!("avx512vl"))
        {
            println!("no AVX-512F and VL on this CPU: the eight-lane path is never taken here");
            return;
        }
        #[target_feature(enable = "avx2,avx512f,avx512vl")]
        unsafe fn run() {
            lanes_give_the_scalar_distance::<crate::lanes::F64x8>();
            lanes_pick_the_scalar_candidate::<crate::lanes::F64x8>();
        }
        // SAFETY: AVX-512F and VL are present (checked above)
        unsafe { run() }
    }
}
