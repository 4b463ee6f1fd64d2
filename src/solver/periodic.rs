//! The periodic cell during a step: its kinematics (the stages drive each periodic axis
//! like a wall: `ServoState::displacement` is the axis' shortening L0 − L), the images
//! of owned grains mirrored on this rank, and the two sums the cell needs from contact.
//!
//! **Homogenised stress** (compression positive, Love–Weber):
//! σ = (1/V) [Σ_c f_c ⊗ l_c + Σ_g m_g v′_g ⊗ v′_g], where f_c is the force of contact
//! point c on its slave grain and l_c = x_slave − x_master the branch vector between the
//! two grains' centres, the master's periodic image shift included; each point is counted
//! by the rank owning its slave node, and the two passes of a pair (weight ½ each) add up
//! to the pair's force. A grain's centre here is the mean of its surface nodes: in
//! equilibrium (every grain's net force zero) any point of each grain gives the same sum.
//! The kinetic term uses each grain's velocity relative to the cell's homogeneous flow
//! L̇ₖ/Lₖ (xₖ − minₖ) and is added in the history (it is ~ρv², negligible quasi-statically,
//! so the servo acts on the contact part).
//!
//! **Work of the cell.** An image moves with its grain plus the cell vector's rate, so a
//! contact with an image does work that no node's motion accounts for. With f_el the
//! elastic + friction force of a point on its slave and r = s_master − s_slave the
//! relative image shift, the power the cell feeds in is Σ f_el · (r ∘ L̇); it is
//! integrated with the trapezoidal rule of every other work (`crate::energy`) and enters
//! ALLWK. The normal dashpot's part is not in it: ALLVD already counts the dashpot's power
//! on each node with the node's own velocity.

use super::state::State;
use crate::boundary::servo::ServoState;
use crate::contact::ContactScratch;
use crate::energy::WorkAccumulator;
use crate::model::periodic::{relative_image, CellKinematics, PeriodicCell};
use crate::model::Model;
use serde::{Deserialize, Serialize};

/// The periodic cell's part of the run state.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct CellState {
    /// Kinematics of each periodic axis (`None` along the others): displacement = the
    /// axis' shortening since t = 0 (m), as for a servo wall.
    pub axes: [Option<ServoState>; 3],
    /// Work of the cell on this rank's grains (J).
    pub work: WorkAccumulator,
    /// Contact part of the homogenised stress at the last step, summed over ranks
    /// (Pa, compression positive, row-major).
    pub contact_stress: [f64; 9],
    /// Cell vector by which each grain has been wrapped back into the box so far (m), by
    /// global id: displacements are reported against the reference shifted by it.
    #[serde(default)]
    pub wrapped: Vec<[f64; 3]>,
}

impl CellState {
    pub fn new(cell: &PeriodicCell, grains: usize) -> Self {
        Self {
            axes: cell.periodic.map(|p| p.then(ServoState::default)),
            wrapped: vec![[0.0; 3]; grains],
            ..Default::default()
        }
    }

    /// Lengths at the state's time and their rates over the step that led there.
    pub fn kinematics(&self, cell: &PeriodicCell, dt: f64) -> CellKinematics {
        let mut k = cell.at_rest();
        for (a, s) in self.axes.iter().enumerate() {
            if let Some(s) = s {
                k.length[a] = cell.length0[a] - s.displacement;
                k.rate[a] = -(s.displacement - s.previous) / dt;
            }
        }
        k
    }

    /// Volume of the box (m³).
    pub fn volume(&self, cell: &PeriodicCell) -> f64 {
        self.kinematics(cell, 1.0).length.iter().product()
    }
}

/// The cell's kinematics in `state` (zero lengths without a cell).
pub fn cell_kinematics(model: &Model, state: &State) -> CellKinematics {
    match (&model.periodic, &state.cell) {
        (Some(cell), Some(c)) => c.kinematics(cell, model.dt),
        _ => CellKinematics::default(),
    }
}

/// Copies every owned grain's surface into its images held here, shifted by the cell.
pub fn refresh_local_images(
    model: &Model,
    x: &mut [[f64; 3]],
    v: &mut [[f64; 3]],
    cell: &CellKinematics,
) {
    for &(image, source) in &model.local_images {
        let (to, from) = (&model.grains[image], &model.grains[source]);
        let (dx, dv) = (cell.offset(to.image), cell.velocity(to.image));
        for (&n, &m) in to.surface.nodes.iter().zip(&from.surface.nodes) {
            let (p, u) = (x[m as usize], v[m as usize]);
            x[n as usize] = [0, 1, 2].map(|k| p[k] + dx[k]);
            v[n as usize] = [0, 1, 2].map(|k| u[k] + dv[k]);
        }
    }
}

/// This rank's contact sums of one step: Σ f ⊗ l over its contact points (N·m,
/// row-major; divide by V for the stress) and, per axis, Σ f_el,k r_k (N): the cell's
/// power is that dotted with L̇ (see the module docs).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct CellContactSums {
    pub force_branch: [f64; 9],
    pub image_force: [f64; 3],
}

/// [`CellContactSums`] of the last contact evaluation at `x`; `centres` is scratch (one
/// entry per model grain).
pub fn cell_contact_sums(
    model: &Model,
    x: &[[f64; 3]],
    contact: &ContactScratch,
    centres: &mut Vec<[f64; 3]>,
) -> CellContactSums {
    let cm = &model.contact;
    centres.clear();
    centres.extend(model.grains.iter().map(|g| {
        let nodes = &g.surface.nodes;
        let mut c = [0.0; 3];
        for &n in nodes {
            for k in 0..3 {
                c[k] += x[n as usize][k];
            }
        }
        c.map(|v| v / nodes.len().max(1) as f64)
    }));
    let mut sums = CellContactSums::default();
    let lists = &contact.lists;
    for (e, r) in lists.entries.iter().zip(&contact.results) {
        let pass = lists.passes[e.pass as usize];
        let (s, m) = (pass.slave as usize, pass.master as usize);
        if !r.active || !cm.surfaces[s].owned {
            continue;
        }
        let l = [0, 1, 2].map(|k| centres[s][k] - centres[m][k]);
        for i in 0..3 {
            for j in 0..3 {
                sums.force_branch[3 * i + j] += r.force[i] * l[j];
            }
        }
        let shift = relative_image(model.grains[s].image, model.grains[m].image);
        for k in 0..3 {
            let elastic = r.force[k] - r.damping_force * r.normal[k];
            sums.image_force[k] += elastic * f64::from(shift[k]);
        }
    }
    sums
}

/// Power of the cell (W) for image forces `q` (N) at rates `rate` (m/s).
#[inline]
pub fn cell_power(q: &[f64; 3], rate: &[f64; 3]) -> f64 {
    q[0] * rate[0] + q[1] * rate[1] + q[2] * rate[2]
}
