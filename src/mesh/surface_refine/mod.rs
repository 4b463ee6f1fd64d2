//! Size-driven triangulation of a sphere surface.
//!
//! 1. **Geodesic base**: every icosahedron face split into n² triangles on a barycentric
//!    grid, projected onto the sphere, n chosen so that the mean edge is the base size
//!    (edges in steps of 1/n rather than the √2 steps of repeated bisection; all angles
//!    ≤ 72°).
//! 2. **Local refinement** by conforming longest-edge bisection (Rivara's LEPP algorithm):
//!    to split a triangle, follow the longest-edge propagation path through neighbours
//!    across their longest edges until two triangles share their longest edge, and bisect
//!    that pair together (midpoint projected onto the sphere). No hanging nodes.
//! 3. **Edge flips** until every edge is convex: the triangulation becomes the convex hull
//!    of its vertices, which for points on a sphere is the spherical Delaunay triangulation.
//! 4. **Pins** ([`Pin`]): the vertex nearest each pinned point is moved exactly onto it
//!    (`Refiner::pin`), so that a contact or a wall meets the mesh at a node rather than at
//!    a facet lying the faceting sag inside the sphere.
//! 5. Where bisection happened or a vertex was pinned, **make the triangles acute**
//!    (`Refiner::make_acute`): removal of valence-3/4 vertices, Lloyd relaxation with density
//!    h⁻⁴ (flattened within one edge of a pin, `PIN_PLATEAU`), a bisection next to any pin
//!    left at valence 4, and local vertex moves, until no angle exceeds [`MAX_ANGLE_DEG`];
//!    pinned vertices never move. TetGen treats every surface edge as a segment and splits
//!    any whose diametral ball holds a vertex — every edge opposite an angle ≥ 90° — and
//!    such splits cascade into edges several times shorter than requested, which would set
//!    the explicit time step.
//!
//! Adjacency is kept as per-triangle neighbour arrays (O(1) updates per bisection or flip,
//! no hashing or allocation per step); a directed-edge hash map is used only to (re)build
//! them. Processing order is fixed, so the same input gives a bitwise identical output.

use std::collections::HashMap;

use super::MeshError;

mod acute;
mod topology;
use crate::math::{add, cross, dot, norm, scale, sub};

/// Refinement criterion: a triangle is split while its longest edge exceeds
/// `LONGEST_EDGE_FACTOR × h(centroid)`. It sits above the longest edge of the geodesic base
/// mesh (≈ 1.1 × its mean), so uniform regions keep the base mesh (mean edge ≈ h), and below
/// 1.5 so that refined patches stay below 1.5 h (bisection leaves their mean edge near
/// 0.85 h; the Lloyd relaxation that follows redistributes but does not add vertices).
pub const LONGEST_EDGE_FACTOR: f64 = 1.42;

/// Target largest angle of the surface triangles after refinement (degrees): below 90° with
/// a margin (see `Refiner::make_acute`). The geodesic base mesh has at most 72°.
pub const MAX_ANGLE_DEG: f64 = 85.0;
/// Lloyd sweeps per pass of `make_acute` (measured: ~40 bring obtuse angles from ~10 % of
/// the bisected triangles to a few 5–7 valence defects, which the local moves then fix).
const LLOYD_ITERATIONS: usize = 40;
/// Rounds of local vertex moves per pass of `make_acute`.
const REPAIR_ROUNDS: usize = 10;
/// Passes of (vertex removal, Lloyd, local moves) at most.
const ACUTE_PASSES: usize = 3;

/// Rings of neighbours around each pinned vertex that `Refiner::make_acute` relaxes. The
/// snap moves a vertex by up to about half an edge, and with the 2 rings of the bisected
/// zone's margin the distortion piles up at the fixed rim. Measured with the
/// random specs of `tests::pins_leave_surfaces_acute_and_pins_at_valence_five_or_more`
/// (seed 777, 1 200 draws = 392 specs; the test keeps the first 600 draws): 2 rings leave 9 surfaces with an angle
/// above 85.5° and 2 above 90°, 6 rings 6 and 0, the same specs without pins 7 and 0.
const PIN_RINGS: usize = 6;

