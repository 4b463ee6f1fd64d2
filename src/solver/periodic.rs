//! The periodic cell during a step: its kinematics (the stages drive each periodic axis
//! like a wall: `ServoState::displacement` is the axis' shortening L0 − L), the images
//! of owned grains mirrored on this rank, and the two sums the cell needs from contact.
//!
//! **Homogenised stress** (compression positive, Love–Weber):
//! σ = (1/V) [Σ_c f_c ⊗ l_c + Σ_g m_g v′_g ⊗ v′_g], where f_c is the force of contact
//! point c on its slave grain and l_c = x_slave − x_master the branch vector between the
//! two grains' centres, the master's periodic image shift included; each point is counted
//! by the rank owning its slave node, and the two passes of a pair (weight ½ each) add up
//! to the pair's force. The sum is kept per slave grain and added in global grain order
//! after the sum over ranks, so the servo sees the same number on any rank count. A grain's centre here is the mean of its surface nodes: in
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
    /// The cell at rest at its t = 0 box (no grain wrapped yet: `wrapped` grows when one is).
    pub fn new(cell: &PeriodicCell) -> Self {
        Self {
            axes: cell.periodic.map(|p| p.then(ServoState::default)),
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

/// This rank's part of the contact sums of one step, per axis Σ f_el,k r_k (N): the
/// cell's power is that dotted with L̇ (see the module docs).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct CellContactSums {
    pub image_force: [f64; 3],
}

/// The sums of the last contact evaluation at `x`: Σ f ⊗ l of each owned slave grain
/// (N·m, row-major) into `per_grain` at 9 × its global id (zero elsewhere, `grains`
/// global grains), so that summing over ranks and then over grains in global order gives
/// every rank count the serial total bit for bit ([`total_over_grains`]); and the
/// returned image forces. `centres` is scratch (one entry per model grain).
pub fn cell_contact_sums(
    model: &Model,
    x: &[[f64; 3]],
    contact: &ContactScratch,
    centres: &mut Vec<[f64; 3]>,
    per_grain: &mut Vec<f64>,
    grains: usize,
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
    per_grain.clear();
    per_grain.resize(9 * grains, 0.0);
    let mut sums = CellContactSums::default();
    let lists = &contact.lists;
    for r in &contact.results {
        let pass = lists.passes[r.pass as usize];
        let (s, m) = (pass.slave as usize, pass.master as usize);
        if !r.active || !cm.surfaces[s].owned {
            continue;
        }
        let l = [0, 1, 2].map(|k| centres[s][k] - centres[m][k]);
        let g = 9 * model.grains[s].global_id as usize;
        for i in 0..3 {
            for j in 0..3 {
                per_grain[g + 3 * i + j] += r.force[i] * l[j];
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

/// Σ over grains, in global order, of the per-grain sums of [`cell_contact_sums`].
pub fn total_over_grains(per_grain: &[f64]) -> [f64; 9] {
    let mut total = [0.0; 9];
    for g in per_grain.chunks_exact(9) {
        for i in 0..9 {
            total[i] += g[i];
        }
    }
    total
}

/// Limits how fast each axis' speed may change: by at most max(|v_old|, |v_new|) × Δt/T
/// per step, T one P-wave transit across the cell, so the cell takes up a new speed over
/// at least one transit. The stages set speeds stepwise (a servo starts at G F*, a strain
/// rate at its full value); a wall can take such a step (it is a kinematic constraint),
/// but an image jumping to a new speed hits the grains it touches like an impact, and the
/// penalty contacts' integration error at such an impact shows in the ledger.
pub fn ramp_axis_speeds(model: &Model, cell: &mut CellState, before: [f64; 3], dt: f64) {
    let Some(periodic) = &model.periodic else {
        return;
    };
    let wave_speed = (model.materials.iter())
        .map(|m| m.dilatational_wave_speed())
        .fold(0.0, f64::max);
    let transit = periodic.length0.iter().cloned().fold(0.0, f64::max) / wave_speed;
    for (axis, old) in cell.axes.iter_mut().zip(before) {
        if let Some(a) = axis {
            let step = old.abs().max(a.velocity.abs()) * dt / transit;
            a.velocity = old + (a.velocity - old).clamp(-step, step);
        }
    }
}

/// Speed of each axis over the next step (m/s of shortening; 0 along fixed axes).
pub fn axis_speeds(cell: &CellState) -> [f64; 3] {
    cell.axes.map(|a| a.map_or(0.0, |s| s.velocity))
}

/// Power of the cell (W) for image forces `q` (N) at rates `rate` (m/s).
#[inline]
pub fn cell_power(q: &[f64; 3], rate: &[f64; 3]) -> f64 {
    q[0] * rate[0] + q[1] * rate[1] + q[2] * rate[2]
}
