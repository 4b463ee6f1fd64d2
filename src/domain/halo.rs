//! Forward halo: every step, the owners of grains mirrored on other ranks send the current
//! positions x_n and velocities v_{n−½} of those grains' surface nodes; receivers overwrite
//! their ghost copies. Contact then sees the same surfaces on every rank that holds a pair,
//! and each rank keeps the contact forces on its own nodes (no reverse exchange needed).
//! Begin/end halves let interior work (internal forces) overlap the communication. The
//! send and receive buffers, request and status lists are kept from step to step, so a
//! step allocates nothing once they have grown to the plan's size.

use super::{Domain, Exchange, ExchangeBuffers, PendingExchange};
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
    /// `(rank, values)` of each message sent and received, from the plan.
    send_counts: Vec<(usize, usize)>,
    recv_counts: Vec<(usize, usize)>,
    /// The buffers between exchanges (inside `pending` while one is in flight).
    buffers: Option<ExchangeBuffers>,
    pending: Option<PendingExchange<'d>>,
}

impl<'d> Halo<'d> {
    pub fn new(domain: &'d Domain, plan: HaloPlan) -> Self {
        let counts = |list: &[(usize, Vec<u32>)]| -> Vec<(usize, usize)> {
            list.iter()
                .map(|(r, n)| (*r, n.len() * VALUES_PER_NODE))
                .collect()
        };
        Self {
            domain,
            send_counts: counts(&plan.sends),
            recv_counts: counts(&plan.receives),
            plan,
            exchange: Exchange::new(FORWARD_TAG),
            buffers: Some(ExchangeBuffers::default()),
            pending: None,
        }
    }

    /// Posts the sends of the owned surface nodes' x and v and the receives of the ghosts'.
    /// Only neighbours take part (not collective).
    pub fn begin(&mut self, x: &[[f64; 3]], v: &[[f64; 3]]) -> Result<(), MufeError> {
        if self.plan.sends.is_empty() && self.plan.receives.is_empty() {
            return Ok(());
        }
        let mut buffers = self.buffers.take().unwrap_or_default();
        buffers.send.clear();
        for (_, nodes) in &self.plan.sends {
            for &n in nodes {
                buffers.send.extend_from_slice(&x[n as usize]);
                buffers.send.extend_from_slice(&v[n as usize]);
            }
        }
        self.pending = Some(self.exchange.begin_reusing(
            self.domain,
            buffers,
            &self.send_counts,
            &self.recv_counts,
        )?);
        Ok(())
    }

    /// Waits for the ghost data and writes it into the ghost nodes of x and v.
    pub fn end(&mut self, x: &mut [[f64; 3]], v: &mut [[f64; 3]]) -> Result<(), MufeError> {
        let Some(pending) = self.pending.take() else {
            return Ok(());
        };
        let buffers = self.exchange.end_reusing(pending)?;
        for ((rank, data), (_, nodes)) in buffers.received().zip(&self.plan.receives) {
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
        self.buffers = Some(buffers);
        Ok(())
    }

    /// Start of the send buffer and its capacity (for the test that steps reuse it).
    pub fn send_buffer_identity(&self) -> Option<(*const f64, usize)> {
        self.buffers
            .as_ref()
            .map(|b| (b.send.as_ptr(), b.send.capacity()))
    }

    /// begin + end: a blocking exchange.
    pub fn exchange(&mut self, x: &mut [[f64; 3]], v: &mut [[f64; 3]]) -> Result<(), MufeError> {
        self.begin(x, v)?;
        self.end(x, v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_self_halo_copies_owned_into_ghost_nodes_and_reuses_its_buffers() {
        crate::domain::with_test_domain(|domain| {
            // nodes 0, 1 are "owned", 2, 3 their ghost copies (rank 0 sends to itself)
            let plan = HaloPlan {
                sends: vec![(0, vec![0, 1])],
                receives: vec![(0, vec![2, 3])],
            };
            assert_eq!(plan.bytes_per_step(), 2 * VALUES_PER_NODE * 8);
            let mut halo = Halo::new(domain, plan);
            let mut x = vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0], [0.0; 3], [0.0; 3]];
            let mut v = vec![[-1.0, -2.0, -3.0], [-4.0, -5.0, -6.0], [0.0; 3], [0.0; 3]];
            halo.exchange(&mut x, &mut v).unwrap();
            let first = halo.send_buffer_identity().unwrap();
            assert_eq!((x[2], x[3]), (x[0], x[1]));
            assert_eq!((v[2], v[3]), (v[0], v[1]));
            for step in 0..3 {
                x[0][0] += 1.0;
                v[1][2] -= 1.0;
                halo.exchange(&mut x, &mut v).unwrap();
                assert_eq!((x[2], x[3]), (x[0], x[1]), "step {step}");
                assert_eq!((v[2], v[3]), (v[0], v[1]), "step {step}");
                // the same allocation every step: nothing is allocated per step
                assert_eq!(halo.send_buffer_identity().unwrap(), first);
            }
        });
    }
}
