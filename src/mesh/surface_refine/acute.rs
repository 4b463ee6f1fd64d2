//! Step 5 of the surface triangulation: making the triangles acute where bisection or a
//! pin changed them (Lloyd relaxation, obtuse-angle repair, low-valence removal).

use super::{Refiner, ACUTE_PASSES, LLOYD_ITERATIONS, MAX_ANGLE_DEG, REPAIR_ROUNDS};
use crate::math::{add, cross, dot, norm, scale, sub};

impl Refiner {
    /// Lloyd iterations towards a centroidal Voronoi tessellation with density h⁻⁴: every
    /// vertex moves to the density-weighted centroid of its Voronoi cell (then back onto the
    /// sphere) and edges are re-flipped. The cell is assembled per triangle corner from the
    /// two kites (v, edge midpoint, circumcentre) with signed areas, so no fan ordering is
    /// needed. Only `movable` vertices move; triangles without one are skipped. One
    /// accumulator array is allocated for all sweeps.
    pub(super) fn lloyd<F: Fn([f64; 3]) -> f64>(
        &mut self,
        size: &F,
        iterations: usize,
        movable: &[bool],
    ) {
        let np = self.pts.len();
        let mut acc = vec![([0.0; 3], 0.0); np];
        let mut active: Vec<u32> = Vec::new();
        for _ in 0..iterations {
            acc.iter_mut().for_each(|a| *a = ([0.0; 3], 0.0));
            active.clear();
            for (ti, t) in self.tris.iter().enumerate() {
                if !t.v.iter().any(|&i| movable[i as usize]) {
                    continue;
                }
                active.push(ti as u32);
                let p = t.v.map(|i| self.pts[i as usize]);
                let (ab, ac) = (sub(p[1], p[0]), sub(p[2], p[0]));
                let n = cross(ab, ac);
                let nn = dot(n, n);
                let num = add(
                    scale(cross(n, ab), dot(ac, ac)),
                    scale(cross(ac, n), dot(ab, ab)),
                );
                let cc = add(p[0], scale(num, 0.5 / nn));
                let nhat = scale(n, 1.0 / nn.sqrt());
                // Density sampled once per triangle (at its centroid on the sphere).
                let g = add(add(p[0], p[1]), p[2]);
                let h = size(scale(g, self.radius / norm(g)));
                let rho = 1.0 / (h * h * h * h);
                for k in 0..3 {
                    let v = p[k];
                    for (w, first) in [(p[(k + 1) % 3], true), (p[(k + 2) % 3], false)] {
                        let m = scale(add(v, w), 0.5);
                        // Signed area of (v, m, cc) toward the next vertex, (v, cc, m) toward
                        // the previous one.
                        let (q1, q2) = if first { (m, cc) } else { (cc, m) };
                        let wgt = rho * 0.5 * dot(cross(sub(q1, v), sub(q2, v)), nhat);
                        let a = &mut acc[t.v[k] as usize];
                        a.0 = add(a.0, scale(add(add(v, q1), q2), wgt / 3.0));
                        a.1 += wgt;
                    }
                }
            }
            let mut max_move2: f64 = 0.0;
            let mut min_h2 = f64::INFINITY;
            for ((p, a), &m) in self.pts.iter_mut().zip(&acc).zip(movable) {
                if m && a.1 > 0.0 {
                    let c = scale(a.0, 1.0 / a.1);
                    let q = scale(c, self.radius / norm(c));
                    let d = sub(q, *p);
                    max_move2 = max_move2.max(dot(d, d));
                    min_h2 = min_h2.min(size(q).powi(2));
                    *p = q;
                }
            }
            self.flip_from(&active);
            // Converged: nothing moved by more than 0.1 % of the finest size.
            if max_move2 < 1e-6 * min_h2 {
                break;
            }
        }
    }

    /// Largest angle (as its cosine's negative: larger = worse) over triangles `fan` when
    /// vertex `v` sits at `x`; `None` if a triangle flips over.
    pub(super) fn fan_worst(&self, fan: &[u32], v: u32, x: [f64; 3]) -> Option<f64> {
        let mut worst = f64::NEG_INFINITY;
        for &t in fan {
            let p = self.tris[t as usize]
                .v
                .map(|i| if i == v { x } else { self.pts[i as usize] });
            let n = cross(sub(p[1], p[0]), sub(p[2], p[0]));
            if dot(n, add(add(p[0], p[1]), p[2])) <= 0.0 {
                return None;
            }
            for k in 0..3 {
                let e1 = sub(p[(k + 1) % 3], p[k]);
                let e2 = sub(p[(k + 2) % 3], p[k]);
                let c = -dot(e1, e2) / (norm(e1) * norm(e2));
                worst = worst.max(c);
            }
        }
        Some(worst)
    }

