//! Element and node order for memory locality.
//!
//! The explicit step is bound by memory traffic: each element gathers the positions of its
//! four nodes and scatters four forces back. Meshers emit nodes and tets in the order they
//! are generated (lattice levels, TetGen's insertion order), so neighbouring elements sit
//! far apart in memory and every gather misses the cache. Sorting the tets along a Morton
//! (Z-order) curve of their centroids and numbering nodes in order of first use puts
//! elements that share nodes next to each other, and the nodes they share in the same
//! cache lines. The geometry and every tet's orientation are unchanged.

use super::{compact_cells, TetMesh};

/// Bits per axis of the Morton key (3 × 21 = 63 bits).
const MORTON_BITS: u32 = 21;

/// The same mesh with tets in Morton order of their centroids and nodes in order of first
/// use by those tets. Deterministic: ties keep the original order. Nodes used by no tet
/// are dropped (no mesher emits any).
pub fn order_for_locality(mesh: TetMesh) -> TetMesh {
    if mesh.tets.is_empty() {
        return mesh;
    }
    let (lo, hi) = bounding_box(&mesh.nodes);
    let scale: [f64; 3] = std::array::from_fn(|i| {
        let span = hi[i] - lo[i];
        if span > 0.0 {
            ((1u64 << MORTON_BITS) - 1) as f64 / span
        } else {
            0.0
        }
    });
    let mut keyed: Vec<(u64, [u32; 4])> = mesh
        .tets
        .iter()
        .map(|t| {
            let mut c = [0.0; 3];
            for &n in t {
                let p = mesh.nodes[n as usize];
                for i in 0..3 {
                    c[i] += 0.25 * p[i];
                }
            }
            let cell: [u64; 3] = std::array::from_fn(|i| ((c[i] - lo[i]) * scale[i]) as u64);
            (morton_key(cell), *t)
        })
        .collect();
    // stable: equal keys keep their original order
    keyed.sort_by_key(|&(key, _)| key);
    let (nodes, tets, _) = compact_cells(&mesh.nodes, keyed.into_iter().map(|(_, t)| t));
    TetMesh { nodes, tets }
}

fn bounding_box(points: &[[f64; 3]]) -> ([f64; 3], [f64; 3]) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in points {
        for i in 0..3 {
            lo[i] = lo[i].min(p[i]);
            hi[i] = hi[i].max(p[i]);
        }
    }
    (lo, hi)
}

/// Interleaves the low 21 bits of three cell coordinates (x in bit 0, y in bit 1, …).
fn morton_key(cell: [u64; 3]) -> u64 {
    fn spread(v: u64) -> u64 {
        // the classic bit-spreading sequence: each step halves the block size
        let mut x = v & 0x1f_ffff;
        x = (x | x << 32) & 0x001f_0000_0000_ffff;
        x = (x | x << 16) & 0x001f_0000_ff00_00ff;
        x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
        x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
        x = (x | x << 2) & 0x1249_2492_4924_9249;
        x
    }
    spread(cell[0]) | spread(cell[1]) << 1 | spread(cell[2]) << 2
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::block::mesh_block;

    #[test]
    fn morton_key_interleaves_bits() {
        assert_eq!(morton_key([1, 0, 0]), 0b001);
        assert_eq!(morton_key([0, 1, 0]), 0b010);
        assert_eq!(morton_key([0, 0, 1]), 0b100);
        assert_eq!(morton_key([3, 0, 0]), 0b001_001);
        let all = (1u64 << MORTON_BITS) - 1;
        assert_eq!(morton_key([all, all, all]), (1u64 << 63) - 1);
    }

    #[test]
    fn reordering_keeps_every_tet_and_its_orientation() {
        let mesh = mesh_block([1e-3, 2e-3, 1.5e-3], [4, 5, 3]);
        let ordered = order_for_locality(mesh.clone());
        assert_eq!(ordered.nodes.len(), mesh.nodes.len());
        assert_eq!(ordered.tets.len(), mesh.tets.len());
        let as_points = |m: &TetMesh| {
            let mut v: Vec<[u64; 12]> = m
                .tets
                .iter()
                .map(|t| {
                    let p = t.map(|n| m.nodes[n as usize]);
                    std::array::from_fn(|k| p[k / 3][k % 3].to_bits())
                })
                .collect();
            v.sort();
            v
        };
        // same tets, same corner order (hence orientation), same coordinates
        assert_eq!(as_points(&ordered), as_points(&mesh));
    }

    #[test]
    fn reordered_neighbours_share_nodes_more_often() {
        // mean |node index spread| within a tet drops: the point of the exercise
        let mesh = mesh_block([1e-3; 3], [12, 12, 12]);
        let spread = |m: &TetMesh| {
            m.tets
                .iter()
                .map(|t| (t.iter().max().unwrap() - t.iter().min().unwrap()) as f64)
                .sum::<f64>()
                / m.tets.len() as f64
        };
        let mut shuffled = mesh.clone();
        // a fixed scramble of the tet order, as a mesher's insertion order would give
        let n = shuffled.tets.len();
        shuffled.tets = (0..n).map(|k| mesh.tets[(k * 7919) % n]).collect();
        let (nodes, tets, _) = compact_cells(&shuffled.nodes, shuffled.tets.iter().copied());
        let scrambled = TetMesh { nodes, tets };
        let ordered = order_for_locality(scrambled.clone());
        assert!(
            spread(&ordered) < 0.25 * spread(&scrambled),
            "{} vs {}",
            spread(&ordered),
            spread(&scrambled)
        );
    }
}
