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
                    let m = Arc::new(mesh_shape(&g.shape).map_err(|e| {
                        InputError::new(&loaded.path, format!("grains[{gi}].shape"), e.to_string())
                    })?);
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

/// Partitions the grains over the ranks (METIS on rank 0, broadcast). All ranks must call.
pub fn partition_grains(
    domain: &Domain,
    loaded: &LoadedScene,
    global: &GlobalMesh,
) -> Result<Vec<u32>> {
    let n = loaded.scene.grains.len();
    let parts = domain.size();
    if parts > n {
        return Err(InputError::new(
            &loaded.path,
            "grains",
            format!("{parts} ranks but only {n} grains: every rank needs at least one grain"),
        )
        .into());
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
        let graph = partition::GrainGraph::build(
            &infos,
            ghost_margin(global),
            &partition::CostModel::default(),
        );
        let owner = partition::partition(&graph, parts, 1)
            .map_err(|e| MufeError::Run(format!("partitioning: {e}")))?;
        bytes = owner.iter().flat_map(|o| o.to_le_bytes()).collect();
    }
    domain.broadcast_bytes(&mut bytes);
    Ok(bytes
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect())
}

/// This rank's solver, decomposition and halo plan. All ranks must call.
pub fn build_rank_solver(
    domain: &Domain,
    loaded: &LoadedScene,
    global: &GlobalMesh,
    owner: &[u32],
) -> Result<(Solver, Decomposition, HaloPlan)> {
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
    let mut sums: Vec<f64> = kinds
        .iter()
        .zip(row.iter())
        .filter(|(k, _)| **k == Reduce::Sum)
        .map(|(_, v)| *v)
        .collect();
    let mut maxes: Vec<f64> = kinds
        .iter()
        .zip(row.iter())
        .filter(|(k, _)| **k == Reduce::Max)
        .map(|(_, v)| *v)
        .collect();
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
pub fn gather_rows(
    domain: &Domain,
    owner: &[u32],
    offsets: &[usize],
    local: &[f64],
    k: usize,
) -> Option<Vec<f64>> {
    let all = domain.gather_f64_to_root(local)?;
    let total = *offsets.last().unwrap_or(&0);
    let mut out = vec![0.0; total * k];
    let mut cursor = 0;
    for r in 0..domain.size() {
        for (g, &o) in owner.iter().enumerate() {
            if o as usize == r {
                let rows = offsets[g + 1] - offsets[g];
                out[offsets[g] * k..(offsets[g] + rows) * k]
                    .copy_from_slice(&all[cursor..cursor + rows * k]);
                cursor += rows * k;
            }
        }
    }
    Some(out)
}

/// The energy ledger summed over ranks (each rank's ledger covers its owned grains). All
/// ranks must call.
pub fn global_ledger(
    domain: &Domain,
    e: &crate::energy::EnergyLedger,
) -> crate::energy::EnergyLedger {
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
        body_force: crate::energy::WorkAccumulator {
            work: v[6],
            pending: v[7],
        },
        boundary_work: v[8],
        damping: crate::energy::WorkAccumulator {
            work: v[9],
            pending: v[10],
        },
        initial_total: e.initial_total.map(|_| v[11]),
    }
}

