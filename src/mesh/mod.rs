//! Linear tetrahedral meshes of grains: sphere mesher (uniform, graded, locally refined),
//! surface extraction with outward normals, quality report.
//!
//! Node coordinates are in metres, in the grain's own frame (centre at the origin for
//! generated spheres); the solver places grains in the scene.
//!
//! Pipeline of [`mesh_sphere`] (details in `sphere.rs` and [`surface_refine`]):
//! 1. [`surface_refine`]: geodesic icosphere at the seeding, conforming longest-edge (Rivara
//!    LEPP) bisection where refinement patches ask for smaller elements, flips to the convex
//!    hull, and relaxation of the refined zone to strictly acute triangles;
//! 2. the interior is seeded with nested body-centred cubic lattices following a 3D size
//!    field (seeding; core size below a graded band; refinement patches);
//! 3. TetGen (private `tetgen` module) tetrahedralises the surface with the lattice points
//!    as isolated vertices under a radius–edge bound, keeping the surface exactly as
//!    triangulated; tets are re-oriented to positive volume;
//! 4. [`improve`]: the interior nodes of slivers are moved to raise the smallest element
//!    height ([`smooth`]), interior edges and faces are flipped where that raises it
//!    further ([`flip`]), and the nodes are moved again; the surface stays exactly as
//!    triangulated. Then the mesh is checked with [`validate`].
//!
//! [`extract_surface`], [`facet_normals`] and [`surface_node_geometry`] give contact what it
//! needs; [`quality()`] summarises element shape (the explicit time step depends on the worst
//! element, so the minimum dihedral angle matters).

pub mod block;
pub mod collapse;
pub mod ellipsoid;
pub mod flip;
pub mod import;
pub mod improve;
pub mod joint;
mod lattice;
pub mod locality;
mod quality;
pub mod smooth;
mod sphere;
mod surface;
pub mod surface_refine;
mod tetgen;

pub use quality::{quality, tet_dihedral_angles, tet_volume, validate, QualityReport};
pub use sphere::{
    fcc_contact_directions, mesh_sphere, GradedBand, LocalRefinement, SphereMeshSpec,
};
pub use surface::{
    extract_surface, facet_normals, longest_edge_within_two_rings, mean_edge_at_nodes,
    surface_node_geometry, SurfaceNodeGeometry,
};

/// A linear tetrahedral (tet4) mesh of one grain. Every tet is positively oriented:
/// `(x1−x0)·((x2−x0)×(x3−x0)) > 0`.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TetMesh {
    /// Node positions (m).
    pub nodes: Vec<[f64; 3]>,
    /// Tetrahedra as node indices into `nodes`.
    pub tets: Vec<[u32; 4]>,
}

/// The points used by `cells` (triangles or tets over `points`), renumbered densely in
/// order of first use: (those points, the cells over them, each new point's old index).
pub fn compact_cells<const N: usize>(
    points: &[[f64; 3]],
    cells: impl IntoIterator<Item = [u32; N]>,
) -> (Vec<[f64; 3]>, Vec<[u32; N]>, Vec<u32>) {
    let mut new_id = vec![u32::MAX; points.len()];
    let (mut used, mut out, mut old) = (Vec::new(), Vec::new(), Vec::new());
    for cell in cells {
        out.push(cell.map(|v| {
            if new_id[v as usize] == u32::MAX {
                new_id[v as usize] = used.len() as u32;
                used.push(points[v as usize]);
                old.push(v);
            }
            new_id[v as usize]
        }));
    }
    (used, out, old)
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

/// Everything that can go wrong while building or checking a mesh. Each message is one line
/// naming the spec field or the element/node concerned.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MeshError {
    /// A field of a [`SphereMeshSpec`] is out of range (`field` is the dotted path,
    /// e.g. `graded.band_depth`, `refine[1].direction`).
    #[error("{field}: {message}")]
    InvalidSpec { field: String, message: String },
    /// The spec would need more surface triangles than the mesher accepts.
    #[error("{field}: the surface would need more than {limit} triangles; use a larger seeding")]
    TooLarge { field: String, limit: usize },
    /// TetGen rejected the input or produced an unusable mesh.
    #[error("TetGen failed: {0}")]
    TetGen(String),
    /// A surface file is unreadable or defective: the error names that file and the item
    /// (`facet 17`, `line 4`).
    #[error("{0}")]
    File(crate::error::InputError),
    /// The mesh has no elements.
    #[error("mesh has no elements")]
    Empty,
    /// A node coordinate is NaN or infinite.
    #[error("node {node}: non-finite coordinate {coords:?}")]
    NonFiniteNode { node: usize, coords: [f64; 3] },
    /// An element refers to a node id that does not exist.
    #[error("element {element}: node id {node} out of range (mesh has {nnodes} nodes)")]
    NodeOutOfRange {
        element: usize,
        node: u32,
        nnodes: usize,
    },
    /// An element lists the same node twice.
    #[error("element {element}: node {node} appears twice")]
    RepeatedNode { element: usize, node: u32 },
    /// An element has negative volume (nodes ordered clockwise).
    #[error("element {element}: inverted, volume {volume:e} m³ < 0")]
    InvertedElement { element: usize, volume: f64 },
    /// An element is flat: |volume| < 1e-12·(mean edge)³.
    #[error("element {element}: degenerate, volume {volume:e} m³ (mean edge {mean_edge:e} m)")]
    DegenerateElement {
        element: usize,
        volume: f64,
        mean_edge: f64,
    },
}

