//! Grain migration between ranks: what travels with a grain when it changes hands, and
//! the redistribution that builds every rank's new solver around it.

use super::rank::plan_ghosts;
use crate::domain::halo::HaloPlan;
use crate::domain::{Domain, Exchange};
use crate::error::{MufeError, Result};
use crate::model::decomposition::{Decomposition, GrainBound};
use crate::model::global::GlobalMesh;
use crate::scene::LoadedScene;
use crate::solver::{build_solver_for, Solver};

/// Values per friction history point in a package: other, node, the slave's and the
/// master's image (3 + 3), traction (3).
const HISTORY_VALUES: usize = 11;

/// Serialises what travels with a grain when it changes hands: its nodes' x and v, the
/// friction history of its surface nodes as slaves, the state of its prescribed motions
/// and the plastic state of its elements. Integers are stored as f64 (exact below 2⁵³).
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
    let plastic = m
        .plastic_range(model_grain)
        .map(|r| &st.plastic[r])
        .unwrap_or(&[]);
    out.extend_from_slice(&[
        g.global_id as f64,
        nodes.len() as f64,
        hist.len() as f64,
        motion_ix.len() as f64,
        plastic.len() as f64,
    ]);
    for n in nodes.clone() {
        out.extend_from_slice(&st.x[n]);
    }
    for n in nodes {
        out.extend_from_slice(&st.v[n]);
    }
    for p in hist {
        push_history_point(p, out);
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
    for p in plastic {
        out.extend_from_slice(&p.strain);
        out.push(p.equivalent);
    }
}

/// Serialises the friction history of the passes whose slave is `model_grain`, a ghost
/// image of another rank's grain: a contact with an image is computed twice, as A against
/// B's image (by A's owner) and as A's image against B (by B's owner), and the second
/// pass's history lives only where it was computed, so it travels on its own (a package
/// without nodes, see [`unpack_grains`]). Writes nothing when there is none.
pub fn pack_image_history(solver: &Solver, model_grain: usize, out: &mut Vec<f64>) {
    let g = &solver.model.grains[model_grain];
    let hist: Vec<&crate::contact::FrictionPoint> = (solver.state.contact.history.iter())
        .filter(|p| p.key.grain == g.global_id && p.key.image == g.image)
        .collect();
    if hist.is_empty() || g.image == crate::model::periodic::NO_IMAGE {
        return;
    }
    out.extend_from_slice(&[g.global_id as f64, 0.0, hist.len() as f64, 0.0, 0.0]);
    for p in hist {
        push_history_point(p, out);
    }
}

/// Model grains whose image histories travel separately ([`pack_image_history`]):
/// images of other ranks' grains.
pub fn remote_images(solver: &Solver) -> impl Iterator<Item = usize> + '_ {
    let m = &solver.model;
    (m.owned_grains..m.grains.len()).filter(move |&g| {
        m.grains[g].image != crate::model::periodic::NO_IMAGE
            && !m.local_images.iter().any(|&(i, _)| i == g)
    })
}

fn push_history_point(p: &crate::contact::FrictionPoint, out: &mut Vec<f64>) {
    out.extend_from_slice(&[
        p.key.other as f64,
        p.key.node as f64,
        f64::from(p.key.image[0]),
        f64::from(p.key.image[1]),
        f64::from(p.key.image[2]),
        f64::from(p.key.other_image[0]),
        f64::from(p.key.other_image[1]),
        f64::from(p.key.other_image[2]),
        p.traction[0],
        p.traction[1],
        p.traction[2],
    ]);
}

