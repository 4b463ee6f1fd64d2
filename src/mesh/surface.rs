//! Boundary extraction and surface geometry for contact.

use super::{SurfaceMesh, TetMesh};
use crate::math::{add, cross, norm, scale, sub};

/// Faces of a positively oriented tet `[x0,x1,x2,x3]`, each ordered so that its normal
/// `(b−a)×(c−a)` points away from the opposite node (out of the tet).
pub(crate) const TET_FACES: [[usize; 3]; 4] = [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]];

/// Boundary of `mesh`: the faces that belong to exactly one tet, oriented outward
/// (counter-clockwise seen from outside, inherited from the tet's positive orientation),
/// and the ascending list of their nodes. Facets come in ascending order of their sorted
/// node triple (deterministic).
///
/// Faces are matched by sorting (key = sorted node triple) rather than hashing: one
/// allocation of 4·n_tets entries and an O(n log n) sort, deterministic, no hash overhead.
pub fn extract_surface(mesh: &TetMesh) -> SurfaceMesh {
    let mut faces: Vec<([u32; 3], u32)> = Vec::with_capacity(mesh.tets.len() * 4);
    for (e, t) in mesh.tets.iter().enumerate() {
        for (k, f) in TET_FACES.iter().enumerate() {
            let mut key = [t[f[0]], t[f[1]], t[f[2]]];
            key.sort_unstable();
            faces.push((key, (e as u32) * 4 + k as u32));
        }
    }
    faces.sort_unstable();
    let mut facets = Vec::new();
    let mut i = 0;
    while i < faces.len() {
        let mut j = i + 1;
        while j < faces.len() && faces[j].0 == faces[i].0 {
            j += 1;
        }
        if j - i == 1 {
            let (e, k) = ((faces[i].1 / 4) as usize, (faces[i].1 % 4) as usize);
            let t = mesh.tets[e];
            let f = TET_FACES[k];
            facets.push([t[f[0]], t[f[1]], t[f[2]]]);
        }
        i = j;
    }
    let mut nodes: Vec<u32> = facets.iter().flatten().copied().collect();
    nodes.sort_unstable();
    nodes.dedup();
    SurfaceMesh { nodes, facets }
}

/// Area vector of a facet: outward normal × area.
#[inline]
fn area_vector(mesh: &TetMesh, f: &[u32; 3]) -> [f64; 3] {
    let [a, b, c] = f.map(|i| mesh.nodes[i as usize]);
    scale(cross(sub(b, a), sub(c, a)), 0.5)
}

/// Per surface node (in `surface.nodes` order): the mean length of its surface edges (m),
/// and the shortest surface edge, at node positions `x` (indexed by the surface's node
/// ids). Each edge is seen from both of its facets: counted twice at both ends, which
/// leaves the mean unchanged. A node on no facet has 0.
pub fn mean_edge_at_nodes(surface: &SurfaceMesh, x: &[[f64; 3]]) -> (Vec<f64>, f64) {
    let n = surface.nodes.len();
    let local = |id: u32| surface.nodes.binary_search(&id).unwrap_or(0);
    let (mut sum, mut count, mut shortest) = (vec![0.0; n], vec![0u32; n], f64::INFINITY);
    for f in &surface.facets {
        for k in 0..3 {
            let s = local(f[k]);
            for other in [f[(k + 1) % 3], f[(k + 2) % 3]] {
                let l = norm(sub(x[other as usize], x[f[k] as usize]));
                sum[s] += l;
                count[s] += 1;
                shortest = shortest.min(l);
            }
        }
    }
    for (h, &c) in sum.iter_mut().zip(&count) {
        if c > 0 {
            *h /= f64::from(c);
        }
    }
    (sum, shortest)
}

/// Per surface node (in `surface.nodes` order): the longest facet edge within two rings
/// of it (m), at node positions `x` (indexed by the surface's node ids). The reach of the
/// facets a node's curved contact patch and its neighbours' depend on.
pub fn longest_edge_within_two_rings(surface: &SurfaceMesh, x: &[[f64; 3]]) -> Vec<f64> {
    let n = surface.nodes.len();
    let local = |id: u32| surface.nodes.binary_search(&id).unwrap_or(0);
    let longest = |f: &[u32; 3]| {
        (0..3)
            .map(|i| norm(sub(x[f[(i + 1) % 3] as usize], x[f[i] as usize])))
            .fold(0.0, f64::max)
    };
    // longest edge of the facets around each node (one ring) …
    let mut one_ring = vec![0.0f64; n];
    for f in &surface.facets {
        let e = longest(f);
        for &id in f {
            let k = local(id);
            one_ring[k] = one_ring[k].max(e);
        }
    }
    // … then over the corners of those facets (two rings)
    let mut two_rings = one_ring.clone();
    for f in &surface.facets {
        let reach = f.iter().map(|&id| one_ring[local(id)]).fold(0.0, f64::max);
        for &id in f {
            let k = local(id);
            two_rings[k] = two_rings[k].max(reach);
        }
    }
    two_rings
}

