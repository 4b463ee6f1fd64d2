//! Topological improvement of a tet mesh: edge removal and 2–3 face flips.
//!
//! Moving nodes ([`super::smooth`]) cannot repair an element whose shape is fixed by its
//! connectivity: the slivers left after smoothing join a surface edge to two interior nodes
//! just below the surface, and every position of those nodes that lifts the sliver flattens
//! a neighbour. Changing which nodes the elements join can. Two transformations, as in
//! Klingner and Shewchuk's tetrahedral mesh improvement (IMR 2007):
//!
//! - **Edge removal.** The m elements around an interior edge ab, whose other nodes form the
//!   ring r₀…r_{m−1}, are replaced by 2(m − 2) elements: a triangulation of the ring polygon,
//!   each triangle joined to a and to b. The triangulation that maximises the smallest shape
//!   ratio is found by dynamic programming over the polygon's sub-chains (O(m³)). For m = 3
//!   this is the 3–2 flip.
//! - **2–3 flip.** Two elements abcd and abce sharing an interior face abc become abde, bcde
//!   and cade, when the segment de crosses the triangle abc (all three have one orientation).
//!
//! A transformation is applied when it raises the smallest shape ratio ([`height_ratio`])
//! of the elements it replaces. Only interior edges (closed rings) and interior faces are
//! touched, so every surface facet, and with it the grain's contact geometry, stays exactly
//! as meshed; no node moves. Candidates are the elements below [`TARGET_RATIO`], visited
//! worst first (ties by index): same mesh in, same mesh out.

use super::smooth::{height_ratio, TARGET_RATIO};
use super::surface::TET_FACES;
use super::{tet_volume, TetMesh};

/// Passes of flips over the mesh (each ends when nothing improved).
pub const PASSES: usize = 6;
/// Rings larger than this are not removed (the dynamic programme is O(m³), and such rings
/// are not where slivers sit).
const MAX_RING: usize = 10;
/// A transformation must raise the smallest ratio by at least this factor.
const GAIN: f64 = 1.0 + 1e-6;

/// What [`improve_by_flips`] did.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FlipReport {
    /// Interior edges removed (3–2 flips included).
    pub edge_removals: usize,
    /// 2–3 face flips.
    pub face_flips: usize,
}

/// Applies edge removals and 2–3 flips that raise the local smallest shape ratio (module
/// docs), in up to [`PASSES`] passes. Tets stay positively oriented; nodes are unchanged.
pub fn improve_by_flips(mesh: &mut TetMesh) -> FlipReport {
    let mut work = FlipMesh::new(&mesh.nodes, std::mem::take(&mut mesh.tets));
    let mut report = FlipReport::default();
    for _ in 0..PASSES {
        let mut poor: Vec<(f64, usize)> = (0..work.tets.len())
            .filter(|&e| work.alive[e])
            .map(|e| (work.ratio(work.tets[e]), e))
            .filter(|&(r, _)| r < TARGET_RATIO)
            .collect();
        poor.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let before = report;
        for &(_, e) in &poor {
            if !work.alive[e] {
                continue;
            }
            let t = work.tets[e];
            if EDGES.iter().any(|&(i, j)| work.try_remove_edge(t[i], t[j])) {
                report.edge_removals += 1;
            } else if (0..4).any(|k| {
                let face = TET_FACES[k].map(|i| t[i]);
                work.try_flip_face(e, face, t[k])
            }) {
                report.face_flips += 1;
            }
        }
        if report == before {
            break;
        }
    }
    mesh.tets = work.into_live_tets();
    report
}

const EDGES: [(usize, usize); 6] = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)];

/// The mesh while it is being flipped: tets with a liveness flag (removed ones are dropped
/// at the end) and each node's incident tets.
struct FlipMesh<'a> {
    nodes: &'a [[f64; 3]],
    tets: Vec<[u32; 4]>,
    alive: Vec<bool>,
    star: Vec<Vec<u32>>,
}

impl<'a> FlipMesh<'a> {
    fn new(nodes: &'a [[f64; 3]], tets: Vec<[u32; 4]>) -> Self {
        let mut star = vec![Vec::new(); nodes.len()];
        for (e, t) in tets.iter().enumerate() {
            for &v in t {
                star[v as usize].push(e as u32);
            }
        }
        FlipMesh {
            nodes,
            alive: vec![true; tets.len()],
            tets,
            star,
        }
    }

    fn x(&self, v: u32) -> [f64; 3] {
        self.nodes[v as usize]
    }

    fn ratio(&self, t: [u32; 4]) -> f64 {
        height_ratio(&t.map(|v| self.x(v)))
    }

    fn volume(&self, t: [u32; 4]) -> f64 {
        tet_volume(&t.map(|v| self.x(v)))
    }

    fn remove(&mut self, e: usize) {
        self.alive[e] = false;
        for v in self.tets[e] {
            self.star[v as usize].retain(|&f| f as usize != e);
        }
    }

