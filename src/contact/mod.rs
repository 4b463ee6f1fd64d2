//! Contact between grain surfaces (penalty, symmetric node-to-surface, Coulomb friction)
//! and with rigid plane walls (kinematic).
//!
//! # Grain–grain contact
//! Two passes per touching pair: every surface node of A against the facets of B, and every
//! surface node of B against the facets of A, each with weight ½ ([`narrow::PASS_WEIGHT`]),
//! so no grain is "master" and results do not depend on grain order. For a slave node s that
//! is inside the master surface by g > 0 (distance to the closest surface point, see
//! [`narrow`]) the contact pressure is p = ε_n g and the slave gets
//! f = ½ A_s (p n + t), with A_s its tributary area (one third of the adjacent facet areas,
//! reference configuration), n the master's outward normal at the contact point and t the
//! friction traction. The reaction −f goes to the master facet's corners by the barycentric
//! weights of the contact point, so linear and angular momentum balance exactly (up to the
//! O(g) lever arm of the tangential part).
//!
//! **Penalty stiffness** (pressure per unit penetration, Pa/m):
//! ε_n = factor · E' · min(h_s, h_m) / h_s², with E' = E/(1−ν²) of the stiffer of the two
//! materials, h_s the mean surface edge length at the slave node and h_m the same at the
//! contact point on the master (interpolated from the facet corners, so it is continuous).
//! On matching meshes this is factor · E'/h: the nodal spring ε_n A_s ≈ 0.9 factor E' h is
//! `factor` times stiffer than the local surface compliance of the mesh itself (a point load
//! on a surface node of a linear-tet mesh deflects by ~F/(E' h)), so the penetration is about
//! 1/factor of the local elastic approach there. When the slave side is the coarser one
//! (h_m < h_s) the pass is softened by h_m/h_s so that a big slave node cannot load one small
//! master node with a spring much stiffer than that node's own elements (that would set the
//! stable step); the fine-slave pass then carries the resolution.
//! Default factor: [`DEFAULT_PENALTY_FACTOR`] = 20. Measured (tests/contact_hard_cases.rs,
//! glass): max penetration / Hertz approach = 0.7 % (oblique impact, contact radius ≈ 2
//! elements), 1.3 % (sphere sliding on a block, ≈ 2.5 elements), 2.7 % (head-on impact whose
//! contact radius is below one element); it scales as 1/factor. On those meshes the stable
//! step with contact is ×0.87 / 0.81 / 0.72 / 0.65 of the element-only step at factor 5 / 10
//! / 20 / 30 (`mufe check` prints it); with `target_dt` the cost is added mass instead.
//!
//! **Contact damping**: a normal dashpot c ġ per point, c = 2ζ√(k m_s) (k = ε_n A, m_s the
//! slave node's mass), never pulling. Without it the node on its stiff penalty spring can
//! chatter at the highest frequencies of the mesh; friction (t = μ p(g)) feeds that
//! chatter, which then rectifies the friction force (measured: steady sliding force 2–3 %
//! below μN, erratically with the penalty factor) and, at sharp edges, flips the contact
//! direction from step to step. ζ = [`DEFAULT_CONTACT_DAMPING`] = 0.05 removes both (sliding
//! force within 0.3 % of μN for any factor) and dissipates ~2e-5 of the energy of a 1 m/s
//! elastic impact. Its work is part of ALLVD (`damping_dissipation`), integrated with the
//! same trapezoidal rule as every other force ([`damping_power`]). The stable step accounts
//! for the lagged dashpot: Δt ≤ (2/ω)(√(1+ζ²) − ζ).
//!
//! **Known limitation**: at a sharp convex edge the contact normal is the direction of the
//! closest face (the minimum translation), which switches between the two faces on their
//! medial plane. The penetration depth, hence the force magnitude, stays continuous (no
//! spike), but a perfectly symmetric edge-on-edge hit is resolved along the average of the
//! two face normals only thanks to the contact damping.
//!
//! **Stable step**: a surface node that can touch another grain gets
//! ω² = ω_el² + 2 k/m, k = ε_n,max A (the relative mode of two such nodes), ω_el the largest
//! frequency of its elements; Δt = safety · 2/max ω. Without `target_dt` this lowers the step
//! (reported by `mufe check/run`); with `target_dt` the contact nodes are mass-scaled like
//! elements so that the target holds (the added mass is reported).
//!
//! **Friction** ([`friction`]): elastic tangential predictor with ε_t = ε_n (the tangential
//! spring is a numerical compliance like the normal one, equally stiff, and does not raise
//! the stable step beyond the normal spring's estimate), return to |t| ≤ μ p, exact
//! dissipation ½A·(−t·Δs) per step. The traction of each contact point is remembered between
//! steps in [`ContactState::history`], keyed by [`ContactKey`] (slave grain id, master grain
//! id, node index within the slave grain: global ids that survive migration between ranks),
//! and rotated onto the current tangent plane each step. A point that stops penetrating
//! loses its history.
//!
//! **Energy**: contact forces between grains are internal. The stored penalty energy
//! ½ ε_n g² A + ½ |t|²/ε_t A (×½ per pass) is `contact_energy` (part of ALLIE), slip
//! dissipation is `friction_dissipation` (ALLFD); with central differences their sum changes
//! by minus the work of the contact forces (exactly for a linear spring in stick, up to
//! O(g/h) terms otherwise), so ETOTAL stays flat.
//!
//! **Detection** ([`broad`], [`narrow`]): Verlet-list broad phase over grain boxes with a
//! margin, per-grain facet BVHs, cached (node, candidate facets) lists; rebuilt only when some
//! surface node has moved by margin/2 since the last rebuild.
//!
//! # Walls
//! See [`walls`]: kinematic (exact) enforcement on v_{n+½}, optional Coulomb friction.
//!
//! # Determinism
//! Entries are evaluated in parallel over fixed chunks, each into its own slot; forces,
//! energies and the new history are then accumulated serially in entry order (passes sorted
//! by grain, slave nodes ascending). 1 and N threads give bitwise identical results.
//!
//! # Use from the solver (see `solver::step`)
//! 1. [`evaluate`] at x_n, v_{n−½} (stage `contact`; the step calls `evaluate_with` with
//!    the ranks' rebuild decision), after the internal forces;
//! 2. [`add_forces`] into the force buffer that holds the internal forces, which also
//!    returns the dampers' power at v_{n−½} ([`damping_power`] gives it at v_{n+½}, after
//!    the integrator);
//! 3. [`enforce_walls`] after v_{n+½} has been predicted and prescribed motions applied;
//! 4. the ledger reads [`ContactState::friction_dissipation_total`],
//!    [`ContactStats::energy`] and [`ContactState::wall_external_work`].

