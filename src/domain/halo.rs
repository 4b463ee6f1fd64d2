//! Forward halo: every step, the owners of grains mirrored on other ranks send the current
//! positions x_n and velocities v_{n−½} of those grains' surface nodes; receivers overwrite
//! their ghost copies. Contact then sees the same surfaces on every rank that holds a pair,
//! and each rank keeps the contact forces on its own nodes (no reverse exchange needed).
//! Begin/end halves let interior work (internal forces) overlap the communication. The
//! send and receive buffers, request and status lists are kept from step to step, so a
//! step allocates nothing once they have grown to the plan's size.
//!
//! # Trimmed ghosts
//! A ghost touches the receiving rank's grains over a small cap of its surface, so only
//! the nodes of that cap are sent every step. After a plan, and then at every balance
//! check ([`Halo::retarget`]), one *full* exchange sends every surface node with a flag
//! the sender computes: whether the node lies within the *contact zone* of the receiver,
//! |p − c_h| ≤ R_h + ½ M + cushion for a grain h (bounding sphere c_h, R_h, as gathered at
//! the check) owned by the receiver, M the ghost margin and the cushion a few local edge
//! lengths plus the broad-phase reach ([`HaloPlan::new`]). Until the next full exchange only the
//! flagged nodes are sent; the others (*dormant*) keep their values. Why that loses no
//! contact: a dormant node starts ½ M + cushion outside every receiving grain's bounding
//! sphere; as long as it and those grains move less than ½ M together before the next
//! check, every facet within the broad-phase reach of a receiving grain — and every node
//! its curved patch depends on (one ring around its corners) — is fresh, so candidate
//! lists, patches and forces are those of whole ghosts, bit for bit. A full exchange
//! measures how far the dormant nodes had moved meanwhile and warns above ¼ M. Periodic
//! images are always sent whole (their shift changes with the cell).
//!
//! # What contact reads
//! A zone is planned for any contact the grains could make before the next check, but
//! between two rebuilds of the contact lists the narrow phase reads only the nodes the
//! lists name (`crate::contact::mark_nodes_the_lists_read`): far fewer than the zone
//! holds. So after each rebuild every rank tells the owners of its ghosts which zone nodes
//! its lists read ([`Halo::send_only_what_is_read`]), and only those are sent every step
//! until the next rebuild. Before a rebuild the whole zone is refreshed
//! ([`Halo::refresh_zones`]) with the values the step began with, so the broad phase sees
//! what it would have seen had every zone node been sent every step: lists, forces and
//! results are the same to the bit. A new halo (at the start, a restart or a re-partition)
//! does not know the reads and sends whole zones until the first step's lists, built or
//! restored, tell them (`crate::solver::step`); a plan that does not trim
//! (a periodic cell, or `parallel.trim_ghosts = false`) sends whole surfaces throughout.

use super::{Domain, Exchange, ExchangeBuffers, PendingExchange};
use crate::error::MufeError;
use crate::mesh::longest_edge_within_two_rings;
use crate::model::decomposition::{
    contact_zone, contact_zone_cushion, in_contact_zone, Decomposition, GhostRef, GrainBound,
};
use crate::model::periodic::{CellKinematics, Image, NO_IMAGE};
use crate::model::Model;
use std::ops::Range;

/// Values sent per surface node every step: x (3) and v (3).
pub const VALUES_PER_NODE: usize = 6;

/// Values sent per surface node in a full exchange: x, v and the keep flag.
pub const VALUES_PER_NODE_FULL: usize = 7;

/// Message tag of the forward halo.
const FORWARD_TAG: i32 = 101;

/// Message tag of the read flags a receiver sends the owners of its ghosts.
const READS_TAG: i32 = 103;

