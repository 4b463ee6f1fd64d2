//! Volume meshing of a closed triangulated surface with TetGen (through `tritet`).
//!
//! `tritet::Tetgen::generate_mesh` runs TetGen with the switches `pzAfQ` + `a` (per-region
//! volume constraints when no global value is given) + `q<ratio>`: tritet passes its last
//! argument straight after `q`, which TetGen reads as the maximum radius–edge ratio (not an
//! angle). TetGen's mesh optimisation (`-O2/7`, max dihedral 165° under `-q`) runs by
//! default. Points that are on no facet are kept as isolated interior vertices.
//!
//! Things to know when feeding it (no `-Y`: TetGen may split the surface): every facet edge
//! is a segment, split if any vertex lies in its diametral ball (so surface triangles must be
//! acute); a facet is split if a vertex lies in its circumball, or if its area^1.5 exceeds
//! the volume bound of an adjacent region (so volume bounds must be loose or absent near the
//! surface).
//!
//! TetGen keeps process-wide state (robust predicates), so all calls are serialised through
//! one mutex. Its C++ exceptions are caught by tritet and — for `throw int` — reported as
//! success with an empty output (after printing `status = N`), so an empty result is treated
//! as a failure here.

use std::sync::Mutex;

use super::{MeshError, TetMesh};
use crate::math::{cross, dot, sub};

/// Serialises every TetGen call in the process (TetGen is not thread-safe).
static TETGEN_LOCK: Mutex<()> = Mutex::new(());

/// A region of the PLC: a point strictly inside it and the maximum tet volume there.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Region {
    pub point: [f64; 3],
    pub marker: i32,
    pub max_volume: Option<f64>,
}

/// Tetrahedralises the closed PLC made of triangular `facets` over `points`. Coordinates
/// should be of order one (the caller scales), because TetGen's tolerances are relative and
/// volume constraints pass through text. `radius_edge_ratio` is TetGen's `q` bound (> 1.0;
/// 1.4–2.0 is typical); `max_volume` a bound on every tet's volume (TetGen `-a<V>`).
/// Returned tets are positively oriented.
pub(crate) fn tetrahedralize(
    points: &[[f64; 3]],
    facets: &[[u32; 3]],
    regions: &[Region],
    radius_edge_ratio: f64,
    max_volume: Option<f64>,
) -> Result<TetMesh, MeshError> {
    tetrahedralize_marked(points, facets, regions, radius_edge_ratio, max_volume).map(|(m, _)| m)
}

/// [`tetrahedralize`], also returning each tet's region marker (0: in no region).
pub(crate) fn tetrahedralize_marked(
    points: &[[f64; 3]],
    facets: &[[u32; 3]],
    regions: &[Region],
    radius_edge_ratio: f64,
    max_volume: Option<f64>,
) -> Result<(TetMesh, Vec<i32>), MeshError> {
    let err = |e: &str| MeshError::TetGen(e.to_string());
    let mut tg = tritet::Tetgen::new(
        points.len(),
        Some(vec![3; facets.len()]),
        (!regions.is_empty()).then_some(regions.len()),
        None,
    )
    .map_err(err)?;
    for (i, p) in points.iter().enumerate() {
        // Marker 1 is reserved by TetGen for boundary points; 0 = none.
        tg.set_point(i, 0, p[0], p[1], p[2]).map_err(err)?;
    }
    for (f, tri) in facets.iter().enumerate() {
        for (m, &p) in tri.iter().enumerate() {
            tg.set_facet_point(f, m, p as usize).map_err(err)?;
        }
    }
    for (i, r) in regions.iter().enumerate() {
        tg.set_region(
            i,
            r.marker,
            r.point[0],
            r.point[1],
            r.point[2],
            r.max_volume,
        )
        .map_err(err)?;
    }

    let (nodes, mut tets, markers) = {
        let _guard = TETGEN_LOCK
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner());
        tg.generate_mesh(false, false, max_volume, Some(radius_edge_ratio))
            .map_err(err)?;
        let npoint = tg.out_npoint();
        let ncell = tg.out_ncell();
        if ncell == 0 || npoint < 4 {
            return Err(MeshError::TetGen(format!(
                "no tetrahedra produced from {} points and {} facets (self-intersecting or too fine input surface?)",
                points.len(),
                facets.len()
            )));
        }
        if tg.out_cell_npoint() != 4 {
            return Err(MeshError::TetGen(format!(
                "expected 4-node tets, got {}",
                tg.out_cell_npoint()
            )));
        }
        let nodes: Vec<[f64; 3]> = (0..npoint)
            .map(|i| [tg.out_point(i, 0), tg.out_point(i, 1), tg.out_point(i, 2)])
            .collect();
        let mut tets: Vec<[u32; 4]> = Vec::with_capacity(ncell);
        for c in 0..ncell {
            let mut t = [0u32; 4];
            for (m, slot) in t.iter_mut().enumerate() {
                let p = tg.out_cell_point(c, m);
                if p >= npoint {
                    return Err(MeshError::TetGen(format!(
                        "tet {c} refers to node {p} of {npoint}"
                    )));
                }
                *slot = p as u32;
            }
            tets.push(t);
        }
        let markers: Vec<i32> = (0..ncell).map(|c| tg.out_cell_marker(c)).collect();
        (nodes, tets, markers)
    };

    // Positive orientation: swap the last two nodes of negatively oriented tets.
    for t in tets.iter_mut() {
        let [a, b, c, d] = t.map(|i| nodes[i as usize]);
        if dot(sub(b, a), cross(sub(c, a), sub(d, a))) < 0.0 {
            t.swap(2, 3);
        }
    }
    Ok((TetMesh { nodes, tets }, markers))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{quality, tet_volume};

    fn tet_plc(offset: [f64; 3]) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
        let o = offset;
        let pts = vec![
            o,
            [o[0] + 1.0, o[1], o[2]],
            [o[0], o[1] + 1.0, o[2]],
            [o[0], o[1], o[2] + 1.0],
        ];
        (pts, vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    }

    #[test]
    fn meshes_a_tetrahedron_with_positive_tets() {
        let (pts, facets) = tet_plc([0.0; 3]);
        let region = Region {
            point: [0.1; 3],
            marker: 1,
            max_volume: Some(0.01),
        };
        let m = tetrahedralize(&pts, &facets, &[region], 2.0, None).unwrap();
        assert!(m.tets.len() > 10);
        let v: f64 = m
            .tets
            .iter()
            .map(|t| tet_volume(&t.map(|i| m.nodes[i as usize])))
            .sum();
        assert!((v - 1.0 / 6.0).abs() < 1e-12);
        for t in &m.tets {
            assert!(tet_volume(&t.map(|i| m.nodes[i as usize])) > 0.0);
        }
        assert!(quality(&m).min_dihedral_deg > 1.0);
    }

    #[test]
    fn rejects_intersecting_facets_with_an_error() {
        // Two interpenetrating tetrahedra: a self-intersecting PLC.
        let (mut pts, mut facets) = tet_plc([0.0; 3]);
        let (p2, f2) = tet_plc([0.2; 3]);
        pts.extend(p2);
        facets.extend(f2.iter().map(|f| f.map(|i| i + 4)));
        let region = Region {
            point: [0.05; 3],
            marker: 1,
            max_volume: None,
        };
        let e = tetrahedralize(&pts, &facets, &[region], 2.0, None).unwrap_err();
        assert!(matches!(e, MeshError::TetGen(_)));
        assert!(e.to_string().starts_with("TetGen failed: "), "{e}");
    }
}
