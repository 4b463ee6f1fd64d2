//! The explicit central-difference step as named, timed stages:
//! internal forces (owned data only, overlapping the ghost exchange begun by the previous
//! step) → contact (detection, grain–grain forces at x_n, added to the force)
//! → boundary (prescribed motions; gravity and damping join a node's force wherever its
//! v_{n+½} is read, `crate::kinematics`) → contact (kinematic walls on v_{n+½}; the walls'
//! forces start their sum over ranks) → integrate (while the sum runs) → contact (servo
//! walls move to t_{n+1} from the summed force) → energy. Time in the contact parts is
//! charged to `contact`; the ghost exchange to `halo`, and the step's small collectives,
//! which wait for the slowest rank, to `sync`.
//!
//! Convention: at the start of step n the state holds x_n and v_{n−½};
//! v_{n+½} = v_{n−½} + Δt M⁻¹ f_n, x_{n+1} = x_n + Δt v_{n+½}.

use super::damping::{body_forces, damping_in_force, gravity_in_force, prepare_body_forces};
use super::forces::{compute_internal_forces_into, ElementScratch, NODE_CHUNK};
use super::integrate::{integrate_and_sum, NodePartials, StepResults};
use super::motions::drive_prescribed_motions;
use super::periodic::{
    axis_speeds, cell_contact_sums, cell_power, ramp_axis_speeds, refresh_local_images,
    total_over_grains, CellState,
};
use super::state::{Reaction, State};
use super::timing::{Stage, StageTimers};
use crate::boundary::PrescribedMotion;
use crate::contact::{ContactScratch, ContactState};
use crate::energy::{EnergyLedger, WorkAccumulator};
use crate::error::MufeError;
use crate::kinematics::{NextVelocity, Predictor, RigidVelocity};
use crate::lanes::NodeForce;
use crate::model::decomposition::Partition;
use crate::model::periodic::CellKinematics;
use crate::model::Model;

/// What a step needs from other ranks. The serial implementation ([`Serial`]) does
/// nothing; the MPI one is `crate::driver::rank::RankHooks`, which calls `crate::domain`
/// (the only module that talks to MPI).
pub trait StepHooks {
    /// Completes the ghost update: ghost surface x_n and v_{n−½} from their owners.
    fn ghosts_in(&mut self, _x: &mut [[f64; 3]], _v: &mut [[f64; 3]]) -> Result<(), MufeError> {
        Ok(())
    }
    /// Starts sending owned surface x_{n+1}, v_{n+½} to the ranks that mirror them
    /// (images shifted by the periodic cell at that time, `cell`).
    fn ghosts_out(
        &mut self,
        _x: &[[f64; 3]],
        _v: &[[f64; 3]],
        _cell: &CellKinematics,
    ) -> Result<(), MufeError> {
        Ok(())
    }
    /// Whether [`StepHooks::ghosts_read`] uses what it is told: then the caller marks,
    /// after every rebuild or restore of the contact lists, the nodes the lists read.
    fn sends_only_what_is_read(&self) -> bool {
        false
    }
    /// The contact lists were rebuilt or restored at this step and read the nodes marked in `read`
    /// (one flag per model node): from now on only those ghost nodes need be sent. All
    /// ranks call at the same step.
    fn ghosts_read(&mut self, _read: &[bool]) -> Result<(), MufeError> {
        Ok(())
    }
    /// The contact lists are about to be rebuilt at this step: ghosts whose unread nodes
    /// were not sent since the last rebuild get them now (x_n, v_{n−½}, images shifted
    /// by `cell`). All ranks call at the same step.
    fn refresh_ghosts(
        &mut self,
        _x: &mut [[f64; 3]],
        _v: &mut [[f64; 3]],
        _cell: &CellKinematics,
    ) -> Result<(), MufeError> {
        Ok(())
    }
    /// Element-wise maximum over ranks in place (all ranks must call).
    fn max(&mut self, _values: &mut [f64]) {}
    /// Sums over ranks in place (all ranks must call).
    fn sum(&mut self, _values: &mut [f64]) {}
    /// Starts the sum over ranks of `values` and returns at once (all ranks must call);
    /// [`StepHooks::finish_sum`] gives the result. One sum is in flight at a time.
    fn start_sum(&mut self, _values: &[f64]) {}
    /// Writes the sum begun by [`StepHooks::start_sum`] into `values` (the same length),
    /// waiting for the other ranks if it has not arrived.
    fn finish_sum(&mut self, _values: &mut [f64]) {}
    /// Whether the step measures the next step's rebuild inputs at its own end and
    /// reduces them over ranks while the next force stage runs ([`StepHooks::start_max`]).
    /// Only a caller that changes nothing between steps but through [`Solver::restore`]
    /// or a new solver may say yes: the measure is of the state the step left.
    fn decides_rebuild_ahead(&self) -> bool {
        false
    }
    /// Starts the element-wise maximum over ranks of `values` and returns at once (all
    /// ranks must call); [`StepHooks::finish_max`] gives the result. One maximum is in
    /// flight at a time; starting one drops (after waiting for) any left unfinished.
    fn start_max(&mut self, _values: &[f64]) {}
    /// Writes the maximum begun by [`StepHooks::start_max`] into `values` (the same
    /// length), waiting for the other ranks if it has not arrived.
    fn finish_max(&mut self, _values: &mut [f64]) {}
}

