//! Internal forces: rayon over fixed-size element chunks into a per-element force buffer,
//! then a per-node gather in a fixed order through the node→element incidence. Neither
//! step depends on the number of threads, so 1 and N threads give bitwise identical
//! forces and energies (no atomics, no reduction whose order follows scheduling).

use crate::element::{deformation_gradient, tet_forces, ElementForces};
use crate::material::{PlasticPoint, Response};
use crate::model::{Model, NONE};
use rayon::prelude::*;
use std::ops::Range;

/// Elements per parallel work item. Fixed (not derived from the thread count) so that
/// the partial sums — and hence every reduced quantity — are reproducible.
pub const ELEMENT_CHUNK: usize = 2048;
/// Nodes per parallel work item in node passes.
pub const NODE_CHUNK: usize = 4096;

/// Largest equivalent plastic strain one element may gain in one step. Explicit steps are
/// a fraction of a wave transit, so physical plastic flow adds far less; more means the
/// integration is exploding.
pub const MAX_PLASTIC_INCREMENT: f64 = 0.05;

/// Per-element scratch (not state): forces of each element's four corners.
#[derive(Debug, Default)]
pub struct ElementScratch {
    pub corner_forces: Vec<[[f64; 3]; 4]>,
    /// Per-chunk partial results (strain energy, plastic work, worst element).
    pub chunk_results: Vec<ChunkResult>,
    /// First plastic slot of each element chunk (and the total at the end), so that
    /// chunks take disjoint parts of `State::plastic`.
    pub chunk_plastic_start: Vec<usize>,
}

/// An element that failed: inverted, non-finite, or an exploding plastic increment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BadElement {
    pub element: usize,
    /// det F (–).
    pub jacobian: f64,
    /// Equivalent plastic strain gained in this step (–).
    pub plastic_increment: f64,
}

impl BadElement {
    /// What went wrong, for the error line.
    pub fn describe(&self) -> String {
        if self.jacobian.is_nan() || self.jacobian <= 0.0 {
            format!("inverted (det F = {:.3e})", self.jacobian)
        } else if self.plastic_increment > MAX_PLASTIC_INCREMENT {
            format!(
                "gained {:.3e} equivalent plastic strain in one step (limit {MAX_PLASTIC_INCREMENT})",
                self.plastic_increment
            )
        } else {
            format!("has a non-finite force (det F = {:.3e})", self.jacobian)
        }
    }
}

/// Reduction of one element chunk.
#[derive(Debug, Clone, Copy, Default)]
pub struct ChunkResult {
    pub strain_energy: f64,
    pub plastic_work: f64,
    /// First failing element in the chunk, if any.
    pub bad_element: Option<BadElement>,
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
        let chunks = model.owned_elements.div_ceil(ELEMENT_CHUNK);
        let mut chunk_plastic_start = Vec::with_capacity(chunks + 1);
        let mut slots = 0;
        for e in 0..model.owned_elements {
            if e % ELEMENT_CHUNK == 0 {
                chunk_plastic_start.push(slots);
            }
            if model.plastic_slot.get(e).is_some_and(|&s| s != NONE) {
                slots += 1;
            }
        }
        chunk_plastic_start.push(slots);
        Self {
            corner_forces: vec![[[0.0; 3]; 4]; model.owned_elements],
            chunk_results: vec![ChunkResult::default(); chunks],
            chunk_plastic_start,
        }
    }
}

/// Computes element forces at positions `x`, commits the plastic state of plastic
/// elements, and writes the assembled internal force of every node into `force`
/// (overwriting it).
pub fn compute_internal_forces_into(
    model: &Model,
    x: &[[f64; 3]],
    plastic: &mut [PlasticPoint],
    scratch: &mut ElementScratch,
    force: &mut [[f64; 3]],
) -> InternalForceSummary {
    let chunks = scratch.chunk_results.len();
    if chunks > 0 {
        evaluate_chunks(
            model,
            x,
            0..chunks,
            ChunkSlices {
                corners: &mut scratch.corner_forces,
                results: &mut scratch.chunk_results,
                plastic,
                plastic_base: 0,
            },
            &scratch.chunk_plastic_start,
        );
    }

    let corner_forces = &scratch.corner_forces;
    let inc = &model.incidence;
    // ghost nodes (after the owned ones) carry no element forces here
    let (owned, ghosts) = force.split_at_mut(model.owned_nodes);
    ghosts.fill([0.0; 3]);
    owned
        .par_chunks_mut(NODE_CHUNK)
        .enumerate()
        .for_each(|(chunk, out)| {
            let base = chunk * NODE_CHUNK;
            for (k, f) in out.iter_mut().enumerate() {
                let n = base + k;
                let mut acc = [0.0; 3];
                for &entry in &inc.entries[inc.offsets[n] as usize..inc.offsets[n + 1] as usize] {
                    let c = &corner_forces[(entry >> 2) as usize][(entry & 3) as usize];
                    acc[0] += c[0];
                    acc[1] += c[1];
                    acc[2] += c[2];
                }
                *f = acc;
            }
        });

    let mut strain_energy = 0.0;
    let mut plastic_work = 0.0;
    let mut bad_element = None;
    for r in &scratch.chunk_results {
        strain_energy += r.strain_energy;
        plastic_work += r.plastic_work;
        if bad_element.is_none() {
            bad_element = r.bad_element;
        }
    }
    InternalForceSummary {
        strain_energy,
        plastic_work,
        bad_element,
    }
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
    let f = deformation_gradient(&xe, &model.tet_reference[e].dm_inv);
    let point = model
        .plastic_slot
        .get(e)
        .filter(|&&s| s != NONE)
        .map(|&s| &plastic[s as usize]);
    (f, model.laws[model.tet_law[e] as usize].respond(&f, point))
}

