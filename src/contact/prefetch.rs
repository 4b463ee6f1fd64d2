//! Starting the narrow phase's loads ahead of it.
//!
//! Why: an evaluated entry reads one grain pair's corner of the surface arrays, which the
//! element stage has long evicted (it streams the whole mesh), and reaches it through a
//! chain of dependent lookups: entry → its candidate facets' records
//! ([`super::candidate_facet`]) → their corners' positions → (nearest facet) → its corners'
//! fans, and its neighbours' far corners and their fans → the fans' positions. Evaluated
//! one entry after another, every link is a miss the core waits for.
//!
//! [`evaluate_pipelined`] walks the chain for batches of [`BATCH`] entries as a software
//! pipeline: at each turn every [`Stage`] handles its own batch, stage s the batch s
//! turns behind the first, and each prefetches the next link for its batch. A link is
//! thus read one whole turn (a batch's evaluation, several µs) after its line was asked
//! for, when it has arrived, and the misses of the batches in flight overlap the
//! arithmetic instead of stalling it (docs/BENCHMARKS.md, session 34: the two-round
//! prefetch before it stalled on each link's own loads). Only prefetches are added: the
//! results do not change.
//!
//! The chain forks at the nearest candidate facet: only its corners' rings are read (the
//! curved patch's vertex normals). A ring is read as its fan of corner pairs
//! (`ContactModel::vertex_fans`), whose place the facet's record holds, as it holds the
//! fans of the neighbours' far corners (a patch point clamped to an edge needs the far
//! corner's normal). Those fans' positions are not asked for ahead: most are on the
//! facet's own corners' rings.

use super::narrow::{
    evaluate_entry_on, nearest_facet, Entry, EvalContext, HistoryCursor, PointResult,
};

/// Entries per batch: enough misses in flight per stage to fill the core's miss buffers,
/// few enough that the lines of all batches in the pipeline (≈ 40 per entry) stay in L2.
pub const BATCH: usize = 16;

/// What each turn does to its batch, in chain order (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Stage {
    /// The slave's surface records and its candidate facets' records.
    EntryHeads,
    /// The slave's position, velocity and mass; the candidate facets' corner positions.
    SlaveAndCorners,
    /// Finds the nearest candidate; its corners' fans, edges and velocities, and its
    /// record's second line (the neighbours across its edges).
    Nearest,
    /// The fans' positions; the neighbours' far corners' positions and fans.
    FanPositions,
    /// The evaluation itself.
    Evaluate,
}

const STAGES: [Stage; 5] = [
    Stage::EntryHeads,
    Stage::SlaveAndCorners,
    Stage::Nearest,
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
///
/// On a CPU with AVX2 and FMA the whole evaluation is compiled for them (the portable
/// build's scalar code is SSE2, two-operand, and spends a fifth of the evaluation's time
/// copying registers). The results are the same to the bit on both paths: the code asks
/// for no fused multiply–add, so none is formed, and IEEE operations round alike.
pub fn evaluate_pipelined(
    ctx: &EvalContext,
    entries: &[Entry],
    indices: &[u32],
    out: &mut [PointResult],
) {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            // SAFETY: the CPU supports AVX2 and FMA (checked above)
            return unsafe { evaluate_pipelined_avx2(ctx, entries, indices, out) };
        }
    }
    pipeline(ctx, entries, indices, out)
}

/// # Safety
/// The CPU must support AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn evaluate_pipelined_avx2(
    ctx: &EvalContext,
    entries: &[Entry],
    indices: &[u32],
    out: &mut [PointResult],
) {
    pipeline(ctx, entries, indices, out)
}