    /// Moves the vertices of triangles with an angle above `max_deg` (pattern search on the
    /// largest angle of their fans, in the tangent plane, re-projected onto the sphere),
    /// re-flipping after each round. Returns the number of such angles left.
    pub(super) fn repair_obtuse(&mut self, max_deg: f64, rounds: usize, movable: &[bool]) -> usize {
        let cmax = -max_deg.to_radians().cos();
        let mut left = 0;
        for _ in 0..rounds {
            let mut vt = vec![u32::MAX; self.pts.len()];
            let mut bad: Vec<u32> = Vec::new();
            for (t, tri) in self.tris.iter().enumerate() {
                let p = tri.v.map(|i| self.pts[i as usize]);
                for k in 0..3 {
                    vt[tri.v[k] as usize] = t as u32;
                    let e1 = sub(p[(k + 1) % 3], p[k]);
                    let e2 = sub(p[(k + 2) % 3], p[k]);
                    if -dot(e1, e2) / (norm(e1) * norm(e2)) > cmax {
                        bad.extend_from_slice(&tri.v);
                    }
                }
            }
            left = bad.len() / 3;
            if bad.is_empty() {
                return 0;
            }
            bad.retain(|&v| movable[v as usize]);
            bad.sort_unstable();
            bad.dedup();
            for &v in &bad {
                let fan = self.fan(v, vt[v as usize]);
                let x0 = self.pts[v as usize];
                let nrm = scale(x0, 1.0 / norm(x0));
                let (u, w) = crate::math::tangent_basis(nrm);
                let mean_edge = fan
                    .iter()
                    .map(|&t| {
                        let tv = self.tris[t as usize].v;
                        let k = tv.iter().position(|&x| x == v).unwrap();
                        norm(sub(self.pts[tv[(k + 1) % 3] as usize], x0))
                    })
                    .sum::<f64>()
                    / fan.len() as f64;
                let mut x = x0;
                let mut best = self.fan_worst(&fan, v, x).unwrap_or(f64::INFINITY);
                let mut step = 0.1 * mean_edge;
                for _ in 0..30 {
                    let mut improved = false;
                    for d in 0..8 {
                        let ang = d as f64 * std::f64::consts::FRAC_PI_4;
                        let dir = add(scale(u, ang.cos()), scale(w, ang.sin()));
                        let y = add(x, scale(dir, step));
                        let y = scale(y, self.radius / norm(y));
                        if let Some(f) = self.fan_worst(&fan, v, y) {
                            if f < best - 1e-12 {
                                best = f;
                                x = y;
                                improved = true;
                            }
                        }
                    }
                    if !improved {
                        step *= 0.5;
                        if step < 1e-3 * mean_edge {
                            break;
                        }
                    }
                }
                self.pts[v as usize] = x;
            }
            self.flip_to_convex();
        }
        left
    }

    /// Number of triangle angles above `max_deg`.
    pub(super) fn count_angles_above(&self, max_deg: f64) -> usize {
        let cmax = -max_deg.to_radians().cos();
        let mut n = 0;
        for tri in &self.tris {
            let p = tri.v.map(|i| self.pts[i as usize]);
            for k in 0..3 {
                let e1 = sub(p[(k + 1) % 3], p[k]);
                let e2 = sub(p[(k + 2) % 3], p[k]);
                if -dot(e1, e2) / (norm(e1) * norm(e2)) > cmax {
                    n += 1;
                }
            }
        }
        n
    }

    /// The vertices of `seed`, dilated by `rings` rings of neighbours.
    pub(super) fn dilate(&self, seed: Vec<bool>, rings: usize) -> Vec<bool> {
        let mut m = seed;
        for _ in 0..rings {
            let prev = m.clone();
            for t in &self.tris {
                if t.v.iter().any(|&i| prev[i as usize]) {
                    for &i in &t.v {
                        m[i as usize] = true;
                    }
                }
            }
        }
        m
    }