/// Serialises what travels with a grain when it changes hands: its nodes' x and v, the
/// friction history of its surface nodes as slaves, and the state of its prescribed
/// motions. Integers are stored as f64 (exact below 2⁵³).
pub fn pack_grain(solver: &Solver, model_grain: usize, out: &mut Vec<f64>) {
    let m = &solver.model;
    let g = &m.grains[model_grain];
    let st = &solver.state;
    let hist: Vec<&crate::contact::FrictionPoint> = st
        .contact
        .history
        .iter()
        .filter(|p| p.key.grain == g.global_id)
        .collect();
    let nodes = g.nodes.clone();
    let motion_ix: Vec<usize> = solver
        .motions
        .iter()
        .enumerate()
        .filter(|(_, mo)| {
            mo.nodes
                .first()
                .is_some_and(|&n| g.nodes.contains(&(n as usize)))
        })
        .map(|(k, _)| k)
        .collect();
    out.extend_from_slice(&[
        g.global_id as f64,
        nodes.len() as f64,
        hist.len() as f64,
        motion_ix.len() as f64,
    ]);
    for n in nodes.clone() {
        out.extend_from_slice(&st.x[n]);
    }
    for n in nodes {
        out.extend_from_slice(&st.v[n]);
    }
    for p in hist {
        out.extend_from_slice(&[
            p.key.other as f64,
            p.key.node as f64,
            p.traction[0],
            p.traction[1],
            p.traction[2],
        ]);
    }
    for k in motion_ix {
        let b = m
            .boundary_names
            .iter()
            .position(|n| *n == solver.motions[k].name)
            .unwrap_or(usize::MAX);
        out.push(b as f64);
        out.extend_from_slice(&st.motion_rotation[k]);
        let r = &st.reactions[k];
        for v in [r.force, r.moment, r.displacement, r.rotation] {
            out.extend_from_slice(&v);
        }
        out.extend_from_slice(&[st.motion_work[k].work, st.motion_work[k].pending]);
    }
}

/// Installs packed grains (see [`pack_grain`]) into a freshly built solver. Returns the
/// global ids installed.
pub fn unpack_grains(solver: &mut Solver, data: &[f64]) -> Result<Vec<u32>> {
    let bad = || MufeError::Run("migration: malformed grain package".into());
    let mut installed = Vec::new();
    let mut i = 0;
    while i < data.len() {
        let head = data.get(i..i + 4).ok_or_else(bad)?;
        let (gid, nn, nh, nm) = (
            head[0] as u32,
            head[1] as usize,
            head[2] as usize,
            head[3] as usize,
        );
        i += 4;
        let Some(mg) = solver.model.grains.iter().position(|g| g.global_id == gid) else {
            // not held here: skip the package
            i += 6 * nn + 5 * nh + nm * (1 + 9 + 12 + 2);
            continue;
        };
        let range = solver.model.grains[mg].nodes.clone();
        if range.len() != nn {
            return Err(MufeError::Run(format!(
                "migration: grain {gid} has {} nodes here, {nn} in the package",
                range.len()
            )));
        }
        for (k, n) in range.clone().enumerate() {
            let p = data.get(i + 3 * k..i + 3 * k + 3).ok_or_else(bad)?;
            solver.state.x[n] = [p[0], p[1], p[2]];
            let q = data
                .get(i + 3 * nn + 3 * k..i + 3 * nn + 3 * k + 3)
                .ok_or_else(bad)?;
            solver.state.v[n] = [q[0], q[1], q[2]];
        }
        i += 6 * nn;
        for _ in 0..nh {
            let p = data.get(i..i + 5).ok_or_else(bad)?;
            solver
                .state
                .contact
                .history
                .push(crate::contact::FrictionPoint {
                    key: crate::contact::ContactKey {
                        grain: gid,
                        other: p[0] as u32,
                        node: p[1] as u32,
                    },
                    traction: [p[2], p[3], p[4]],
                });
            i += 5;
        }
        for _ in 0..nm {
            let p = data.get(i..i + 24).ok_or_else(bad)?;
            let name = solver
                .model
                .boundary_names
                .get(p[0] as usize)
                .cloned()
                .unwrap_or_default();
            if let Some(k) = solver.motions.iter().position(|mo| mo.name == name) {
                solver.state.motion_rotation[k].copy_from_slice(&p[1..10]);
                let r = &mut solver.state.reactions[k];
                r.force.copy_from_slice(&p[10..13]);
                r.moment.copy_from_slice(&p[13..16]);
                r.displacement.copy_from_slice(&p[16..19]);
                r.rotation.copy_from_slice(&p[19..22]);
                solver.state.motion_work[k] = crate::energy::WorkAccumulator {
                    work: p[22],
                    pending: p[23],
                };
            }
            i += 24;
        }
        installed.push(gid);
    }
    solver.state.contact.history.sort_by_key(|p| p.key);
    solver.state.contact.history.dedup_by_key(|p| p.key);
    Ok(installed)
}