/// Steps between two blow-up checks of the energy ledger, at steps that are multiples of
/// it (so a restarted run checks at the same steps). The check sums six values over the
/// ranks, a collective that waits for the slowest one: every step it cost 0.13–0.15 ms of
/// a 40 ms step on 2 ranks, and it is a third of the reductions' latency projected for
/// 1024 (docs/BENCHMARKS.md, session 39). An unstable integration grows the energy by
/// orders of magnitude within a few steps, so the check still stops it early; what
/// becomes non-finite or inverts sooner is caught every step by the element and velocity
/// checks.
pub const ENERGY_CHECK_EVERY: u64 = 16;

/// Measures this rank's rebuild inputs at the state's x_n into `scratch.over_ranks`, for
/// the maximum over ranks: each grain's surface motion
/// (`crate::contact::share_surface_motion`), then the largest displacement, the rebuild
/// vote, the travel into this step and whether the lists are still to be built.
fn measure_rebuild_inputs(model: &Model, state: &State, scratch: &mut Scratch, dt: f64) {
    let local = crate::contact::needs_rebuild(
        model,
        &state.x,
        state.time,
        state.step,
        dt,
        &state.contact,
        &mut scratch.contact,
    );
    // Every rank skips entries by the largest displacement of any surface node, ghosts
    // included (their owners count them): a rank whose own grains rest must still see a
    // ghost grain that comes at them. The same reduction gives every ghost surface its
    // owner's motion since the rebuild, which bounds the entries evaluated.
    let over_ranks = &mut scratch.over_ranks;
    let grains = state.partition.owner.len();
    crate::contact::share_surface_motion(model, &scratch.contact, grains, over_ranks);
    let broad = &scratch.contact.broad;
    over_ranks.extend([
        broad.moved,
        f64::from(u8::from(local)),
        broad.travel_into(state.step),
        f64::from(u8::from(crate::contact::has_no_lists_yet(
            model,
            &scratch.contact,
        ))),
    ]);
}

/// One rank, nothing to exchange.
pub struct Serial;
impl StepHooks for Serial {}

