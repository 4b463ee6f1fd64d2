//! Running one scene on many ranks: partition the grains with METIS, build each rank's
//! model (owned grains + ghosts), step with halo exchange, reduce the history and gather
//! frames for the writer. The same code runs on one rank (one part, no ghosts, no halo).
//! MPI itself is reached only through [`crate::domain::Domain`].

use super::model::{build_model_with_ghosts, mesh_shape};
use super::run::initial_velocities;
use super::step::{Solver, StepHooks};
use crate::domain::decomposition::{Decomposition, GrainBound};
use crate::domain::halo::{Halo, HaloPlan};
use crate::domain::Domain;
use crate::error::{InputError, MufeError, Result};
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
        let mut cache: BTreeMap<String, (Arc<TetMesh>, usize)> = BTreeMap::new();
        let (mut meshes, mut node_offset, mut element_offset, mut surface_nodes, mut bounds) =
            (Vec::new(), vec![0], vec![0], Vec::new(), Vec::new());
        for (gi, g) in scene.grains.iter().enumerate() {
            let key = serde_json::to_string(&g.shape).unwrap_or_default();
            let (m, ns) = match cache.get(&key) {
                Some(v) => v.clone(),
                None => {
                    let m = Arc::new(mesh_shape(&g.shape).map_err(|e| InputError::new(&loaded.path, format!("grains[{gi}].shape"), e.to_string()))?);
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
            let radius = m.nodes.iter().map(|p| ((p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2) + (p[2] - c[2]).powi(2)).sqrt()).fold(0.0, f64::max);
            bounds.push(GrainBound { centre: [c[0] + g.centre[0], c[1] + g.centre[1], c[2] + g.centre[2]], radius });
            meshes.push(m);
        }
        Ok(Self { meshes, node_offset, element_offset, surface_nodes, bounds })
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
    let r_min = global.bounds.iter().map(|b| b.radius).fold(f64::INFINITY, f64::min);
    0.25 * r_min
}

/// Partitions the grains over the ranks (METIS on rank 0, broadcast). All ranks must call.
pub fn partition_grains(domain: &Domain, loaded: &LoadedScene, global: &GlobalMesh) -> Result<Vec<u32>> {
    let n = loaded.scene.grains.len();
    let parts = domain.size();
    if parts > n {
        return Err(InputError::new(&loaded.path, "grains", format!("{parts} ranks but only {n} grains: every rank needs at least one grain")).into());
    }
    let mut bytes = Vec::new();
    if domain.is_root() {
        let infos: Vec<partition::GrainInfo> = (0..n)
            .map(|g| partition::GrainInfo {
                centre: global.bounds[g].centre,
                bounding_radius: global.bounds[g].radius,
                elements: global.element_offset[g + 1] - global.element_offset[g],
                surface_nodes: global.surface_nodes[g],
            })
            .collect();
        let graph = partition::GrainGraph::build(&infos, ghost_margin(global), &partition::CostModel::default());
        let owner = partition::partition(&graph, parts, 1).map_err(|e| MufeError::Run(format!("partitioning: {e}")))?;
        bytes = owner.iter().flat_map(|o| o.to_le_bytes()).collect();
    }
    domain.broadcast_bytes(&mut bytes);
    Ok(bytes.chunks_exact(4).map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect())
}

/// This rank's solver, decomposition and halo plan. All ranks must call.
pub fn build_rank_solver(domain: &Domain, loaded: &LoadedScene, global: &GlobalMesh, owner: &[u32]) -> Result<(Solver, Decomposition, HaloPlan)> {
    let plan = Decomposition::plan(owner, &global.bounds, ghost_margin(global), domain.rank());
    let built = build_model_with_ghosts(loaded, &plan.owned, &plan.ghosts);
    // A bad scene fails on every rank alike (same input), so returning is safe; anything
    // rank-specific would need the job aborted.
    let (mut model, motions) = built?;
    let mut dt = [model.dt];
    domain.min_in_place(&mut dt);
    model.dt = dt[0];
    let v0 = initial_velocities(&model, loaded);
    let halo = HaloPlan::new(&model, &plan);
    Ok((Solver::new(model, motions, v0), plan, halo))
}

/// The MPI side of a step: ghost exchange and reductions.
pub struct RankHooks<'d> {
    pub domain: &'d Domain,
    pub halo: Halo<'d>,
}

