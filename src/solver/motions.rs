//! Prescribed motions in the step: driven components of v_{n+½} are overridden so that the
//! driven nodes land exactly on their prescribed positions at t_{n+1}, and the reaction
//! force, moment and work of each motion are recorded in the state.

use super::state::{Reaction, State};
use crate::boundary::PrescribedMotion;
use crate::kinematics::{BodyForces, NextVelocity, Predictor};
use crate::lanes::NodeForce;
use crate::model::Model;

/// Overrides the driven components of v_{n+½} so that driven nodes land exactly on their
/// prescribed positions at t_{n+1}; records reaction force, moment and work. `force`
/// holds the element and contact forces, `body` gravity and damping.
pub(super) fn drive_prescribed_motions(
    model: &Model,
    motions: &[PrescribedMotion],
    state: &mut State,
    force: &[NodeForce],
    body: Option<BodyForces>,
    v_next: &mut NextVelocity,
    dt: f64,
) {
    let t = state.time;
    for (k, motion) in motions.iter().enumerate() {
        let working = motion;
        let q_next = working.rotation_after(&state.motion_rotation[k], t, dt);
        let c_next = working.centre_at(t + dt);
        let c_now = working.centre_at(t);
        let mut reaction = Reaction::default();
        let (mut p_before, mut p_after) = (0.0, 0.0);
        let predictor =
            Predictor::new(&state.v, force, &model.mass, dt).with_body_forces(body, &state.x);
        for (j, &node) in working.nodes.iter().enumerate() {
            let n = node as usize;
            let target = working.position(j, &c_next, &q_next);
            let x = state.x[n];
            let m = model.mass[n];
            let mut r = [0.0; 3];
            let mut driven = v_next.get(n, &predictor);
            let f = predictor.force_at(n);
            for i in 0..3 {
                if working.components[i] {
                    let v_new = (target[i] - x[i]) / dt;
                    r[i] = m * (v_new - state.v[n][i]) / dt - f[i];
                    driven[i] = v_new;
                    p_before += r[i] * state.v[n][i];
                    p_after += r[i] * v_new;
                }
            }
            v_next.set(n, driven);
            let arm = [x[0] - c_now[0], x[1] - c_now[1], x[2] - c_now[2]];
            for i in 0..3 {
                reaction.force[i] += r[i];
            }
            reaction.moment[0] += arm[1] * r[2] - arm[2] * r[1];
            reaction.moment[1] += arm[2] * r[0] - arm[0] * r[2];
            reaction.moment[2] += arm[0] * r[1] - arm[1] * r[0];
        }
        reaction.displacement = [
            c_now[0] - working.centre0[0],
            c_now[1] - working.centre0[1],
            c_now[2] - working.centre0[2],
        ];
        reaction.rotation = rotation_vector(&state.motion_rotation[k]);
        state.reactions[k] = reaction;
        state.motion_work[k].record(dt, p_before, p_after);
        state.motion_rotation[k] = q_next;
    }
}

/// Rotation vector (axis × angle, rad) of a rotation matrix.
pub fn rotation_vector(q: &[f64; 9]) -> [f64; 3] {
    let cos = ((q[0] + q[4] + q[8] - 1.0) * 0.5).clamp(-1.0, 1.0);
    let angle = cos.acos();
    let w = [q[7] - q[5], q[2] - q[6], q[3] - q[1]];
    let s = angle.sin();
    if s.abs() < 1e-12 {
        // small angle: θ ≈ ½ vee(Q − Qᵀ)
        return [0.5 * w[0], 0.5 * w[1], 0.5 * w[2]];
    }
    let f = angle / (2.0 * s);
    [f * w[0], f * w[1], f * w[2]]
}
