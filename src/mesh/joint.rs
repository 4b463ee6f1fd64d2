//! Conforming meshes of grains that touch over shared faces: one TetGen run over the union
//! of their surfaces (each shared triangle once), one region per grain, then one mesh per
//! grain cut out of it by region.
//!
//! Why one run: TetGen splits surface triangles as it refines (no `-Y` through `tritet`).
//! Meshed one by one, two touching grains would get different Steiner points on their
//! common face, each lying on the *flat* triangles of the other — but contact sees the
//! other grain's curved patches, which bulge off those triangles, so the run would start
//! with spurious overlaps. Meshed together, a shared triangle is split once and both grains
//! get the same nodes on it, which lie on both grains' patches (a patch passes through its
//! corners): the contact starts closed and stress-free.

use rayon::prelude::*;

use super::tetgen::{tetrahedralize_marked, Region};
use super::{MeshError, TetMesh};
use crate::math::{norm, sub};

/// Meshes the closed surfaces given by `facets` over `points` (shared faces listed once),
/// `inside[g]` a point strictly inside grain g, with tets of at most a regular tet of edge
/// `seeding` and the sphere mesher's radius–edge bound; returns one mesh per grain. Input
/// points keep their exact coordinates. No interior smoothing: on the virtual sand it
/// tripled the meshing time and left the stable step and the mass scaling unchanged (the
/// worst elements touch the surface, which smoothing must not move).
pub fn mesh_touching(
    points: &[[f64; 3]],
    facets: &[[u32; 3]],
    inside: &[[f64; 3]],
    seeding: f64,
) -> Result<Vec<TetMesh>, MeshError> {
    // TetGen's tolerances are relative: order-one coordinates.
    let (lo, hi) = super::import::bounding_box(points);
    let centre = [0, 1, 2].map(|k| 0.5 * (lo[k] + hi[k]));
    let size = (0..3)
        .map(|k| 0.5 * (hi[k] - lo[k]))
        .fold(0.0, f64::max)
        .max(f64::MIN_POSITIVE);
    let to_unit = |p: [f64; 3]| [0, 1, 2].map(|k| (p[k] - centre[k]) / size);
    let scaled: Vec<[f64; 3]> = points.iter().map(|&p| to_unit(p)).collect();
    let h = seeding / size;
    let max_volume = h * h * h / (6.0 * std::f64::consts::SQRT_2);
    let regions: Vec<Region> = inside
        .iter()
        .enumerate()
        .map(|(g, &p)| Region {
            point: to_unit(p),
            marker: g as i32 + 1,
            max_volume: Some(max_volume),
        })
        .collect();
    let (mesh, markers) = tetrahedralize_marked(
        &scaled,
        facets,
        &regions,
        super::sphere::RADIUS_EDGE_RATIO,
        Some(max_volume),
    )?;
    // TetGen numbers the input points first; give them back their exact coordinates.
    let nodes: Vec<[f64; 3]> = mesh
        .nodes
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let back = [0, 1, 2].map(|k| p[k] * size + centre[k]);
            match points.get(i) {
                Some(&q) if norm(sub(q, back)) <= 1e-9 * size => q,
                _ => back,
            }
        })
        .collect();
    // One pass to bucket the tets by region (0: a pore enclosed by grains, dropped).
    let mut by_grain: Vec<Vec<[u32; 4]>> = vec![Vec::new(); inside.len()];
    for (tet, &marker) in mesh.tets.iter().zip(&markers) {
        if marker >= 1 && (marker as usize) <= inside.len() {
            by_grain[marker as usize - 1].push(*tet);
        }
    }
    let out = by_grain
        .into_par_iter()
        .enumerate()
        .map(|(g, tets)| {
            if tets.is_empty() {
                return Err(MeshError::TetGen(format!(
                    "grain {g}: no tetrahedra in its region (is its inside point inside it?)"
                )));
            }
            let (nodes, tets, _) = super::compact_cells(&nodes, tets);
            let m = TetMesh { nodes, tets };
            super::validate(&m)?;
            Ok(m)
        })
        .collect::<Result<Vec<TetMesh>, MeshError>>()?;
    Ok(out)
}