pub mod broad;
mod candidate_facet;
pub mod fabric;
pub mod friction;
pub mod narrow;
mod overlap;
pub mod patch;
mod prefetch;
mod reads;
pub mod triangle;
mod vertex_normals;
pub mod walls;

pub use crate::model::contact_layout::{
    ContactModel, GrainSurface, StableStepReport, Wall, DEFAULT_CONTACT_DAMPING,
    DEFAULT_MARGIN_FRACTION, DEFAULT_PENALTY_FACTOR, NONE,
};
pub use overlap::check_initial_overlap;
pub use reads::{mark_nodes_the_lists_read, NodeReadMarks};
pub use walls::GrainWallForces;

use crate::boundary::servo::ServoState;
use crate::boundary::stages::{StagePlan, StageProgress};
use crate::energy::WorkAccumulator;
use crate::error::MufeError;
use crate::kinematics::{NextVelocity, Predictor};
use crate::lanes::NodeForce;
use crate::math::dot;
use crate::model::Model;
pub use broad::DetectionReference;
use broad::{BroadPhase, CandidateLists};
use narrow::{EvalContext, PointResult};
use prefetch::{evaluate_pipelined, touch_point_nodes, RESULTS_AHEAD};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::ops::IndexMut;

/// Initial overlap beyond this fraction of the smallest surface edge of the two grains is an
/// input error.
pub const OVERLAP_TOLERANCE: f64 = 1e-3;
/// Entries per parallel work item (fixed, so results do not depend on the thread count).
const ENTRY_CHUNK: usize = 256;

