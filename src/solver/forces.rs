//! Internal forces: one pass over the elements that computes each element's forces and
//! adds them straight into the node force array. Chunks of elements that share no node
//! run in parallel, and chunks that do in colour order ([`ElementSchedule`]), so every
//! node receives its forces in a fixed order and 1 and N threads give bitwise identical
//! forces and energies (no atomics, no reduction whose order follows scheduling). Each
//! chunk is evaluated by a loop compiled for its grain's law, so the hot loop has no
//! per-element dispatch ([`super::element_loops`]).

use super::chunk_order::ChunkQueue;
use super::element_loops::{evaluate_chunk, Disjoint, Pass};
pub use super::element_loops::{BadElement, ChunkResult, KernelPath, MAX_PLASTIC_INCREMENT};
use super::element_schedule::ElementSchedule;
use crate::element::deformation_gradient;
use crate::lanes::NodeForce;
use crate::material::{PlasticPoint, Response};
use crate::model::{Model, NONE};
use rayon::prelude::*;

/// Nodes per parallel work item in node passes.
pub const NODE_CHUNK: usize = 4096;

/// Scratch of the force pass (not state): the chunk schedule and per-chunk results.
#[derive(Debug, Default)]
pub struct ElementScratch {
    pub schedule: ElementSchedule,
    /// Which compiled element loop runs.
    pub path: KernelPath,
    /// Per-chunk partial results (strain energy, plastic work, first failure), in
    /// schedule order.
    pub chunk_results: Vec<ChunkResult>,
    /// Runs the large grains' chunks in their order ([`ElementSchedule`]'s `large_order`).
    queue: ChunkQueue,
}

/// Result of an internal-force evaluation.
#[derive(Debug, Clone, Copy)]
pub struct InternalForceSummary {
    /// Σ V0·W of the elastic strains (J): ALLSE.
    pub strain_energy: f64,
    /// Σ V0·T̃:Δεᵖ of this evaluation (J): the step's increment of ALLPD.
    pub plastic_work: f64,
    /// Lowest-index element that failed.
    pub bad_element: Option<BadElement>,
}

impl ElementScratch {
    pub fn new(model: &Model) -> Self {
        let schedule = ElementSchedule::new(model);
        Self {
            chunk_results: vec![ChunkResult::default(); schedule.chunks.len()],
            queue: ChunkQueue::new(&schedule.tasks.large_order),
            schedule,
            path: KernelPath::detect(),
        }
    }
}

/// Computes element forces at positions `x`, commits the plastic state of plastic
/// elements, and writes the assembled internal force of every node into `force`
/// (overwriting it; ghost nodes get zero). A grain that runs whole zeroes its own nodes'
/// forces just before its elements add to them, so they are still in cache.
pub fn compute_internal_forces_into(
    model: &Model,
    x: &[[f64; 3]],
    plastic: &mut [PlasticPoint],
    scratch: &mut ElementScratch,
    force: &mut [NodeForce],
) -> InternalForceSummary {
    // the schedule's node ranges were laid out for this model's nodes
    assert_eq!(force.len(), model.num_nodes());
    let tasks = &scratch.schedule.tasks;
    for r in &tasks.zeroed_before {
        force[r.clone()]
            .par_chunks_mut(NODE_CHUNK)
            .for_each(|part| part.fill(NodeForce::ZERO));
    }
    let pass = Pass {
        model,
        x,
        force: Disjoint::new(force),
        plastic: Disjoint::new(plastic),
    };
    let schedule = &scratch.schedule;
    let path = scratch.path;
    let results = Disjoint::new(&mut scratch.chunk_results);
    let run = |k: usize| {
        // SAFETY: every chunk is one task's (`ScheduleTasks`); tasks that run at the same
        // time share no node and own disjoint element (hence plastic slot) ranges: whole
        // grains share nothing with each other or with the large grains, and a chunk of a
        // large grain runs only after the chunks of earlier colours it shares a node with
        unsafe { *results.get(k) = evaluate_chunk(path, &pass, &schedule.chunks[k]) };
    };
    tasks
        .whole_grains
        .par_iter()
        .zip(&tasks.whole_nodes)
        .for_each(|(g, nodes)| {
            // SAFETY: a grain's nodes are its task's alone
            unsafe { pass.force.slice_mut(nodes.start, nodes.len()) }.fill(NodeForce::ZERO);
            // the elements read these positions in no order a hardware prefetcher follows
            crate::lanes::prefetch(x[nodes.clone()].as_ptr(), nodes.len());
            tasks.whole_chunks[g.clone()].iter().for_each(|&k| run(k));
        });
    // a chunk starts once the chunks of earlier colours it shares a node with have
    // finished (`ChunkOrder`): chunks running together share no node, and each node
    // receives its forces in colour order, as in a sweep colour by colour
    scratch
        .queue
        .run_all(&tasks.large_order, |p| run(tasks.large_chunks[p]));

    let mut strain_energy = 0.0;
    let mut plastic_work = 0.0;
    let mut bad_element: Option<BadElement> = None;
    for r in &scratch.chunk_results {
        strain_energy += r.strain_energy;
        plastic_work += r.plastic_work;
        if let Some(b) = r.bad_element {
            if bad_element.is_none_or(|first| b.element < first.element) {
                bad_element = Some(b);
            }
        }
    }
    InternalForceSummary {
        strain_energy,
        plastic_work,
        bad_element,
    }
}