    fn add(&mut self, t: [u32; 4]) {
        let e = self.tets.len() as u32;
        self.tets.push(t);
        self.alive.push(true);
        for v in t {
            self.star[v as usize].push(e);
        }
    }

    /// The live tets containing both a and b.
    fn around_edge(&self, a: u32, b: u32) -> Vec<usize> {
        self.star[a as usize]
            .iter()
            .map(|&e| e as usize)
            .filter(|&e| self.tets[e].contains(&b))
            .collect()
    }

    /// The ring of nodes around edge ab, oriented so that (a, b, rᵢ, rᵢ₊₁) is positive, and
    /// the tets of the ring; `None` when the ring is open (a boundary edge) or too large.
    fn ring(&self, a: u32, b: u32) -> Option<(Vec<u32>, Vec<usize>)> {
        let tets = self.around_edge(a, b);
        if tets.len() < 3 || tets.len() > MAX_RING {
            return None;
        }
        let pairs: Vec<[u32; 2]> = tets
            .iter()
            .map(|&e| {
                let mut other = [0; 2];
                let mut k = 0;
                for v in self.tets[e] {
                    if v != a && v != b {
                        other[k] = v;
                        k += 1;
                    }
                }
                other
            })
            .collect();
        let mut used = vec![false; pairs.len()];
        used[0] = true;
        let mut ring = vec![pairs[0][0], pairs[0][1]];
        while ring.len() < pairs.len() {
            let last = *ring.last().unwrap();
            let next = (0..pairs.len()).find(|&p| !used[p] && pairs[p].contains(&last))?;
            used[next] = true;
            let pair = pairs[next];
            ring.push(if pair[0] == last { pair[1] } else { pair[0] });
        }
        // closed: the unused pair joins the last node back to the first
        let closing = (0..pairs.len()).find(|&p| !used[p])?;
        let last = *ring.last().unwrap();
        if !(pairs[closing].contains(&last) && pairs[closing].contains(&ring[0])) {
            return None;
        }
        if self.volume([a, b, ring[0], ring[1]]) < 0.0 {
            ring.reverse();
        }
        Some((ring, tets))
    }

    /// Edge removal of ab (module docs), if it raises the smallest ratio of its ring.
    fn try_remove_edge(&mut self, a: u32, b: u32) -> bool {
        let Some((ring, old)) = self.ring(a, b) else {
            return false;
        };
        let current = old
            .iter()
            .map(|&e| self.ratio(self.tets[e]))
            .fold(f64::INFINITY, f64::min);
        let m = ring.len();
        // best[i][j]: largest smallest ratio over triangulations of the chain rᵢ…rⱼ;
        // split[i][j]: the apex k of the triangle on the chord rᵢrⱼ
        let mut best = vec![vec![f64::INFINITY; m]; m];
        let mut split = vec![vec![0usize; m]; m];
        for len in 2..m {
            for i in 0..m - len {
                let j = i + len;
                best[i][j] = f64::NEG_INFINITY;
                for k in i + 1..j {
                    let tri = self.ring_tets(&ring, a, b, i, k, j);
                    let q = best[i][k]
                        .min(best[k][j])
                        .min(self.ratio(tri[0]))
                        .min(self.ratio(tri[1]));
                    if q > best[i][j] {
                        best[i][j] = q;
                        split[i][j] = k;
                    }
                }
            }
        }
        if best[0][m - 1] <= current * GAIN || best[0][m - 1] <= 0.0 {
            return false;
        }
        for e in old {
            self.remove(e);
        }
        let mut chords = vec![(0, m - 1)];
        while let Some((i, j)) = chords.pop() {
            if j - i < 2 {
                continue;
            }
            let k = split[i][j];
            for t in self.ring_tets(&ring, a, b, i, k, j) {
                self.add(t);
            }
            chords.push((i, k));
            chords.push((k, j));
        }
        true
    }

    /// The two tets of ring triangle (rᵢ, r_k, r_j), i < k < j, with a and with b,
    /// positively oriented for a valid triangulation (the ring's orientation fixes it).
    fn ring_tets(
        &self,
        ring: &[u32],
        a: u32,
        b: u32,
        i: usize,
        k: usize,
        j: usize,
    ) -> [[u32; 4]; 2] {
        let (p, q, r) = (ring[i], ring[k], ring[j]);
        [[p, q, r, b], [q, p, r, a]]
    }

    /// 2–3 flip of the face `face` of tet `e` (whose fourth node is `d`), if the face is
    /// interior, the flip is valid and it raises the smallest ratio of the two tets.
    fn try_flip_face(&mut self, e: usize, face: [u32; 3], d: u32) -> bool {
        let [a, b, c] = face;
        let Some(other) = self.star[a as usize]
            .iter()
            .map(|&f| f as usize)
            .find(|&f| f != e && self.tets[f].contains(&b) && self.tets[f].contains(&c))
        else {
            return false;
        };
        let Some(&apex) = self.tets[other]
            .iter()
            .find(|&&v| v != a && v != b && v != c)
        else {
            return false;
        };
        let current = self.ratio(self.tets[e]).min(self.ratio(self.tets[other]));
        let mut new = [[a, b, d, apex], [b, c, d, apex], [c, a, d, apex]];
        let signs = new.map(|t| self.volume(t));
        let positive = signs.iter().all(|&s| s > 0.0);
        if !positive && !signs.iter().all(|&s| s < 0.0) {
            return false;
        }
        if !positive {
            for t in new.iter_mut() {
                t.swap(0, 1);
            }
        }
        let q = new
            .iter()
            .map(|&t| self.ratio(t))
            .fold(f64::INFINITY, f64::min);
        if q <= current * GAIN {
            return false;
        }
        self.remove(e);
        self.remove(other);
        for t in new {
            self.add(t);
        }
        true
    }

