//! What the narrow phase reads of a master facet's topology, in one cache line.
//!
//! Why: evaluating a cached entry reached the master's topology through a chain of
//! dependent lookups (candidate → facet → corners' surface slots → fan offsets → fans),
//! each a cache miss the pipeline of [`super::prefetch`] could only start once the one
//! before had arrived. Most of the narrow phase's wait for memory was this chain, not the
//! positions (docs/BENCHMARKS.md, session 71). The broad phase therefore lists each
//! candidate facet of an entry as a [`CandidateFacet`] that holds every index the
//! evaluation follows from it: its corners, its neighbours across the edges, and where each
//! corner's edge length and fan are. The entry's candidates are then contiguous lines, and
//! from them the positions and fans are one step away (docs/BENCHMARKS.md, session 72).
//!
//! The values are copies of [`ContactModel`]'s, read in the same order, so an evaluation
//! through a record is the same to the bit as one through the model.

use super::vertex_normals::around;
use super::{ContactModel, NONE};

/// A master facet's corners and the indices an evaluation follows from them (module docs).
/// 64 bytes, aligned to a cache line.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[repr(C, align(64))]
pub struct CandidateFacet {
    /// Model node ids of the corners, in the facet's outward orientation.
    pub corners: [u32; 3],
    /// Global facet index (into [`ContactModel::facet`]).
    pub facet: u32,
    /// The facet across each edge (edge k joins corners k and k+1), or [`NONE`].
    pub adjacent: [u32; 3],
    /// Each corner's flat surface index (where its edge length `node_h` is).
    pub slots: [u32; 3],
    /// Each corner's fan is `ContactModel::vertex_fans[fan_start[k]..fan_end[k]]`.
    pub fan_start: [u32; 3],
    pub fan_end: [u32; 3],
}

const _: () = assert!(std::mem::size_of::<CandidateFacet>() == 64);

impl CandidateFacet {
    /// The record of facet `facet` of `cm`.
    pub fn of(cm: &ContactModel, facet: usize) -> Self {
        let corners = cm.facet[facet];
        let fans = corners.map(|n| around(cm, n));
        Self {
            corners,
            facet: facet as u32,
            adjacent: cm.facet_adjacent[facet],
            slots: corners.map(|n| cm.surface_index[n as usize]),
            fan_start: fans.clone().map(|r| r.start as u32),
            fan_end: fans.map(|r| r.end as u32),
        }
    }

    /// For each facet around corner `k`, its other two corners in orientation order (see
    /// `ContactModel::vertex_fans`).
    #[inline]
    pub fn fan<'a>(&self, cm: &'a ContactModel, k: usize) -> &'a [[u32; 2]] {
        &cm.vertex_fans[self.fan_start[k] as usize..self.fan_end[k] as usize]
    }

    /// The facet across edge `k`, if any.
    #[inline]
    pub fn across(&self, k: usize) -> Option<usize> {
        Some(self.adjacent[k])
            .filter(|&o| o != NONE)
            .map(|o| o as usize)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contact::vertex_normals::fan_around;

    /// Every facet's record holds what the model holds for it.
    #[test]
    fn a_record_holds_the_models_topology() {
        let (solver, _) = crate::contact::tests::pressed_pair_with_lists(1e-3, 3e-4, 1e-5, 2e-5);
        let cm = &solver.model.contact;
        assert!(cm.facet.len() > 100, "{} facets", cm.facet.len());
        for f in 0..cm.facet.len() {
            let r = CandidateFacet::of(cm, f);
            assert_eq!((r.corners, r.facet as usize), (cm.facet[f], f));
            for k in 0..3 {
                let n = cm.facet[f][k];
                assert_eq!(cm.node[r.slots[k] as usize], n);
                assert_eq!(r.fan(cm, k), fan_around(cm, n));
                let o = cm.facet_adjacent[f][k];
                assert_eq!(r.across(k), (o != NONE).then_some(o as usize));
            }
        }
    }
}
