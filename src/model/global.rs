//! The whole scene's mesh layout, identical on every rank: each grain's mesh (distinct
//! shapes meshed once), global node and element offsets, surface sizes and bounding
//! spheres. It sizes the partition, the results file and the ghost margin.

use super::assemble::mesh_shape;
use super::decomposition::{Decomposition, GhostRef, GrainBound, PlanCell};
use super::periodic::PeriodicCell;
use crate::error::InputError;
use crate::mesh::{self, TetMesh};
use crate::scene::LoadedScene;
use std::collections::BTreeMap;
use std::sync::Arc;

/// The whole scene's mesh layout, identical on every rank (each distinct shape is meshed
/// once per rank; meshing is deterministic).
#[derive(Debug, Clone)]
pub struct GlobalMesh {
    /// Mesh of each grain (shared between grains of the same shape), grain frame.
    pub meshes: Vec<Arc<TetMesh>>,
    /// First global node / element of each grain, plus the totals at the end.
    pub node_offset: Vec<usize>,
    pub element_offset: Vec<usize>,
    /// Surface node count of each grain.
    pub surface_nodes: Vec<usize>,
    /// Bounding sphere of each grain at t = 0 (world frame).
    pub bounds: Vec<GrainBound>,
}

impl GlobalMesh {
    pub fn build(loaded: &LoadedScene) -> Result<Self, InputError> {
        let scene = &loaded.scene;
        super::assemble::premesh_surfaces(loaded);
        let mut cache: BTreeMap<String, (Arc<TetMesh>, usize)> = BTreeMap::new();
        let (mut meshes, mut node_offset, mut element_offset, mut surface_nodes, mut bounds) =
            (Vec::new(), vec![0], vec![0], Vec::new(), Vec::new());
        for (gi, g) in scene.grains.iter().enumerate() {
            let key = serde_json::to_string(&g.shape).unwrap_or_default();
            let (m, ns) = match cache.get(&key) {
                Some(v) => v.clone(),
                None => {
                    let m =
                        Arc::new(mesh_shape(&g.shape).map_err(|e| e.for_grain(&loaded.path, gi))?);
                    let ns = mesh::extract_surface(&m).nodes.len();
                    cache.insert(key, (m.clone(), ns));
                    (m, ns)
                }
            };
            node_offset.push(node_offset[gi] + m.nodes.len());
            element_offset.push(element_offset[gi] + m.tets.len());
            surface_nodes.push(ns);
            let n = m.nodes.len() as f64;
            let mut c = [0.0; 3];
            for p in &m.nodes {
                for i in 0..3 {
                    c[i] += p[i] / n;
                }
            }
            let radius = m
                .nodes
                .iter()
                .map(|p| {
                    ((p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2) + (p[2] - c[2]).powi(2)).sqrt()
                })
                .fold(0.0, f64::max);
            bounds.push(GrainBound {
                centre: [c[0] + g.centre[0], c[1] + g.centre[1], c[2] + g.centre[2]],
                radius,
            });
            meshes.push(m);
        }
        Ok(Self {
            meshes,
            node_offset,
            element_offset,
            surface_nodes,
            bounds,
        })
    }

    pub fn total_nodes(&self) -> usize {
        *self.node_offset.last().unwrap_or(&0)
    }
    pub fn total_elements(&self) -> usize {
        *self.element_offset.last().unwrap_or(&0)
    }
}

/// Margin (m) within which another rank's grain is mirrored as a ghost: generous compared
/// with the contact margin (a fraction of a surface edge), so contacts are never missed
/// between plan updates.
pub fn ghost_margin(global: &GlobalMesh) -> f64 {
    let r_min = global
        .bounds
        .iter()
        .map(|b| b.radius)
        .fold(f64::INFINITY, f64::min);
    0.25 * r_min
}

/// The periodic images one rank holding every grain mirrors at t = 0 (none without a
/// periodic cell).
pub fn serial_images(loaded: &LoadedScene) -> Result<Vec<GhostRef>, InputError> {
    let Some(cell) = PeriodicCell::of_scene(&loaded.scene) else {
        return Ok(Vec::new());
    };
    let global = GlobalMesh::build(loaded)?;
    let margin = ghost_margin(&global);
    let at = PlanCell {
        cell: &cell,
        length: cell.length0,
    };
    let owner = vec![0; loaded.scene.grains.len()];
    Ok(Decomposition::plan(&owner, &global.bounds, margin, 0, Some(at)).ghosts)
}