/// Installs packed grains (see [`pack_grain`]) into a freshly built solver. Returns the
/// global ids installed.
pub fn unpack_grains(solver: &mut Solver, data: &[f64]) -> Result<Vec<u32>> {
    let bad = || MufeError::Run("migration: malformed grain package".into());
    let mut installed = Vec::new();
    let mut i = 0;
    while i < data.len() {
        let head = data.get(i..i + 5).ok_or_else(bad)?;
        let (gid, nn, nh, nm, np) = (
            head[0] as u32,
            head[1] as usize,
            head[2] as usize,
            head[3] as usize,
            head[4] as usize,
        );
        i += 5;
        let history_only = nn == 0;
        let Some(mg) = solver.model.grains.iter().position(|g| g.global_id == gid) else {
            // not held here: skip the package
            i += 6 * nn + HISTORY_VALUES * nh + nm * (1 + 9 + 12 + 2) + 7 * np;
            continue;
        };
        let range = solver.model.grains[mg].nodes.clone();
        if range.len() != nn && !history_only {
            return Err(MufeError::Run(format!(
                "migration: grain {gid} has {} nodes here, {nn} in the package",
                range.len()
            )));
        }
        for (k, n) in range.clone().enumerate().take(nn) {
            let p = data.get(i + 3 * k..i + 3 * k + 3).ok_or_else(bad)?;
            solver.state.x[n] = [p[0], p[1], p[2]];
            let q = data
                .get(i + 3 * nn + 3 * k..i + 3 * nn + 3 * k + 3)
                .ok_or_else(bad)?;
            solver.state.v[n] = [q[0], q[1], q[2]];
        }
        i += 6 * nn;
        for _ in 0..nh {
            let p = data.get(i..i + HISTORY_VALUES).ok_or_else(bad)?;
            solver
                .state
                .contact
                .history
                .push(crate::contact::FrictionPoint {
                    key: crate::contact::ContactKey {
                        grain: gid,
                        other: p[0] as u32,
                        image: [p[2] as i8, p[3] as i8, p[4] as i8],
                        other_image: [p[5] as i8, p[6] as i8, p[7] as i8],
                        node: p[1] as u32,
                    },
                    traction: [p[8], p[9], p[10]],
                });
            i += HISTORY_VALUES;
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
        // plastic state: only an owner keeps it (ghost elements are not evaluated)
        if let Some(range) = solver.model.plastic_range(mg).filter(|_| !history_only) {
            if range.len() != np {
                return Err(MufeError::Run(format!(
                    "migration: grain {gid} has {} plastic elements here, {np} in the package",
                    range.len()
                )));
            }
            for (k, slot) in range.enumerate() {
                let p = data.get(i + 7 * k..i + 7 * k + 7).ok_or_else(bad)?;
                solver.state.plastic[slot] = crate::material::PlasticPoint {
                    strain: [p[0], p[1], p[2], p[3], p[4], p[5]],
                    equivalent: p[6],
                };
            }
        }
        i += 7 * np;
        if !history_only {
            installed.push(gid);
        }
    }
    solver.state.contact.history.sort_by_key(|p| p.key);
    solver.state.contact.history.dedup_by_key(|p| p.key);
    Ok(installed)
}

/// Moves grains between ranks: builds every rank's model for `new_owner` (with ghosts from
/// the grain bounds `bounds`) and carries over the full state of every grain it will hold
/// from that grain's previous owner. Per-rank totals (energies, the walls' work) stay where
/// they are (only their sum over ranks is meaningful); stage progress, walls and time carry
/// over. The caller must have completed any halo
/// exchange in flight. All ranks must call.
pub fn redistribute(
    domain: &Domain,
    loaded: &LoadedScene,
    global: &GlobalMesh,
    old: &Solver,
    new_owner: &[u32],
    bounds: &[GrainBound],
) -> Result<(Solver, Decomposition, HaloPlan)> {
    let cell = old.state.cell_kinematics(&old.model).length;
    let plan = plan_ghosts(loaded, global, new_owner, bounds, cell, domain.rank());
    // who will hold each grain (owner + ghost holders): every rank can compute every plan
    let plans: Vec<Decomposition> = (0..domain.size())
        .map(|r| plan_ghosts(loaded, global, new_owner, bounds, cell, r))
        .collect();
    let me = domain.rank();
    let mut sends: Vec<Vec<f64>> = vec![Vec::new(); domain.size()];
    for (mg, g) in old.model.grains[..old.model.owned_grains]
        .iter()
        .enumerate()
    {
        let gid = g.global_id as usize;
        debug_assert_eq!(old.state.partition.owner[gid] as usize, me);
        for (r, p) in plans.iter().enumerate() {
            if p.holds(gid) {
                pack_grain(old, mg, &mut sends[r]);
            }
        }
    }
    for mg in remote_images(old) {
        let gid = old.model.grains[mg].global_id as usize;
        for (r, p) in plans.iter().enumerate() {
            if p.holds(gid) {
                pack_image_history(old, mg, &mut sends[r]);
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
    let exchange = Exchange::new(202);
    let pending = exchange.begin(domain, &outgoing, &incoming)?;
    let received = exchange.end(pending)?;

    let mut solver = build_solver_for(loaded, &plan.owned, &plan.ghosts)?;
    solver.model.dt = old.model.dt;
    // run-level state that is not per grain (this rank keeps its own totals)
    solver.state.take_run_level_from(&old.state);
    solver.timers = old.timers.clone();
    // the narrow phase's tally spans the same steps as the stage table it is read beside
    solver.scratch.contact.narrow = old.scratch.contact.narrow;
    solver.state.contact.history.clear();
    let mut installed = unpack_grains(&mut solver, &local)?;
    for (_, data) in &received {
        installed.extend(unpack_grains(&mut solver, data)?);
    }
    installed.sort_unstable();
    installed.dedup();
    let expected: Vec<u32> = (plan.owned.iter().copied())
        .chain(plan.ghosts.iter().map(|r| r.grain))
        .map(|g| g as u32)
        .collect::<std::collections::BTreeSet<_>>()
        .into_iter()
        .collect();
    if installed != expected {
        return Err(MufeError::Run(format!(
            "migration on rank {me}: received grains {installed:?}, expected {expected:?}"
        )));
    }
    let halo = super::rank::halo_plan(loaded, global, &solver, &plan, new_owner, bounds);
    Ok((solver, plan, halo))
}
