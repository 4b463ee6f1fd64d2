//! Element quality report and mesh validation.

use std::fmt;

use super::surface::extract_surface;
use super::{MeshError, TetMesh};
use crate::math::{cross, dot, norm, sub};

/// Shape statistics of a tet mesh. The explicit time step is set by the worst element, so
/// the extremes (minimum dihedral angle, maximum aspect ratio, shortest edge) matter more
/// than averages.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct QualityReport {
    pub elements: usize,
    pub nodes: usize,
    pub surface_facets: usize,
    pub surface_nodes: usize,
    /// Smallest dihedral angle over all tets (degrees; 70.53° for a regular tet).
    pub min_dihedral_deg: f64,
    /// Largest dihedral angle over all tets (degrees).
    pub max_dihedral_deg: f64,
    /// Largest longest-edge / (2√6 · inradius); 1 for a regular tet.
    pub max_aspect_ratio: f64,
    /// Smallest signed tet volume (m³).
    pub min_volume: f64,
    /// Shortest and longest tet edge (m).
    pub min_edge: f64,
    pub max_edge: f64,
    /// Mean length of the distinct surface edges (m).
    pub mean_surface_edge: f64,
}

impl fmt::Display for QualityReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} tets, {} nodes, {} surface facets on {} nodes; dihedral {:.2}°–{:.2}°, max aspect {:.2}, \
             min volume {:.3e} m³, edges {:.3e}–{:.3e} m, mean surface edge {:.3e} m",
            self.elements,
            self.nodes,
            self.surface_facets,
            self.surface_nodes,
            self.min_dihedral_deg,
            self.max_dihedral_deg,
            self.max_aspect_ratio,
            self.min_volume,
            self.min_edge,
            self.max_edge,
            self.mean_surface_edge
        )
    }
}

/// Signed volume of the tet with corners `x`: positive when `(x1−x0)·((x2−x0)×(x3−x0)) > 0`.
#[inline]
pub fn tet_volume(x: &[[f64; 3]; 4]) -> f64 {
    dot(sub(x[1], x[0]), cross(sub(x[2], x[0]), sub(x[3], x[0]))) / 6.0
}

/// Edges of a tet as (node, node, first other node, second other node).
const EDGES: [[usize; 4]; 6] = [
    [0, 1, 2, 3],
    [0, 2, 3, 1],
    [0, 3, 1, 2],
    [1, 2, 0, 3],
    [1, 3, 2, 0],
    [2, 3, 0, 1],
];

/// The six interior dihedral angles (radians) of a tet, one per edge in the order
/// 01, 02, 03, 12, 13, 23. Independent of orientation.
#[inline]
pub fn tet_dihedral_angles(x: &[[f64; 3]; 4]) -> [f64; 6] {
    let mut out = [0.0; 6];
    for (k, &[i, j, p, q]) in EDGES.iter().enumerate() {
        // Angle between the projections of xp−xi and xq−xi on the plane ⟂ to the edge:
        // equal to the angle between e×(xp−xi) and e×(xq−xi).
        let e = sub(x[j], x[i]);
        let u = cross(e, sub(x[p], x[i]));
        let v = cross(e, sub(x[q], x[i]));
        out[k] = norm(cross(u, v)).atan2(dot(u, v));
    }
    out
}

