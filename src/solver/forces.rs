//! Internal forces: rayon over fixed-size element chunks into a per-element force buffer,
//! then a per-node gather in a fixed order through the node→element incidence. Neither
//! step depends on the number of threads, so 1 and N threads give bitwise identical
//! forces and energies (no atomics, no reduction whose order follows scheduling).

use crate::element::{tet_forces, ElementForces};
use crate::model::Model;
use rayon::prelude::*;

/// Elements per parallel work item. Fixed (not derived from the thread count) so that
/// the partial sums — and hence every reduced quantity — are reproducible.
pub const ELEMENT_CHUNK: usize = 2048;
/// Nodes per parallel work item in node passes.
pub const NODE_CHUNK: usize = 4096;

/// Per-element scratch (not state): forces of each element's four corners.
#[derive(Debug, Default)]
pub struct ElementScratch {
    pub corner_forces: Vec<[[f64; 3]; 4]>,
    /// Per-chunk partial results (strain energy, worst element).
    pub chunk_results: Vec<ChunkResult>,
}

/// Reduction of one element chunk.
#[derive(Debug, Clone, Copy, Default)]
pub struct ChunkResult {
    pub strain_energy: f64,
    /// First element in the chunk with det F ≤ 0 or a non-finite force, if any.
    pub bad_element: Option<(usize, f64)>,
}

/// Result of an internal-force evaluation.
#[derive(Debug, Clone, Copy)]
pub struct InternalForceSummary {
    /// Σ V0·W (J).
    pub strain_energy: f64,
    /// Lowest-index element that inverted or produced a non-finite force, with det F.
    pub bad_element: Option<(usize, f64)>,
}

impl ElementScratch {
    pub fn new(model: &Model) -> Self {
        Self {
            corner_forces: vec![[[0.0; 3]; 4]; model.owned_elements],
            chunk_results: vec![
                ChunkResult::default();
                model.owned_elements.div_ceil(ELEMENT_CHUNK)
            ],
        }
    }
}

/// Computes element forces at positions `x` and writes the assembled internal force of
/// every node into `force` (overwriting it).
pub fn compute_internal_forces_into(
    model: &Model,
    x: &[[f64; 3]],
    scratch: &mut ElementScratch,
    force: &mut [[f64; 3]],
) -> InternalForceSummary {
    scratch
        .corner_forces
        .par_chunks_mut(ELEMENT_CHUNK)
        .zip(scratch.chunk_results.par_iter_mut())
        .enumerate()
        .for_each(|(chunk, (out, result))| {
            let base = chunk * ELEMENT_CHUNK;
            let mut energy = 0.0;
            let mut bad = None;
            for (k, corner) in out.iter_mut().enumerate() {
                let e = base + k;
                let t = &model.tets[e];
                let xe = [
                    x[t[0] as usize],
                    x[t[1] as usize],
                    x[t[2] as usize],
                    x[t[3] as usize],
                ];
                let law = &model.laws[model.tet_law[e] as usize];
                let ElementForces {
                    nodal,
                    strain_energy,
                    jacobian,
                } = tet_forces(&xe, &model.tet_reference[e], law);
                if bad.is_none() && !(jacobian > 0.0 && strain_energy.is_finite()) {
                    bad = Some((e, jacobian));
                }
                energy += strain_energy;
                *corner = nodal;
            }
            *result = ChunkResult {
                strain_energy: energy,
                bad_element: bad,
            };
        });

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
    let mut bad_element = None;
    for r in &scratch.chunk_results {
        strain_energy += r.strain_energy;
        if bad_element.is_none() {
            bad_element = r.bad_element;
        }
    }
    InternalForceSummary {
        strain_energy,
        bad_element,
    }
}