/// Radius, in units of the size at the pin, within which the relaxation density around a
/// pin is flattened (the size field is read on that circle instead). A pin usually sits at
/// the finest point of the size field (a patch centre), where the Lloyd density h⁻⁴
/// peaks: a free vertex drifts off the peak, but a fixed one draws its neighbours in until
/// it has only 4, whose angles then sum to just under 360° (the sphere's angle defect),
/// ~90° each, which no vertex move makes acute. With the plateau the pins keep valence
/// 5–7 like the vertices around them. The same sweep (seed 777) without the plateau:
/// 17 surfaces above 85.5° and 3 above 90°; with it 6 and 0. Over its four seeds (1 519
/// specs) pinned surfaces have 20 above 85.5° and 1 above 90°, the same specs without pins
/// 39 and 2.
const PIN_PLATEAU: f64 = 1.0;

/// Mean edge of the frequency-n geodesic sphere of unit radius, times n (measured; the
/// continuum estimate is √(4π/(5√3)) ≈ 1.2046; 1.203 within 0.3 % for n ≥ 5).
pub const GEODESIC_MEAN_EDGE: f64 = 1.203;

/// Upper bound on the number of surface triangles (the volume mesh would have tens of
/// millions of tets per grain); beyond it the spec is rejected instead of running the
/// machine out of memory.
pub const MAX_SURFACE_TRIANGLES: usize = 4_000_000;

/// A closed triangulated sphere: vertices exactly on the sphere, triangles counter-clockwise
/// seen from outside.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SphereSurface {
    /// Vertex positions.
    pub points: Vec<[f64; 3]>,
    /// Triangles (vertex indices), outward orientation.
    pub triangles: Vec<[u32; 3]>,
}

/// A point of the sphere that must be a vertex of the triangulation.
#[derive(Debug, Clone, PartialEq)]
pub struct Pin {
    /// Direction from the centre (any length > 0): the vertex is put at
    /// `radius · direction/|direction|`.
    pub direction: [f64; 3],
    /// The spec field that asked for the pin, named by the error when two pins would need
    /// the same vertex.
    pub field: String,
}

/// Triangle with neighbour links: `n[i]` is the triangle across the edge opposite `v[i]`,
/// i.e. across edge `(v[i+1], v[i+2])`.
#[derive(Clone, Copy, Debug)]
struct Tri {
    v: [u32; 3],
    n: [u32; 3],
}

struct Refiner {
    radius: f64,
    pts: Vec<[f64; 3]>,
    tris: Vec<Tri>,
}

/// Triangulates the sphere of `radius` centred at the origin following the sizing function
/// `size` (edge length as a function of a point on the sphere, positive and finite, at most
/// `base_size`): the geodesic base has mean edge ≈ `base_size`; where `size` is smaller,
/// triangles are bisected until their longest edge is ≤ [`LONGEST_EDGE_FACTOR`]`·size` at
/// their centroid, then relaxed to acute shapes. All vertices lie exactly on the sphere, and
/// each of `pins` is exactly a vertex. `field` names the spec field for the error returned
/// if the triangle count would exceed [`MAX_SURFACE_TRIANGLES`]; two pins that would need
/// the same vertex (closer than the local edge length) are an
/// [`MeshError::InvalidSpec`] naming the second pin's field.
pub fn triangulate_sphere<F>(
    radius: f64,
    base_size: f64,
    size: F,
    pins: &[Pin],
    field: &str,
) -> Result<SphereSurface, MeshError>
where
    F: Fn([f64; 3]) -> f64,
{
    triangulate_sphere_limited(radius, base_size, size, pins, field, MAX_SURFACE_TRIANGLES)
}

/// Frequency of the geodesic base mesh whose mean edge is closest to `base_size`.
pub fn geodesic_frequency(radius: f64, base_size: f64) -> usize {
    let n = (GEODESIC_MEAN_EDGE * radius / base_size).round();
    if n.is_finite() && n >= 1.0 {
        n.min(1e6) as usize
    } else {
        1
    }
}

