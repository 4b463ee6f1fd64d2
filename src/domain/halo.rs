//! Forward halo: every step, the owners of grains mirrored on other ranks send the current
//! positions x_n and velocities v_{n−½} of those grains' surface nodes; receivers overwrite
//! their ghost copies. Contact then sees the same surfaces on every rank that holds a pair,
//! and each rank keeps the contact forces on its own nodes (no reverse exchange needed).
//! Begin/end halves let interior work (internal forces) overlap the communication. The
//! send and receive buffers, request and status lists are kept from step to step, so a
//! step allocates nothing once they have grown to the plan's size.

use super::{Domain, Exchange, ExchangeBuffers, PendingExchange};
use crate::error::MufeError;
use crate::model::decomposition::{Decomposition, GhostRef};
use crate::model::periodic::{CellKinematics, Image};
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
    /// The periodic image each sent node goes to (parallel to `sends`): the sender adds
    /// the image's offset and velocity, so receivers copy.
    pub send_images: Vec<Vec<Image>>,
    /// (rank, model node ids of ghost surface nodes it owns), in the sender's order.
    pub receives: Vec<(usize, Vec<u32>)>,
}

impl HaloPlan {
    /// Maps a decomposition onto a model built with its owned and ghost grains. Both sides
    /// list (grain, image) ascending and each grain's surface nodes ascending, so the
    /// sender's packing order is the receiver's unpacking order.
    pub fn new(model: &Model, plan: &Decomposition) -> Self {
        let owned = &model.grains[..model.owned_grains];
        let ghosts = &model.grains[model.owned_grains..];
        let surface_in = |grains: &[crate::model::GrainBlock], r: &GhostRef, image: bool| {
            grains
                .iter()
                .find(|g| g.global_id as usize == r.grain && (!image || g.image == r.image))
                .map(|g| g.surface.nodes.clone())
                .unwrap_or_default()
        };
        let (mut sends, mut send_images) = (Vec::new(), Vec::new());
        for (q, refs) in &plan.sends {
            let (mut nodes, mut images) = (Vec::new(), Vec::new());
            for r in refs {
                let surface = surface_in(owned, r, false);
                images.extend(std::iter::repeat_n(r.image, surface.len()));
                nodes.extend(surface);
            }
            sends.push((*q, nodes));
            send_images.push(images);
        }
        let receives = (plan.receives.iter())
            .map(|(q, refs)| {
                (
                    *q,
                    refs.iter()
                        .flat_map(|r| surface_in(ghosts, r, true))
                        .collect(),
                )
            })
            .collect();
        Self {
            sends,
            send_images,
            receives,
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
    /// `cell`: the periodic cell's lengths and rates at the time of x and v (zero
    /// without one), for the images sent.
    pub fn begin(
        &mut self,
        x: &[[f64; 3]],
        v: &[[f64; 3]],
        cell: &CellKinematics,
    ) -> Result<(), MufeError> {
        if self.plan.sends.is_empty() && self.plan.receives.is_empty() {
            return Ok(());
        }
        let mut buffers = self.buffers.take().unwrap_or_default();
        buffers.send.clear();
        for ((_, nodes), images) in self.plan.sends.iter().zip(&self.plan.send_images) {
            for (&n, &image) in nodes.iter().zip(images) {
                let (dx, dv) = (cell.offset(image), cell.velocity(image));
                let (p, u) = (x[n as usize], v[n as usize]);
                buffers
                    .send
                    .extend_from_slice(&[0, 1, 2].map(|k| p[k] + dx[k]));
                buffers
                    .send
                    .extend_from_slice(&[0, 1, 2].map(|k| u[k] + dv[k]));
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
    pub fn exchange(
        &mut self,
        x: &mut [[f64; 3]],
        v: &mut [[f64; 3]],
        cell: &CellKinematics,
    ) -> Result<(), MufeError> {
        self.begin(x, v, cell)?;
        self.end(x, v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::periodic::NO_IMAGE;

    #[test]
    fn an_image_arrives_shifted_by_the_cell_and_moving_with_it() {
        crate::domain::with_test_domain(|domain| {
            let plan = HaloPlan {
                sends: vec![(0, vec![0])],
                send_images: vec![vec![[1, 0, -1]]],
                receives: vec![(0, vec![1])],
            };
            let mut halo = Halo::new(domain, plan);
            let cell = CellKinematics {
                length: [2.0, 3.0, 4.0],
                rate: [-0.5, 0.0, 0.25],
            };
            let mut x = vec![[1.0, 1.0, 1.0], [0.0; 3]];
            let mut v = vec![[0.1, 0.2, 0.3], [0.0; 3]];
            halo.exchange(&mut x, &mut v, &cell).unwrap();
            assert_eq!(x[1], [3.0, 1.0, -3.0]);
            assert_eq!(v[1], [0.1 - 0.5, 0.2, 0.3 - 0.25]);
        });
    }

    #[test]
    fn a_self_halo_copies_owned_into_ghost_nodes_and_reuses_its_buffers() {
        crate::domain::with_test_domain(|domain| {
            // nodes 0, 1 are "owned", 2, 3 their ghost copies (rank 0 sends to itself)
            let plan = HaloPlan {
                sends: vec![(0, vec![0, 1])],
                send_images: vec![vec![NO_IMAGE; 2]],
                receives: vec![(0, vec![2, 3])],
            };
            assert_eq!(plan.bytes_per_step(), 2 * VALUES_PER_NODE * 8);
            let mut halo = Halo::new(domain, plan);
            let mut x = vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0], [0.0; 3], [0.0; 3]];
            let mut v = vec![[-1.0, -2.0, -3.0], [-4.0, -5.0, -6.0], [0.0; 3], [0.0; 3]];
            halo.exchange(&mut x, &mut v, &CellKinematics::default())
                .unwrap();
            let first = halo.send_buffer_identity().unwrap();
            assert_eq!((x[2], x[3]), (x[0], x[1]));
            assert_eq!((v[2], v[3]), (v[0], v[1]));
            for step in 0..3 {
                x[0][0] += 1.0;
                v[1][2] -= 1.0;
                halo.exchange(&mut x, &mut v, &CellKinematics::default())
                    .unwrap();
                assert_eq!((x[2], x[3]), (x[0], x[1]), "step {step}");
                assert_eq!((v[2], v[3]), (v[0], v[1]), "step {step}");
                // the same allocation every step: nothing is allocated per step
                assert_eq!(halo.send_buffer_identity().unwrap(), first);
            }
        });
    }
}