/// Computes the [`QualityReport`] of `mesh` (one pass over the tets, no per-element
/// allocation; the surface is extracted once).
pub fn quality(mesh: &TetMesh) -> QualityReport {
    let surface = extract_surface(mesh);
    let mut r = QualityReport {
        elements: mesh.tets.len(),
        nodes: mesh.nodes.len(),
        surface_facets: surface.facets.len(),
        surface_nodes: surface.nodes.len(),
        min_dihedral_deg: f64::INFINITY,
        max_dihedral_deg: f64::NEG_INFINITY,
        max_aspect_ratio: 0.0,
        min_volume: f64::INFINITY,
        min_edge: f64::INFINITY,
        max_edge: 0.0,
        mean_surface_edge: 0.0,
    };
    let two_sqrt6 = 2.0 * 6f64.sqrt();
    for t in &mesh.tets {
        let x = t.map(|i| mesh.nodes[i as usize]);
        let v = tet_volume(&x);
        r.min_volume = r.min_volume.min(v);
        for a in tet_dihedral_angles(&x) {
            r.min_dihedral_deg = r.min_dihedral_deg.min(a.to_degrees());
            r.max_dihedral_deg = r.max_dihedral_deg.max(a.to_degrees());
        }
        let mut lmax: f64 = 0.0;
        for &[i, j, _, _] in &EDGES {
            let l = norm(sub(x[j], x[i]));
            lmax = lmax.max(l);
            r.min_edge = r.min_edge.min(l);
        }
        r.max_edge = r.max_edge.max(lmax);
        let area: f64 = super::surface::TET_FACES
            .iter()
            .map(|f| 0.5 * norm(cross(sub(x[f[1]], x[f[0]]), sub(x[f[2]], x[f[0]]))))
            .sum();
        let inradius = 3.0 * v.abs() / area;
        let aspect = if inradius > 0.0 {
            lmax / (two_sqrt6 * inradius)
        } else {
            f64::INFINITY
        };
        r.max_aspect_ratio = r.max_aspect_ratio.max(aspect);
    }
    // Each closed-surface edge appears in two facets: count it from the facet where it runs
    // from the smaller to the larger id (exactly once for an oriented closed surface).
    let (mut sum, mut n) = (0.0, 0usize);
    for f in &surface.facets {
        for k in 0..3 {
            let (a, b) = (f[k], f[(k + 1) % 3]);
            if a < b {
                sum += norm(sub(mesh.nodes[b as usize], mesh.nodes[a as usize]));
                n += 1;
            }
        }
    }
    r.mean_surface_edge = if n > 0 { sum / n as f64 } else { 0.0 };
    if mesh.tets.is_empty() {
        r.min_dihedral_deg = 0.0;
        r.max_dihedral_deg = 0.0;
        r.min_volume = 0.0;
        r.min_edge = 0.0;
    }
    r
}