/// Global key of a grain–grain contact point: the slave node (grain id + node index within
/// that grain) and the opposing grain, each with its periodic image. A contact with an
/// image is seen twice (A against B's image, A's image against B); the two passes are
/// distinct points with their own history, held by whichever ranks hold them, so a run
/// gives the same history on any number of ranks. Ordered by (grain, other, image,
/// other_image, node).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct ContactKey {
    /// Global id (scene index) of the slave node's grain.
    pub grain: u32,
    /// Global id of the master grain.
    pub other: u32,
    /// Periodic image of the slave grain (all zero without a periodic cell).
    #[serde(default)]
    pub image: crate::model::periodic::Image,
    /// Periodic image of the master grain.
    #[serde(default)]
    pub other_image: crate::model::periodic::Image,
    /// Node index within the slave grain's mesh.
    pub node: u32,
}

impl ContactKey {
    /// The key of slave node `node` (model id) of surface `slave` against `master`.
    #[inline]
    pub fn of(slave: &GrainSurface, master: &GrainSurface, node: u32) -> Self {
        Self {
            grain: slave.global_id,
            other: master.global_id,
            image: slave.image,
            other_image: master.image,
            node: node - slave.node_base,
        }
    }
}

/// Friction history of one contact point.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FrictionPoint {
    pub key: ContactKey,
    /// Tangential traction on the slave (Pa), global frame.
    pub traction: [f64; 3],
}

/// State of one wall (part of the checkpoint).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct WallState {
    /// Work of the wall force on the grains, ∫ f·v_node dt (J).
    pub work: WorkAccumulator,
    /// ∫ f_t·(v_node − v_wall) dt (J, ≤ 0): minus the friction dissipation at this wall.
    pub friction: WorkAccumulator,
    /// Force the wall exerts on the grains at the last step (N).
    pub force: [f64; 3],
    /// Wall displacement at the time of that force (m).
    pub displacement: [f64; 3],
    /// Nodes in contact at the last step.
    pub contacts: usize,
    /// Kinematics (and filtered force) of a wall driven by its state: a servo wall, or any
    /// wall of a staged scene (`None` for walls following a prescribed history).
    #[serde(default)]
    pub servo: Option<ServoState>,
}

/// Diagnostics of the last contact evaluation (and maxima over the run).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ContactStats {
    /// Active grain–grain contact points (a node penetrating in one pass counts once).
    pub points: usize,
    /// Largest penetration depth at the last step (m).
    pub max_penetration: f64,
    /// Stored penalty energy at the last step (J).
    pub energy: f64,
    /// Largest penetration seen so far (m).
    pub max_penetration_run: f64,
    /// Most contact points (grain + wall) seen at one step so far.
    pub max_contacts_run: usize,
    /// Resultant grain–grain contact force on each grain (N), aligned with `Model::grains`.
    pub grain_force: Vec<[f64; 3]>,
    /// Broad-phase rebuilds so far.
    pub rebuilds: u64,
    /// The skin of the broad phase's lists (m): how far surfaces may move before their
    /// rebuild (see [`broad`]).
    #[serde(default)]
    pub skin: f64,
}

/// Everything contact keeps between steps (serialised with the solver state).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ContactState {
    /// Friction history, sorted by key.
    pub history: Vec<FrictionPoint>,
    /// Energy dissipated by grain–grain slip so far (J).
    pub friction_dissipation: f64,
    pub walls: Vec<WallState>,
    pub stats: ContactStats,
    /// Surfaces at the last candidate-list rebuild.
    pub detection: DetectionReference,
}

impl ContactState {
    /// Initial contact state for a model.
    pub fn new(model: &Model) -> Self {
        Self {
            walls: (0..model.contact.walls.len())
                .map(|w| WallState {
                    servo: (model.stages.as_ref())
                        .is_some_and(|p| p.drives_wall(w))
                        .then(ServoState::default),
                    ..Default::default()
                })
                .collect(),
            stats: ContactStats {
                grain_force: vec![[0.0; 3]; model.grains.len()],
                ..Default::default()
            },
            ..Default::default()
        }
    }

