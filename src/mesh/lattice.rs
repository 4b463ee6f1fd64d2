//! Interior seeding for TetGen: nested body-centred cubic lattices following a size field,
//! kept out of the surface triangles' and edges' diametral balls (TetGen splits any surface
//! triangle or edge whose ball holds a vertex). Used by the sphere mesher and by the local
//! refinement of imported surfaces.

use crate::math::{add, cross, dot, norm, scale, sub};

/// BCC lattice constant in units of the nominal edge length: the Delaunay tets of a BCC
/// lattice (Sommerville tets, dihedral angles 60° and 90°) have edges a and a·√3/2, so
/// a = 1.07 h gives a mean edge ≈ h.
pub(crate) const LATTICE_FACTOR: f64 = 1.07;

/// No lattice point closer than `SKIN_DEPTH × h` to the surface (h the local size): the
/// layer of tets on the surface triangles is left to TetGen (a regular tet is 0.82 h high).
pub(crate) const SKIN_DEPTH: f64 = 0.7;

/// Relative margin around the surface triangles' and edges' diametral balls kept free of
/// lattice points (TetGen splits any surface edge or triangle whose ball holds a vertex).
pub(crate) const BALL_MARGIN: f64 = 0.15;

/// The diametral balls of the surface triangles (circumscribed balls centred in the
/// triangle's plane) and edges (the edge as diameter), inflated by a margin and bucketed on a
/// uniform grid of cell ≥ the largest radius so that a query checks 27 cells.
pub(crate) struct DiametralBalls {
    cell: f64,
    grid: std::collections::HashMap<[i64; 3], Vec<u32>>,
    balls: Vec<([f64; 3], f64)>,
}

impl DiametralBalls {
    pub(crate) fn new(points: &[[f64; 3]], facets: &[[u32; 3]], margin: f64) -> Self {
        let grow = (1.0 + margin) * (1.0 + margin);
        let mut balls: Vec<([f64; 3], f64)> = Vec::with_capacity(facets.len() * 5 / 2);
        for t in facets {
            let [a, b, c] = t.map(|i| points[i as usize]);
            let (ab, ac) = (sub(b, a), sub(c, a));
            let n = cross(ab, ac);
            let num = add(
                scale(cross(n, ab), dot(ac, ac)),
                scale(cross(ac, n), dot(ab, ab)),
            );
            let off = scale(num, 0.5 / dot(n, n));
            balls.push((add(a, off), grow * dot(off, off)));
            // Edges once each, from the triangle where they ascend.
            for k in 0..3 {
                let (i, j) = (t[k], t[(k + 1) % 3]);
                if i < j {
                    let (p, q) = (points[i as usize], points[j as usize]);
                    let d = sub(q, p);
                    balls.push((scale(add(p, q), 0.5), 0.25 * grow * dot(d, d)));
                }
            }
        }
        let cell = balls
            .iter()
            .map(|b| b.1)
            .fold(0.0, f64::max)
            .sqrt()
            .max(1e-12);
        let mut grid: std::collections::HashMap<[i64; 3], Vec<u32>> =
            std::collections::HashMap::new();
        for (i, b) in balls.iter().enumerate() {
            grid.entry(b.0.map(|x| (x / cell).floor() as i64))
                .or_default()
                .push(i as u32);
        }
        Self { cell, grid, balls }
    }

    /// True if `p` lies inside an (inflated) diametral ball.
    pub(crate) fn encroaches(&self, p: [f64; 3]) -> bool {
        let c = p.map(|x| (x / self.cell).floor() as i64);
        for di in -1..=1 {
            for dj in -1..=1 {
                for dk in -1..=1 {
                    if let Some(list) = self.grid.get(&[c[0] + di, c[1] + dj, c[2] + dk]) {
                        for &i in list {
                            let (centre, r2) = self.balls[i as usize];
                            let d = sub(p, centre);
                            if dot(d, d) < r2 {
                                return true;
                            }
                        }
                    }
                }
            }
        }
        false
    }
}

