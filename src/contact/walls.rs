//! Rigid plane walls, enforced kinematically (exactly, zero penetration).
//!
//! After v_{n+½} has been predicted from all forces (and prescribed motions applied), each
//! candidate surface node whose predicted position x_n + Δt v_{n+½} would lie behind the
//! wall plane at t_{n+1} gets the normal component of v_{n+½} corrected so that it lands
//! exactly on the plane. The wall force on the node is f_n = m Δv/Δt (m = the nodal mass used
//! by the integrator, i.e. after mass scaling). With friction μ the node sticks (its
//! tangential velocity becomes the wall's) when the force needed, m |v_t,rel|/Δt, is at most
//! μ f_n, and otherwise slides with a tangential force μ f_n opposing the relative motion.
//!
//! Energy: a wall is an external body. Its work is integrated like that of prescribed
//! motions, W += ½Δt(f_n·v_{n−½} + f_n·v_{n+½}) (see `crate::energy`), so the balance closes.
//! The part spent against friction, −∫ f_t·(v − v_wall) dt, is reported as friction
//! dissipation (ALLFD) and the rest as external work (ALLWK). Because kinematic enforcement
//! stops a node's approach within one step, a fixed wall's external work is slightly
//! negative during impacts (the inelastic arrest of single nodes); it vanishes as the mesh
//! is refined (it scales with the mass of the nodes that arrive per step).
//!
//! Nodes with any prescribed component are left to their prescribed motion. A node touching
//! two walls is corrected wall after wall, in scene order.

use super::{ContactModel, ContactState, Wall, WallState};
use crate::kinematics::{NextVelocity, Predictor};

use crate::math::{add, dot, norm, scale, sub};

/// Normal force of each wall on each grain of this rank at the last step (N): summed
/// per grain in node order, so that the walls' total, summed over grains in global order
/// after an exchange, is bitwise the same on any number of ranks (a servo wall then moves
/// identically, and so does everything it pushes). Kept only when some wall is driven by
/// state (`Model::stages`).
#[derive(Debug, Default, Clone)]
pub struct GrainWallForces {
    grains: usize,
    /// `[wall × grains + grain]`.
    values: Vec<f64>,
}

impl GrainWallForces {
    fn clear(&mut self, walls: usize, grains: usize) {
        self.grains = grains;
        self.values.clear();
        self.values.resize(walls * grains, 0.0);
    }

    /// The force of wall `w` on local grain `g` (N).
    pub fn get(&self, w: usize, g: usize) -> f64 {
        self.values.get(w * self.grains + g).copied().unwrap_or(0.0)
    }
}

/// Displacement of a wall from t = 0 (m) at t_{n−1}, t_n and t_{n+1} (`t` = t_n): from its
/// prescribed history, or for a servo wall from its state (s n at each time).
#[inline]
pub fn displacements(wall: &Wall, ws: &WallState, t: f64, dt: f64) -> [[f64; 3]; 3] {
    match &ws.servo {
        Some(s) => s.displacements(dt).map(|d| scale(wall.normal, d)),
        None => [
            wall.displacement_at(t - dt),
            wall.displacement_at(t),
            wall.displacement_at(t + dt),
        ],
    }
}

/// Wall nodes looked ahead by [`enforce`].
const NODES_AHEAD: usize = 8;

/// Prefetches what [`enforce`] reads of model node `n`: the wall nodes of a wall are a few
/// per grain, scattered over the mesh.
#[inline(always)]
fn touch_wall_node(n: usize, x: &[[f64; 3]], predictor: &Predictor) {
    crate::lanes::touch_value(x, n);
    predictor.touch(n);
}

/// Corrects `v_next` (v_{n+½}, where not stored `predictor`'s, whose `v` is v_{n−½}) of the
/// candidate nodes `wall_nodes` (wall, flat surface
/// index; ordered by wall) so that no node ends behind a wall at t_{n+1}; records each
/// wall's force, displacement, contacts, work and friction work in `state`, and each
/// contact's force on its node in `node_forces` (for the frames' nodal contact force); with
/// `by_grain` (each node's local grain, the grain count, the sums) also each wall's normal
/// force per grain.
#[allow(clippy::too_many_arguments)]
pub fn enforce(
    cm: &ContactModel,
    mass: &[f64],
    driven: &[u8],
    x: &[[f64; 3]],
    predictor: &Predictor,
    v_next: &mut NextVelocity,
    t: f64,
    dt: f64,
    wall_nodes: &[(u32, u32)],
    state: &mut ContactState,
    node_forces: &mut Vec<(u32, [f64; 3])>,
    mut by_grain: Option<(&[u32], usize, &mut GrainWallForces)>,
) {
    let v = predictor.v;
    node_forces.clear();
    if let Some((_, grains, f)) = &mut by_grain {
        f.clear(cm.walls.len(), *grains);
    }
    let mut cursor = 0;
    for (w, wall) in cm.walls.iter().enumerate() {
        let [u_prev, u_now, u_next] = displacements(wall, &state.walls[w], t, dt);
        let vw_before = scale(sub(u_now, u_prev), 1.0 / dt);
        let vw_after = scale(sub(u_next, u_now), 1.0 / dt);
        let p_next = wall.point_at_displacement(u_next);
        let n = wall.normal;
        let mu = wall.friction;
        let mut force = [0.0; 3];
        let (mut p_before, mut p_after, mut q_before, mut q_after) = (0.0, 0.0, 0.0, 0.0);
        let mut contacts = 0;
        while cursor < wall_nodes.len() && wall_nodes[cursor].0 as usize == w {
            if let Some(&(_, ahead)) = wall_nodes.get(cursor + NODES_AHEAD) {
                touch_wall_node(cm.node[ahead as usize] as usize, x, predictor);
            }
            let k = wall_nodes[cursor].1 as usize;
            cursor += 1;
            let node = cm.node[k] as usize;
            if driven[node] != 0 {
                continue;
            }
            let vn = v_next.get(node, predictor);
            let gap = dot(sub(add(x[node], scale(vn, dt)), p_next), n);
            if gap >= 0.0 {
                continue;
            }
            let m = mass[node];
            let dvn = -gap / dt;
            let f_n = m * dvn / dt;
            let mut v_new = add(vn, scale(n, dvn));
            let mut f_t = [0.0; 3];
            if mu > 0.0 {
                let rel = sub(v_new, vw_after);
                let rel_t = sub(rel, scale(n, dot(rel, n)));
                let r = norm(rel_t);
                if r > 0.0 {
                    if m * r / dt <= mu * f_n {
                        v_new = sub(v_new, rel_t);
                        f_t = scale(rel_t, -m / dt);
                    } else {
                        v_new = sub(v_new, scale(rel_t, mu * f_n * dt / (m * r)));
                        f_t = scale(rel_t, -mu * f_n / r);
                    }
                }
            }
            let f = add(scale(n, f_n), f_t);
            if let Some((node_grain, _, f)) = &mut by_grain {
                f.values[w * f.grains + node_grain[node] as usize] += f_n;
            }
            v_next.set(node, v_new);
            node_forces.push((node as u32, f));
            force = add(force, f);
            p_before += dot(f, v[node]);
            p_after += dot(f, v_new);
            q_before += dot(f_t, sub(v[node], vw_before));
            q_after += dot(f_t, sub(v_new, vw_after));
            contacts += 1;
        }
        let ws = &mut state.walls[w];
        ws.work.record(dt, p_before, p_after);
        ws.friction.record(dt, q_before, q_after);
        ws.force = force;
        ws.displacement = u_now;
        ws.contacts = contacts;
    }
}