    /// Grain–grain plus wall friction dissipation (J): ALLFD.
    pub fn friction_dissipation_total(&self) -> f64 {
        self.friction_dissipation - self.walls.iter().map(|w| w.friction.work).sum::<f64>()
    }

    /// Work of the walls counted as external work (J): their total work on the grains plus
    /// the part dissipated by wall friction (which is reported in ALLFD).
    pub fn wall_external_work(&self) -> f64 {
        self.walls
            .iter()
            .map(|w| w.work.work - w.friction.work)
            .sum()
    }

    /// Contact points at the last step: grain–grain points plus wall nodes.
    pub fn contacts(&self) -> usize {
        self.stats.points + self.walls.iter().map(|w| w.contacts).sum::<usize>()
    }
}

/// Contact scratch (not state): cached candidate lists and per-entry results.
#[derive(Debug, Default, Clone)]
pub struct ContactScratch {
    pub broad: BroadPhase,
    pub lists: CandidateLists,
    /// Indices of the entries evaluated at the last step (ascending): those a node could
    /// reach since the rebuild; every other entry is known to be out of contact.
    evaluated: Vec<u32>,
    /// One result per evaluated entry of the last evaluation (aligned with `evaluated`).
    pub results: Vec<PointResult>,
    history_old: Vec<FrictionPoint>,
    wall_now: Vec<[f64; 3]>,
    wall_next: Vec<[f64; 3]>,
    /// Normal force of each wall on each local grain at the last step.
    pub wall_grain_force: GrainWallForces,
    /// Force of the walls on each node they touched at the last step (node, N).
    pub wall_node_force: Vec<(u32, [f64; 3])>,
    /// What the narrow phase cost on this rank over the run's steps (see the type).
    pub narrow: NarrowPhaseTally,
}

/// Wall time and work of the narrow phase (the evaluation of the entries within reach),
/// summed over the steps the stage timers cover: from the run's start or its restart,
/// carried over a re-partition as they are. The largest part of the contact row, and the
/// cost that issue 14's whole-step measure turns on (docs/BENCHMARKS.md, session 71).
#[derive(Debug, Default, Clone, Copy)]
pub struct NarrowPhaseTally {
    pub seconds: f64,
    /// Entries evaluated, summed over the steps.
    pub entries: u64,
    pub steps: u64,
}

impl NarrowPhaseTally {
    /// Milliseconds per step, entries per step and microseconds per entry; `None` before
    /// any step evaluated an entry.
    pub fn per_step(&self) -> Option<(f64, f64, f64)> {
        (self.steps > 0 && self.entries > 0).then(|| {
            let steps = self.steps as f64;
            (
                1e3 * self.seconds / steps,
                self.entries as f64 / steps,
                1e6 * self.seconds / self.entries as f64,
            )
        })
    }
}

/// Stage 1 of the step: detection and grain–grain contact forces at x_n (velocities
/// v_{n−½} give the slip increment of the last step). Results stay in `scratch` until
/// [`add_forces`]; statistics, stored energy, dissipation and the new friction history go
/// into `state`. Fails (as a run error) when a node is found deeper than half its local
/// edge inside another grain: detection can no longer be trusted.
#[allow(clippy::too_many_arguments)]
pub fn evaluate(
    model: &Model,
    x: &[[f64; 3]],
    v: &[[f64; 3]],
    time: f64,
    step: u64,
    dt: f64,
    state: &mut ContactState,
    scratch: &mut ContactScratch,
) -> Result<(), MufeError> {
    let voted = needs_rebuild(model, x, time, step, dt, state, scratch);
    let rebuild = rebuild_skin(model, state, scratch, step, scratch.broad.moved, voted);
    let travel = scratch.broad.travel_into(step);
    scratch.lists.advance_odometer(travel);
    evaluate_with(model, x, v, time, step, dt, rebuild, state, scratch)
}

/// Whether this rank's contact lists are still to be made: [`evaluate_with`] rebuilds or
/// restores them at its next call (after a restart or a re-partition).
pub fn has_no_lists_yet(model: &Model, scratch: &ContactScratch) -> bool {
    model.contact.active() && !scratch.broad.built
}

