//! Starting the narrow phase's loads ahead of it.
//!
//! Why: an evaluated entry reads one grain pair's corner of the surface arrays, which the
//! element stage has long evicted (it streams the whole mesh), and reaches it through a
//! chain of dependent lookups: entry → slave node and candidate facets → their corners'
//! positions → (nearest facet) → its neighbours and its corners' surface slots → each
//! corner's fan → the fan's positions. Evaluated one entry after another, every link is a
//! miss the core waits for.
//!
//! [`evaluate_pipelined`] walks the chain for batches of [`BATCH`] entries as a software
//! pipeline: at each turn every [`Stage`] handles its own batch, stage s the batch s
//! turns behind the first, and each prefetches the next link for its batch. A link is
//! thus read one whole turn (a batch's evaluation, several µs) after its line was asked
//! for, when it has arrived, and the misses of eight batches overlap the arithmetic
//! instead of stalling it (docs/BENCHMARKS.md, session 34: the two-round prefetch before
//! it stalled on each link's own loads). Only prefetches are added: the results do not
//! change.
//!
//! The chain forks at the nearest candidate facet: only its corners' rings are read (the
//! curved patch's vertex normals). A ring is read as its fan of corner pairs
//! (`ContactModel::vertex_fans`), not through its facets: one link fewer.

use super::narrow::{
    evaluate_entry_on, nearest_facet, Entry, EvalContext, HistoryCursor, PointResult,
};
use super::vertex_normals::fan_around;

/// Entries per batch: enough misses in flight per stage to fill the core's miss buffers,
/// few enough that the lines of all batches in the pipeline (≈ 40 per entry) stay in L2.
pub const BATCH: usize = 16;

/// What each turn does to its batch, in chain order (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Stage {
    /// The slave's surface slot and its candidate list.
    EntryHeads,
    /// The slave's position, velocity and mass; the candidate facets.
    SlaveAndFacets,
    /// The candidate facets' corner positions.
    CandidateCorners,
    /// Finds the nearest candidate; its neighbours, corner velocities and surface slots.
    Nearest,
    /// The corners' fan offsets and sizes; the neighbours' corners.
    RingHeads,
    /// The corners' fans.
    Fans,
    /// The fans' positions.
    FanPositions,
    /// The evaluation itself.
    Evaluate,
}

const STAGES: [Stage; 8] = [
    Stage::EntryHeads,
    Stage::SlaveAndFacets,
    Stage::CandidateCorners,
    Stage::Nearest,
    Stage::RingHeads,
    Stage::Fans,
    Stage::FanPositions,
    Stage::Evaluate,
];

/// Turns from `Nearest` to `Evaluate` inclusive: the nearest facets kept at once.
const NEAREST_KEPT: usize = Stage::Evaluate as usize - Stage::Nearest as usize + 1;

/// Hints the cache line holding `r` into L1.
#[inline(always)]
fn touch<T>(r: &T) {
    crate::lanes::prefetch((r as *const T).cast::<u8>(), 1);
}

/// [`crate::lanes::touch_value`] of node `n`'s vector.
#[inline(always)]
fn touch_node(v: &[[f64; 3]], n: u32) {
    crate::lanes::touch_value(v, n as usize);
}

/// Results looked ahead by the serial passes over them ([`touch_point_nodes`]).
pub const RESULTS_AHEAD: usize = 8;

/// Calls `touch` on the nodes result `r` acts on (its slave and master corners): the
/// serial passes over the results (forces, damper power) read their values scattered over
/// the mesh, and prefetch them this way [`RESULTS_AHEAD`] results early.
#[inline(always)]
pub fn touch_point_nodes(r: &PointResult, touch: impl Fn(usize)) {
    if !r.active {
        return;
    }
    for n in std::iter::once(r.slave).chain(r.masters) {
        touch(n as usize);
    }
}

