//! The explicit central-difference step as named, timed stages:
//! contact (detection, grain–grain forces at x_n) → internal forces (+ contact forces)
//! → boundary (body force, damping, prescribed motions) → contact (kinematic walls on
//! v_{n+½}) → integrate → energy. Time in both contact parts is charged to `contact`.
//!
//! Convention: at the start of step n the state holds x_n and v_{n−½};
//! v_{n+½} = v_{n−½} + Δt M⁻¹ f_n, x_{n+1} = x_n + Δt v_{n+½}.

use super::forces::{compute_internal_forces_into, ElementScratch, NODE_CHUNK};
use super::model::Model;
use super::timing::{Stage, StageTimers};
use crate::boundary::PrescribedMotion;
use crate::contact::{ContactScratch, ContactState};
use crate::energy::{EnergyLedger, WorkAccumulator};
use crate::error::MufeError;
use rayon::prelude::*;
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

/// Everything that evolves during a run (a checkpoint is this plus the scene).
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
    /// Rotation of each prescribed motion at t_n.
    pub motion_rotation: Vec<[f64; 9]>,
    pub reactions: Vec<Reaction>,
    /// Work done by each prescribed motion (J).
    pub motion_work: Vec<WorkAccumulator>,
    /// Friction history, wall work and contact diagnostics.
    #[serde(default)]
    pub contact: ContactState,
}

/// What a step needs from other ranks. The serial implementation ([`Serial`]) does
/// nothing; the MPI one lives in `crate::domain` (the only module that talks to MPI).
pub trait StepHooks {
    /// Completes the ghost update: ghost surface x_n and v_{n−½} from their owners.
    fn ghosts_in(&mut self, _x: &mut [[f64; 3]], _v: &mut [[f64; 3]]) -> Result<(), MufeError> {
        Ok(())
    }
    /// Starts sending owned surface x_{n+1}, v_{n+½} to the ranks that mirror them.
    fn ghosts_out(&mut self, _x: &[[f64; 3]], _v: &[[f64; 3]]) -> Result<(), MufeError> {
        Ok(())
    }
    /// Logical OR over ranks (all ranks must call).
    fn any(&mut self, local: bool) -> bool {
        local
    }
    /// Sums over ranks in place (all ranks must call).
    fn sum(&mut self, _values: &mut [f64]) {}
}

/// One rank, nothing to exchange.
pub struct Serial;
impl StepHooks for Serial {}