/// The skin of the lists rebuilt at step `step`, or `None` when they are kept: see
/// [`broad::next_skin`]. `voted`: some rank's [`needs_rebuild`] found that its lists may
/// miss a contact; `moved`: the largest surface displacement since the rebuild over all
/// ranks.
pub fn rebuild_skin(
    model: &Model,
    state: &ContactState,
    scratch: &ContactScratch,
    step: u64,
    moved: f64,
    voted: bool,
) -> Option<f64> {
    let cm = &model.contact;
    if !cm.active() {
        return None;
    }
    if scratch.broad.fixed_skin {
        return (voted || !state.detection.built).then_some(cm.margin);
    }
    let wall_moved = scratch.broad.wall_moved;
    broad::next_skin(cm, &state.detection, step, moved, wall_moved, voted)
}

/// Whether the cached candidate lists must be rebuilt before evaluating at x_n (t_n =
/// `time`, n = `step`). Under MPI the ranks OR their answers so that all rebuild at the
/// same step, as the serial run would.
pub fn needs_rebuild(
    model: &Model,
    x: &[[f64; 3]],
    time: f64,
    step: u64,
    dt: f64,
    state: &ContactState,
    scratch: &mut ContactScratch,
) -> bool {
    let cm = &model.contact;
    if !cm.active() {
        return false;
    }
    scratch.wall_now.clear();
    scratch.wall_next.clear();
    for (w, ws) in cm.walls.iter().zip(&state.walls) {
        let [_, now, next] = walls::displacements(w, ws, time, dt);
        scratch.wall_now.push(now);
        scratch.wall_next.push(next);
    }
    scratch
        .broad
        .needs_rebuild(cm, x, &scratch.wall_next, &state.detection, step)
}

/// Values per grain in [`share_surface_motion`]'s buffer.
const MOTION_VALUES: usize = 4;

/// Writes the motion of this rank's own surfaces (from [`needs_rebuild`]) into `buffer`,
/// indexed by global grain id (`grains` of them), −∞ everywhere else: the element-wise
/// maximum of every rank's buffer then holds each grain's motion as its owner measured it
/// (the max with −∞ is exact), which [`take_surface_motion`] gives the ghosts.
pub fn share_surface_motion(
    model: &Model,
    scratch: &ContactScratch,
    grains: usize,
    buffer: &mut Vec<f64>,
) {
    buffer.clear();
    buffer.resize(MOTION_VALUES * grains, f64::NEG_INFINITY);
    let cm = &model.contact;
    for (g, m) in cm.surfaces.iter().zip(&scratch.broad.motion) {
        if g.owned && g.image == crate::model::periodic::NO_IMAGE {
            let at = MOTION_VALUES * g.global_id as usize;
            buffer[at..at + 3].copy_from_slice(&m.shift);
            buffer[at + 3] = m.spread;
        }
    }
}

/// The plain ghosts' motion from the maximum over ranks of [`share_surface_motion`]'s
/// buffers.
pub fn take_surface_motion(model: &Model, buffer: &[f64], scratch: &mut ContactScratch) {
    let cm = &model.contact;
    for (g, m) in cm.surfaces.iter().zip(&mut scratch.broad.motion) {
        if !g.moves_here() {
            let at = MOTION_VALUES * g.global_id as usize;
            let values = buffer.get(at..at + MOTION_VALUES);
            *m = match values {
                Some(&[a, b, c, spread]) if spread > f64::NEG_INFINITY => broad::SurfaceMotion {
                    shift: [a, b, c],
                    spread,
                },
                _ => broad::SurfaceMotion::UNKNOWN,
            };
        }
    }
}