/// Per-step scratch buffers (never serialised).
#[derive(Debug, Default)]
pub struct Scratch {
    /// Total force on each node at x_n (N).
    pub force: Vec<NodeForce>,
    /// v_{n+½} being built (m/s).
    pub v_next: NextVelocity,
    pub elements: ElementScratch,
    /// Cached contact candidate lists and per-point results.
    pub contact: ContactScratch,
    /// Normal force of each wall on each grain of the scene, this rank's share then
    /// summed over ranks (N), and each wall's total (`crate::contact::wall_normal_forces`).
    wall_grain_forces: Vec<f64>,
    wall_forces: Vec<f64>,
    /// Per model node: whether the contact lists read it (marked when they are built or
    /// restored, for the halo).
    read_by_contact: crate::contact::NodeReadMarks,
    node_partials: Vec<NodePartials>,
    /// Rigid-body velocity field of each grain (for deformation damping).
    pub(super) grain_rigid: Vec<RigidVelocity>,
    /// Centre of each grain for the periodic cell's stress.
    grain_centres: Vec<[f64; 3]>,
    /// Σ f ⊗ l of each grain of the scene (9 per global id) for the cell's stress.
    cell_grain_sums: Vec<f64>,
    /// What the contact check takes the maximum of over ranks: each grain's surface motion
    /// (`crate::contact::share_surface_motion`), then the largest displacement and the
    /// rebuild vote.
    over_ranks: Vec<f64>,
    /// The step whose rebuild inputs `over_ranks` holds, their maximum over ranks in
    /// flight (`StepHooks::decides_rebuild_ahead`).
    rebuild_inputs_for: Option<u64>,
}

