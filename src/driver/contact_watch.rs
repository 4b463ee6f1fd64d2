//! Grain-pair contact counts for the history rows, and the failure watch of a staged
//! run: the first gap opening between grains that touched when the watched stage began
//! (the last stage ending on failure, else the last stage). Sampled at history rows, so
//! the opening time is known to one history interval.

use super::history::{FABRIC_COLUMNS, INTERNAL, KINETIC};
use crate::contact::fabric::{merge_pairs, pair_partials, PairContact, PairPartial};
use crate::domain::Domain;
use crate::model::periodic::Image;
use crate::solver::Solver;

/// The grain-pair contacts of the last contact evaluation, merged over ranks: `Some` on
/// rank 0, `None` elsewhere (`partials`, `encoded`: reusable buffers). All ranks must call.
pub fn gather_pair_contacts(
    domain: &Domain,
    solver: &Solver,
    partials: &mut Vec<PairPartial>,
    encoded: &mut Vec<f64>,
) -> Option<Vec<PairContact>> {
    pair_partials(
        &solver.model,
        &solver.state.x,
        &solver.scratch.contact,
        &solver.state.cell_kinematics(&solver.model),
        partials,
    );
    encoded.clear();
    for p in partials.iter() {
        p.encode(encoded);
    }
    domain
        .gather_f64_to_root(encoded)
        .map(|all| merge_pairs(&all))
}

/// A pair that stopped touching.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GapOpening {
    pub a: u32,
    pub b: u32,
    /// Time of the first history row without the contact (s).
    pub time: f64,
    /// Axial strain since the start of the watched stage (–).
    pub axial_strain: f64,
}

/// What rank 0 keeps between history rows.
#[derive(Debug, Default)]
pub struct ContactWatch {
    partials: Vec<PairPartial>,
    encoded: Vec<f64>,
    /// Stage whose start defines "initially touching" (staged runs with a cell only).
    watched_stage: Option<usize>,
    /// Pairs touching at the first row of the watched stage, by (a, b, image).
    touching: Option<Vec<(u32, u32, Image)>>,
    pub first_opening: Option<GapOpening>,
    /// Largest ALLKE/ALLIE seen at the history rows of each stage (quasi-static check).
    pub max_kinetic_ratio: Vec<f64>,
}

impl ContactWatch {
    pub fn new(solver: &Solver) -> Self {
        let watched_stage = solver
            .model
            .stages
            .as_ref()
            .filter(|p| p.staged && p.cell.is_some())
            .map(|p| {
                (p.stages.iter())
                    .rposition(|s| s.until.failure.is_some())
                    .unwrap_or(p.stages.len() - 1)
            });
        Self {
            watched_stage,
            ..Default::default()
        }
    }

    /// Fills the contact counts of a history row (its last [`FABRIC_COLUMNS`]) on rank 0
    /// and updates the watch. All ranks must call.
    pub fn fill_row(&mut self, domain: &Domain, solver: &Solver, row: &mut [f64]) {
        if !solver.model.contact.grain_contact {
            return;
        }
        let Some(pairs) =
            gather_pair_contacts(domain, solver, &mut self.partials, &mut self.encoded)
        else {
            return;
        };
        let at = row.len() - FABRIC_COLUMNS.len();
        row[at] = pairs.len() as f64;
        row[at + 1] = pairs.iter().filter(|p| p.sliding).count() as f64;
        self.watch(solver, &pairs, row[0]);
    }

    /// Records ALLKE/ALLIE of a reduced history row against `stage` (0-based), the
    /// stage in force when the row was written.
    pub fn observe_reduced(&mut self, stage: usize, row: &[f64]) {
        if self.max_kinetic_ratio.len() <= stage {
            self.max_kinetic_ratio.resize(stage + 1, 0.0);
        }
        if row[INTERNAL] > 0.0 {
            let r = &mut self.max_kinetic_ratio[stage];
            *r = r.max(row[KINETIC] / row[INTERNAL]);
        }
    }

    fn watch(&mut self, solver: &Solver, pairs: &[PairContact], time: f64) {
        let (Some(stage), Some(plan)) = (self.watched_stage, &solver.model.stages) else {
            return;
        };
        let progress = &solver.state.stages;
        if progress.index != stage || progress.finished || self.first_opening.is_some() {
            return;
        }
        let now: Vec<(u32, u32, Image)> = pairs.iter().map(|p| (p.a, p.b, p.image)).collect();
        let Some(before) = &self.touching else {
            self.touching = Some(now);
            return;
        };
        if let Some(&(a, b, _)) = before.iter().find(|k| now.binary_search(k).is_err()) {
            let axial_strain = plan
                .measure(&progress.wall_displacements, &progress.wall_forces)
                .map_or(0.0, |m| plan.stage_axial_strain(progress, &m));
            self.first_opening = Some(GapOpening {
                a,
                b,
                time,
                axial_strain,
            });
        }
    }
}
