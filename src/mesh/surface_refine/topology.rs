//! Steps 3 and 4 of the surface triangulation: vertex fans, pins moved onto their
//! points, and the edge flips that keep the triangulation convex (spherical Delaunay).

use super::{MeshError, Pin, Refiner, Tri};
use crate::math::{cross, dot, norm, scale, sub};

impl Refiner {
    /// Triangles around vertex `v` in fan order, starting at `start` (which contains `v`).
    pub(super) fn fan(&self, v: u32, start: u32) -> Vec<u32> {
        let mut fan = Vec::new();
        let mut cur = start;
        loop {
            fan.push(cur);
            let tv = self.tris[cur as usize];
            let k =
                tv.v.iter()
                    .position(|&x| x == v)
                    .expect("vertex not in its fan");
            cur = tv.n[(k + 1) % 3];
            if cur == start {
                return fan;
            }
        }
    }

    /// Moves, pin by pin, a vertex exactly onto each pinned point and restores convexity by
    /// flips; returns the mask of pinned vertices. The vertex is the nearest one (it owns the
    /// Voronoi cell holding the point, so it moves by about half the local edge at most)
    /// unless it has valence 3–4 (a pinned vertex is never removed, and at valence 4 its
    /// angles cannot all become acute, see `PIN_PLATEAU`) or the move would fold one of its
    /// triangles over (where a triangle is obtuse at the vertex its cell reaches past the
    /// opposite edge); then the nearest vertex of its ring that qualifies is moved instead,
    /// or failing that the nearest whose fan at least stays outward. Two pins whose nearest
    /// vertex is the same would give one node to two points closer than an edge: an error
    /// naming the second pin's field.
    pub(super) fn pin(&mut self, pins: &[Pin]) -> Result<Vec<bool>, MeshError> {
        let mut owner: Vec<Option<usize>> = vec![None; self.pts.len()];
        for (k, pin) in pins.iter().enumerate() {
            let target = scale(pin.direction, self.radius / norm(pin.direction));
            let dist2 = |x: [f64; 3]| {
                let d = sub(x, target);
                dot(d, d)
            };
            // Strict comparison: ties go to the lowest id, so the choice is reproducible.
            let mut nearest = 0u32;
            let mut best = f64::INFINITY;
            for (i, &x) in self.pts.iter().enumerate() {
                let d2 = dist2(x);
                if d2 < best {
                    best = d2;
                    nearest = i as u32;
                }
            }
            if let Some(other) = owner[nearest as usize] {
                return Err(MeshError::InvalidSpec {
                    field: pin.field.clone(),
                    message: format!(
                        "its node would be the surface vertex already pinned for {}: the two points are closer than the local edge length (refine there, or pin one of them)",
                        pins[other].field
                    ),
                });
            }
            let mut first_tri = vec![u32::MAX; self.pts.len()];
            for (t, tri) in self.tris.iter().enumerate() {
                for &v in &tri.v {
                    first_tri[v as usize] = t as u32;
                }
            }
            let nearest_fan = self.fan(nearest, first_tri[nearest as usize]);
            let mut ring: Vec<u32> = nearest_fan
                .iter()
                .map(|&t| {
                    let tv = self.tris[t as usize].v;
                    let j = tv.iter().position(|&x| x == nearest).expect("fan");
                    tv[(j + 1) % 3]
                })
                .filter(|&v| owner[v as usize].is_none())
                .collect();
            ring.sort_by(|&a, &b| {
                dist2(self.pts[a as usize])
                    .total_cmp(&dist2(self.pts[b as usize]))
                    .then(a.cmp(&b))
            });
            let outward: Vec<(u32, Vec<u32>)> = std::iter::once(nearest)
                .chain(ring)
                .map(|v| (v, self.fan(v, first_tri[v as usize])))
                .filter(|(v, fan)| self.fan_worst(fan, *v, target).is_some())
                .collect();
            let chosen = outward
                .iter()
                .find(|(_, fan)| fan.len() >= 5)
                .or(outward.first())
                .cloned();
            let Some((v, fan)) = chosen else {
                return Err(MeshError::InvalidSpec {
                    field: pin.field.clone(),
                    message: "no surface vertex near the point can be moved onto it without folding the surface over".into(),
                });
            };
            self.pts[v as usize] = target;
            owner[v as usize] = Some(k);
            self.flip_from(&fan);
        }
        Ok(owner.iter().map(Option::is_some).collect())
    }