    /// Removes movable vertices of valence 3 or 4 (no two adjacent ones in one pass): their
    /// angles average ≥ 90°, so no smoothing can make their triangles acute. The hole is
    /// re-triangulated from the ring (flips restore convexity afterwards), never leaving a
    /// `pinned` vertex (which cannot go itself) at valence 4, and the structure is rebuilt
    /// with compacted vertex ids; `movable` and `pinned` are compacted alongside. Returns
    /// the number of vertices removed.
    pub(super) fn remove_low_valence(
        &mut self,
        movable: &mut Vec<bool>,
        pinned: &mut Vec<bool>,
    ) -> usize {
        let np = self.pts.len();
        let mut valence = vec![0u32; np];
        let mut vt = vec![u32::MAX; np];
        for (t, tri) in self.tris.iter().enumerate() {
            for &v in &tri.v {
                valence[v as usize] += 1;
                vt[v as usize] = t as u32;
            }
        }
        // Undirected edges, so that no re-triangulation adds an edge that already exists
        // (a valence-4 vertex whose opposite ring vertices are already joined elsewhere):
        // that would make the surface non-manifold.
        let key = |a: u32, b: u32| (a.min(b), a.max(b));
        let mut edges: std::collections::HashSet<(u32, u32)> =
            std::collections::HashSet::with_capacity(3 * self.tris.len() / 2);
        for tri in &self.tris {
            for k in 0..3 {
                edges.insert(key(tri.v[k], tri.v[(k + 1) % 3]));
            }
        }
        let mut dead_tri = vec![false; self.tris.len()];
        let mut locked = vec![false; np];
        let mut removed = vec![false; np];
        let mut new_tris: Vec<[u32; 3]> = Vec::new();
        let mut ring: Vec<u32> = Vec::with_capacity(4);
        let mut fan: Vec<u32> = Vec::with_capacity(4);
        for v in 0..np {
            if !movable[v] || locked[v] || valence[v] > 4 {
                continue;
            }
            ring.clear();
            fan.clear();
            let start = vt[v];
            let mut cur = start;
            loop {
                let tv = self.tris[cur as usize];
                let k = tv.v.iter().position(|&x| x as usize == v).expect("fan");
                ring.push(tv.v[(k + 1) % 3]);
                fan.push(cur);
                cur = tv.n[(k + 1) % 3];
                if cur == start {
                    break;
                }
            }
            if fan.iter().any(|&t| dead_tri[t as usize])
                || ring.iter().any(|&r| removed[r as usize])
            {
                continue;
            }
            // Valence 4: split the quadrilateral along a diagonal that is not yet an edge;
            // valence 3: the ring triangle must not duplicate one (closed tetrahedron). The
            // ring vertices off the new diagonal lose an edge.
            let drops_pin = |r: u32| pinned[r as usize] && valence[r as usize] <= 5;
            if ring.len() == 4 {
                let diagonal_ok = |a: u32, b: u32, off: [u32; 2]| {
                    !edges.contains(&key(a, b)) && !off.iter().any(|&r| drops_pin(r))
                };
                if !diagonal_ok(ring[0], ring[2], [ring[1], ring[3]]) {
                    if !diagonal_ok(ring[1], ring[3], [ring[0], ring[2]]) {
                        continue;
                    }
                    ring.rotate_left(1);
                }
                edges.insert(key(ring[0], ring[2]));
                valence[ring[1] as usize] -= 1;
                valence[ring[3] as usize] -= 1;
            } else if ring.len() == 3 {
                if ring.iter().any(|&r| drops_pin(r)) {
                    continue;
                }
                for &r in &ring {
                    valence[r as usize] -= 1;
                }
            } else {
                continue;
            }
            removed[v] = true;
            for &t in &fan {
                dead_tri[t as usize] = true;
            }
            for &r in &ring {
                locked[r as usize] = true;
            }
            // Ring order follows the fan walk; orient each new triangle outward.
            let mut push = |a: u32, b: u32, c: u32| {
                let [pa, pb, pc] = [a, b, c].map(|i| self.pts[i as usize]);
                if dot(cross(sub(pb, pa), sub(pc, pa)), add(add(pa, pb), pc)) > 0.0 {
                    new_tris.push([a, b, c]);
                } else {
                    new_tris.push([a, c, b]);
                }
            };
            push(ring[0], ring[1], ring[2]);
            if ring.len() == 4 {
                push(ring[0], ring[2], ring[3]);
            }
        }
        let count = removed.iter().filter(|&&r| r).count();
        if count == 0 {
            return 0;
        }
        let mut new_id = vec![u32::MAX; np];
        let mut pts = Vec::with_capacity(np - count);
        let mut mov = Vec::with_capacity(np - count);
        let mut pin = Vec::with_capacity(np - count);
        for v in 0..np {
            if !removed[v] {
                new_id[v] = pts.len() as u32;
                pts.push(self.pts[v]);
                mov.push(movable[v]);
                pin.push(pinned[v]);
            }
        }
        let tri_v: Vec<[u32; 3]> = self
            .tris
            .iter()
            .zip(&dead_tri)
            .filter(|(_, &d)| !d)
            .map(|(t, _)| t.v)
            .chain(new_tris)
            .map(|t| t.map(|i| new_id[i as usize]))
            .collect();
        *self = Self::from_triangles(self.radius, pts, &tri_v);
        *movable = mov;
        *pinned = pin;
        self.flip_to_convex();
        count
    }