/// [`evaluate`] with the rebuild decision taken by the caller: `rebuild` is the skin of the
/// lists to rebuild (see [`rebuild_skin`]), `None` to keep them.
#[allow(clippy::too_many_arguments)]
pub fn evaluate_with(
    model: &Model,
    x: &[[f64; 3]],
    v: &[[f64; 3]],
    time: f64,
    step: u64,
    dt: f64,
    rebuild: Option<f64>,
    state: &mut ContactState,
    scratch: &mut ContactScratch,
) -> Result<(), MufeError> {
    let cm = &model.contact;
    if !cm.active() {
        return Ok(());
    }
    if scratch.wall_now.len() != cm.walls.len() {
        needs_rebuild(model, x, time, step, dt, state, scratch);
    }
    if let Some(skin) = rebuild {
        scratch.broad.rebuild(
            cm,
            x,
            &scratch.wall_now,
            &mut scratch.lists,
            &mut state.detection,
            skin,
            step,
        );
    } else if !scratch.broad.built {
        scratch
            .broad
            .restore(cm, x, &state.detection, &mut scratch.lists);
    }
    state.stats.rebuilds = state.detection.rebuilds;
    state.stats.skin = state.detection.skin(cm);

    std::mem::swap(&mut state.history, &mut scratch.history_old);
    state.history.clear();
    let lists = &scratch.lists;
    let moved = scratch.broad.moved;
    // Only entries within reach are evaluated; in a dense packing they are a few % of the
    // cached ones, so neither the evaluation nor the passes over its results touch the rest.
    lists.within_reach(moved, &scratch.broad.motion, &mut scratch.evaluated);
    scratch
        .results
        .resize(scratch.evaluated.len(), PointResult::default());
    let ctx = EvalContext {
        cm,
        passes: &lists.passes,
        facets: &lists.candidate_facets,
        x,
        v,
        mass: &model.mass,
        dt,
        history: &scratch.history_old,
        friction: cm.friction > 0.0,
    };
    let started = std::time::Instant::now();
    scratch
        .results
        .par_chunks_mut(ENTRY_CHUNK)
        .zip(scratch.evaluated.par_chunks(ENTRY_CHUNK))
        .for_each(|(out, indices)| evaluate_pipelined(&ctx, &lists.entries, indices, out));
    let narrow = &mut scratch.narrow;
    narrow.seconds += started.elapsed().as_secs_f64();
    narrow.entries += scratch.evaluated.len() as u64;
    narrow.steps += 1;

    let stats = &mut state.stats;
    stats.points = 0;
    stats.max_penetration = 0.0;
    stats.energy = 0.0;
    let mut dissipation = 0.0;
    for (&i, r) in scratch.evaluated.iter().zip(&scratch.results) {
        if !r.active {
            continue;
        }
        let pass = lists.passes[r.pass as usize];
        if r.tunnel {
            let (sg, mg) = (
                &model.grains[pass.slave as usize],
                &model.grains[pass.master as usize],
            );
            return Err(MufeError::Run(format!(
                "contact failure at t = {time:.6e} s (step {step}): node {} of grain '{}' is {:.3e} m inside grain '{}', more than half its local surface edge {:.3e} m (tunnelling); raise contact.penalty_factor or reduce the loading rate",
                r.slave as usize - sg.nodes.start,
                sg.name,
                r.gap,
                mg.name,
                cm.node_h[lists.entries[i as usize].slave as usize]
            )));
        }
        if cm.surfaces[pass.slave as usize].owned {
            stats.points += 1;
            stats.max_penetration = stats.max_penetration.max(r.gap);
            stats.energy += r.energy;
            dissipation += r.dissipation;
        }
        if ctx.friction {
            let (sg, mg) = (
                &cm.surfaces[pass.slave as usize],
                &cm.surfaces[pass.master as usize],
            );
            state.history.push(FrictionPoint {
                key: ContactKey::of(sg, mg, r.slave),
                traction: r.traction,
            });
        }
    }
    debug_assert!(state.history.windows(2).all(|w| w[0].key < w[1].key));
    let outside = (scratch.results.iter()).map(|r| (!r.active).then_some(r.separation));
    scratch.lists.note_separations(&scratch.evaluated, outside);
    state.friction_dissipation += dissipation;
    stats.max_penetration_run = stats.max_penetration_run.max(stats.max_penetration);
    let c = state.contacts();
    state.stats.max_contacts_run = state.stats.max_contacts_run.max(c);
    Ok(())
}

