//! Load balance and ghost re-planning between steps (MPI runs only).
//!
//! Both decisions are taken from counted work and positions, never from wall-clock time,
//! so that two runs of one scene — and a run and its restart — migrate the same grains at
//! the same steps. A grain's work per step is
//! `cost_per_element × elements + cost_per_contact_node × contact candidate entries`
//! (slave nodes of the grain with candidate facets in the current lists; the partition
//! crate's [`partition::CostModel`] prices). A rank's load is the sum over its grains;
//! when max/mean − 1 exceeds `parallel.imbalance_threshold`, METIS re-partitions with
//! those weights. The ghosts are re-planned when some grain's bounding sphere has moved
//! (centre shift + radius change) by more than a quarter of the ghost margin since the
//! last plan ([`Partition::planned_bounds`]).

use super::migration::redistribute;
use super::rank::metis_owner;
use crate::domain::halo::HaloPlan;
use crate::domain::Domain;
use crate::error::Result;
use crate::model::decomposition::{imbalance, GrainBound, Partition};
use crate::model::global::{ghost_margin, GlobalMesh};
use crate::scene::LoadedScene;
use crate::solver::Solver;

/// A new decomposition: grains changed hands or the ghosts were re-planned.
pub struct Rebalanced {
    pub solver: Solver,
    pub halo: HaloPlan,
    /// Grains whose owner changed.
    pub migrated: usize,
}

/// Work of each owned grain per step (cost units), in model grain order.
fn owned_grain_work(solver: &Solver) -> Vec<f64> {
    let m = &solver.model;
    let prices = partition::CostModel::default();
    let mut entries = vec![0usize; m.grains.len()];
    let lists = &solver.scratch.contact.lists;
    for e in &lists.entries {
        entries[lists.passes[e.pass as usize].slave as usize] += 1;
    }
    m.grains[..m.owned_grains]
        .iter()
        .zip(&entries)
        .map(|(g, &n)| {
            prices.cost_per_element * g.elements.len() as f64
                + prices.cost_per_contact_node * n as f64
        })
        .collect()
}

/// Current bounding sphere and work of every grain, from its owner (every rank gets the
/// whole table). All ranks must call.
fn gather_grain_status(
    domain: &Domain,
    solver: &Solver,
    n_grains: usize,
) -> (Vec<GrainBound>, Vec<f64>) {
    let m = &solver.model;
    let work = owned_grain_work(solver);
    let mut local = Vec::with_capacity(5 * m.owned_grains);
    for (g, w) in m.grains[..m.owned_grains].iter().zip(&work) {
        let nodes = &solver.state.x[g.nodes.clone()];
        let c = crate::math::centroid(nodes);
        let r = nodes
            .iter()
            .map(|p| ((p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2) + (p[2] - c[2]).powi(2)).sqrt())
            .fold(0.0, f64::max);
        local.extend_from_slice(&[c[0], c[1], c[2], r, *w]);
    }
    let offsets: Vec<usize> = (0..=n_grains).collect();
    let owner = &solver.state.partition.owner;
    let mut bytes = gather_rows(domain, owner, &offsets, &local, 5)
        .map(|v| v.iter().flat_map(|f| f.to_le_bytes()).collect::<Vec<u8>>())
        .unwrap_or_default();
    domain.broadcast_bytes(&mut bytes);
    bytes
        .chunks_exact(40)
        .map(|c| {
            let f = |k: usize| f64::from_le_bytes(c[8 * k..8 * k + 8].try_into().expect("8 bytes"));
            (
                GrainBound {
                    centre: [f(0), f(1), f(2)],
                    radius: f(3),
                },
                f(4),
            )
        })
        .unzip()
}

