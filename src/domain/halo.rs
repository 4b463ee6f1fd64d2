//! Forward halo: every step, the owners of grains mirrored on other ranks send the current
//! positions x_n and velocities v_{n−½} of those grains' surface nodes; receivers overwrite
//! their ghost copies. Contact then sees the same surfaces on every rank that holds a pair,
//! and each rank keeps the contact forces on its own nodes (no reverse exchange needed).
//! Begin/end halves let interior work (internal forces) overlap the communication.

use super::{Domain, Exchange, PendingExchange};
use crate::error::MufeError;
use crate::model::decomposition::Decomposition;
use crate::model::Model;

/// Values sent per surface node: x (3) and v (3).
pub const VALUES_PER_NODE: usize = 6;

/// Message tag of the forward halo.
const FORWARD_TAG: i32 = 101;

/// Which model nodes go to / come from each neighbour rank (fixed between re-plans).
#[derive(Debug, Clone, Default)]
pub struct HaloPlan {
    /// (rank, model node ids of owned surface nodes it mirrors), ascending ranks.
    pub sends: Vec<(usize, Vec<u32>)>,
    /// (rank, model node ids of ghost surface nodes it owns), in the sender's order.
    pub receives: Vec<(usize, Vec<u32>)>,
}

impl HaloPlan {
    /// Maps a decomposition onto a model built with its owned and ghost grains. Both sides
    /// list grains ascending by global id and each grain's surface nodes ascending, so the
    /// sender's packing order is the receiver's unpacking order.
    pub fn new(model: &Model, plan: &Decomposition) -> Self {
        let surface_of = |global: usize| -> Vec<u32> {
            model
                .grains
                .iter()
                .find(|g| g.global_id as usize == global)
                .map(|g| g.surface.nodes.clone())
                .unwrap_or_default()
        };
        let pack = |list: &[(usize, Vec<usize>)]| -> Vec<(usize, Vec<u32>)> {
            list.iter()
                .map(|(r, grains)| (*r, grains.iter().flat_map(|&g| surface_of(g)).collect()))
                .collect()
        };
        Self {
            sends: pack(&plan.sends),
            receives: pack(&plan.receives),
        }
    }

    /// Bytes sent per step by this rank.
    pub fn bytes_per_step(&self) -> usize {
        self.sends
            .iter()
            .map(|(_, n)| n.len() * VALUES_PER_NODE * 8)
            .sum()
    }
}

/// The forward halo exchange of one rank.
pub struct Halo<'d> {
    domain: &'d Domain,
    pub plan: HaloPlan,
    exchange: Exchange,
    pending: Option<PendingExchange<'d>>,
}

impl<'d> Halo<'d> {
    pub fn new(domain: &'d Domain, plan: HaloPlan) -> Self {
        Self {
            domain,
            plan,
            exchange: Exchange::new(FORWARD_TAG),
            pending: None,
        }
    }

    /// Posts the sends of the owned surface nodes' x and v and the receives of the ghosts'.
    /// Only neighbours take part (not collective).
    pub fn begin(&mut self, x: &[[f64; 3]], v: &[[f64; 3]]) -> Result<(), MufeError> {
        if self.plan.sends.is_empty() && self.plan.receives.is_empty() {
            return Ok(());
        }
        let sends: Vec<(usize, Vec<f64>)> = self
            .plan
            .sends
            .iter()
            .map(|(r, nodes)| {
                let mut buf = Vec::with_capacity(nodes.len() * VALUES_PER_NODE);
                for &n in nodes {
                    buf.extend_from_slice(&x[n as usize]);
                    buf.extend_from_slice(&v[n as usize]);
                }
                (*r, buf)
            })
            .collect();
        let counts: Vec<(usize, usize)> = self
            .plan
            .receives
            .iter()
            .map(|(r, n)| (*r, n.len() * VALUES_PER_NODE))
            .collect();
        self.pending = Some(self.exchange.begin(self.domain, &sends, &counts)?);
        Ok(())
    }

    /// Waits for the ghost data and writes it into the ghost nodes of x and v.
    pub fn end(&mut self, x: &mut [[f64; 3]], v: &mut [[f64; 3]]) -> Result<(), MufeError> {
        let Some(pending) = self.pending.take() else {
            return Ok(());
        };
        let received = self.exchange.end(pending)?;
        for (rank, data) in received {
            let Some((_, nodes)) = self.plan.receives.iter().find(|(r, _)| *r == rank) else {
                return Err(MufeError::Run(format!(
                    "halo: unexpected message from rank {rank}"
                )));
            };
            if data.len() != nodes.len() * VALUES_PER_NODE {
                return Err(MufeError::Run(format!(
                    "halo: rank {rank} sent {} values, expected {}",
                    data.len(),
                    nodes.len() * VALUES_PER_NODE
                )));
            }
            for (k, &n) in nodes.iter().enumerate() {
                let d = &data[k * VALUES_PER_NODE..(k + 1) * VALUES_PER_NODE];
                x[n as usize] = [d[0], d[1], d[2]];
                v[n as usize] = [d[3], d[4], d[5]];
            }
        }
        Ok(())
    }

    /// begin + end: a blocking exchange.
    pub fn exchange(&mut self, x: &mut [[f64; 3]], v: &mut [[f64; 3]]) -> Result<(), MufeError> {
        self.begin(x, v)?;
        self.end(x, v)
    }
}