    fn into_live_tets(self) -> Vec<[u32; 4]> {
        self.tets
            .into_iter()
            .zip(self.alive)
            .filter_map(|(t, alive)| alive.then_some(t))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::extract_surface;
    use crate::mesh::smooth::min_ratio;

    /// The boundary facets as sorted triples, in order.
    fn boundary_faces(mesh: &TetMesh) -> Vec<[u32; 3]> {
        let mut faces: Vec<[u32; 3]> = extract_surface(mesh)
            .facets
            .into_iter()
            .map(|mut f| {
                f.sort_unstable();
                f
            })
            .collect();
        faces.sort_unstable();
        faces
    }

    fn volumes(mesh: &TetMesh) -> Vec<f64> {
        mesh.tets
            .iter()
            .map(|t| tet_volume(&t.map(|v| mesh.nodes[v as usize])))
            .collect()
    }

    /// Nodes 0–2 an equilateral triangle of circumradius 1 in z = 0, nodes 3 and 4 on its
    /// axis at z = ±h. Shape ratios (computed for this layout): h = 1.6, the three tets
    /// around the axis edge 0.534 and the two tets on the triangle 0.994; h = 0.3, 0.706
    /// and 0.439.
    fn bipyramid(h: f64) -> Vec<[f64; 3]> {
        let mut nodes: Vec<[f64; 3]> = (0..3)
            .map(|i| {
                let t = 2.0 * std::f64::consts::PI * i as f64 / 3.0;
                [t.cos(), t.sin(), 0.0]
            })
            .collect();
        nodes.push([0.0, 0.0, h]);
        nodes.push([0.0, 0.0, -h]);
        nodes
    }

    fn positively_oriented(nodes: &[[f64; 3]], mut t: [u32; 4]) -> [u32; 4] {
        if tet_volume(&t.map(|v| nodes[v as usize])) < 0.0 {
            t.swap(0, 1);
        }
        t
    }

    fn check_flip(mut mesh: TetMesh, tets_after: usize) -> FlipReport {
        let before = mesh.clone();
        let report = improve_by_flips(&mut mesh);
        assert_eq!(mesh.tets.len(), tets_after, "{report:?}");
        assert_eq!(boundary_faces(&mesh), boundary_faces(&before));
        assert_eq!(mesh.nodes, before.nodes);
        assert!(volumes(&mesh).iter().all(|&v| v > 0.0));
        let total = |m: &TetMesh| volumes(m).iter().sum::<f64>();
        assert!((total(&mesh) - total(&before)).abs() < 1e-12 * total(&before));
        assert!(min_ratio(&mesh) > min_ratio(&before) * 1.2, "{report:?}");
        // deterministic, and a second call finds nothing left to improve here
        let mut again = before.clone();
        improve_by_flips(&mut again);
        assert_eq!(again, mesh);
        assert_eq!(improve_by_flips(&mut again), FlipReport::default());
        report
    }

    #[test]
    fn three_slivers_around_a_long_edge_become_two_tets() {
        let nodes = bipyramid(1.6);
        let tets = (0..3)
            .map(|i| positively_oriented(&nodes, [3, 4, i, (i + 1) % 3]))
            .collect();
        let report = check_flip(TetMesh { nodes, tets }, 2);
        assert_eq!(report.edge_removals, 1);
    }

    #[test]
    fn two_flat_tets_on_a_face_become_three() {
        let nodes = bipyramid(0.3);
        let tets = vec![
            positively_oriented(&nodes, [0, 1, 2, 3]),
            positively_oriented(&nodes, [0, 1, 2, 4]),
        ];
        let report = check_flip(TetMesh { nodes, tets }, 3);
        assert_eq!(report.face_flips, 1);
    }

    #[test]
    fn a_boundary_edge_is_never_removed() {
        // the h = 1.6 ring opened: two of the three tets, whose long edge is now on the
        // boundary, stay as they are
        let nodes = bipyramid(1.6);
        let tets: Vec<[u32; 4]> = (0..2)
            .map(|i| positively_oriented(&nodes, [3, 4, i, i + 1]))
            .collect();
        let mut mesh = TetMesh { nodes, tets };
        let before = mesh.clone();
        assert_eq!(improve_by_flips(&mut mesh), FlipReport::default());
        assert_eq!(mesh, before);
    }
}