/// [`evaluate_pipelined`] on the instruction set of its caller: everything it runs per
/// entry is inlined into it.
#[inline(always)]
fn pipeline(ctx: &EvalContext, entries: &[Entry], indices: &[u32], out: &mut [PointResult]) {
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
#[inline(always)]
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
    let records = |e: &Entry| &ctx.facets[e.start as usize..e.end as usize];
    if stage == Stage::Nearest {
        *nearest = [None; BATCH];
        for (f, e) in nearest.iter_mut().zip(batch()) {
            *f = nearest_facet(ctx, e);
        }
    }
    let found = || nearest.iter().flatten().map(|&i| &ctx.facets[i as usize]);
    match stage {
        Stage::EntryHeads => {
            for e in batch() {
                let k = e.slave as usize;
                touch(&cm.node[k]);
                touch(&cm.node_h[k]);
                touch(&cm.node_area[k]);
                for r in records(e) {
                    touch(r);
                }
            }
        }
        Stage::SlaveAndCorners => {
            for e in batch() {
                let s = cm.node[e.slave as usize];
                touch_node(ctx.x, s);
                touch_node(ctx.v, s);
                if let Some(m) = ctx.mass.get(s as usize) {
                    touch(m);
                }
                for r in records(e) {
                    for n in r.corners {
                        touch_node(ctx.x, n);
                    }
                }
            }
        }
        Stage::Nearest => {
            for r in found() {
                for k in 0..3 {
                    let fan = r.fan(cm, k);
                    if let (Some(first), Some(last)) = (fan.first(), fan.last()) {
                        touch(first);
                        touch(last);
                    }
                    touch(&cm.node_h[r.slots[k] as usize]);
                    touch_node(ctx.v, r.corners[k]);
                }
                // the neighbours across the edges a patch point may be clamped to
                touch(&r.neighbours);
            }
        }
        Stage::FanPositions => {
            for r in found() {
                for k in 0..3 {
                    // around a closed surface's vertex every fan corner comes first in one
                    // pair
                    let fan = r.fan(cm, k);
                    for &[a, _] in fan {
                        touch_node(ctx.x, a);
                    }
                    if let Some(&[_, b]) = fan.last() {
                        touch_node(ctx.x, b);
                    }
                    // the neighbour's far corner and its fan (the others are this
                    // facet's)
                    if let Some(far) = r.far_corner(k) {
                        touch_node(ctx.x, far);
                        let far_fan = r.far_fan(cm, k);
                        if let (Some(first), Some(last)) = (far_fan.first(), far_fan.last()) {
                            touch(first);
                            touch(last);
                        }
                    }
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contact::narrow::evaluate_entry;
    use crate::contact::tests::{pressed_pair_with_lists, result_bits};
    use crate::contact::{ContactKey, FrictionPoint};

    /// Two spheres pressed together, every node moved a little and given a velocity, half
    /// the contact points with a friction history: the pipeline on this CPU's instruction
    /// set, the same pipeline compiled for the portable baseline, and one entry at a time
    /// through the model's arrays agree to the bit.
    #[test]
    fn every_evaluation_path_gives_the_same_bits() {
        let (solver, x0) = pressed_pair_with_lists(1.0e-3, 6.0e-5, 8.0e-5, 2.0e-5);
        let (model, lists) = (&solver.model, &solver.scratch.contact.lists);
        let cm = &model.contact;
        let mut rng = crate::math::SplitMix64(7);
        let mut x = x0;
        let mut v = vec![[0.0; 3]; x.len()];
        for &n in &cm.node {
            let (stray, speed) = (rng.direction(), rng.direction());
            for i in 0..3 {
                x[n as usize][i] += 5.0e-6 * stray[i];
                v[n as usize][i] = 0.1 * speed[i];
            }
        }
        let mut history: Vec<FrictionPoint> = (lists.entries.iter().step_by(2))
            .map(|e| {
                let pass = lists.passes[e.pass as usize];
                let (sg, mg) = (
                    &cm.surfaces[pass.slave as usize],
                    &cm.surfaces[pass.master as usize],
                );
                let key = ContactKey::of(sg, mg, cm.node[e.slave as usize]);
                let traction = rng.direction().map(|t| 1.0e12 * t);
                FrictionPoint { key, traction }
            })
            .collect();
        history.sort_by_key(|p| p.key);
        let ctx = EvalContext {
            cm,
            passes: &lists.passes,
            facets: &lists.candidate_facets,
            x: &x,
            v: &v,
            mass: &model.mass,
            dt: model.dt,
            history: &history,
            friction: true,
        };
        let all: Vec<u32> = (0..lists.entries.len() as u32).collect();
        let mut dispatched = vec![PointResult::default(); all.len()];
        let mut portable = dispatched.clone();
        evaluate_pipelined(&ctx, &lists.entries, &all, &mut dispatched);
        pipeline(&ctx, &lists.entries, &all, &mut portable);
        let mut active = 0;
        for (i, e) in lists.entries.iter().enumerate() {
            let one = result_bits(&evaluate_entry(&ctx, e));
            assert_eq!(result_bits(&dispatched[i]), one, "entry {i}");
            assert_eq!(result_bits(&portable[i]), one, "entry {i}");
            active += usize::from(dispatched[i].active);
        }
        assert!(active > 100, "{active} active of {}", all.len());
        assert!(dispatched.iter().any(|r| r.sliding), "no point slides");
    }
}