/// Moves grains between ranks: builds every rank's model for `new_owner` (with ghosts from
/// the current grain bounds) and carries over the full state of every grain it will hold
/// from that grain's previous owner. Per-rank energy accumulators stay where they are
/// (only their sum over ranks is meaningful). The caller must have completed any halo
/// exchange in flight. All ranks must call.
pub fn redistribute(
    domain: &Domain,
    loaded: &LoadedScene,
    global: &GlobalMesh,
    old: Solver,
    old_owner: &[u32],
    new_owner: &[u32],
    bounds: &[GrainBound],
) -> Result<(Solver, Decomposition, HaloPlan)> {
    let plan = Decomposition::plan(new_owner, bounds, ghost_margin(global), domain.rank());
    // who will hold each grain (owner + ghost holders): every rank can compute every plan
    let plans: Vec<Decomposition> = (0..domain.size())
        .map(|r| Decomposition::plan(new_owner, bounds, ghost_margin(global), r))
        .collect();
    let me = domain.rank();
    let mut sends: Vec<Vec<f64>> = vec![Vec::new(); domain.size()];
    for (mg, g) in old.model.grains[..old.model.owned_grains]
        .iter()
        .enumerate()
    {
        let gid = g.global_id as usize;
        debug_assert_eq!(old_owner[gid] as usize, me);
        for (r, p) in plans.iter().enumerate() {
            if p.owned.binary_search(&gid).is_ok() || p.ghosts.binary_search(&gid).is_ok() {
                pack_grain(&old, mg, &mut sends[r]);
            }
        }
    }
    let counts = domain.all_to_all_u64(&sends.iter().map(|s| s.len() as u64).collect::<Vec<_>>());
    let local = std::mem::take(&mut sends[me]);
    let outgoing: Vec<(usize, Vec<f64>)> = sends
        .into_iter()
        .enumerate()
        .filter(|(r, s)| *r != me && !s.is_empty())
        .collect();
    let incoming: Vec<(usize, usize)> = counts
        .iter()
        .enumerate()
        .filter(|(r, c)| *r != me && **c > 0)
        .map(|(r, c)| (r, *c as usize))
        .collect();
    let exchange = crate::domain::Exchange::new(202);
    let pending = exchange.begin(domain, &outgoing, &incoming)?;
    let received = exchange.end(pending)?;

    let (mut model, motions) = build_model_with_ghosts(loaded, &plan.owned, &plan.ghosts)?;
    model.dt = old.model.dt;
    let v0 = initial_velocities(&model, loaded);
    let mut solver = Solver::new(model, motions, v0);
    // run-level state that is not per grain
    solver.state.time = old.state.time;
    solver.state.step = old.state.step;
    solver.state.energy = old.state.energy.clone();
    solver.state.contact.friction_dissipation = old.state.contact.friction_dissipation;
    solver.state.contact.walls = old.state.contact.walls.clone();
    solver.state.contact.stats.max_penetration_run = old.state.contact.stats.max_penetration_run;
    solver.state.contact.stats.max_contacts_run = old.state.contact.stats.max_contacts_run;
    solver.timers = old.timers.clone();
    solver.state.contact.history.clear();
    let mut installed = unpack_grains(&mut solver, &local)?;
    for (_, data) in &received {
        installed.extend(unpack_grains(&mut solver, data)?);
    }
    installed.sort_unstable();
    installed.dedup();
    let expected: Vec<u32> = plan
        .owned
        .iter()
        .chain(&plan.ghosts)
        .map(|&g| g as u32)
        .collect::<std::collections::BTreeSet<_>>()
        .into_iter()
        .collect();
    if installed != expected {
        return Err(MufeError::Run(format!(
            "migration on rank {me}: received grains {installed:?}, expected {expected:?}"
        )));
    }
    // The energy ledger's motion work moved with the motions: recompute the boundary part.
    let halo = HaloPlan::new(&solver.model, &plan);
    Ok((solver, plan, halo))
}