/// One grain (or image) in a send list: its nodes there and the zone whose nodes are kept.
#[derive(Debug, Clone, Default)]
pub struct SentGrain {
    /// Range of the grain's nodes in the send list.
    pub nodes: Range<usize>,
    pub grain: usize,
    pub image: Image,
    /// Per node of the grain: how far outside a receiving grain's bounding sphere (beyond
    /// ½ M) the node is still kept (m): see [`HaloPlan::new`].
    pub cushion: Vec<f64>,
    /// Spheres (centre, radius R_h + ½ M) of the receiving rank's grains near this one;
    /// `None`: the whole surface is sent.
    pub zone: Option<Vec<([f64; 3], f64)>>,
}

impl SentGrain {
    /// Whether the `k`-th node of the grain, at `p` (image shift included), is sent every
    /// step.
    fn keeps(&self, k: usize, p: [f64; 3]) -> bool {
        (self.zone.as_ref()).is_none_or(|zone| in_contact_zone(zone, p, self.cushion[k]))
    }
}

/// Which model nodes go to / come from each neighbour rank (fixed between re-plans).
#[derive(Debug, Clone, Default)]
pub struct HaloPlan {
    /// (rank, model node ids of owned surface nodes it mirrors), ascending ranks.
    pub sends: Vec<(usize, Vec<u32>)>,
    /// The periodic image each sent node goes to (parallel to `sends`): the sender adds
    /// the image's offset and velocity, so receivers copy.
    pub send_images: Vec<Vec<Image>>,
    /// The grains of each send list, in order (parallel to `sends`).
    pub sent_grains: Vec<Vec<SentGrain>>,
    /// (rank, model node ids of ghost surface nodes it owns), in the sender's order.
    pub receives: Vec<(usize, Vec<u32>)>,
    /// Ghosts are sent their contact zones only ([`HaloPlan::aim`], [`Halo::retarget`]);
    /// false: whole surfaces every step.
    pub trims: bool,
}

impl HaloPlan {
    /// Maps a decomposition onto a model built with its owned and ghost grains. Both sides
    /// list (grain, image) ascending and each grain's surface nodes ascending, so the
    /// sender's packing order is the receiver's unpacking order. Every node is sent until
    /// [`HaloPlan::aim`] gives the grains their contact zones.
    ///
    /// A node's cushion ([`contact_zone_cushion`]) takes the longest facet edge within two
    /// rings of it, and as query half-size the broad-phase margin + ½ the largest mean
    /// surface edge of the grains held here (the receiving grains among them).
    pub fn new(model: &Model, plan: &Decomposition) -> Self {
        let owned = &model.grains[..model.owned_grains];
        let ghosts = &model.grains[model.owned_grains..];
        let find = |grains: &[crate::model::GrainBlock], r: &GhostRef, image: bool| {
            grains
                .iter()
                .position(|g| g.global_id as usize == r.grain && (!image || g.image == r.image))
        };
        let cm = &model.contact;
        // the largest query half-size of a receiving node: margin + ½ h of any held grain
        let query = cm.margin + 0.5 * cm.surfaces.iter().map(|s| s.h_max).fold(0.0, f64::max);
        let (mut sends, mut send_images, mut sent_grains) = (Vec::new(), Vec::new(), Vec::new());
        for (q, refs) in &plan.sends {
            let (mut nodes, mut images, mut grains) = (Vec::new(), Vec::new(), Vec::new());
            for r in refs {
                let Some(mg) = find(owned, r, false) else {
                    continue;
                };
                let surface = &owned[mg].surface.nodes;
                let cushion = longest_edge_within_two_rings(&owned[mg].surface, &model.x0)
                    .into_iter()
                    .map(|e| contact_zone_cushion(e, query))
                    .collect();
                grains.push(SentGrain {
                    nodes: nodes.len()..nodes.len() + surface.len(),
                    grain: r.grain,
                    image: r.image,
                    cushion,
                    zone: None,
                });
                images.extend(std::iter::repeat_n(r.image, surface.len()));
                nodes.extend_from_slice(surface);
            }
            sends.push((*q, nodes));
            send_images.push(images);
            sent_grains.push(grains);
        }
        let receives = (plan.receives.iter())
            .map(|(q, refs)| {
                (
                    *q,
                    refs.iter()
                        .filter_map(|r| find(ghosts, r, true))
                        .flat_map(|g| ghosts[g].surface.nodes.iter().copied())
                        .collect(),
                )
            })
            .collect();
        Self {
            sends,
            send_images,
            sent_grains,
            receives,
            trims: false,
        }
    }