/// Brings every owned grain whose centroid has left the periodic box back into it by a
/// whole cell vector (nodes shifted, the shift added to `CellState::wrapped` so that
/// reported displacements stay continuous), and renames the friction history of its
/// contacts to the images they now are. Returns whether any grain of the scene was
/// wrapped (the ghosts must then be re-planned: the grain moved by a cell length). All
/// ranks must call.
pub fn wrap_into_cell(domain: &Domain, solver: &mut Solver) -> bool {
    let Some(cell) = solver.model.periodic.clone() else {
        return false;
    };
    let n = solver.state.partition.owner.len();
    let length = solver.state.cell_kinematics(&solver.model).length;
    let m = &solver.model;
    // whole cell vectors per grain of the scene, this rank's owned grains filled in
    let mut shifts = vec![0.0; 3 * n];
    for g in &m.grains[..m.owned_grains] {
        let offset = cell.wrap_offset(
            crate::math::centroid(&solver.state.x[g.nodes.clone()]),
            length,
        );
        for k in 0..3 {
            if length[k] > 0.0 {
                shifts[3 * g.global_id as usize + k] = (offset[k] / length[k]).round();
            }
        }
    }
    if domain.size() > 1 {
        domain.sum_in_place(&mut shifts);
    }
    if shifts.iter().all(|&s| s == 0.0) {
        return false;
    }
    let shift_of = |gid: u32| -> [f64; 3] {
        let i = 3 * gid as usize;
        [shifts[i], shifts[i + 1], shifts[i + 2]]
    };
    let state = &mut solver.state;
    for g in &m.grains[..m.owned_grains] {
        let k = shift_of(g.global_id);
        for x in &mut state.x[g.nodes.clone()] {
            for a in 0..3 {
                x[a] += k[a] * length[a];
            }
        }
    }
    if let Some(c) = &mut state.cell {
        c.wrapped.resize(n, [0.0; 3]);
        for (gid, w) in c.wrapped.iter_mut().enumerate() {
            let k = shift_of(gid as u32);
            for a in 0..3 {
                w[a] += k[a] * length[a];
            }
        }
    }
    // a grain moved by k cell vectors is, to everything it touched, its image −k
    let history = &mut state.contact.history;
    history.retain_mut(|p| {
        let (ks, km) = (shift_of(p.key.grain), shift_of(p.key.other));
        let mut inside = true;
        for a in 0..3 {
            let (s, o) = (
                f64::from(p.key.image[a]) - ks[a],
                f64::from(p.key.other_image[a]) - km[a],
            );
            inside &= s.abs() <= 1.0 && o.abs() <= 1.0;
            p.key.image[a] = s as i8;
            p.key.other_image[a] = o as i8;
        }
        inside
    });
    history.sort_by_key(|p| p.key);
    true
}

/// What a balance check decided.
pub enum BalanceCheck {
    /// Same owners and ghosts; every grain's current bounding sphere (global order), for
    /// the halo's contact zones.
    Unchanged(Vec<GrainBound>),
    Rebalanced(Box<Rebalanced>),
}

/// Every grain's current bounding sphere (global order), the same on every rank. All
/// ranks must call.
pub fn current_bounds(domain: &Domain, solver: &Solver, n_grains: usize) -> Vec<GrainBound> {
    gather_grain_status(domain, solver, n_grains).0
}

/// Re-partitions when the counted load imbalance exceeds the threshold, or re-plans the
/// ghosts when some grain moved far from the last plan (see the module docs). The caller
/// must have completed any halo exchange in flight. All ranks must call.
pub fn rebalance(
    domain: &Domain,
    loaded: &LoadedScene,
    global: &GlobalMesh,
    solver: &Solver,
) -> Result<BalanceCheck> {
    let n = loaded.scene.grains.len();
    let (bounds, work) = gather_grain_status(domain, solver, n);
    let partition = &solver.state.partition;
    let mut load = vec![0.0; domain.size()];
    for (g, w) in work.iter().enumerate() {
        load[partition.owner[g] as usize] += w;
    }
    let moved = bounds
        .iter()
        .zip(&partition.planned_bounds)
        .map(|(now, then)| {
            let shift = (0..3)
                .map(|i| (now.centre[i] - then.centre[i]).powi(2))
                .sum::<f64>()
                .sqrt();
            shift + (now.radius - then.radius).abs()
        })
        .fold(0.0, f64::max);
    // the images move with the cell's edges
    let cell_now = solver.state.cell_kinematics(&solver.model).length;
    let cell_moved = (0..3)
        .map(|k| (cell_now[k] - partition.planned_cell[k]).abs())
        .sum::<f64>();
    let moved = moved + cell_moved;
    let repartition = imbalance(&load) > loaded.scene.parallel.imbalance_threshold;
    if !repartition && moved <= 0.25 * ghost_margin(global) {
        return Ok(BalanceCheck::Unchanged(bounds));
    }
    let old_owner = partition.owner.clone();
    let new_owner = if repartition {
        let infos: Vec<partition::GrainInfo> = (0..n)
            .map(|g| partition::GrainInfo {
                centre: bounds[g].centre,
                bounding_radius: bounds[g].radius,
                elements: work[g].round().max(1.0) as usize,
                surface_nodes: 0,
            })
            .collect();
        metis_owner(domain, &infos, ghost_margin(global), "re-partitioning")?
    } else {
        old_owner.clone()
    };
    let migrated = old_owner
        .iter()
        .zip(&new_owner)
        .filter(|(a, b)| a != b)
        .count();
    let (mut solver, _plan, halo) =
        redistribute(domain, loaded, global, solver, &new_owner, &bounds)?;
    solver.state.partition = Partition {
        owner: new_owner,
        planned_bounds: bounds,
        planned_cell: cell_now,
    };
    Ok(BalanceCheck::Rebalanced(Box::new(Rebalanced {
        solver,
        halo,
        migrated,
    })))
}

/// Gathers per-grain rows of the owned grains to rank 0 in global order (the grain bounds
/// and work: a few values per grain; bulk fields are written collectively instead, see
/// `super::frames`). `offsets[g]..offsets[g + 1]` are the rows of grain g; `local` holds
/// this rank's owned grains' rows (ascending global id), `k` values per row. All ranks
/// must call; rank 0 gets `Some(global rows)`.
fn gather_rows(
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