/// Axis-aligned box (min corner, max corner) in the lattice frame.
pub(crate) type Aabb = ([f64; 3], [f64; 3]);

/// Appends points of nested body-centred cubic lattices. The lattices
/// are rotated by a fixed rotation so that no lattice plane lines up with the icosahedral
/// surface.
///
/// Level ℓ has lattice constant `a0`/2^ℓ and is visited only inside `boxes[ℓ]` (lattice
/// frame). `want(p)` rejects a point (`None`; it must reject every point outside the body) or gives the
/// level of detail wanted at p; a point is kept if it is wanted at a level ≥ the coarsest
/// lattice it belongs to. Since BCC(a) ⊂ BCC(a/2), each point is examined once, at its
/// coarsest level, so the levels form one point set without duplicates, and a point of a
/// coarse lattice stays where finer levels take over (2:1 transitions). Deterministic order.
pub(crate) fn add_nested_bcc<F: Fn([f64; 3]) -> Option<u32>>(
    a0: f64,
    boxes: &[Vec<Aabb>],
    want: F,
    points: &mut Vec<[f64; 3]>,
) {
    let rot = lattice_rotation();
    let inside = |b: &Aabb, x: [f64; 3]| (0..3).all(|d| x[d] >= b.0[d] && x[d] <= b.1[d]);
    for (l, level_boxes) in boxes.iter().enumerate() {
        // Half-lattice integer coordinates q: lattice-frame point = q · half; BCC points have
        // q all even (cube corners) or all odd (cube centres).
        let half = 0.5 * a0 / (1u64 << l) as f64;
        for (b, bx) in level_boxes.iter().enumerate() {
            let lo = bx.0.map(|c| (c / half).floor() as i64);
            let hi = bx.1.map(|c| (c / half).ceil() as i64);
            for qi in lo[0]..=hi[0] {
                for qj in lo[1]..=hi[1] {
                    for qk in lo[2]..=hi[2] {
                        let q = [qi, qj, qk];
                        let parity = qi.rem_euclid(2);
                        if q.iter().any(|c| c.rem_euclid(2) != parity) {
                            continue;
                        }
                        // Member of the next coarser lattice: q/2 integer with uniform parity.
                        if l > 0 && parity == 0 {
                            let p2 = (qi / 2).rem_euclid(2);
                            if q.iter().all(|c| (c / 2).rem_euclid(2) == p2) {
                                continue;
                            }
                        }
                        let x = q.map(|c| c as f64 * half);
                        if !inside(bx, x) || level_boxes[..b].iter().any(|other| inside(other, x)) {
                            continue;
                        }
                        let p = mat_vec(&rot, x);
                        if want(p).is_some_and(|w| w as usize >= l) {
                            points.push(p);
                        }
                    }
                }
            }
        }
    }
}

/// The fixed lattice rotation: 0.7 rad about the irrational axis (1, φ, e).
pub(crate) fn lattice_rotation() -> [[f64; 3]; 3] {
    let axis = [1.0, (1.0 + 5f64.sqrt()) / 2.0, std::f64::consts::E];
    let [x, y, z] = axis.map(|c| c / norm(axis));
    let (sn, c) = 0.7f64.sin_cos();
    let t = 1.0 - c;
    [
        [t * x * x + c, t * x * y - sn * z, t * x * z + sn * y],
        [t * x * y + sn * z, t * y * y + c, t * y * z - sn * x],
        [t * x * z - sn * y, t * y * z + sn * x, t * z * z + c],
    ]
}

pub(crate) fn transpose(m: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    [
        [m[0][0], m[1][0], m[2][0]],
        [m[0][1], m[1][1], m[2][1]],
        [m[0][2], m[1][2], m[2][2]],
    ]
}

pub(crate) fn mat_vec(m: &[[f64; 3]; 3], v: [f64; 3]) -> [f64; 3] {
    [dot(m[0], v), dot(m[1], v), dot(m[2], v)]
}