    /// Gives every plain ghost sent its receiver's contact zone (module docs) from the
    /// grains' bounding spheres `bounds` and owners `owner` (global, the same on every
    /// rank) and the ghost margin `margin` (m); from then on the plan trims. Images stay
    /// whole.
    pub fn aim(&mut self, owner: &[u32], bounds: &[GrainBound], margin: f64) {
        self.trims = true;
        for ((q, _), grains) in self.sends.iter().zip(&mut self.sent_grains) {
            for sent in grains.iter_mut() {
                if sent.image != NO_IMAGE {
                    sent.zone = None;
                    continue;
                }
                let widest = sent.cushion.iter().cloned().fold(0.0, f64::max);
                let spheres = contact_zone(owner, bounds, margin, sent.grain, *q, widest);
                sent.zone = Some(spheres);
            }
        }
    }

    /// Bytes sent per step by this rank with whole ghost surfaces.
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
    /// `(rank, values)` of each message of the exchange in flight or next.
    send_counts: Vec<(usize, usize)>,
    recv_counts: Vec<(usize, usize)>,
    /// Positions in the send / receive lists of the nodes exchanged every step.
    active_sends: Vec<Vec<u32>>,
    active_receives: Vec<Vec<u32>>,
    /// Per receive list: whether each node is active (parallel to `plan.receives`).
    received_active: Vec<Vec<bool>>,
    /// What the receivers' contact lists read; `None` until they have told (then every
    /// rank has, so all of them refresh their zones before a rebuild).
    read: Option<ReadFlags>,
    /// Positions of the nodes exchanged every step: the active ones that are read (all
    /// active ones while the reads are unknown).
    stepped_sends: Vec<Vec<u32>>,
    stepped_receives: Vec<Vec<u32>>,
    read_exchange: Exchange,
    /// The read-flag exchange's buffers between rebuilds.
    read_buffers: Option<ExchangeBuffers>,
    /// The next exchange sends every node (after a plan or a retarget).
    full_next: bool,
    full_in_flight: bool,
    /// The next exchange sends every active node, read or not (a refresh before a rebuild).
    zones_next: bool,
    zones_in_flight: bool,
    /// A full exchange has set the active lists once (dormant nodes hold real values).
    trimmed_once: bool,
    /// Largest distance a dormant node had moved when a full exchange refreshed it (m).
    pub dormant_drift: f64,
    /// Above this drift a contact may have been missed (¼ of the ghost margin, m).
    drift_limit: f64,
    warned: bool,
    /// Values sent by this rank and exchanges made, for the mean bytes per step.
    pub values_sent: u64,
    pub exchanges: u64,
    /// The buffers between exchanges (inside `pending` while one is in flight, and inside
    /// `sends_in_flight` from its `end` to the next `begin`).
    buffers: Option<ExchangeBuffers>,
    pending: Option<PendingExchange<'d>>,
    /// The last exchange once its receives are in: its sends complete when the receivers
    /// take them, which `end` does not wait for ([`Exchange::end_receives`]); the next
    /// `begin` does, before it packs the buffer again.
    sends_in_flight: Option<PendingExchange<'d>>,
}