/// Stage 2: adds the grain–grain contact forces of the last [`evaluate`] to `force` (serially,
/// in entry order), records the resultant contact force on each grain, and returns the
/// power of the contact dampers at the velocities `v` (v_{n−½}: see [`damping_power`]).
/// The power is summed in the same pass because it reads the same nodes of the same
/// points; a pass of its own cost a second round of scattered misses.
#[must_use = "the dampers' power belongs in the energy ledger"]
pub fn add_forces(
    model: &Model,
    scratch: &ContactScratch,
    state: &mut ContactState,
    v: &[[f64; 3]],
    force: &mut [NodeForce],
) -> f64 {
    let cm = &model.contact;
    if !cm.grain_contact {
        return 0.0;
    }
    let gf = &mut state.stats.grain_force;
    gf.clear();
    gf.resize(model.grains.len(), [0.0; 3]);
    let lists = &scratch.lists;
    let results = &scratch.results;
    let damped = cm.damping != 0.0;
    let mut power = 0.0;
    for (i, r) in results.iter().enumerate() {
        if let Some(ahead) = results.get(i + RESULTS_AHEAD) {
            touch_point_nodes(ahead, |n| {
                crate::lanes::touch_value(force, n);
                if damped {
                    crate::lanes::touch_value(v, n);
                }
            });
        }
        if !r.active {
            continue;
        }
        add_point_force(r, force);
        let f = r.force;
        let pass = lists.passes[r.pass as usize];
        for i in 0..3 {
            gf[pass.slave as usize][i] += f[i];
            gf[pass.master as usize][i] -= f[i];
        }
        if damped {
            add_point_damping_power(r, v, model.owned_nodes, &mut power);
        }
    }
    power
}

/// The contact force on every node at the last step (N): grain–grain (what
/// [`add_forces`] adds) plus the walls' (what [`enforce_walls`] applied through the
/// velocity correction), into `force` (zeroed first; one entry per model node), for
/// output.
pub fn contact_forces_into(scratch: &ContactScratch, force: &mut [[f64; 3]]) {
    force.iter_mut().for_each(|f| *f = [0.0; 3]);
    for r in scratch.results.iter().filter(|r| r.active) {
        add_point_force(r, force);
    }
    for (n, f) in &scratch.wall_node_force {
        let node = &mut force[*n as usize];
        for i in 0..3 {
            node[i] += f[i];
        }
    }
}

/// A contact point's force on its slave node and, weighted, the reaction on the master
/// facet's corners, into node forces of either layout (the step's, or output's `[f64; 3]`).
#[inline]
fn add_point_force<F: IndexMut<usize, Output = f64>>(r: &PointResult, force: &mut [F]) {
    let f = r.force;
    let s = r.slave as usize;
    for i in 0..3 {
        force[s][i] += f[i];
    }
    for (k, &m) in r.masters.iter().enumerate() {
        let w = r.weights[k];
        let m = m as usize;
        for i in 0..3 {
            force[m][i] -= w * f[i];
        }
    }
}

/// Power of the contact damping forces of the last [`evaluate`] at the velocities `v`:
/// [`add_forces`] returns it with v_{n−½}, and this is called with v_{n+½} after the
/// integrator, for the ledger's trapezoidal work rule (see `crate::energy`). ≤ 0 when the
/// damper only resists. After the integrator v_{n+½} is read where it was stored, not
/// predicted again at the four nodes of every point (with the grain's rigid velocity for
/// the mass damping).
pub fn damping_power(model: &Model, v: &[[f64; 3]], scratch: &ContactScratch) -> f64 {
    let mut power = 0.0;
    if model.contact.damping == 0.0 {
        return 0.0;
    }
    let results = &scratch.results;
    for (i, r) in results.iter().enumerate() {
        if let Some(ahead) = results.get(i + RESULTS_AHEAD) {
            touch_point_nodes(ahead, |n| crate::lanes::touch_value(v, n));
        }
        if r.active {
            add_point_damping_power(r, v, model.owned_nodes, &mut power);
        }
    }
    power
}

