//! Damping and body forces of the step: mass-proportional damping of the absolute
//! velocity (α) and of each grain's velocity relative to its rigid-body motion (α_def, no
//! net force or moment on the grain), and gravity on the physical mass. They are added to
//! a node's force where its v_{n+½} is read (`crate::kinematics::BodyForces`).

use super::state::State;
use crate::kinematics::{BodyForces, RigidVelocity};
use crate::model::Model;
use rayon::prelude::*;

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

/// Gravity and damping of the step for the readers of v_{n+½} (`crate::kinematics`):
/// `None` without either (an undamped stage without gravity, e.g. the triaxial loading),
/// so that the node passes skip their terms. `rigid` holds the grains' rigid velocities
/// when the scene damps deformation (`prepare_body_forces`).
pub(super) fn body_forces<'a>(
    model: &'a Model,
    alpha: f64,
    gravity: [f64; 3],
    rigid: &'a [RigidVelocity],
) -> Option<BodyForces<'a>> {
    has_body_or_damping_force(model, alpha, gravity).then_some(BodyForces {
        gravity,
        alpha,
        deformation_damping: model.deformation_damping,
        physical_mass: &model.physical_mass,
        node_grain: &model.node_grain,
        rigid,
    })
}

/// The boundary stage's part in gravity and damping: they are added where each node's
/// v_{n+½} is read ([`body_forces`]), so all that is left is the rigid velocity of every
/// grain when the scene damps deformation, from x_n and v_{n−½} before anything moves.
pub(super) fn prepare_body_forces(model: &Model, state: &State, rigid: &mut [RigidVelocity]) {
    if model.deformation_damping > 0.0 {
        compute_grain_rigid_velocities(model, state, rigid);
    }
}

/// Whether the step has gravity or damping: without either (an undamped stage without
/// gravity, e.g. the triaxial loading) the node passes skip their terms.
pub(super) fn has_body_or_damping_force(model: &Model, alpha: f64, g: [f64; 3]) -> bool {
    alpha != 0.0 || model.deformation_damping != 0.0 || g != [0.0; 3]
}