/// Bytes one force pass moves per owned element, from the layout it reads and writes:
/// the connectivity (16 B) and reference data (80 B) of each element; for each node, its
/// position read (24 B), its force ([`NodeForce`], 32 B) zeroed and then read and written
/// by its elements (96 B), at the mesh's nodes per element; for plastic elements the state read
/// (56 B) and, when the plastic branch is taken (`plastic_written`), written back (56 B;
/// an elastic step leaves it untouched); and the schedule's first-touch lists that the
/// node prefetch reads (4 B a node, 2 B a block of eight elements). Each node's data is
/// counted once per pass: the Morton order keeps a node's elements close enough for the
/// caches to catch the rest. This is the denominator of the bandwidth ceiling in
/// `benches/kernel_roofline.rs`.
pub fn bytes_moved_per_element(
    model: &Model,
    schedule: &ElementSchedule,
    plastic_written: bool,
) -> f64 {
    let elements = model.owned_elements.max(1) as f64;
    let per_element = (std::mem::size_of::<[u32; 4]>()
        + std::mem::size_of::<crate::element::TetReference>()) as f64;
    let per_node = (std::mem::size_of::<[f64; 3]>() + 3 * std::mem::size_of::<NodeForce>()) as f64;
    let plastic_elements = model.plastic_slot.iter().filter(|&&s| s != NONE).count() as f64;
    let state = std::mem::size_of::<PlasticPoint>() as f64;
    let per_plastic = if plastic_written { 2.0 * state } else { state };
    let first_touches: usize = (schedule.chunks.iter())
        .map(|c| {
            let t = &c.first_touches;
            std::mem::size_of_val(&t.nodes[..]) + std::mem::size_of_val(&t.block_end[..])
        })
        .sum();
    per_element
        + per_node * model.owned_nodes as f64 / elements
        + per_plastic * plastic_elements / elements
        + first_touches as f64 / elements
}

/// Deformation gradient and stress response of element `e` at positions `x` from the
/// committed plastic state (nothing is committed): for output and diagnostics.
pub fn element_response(
    model: &Model,
    x: &[[f64; 3]],
    plastic: &[PlasticPoint],
    e: usize,
) -> ([f64; 9], Response) {
    let xe = model.tets[e].map(|n| x[n as usize]);
    let f = deformation_gradient(&xe, &model.tet_reference.get(e).dm_inv);
    let point = model
        .plastic_slot
        .get(e)
        .filter(|&&s| s != NONE)
        .map(|&s| &plastic[s as usize]);
    (f, model.laws[model.tet_law[e] as usize].respond(&f, point))
}