/// [`triangulate_sphere`] with an explicit triangle-count limit.
pub(crate) fn triangulate_sphere_limited<F>(
    radius: f64,
    base_size: f64,
    size: F,
    pins: &[Pin],
    field: &str,
    limit: usize,
) -> Result<SphereSurface, MeshError>
where
    F: Fn([f64; 3]) -> f64,
{
    let n = geodesic_frequency(radius, base_size);
    if 20 * n * n > limit {
        return Err(MeshError::TooLarge {
            field: field.to_string(),
            limit,
        });
    }
    let mut r = Refiner::geodesic(radius, n);
    let base_vertices = r.pts.len();
    r.refine(&size, field, limit)?;
    r.flip_to_convex();
    let pinned = r.pin(pins)?;
    // Snapping distorts the pins' fans even where nothing was bisected.
    if r.pts.len() > base_vertices || !pins.is_empty() {
        let np = r.pts.len();
        let near_refined = r.dilate((0..np).map(|i| i >= base_vertices).collect(), 2);
        let near_pins = r.dilate(pinned.clone(), PIN_RINGS);
        let movable = (0..np)
            .map(|i| (near_refined[i] || near_pins[i]) && !pinned[i])
            .collect();
        let plateaus: Vec<([f64; 3], f64)> = pins
            .iter()
            .map(|p| {
                let centre = scale(p.direction, radius / norm(p.direction));
                (centre, PIN_PLATEAU * size(centre))
            })
            .collect();
        let relaxation_size = |x: [f64; 3]| {
            let inside = plateaus.iter().find_map(|&(c, reach)| {
                let d = norm(sub(x, c));
                (d > 0.0 && d < reach).then(|| add(c, scale(sub(x, c), reach / d)))
            });
            match inside {
                None => size(x),
                Some(y) => size(scale(y, radius / norm(y))),
            }
        };
        r.make_acute(&relaxation_size, movable, pinned);
    }
    Ok(SphereSurface {
        points: r.pts,
        triangles: r.tris.iter().map(|t| t.v).collect(),
    })
}