impl StepHooks for RankHooks<'_> {
    fn ghosts_in(&mut self, x: &mut [[f64; 3]], v: &mut [[f64; 3]]) -> Result<(), MufeError> {
        self.halo.end(x, v)
    }
    fn ghosts_out(&mut self, x: &[[f64; 3]], v: &[[f64; 3]]) -> Result<(), MufeError> {
        self.halo.begin(x, v)
    }
    fn any(&mut self, local: bool) -> bool {
        if self.domain.size() == 1 {
            return local;
        }
        let mut v = [if local { 1.0 } else { 0.0 }];
        self.domain.max_in_place(&mut v);
        v[0] > 0.0
    }
    fn sum(&mut self, values: &mut [f64]) {
        if self.domain.size() > 1 {
            self.domain.sum_in_place(values);
        }
    }
}

/// How a history column combines over ranks.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Reduce {
    /// Identical on every rank (time, wall displacement).
    Same,
    Sum,
    Max,
}

/// Reduces a history row in place. All ranks must call.
pub fn reduce_row(domain: &Domain, kinds: &[Reduce], row: &mut [f64]) {
    if domain.size() == 1 {
        return;
    }
    let mut sums: Vec<f64> = kinds.iter().zip(row.iter()).filter(|(k, _)| **k == Reduce::Sum).map(|(_, v)| *v).collect();
    let mut maxes: Vec<f64> = kinds.iter().zip(row.iter()).filter(|(k, _)| **k == Reduce::Max).map(|(_, v)| *v).collect();
    domain.sum_in_place(&mut sums);
    domain.max_in_place(&mut maxes);
    let (mut s, mut m) = (sums.into_iter(), maxes.into_iter());
    for (k, v) in kinds.iter().zip(row.iter_mut()) {
        match k {
            Reduce::Sum => *v = s.next().unwrap_or(*v),
            Reduce::Max => *v = m.next().unwrap_or(*v),
            Reduce::Same => {}
        }
    }
}

/// Gathers a per-node (or per-element) field of the owned grains to rank 0 in global
/// order. `per_grain[g]` is the row count of grain g; `local` holds this rank's owned
/// grains' rows (ascending global id), `k` values per row. All ranks must call; rank 0
/// gets `Some(global rows)`.
pub fn gather_rows(domain: &Domain, owner: &[u32], offsets: &[usize], local: &[f64], k: usize) -> Option<Vec<f64>> {
    let all = domain.gather_f64_to_root(local)?;
    let total = *offsets.last().unwrap_or(&0);
    let mut out = vec![0.0; total * k];
    let mut cursor = 0;
    for r in 0..domain.size() {
        for (g, &o) in owner.iter().enumerate() {
            if o as usize == r {
                let rows = offsets[g + 1] - offsets[g];
                out[offsets[g] * k..(offsets[g] + rows) * k].copy_from_slice(&all[cursor..cursor + rows * k]);
                cursor += rows * k;
            }
        }
    }
    Some(out)
}

/// The energy ledger summed over ranks (each rank's ledger covers its owned grains). All
/// ranks must call.
pub fn global_ledger(domain: &Domain, e: &crate::energy::EnergyLedger) -> crate::energy::EnergyLedger {
    let mut v = [
        e.kinetic,
        e.strain,
        e.recoverable_strain,
        e.plastic_dissipation,
        e.friction_dissipation,
        e.contact_energy,
        e.body_force.work,
        e.body_force.pending,
        e.boundary_work,
        e.damping.work,
        e.damping.pending,
        e.initial_total.unwrap_or(0.0),
    ];
    if domain.size() > 1 {
        domain.sum_in_place(&mut v);
    }
    crate::energy::EnergyLedger {
        kinetic: v[0],
        strain: v[1],
        recoverable_strain: v[2],
        plastic_dissipation: v[3],
        friction_dissipation: v[4],
        contact_energy: v[5],
        body_force: crate::energy::WorkAccumulator { work: v[6], pending: v[7] },
        boundary_work: v[8],
        damping: crate::energy::WorkAccumulator { work: v[9], pending: v[10] },
        initial_total: e.initial_total.map(|_| v[11]),
    }
}