impl<'d> Halo<'d> {
    /// A halo whose first exchange is a full one. `margin`: the ghost margin (m), which
    /// sets the drift warning.
    pub fn new(domain: &'d Domain, plan: HaloPlan, margin: f64) -> Self {
        let (ns, nr) = (plan.sends.len(), plan.receives.len());
        Self {
            domain,
            received_active: plan
                .receives
                .iter()
                .map(|(_, n)| vec![false; n.len()])
                .collect(),
            plan,
            exchange: Exchange::new(FORWARD_TAG),
            send_counts: Vec::with_capacity(ns),
            recv_counts: Vec::with_capacity(nr),
            active_sends: vec![Vec::new(); ns],
            active_receives: vec![Vec::new(); nr],
            read: None,
            stepped_sends: vec![Vec::new(); ns],
            stepped_receives: vec![Vec::new(); nr],
            read_exchange: Exchange::new(READS_TAG),
            read_buffers: None,
            full_next: true,
            full_in_flight: false,
            zones_next: false,
            zones_in_flight: false,
            trimmed_once: false,
            dormant_drift: 0.0,
            drift_limit: 0.25 * margin,
            warned: false,
            values_sent: 0,
            exchanges: 0,
            buffers: Some(ExchangeBuffers::default()),
            pending: None,
            sends_in_flight: None,
        }
    }

    /// New contact zones from the grains' current `bounds` (see [`HaloPlan::aim`]); the
    /// next exchange is a full one. Nothing for a plan that sends whole surfaces. All ranks
    /// must call at the same step.
    pub fn retarget(&mut self, owner: &[u32], bounds: &[GrainBound], margin: f64) {
        if !self.plan.trims {
            return;
        }
        self.plan.aim(owner, bounds, margin);
        self.full_next = true;
    }

    /// Keeps the traffic counters and the drift of the halo this one replaces.
    pub fn carry_counters_from(&mut self, old: &Halo) {
        self.values_sent += old.values_sent;
        self.exchanges += old.exchanges;
        self.dormant_drift = self.dormant_drift.max(old.dormant_drift);
    }

    /// Bytes this rank sends per step now: the zone nodes the receivers read.
    pub fn bytes_per_step(&self) -> usize {
        let nodes: usize = self.stepped_sends.iter().map(Vec::len).sum();
        nodes * VALUES_PER_NODE * 8
    }

    /// Bytes this rank would send per step with whole contact zones.
    pub fn zone_bytes_per_step(&self) -> usize {
        let nodes: usize = self.active_sends.iter().map(Vec::len).sum();
        nodes * VALUES_PER_NODE * 8
    }

    /// Tells the owners of this rank's ghosts which of their nodes its contact lists read
    /// (`read`: one flag per model node, as the lists built at this step mark them) and
    /// learns the same of the ghosts it sends: from the next exchange on, only the zone
    /// nodes that are read are sent (module docs). A blocking exchange between
    /// neighbours: every rank calls at the same step, with no exchange in flight. Nothing
    /// for a plan that does not trim.
    pub fn send_only_what_is_read(&mut self, read: &[bool]) -> Result<(), MufeError> {
        if !self.plan.trims || self.pending.is_some() {
            return Ok(());
        }
        // what this rank reads of each receive list goes back to its sender; the send and
        // receive counts of the forward exchange are free while nothing is in flight
        let flags = self.read.get_or_insert_with(ReadFlags::default);
        let told =
            (self.plan.receives.iter()).map(|(_, nodes)| nodes.iter().map(|&n| read[n as usize]));
        refill(&mut flags.receives, told);
        let mut buffers = self.read_buffers.take().unwrap_or_default();
        buffers.send.clear();
        self.send_counts.clear();
        for ((q, _), told) in self.plan.receives.iter().zip(&flags.receives) {
            buffers
                .send
                .extend(told.iter().map(|&on| if on { 1.0 } else { 0.0 }));
            self.send_counts.push((*q, told.len()));
        }
        self.recv_counts.clear();
        (self.recv_counts).extend(self.plan.sends.iter().map(|(q, nodes)| (*q, nodes.len())));
        let pending = (self.read_exchange).begin_reusing(
            self.domain,
            buffers,
            &self.send_counts,
            &self.recv_counts,
        )?;
        let buffers = self.read_exchange.end_reusing(pending)?;
        let heard = buffers.received().map(|(_, f)| f.iter().map(|&f| f != 0.0));
        refill(&mut flags.sends, heard);
        self.read_buffers = Some(buffers);
        let read = &*flags;
        for (i, active) in self.active_sends.iter().enumerate() {
            step_only_what_is_read(active, Some(&read.sends[i]), &mut self.stepped_sends[i]);
        }
        for (i, active) in self.active_receives.iter().enumerate() {
            let stepped = &mut self.stepped_receives[i];
            step_only_what_is_read(active, Some(&read.receives[i]), stepped);
        }
        Ok(())
    }