/// Power of one point's damper on the nodes it acts on, counted for owned nodes only
/// (below `owned`): every node belongs to exactly one rank, so the sum over ranks is the
/// serial one (and no ghost v_{n+½}, which only its owner knows, is needed).
/// Added to `power` term by term, in the order a sum over all points has always taken.
#[inline]
fn add_point_damping_power(r: &PointResult, v: &[[f64; 3]], owned: usize, power: &mut f64) {
    let f = r.damping_force;
    if f == 0.0 {
        return;
    }
    let s = r.slave as usize;
    if s < owned {
        *power += f * dot(v[s], r.normal);
    }
    for (k, &m) in r.masters.iter().enumerate() {
        let m = m as usize;
        if m < owned {
            *power -= f * r.weights[k] * dot(v[m], r.normal);
        }
    }
}

/// Stage 3: kinematic walls on v_{n+½} (see [`walls`]). `t` = t_n.
#[allow(clippy::too_many_arguments)]
pub fn enforce_walls(
    model: &Model,
    x: &[[f64; 3]],
    predictor: &Predictor,
    v_next: &mut NextVelocity,
    t: f64,
    dt: f64,
    state: &mut ContactState,
    scratch: &mut ContactScratch,
) {
    let cm = &model.contact;
    if cm.walls.is_empty() {
        return;
    }
    walls::enforce(
        cm,
        &model.mass,
        &model.driven,
        x,
        predictor,
        v_next,
        t,
        dt,
        &scratch.lists.wall_nodes,
        state,
        &mut scratch.wall_node_force,
        // per-grain sums only where a wall moves by them (see `GrainWallForces`)
        (model.stages.is_some()).then_some((
            &model.node_grain[..],
            model.grains.len(),
            &mut scratch.wall_grain_force,
        )),
    );
    let c = state.contacts();
    state.stats.max_contacts_run = state.stats.max_contacts_run.max(c);
}

/// This rank's share of the normal force F = f·n of every wall on every grain of the
/// scene (N), `[wall × grains + global id]`, zero for grains it does not own, into `out`;
/// the caller sums it over ranks (exactly: each entry has one non-zero term) and then
/// [`wall_totals`] adds the grains in global order, as a serial run does.
pub fn wall_normal_forces(
    model: &Model,
    scratch: &ContactScratch,
    grains: usize,
    out: &mut Vec<f64>,
) {
    let walls = model.contact.walls.len();
    out.clear();
    out.resize(walls * grains, 0.0);
    for w in 0..walls {
        for (g, grain) in model.grains[..model.owned_grains].iter().enumerate() {
            out[w * grains + grain.global_id as usize] = scratch.wall_grain_force.get(w, g);
        }
    }
}

/// Per-wall totals (N) of the summed [`wall_normal_forces`], in `totals`.
pub fn wall_totals(per_grain: &[f64], walls: usize, totals: &mut Vec<f64>) {
    totals.clear();
    let grains = per_grain.len() / walls.max(1);
    totals.extend((0..walls).map(|w| per_grain[w * grains..(w + 1) * grains].iter().sum::<f64>()));
}

/// Stage 3b: moves each state-driven wall to t_{n+1} and sets its next speed by the
/// current stage (see [`crate::boundary::stages`]) from the wall forces `global` (N,
/// summed over ranks, in the order of [`wall_normal_forces`]); may end the stage.
/// The periodic cell's axes (`cell_axes`) follow the walls as the plan's last three
/// entries: an axis moves like a wall whose displacement is its shortening, along −eₖ.
pub fn advance_walls(
    plan: &StagePlan,
    state: &mut ContactState,
    cell_axes: Option<&mut [Option<ServoState>; 3]>,
    progress: &mut StageProgress,
    global: &[f64],
    t_next: f64,
    dt: f64,
) {
    progress.wall_displacements.clear();
    (progress.wall_displacements).extend(state.walls.iter().map(|w| w.displacement));
    if let Some(axes) = &cell_axes {
        for (k, a) in axes.iter().enumerate() {
            let mut u = [0.0; 3];
            u[k] = -a.map_or(0.0, |s| s.displacement);
            progress.wall_displacements.push(u);
        }
    }
    let kinematics = (state.walls.iter_mut().map(|w| &mut w.servo))
        .chain(cell_axes.into_iter().flat_map(|a| a.iter_mut()));
    plan.advance(progress, kinematics, global, t_next, dt);
}

#[cfg(test)]
mod tests;
