//! What the narrow phase reads of a master facet's topology, in two cache lines.
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
//! A record's second line holds the neighbours across its edges and where their far
//! corners' fans are: a curved patch point clamped to an edge (about a quarter of the
//! evaluated entries) is looked for on the neighbour's patch too, which needs the far
//! corner's smooth normal. Reached through the model (facet → far corner's surface slot →
//! fan offsets → fan), that chain was four dependent misses no stage of the pipeline had
//! asked for, and an eighth of the pipeline's time (docs/BENCHMARKS.md, session 73).
//! Only the nearest candidate's second line is read; the candidates' first lines are what
//! every evaluation streams. (The second lines as a list of their own, so that the
//! candidates' first lines are contiguous, measured no faster: one record it is.)
//!
//! The values are copies of [`ContactModel`]'s, read in the same order, so an evaluation
//! through a record is the same to the bit as one through the model.

use super::vertex_normals::around;
use super::{ContactModel, NONE};

/// A master facet's corners and the indices an evaluation follows from them (module docs).
/// Two cache lines: the first is read for every evaluation, the second (from
/// `neighbours` on) only for a patch point clamped to an edge and for an edge's
/// pseudo-normal.
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
    /// The corners of the facet across each edge, in its orientation (`ContactModel::facet`
    /// of `adjacent[k]`), or [`NONE`]s.
    pub neighbours: [[u32; 3]; 3],
    /// The fan of the far corner of `neighbours[k]` (the one not on edge k) is
    /// `ContactModel::vertex_fans[far_fan_start[k]..far_fan_end[k]]` (empty without a
    /// neighbour).
    pub far_fan_start: [u32; 3],
    pub far_fan_end: [u32; 3],
}

const _: () = assert!(std::mem::size_of::<CandidateFacet>() == 128);
// the evaluation's first line ends where the neighbours begin
const _: () = assert!(std::mem::offset_of!(CandidateFacet, neighbours) == 64);

impl CandidateFacet {
    /// The record of facet `facet` of `cm`.
    pub fn of(cm: &ContactModel, facet: usize) -> Self {
        let corners = cm.facet[facet];
        let fans = corners.map(|n| around(cm, n));
        let adjacent = cm.facet_adjacent[facet];
        let neighbours = adjacent.map(|o| match o {
            NONE => [NONE; 3],
            o => cm.facet[o as usize],
        });
        let far_fans = neighbours.map(|o| far_of(corners, o).map_or(0..0, |v| around(cm, v)));
        Self {
            corners,
            facet: facet as u32,
            adjacent,
            slots: corners.map(|n| cm.surface_index[n as usize]),
            fan_start: fans.clone().map(|r| r.start as u32),
            fan_end: fans.map(|r| r.end as u32),
            neighbours,
            far_fan_start: far_fans.clone().map(|r| r.start as u32),
            far_fan_end: far_fans.map(|r| r.end as u32),
        }
    }

    /// The corner of `neighbours[k]` that is not one of this facet's, if there is a
    /// neighbour.
    #[inline]
    pub fn far_corner(&self, k: usize) -> Option<u32> {
        far_of(self.corners, self.neighbours[k])
    }

    /// The fan (as [`Self::fan`]) of [`Self::far_corner`] `k` (empty without one).
    #[inline]
    pub fn far_fan<'a>(&self, cm: &'a ContactModel, k: usize) -> &'a [[u32; 2]] {
        &cm.vertex_fans[self.far_fan_start[k] as usize..self.far_fan_end[k] as usize]
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

/// The corner of a neighbour's `neighbour` corners that is not one of `corners`
/// ([`NONE`]s: no neighbour).
#[inline]
fn far_of(corners: [u32; 3], neighbour: [u32; 3]) -> Option<u32> {
    (neighbour.into_iter()).find(|&v| v != NONE && !corners.contains(&v))
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
                if o != NONE {
                    let neighbour = cm.facet[o as usize];
                    assert_eq!(r.neighbours[k], neighbour);
                    let far: Vec<u32> = (neighbour.into_iter())
                        .filter(|v| !cm.facet[f].contains(v))
                        .collect();
                    assert_eq!(far.len(), 1, "facet {f} edge {k}: {neighbour:?}");
                    assert_eq!(r.far_fan(cm, k), fan_around(cm, far[0]));
                }
            }
        }
    }
}