/// Unit outward normal of every facet of `surface` (same order as `surface.facets`).
/// A zero-area facet gets `[0, 0, 0]`.
pub fn facet_normals(mesh: &TetMesh, surface: &SurfaceMesh) -> Vec<[f64; 3]> {
    surface
        .facets
        .iter()
        .map(|f| {
            let v = area_vector(mesh, f);
            let l = norm(v);
            if l > 0.0 {
                scale(v, 1.0 / l)
            } else {
                [0.0; 3]
            }
        })
        .collect()
}

/// Per-surface-node geometry for node-to-surface contact, aligned with `SurfaceMesh::nodes`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SurfaceNodeGeometry {
    /// Unit outward normal: the normalised sum of the adjacent facets' area vectors
    /// (area-weighted average of the facet normals).
    pub normals: Vec<[f64; 3]>,
    /// Tributary area (m²): one third of the area of each adjacent facet. Sums to the
    /// surface area.
    pub areas: Vec<f64>,
}

/// Area-weighted outward normals and tributary areas of the surface nodes.
pub fn surface_node_geometry(mesh: &TetMesh, surface: &SurfaceMesh) -> SurfaceNodeGeometry {
    // Dense mesh-node → surface-node map (surface.nodes is ascending, but a dense table
    // avoids a binary search per facet corner).
    let mut slot = vec![u32::MAX; mesh.nodes.len()];
    for (k, &n) in surface.nodes.iter().enumerate() {
        slot[n as usize] = k as u32;
    }
    let m = surface.nodes.len();
    let mut normals = vec![[0.0; 3]; m];
    let mut areas = vec![0.0; m];
    for f in &surface.facets {
        let v = area_vector(mesh, f);
        let a = norm(v) / 3.0;
        for &n in f {
            let k = slot[n as usize] as usize;
            normals[k] = add(normals[k], v);
            areas[k] += a;
        }
    }
    for nrm in normals.iter_mut() {
        let l = norm(*nrm);
        if l > 0.0 {
            *nrm = scale(*nrm, 1.0 / l);
        }
    }
    SurfaceNodeGeometry { normals, areas }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_cube_tets() -> TetMesh {
        // Cube [0,1]³ split into 6 tets around the diagonal 0–7 (Kuhn triangulation).
        let nodes: Vec<[f64; 3]> = (0..8)
            .map(|i| [(i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64])
            .collect();
        let paths = [[1, 3], [1, 5], [2, 3], [2, 6], [4, 5], [4, 6]];
        let mut tets = Vec::new();
        for p in paths {
            let mut t = [0u32, p[0], p[1], 7];
            let [a, b, c, d] = t.map(|i| nodes[i as usize]);
            if crate::math::dot(sub(b, a), cross(sub(c, a), sub(d, a))) < 0.0 {
                t.swap(2, 3);
            }
            tets.push(t);
        }
        TetMesh { nodes, tets }
    }

    #[test]
    fn cube_surface_is_closed_outward_with_unit_normals() {
        let mesh = unit_cube_tets();
        let s = extract_surface(&mesh);
        assert_eq!(s.facets.len(), 12);
        assert_eq!(s.nodes, (0..8).collect::<Vec<u32>>());
        let normals = facet_normals(&mesh, &s);
        for (f, n) in s.facets.iter().zip(&normals) {
            // Outward: the normal points from the cube centre to the facet.
            let c = f.map(|i| mesh.nodes[i as usize]);
            let centroid = scale(add(add(c[0], c[1]), c[2]), 1.0 / 3.0);
            assert!(crate::math::dot(*n, sub(centroid, [0.5; 3])) > 0.0);
            // Axis aligned unit normal.
            let sorted = {
                let mut a = n.map(f64::abs);
                a.sort_by(f64::total_cmp);
                a
            };
            assert!((sorted[2] - 1.0).abs() < 1e-12 && sorted[1] < 1e-12);
        }
        let g = surface_node_geometry(&mesh, &s);
        let total: f64 = g.areas.iter().sum();
        assert!((total - 6.0).abs() < 1e-12);
        // Corner node 0 normal is along -(1,1,1) only if its three faces carry equal area
        // vectors; with the Kuhn split node 0 touches 2 triangles of each adjacent face.
        let n0 = g.normals[0];
        let e = 1.0 / 3f64.sqrt();
        assert!(norm(sub(n0, [-e, -e, -e])) < 1e-12, "{n0:?}");
    }
}