    /// Sends every active node once more, read or not, so that a rebuild of the contact
    /// lists at this step sees the whole zones as they are (module docs). A blocking
    /// exchange between neighbours: every rank calls at the same step, with no exchange in
    /// flight; nothing while every active node is sent anyway.
    pub fn refresh_zones(
        &mut self,
        x: &mut [[f64; 3]],
        v: &mut [[f64; 3]],
        cell: &CellKinematics,
    ) -> Result<(), MufeError> {
        if self.read.is_none() || self.pending.is_some() {
            return Ok(());
        }
        self.zones_next = true;
        self.exchange(x, v, cell)
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
        let full = self.full_next;
        let zones = self.zones_next && !full;
        self.complete_sends()?;
        let mut buffers = self.buffers.take().unwrap_or_default();
        buffers.send.clear();
        self.send_counts.clear();
        for (i, ((q, nodes), images)) in
            (self.plan.sends.iter().zip(&self.plan.send_images)).enumerate()
        {
            let start = buffers.send.len();
            let active = &mut self.active_sends[i];
            let pack = |k: usize, send: &mut Vec<f64>| {
                let (dx, dv) = (cell.offset(images[k]), cell.velocity(images[k]));
                let (p, u) = (x[nodes[k] as usize], v[nodes[k] as usize]);
                let p = [0, 1, 2].map(|j| p[j] + dx[j]);
                send.extend_from_slice(&p);
                send.extend_from_slice(&[0, 1, 2].map(|j| u[j] + dv[j]));
                p
            };
            if full {
                active.clear();
                for sent in &self.plan.sent_grains[i] {
                    for k in sent.nodes.clone() {
                        let keep = sent.keeps(k - sent.nodes.start, pack(k, &mut buffers.send));
                        buffers.send.push(if keep { 1.0 } else { 0.0 });
                        if keep {
                            active.push(k as u32);
                        }
                    }
                }
                let read = self.read.as_ref().map(|r| &r.sends[i][..]);
                step_only_what_is_read(active, read, &mut self.stepped_sends[i]);
            } else {
                let sent = if zones {
                    active
                } else {
                    &self.stepped_sends[i]
                };
                for &k in sent.iter() {
                    pack(k as usize, &mut buffers.send);
                }
            }
            self.send_counts.push((*q, buffers.send.len() - start));
        }
        self.recv_counts.clear();
        for (i, (q, nodes)) in self.plan.receives.iter().enumerate() {
            let values = if full {
                nodes.len() * VALUES_PER_NODE_FULL
            } else {
                self.received_list(i, zones).len() * VALUES_PER_NODE
            };
            self.recv_counts.push((*q, values));
        }
        self.values_sent += buffers.send.len() as u64;
        // a refresh is an extra exchange within a step
        self.exchanges += u64::from(!zones);
        self.full_in_flight = full;
        self.full_next = false;
        self.zones_in_flight = zones;
        self.zones_next = false;
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
        let Some(mut pending) = self.pending.take() else {
            return Ok(());
        };
        self.exchange.end_receives(&mut pending)?;
        let (full, zones) = (self.full_in_flight, self.zones_in_flight);
        let per_node = if full {
            VALUES_PER_NODE_FULL
        } else {
            VALUES_PER_NODE
        };
        for (i, ((rank, data), (_, nodes))) in
            pending.received().zip(&self.plan.receives).enumerate()
        {
            let expected = if full {
                nodes.len()
            } else {
                self.received_list(i, zones).len()
            };
            if data.len() != expected * per_node {
                return Err(MufeError::Run(format!(
                    "halo: rank {rank} sent {} values, expected {}",
                    data.len(),
                    expected * per_node
                )));
            }
            if full {
                let (active, flags) = (&mut self.active_receives[i], &mut self.received_active[i]);
                active.clear();
                for (k, d) in data.chunks_exact(per_node).enumerate() {
                    let n = nodes[k] as usize;
                    if self.trimmed_once && !flags[k] {
                        let moved = [0, 1, 2].map(|j| d[j] - x[n][j]);
                        let moved =
                            (moved[0] * moved[0] + moved[1] * moved[1] + moved[2] * moved[2])
                                .sqrt();
                        self.dormant_drift = self.dormant_drift.max(moved);
                    }
                    x[n] = [d[0], d[1], d[2]];
                    v[n] = [d[3], d[4], d[5]];
                    flags[k] = d[6] != 0.0;
                    if flags[k] {
                        active.push(k as u32);
                    }
                }
                let read = self.read.as_ref().map(|r| &r.receives[i][..]);
                step_only_what_is_read(active, read, &mut self.stepped_receives[i]);
            } else {
                for (&k, d) in
                    (self.received_list(i, zones).iter()).zip(data.chunks_exact(per_node))
                {
                    let n = nodes[k as usize] as usize;
                    x[n] = [d[0], d[1], d[2]];
                    v[n] = [d[3], d[4], d[5]];
                }
            }
        }
        if full {
            self.trimmed_once = true;
            if self.dormant_drift > self.drift_limit && !self.warned {
                self.warned = true;
                crate::error::report_line(format_args!(
                    "rank {}: warning: ghost nodes outside the trimmed halo moved {:.3e} m between two balance checks (more than a quarter of the ghost margin, {:.3e} m); a contact may have been missed: lower parallel.check_interval or set parallel.trim_ghosts = false",
                    self.domain.rank(),
                    self.dormant_drift,
                    self.drift_limit
                ));
            }
        }
        self.sends_in_flight = Some(pending);
        Ok(())
    }

