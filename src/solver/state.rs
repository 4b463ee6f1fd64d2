//! Everything that evolves during a run, in one serde type: a checkpoint is this plus the
//! scene. Scratch buffers (`crate::solver::Scratch`, contact candidate lists, element
//! corner forces) are not state: they are rebuilt from the model and the state.

use crate::boundary::stages::StageProgress;
use crate::contact::ContactState;
use crate::energy::{EnergyLedger, WorkAccumulator};
use crate::material::PlasticPoint;
use crate::model::decomposition::Partition;
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
    /// x_n (m).
    pub x: Vec<[f64; 3]>,
    /// v_{n−½} (m/s).
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
    /// ranks (J): the blow-up check's bound on kinetic + strain energy.
    pub supplied_energy: f64,
    /// Owner of every grain and the grain bounds of the last ghost plan (maintained by the
    /// run driver; one part on a serial run).
    pub partition: Partition,
}