/// Model + motions + state + scratch: one rank's explicit solver.
pub struct Solver {
    pub model: Model,
    pub motions: Vec<PrescribedMotion>,
    pub state: State,
    pub scratch: Scratch,
    pub timers: StageTimers,
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
            time_origin: 0.0,
            step_origin: 0,
            x: model.x0.clone(),
            v: v0,
            energy: EnergyLedger::default(),
            plastic: vec![
                crate::material::PlasticPoint::default();
                model
                    .plastic_slot
                    .iter()
                    .filter(|&&s| s != crate::model::NONE)
                    .count()
            ],
            motion_rotation: motions.iter().map(|m| m.rotation).collect(),
            reactions: vec![Reaction::default(); motions.len()],
            motion_work: vec![WorkAccumulator::default(); motions.len()],
            contact: ContactState::new(&model),
            stages: (model.stages.as_ref()).map_or_else(Default::default, |p| p.start()),
            supplied_energy: 0.0,
            partition: Partition {
                owner: vec![0; model.grains.len()],
                planned_bounds: Vec::new(),
                ..Default::default()
            },
            cell: (model.periodic.as_ref()).map(CellState::new),
        };
        let scratch = Scratch {
            force: vec![NodeForce::ZERO; n],
            v_next: NextVelocity::new(n),
            elements: ElementScratch::new(&model),
            contact: ContactScratch::default(),
            wall_grain_forces: Vec::new(),
            wall_forces: Vec::new(),
            read_by_contact: Default::default(),
            node_partials: vec![NodePartials::default(); model.owned_nodes.div_ceil(NODE_CHUNK)],
            grain_rigid: vec![RigidVelocity::default(); model.grains.len()],
            grain_centres: Vec::with_capacity(model.grains.len()),
            cell_grain_sums: Vec::new(),
            over_ranks: Vec::new(),
            rebuild_inputs_for: None,
        };
        Self {
            model,
            motions,
            state,
            scratch,
            timers: StageTimers::default(),
            energy_floor,
        }
    }

    /// Continues from `state` (taken from this solver, or from one built from the same
    /// scene and partition, e.g. a checkpoint): the scratch is dropped and rebuilt from
    /// the model and the state at the next step, so the run goes on exactly as it would
    /// have. Fails when the state does not fit this model.
    pub fn restore(&mut self, state: State) -> Result<(), MufeError> {
        let m = &self.model;
        let fits = state.x.len() == m.num_nodes()
            && state.v.len() == m.num_nodes()
            && state.reactions.len() == self.motions.len()
            && state.motion_rotation.len() == self.motions.len()
            && state.motion_work.len() == self.motions.len()
            && state.plastic.len() == self.state.plastic.len()
            && state.contact.walls.len() == m.contact.walls.len()
            && (state.contact.walls.iter()).enumerate().all(|(w, ws)| {
                ws.servo.is_some() == m.stages.as_ref().is_some_and(|p| p.drives_wall(w))
            })
            && state.stages.index <= m.stages.as_ref().map_or(0, |p| p.stages.len())
            && state.partition.owner.len() == self.state.partition.owner.len()
            && state.cell.is_some() == m.periodic.is_some();
        if !fits {
            return Err(MufeError::Run(format!(
                "the state ({} nodes, {} motions, {} walls) does not fit this model ({} nodes, {} motions, {} walls)",
                state.x.len(),
                state.reactions.len(),
                state.contact.walls.len(),
                m.num_nodes(),
                self.motions.len(),
                m.contact.walls.len()
            )));
        }
        self.state = state;
        if self.state.time_at_step(self.state.step, m.dt) != self.state.time {
            // a branch with another Δt: time goes on from the checkpoint's
            self.state.time_origin = self.state.time;
            self.state.step_origin = self.state.step;
        }
        self.scratch.contact = ContactScratch::default();
        // rebuild inputs measured on the state replaced are not this state's
        self.scratch.rebuild_inputs_for = None;
        Ok(())
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
        // one damping for the whole step: its force and its work use the same α
        let alpha = damping_in_force(model, &state.stages);
        // and one gravity: the stage's, for the force and for its work
        let gravity = gravity_in_force(model, &state.stages);

        // Internal forces first: they need only owned data, so they overlap the halo
        // exchange begun at the end of the previous step.
        let summary = timers.time(Stage::InternalForces, || {
            compute_internal_forces_into(
                model,
                &state.x,
                &mut state.plastic,
                &mut scratch.elements,
                &mut scratch.force,
            )
        });
        timers.time(Stage::Halo, || hooks.ghosts_in(&mut state.x, &mut state.v))?;
        // the cell at t_n, with its rate over the step that led there
        let cell_before = state.cell_kinematics(model);
        if model.periodic.is_some() {
            timers.time(Stage::Halo, || {
                refresh_local_images(model, &mut state.x, &mut state.v, &cell_before)
            });
        }
        // The rebuild inputs at x_n: measured at the end of the previous step and reduced
        // while this rank computed its forces, or here (the first step, after a restore
        // or a new solver, and for a periodic cell, which moves its images in between).
        if scratch.rebuild_inputs_for == Some(state.step) {
            timers.time(Stage::Sync, || hooks.finish_max(&mut scratch.over_ranks));
        } else {
            timers.time(Stage::Contact, || {
                measure_rebuild_inputs(model, state, scratch, dt)
            });
            timers.time(Stage::Sync, || hooks.max(&mut scratch.over_ranks));
        }
        scratch.rebuild_inputs_for = None;
        let over_ranks = &scratch.over_ranks;
        let [moved, rebuild, travel, no_lists] = over_ranks[over_ranks.len() - 4..] else {
            unreachable!("four values were appended")
        };
        scratch.contact.broad.moved = moved;
        scratch.contact.lists.advance_odometer(travel);
        let rebuild = crate::contact::rebuild_skin(
            model,
            &state.contact,
            &scratch.contact,
            state.step,
            moved,
            rebuild > 0.0,
        );
        timers.time(Stage::Contact, || {
            crate::contact::take_surface_motion(model, &scratch.over_ranks, &mut scratch.contact)
        });
        // A rebuild sees whole contact zones; the lists it builds say what is read after.
        // Lists restored from a checkpoint (a restart on the partition it was written
        // with) say it as well: the new halo sends whole zones until told, which would
        // otherwise last until the next rebuild. Every rank decides alike (both reduced).
        let rebuilds = rebuild.is_some();
        let tells_reads = (rebuilds || no_lists > 0.0) && hooks.sends_only_what_is_read();
        if tells_reads && rebuilds {
            timers.time(Stage::Halo, || {
                hooks.refresh_ghosts(&mut state.x, &mut state.v, &cell_before)
            })?;
        }
        timers.time(Stage::Contact, || {
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
        if tells_reads {
            timers.time(Stage::Halo, || {
                let marks = &mut scratch.read_by_contact;
                crate::contact::mark_nodes_the_lists_read(model, &scratch.contact, marks);
                hooks.ghosts_read(marks.read())
            })?;
        }
        // the dampers' power at v_{n−½} comes with the forces (the integrator overwrites v)
        let contact_damping_before = timers.time(Stage::Contact, || {
            crate::contact::add_forces(
                model,
                &scratch.contact,
                &mut state.contact,
                &state.v,
                &mut scratch.force,
            )
        });
        if let Some(bad) = summary.bad_element {
            let g = &model.grains[model.grain_of_element(bad.element)];
            return Err(MufeError::Run(format!(
                "blow-up at t = {:.6e} s (step {}): element {} of grain '{}' {}; reduce simulation.dt_safety or check the loading",
                state.time,
                state.step,
                bad.element - g.elements.start,
                g.name,
                bad.describe()
            )));
        }

        timers.time(Stage::Boundary, || {
            prepare_body_forces(model, state, &mut scratch.grain_rigid);
            scratch.v_next.predict_where_read();
            drive_prescribed_motions(
                model,
                &self.motions,
                state,
                &scratch.force,
                body_forces(model, alpha, gravity, &scratch.grain_rigid),
                &mut scratch.v_next,
                dt,
            );
        });
        let body = body_forces(model, alpha, gravity, &scratch.grain_rigid);
        let predictor = Predictor::new(&state.v, &scratch.force, &model.mass, dt)
            .with_body_forces(body, &state.x);
        timers.time(Stage::Contact, || {
            crate::contact::enforce_walls(
                model,
                &state.x,
                &predictor,
                &mut scratch.v_next,
                state.time,
                dt,
                &mut state.contact,
                &mut scratch.contact,
            )
        });
        let cell_sums = (model.periodic.as_ref()).map(|_| {
            let sums = timers.time(Stage::Contact, || {
                cell_contact_sums(
                    model,
                    &state.x,
                    &scratch.contact,
                    &mut scratch.grain_centres,
                    &mut scratch.cell_grain_sums,
                    state.partition.owner.len(),
                )
            });
            timers.time(Stage::Sync, || hooks.sum(&mut scratch.cell_grain_sums));
            timers.time(Stage::Contact, || {
                let total = total_over_grains(&scratch.cell_grain_sums);
                let volume: f64 = cell_before.length.iter().product();
                if let Some(c) = &mut state.cell {
                    c.contact_stress = total.map(|v| v / volume);
                }
            });
            sums
        });
        // State-driven walls must move identically on every rank, and stages end at the
        // same step everywhere: one sum over ranks of the walls' normal forces (serial runs:
        // the local forces as they are). Nothing the integrator reads depends on it, so the
        // sum runs while this rank integrates: its latency is hidden there, and a rank
        // that arrived early computes instead of waiting.
        if model.stages.is_some() {
            timers.time(Stage::Contact, || {
                let grains = state.partition.owner.len();
                crate::contact::wall_normal_forces(
                    model,
                    &scratch.contact,
                    grains,
                    &mut scratch.wall_grain_forces,
                );
            });
            timers.time(Stage::Sync, || hooks.start_sum(&scratch.wall_grain_forces));
        }

        let partials = timers.time(Stage::Integrate, || {
            let step = StepResults {
                force: &scratch.force,
                next: &scratch.v_next,
                rigid: &scratch.grain_rigid,
                path: scratch.elements.path,
            };
            let partials = &mut scratch.node_partials;
            integrate_and_sum(model, alpha, gravity, state, step, partials, dt)
        });
        if let Some(plan) = &model.stages {
            timers.time(Stage::Sync, || {
                hooks.finish_sum(&mut scratch.wall_grain_forces)
            });
            timers.time(Stage::Contact, || {
                crate::contact::wall_totals(
                    &scratch.wall_grain_forces,
                    model.contact.walls.len(),
                    &mut scratch.wall_forces,
                );
                if let Some(c) = &state.cell {
                    // a cell axis acts as a wall pushing with σ_kk on the current face
                    let l = cell_before.length;
                    for k in 0..3 {
                        let area = l[(k + 1) % 3] * l[(k + 2) % 3];
                        scratch.wall_forces.push(c.contact_stress[4 * k] * area);
                    }
                }
                let speeds = state.cell.as_ref().map(axis_speeds);
                crate::contact::advance_walls(
                    plan,
                    &mut state.contact,
                    state.cell.as_mut().map(|c| &mut c.axes),
                    &mut state.stages,
                    &scratch.wall_forces,
                    state.time + dt,
                    dt,
                );
                if let (Some(c), Some(before)) = (&mut state.cell, speeds) {
                    ramp_axis_speeds(model, c, before, dt);
                }
            });
        }
        let cell_after = state.cell_kinematics(model);
        if let (Some(sums), Some(c)) = (cell_sums, &mut state.cell) {
            c.work.record(
                dt,
                cell_power(&sums.image_force, &cell_before.rate),
                cell_power(&sums.image_force, &cell_after.rate),
            );
        }
        // and with v_{n+½}, for the trapezoidal rule
        let contact_damping_after = timers.time(Stage::Contact, || {
            crate::contact::damping_power(model, &state.v, &scratch.contact)
        });
        timers.time(Stage::Halo, || {
            hooks.ghosts_out(&state.x, &state.v, &cell_after)
        })?;
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
            e.recoverable_strain = summary.strain_energy;
            e.plastic_dissipation += summary.plastic_work;
            e.body_force
                .record(dt, partials.gravity_before, partials.gravity_after);
            e.damping.record(
                dt,
                partials.damping_before + contact_damping_before,
                partials.damping_after + contact_damping_after,
            );
            e.friction_dissipation = state.contact.friction_dissipation_total();
            e.contact_energy = state.contact.stats.energy;
            e.boundary_work = state.motion_work.iter().map(|w| w.work).sum::<f64>()
                + state.contact.wall_external_work()
                + state.cell.as_ref().map_or(0.0, |c| c.work.work);
            if e.initial_total.is_none() {
                e.initial_total = Some(e.total());
            }
        });

        state.time = state.time_at_step(state.step + 1, dt);
        state.step += 1;
        // a periodic cell also shifts the images' nodes, which the integrator's speeds do
        // not bound: the contact check then measures every step
        if model.periodic.is_none() {
            let travel = 3f64.sqrt() * dt * partials.max_speed;
            scratch.contact.broad.note_travel(state.step, travel);
        }
        // The state is now the next step's x_n: its rebuild inputs are measured here and
        // their maximum over ranks runs through the next force stage, so that a rank whose
        // force stage ran faster does not wait for the others' there.
        if hooks.decides_rebuild_ahead() && model.periodic.is_none() {
            timers.time(Stage::Contact, || {
                measure_rebuild_inputs(model, state, scratch, dt)
            });
            timers.time(Stage::Sync, || hooks.start_max(&scratch.over_ranks));
            scratch.rebuild_inputs_for = Some(state.step);
        }

        // Exploding energy: with every force accounted for, KE + U cannot exceed the energy
        // supplied; an unstable integration grows it exponentially past any such bound.
        if !state.step.is_multiple_of(ENERGY_CHECK_EVERY) {
            return Ok(());
        }
        let e = &state.energy;
        let mut global = [
            e.external_work(),
            e.initial_total.unwrap_or(0.0),
            e.damping_dissipation(),
            e.kinetic + e.strain(),
            self.energy_floor,
            e.contact_energy + e.friction_dissipation,
        ];
        timers.time(Stage::Sync, || hooks.sum(&mut global));
        state.supplied_energy = state
            .supplied_energy
            .max(global[0].abs() + global[1].abs() + global[2].abs());
        let stored = global[3];
        // Written so that a NaN anywhere in the ledger fails the check (NaN compares false).
        let finite = global.iter().all(|v| v.is_finite());
        if !finite || !(stored <= 10.0 * state.supplied_energy || stored <= global[4]) {
            let (e, density) =
                super::diagnose::most_strained_element(&self.model, &state.x, &state.plastic);
            let g = &self.model.grains[self.model.grain_of_element(e)];
            return Err(MufeError::Run(format!(
                "blow-up at t = {:.6e} s (step {}): energy exploded or is not finite (kinetic + strain = {:.3e} J, supplied {:.3e} J); most strained: element {} of grain '{}' ({:.3e} J/m³); reduce simulation.dt_safety",
                state.time,
                state.step,
                stored,
                state.supplied_energy,
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