/// Per-step scratch buffers (never serialised).
#[derive(Debug, Default)]
pub struct Scratch {
    /// Total force on each node at x_n (N).
    pub force: Vec<[f64; 3]>,
    /// v_{n+½} being built (m/s).
    pub v_next: Vec<[f64; 3]>,
    pub elements: ElementScratch,
    /// Cached contact candidate lists and per-point results.
    pub contact: ContactScratch,
    node_partials: Vec<NodePartials>,
    /// Rigid-body velocity field of each grain (for deformation damping).
    grain_rigid: Vec<RigidVelocity>,
}

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
fn compute_grain_rigid_velocities(model: &Model, state: &State, out: &mut [RigidVelocity]) {
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

/// Damping force on node n: −α m v − α_def m (v − v_rigid(x)) (N).
#[inline(always)]
fn damping_force(
    model: &Model,
    rigid: &[RigidVelocity],
    n: usize,
    x: &[f64; 3],
    v: &[f64; 3],
) -> [f64; 3] {
    let m = model.mass[n];
    let mut f = [
        -model.damping * m * v[0],
        -model.damping * m * v[1],
        -model.damping * m * v[2],
    ];
    if model.deformation_damping > 0.0 {
        let vr = rigid[model.node_grain[n] as usize].at(x);
        for i in 0..3 {
            f[i] -= model.deformation_damping * m * (v[i] - vr[i]);
        }
    }
    f
}

#[derive(Debug, Clone, Copy, Default)]
struct NodePartials {
    kinetic: f64,
    gravity_before: f64,
    gravity_after: f64,
    damping_before: f64,
    damping_after: f64,
    bad_node: Option<usize>,
}

/// Model + motions + state + scratch: one rank's explicit solver.
pub struct Solver {
    pub model: Model,
    pub motions: Vec<PrescribedMotion>,
    pub state: State,
    pub scratch: Scratch,
    pub timers: StageTimers,
    /// Energy supplied so far, for the blow-up check (J).
    energy_scale: f64,
    /// This rank's share of the smallest energy the blow-up check reacts to (J):
    /// 1e-12 × M c_p², far below any physical energy of the run yet far above round-off
    /// (a run starting at rest with a gap has KE + U ~ 1e-28 J of pure noise).
    energy_floor: f64,
}

impl Solver {
    /// Builds a solver at t = 0 with the given initial velocities.
    pub fn new(model: Model, motions: Vec<PrescribedMotion>, v0: Vec<[f64; 3]>) -> Self {
        let n = model.num_nodes();
        let c_max = model
            .materials
            .iter()
            .map(|m| m.dilatational_wave_speed())
            .fold(0.0, f64::max);
        let owned_mass: f64 = model.physical_mass[..model.owned_nodes].iter().sum();
        let energy_floor = 1e-12 * owned_mass * c_max * c_max;
        let state = State {
            time: 0.0,
            step: 0,
            x: model.x0.clone(),
            v: v0,
            energy: EnergyLedger::default(),
            motion_rotation: motions.iter().map(|m| m.rotation).collect(),
            reactions: vec![Reaction::default(); motions.len()],
            motion_work: vec![WorkAccumulator::default(); motions.len()],
            contact: ContactState::new(&model),
        };
        let scratch = Scratch {
            force: vec![[0.0; 3]; n],
            v_next: vec![[0.0; 3]; n],
            elements: ElementScratch::new(&model),
            contact: ContactScratch::default(),
            node_partials: vec![NodePartials::default(); model.owned_nodes.div_ceil(NODE_CHUNK)],
            grain_rigid: vec![RigidVelocity::default(); model.grains.len()],
        };
        Self {
            model,
            motions,
            state,
            scratch,
            timers: StageTimers::default(),
            energy_scale: 0.0,
            energy_floor,
        }
    }

    /// Advances one step on one rank. Errors name time, step and the element or node that
    /// failed.
    pub fn step(&mut self) -> Result<(), MufeError> {
        self.step_with(&mut Serial)
    }

    /// Advances one step, using `hooks` for what other ranks contribute (ghost surfaces,
    /// the common contact rebuild decision, global energy sums).
    pub fn step_with(&mut self, hooks: &mut dyn StepHooks) -> Result<(), MufeError> {
        let dt = self.model.dt;
        let model = &self.model;
        let state = &mut self.state;
        let scratch = &mut self.scratch;
        let timers = &mut self.timers;

        // Internal forces first: they need only owned data, so they overlap the halo
        // exchange begun at the end of the previous step.
        let summary = timers.time(Stage::InternalForces, || {
            compute_internal_forces_into(model, &state.x, &mut scratch.elements, &mut scratch.force)
        });
        timers.time(Stage::Halo, || hooks.ghosts_in(&mut state.x, &mut state.v))?;
        timers.time(Stage::Contact, || {
            let local = crate::contact::needs_rebuild(
                model,
                &state.x,
                state.time,
                dt,
                &mut scratch.contact,
            );
            let rebuild = hooks.any(local);
            crate::contact::evaluate_with(
                model,
                &state.x,
                &state.v,
                state.time,
                state.step,
                dt,
                rebuild,
                &mut state.contact,
                &mut scratch.contact,
            )
        })?;
        timers.time(Stage::Contact, || {
            crate::contact::add_forces(
                model,
                &scratch.contact,
                &mut state.contact,
                &mut scratch.force,
            )
        });
        if let Some((e, jac)) = summary.bad_element {
            let g = &model.grains[model.grain_of_element(e)];
            return Err(MufeError::Run(format!(
                "blow-up at t = {:.6e} s (step {}): element {} of grain '{}' {} (det F = {:.3e}); reduce simulation.dt_safety or check the loading",
                state.time,
                state.step,
                e - g.elements.start,
                g.name,
                if jac <= 0.0 { "inverted" } else { "has a non-finite force" },
                jac
            )));
        }

        timers.time(Stage::Boundary, || {
            apply_body_and_damping_forces(model, state, scratch, dt);
            drive_prescribed_motions(model, &self.motions, state, scratch, dt);
        });
        timers.time(Stage::Contact, || {
            crate::contact::enforce_walls(
                model,
                &state.x,
                &state.v,
                &mut scratch.v_next,
                state.time,
                dt,
                &mut state.contact,
                &scratch.contact,
            )
        });

        // Power of the contact dampers with v_{n−½} (state.v) and v_{n+½} (scratch.v_next),
        // before integration overwrites v.
        let contact_damping = timers.time(Stage::Contact, || {
            crate::contact::damping_power(model, &state.v, &scratch.v_next, &scratch.contact)
        });

        let partials = timers.time(Stage::Integrate, || {
            integrate_and_sum(model, state, scratch, dt)
        });
        timers.time(Stage::Halo, || hooks.ghosts_out(&state.x, &state.v))?;
        if let Some(node) = partials.bad_node {
            let g = &model.grains[model.grains.partition_point(|g| g.nodes.end <= node)];
            return Err(MufeError::Run(format!(
                "blow-up at t = {:.6e} s (step {}): non-finite velocity at node {} of grain '{}'",
                state.time,
                state.step,
                node - g.nodes.start,
                g.name
            )));
        }

        timers.time(Stage::Energy, || {
            let e = &mut state.energy;
            e.kinetic = partials.kinetic;
            e.strain = summary.strain_energy;
            e.recoverable_strain = summary.strain_energy;
            e.body_force
                .record(dt, partials.gravity_before, partials.gravity_after);
            e.damping.record(
                dt,
                partials.damping_before + contact_damping.0,
                partials.damping_after + contact_damping.1,
            );
            e.friction_dissipation = state.contact.friction_dissipation_total();
            e.contact_energy = state.contact.stats.energy;
            e.boundary_work = state.motion_work.iter().map(|w| w.work).sum::<f64>()
                + state.contact.wall_external_work();
            if e.initial_total.is_none() {
                e.initial_total = Some(e.total());
            }
        });

        state.time = (state.step + 1) as f64 * dt;
        state.step += 1;

        // Exploding energy: with every force accounted for, KE + U cannot exceed the energy
        // supplied; an unstable integration grows it exponentially past any such bound.
        let e = &state.energy;
        let mut global = [
            e.external_work(),
            e.initial_total.unwrap_or(0.0),
            e.damping_dissipation(),
            e.kinetic + e.strain,
            self.energy_floor,
        ];
        hooks.sum(&mut global);
        self.energy_scale = self
            .energy_scale
            .max(global[0].abs() + global[1].abs() + global[2].abs());
        let stored = global[3];
        if !stored.is_finite() || (stored > 10.0 * self.energy_scale && stored > global[4]) {
            let (e, density) = super::diagnose::most_strained_element(&self.model, &state.x);
            let g = &self.model.grains[self.model.grain_of_element(e)];
            return Err(MufeError::Run(format!(
                "blow-up at t = {:.6e} s (step {}): energy exploded (kinetic + strain = {:.3e} J, supplied {:.3e} J); most strained: element {} of grain '{}' ({:.3e} J/m³); reduce simulation.dt_safety",
                state.time,
                state.step,
                stored,
                self.energy_scale,
                e - g.elements.start,
                g.name,
                density
            )));
        }
        Ok(())
    }

    /// Total linear momentum Σ m v_{n−½} (kg·m/s).
    pub fn linear_momentum(&self) -> [f64; 3] {
        let mut p = [0.0; 3];
        for (m, v) in self.model.mass.iter().zip(&self.state.v) {
            for i in 0..3 {
                p[i] += m * v[i];
            }
        }
        p
    }

    /// Angular momentum about the origin, Σ m x_n × v_{n−½} (kg·m²/s): exactly conserved
    /// by central differences for rotation-invariant internal forces.
    pub fn angular_momentum(&self) -> [f64; 3] {
        let mut l = [0.0; 3];
        for ((m, x), v) in self.model.mass.iter().zip(&self.state.x).zip(&self.state.v) {
            l[0] += m * (x[1] * v[2] - x[2] * v[1]);
            l[1] += m * (x[2] * v[0] - x[0] * v[2]);
            l[2] += m * (x[0] * v[1] - x[1] * v[0]);
        }
        l
    }
}

/// f ← f_int + m_phys g − α m v_{n−½}; v_{n+½} ← v_{n−½} + Δt f/m for every node (driven
/// components are overwritten by the motions afterwards). Gravity acts on the physical
/// mass only: mass added by scaling is numerical and must not weigh anything.
fn apply_body_and_damping_forces(model: &Model, state: &State, scratch: &mut Scratch, dt: f64) {
    let g = model.gravity;
    if model.deformation_damping > 0.0 {
        compute_grain_rigid_velocities(model, state, &mut scratch.grain_rigid);
    }
    let rigid = &scratch.grain_rigid;
    let owned = model.owned_nodes;
    scratch.force[..owned]
        .par_chunks_mut(NODE_CHUNK)
        .zip(scratch.v_next[..owned].par_chunks_mut(NODE_CHUNK))
        .enumerate()
        .for_each(|(chunk, (f, vn))| {
            let base = chunk * NODE_CHUNK;
            for k in 0..f.len() {
                let n = base + k;
                let (m, mp, v) = (model.mass[n], model.physical_mass[n], state.v[n]);
                let fd = damping_force(model, rigid, n, &state.x[n], &v);
                for i in 0..3 {
                    f[k][i] += mp * g[i] + fd[i];
                    vn[k][i] = v[i] + dt * f[k][i] / m;
                }
            }
        });
}

/// Overrides the driven components of v_{n+½} so that driven nodes land exactly on their
/// prescribed positions at t_{n+1}; records reaction force, moment and work.
fn drive_prescribed_motions(
    model: &Model,
    motions: &[PrescribedMotion],
    state: &mut State,
    scratch: &mut Scratch,
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
        for (j, &node) in working.nodes.iter().enumerate() {
            let n = node as usize;
            let target = working.position(j, &c_next, &q_next);
            let x = state.x[n];
            let m = model.mass[n];
            let mut r = [0.0; 3];
            for i in 0..3 {
                if working.components[i] {
                    let v_new = (target[i] - x[i]) / dt;
                    r[i] = m * (v_new - state.v[n][i]) / dt - scratch.force[n][i];
                    scratch.v_next[n][i] = v_new;
                    p_before += r[i] * state.v[n][i];
                    p_after += r[i] * v_new;
                }
            }
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

/// Kinetic energy and power sums over nodes (fixed chunks, summed in order), then
/// x_{n+1} = x_n + Δt v_{n+½} and v ← v_{n+½}.
fn integrate_and_sum(
    model: &Model,
    state: &mut State,
    scratch: &mut Scratch,
    dt: f64,
) -> NodePartials {
    let g = model.gravity;
    let rigid = &scratch.grain_rigid;
    let owned = model.owned_nodes;
    state.x[..owned]
        .par_chunks_mut(NODE_CHUNK)
        .zip(state.v[..owned].par_chunks_mut(NODE_CHUNK))
        .zip(scratch.v_next[..owned].par_chunks(NODE_CHUNK))
        .zip(scratch.node_partials.par_iter_mut())
        .enumerate()
        .for_each(|(chunk, (((x, v), vn), out))| {
            let base = chunk * NODE_CHUNK;
            let mut p = NodePartials::default();
            for k in 0..x.len() {
                let n = base + k;
                let (m, mp) = (model.mass[n], model.physical_mass[n]);
                let (a, b) = (v[k], vn[k]);
                let ab = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
                let fd = damping_force(model, rigid, n, &x[k], &a);
                p.kinetic += 0.5 * m * ab;
                p.gravity_before += mp * (g[0] * a[0] + g[1] * a[1] + g[2] * a[2]);
                p.gravity_after += mp * (g[0] * b[0] + g[1] * b[1] + g[2] * b[2]);
                p.damping_before += fd[0] * a[0] + fd[1] * a[1] + fd[2] * a[2];
                p.damping_after += fd[0] * b[0] + fd[1] * b[1] + fd[2] * b[2];
                if p.bad_node.is_none()
                    && !(b[0].is_finite() && b[1].is_finite() && b[2].is_finite())
                {
                    p.bad_node = Some(n);
                }
                for i in 0..3 {
                    x[k][i] += dt * b[i];
                }
                v[k] = b;
            }
            *out = p;
        });
    let mut total = NodePartials::default();
    for p in &scratch.node_partials {
        total.kinetic += p.kinetic;
        total.gravity_before += p.gravity_before;
        total.gravity_after += p.gravity_after;
        total.damping_before += p.damping_before;
        total.damping_after += p.damping_after;
        if total.bad_node.is_none() {
            total.bad_node = p.bad_node;
        }
    }
    total
}