    /// True if vertex `target` is adjacent to `a` (walks the triangle fan of `a` starting at
    /// triangle `start`, which must contain `a`).
    pub(super) fn fan_contains(&self, start: u32, a: u32, target: u32) -> bool {
        let mut cur = start;
        loop {
            let tv = self.tris[cur as usize];
            let k =
                tv.v.iter()
                    .position(|&x| x == a)
                    .expect("vertex not in triangle");
            if tv.v[(k + 1) % 3] == target || tv.v[(k + 2) % 3] == target {
                return true;
            }
            // Edge opposite v[k+1] is (v[k+2], a): crossing it rotates about a.
            cur = tv.n[(k + 1) % 3];
            if cur == start {
                return false;
            }
        }
    }

    /// Lawson flips until every edge is convex (the triangulation is the convex hull of its
    /// vertices). For points on a sphere this is the Delaunay criterion, so it terminates;
    /// a small tolerance keeps exactly cocircular quads (frequent by symmetry) unflipped.
    pub(super) fn flip_to_convex(&mut self) {
        let all: Vec<u32> = (0..self.tris.len() as u32).collect();
        self.flip_from(&all);
    }

    /// [`Self::flip_to_convex`] starting from the triangles `start` (flips propagate to
    /// neighbours as needed).
    pub(super) fn flip_from(&mut self, start: &[u32]) {
        let nt = self.tris.len();
        let mut stack: Vec<u32> = start.iter().rev().copied().collect();
        let mut queued = vec![false; nt];
        for &t in start {
            queued[t as usize] = true;
        }
        while let Some(t) = stack.pop() {
            queued[t as usize] = false;
            for i in 0..3 {
                let tt = self.tris[t as usize];
                let u = tt.n[i];
                let (a, b, c) = (tt.v[i], tt.v[(i + 1) % 3], tt.v[(i + 2) % 3]);
                let tu = self.tris[u as usize];
                let j = tu.n.iter().position(|&x| x == t).expect("broken adjacency");
                let d = tu.v[j];
                let [pa, pb, pc, pd] = [a, b, c, d].map(|x| self.pts[x as usize]);
                let nrm = cross(sub(pb, pa), sub(pc, pa));
                let bc = norm(sub(pc, pb));
                let height = dot(sub(pd, pa), nrm);
                if height <= 1e-9 * bc * norm(nrm) {
                    continue;
                }
                if self.fan_contains(t, a, d) {
                    continue;
                }
                // t = (a,b,c), u = (d,c,b) → t = (a,b,d), u = (a,d,c)
                let n_ca = tt.n[(i + 1) % 3];
                let n_ab = tt.n[(i + 2) % 3];
                let n_bd = tu.n[(j + 1) % 3];
                let n_dc = tu.n[(j + 2) % 3];
                self.tris[t as usize] = Tri {
                    v: [a, b, d],
                    n: [n_bd, u, n_ab],
                };
                self.tris[u as usize] = Tri {
                    v: [a, d, c],
                    n: [n_dc, n_ca, t],
                };
                self.relink(n_bd, u, t);
                self.relink(n_ca, t, u);
                for x in [t, u, n_ab, n_bd, n_dc, n_ca] {
                    if !queued[x as usize] {
                        queued[x as usize] = true;
                        stack.push(x);
                    }
                }
                break;
            }
        }
    }
}
