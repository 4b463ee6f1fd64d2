//! Starting the narrow phase's loads ahead of it.
//!
//! Why: an evaluated entry reads one grain pair's corner of the surface arrays, which the
//! element stage has long evicted (it streams the whole mesh), and reaches it through a
//! chain of dependent lookups: entry → candidate facets → their corners → each corner's
//! facet list. Evaluated one entry after another, every link is a miss the core waits for
//! (profiled on the 2000-sphere block: most of the contact stage). [`warm_up`] walks the
//! same chain for a batch of entries one link at a time, so that the misses of the whole
//! batch are in flight together, and the evaluation then finds its data in cache. It only
//! prefetches: the results do not change.
//!
//! The chain forks at the nearest candidate facet: only its corners' facet rings are read
//! (the curved patch's vertex normals), so a batch is fetched in two rounds, [`warm_up`]
//! for the candidates, then, once the nearest facets are found, [`warm_rings`] for the
//! rings (session 28: fetching every candidate corner's ring head, as before, left the
//! rings themselves to miss one link at a time). A ring is read as its fan of corner
//! pairs (`ContactModel::vertex_fans`), not through its facets: one link fewer.

use super::narrow::{Entry, EvalContext};
use super::vertex_normals::fan_around;

/// Entries whose data is fetched together: enough misses in flight to fill the core's
/// miss buffers, few enough that the batch's lines (≈ 100 each) stay in L2 until used.
pub const WARM_BATCH: usize = 16;

/// Hints the cache line holding `r` into L1.
#[inline(always)]
fn touch<T>(r: &T) {
    // one line, at r's first byte
    crate::lanes::prefetch((r as *const T).cast::<u8>(), 1);
}

/// Prefetches, link by link, what finding the nearest candidate facet of the entries
/// `batch` (indices into `entries`) reads: the slave node's data, the candidate facets and
/// their corners' positions. The rest of an evaluation reads around the nearest facet
/// only, which [`warm_rings`] fetches once it is known.
pub fn warm_up(ctx: &EvalContext, entries: &[Entry], batch: &[u32]) {
    let cm = ctx.cm;
    let batch = || batch.iter().map(|&i| &entries[i as usize]);
    let candidates = |e: &Entry| &ctx.candidates[e.start as usize..e.end as usize];
    for e in batch() {
        touch(&cm.node[e.slave as usize]);
        if let Some(first) = candidates(e).first() {
            touch(first);
        }
    }
    for e in batch() {
        let (k, s) = (e.slave as usize, cm.node[e.slave as usize] as usize);
        touch(&ctx.x[s]);
        touch(&ctx.v[s]);
        if let Some(m) = ctx.mass.get(s) {
            touch(m);
        }
        touch(&cm.node_h[k]);
        touch(&cm.node_area[k]);
        for &f in candidates(e) {
            touch(&cm.facet[f as usize]);
        }
    }
    touch_corner_positions(ctx, batch().flat_map(candidates));
}

/// Prefetches the positions of the corners of `facets`.
fn touch_corner_positions<'a>(ctx: &EvalContext, facets: impl Iterator<Item = &'a u32>) {
    for &f in facets {
        for n in ctx.cm.facet[f as usize] {
            touch(&ctx.x[n as usize]);
        }
    }
}

/// Prefetches, link by link, what the rest of an evaluation reads around each entry's
/// nearest facet (`nearest`, from [`super::narrow::nearest_facet`]): its neighbours, its
/// corners' velocities and sizes, and for each corner the fan of corners around it with
/// their positions (the smooth vertex normals of the curved patch).
pub fn warm_rings(ctx: &EvalContext, nearest: &[Option<u32>]) {
    let cm = ctx.cm;
    let corners = || nearest.iter().flatten().flat_map(|&f| cm.facet[f as usize]);
    for &f in nearest.iter().flatten() {
        touch(&cm.facet_adjacent[f as usize]);
    }
    for n in corners() {
        touch(&cm.surface_index[n as usize]);
        touch(&ctx.v[n as usize]);
    }
    for n in corners() {
        let s = cm.surface_index[n as usize] as usize;
        touch(&cm.vertex_facet_offsets[s]);
        touch(&cm.node_h[s]);
    }
    for n in corners() {
        let fan = fan_around(cm, n);
        if let (Some(first), Some(last)) = (fan.first(), fan.last()) {
            touch(first);
            touch(last);
        }
    }
    // the neighbour across the edge a patch point may be clamped to
    for &f in nearest.iter().flatten() {
        for o in cm.facet_adjacent[f as usize] {
            if let Some(facet) = cm.facet.get(o as usize) {
                touch(facet);
            }
        }
    }
    // around a closed surface's vertex every fan corner comes first in one pair
    for n in corners() {
        let fan = fan_around(cm, n);
        for &[a, _] in fan {
            touch(&ctx.x[a as usize]);
        }
        if let Some(&[_, b]) = fan.last() {
            touch(&ctx.x[b as usize]);
        }
    }
}