/// The disjoint parts of the element arrays a run of chunks works on.
struct ChunkSlices<'a> {
    corners: &'a mut [[[f64; 3]; 4]],
    results: &'a mut [ChunkResult],
    plastic: &'a mut [PlasticPoint],
    /// Slot of `plastic[0]`.
    plastic_base: usize,
}

/// Evaluates a run of element chunks, halving it with `rayon::join` down to single chunks.
/// Every chunk owns its own slices (corner forces, result, plastic states), so the work
/// is race-free without locks, and its result does not depend on the schedule.
fn evaluate_chunks(
    model: &Model,
    x: &[[f64; 3]],
    chunks: Range<usize>,
    part: ChunkSlices<'_>,
    chunk_plastic_start: &[usize],
) {
    if chunks.len() == 1 {
        evaluate_chunk(model, x, chunks.start, part);
        return;
    }
    let mid = chunks.start + chunks.len() / 2;
    let (corners_lo, corners_hi) = part
        .corners
        .split_at_mut((mid - chunks.start) * ELEMENT_CHUNK);
    let (results_lo, results_hi) = part.results.split_at_mut(mid - chunks.start);
    let split = chunk_plastic_start[mid];
    let (plastic_lo, plastic_hi) = part.plastic.split_at_mut(split - part.plastic_base);
    rayon::join(
        || {
            let lo = ChunkSlices {
                corners: corners_lo,
                results: results_lo,
                plastic: plastic_lo,
                plastic_base: part.plastic_base,
            };
            evaluate_chunks(model, x, chunks.start..mid, lo, chunk_plastic_start)
        },
        || {
            let hi = ChunkSlices {
                corners: corners_hi,
                results: results_hi,
                plastic: plastic_hi,
                plastic_base: split,
            };
            evaluate_chunks(model, x, mid..chunks.end, hi, chunk_plastic_start)
        },
    );
}

/// One chunk of elements: forces into its corner slots, energies and the first failure
/// into its result, plastic states committed.
fn evaluate_chunk(model: &Model, x: &[[f64; 3]], chunk: usize, part: ChunkSlices<'_>) {
    let base = chunk * ELEMENT_CHUNK;
    let mut result = ChunkResult::default();
    for (k, corner) in part.corners.iter_mut().enumerate() {
        let e = base + k;
        let t = &model.tets[e];
        let xe = [
            x[t[0] as usize],
            x[t[1] as usize],
            x[t[2] as usize],
            x[t[3] as usize],
        ];
        let law = &model.laws[model.tet_law[e] as usize];
        let slot = model
            .plastic_slot
            .get(e)
            .filter(|&&s| s != NONE)
            .map(|&s| s as usize - part.plastic_base);
        let point = slot.map(|s| &part.plastic[s]);
        let ElementForces {
            nodal,
            strain_energy,
            plastic_work,
            jacobian,
            point: new_point,
        } = tet_forces(&xe, &model.tet_reference[e], law, point);
        let mut plastic_increment = 0.0;
        if let (Some(s), Some(p)) = (slot, new_point) {
            plastic_increment = p.equivalent - part.plastic[s].equivalent;
            part.plastic[s] = p;
        }
        if result.bad_element.is_none()
            && !(jacobian > 0.0
                && strain_energy.is_finite()
                && plastic_increment <= MAX_PLASTIC_INCREMENT)
        {
            result.bad_element = Some(BadElement {
                element: e,
                jacobian,
                plastic_increment,
            });
        }
        result.strain_energy += strain_energy;
        result.plastic_work += plastic_work;
        *corner = nodal;
    }
    part.results[0] = result;
}