    /// Makes a triangulation acute in the zone `movable` (the refined vertices plus two rings
    /// of the base mesh, and `PIN_RINGS` rings around each pinned vertex): removes
    /// valence-3/4 vertices, relaxes the zone by Lloyd iterations with density `size`⁻⁴,
    /// gives pins left at valence 4 a fifth neighbour, and moves the vertices of any
    /// remaining angle above `MAX_ANGLE_DEG`. Vertices outside the zone, and the `pinned`
    /// ones, neither move nor go.
    /// TetGen treats every surface edge as a segment and splits any whose diametral ball
    /// holds a vertex, i.e. every edge opposite an angle ≥ 90°; such splits cascade through
    /// the neighbouring segments into edges many times shorter than requested, so the surface
    /// handed to TetGen must be acute. Returns the number of angles still above 90°.
    pub(super) fn make_acute<F: Fn([f64; 3]) -> f64>(
        &mut self,
        size: &F,
        mut movable: Vec<bool>,
        mut pinned: Vec<bool>,
    ) -> usize {
        for _ in 0..ACUTE_PASSES {
            self.remove_low_valence(&mut movable, &mut pinned);
            self.lloyd(size, LLOYD_ITERATIONS, &movable);
            while self.remove_low_valence(&mut movable, &mut pinned) > 0 {
                self.lloyd(size, 5, &movable);
            }
            self.raise_pinned_valence(&mut movable, &mut pinned);
            self.repair_obtuse(MAX_ANGLE_DEG, REPAIR_ROUNDS, &movable);
            if self.count_angles_above(MAX_ANGLE_DEG + 3.0) == 0 {
                break;
            }
        }
        self.count_angles_above(90.0)
    }

    /// Gives every pinned vertex of valence 3–4 one more neighbour by bisecting the edge
    /// opposite its largest angle: its angles sum to just under 360° (the sphere's angle
    /// defect), so at valence 4 they are all ~90° however its neighbours move. The density
    /// plateau (`PIN_PLATEAU`) makes this rare; the new vertex is movable. Returns the
    /// number of bisections.
    pub(super) fn raise_pinned_valence(
        &mut self,
        movable: &mut Vec<bool>,
        pinned: &mut Vec<bool>,
    ) -> usize {
        let mut count = 0;
        for p in 0..self.pts.len() as u32 {
            if !pinned[p as usize] {
                continue;
            }
            let Some(start) = self.tris.iter().position(|t| t.v.contains(&p)) else {
                continue;
            };
            let fan = self.fan(p, start as u32);
            if fan.len() > 4 {
                continue;
            }
            let x = self.pts[p as usize];
            let (_, t, k) = fan
                .iter()
                .map(|&t| {
                    let v = self.tris[t as usize].v;
                    let k = v.iter().position(|&w| w == p).expect("fan");
                    let e1 = sub(self.pts[v[(k + 1) % 3] as usize], x);
                    let e2 = sub(self.pts[v[(k + 2) % 3] as usize], x);
                    (dot(e1, e2) / (norm(e1) * norm(e2)), t, k)
                })
                .fold(
                    (f64::INFINITY, 0, 0),
                    |best, c| if c.0 < best.0 { c } else { best },
                );
            let u = self.tris[t as usize].n[k];
            let j = self.tris[u as usize]
                .n
                .iter()
                .position(|&w| w == t)
                .expect("broken adjacency");
            let (t2, u2) = self.bisect_pair(t, k, u, j);
            movable.push(true);
            pinned.push(false);
            self.flip_from(&[t, t2, u, u2]);
            count += 1;
        }
        count
    }
}
