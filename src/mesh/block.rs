//! Structured rectangular blocks: nx×ny×nz cubes split into 6 tetrahedra each by the
//! Freudenthal (Kuhn) decomposition along the main diagonal. Every cube uses the same
//! diagonal direction, so neighbouring cubes share face triangulations (conforming).
//! Used for bars (wave tests), blocks (sliding tests) and patch tests.

use super::TetMesh;

/// Meshes the box [0, size] with `divisions` cells per axis.
pub fn mesh_block(size: [f64; 3], divisions: [usize; 3]) -> TetMesh {
    let [nx, ny, nz] = divisions;
    let node_id = |i: usize, j: usize, k: usize| (i + (nx + 1) * (j + (ny + 1) * k)) as u32;
    let mut nodes = Vec::with_capacity((nx + 1) * (ny + 1) * (nz + 1));
    for k in 0..=nz {
        for j in 0..=ny {
            for i in 0..=nx {
                nodes.push([
                    size[0] * i as f64 / nx as f64,
                    size[1] * j as f64 / ny as f64,
                    size[2] * k as f64 / nz as f64,
                ]);
            }
        }
    }
    const PERMUTATIONS: [[usize; 3]; 6] = [
        [0, 1, 2],
        [0, 2, 1],
        [1, 0, 2],
        [1, 2, 0],
        [2, 0, 1],
        [2, 1, 0],
    ];
    let mut tets = Vec::with_capacity(6 * nx * ny * nz);
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                for perm in PERMUTATIONS {
                    let mut corner = [i, j, k];
                    let mut tet = [node_id(i, j, k); 4];
                    for (step, axis) in perm.iter().enumerate() {
                        corner[*axis] += 1;
                        tet[step + 1] = node_id(corner[0], corner[1], corner[2]);
                    }
                    if super::tet_volume(&tet.map(|n| nodes[n as usize])) < 0.0 {
                        tet.swap(2, 3);
                    }
                    tets.push(tet);
                }
            }
        }
    }
    TetMesh { nodes, tets }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn block_volume_and_conformity() {
        let m = mesh_block([2.0, 1.0, 0.5], [4, 3, 2]);
        assert_eq!(m.tets.len(), 6 * 24);
        let v: f64 = m
            .tets
            .iter()
            .map(|t| super::super::tet_volume(&t.map(|n| m.nodes[n as usize])))
            .sum();
        assert!((v - 1.0).abs() < 1e-12);
        assert!(m
            .tets
            .iter()
            .all(|t| super::super::tet_volume(&t.map(|n| m.nodes[n as usize])) > 0.0));
        // conforming: the boundary is exactly the box surface (area 2(2·1 + 2·0.5 + 1·0.5) = 7)
        let s = crate::mesh::extract_surface(&m);
        let area: f64 = s
            .facets
            .iter()
            .map(|f| {
                let [a, b, c] = f.map(|n| m.nodes[n as usize]);
                let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
                let w = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
                let cr = [
                    u[1] * w[2] - u[2] * w[1],
                    u[2] * w[0] - u[0] * w[2],
                    u[0] * w[1] - u[1] * w[0],
                ];
                0.5 * (cr[0] * cr[0] + cr[1] * cr[1] + cr[2] * cr[2]).sqrt()
            })
            .sum();
        assert!((area - 7.0).abs() < 1e-12, "area {area}");
    }
}
