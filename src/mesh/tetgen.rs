//! Volume meshing of a closed triangulated surface with TetGen (through `tritet`).
//!
//! `tritet::Tetgen::generate_mesh` runs TetGen with the switches `pzAfQ` + `a` (per-region
//! volume constraints when no global value is given) + `q<ratio>`: tritet passes its last
//! argument straight after `q`, which TetGen reads as the maximum radius–edge ratio (not an
//! angle). TetGen's mesh optimisation (`-O2/7`, max dihedral 165° under `-q`) runs by default.
//!
//! TetGen keeps process-wide state (robust predicates), so all calls are serialised through
//! one mutex. Its C++ exceptions are caught by tritet and — for `throw int` — reported as
//! success with an empty output, so an empty result is treated as a failure here.

use std::sync::Mutex;

use super::{cross, dot, sub, MeshError, TetMesh};

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
/// 1.4–2.0 is typical). Returned tets are positively oriented.
pub(crate) fn tetrahedralize(
    points: &[[f64; 3]],
    facets: &[[u32; 3]],
    regions: &[Region],
    radius_edge_ratio: f64,
) -> Result<TetMesh, MeshError> {
    let err = |e: &str| MeshError::TetGen(e.to_string());
    let delaunay = std::env::var("MUFE_DELAUNAY").is_ok();
    let mut tg = if delaunay {
        tritet::Tetgen::new(points.len(), None, None, None).map_err(err)?
    } else {
        tritet::Tetgen::new(points.len(), Some(vec![3; facets.len()]), Some(regions.len()), None).map_err(err)?
    };
    for (i, p) in points.iter().enumerate() {
        // Marker 1 is reserved by TetGen for boundary points; 0 = none.
        tg.set_point(i, 0, p[0], p[1], p[2]).map_err(err)?;
    }
    for (f, tri) in facets.iter().enumerate().filter(|_| !delaunay) {
        for (m, &p) in tri.iter().enumerate() {
            tg.set_facet_point(f, m, p as usize).map_err(err)?;
        }
    }
    for (i, r) in regions.iter().enumerate().filter(|_| !delaunay) {
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

    let (nodes, mut tets) = {
        let _guard = TETGEN_LOCK
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner());
        if delaunay {
            tg.generate_delaunay(false).map_err(err)?;
        } else {
            tg.generate_mesh(false, false, None, Some(radius_edge_ratio)).map_err(err)?;
        }
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
        (nodes, tets)
    };

    // Positive orientation: swap the last two nodes of negatively oriented tets.
    for t in tets.iter_mut() {
        let [a, b, c, d] = t.map(|i| nodes[i as usize]);
        if dot(sub(b, a), cross(sub(c, a), sub(d, a))) < 0.0 {
            t.swap(2, 3);
        }
    }
    Ok(TetMesh { nodes, tets })
}
