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

use super::narrow::{Entry, EvalContext};

/// Entries whose data is fetched together: enough misses in flight to fill the core's
/// miss buffers, few enough that the batch's lines (≈ 100 each) stay in L2 until used.
pub const WARM_BATCH: usize = 16;

/// Hints the cache line holding `r` into L1.
#[inline(always)]
fn touch<T>(r: &T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch never faults and `r` is a valid reference.
    unsafe {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        _mm_prefetch::<_MM_HINT_T0>((r as *const T).cast::<i8>());
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = r;
}

/// Prefetches, link by link, what evaluating the entries `batch` (indices into `entries`)
/// reads: the slave node's data, the candidate facets, their corners' positions,
/// velocities and facet lists.
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
        touch(&cm.node_h[k]);
        touch(&cm.node_area[k]);
        for &f in candidates(e) {
            touch(&cm.facet[f as usize]);
        }
    }
    for e in batch() {
        for &f in candidates(e) {
            touch(&cm.facet_adjacent[f as usize]);
            for n in cm.facet[f as usize] {
                touch(&ctx.x[n as usize]);
                touch(&cm.surface_index[n as usize]);
            }
        }
    }
    for e in batch() {
        for &f in candidates(e) {
            for n in cm.facet[f as usize] {
                touch(&cm.vertex_facet_offsets[cm.surface_index[n as usize] as usize]);
            }
        }
    }
    for e in batch() {
        for &f in candidates(e) {
            for n in cm.facet[f as usize] {
                let s = cm.surface_index[n as usize] as usize;
                if let Some(f) = cm.vertex_facets.get(cm.vertex_facet_offsets[s] as usize) {
                    touch(f);
                }
            }
        }
    }
}