/// Checks that `mesh` can be simulated: at least one tet, finite coordinates, node ids in
/// range and distinct per tet, every tet positively oriented and not degenerate
/// (|V| ≥ 1e-12·(mean edge of the tet)³). The error names the first bad node or element.
pub fn validate(mesh: &TetMesh) -> Result<(), MeshError> {
    if mesh.tets.is_empty() {
        return Err(MeshError::Empty);
    }
    for (i, p) in mesh.nodes.iter().enumerate() {
        if !p.iter().all(|c| c.is_finite()) {
            return Err(MeshError::NonFiniteNode {
                node: i,
                coords: *p,
            });
        }
    }
    let nn = mesh.nodes.len();
    for (e, t) in mesh.tets.iter().enumerate() {
        for (k, &n) in t.iter().enumerate() {
            if n as usize >= nn {
                return Err(MeshError::NodeOutOfRange {
                    element: e,
                    node: n,
                    nnodes: nn,
                });
            }
            if t[..k].contains(&n) {
                return Err(MeshError::RepeatedNode {
                    element: e,
                    node: n,
                });
            }
        }
        let x = t.map(|i| mesh.nodes[i as usize]);
        let volume = tet_volume(&x);
        let mean_edge = EDGES
            .iter()
            .map(|&[i, j, _, _]| norm(sub(x[j], x[i])))
            .sum::<f64>()
            / 6.0;
        if volume.abs() < 1e-12 * mean_edge.powi(3) {
            return Err(MeshError::DegenerateElement {
                element: e,
                volume,
                mean_edge,
            });
        }
        if volume < 0.0 {
            return Err(MeshError::InvertedElement { element: e, volume });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn regular_tet() -> TetMesh {
        let s = 1.0 / 2f64.sqrt();
        // Alternate corners of a cube: edge √2 → scaled to edge 1.
        let nodes = vec![[s, s, s], [s, -s, -s], [-s, s, -s], [-s, -s, s]]
            .into_iter()
            .map(|p| p.map(|c| c * 0.5))
            .collect();
        let mut m = TetMesh {
            nodes,
            tets: vec![[0, 1, 2, 3]],
        };
        let x = m.tets[0].map(|i| m.nodes[i as usize]);
        if tet_volume(&x) < 0.0 {
            m.tets[0].swap(2, 3);
        }
        m
    }

    #[test]
    fn regular_tet_quality() {
        let m = regular_tet();
        let q = quality(&m);
        let dihedral = (1.0f64 / 3.0).acos().to_degrees();
        assert!((dihedral - 70.528_779).abs() < 1e-5);
        assert!(
            (q.min_dihedral_deg - dihedral).abs() < 1e-9,
            "{}",
            q.min_dihedral_deg
        );
        assert!((q.max_dihedral_deg - dihedral).abs() < 1e-9);
        assert!(
            (q.max_aspect_ratio - 1.0).abs() < 1e-12,
            "{}",
            q.max_aspect_ratio
        );
        let a = 1.0;
        assert!((q.min_edge - a).abs() < 1e-12 && (q.max_edge - a).abs() < 1e-12);
        assert!((q.min_volume - a.powi(3) / (6.0 * 2f64.sqrt())).abs() < 1e-15);
        assert!((q.mean_surface_edge - a).abs() < 1e-12);
        assert_eq!(
            (q.elements, q.nodes, q.surface_facets, q.surface_nodes),
            (1, 4, 4, 4)
        );
        validate(&m).unwrap();
    }

    #[test]
    fn dihedral_angles_of_a_corner_tet() {
        // Right-corner tet: three 90° dihedrals at the corner edges.
        let x = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
        ];
        let a = tet_dihedral_angles(&x).map(f64::to_degrees);
        for corner in &a[..3] {
            assert!((corner - 90.0).abs() < 1e-12);
        }
        for far in &a[3..] {
            assert!((far - (1.0f64 / 3f64.sqrt()).acos().to_degrees()).abs() < 1e-12);
        }
    }

    #[test]
    fn validate_catches_bad_elements() {
        let mut m = regular_tet();
        m.tets[0].swap(2, 3);
        match validate(&m) {
            Err(MeshError::InvertedElement { element: 0, volume }) => assert!(volume < 0.0),
            other => panic!("expected inverted, got {other:?}"),
        }
        assert!(validate(&m)
            .unwrap_err()
            .to_string()
            .starts_with("element 0: inverted"));

        // Degenerate: fourth node in the plane of the first three (second element).
        let mut m = regular_tet();
        let x = m.tets[0].map(|i| m.nodes[i as usize]);
        let mid = [
            (x[0][0] + x[1][0] + x[2][0]) / 3.0,
            (x[0][1] + x[1][1] + x[2][1]) / 3.0,
            (x[0][2] + x[1][2] + x[2][2]) / 3.0,
        ];
        m.nodes.push(mid);
        let t0 = m.tets[0];
        m.tets.push([t0[0], t0[1], t0[2], 4]);
        match validate(&m) {
            Err(MeshError::DegenerateElement {
                element: 1, volume, ..
            }) => assert!(volume.abs() < 1e-15),
            other => panic!("expected degenerate, got {other:?}"),
        }

        let mut m = regular_tet();
        m.tets.push([0, 1, 2, 9]);
        assert!(matches!(
            validate(&m),
            Err(MeshError::NodeOutOfRange {
                element: 1,
                node: 9,
                nnodes: 4
            })
        ));
        let mut m = regular_tet();
        m.tets[0][3] = m.tets[0][1];
        assert!(matches!(
            validate(&m),
            Err(MeshError::RepeatedNode { element: 0, .. })
        ));
        let mut m = regular_tet();
        m.nodes[2][1] = f64::NAN;
        assert!(matches!(
            validate(&m),
            Err(MeshError::NonFiniteNode { node: 2, .. })
        ));
        assert_eq!(validate(&TetMesh::default()), Err(MeshError::Empty));
    }
}
