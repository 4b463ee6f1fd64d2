//! Everything that evolves during a run, in one serde type: a checkpoint is this plus the
//! scene. Scratch buffers (`crate::solver::Scratch`, contact candidate lists, element
//! corner forces) are not state: they are rebuilt from the model and the state.

use super::periodic::CellState;
use crate::boundary::stages::StageProgress;
use crate::contact::ContactState;
use crate::energy::{EnergyLedger, WorkAccumulator};
use crate::material::PlasticPoint;
use crate::model::decomposition::Partition;
use crate::model::periodic::CellKinematics;
use serde::{Deserialize, Serialize};

/// Reaction of a prescribed motion at the last step.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Reaction {
    /// Force the motion exerts on the grain (N).
    pub force: [f64; 3],
    /// Moment about the motion's current centre (N·m).
    pub moment: [f64; 3],
    /// Centre displacement since t = 0 (m).
    pub displacement: [f64; 3],
    /// Rotation vector of the prescribed rotation (rad).
    pub rotation: [f64; 3],
}

/// Everything that evolves during a run on one rank (a checkpoint is this plus the scene).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct State {
    /// t_n (s).
    pub time: f64,
    /// n.
    pub step: u64,
    /// The clock's anchor: t_n = time_origin + (n − step_origin) Δt. (0, 0) for a run
    /// from t = 0; a branch from a checkpoint with another Δt (other mass scaling or
    /// material) re-anchors it at the checkpoint, so time goes on from where it was.
    #[serde(default)]
    pub time_origin: f64,
    #[serde(default)]
    pub step_origin: u64,
    /// x_n (m).
    #[serde(with = "crate::packed_vectors")]
    pub x: Vec<[f64; 3]>,
    /// v_{n−½} (m/s).
    #[serde(with = "crate::packed_vectors")]
    pub v: Vec<[f64; 3]>,
    pub energy: EnergyLedger,
    /// Plastic state of every owned element of a plastic material, committed at x_{n−1}
    /// (the last internal-force evaluation), indexed by `Model::plastic_slot`; empty for
    /// elastic runs (elastic laws are functions of F alone).
    pub plastic: Vec<PlasticPoint>,
    /// Rotation of each prescribed motion at t_n.
    pub motion_rotation: Vec<[f64; 9]>,
    pub reactions: Vec<Reaction>,
    /// Work done by each prescribed motion (J).
    pub motion_work: Vec<WorkAccumulator>,
    /// Friction history, wall state, the candidate-list reference and contact diagnostics.
    pub contact: ContactState,
    /// Stage in force, its progress and the finished stages' records; the walls' global
    /// forces of the last step.
    pub stages: StageProgress,
    /// Largest energy supplied so far, |ALLWK| + |initial total| + |ALLVD| summed over
    /// ranks (J), as sampled by the blow-up checks (every
    /// [`super::step::ENERGY_CHECK_EVERY`] steps): their bound on kinetic + strain energy.
    pub supplied_energy: f64,
    /// Owner of every grain and the grain bounds of the last ghost plan (maintained by the
    /// run driver; one part on a serial run).
    pub partition: Partition,
    /// The periodic cell's axes, work and stress (scenes with `[cell]`).
    #[serde(default)]
    pub cell: Option<CellState>,
}

/// The quantities of a [`State`] that each rank accumulates over what it owns (energies,
/// friction dissipation, the walls' work on its nodes): the model's value is the sum over
/// ranks. A checkpoint keeps them per rank so that a restart on another rank count can
/// hand their sums to one rank.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct RankTotals {
    pub energy: EnergyLedger,
    /// `ContactState::friction_dissipation` (J).
    pub friction_dissipation: f64,
    /// Each wall's `work` and `friction` accumulators (J).
    pub wall_work: Vec<[WorkAccumulator; 2]>,
    /// Work of the periodic cell on the rank's grains (J).
    #[serde(default)]
    pub cell_work: WorkAccumulator,
}

impl RankTotals {
    /// The sum of every rank's totals (ranks in order, so every reader gets the same sum).
    pub fn sum(parts: &[RankTotals]) -> RankTotals {
        let mut energy = [0.0; EnergyLedger::SUMS];
        let mut total = RankTotals::default();
        for p in parts {
            for (e, v) in energy.iter_mut().zip(p.energy.to_sums()) {
                *e += v;
            }
            total.friction_dissipation += p.friction_dissipation;
            total.cell_work.work += p.cell_work.work;
            total.cell_work.pending += p.cell_work.pending;
            total
                .wall_work
                .resize(p.wall_work.len(), [WorkAccumulator::default(); 2]);
            for (t, w) in total.wall_work.iter_mut().zip(&p.wall_work) {
                for k in 0..2 {
                    t[k].work += w[k].work;
                    t[k].pending += w[k].pending;
                }
            }
        }
        let has_initial = parts.iter().any(|p| p.energy.initial_total.is_some());
        total.energy = EnergyLedger::from_sums(&energy, has_initial);
        total
    }