    /// Completes the sends of the last exchange, whose receives are in, and takes its
    /// buffers back.
    fn complete_sends(&mut self) -> Result<(), MufeError> {
        if let Some(sent) = self.sends_in_flight.take() {
            self.buffers = Some(self.exchange.end_reusing(sent)?);
        }
        Ok(())
    }

    /// The positions in receive list `i` of the nodes a step's exchange brings: the active
    /// ones in a refresh (`zones`), else those that are read.
    fn received_list(&self, i: usize, zones: bool) -> &[u32] {
        if zones {
            &self.active_receives[i]
        } else {
            &self.stepped_receives[i]
        }
    }

    /// Start of the send buffer and its capacity (for the test that steps reuse it).
    pub fn send_buffer_identity(&self) -> Option<(*const f64, usize)> {
        let in_flight = self.sends_in_flight.as_ref().map(|p| &p.buffers);
        (self.buffers.as_ref().or(in_flight)).map(|b| (b.send.as_ptr(), b.send.capacity()))
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

/// Per send / receive list and node: whether the receiver's contact lists read it.
#[derive(Debug, Default)]
struct ReadFlags {
    sends: Vec<Vec<bool>>,
    receives: Vec<Vec<bool>>,
}

/// `lists` = one list per item of `from`, refilled in place (no allocation once grown).
fn refill<I: Iterator<Item = bool>>(lists: &mut Vec<Vec<bool>>, from: impl Iterator<Item = I>) {
    let mut n = 0;
    for flags in from {
        if n == lists.len() {
            lists.push(Vec::new());
        }
        lists[n].clear();
        lists[n].extend(flags);
        n += 1;
    }
    lists.truncate(n);
}

/// `stepped` = the positions of `active` that are `read` (all of them while unknown).
fn step_only_what_is_read(active: &[u32], read: Option<&[bool]>, stepped: &mut Vec<u32>) {
    stepped.clear();
    match read {
        Some(read) => stepped.extend(active.iter().filter(|&&k| read[k as usize])),
        None => stepped.extend_from_slice(active),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_image_arrives_shifted_by_the_cell_and_moving_with_it() {
        crate::domain::with_test_domain(|domain| {
            let plan = HaloPlan {
                sends: vec![(0, vec![0])],
                send_images: vec![vec![[1, 0, -1]]],
                sent_grains: vec![vec![SentGrain {
                    nodes: 0..1,
                    image: [1, 0, -1],
                    ..Default::default()
                }]],
                receives: vec![(0, vec![1])],
                trims: false,
            };
            let mut halo = Halo::new(domain, plan, 1.0);
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
                sent_grains: vec![vec![SentGrain {
                    nodes: 0..2,
                    ..Default::default()
                }]],
                receives: vec![(0, vec![2, 3])],
                trims: false,
            };
            assert_eq!(plan.bytes_per_step(), 2 * VALUES_PER_NODE * 8);
            let mut halo = Halo::new(domain, plan, 1.0);
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

    /// Margin, owners and bounding spheres of the trimmed test halos: grain 0 at the origin
    /// and grain 1 centred at x = 2.2, both of radius 1, on rank 0.
    const TEST_MARGIN: f64 = 0.4;
    const TEST_OWNER: [u32; 2] = [0, 0];
    const TEST_BOUNDS: [GrainBound; 2] = [
        GrainBound {
            centre: [0.0; 3],
            radius: 1.0,
        },
        GrainBound {
            centre: [2.2, 0.0, 0.0],
            radius: 1.0,
        },
    ];

    /// A trimming self-halo of grain 0 (nodes 0..`n`, each with `cushion`) mirrored into
    /// nodes `n`..2`n` for grain 1, aimed at grain 1's contact zone (the next exchange is
    /// a full one).
    fn trimmed_self_halo(domain: &Domain, n: u32, cushion: f64) -> Halo<'_> {
        let plan = HaloPlan {
            sends: vec![(0, (0..n).collect())],
            send_images: vec![vec![NO_IMAGE; n as usize]],
            sent_grains: vec![vec![SentGrain {
                nodes: 0..n as usize,
                grain: 0,
                cushion: vec![cushion; n as usize],
                ..Default::default()
            }]],
            receives: vec![(0, (n..2 * n).collect())],
            trims: true,
        };
        let mut halo = Halo::new(domain, plan, TEST_MARGIN);
        retarget_at_the_test_zone(&mut halo);
        halo
    }

    fn retarget_at_the_test_zone(halo: &mut Halo) {
        halo.retarget(&TEST_OWNER, &TEST_BOUNDS, TEST_MARGIN);
    }

    #[test]
    fn a_trimmed_halo_sends_the_contact_zone_and_refreshes_the_rest_at_a_retarget() {
        crate::domain::with_test_domain(|domain| {
            // grain 0 (nodes 0–2) is mirrored into nodes 3–5 for grain 1, centred at
            // x = 2.2 with radius 1: only node 0, at x = 1, lies within its contact zone
            let mut halo = trimmed_self_halo(domain, 3, 0.1);
            let cell = CellKinematics::default();
            let mut x = vec![
                [1.0, 0.0, 0.0],
                [-1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [9.0; 3],
                [9.0; 3],
                [9.0; 3],
            ];
            let mut v = vec![[0.0; 3]; 6];
            // the full exchange copies every node
            halo.exchange(&mut x, &mut v, &cell).unwrap();
            assert_eq!(&x[3..], &x[..3]);
            assert_eq!(halo.bytes_per_step(), VALUES_PER_NODE * 8);
            // then only the node in the zone follows its owner
            for n in 0..3 {
                x[n][2] += 0.01;
            }
            halo.exchange(&mut x, &mut v, &cell).unwrap();
            assert_eq!(x[3], x[0]);
            assert_eq!((x[4], x[5]), ([-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]));
            assert_eq!(halo.dormant_drift, 0.0);
            // a retarget refreshes the dormant nodes and measures how far they had gone
            retarget_at_the_test_zone(&mut halo);
            halo.exchange(&mut x, &mut v, &cell).unwrap();
            assert_eq!(&x[3..], &x[..3]);
            assert!((halo.dormant_drift - 0.01).abs() < 1e-15);
            // without a zone (images, or trimming off) every node is sent
            halo.plan.sent_grains[0][0].zone = None;
            halo.full_next = true;
            halo.exchange(&mut x, &mut v, &cell).unwrap();
            assert_eq!(halo.bytes_per_step(), 3 * VALUES_PER_NODE * 8);
        });
    }

    #[test]
    fn after_a_rebuild_only_the_zone_nodes_contact_reads_follow_and_a_refresh_brings_the_rest() {
        crate::domain::with_test_domain(|domain| {
            // grain 0 (nodes 0–3) mirrored into nodes 4–7; the zone (radius 1 around x = 2.2,
            // cushion 0.5) holds nodes 0, 1 and 2, contact reads nodes 1 and 3 (3 is dormant)
            let mut halo = trimmed_self_halo(domain, 4, 0.5);
            let cell = CellKinematics::default();
            let mut x = vec![
                [1.0, 0.0, 0.0],
                [0.9, 0.3, 0.0],
                [0.8, 0.0, 0.5],
                [-1.0, 0.0, 0.0],
                [9.0; 3],
                [9.0; 3],
                [9.0; 3],
                [9.0; 3],
            ];
            let mut v = vec![[0.0; 3]; 8];
            halo.exchange(&mut x, &mut v, &cell).unwrap();
            assert_eq!(&x[4..], &x[..4]);
            assert_eq!(halo.zone_bytes_per_step(), 3 * VALUES_PER_NODE * 8);
            assert_eq!(halo.bytes_per_step(), 3 * VALUES_PER_NODE * 8);
            let mut read = vec![false; 8];
            (read[5], read[7]) = (true, true);
            halo.send_only_what_is_read(&read).unwrap();
            // only node 1 is in the zone and read
            assert_eq!(halo.bytes_per_step(), VALUES_PER_NODE * 8);
            // the next rebuild's flags travel in the same send buffer
            let flag_buffer = |h: &Halo| h.read_buffers.as_ref().map(|b| b.send.as_ptr());
            let first = flag_buffer(&halo);
            halo.send_only_what_is_read(&read).unwrap();
            assert!(first.is_some() && flag_buffer(&halo) == first);
            assert_eq!(halo.bytes_per_step(), VALUES_PER_NODE * 8);
            assert_eq!(halo.zone_bytes_per_step(), 3 * VALUES_PER_NODE * 8);
            let before = x.clone();
            for n in 0..4 {
                x[n][1] += 0.01;
                v[n][2] -= 1.0;
            }
            halo.exchange(&mut x, &mut v, &cell).unwrap();
            assert_eq!((x[5], v[5]), (x[1], v[1]));
            for (ghost, stale) in [(4, 4), (6, 6), (7, 7)] {
                assert_eq!(x[ghost], before[stale], "node {ghost} kept its value");
            }
            // a refresh before a rebuild sends the whole zone, the dormant node stays
            halo.refresh_zones(&mut x, &mut v, &cell).unwrap();
            assert_eq!(&x[4..7], &x[..3]);
            assert_eq!(&v[4..7], &v[..3]);
            assert_eq!(x[7], before[7]);
            // and the steps after it go on sending what is read
            x[1][0] += 0.01;
            x[0][0] += 0.01;
            halo.exchange(&mut x, &mut v, &cell).unwrap();
            assert_eq!(x[5], x[1]);
            assert_ne!(x[4], x[0]);
            // a retarget's full exchange sends all, then still only what is read
            retarget_at_the_test_zone(&mut halo);
            halo.exchange(&mut x, &mut v, &cell).unwrap();
            assert_eq!(&x[4..], &x[..4]);
            assert_eq!(halo.bytes_per_step(), VALUES_PER_NODE * 8);
        });
    }
}
