//! The whole scene's mesh layout, identical on every rank: each grain's mesh (distinct
//! shapes meshed once), global node and element offsets, surface sizes and bounding
//! spheres. It sizes the partition, the results file and the ghost margin.

use super::assemble::mesh_shape;
use super::decomposition::{
    contact_zone, contact_zone_cushion, in_contact_zone, Decomposition, GhostRef, GrainBound,
    PlanCell,
};
use super::periodic::PeriodicCell;
use crate::error::InputError;
use crate::mesh::{self, TetMesh};
use crate::scene::{LoadedScene, Scene};
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

/// Surface nodes each rank's forward halo carries per step for the partition `owner`
/// (plain ghosts, no periodic images): `[whole ghost surfaces, contact zones]` per rank,
/// as `mufe run` sends them (`crate::domain::halo`: the zones around the grains at their
/// starting positions in `scene`, whose broad-phase margin is the run's).
pub fn halo_nodes_per_rank(global: &GlobalMesh, scene: &Scene, owner: &[u32]) -> Vec<[u64; 2]> {
    let margin = ghost_margin(global);
    // per distinct mesh: its surface, each node's longest edge within two rings, its largest mean edge
    // and its shortest edge
    type Shape = (mesh::SurfaceMesh, Vec<f64>, [f64; 2]);
    let mut shapes: BTreeMap<*const TetMesh, Shape> = BTreeMap::new();
    for m in &global.meshes {
        shapes.entry(Arc::as_ptr(m)).or_insert_with(|| {
            let surface = mesh::extract_surface(m);
            let longest = mesh::longest_edge_within_two_rings(&surface, &m.nodes);
            let (mean_edge, shortest) = mesh::mean_edge_at_nodes(&surface, &m.nodes);
            let widest_mean = mean_edge.iter().cloned().fold(0.0, f64::max);
            (surface, longest, [widest_mean, shortest])
        });
    }
    let h = shapes.values().map(|s| s.2[0]).fold(0.0, f64::max);
    let min_edge = shapes
        .values()
        .map(|s| s.2[1])
        .fold(f64::INFINITY, f64::min);
    let broad_margin =
        (scene.contact.margin).unwrap_or(super::contact_layout::DEFAULT_MARGIN_FRACTION * min_edge);
    let query = broad_margin + 0.5 * h;
    // per distinct mesh: each surface node's cushion and the widest of them
    let cushions: BTreeMap<*const TetMesh, (Vec<f64>, f64)> = (shapes.iter())
        .map(|(&key, (_, longest, _))| {
            let cushion: Vec<f64> = (longest.iter())
                .map(|&e| contact_zone_cushion(e, query))
                .collect();
            let widest = cushion.iter().cloned().fold(0.0, f64::max);
            (key, (cushion, widest))
        })
        .collect();
    let ranks = owner.iter().map(|&r| r as usize + 1).max().unwrap_or(1);
    (0..ranks)
        .map(|r| {
            let plan = Decomposition::plan(owner, &global.bounds, margin, r, None);
            let mut counts = [0u64; 2];
            for ghost in &plan.ghosts {
                let g = ghost.grain;
                let key = Arc::as_ptr(&global.meshes[g]);
                let (surface, (cushion, widest)) = (&shapes[&key].0, &cushions[&key]);
                let zone = contact_zone(owner, &global.bounds, margin, g, r, *widest);
                // placed as the run places it: mesh node + the grain's `centre`
                let centre = scene.grains[g].centre;
                counts[0] += surface.nodes.len() as u64;
                for (k, &n) in surface.nodes.iter().enumerate() {
                    let p = global.meshes[g].nodes[n as usize];
                    let p = [0, 1, 2].map(|i| p[i] + centre[i]);
                    if in_contact_zone(&zone, p, cushion[k]) {
                        counts[1] += 1;
                    }
                }
            }
            counts
        })
        .collect()
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
