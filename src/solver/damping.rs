//! Damping and body forces of the boundary stage: mass-proportional damping of the
//! absolute velocity (α) and of each grain's velocity relative to its rigid-body motion
//! (α_def, no net force or moment on the grain), and gravity on the physical mass.

use super::forces::NODE_CHUNK;
use super::state::State;
use crate::kinematics::{predict, NextVelocity};
use crate::model::Model;
use rayon::prelude::*;

/// A grain's rigid-body velocity field v(x) = v_c + ω × (x − x_c), from its linear and
/// angular momentum (so that damping relative to it exerts no net force or moment).
#[derive(Debug, Clone, Copy, Default)]
pub struct RigidVelocity {
    pub centre: [f64; 3],
    pub velocity: [f64; 3],
    pub omega: [f64; 3],
}

impl RigidVelocity {
    #[inline(always)]
    pub fn at(&self, x: &[f64; 3]) -> [f64; 3] {
        let r = [
            x[0] - self.centre[0],
            x[1] - self.centre[1],
            x[2] - self.centre[2],
        ];
        let w = &self.omega;
        [
            self.velocity[0] + w[1] * r[2] - w[2] * r[1],
            self.velocity[1] + w[2] * r[0] - w[0] * r[2],
            self.velocity[2] + w[0] * r[1] - w[1] * r[0],
        ]
    }
}

/// Rigid-body velocity of every grain from v_{n−½} at x_n: mass-weighted centre and
/// velocity, ω = I⁻¹L about the centre.
pub(super) fn compute_grain_rigid_velocities(
    model: &Model,
    state: &State,
    out: &mut [RigidVelocity],
) {
    let owned = model.owned_grains;
    out[..owned]
        .par_iter_mut()
        .zip(model.grains[..owned].par_iter())
        .for_each(|(rv, g)| {
            let (mut m_tot, mut mx, mut mv) = (0.0, [0.0; 3], [0.0; 3]);
            for n in g.nodes.clone() {
                let m = model.mass[n];
                m_tot += m;
                for i in 0..3 {
                    mx[i] += m * state.x[n][i];
                    mv[i] += m * state.v[n][i];
                }
            }
            if m_tot <= 0.0 {
                *rv = RigidVelocity::default();
                return;
            }
            let c = mx.map(|v| v / m_tot);
            let vc = mv.map(|v| v / m_tot);
            let mut l = [0.0; 3];
            let mut inertia = nalgebra::Matrix3::<f64>::zeros();
            for n in g.nodes.clone() {
                let m = model.mass[n];
                let r = [
                    state.x[n][0] - c[0],
                    state.x[n][1] - c[1],
                    state.x[n][2] - c[2],
                ];
                let u = [
                    state.v[n][0] - vc[0],
                    state.v[n][1] - vc[1],
                    state.v[n][2] - vc[2],
                ];
                l[0] += m * (r[1] * u[2] - r[2] * u[1]);
                l[1] += m * (r[2] * u[0] - r[0] * u[2]);
                l[2] += m * (r[0] * u[1] - r[1] * u[0]);
                let rr = r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
                for i in 0..3 {
                    for j in 0..3 {
                        inertia[(i, j)] += m * (if i == j { rr } else { 0.0 } - r[i] * r[j]);
                    }
                }
            }
            let omega = inertia
                .try_inverse()
                .map(|inv| inv * nalgebra::Vector3::new(l[0], l[1], l[2]))
                .map_or([0.0; 3], |w| [w[0], w[1], w[2]]);
            *rv = RigidVelocity {
                centre: c,
                velocity: vc,
                omega,
            };
        });
}

/// The mass-proportional damping α in force (1/s): the current stage's, else the scene's.
pub(super) fn damping_in_force(
    model: &Model,
    stages: &crate::boundary::stages::StageProgress,
) -> f64 {
    model
        .stages
        .as_ref()
        .and_then(|plan| plan.current(stages).damping)
        .unwrap_or(model.damping)
}

/// Gravity of the current stage, else `simulation.gravity` (m/s²).
pub(super) fn gravity_in_force(
    model: &Model,
    stages: &crate::boundary::stages::StageProgress,
) -> [f64; 3] {
    model
        .stages
        .as_ref()
        .and_then(|plan| plan.current(stages).gravity)
        .unwrap_or(model.gravity)
}

/// Damping force on node n: −α m v − α_def m (v − v_rigid(x)) (N).
#[inline(always)]
pub(super) fn damping_force(
    model: &Model,
    alpha: f64,
    rigid: &[RigidVelocity],
    n: usize,
    x: &[f64; 3],
    v: &[f64; 3],
) -> [f64; 3] {
    let m = model.mass[n];
    let mut f = [-alpha * m * v[0], -alpha * m * v[1], -alpha * m * v[2]];
    if model.deformation_damping > 0.0 {
        let vr = rigid[model.node_grain[n] as usize].at(x);
        for i in 0..3 {
            f[i] -= model.deformation_damping * m * (v[i] - vr[i]);
        }
    }
    f
}

/// f ← f_int + m_phys g − α m v_{n−½}; v_{n+½} ← v_{n−½} + Δt f/m for every node (driven
/// components are overwritten by the motions afterwards); without gravity and damping the
/// prediction is left to its readers. Gravity acts on the physical
/// mass only: mass added by scaling is numerical and must not weigh anything.
#[allow(clippy::too_many_arguments)]
pub(super) fn apply_body_and_damping_forces(
    model: &Model,
    alpha: f64,
    g: [f64; 3],
    state: &State,
    rigid: &mut [RigidVelocity],
    force: &mut [[f64; 3]],
    v_next: &mut NextVelocity,
    dt: f64,
) {
    if !has_body_or_damping_force(model, alpha, g) {
        // v_{n+½} is then the prediction from the internal and contact forces alone, up to
        // the sign of a zero (adding ±0 changes no bit of a nonzero force): computed where
        // read, not stored (`crate::kinematics`)
        v_next.predict_where_read();
        return;
    }
    if model.deformation_damping > 0.0 {
        compute_grain_rigid_velocities(model, state, rigid);
    }
    let rigid = &*rigid;
    let owned = model.owned_nodes;
    force[..owned]
        .par_chunks_mut(NODE_CHUNK)
        .zip(v_next.store_every_node()[..owned].par_chunks_mut(NODE_CHUNK))
        .enumerate()
        .for_each(|(chunk, (f, vn))| {
            let base = chunk * NODE_CHUNK;
            for k in 0..f.len() {
                let n = base + k;
                let (m, mp, v) = (model.mass[n], model.physical_mass[n], state.v[n]);
                let fd = damping_force(model, alpha, rigid, n, &state.x[n], &v);
                for i in 0..3 {
                    f[k][i] += mp * g[i] + fd[i];
                }
                vn[k] = predict(v, f[k], m, dt);
            }
        });
}

/// Whether the step has gravity or damping: without either (an undamped stage without
/// gravity, e.g. the triaxial loading) the node passes skip their terms.
pub(super) fn has_body_or_damping_force(model: &Model, alpha: f64, g: [f64; 3]) -> bool {
    alpha != 0.0 || model.deformation_damping != 0.0 || g != [0.0; 3]
}
