//! Linear tetrahedral meshes of grains: sphere mesher (uniform, graded, locally refined),
//! surface extraction with outward normals, quality report.
//!
//! Node coordinates are in metres, in the grain's own frame (centre at the origin for
//! generated spheres); the solver places grains in the scene.

/// A linear tetrahedral (tet4) mesh of one grain. Every tet is positively oriented:
/// `(x1−x0)·((x2−x0)×(x3−x0)) > 0`.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TetMesh {
    /// Node positions (m).
    pub nodes: Vec<[f64; 3]>,
    /// Tetrahedra as node indices into `nodes`.
    pub tets: Vec<[u32; 4]>,
}

/// Boundary of a tet mesh: triangles with outward normals (counter-clockwise seen from outside).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SurfaceMesh {
    /// Mesh node ids that lie on the surface, ascending.
    pub nodes: Vec<u32>,
    /// Boundary triangles as mesh node ids, ordered so that
    /// `(x1−x0)×(x2−x0)` points out of the body.
    pub facets: Vec<[u32; 3]>,
}