impl MeshError {
    /// The spec field or mesh item the error is about (`radius`, `element 17`, `node 3`), for
    /// building an [`crate::error::InputError`] with the file name added by the caller.
    pub fn item(&self) -> String {
        match self {
            MeshError::InvalidSpec { field, .. } | MeshError::TooLarge { field, .. } => {
                field.clone()
            }
            MeshError::TetGen(_) | MeshError::Empty => String::new(),
            MeshError::File(e) => e.item.clone(),
            MeshError::NonFiniteNode { node, .. } => format!("node {node}"),
            MeshError::NodeOutOfRange { element, .. }
            | MeshError::RepeatedNode { element, .. }
            | MeshError::InvertedElement { element, .. }
            | MeshError::DegenerateElement { element, .. } => format!("element {element}"),
        }
    }

    /// The input error of grain `grain`'s shape in `scene_file`; a surface file's own
    /// defect stays an error of that file.
    pub fn for_grain(&self, scene_file: &str, grain: usize) -> crate::error::InputError {
        match self {
            MeshError::File(e) => e.clone(),
            other => crate::error::InputError::new(
                scene_file,
                format!("grains[{grain}].shape"),
                other.to_string(),
            ),
        }
    }

    /// Converts to the user-facing input error (exit code 2) of `file`. The item is the
    /// `prefix` (e.g. `grains[3].mesh`) joined with [`MeshError::item`].
    pub fn to_input_error(&self, file: &str, prefix: &str) -> crate::error::InputError {
        let item = self.item();
        let item = match (prefix.is_empty(), item.is_empty()) {
            (true, _) => item,
            (false, true) => prefix.to_string(),
            (false, false) if item.starts_with("element") || item.starts_with("node") => {
                format!("{prefix}: {item}")
            }
            (false, false) => format!("{prefix}.{item}"),
        };
        let message = match self {
            MeshError::InvalidSpec { message, .. } => message.clone(),
            MeshError::File(e) => return e.clone(),
            other => {
                // Drop the leading "item: " that Display repeats.
                let full = other.to_string();
                let own = self.item();
                match full.strip_prefix(&format!("{own}: ")) {
                    Some(rest) => rest.to_string(),
                    None => full,
                }
            }
        };
        crate::error::InputError::new(file, item, message)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn error_messages_name_the_item() {
        let e = MeshError::InvertedElement {
            element: 17,
            volume: -1e-12,
        };
        assert_eq!(e.to_string(), "element 17: inverted, volume -1e-12 m³ < 0");
        let ie = e.to_input_error("scene.toml", "grains[2].mesh");
        assert_eq!(ie.item, "grains[2].mesh: element 17");
        assert_eq!(ie.message, "inverted, volume -1e-12 m³ < 0");
        let e = MeshError::InvalidSpec {
            field: "seeding".into(),
            message: "must be > 0, got -1".into(),
        };
        assert_eq!(e.to_string(), "seeding: must be > 0, got -1");
        let ie = e.to_input_error("scene.toml", "grains[2].mesh");
        assert_eq!(ie.item, "grains[2].mesh.seeding");
        assert_eq!(
            ie.to_string(),
            "scene.toml: grains[2].mesh.seeding: must be > 0, got -1"
        );
        assert!(!MeshError::TetGen("x".into()).to_string().contains('\n'));
    }
}