/// Evaluates the entries `indices` (into `entries`) into `out`, in order, through the
/// prefetch pipeline of the module docs.
pub fn evaluate_pipelined(
    ctx: &EvalContext,
    entries: &[Entry],
    indices: &[u32],
    out: &mut [PointResult],
) {
    let batches = indices.len().div_ceil(BATCH);
    let mut nearest = [[None; BATCH]; NEAREST_KEPT];
    let mut history = HistoryCursor::default();
    for turn in 0..batches + STAGES.len() - 1 {
        for &stage in &STAGES {
            let Some(b) = turn.checked_sub(stage as usize).filter(|&b| b < batches) else {
                continue;
            };
            let range = b * BATCH..indices.len().min((b + 1) * BATCH);
            let batch = &indices[range.clone()];
            let slot = &mut nearest[b % NEAREST_KEPT];
            run_stage(
                ctx,
                entries,
                stage,
                batch,
                slot,
                &mut history,
                &mut out[range],
            );
        }
    }
}

/// One stage's work on one batch.
fn run_stage(
    ctx: &EvalContext,
    entries: &[Entry],
    stage: Stage,
    batch: &[u32],
    nearest: &mut [Option<u32>; BATCH],
    history: &mut HistoryCursor,
    out: &mut [PointResult],
) {
    let cm = ctx.cm;
    let batch = || batch.iter().map(|&i| &entries[i as usize]);
    let candidates = |e: &Entry| &ctx.candidates[e.start as usize..e.end as usize];
    if stage == Stage::Nearest {
        *nearest = [None; BATCH];
        for (f, e) in nearest.iter_mut().zip(batch()) {
            *f = nearest_facet(ctx, e);
        }
    }
    let found = || nearest.iter().flatten();
    let corners = || found().flat_map(|&f| cm.facet[f as usize]);
    match stage {
        Stage::EntryHeads => {
            for e in batch() {
                let k = e.slave as usize;
                touch(&cm.node[k]);
                touch(&cm.node_h[k]);
                touch(&cm.node_area[k]);
                if let (Some(first), Some(last)) = (candidates(e).first(), candidates(e).last()) {
                    touch(first);
                    touch(last);
                }
            }
        }
        Stage::SlaveAndFacets => {
            for e in batch() {
                let s = cm.node[e.slave as usize];
                touch_node(ctx.x, s);
                touch_node(ctx.v, s);
                if let Some(m) = ctx.mass.get(s as usize) {
                    touch(m);
                }
                for &f in candidates(e) {
                    touch(&cm.facet[f as usize]);
                }
            }
        }
        Stage::CandidateCorners => {
            for e in batch() {
                for &f in candidates(e) {
                    for n in cm.facet[f as usize] {
                        touch_node(ctx.x, n);
                    }
                }
            }
        }
        Stage::Nearest => {
            for &f in found() {
                touch(&cm.facet_adjacent[f as usize]);
            }
            for n in corners() {
                touch(&cm.surface_index[n as usize]);
                touch_node(ctx.v, n);
            }
        }
        Stage::RingHeads => {
            for n in corners() {
                let s = cm.surface_index[n as usize] as usize;
                touch(&cm.vertex_facet_offsets[s]);
                touch(&cm.vertex_facet_offsets[s + 1]);
                touch(&cm.node_h[s]);
            }
            // the neighbour across the edge a patch point may be clamped to
            for &f in found() {
                for o in cm.facet_adjacent[f as usize] {
                    if let Some(facet) = cm.facet.get(o as usize) {
                        touch(facet);
                    }
                }
            }
        }
        Stage::Fans => {
            for n in corners() {
                let fan = fan_around(cm, n);
                if let (Some(first), Some(last)) = (fan.first(), fan.last()) {
                    touch(first);
                    touch(last);
                }
            }
            for &f in found() {
                for o in cm.facet_adjacent[f as usize] {
                    if let Some(facet) = cm.facet.get(o as usize) {
                        for n in facet {
                            touch_node(ctx.x, *n);
                        }
                    }
                }
            }
        }
        Stage::FanPositions => {
            // around a closed surface's vertex every fan corner comes first in one pair
            for n in corners() {
                let fan = fan_around(cm, n);
                for &[a, _] in fan {
                    touch_node(ctx.x, a);
                }
                if let Some(&[_, b]) = fan.last() {
                    touch_node(ctx.x, b);
                }
            }
        }
        Stage::Evaluate => {
            for ((r, e), &f) in out.iter_mut().zip(batch()).zip(nearest.iter()) {
                *r = evaluate_entry_on(ctx, e, f, history);
            }
        }
    }
}