impl Refiner {
    /// The 12 unit vertices and 20 outward faces of the icosahedron.
    fn icosahedron() -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
        let phi = (1.0 + 5f64.sqrt()) / 2.0;
        let mut raw: Vec<[f64; 3]> = Vec::with_capacity(12);
        for &a in &[-1.0, 1.0] {
            for &b in &[-phi, phi] {
                raw.push([0.0, a, b]);
                raw.push([a, b, 0.0]);
                raw.push([b, 0.0, a]);
            }
        }
        let pts: Vec<[f64; 3]> = raw.iter().map(|&p| scale(p, 1.0 / norm(p))).collect();
        // Faces: triples of mutually adjacent vertices (unnormalised edge length 2).
        let adjacent = |i: usize, j: usize| {
            let d = sub(raw[i], raw[j]);
            (dot(d, d) - 4.0).abs() < 1e-9
        };
        let mut faces: Vec<[u32; 3]> = Vec::with_capacity(20);
        for i in 0..12 {
            for j in i + 1..12 {
                for k in j + 1..12 {
                    if adjacent(i, j) && adjacent(j, k) && adjacent(i, k) {
                        let nrm = cross(sub(pts[j], pts[i]), sub(pts[k], pts[i]));
                        if dot(nrm, pts[i]) > 0.0 {
                            faces.push([i as u32, j as u32, k as u32]);
                        } else {
                            faces.push([i as u32, k as u32, j as u32]);
                        }
                    }
                }
            }
        }
        debug_assert_eq!(faces.len(), 20);
        (pts, faces)
    }

    /// Geodesic sphere of frequency `n`: every icosahedron face split into n² triangles on a
    /// barycentric grid, vertices projected radially onto the sphere. Unlike repeated
    /// bisection (whose sizes come in steps of √2), the frequency sets the edge length in
    /// steps of 1/n, and the triangles are nearly equilateral.
    fn geodesic(radius: f64, n: usize) -> Self {
        let (ico, faces) = Self::icosahedron();
        let nf = n as f64;
        let mut pts: Vec<[f64; 3]> = ico.iter().map(|&p| scale(p, radius)).collect();
        let project = |p: [f64; 3]| scale(p, radius / norm(p));
        // Vertices inside icosahedron edges, generated from the smaller corner id so that
        // both faces sharing the edge see bitwise the same points.
        let mut edge_start: HashMap<(u32, u32), u32> = HashMap::with_capacity(30);
        for f in &faces {
            for k in 0..3 {
                let (a, b) = (f[k].min(f[(k + 1) % 3]), f[k].max(f[(k + 1) % 3]));
                if let std::collections::hash_map::Entry::Vacant(e) = edge_start.entry((a, b)) {
                    e.insert(pts.len() as u32);
                    let (pa, pb) = (ico[a as usize], ico[b as usize]);
                    for i in 1..n {
                        pts.push(project(add(pa, scale(sub(pb, pa), i as f64 / nf))));
                    }
                }
            }
        }
        // Point k/n of the way from corner p to corner q (0 < k < n).
        let on_edge = |p: u32, q: u32, k: usize| -> u32 {
            let start = edge_start[&(p.min(q), p.max(q))];
            if p < q {
                start + (k - 1) as u32
            } else {
                start + (n - k - 1) as u32
            }
        };
        let mut tri_v: Vec<[u32; 3]> = Vec::with_capacity(20 * n * n);
        let mut grid: Vec<u32> = Vec::with_capacity((n + 1) * (n + 2) / 2);
        for f in &faces {
            let [a, b, c] = *f;
            let (pa, pb, pc) = (ico[a as usize], ico[b as usize], ico[c as usize]);
            // grid[row(i) + j] = vertex at A + i/n (B−A) + j/n (C−A), i + j ≤ n.
            grid.clear();
            for i in 0..=n {
                for j in 0..=(n - i) {
                    let id = match (i, j) {
                        (0, 0) => a,
                        _ if i == n => b,
                        _ if j == n => c,
                        (_, 0) => on_edge(a, b, i),
                        (0, _) => on_edge(a, c, j),
                        _ if i + j == n => on_edge(b, c, j),
                        _ => {
                            let p = add(
                                pa,
                                add(
                                    scale(sub(pb, pa), i as f64 / nf),
                                    scale(sub(pc, pa), j as f64 / nf),
                                ),
                            );
                            pts.push(project(p));
                            (pts.len() - 1) as u32
                        }
                    };
                    grid.push(id);
                }
            }
            let row = |i: usize| i * (n + 1) - i * (i.saturating_sub(1)) / 2;
            let at = |i: usize, j: usize| grid[row(i) + j];
            for i in 0..n {
                for j in 0..(n - i) {
                    tri_v.push([at(i, j), at(i + 1, j), at(i, j + 1)]);
                    if i + j + 2 <= n {
                        tri_v.push([at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)]);
                    }
                }
            }
        }
        Self::from_triangles(radius, pts, &tri_v)
    }

    /// Builds the neighbour links of a closed oriented triangulation through a directed-edge
    /// map (used once per construction; refinement and flips then update links locally).
    fn from_triangles(radius: f64, pts: Vec<[f64; 3]>, tri_v: &[[u32; 3]]) -> Self {
        let mut half: HashMap<(u32, u32), u32> = HashMap::with_capacity(3 * tri_v.len());
        for (t, v) in tri_v.iter().enumerate() {
            for k in 0..3 {
                half.insert((v[(k + 1) % 3], v[(k + 2) % 3]), t as u32);
            }
        }
        let tris = tri_v
            .iter()
            .map(|&v| Tri {
                v,
                n: [0, 1, 2].map(|k| half[&(v[(k + 2) % 3], v[(k + 1) % 3])]),
            })
            .collect();
        Refiner { radius, pts, tris }
    }

    /// Ordering key of an edge: squared length, ties broken by the vertex ids. A strict total
    /// order on edges makes every longest-edge propagation path strictly increasing, hence
    /// finite, even for the exactly equal edges of the icosahedron.
    #[inline]
    fn edge_key(&self, a: u32, b: u32) -> (f64, u32, u32) {
        let d = sub(self.pts[a as usize], self.pts[b as usize]);
        (dot(d, d), a.min(b), a.max(b))
    }

    /// Local index (0..3) of the longest edge of triangle `t` (edge i is opposite `v[i]`).
    #[inline]
    fn longest(&self, t: u32) -> usize {
        let v = self.tris[t as usize].v;
        let k0 = self.edge_key(v[1], v[2]);
        let k1 = self.edge_key(v[2], v[0]);
        let k2 = self.edge_key(v[0], v[1]);
        let gt = |x: (f64, u32, u32), y: (f64, u32, u32)| {
            x.0 > y.0 || (x.0 == y.0 && (x.1, x.2) > (y.1, y.2))
        };
        if gt(k0, k1) {
            if gt(k0, k2) {
                0
            } else {
                2
            }
        } else if gt(k1, k2) {
            1
        } else {
            2
        }
    }

    #[inline]
    fn needs_split<F: Fn([f64; 3]) -> f64>(&self, t: u32, size: &F) -> bool {
        let v = self.tris[t as usize].v;
        let [a, b, c] = v.map(|i| self.pts[i as usize]);
        let l2 = self
            .edge_key(v[1], v[2])
            .0
            .max(self.edge_key(v[2], v[0]).0)
            .max(self.edge_key(v[0], v[1]).0);
        let g = add(add(a, b), c);
        let x = scale(g, self.radius / norm(g));
        let h = LONGEST_EDGE_FACTOR * size(x);
        l2 > h * h
    }

    fn refine<F: Fn([f64; 3]) -> f64>(
        &mut self,
        size: &F,
        field: &str,
        limit: usize,
    ) -> Result<(), MeshError> {
        // Depth-first work stack; a triangle may be pushed several times, the criterion is
        // re-evaluated when popped.
        let mut stack: Vec<u32> = (0..self.tris.len() as u32).rev().collect();
        while let Some(t) = stack.pop() {
            if !self.needs_split(t, size) {
                continue;
            }
            // Bisect terminal pairs of LEPP(t) until t itself has been bisected.
            loop {
                let mut cur = t;
                let (i, u, j) = loop {
                    let i = self.longest(cur);
                    let u = self.tris[cur as usize].n[i];
                    let j = self.longest(u);
                    if self.tris[u as usize].n[j] == cur {
                        break (i, u, j);
                    }
                    cur = u;
                };
                let (t2, u2) = self.bisect_pair(cur, i, u, j);
                stack.extend_from_slice(&[u2, u, t2, cur]);
                if self.tris.len() > limit {
                    return Err(MeshError::TooLarge {
                        field: field.to_string(),
                        limit,
                    });
                }
                if cur == t {
                    break;
                }
            }
        }
        Ok(())
    }

    /// Replaces the triangle at the far side of edge `k` of `x` (which pointed to `old`) so
    /// that it points to `new`.
    #[inline]
    fn relink(&mut self, x: u32, old: u32, new: u32) {
        let n = &mut self.tris[x as usize].n;
        for slot in n.iter_mut() {
            if *slot == old {
                *slot = new;
                return;
            }
        }
        unreachable!("broken triangle adjacency");
    }

    /// Bisects the shared longest edge of `t` (local edge `i`) and `u` (local edge `j`) at its
    /// midpoint projected on the sphere. Returns the two new triangles.
    ///
    /// ```text
    ///  t = (a,b,c), u = (d,c,b), shared edge (b,c), m its midpoint:
    ///  t → (a,b,m), t2 = (a,m,c), u → (d,c,m), u2 = (d,m,b)
    /// ```
    fn bisect_pair(&mut self, t: u32, i: usize, u: u32, j: usize) -> (u32, u32) {
        let tt = self.tris[t as usize];
        let tu = self.tris[u as usize];
        let (a, b, c) = (tt.v[i], tt.v[(i + 1) % 3], tt.v[(i + 2) % 3]);
        let d = tu.v[j];
        debug_assert_eq!(tu.v[(j + 1) % 3], c);
        debug_assert_eq!(tu.v[(j + 2) % 3], b);
        let n_ca = tt.n[(i + 1) % 3];
        let n_ab = tt.n[(i + 2) % 3];
        let n_bd = tu.n[(j + 1) % 3];
        let n_dc = tu.n[(j + 2) % 3];

        let mid = scale(add(self.pts[b as usize], self.pts[c as usize]), 0.5);
        let m = self.pts.len() as u32;
        self.pts.push(scale(mid, self.radius / norm(mid)));

        let t2 = self.tris.len() as u32;
        let u2 = t2 + 1;
        self.tris[t as usize] = Tri {
            v: [a, b, m],
            n: [u2, t2, n_ab],
        };
        self.tris.push(Tri {
            v: [a, m, c],
            n: [u, n_ca, t],
        });
        self.tris[u as usize] = Tri {
            v: [d, c, m],
            n: [t2, u2, n_dc],
        };
        self.tris.push(Tri {
            v: [d, m, b],
            n: [t, n_bd, u],
        });
        self.relink(n_ca, t, t2);
        self.relink(n_bd, u, u2);
        (t2, u2)
    }
}

#[cfg(test)]
mod tests;