    /// Zero totals of the same shape (what a rank that inherits none of them starts from;
    /// the first step's total counts as taken, so it is not taken again).
    pub fn zero_like(&self) -> RankTotals {
        let energy = EnergyLedger::from_sums(
            &[0.0; EnergyLedger::SUMS],
            self.energy.initial_total.is_some(),
        );
        RankTotals {
            energy,
            friction_dissipation: 0.0,
            wall_work: vec![[WorkAccumulator::default(); 2]; self.wall_work.len()],
            cell_work: WorkAccumulator::default(),
        }
    }
}

impl State {
    /// This rank's additive totals.
    pub fn rank_totals(&self) -> RankTotals {
        RankTotals {
            energy: self.energy.clone(),
            friction_dissipation: self.contact.friction_dissipation,
            wall_work: (self.contact.walls.iter())
                .map(|w| [w.work, w.friction])
                .collect(),
            cell_work: self.cell.as_ref().map(|c| c.work).unwrap_or_default(),
        }
    }

    /// The periodic cell's edge lengths at t_n and their rates over the step that led
    /// there (zero without a cell).
    pub fn cell_kinematics(&self, model: &crate::model::Model) -> CellKinematics {
        match (&model.periodic, &self.cell) {
            (Some(cell), Some(c)) => c.kinematics(cell, model.dt),
            _ => CellKinematics::default(),
        }
    }

    /// Cell vector by which grain `global_id` has been wrapped back into the periodic
    /// cell so far (m; zero without a cell): displacements are reported net of it.
    pub fn wrapped(&self, global_id: u32) -> [f64; 3] {
        (self.cell.as_ref())
            .and_then(|c| c.wrapped.get(global_id as usize).copied())
            .unwrap_or([0.0; 3])
    }

    /// t_n for step n at the step Δt, on this state's clock.
    pub fn time_at_step(&self, step: u64, dt: f64) -> f64 {
        self.time_origin + (step - self.step_origin) as f64 * dt
    }

    /// Replaces this rank's additive totals.
    pub fn set_rank_totals(&mut self, totals: &RankTotals) {
        self.energy = totals.energy.clone();
        self.contact.friction_dissipation = totals.friction_dissipation;
        for (w, t) in self.contact.walls.iter_mut().zip(&totals.wall_work) {
            w.work = t[0];
            w.friction = t[1];
        }
        if let Some(c) = &mut self.cell {
            c.work = totals.cell_work;
        }
    }

    /// Takes over from `from` (another rank's state, or this rank's before its grains
    /// moved) everything that is not carried by the grains themselves: time, step, this
    /// rank's totals, walls, stage progress, contact maxima, partition. The grains' nodes,
    /// plastic state, friction history and prescribed motions travel as grain packages
    /// (`driver::migration`). Every field of `State` is named here, so a new one does not
    /// compile until it is placed on one side.
    pub fn take_run_level_from(&mut self, from: &State) {
        let State {
            time,
            step,
            time_origin,
            step_origin,
            x: _,
            v: _,
            energy,
            plastic: _,
            motion_rotation: _,
            reactions: _,
            motion_work: _,
            contact,
            stages,
            supplied_energy,
            partition,
            cell,
        } = from;
        let ContactState {
            history: _,
            friction_dissipation,
            walls,
            stats,
            detection,
        } = contact;
        self.time = *time;
        self.step = *step;
        self.time_origin = *time_origin;
        self.step_origin = *step_origin;
        self.energy = energy.clone();
        self.stages = stages.clone();
        self.supplied_energy = *supplied_energy;
        self.partition = partition.clone();
        // the cell's axes, stress and wraps are run-level; its work is this rank's total
        self.cell = cell.clone();
        self.contact.friction_dissipation = *friction_dissipation;
        self.contact.walls = walls.clone();
        self.contact.stats.max_penetration_run = stats.max_penetration_run;
        self.contact.stats.max_contacts_run = stats.max_contacts_run;
        self.contact.stats.rebuilds = stats.rebuilds;
        // the candidate lists are rebuilt for the new layout; only the count carries over
        self.contact.detection.rebuilds = detection.rebuilds;
        self.contact.detection.skin = detection.skin;
    }
}