/// Current bounding spheres of all grains, from their owners' nodes. All ranks must call.
pub fn current_bounds(
    domain: &Domain,
    solver: &Solver,
    owner: &[u32],
    n_grains: usize,
) -> Vec<GrainBound> {
    let m = &solver.model;
    let mut local = Vec::with_capacity(4 * m.owned_grains);
    for g in &m.grains[..m.owned_grains] {
        let nodes = &solver.state.x[g.nodes.clone()];
        let n = nodes.len() as f64;
        let mut c = [0.0; 3];
        for p in nodes {
            for i in 0..3 {
                c[i] += p[i] / n;
            }
        }
        let r = nodes
            .iter()
            .map(|p| ((p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2) + (p[2] - c[2]).powi(2)).sqrt())
            .fold(0.0, f64::max);
        local.extend_from_slice(&[c[0], c[1], c[2], r]);
    }
    let offsets: Vec<usize> = (0..=n_grains).collect();
    let mut bytes = gather_rows(domain, owner, &offsets, &local, 4)
        .map(|v| v.iter().flat_map(|f| f.to_le_bytes()).collect::<Vec<u8>>())
        .unwrap_or_default();
    domain.broadcast_bytes(&mut bytes);
    bytes
        .chunks_exact(32)
        .map(|c| {
            let f = |k: usize| f64::from_le_bytes(c[8 * k..8 * k + 8].try_into().expect("8 bytes"));
            GrainBound {
                centre: [f(0), f(1), f(2)],
                radius: f(3),
            }
        })
        .collect()
}

/// A new partition from measured costs: each rank's compute time over the last interval is
/// spread over its grains in proportion to their static cost, and METIS balances those
/// weights (rank 0 computes, all receive). All ranks must call.
pub fn repartition_measured(
    domain: &Domain,
    global: &GlobalMesh,
    bounds: &[GrainBound],
    owner: &[u32],
    rank_seconds: &[f64],
) -> Result<Vec<u32>> {
    let n = owner.len();
    let model = partition::CostModel::default();
    let static_cost: Vec<f64> = (0..n)
        .map(|g| {
            model.grain_cost(&partition::GrainInfo {
                centre: bounds[g].centre,
                bounding_radius: bounds[g].radius,
                elements: global.element_offset[g + 1] - global.element_offset[g],
                surface_nodes: global.surface_nodes[g],
            })
        })
        .collect();
    let mut rank_static = vec![0.0; domain.size()];
    for g in 0..n {
        rank_static[owner[g] as usize] += static_cost[g];
    }
    let mut bytes = Vec::new();
    if domain.is_root() {
        // measured seconds per unit of static cost on each rank, as an element-count weight
        let infos: Vec<partition::GrainInfo> = (0..n)
            .map(|g| {
                let r = owner[g] as usize;
                let speed = rank_seconds[r] / rank_static[r].max(1e-300);
                let mean_speed =
                    rank_seconds.iter().sum::<f64>() / rank_static.iter().sum::<f64>().max(1e-300);
                let weight = static_cost[g] * (speed / mean_speed.max(1e-300));
                partition::GrainInfo {
                    centre: bounds[g].centre,
                    bounding_radius: bounds[g].radius,
                    elements: weight.round().max(1.0) as usize,
                    surface_nodes: 0,
                }
            })
            .collect();
        let graph = partition::GrainGraph::build(&infos, ghost_margin(global), &model);
        let new = partition::partition(&graph, domain.size(), 1)
            .map_err(|e| MufeError::Run(format!("re-partitioning: {e}")))?;
        bytes = new.iter().flat_map(|o| o.to_le_bytes()).collect();
    }
    domain.broadcast_bytes(&mut bytes);
    Ok(bytes
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect())
}
