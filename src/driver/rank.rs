//! One rank's part of a run: the METIS partition of the grains, the rank's solver (owned
//! grains + ghosts) and the MPI side of a step (halo exchange, reductions).

use crate::domain::halo::{Halo, HaloPlan};
use crate::domain::{Combine, Domain, PendingReduction, ReductionBuffers};
use crate::error::{InputError, MufeError, Result};
use crate::model::decomposition::{Decomposition, GrainBound, Partition, PlanCell};
use crate::model::global::{ghost_margin, GlobalMesh};
use crate::model::periodic::{CellKinematics, PeriodicCell};
use crate::scene::LoadedScene;
use crate::solver::{build_solver_for, Solver, StepHooks};

/// Partitions the grains over the ranks by their static cost (elements, surface nodes).
/// All ranks must call.
pub fn partition_grains(
    domain: &Domain,
    loaded: &LoadedScene,
    global: &GlobalMesh,
) -> Result<Vec<u32>> {
    let n = loaded.scene.grains.len();
    let parts = domain.size();
    if parts > n {
        return Err(InputError::new(
            &loaded.path,
            "grains",
            format!("{parts} ranks but only {n} grains: every rank needs at least one grain"),
        )
        .into());
    }
    let infos: Vec<partition::GrainInfo> = (0..n)
        .map(|g| partition::GrainInfo {
            centre: global.bounds[g].centre,
            bounding_radius: global.bounds[g].radius,
            elements: global.element_offset[g + 1] - global.element_offset[g],
            surface_nodes: global.surface_nodes[g],
        })
        .collect();
    metis_owner(domain, &infos, ghost_margin(global), "partitioning")
}

/// The owner of every grain from METIS over the grain graph of `infos` (rank 0 computes,
/// all receive, so every rank holds the same table). All ranks must call.
pub fn metis_owner(
    domain: &Domain,
    infos: &[partition::GrainInfo],
    margin: f64,
    what: &str,
) -> Result<Vec<u32>> {
    let mut bytes = Vec::new();
    if domain.is_root() {
        let graph = partition::GrainGraph::build(infos, margin, &partition::CostModel::default());
        let owner = partition::partition(&graph, domain.size(), 1)
            .map_err(|e| MufeError::Run(format!("{what}: {e}")))?;
        bytes = owner.iter().flat_map(|o| o.to_le_bytes()).collect();
    }
    domain.broadcast_bytes(&mut bytes);
    Ok(bytes
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect())
}

/// This rank's solver for the partition `owner` with ghosts planned from `bounds`, the
/// decomposition and its halo plan. Every rank steps with the smallest stable step of all
/// ranks. All ranks must call.
pub fn build_rank_solver(
    domain: &Domain,
    loaded: &LoadedScene,
    global: &GlobalMesh,
    owner: &[u32],
    bounds: &[GrainBound],
    cell_length: [f64; 3],
) -> Result<(Solver, Decomposition, HaloPlan)> {
    let plan = plan_ghosts(loaded, global, owner, bounds, cell_length, domain.rank());
    // A bad scene fails on every rank alike (same input), so returning is safe; anything
    // rank-specific would need the job aborted.
    let mut solver = build_solver_for(loaded, &plan.owned, &plan.ghosts)?;
    let mut dt = [solver.model.dt];
    domain.min_in_place(&mut dt);
    solver.model.dt = dt[0];
    solver.state.partition = Partition {
        owner: owner.to_vec(),
        planned_bounds: bounds.to_vec(),
        planned_cell: cell_length,
    };
    let halo = halo_plan(loaded, global, &solver, &plan, owner, bounds);
    Ok((solver, plan, halo))
}

/// Whether the halo sends ghosts their contact zones only: `parallel.trim_ghosts`, and no
/// periodic cell (its Love–Weber branch vectors take a ghost's centre as the mean of all its
/// surface nodes, so a periodic cell's ghosts travel whole).
pub fn trims_ghosts(loaded: &LoadedScene) -> bool {
    loaded.scene.parallel.trim_ghosts && PeriodicCell::of_scene(&loaded.scene).is_none()
}

/// The halo plan of `plan` on this rank's `solver`, with every plain ghost aimed at its
/// receiver's contact zone for the grain `bounds` unless the scene sends whole surfaces
/// (`parallel.trim_ghosts = false`).
pub fn halo_plan(
    loaded: &LoadedScene,
    global: &GlobalMesh,
    solver: &Solver,
    plan: &Decomposition,
    owner: &[u32],
    bounds: &[GrainBound],
) -> HaloPlan {
    let mut halo = HaloPlan::new(&solver.model, plan);
    if trims_ghosts(loaded) {
        halo.aim(owner, bounds, ghost_margin(global));
    }
    halo
}

/// The ghost plan of `rank` for the grain `bounds`, with the periodic cell (if any) at
/// edge lengths `cell_length` (m).
pub fn plan_ghosts(
    loaded: &LoadedScene,
    global: &GlobalMesh,
    owner: &[u32],
    bounds: &[GrainBound],
    cell_length: [f64; 3],
    rank: usize,
) -> Decomposition {
    let cell = PeriodicCell::of_scene(&loaded.scene);
    let at = cell.as_ref().map(|cell| PlanCell {
        cell,
        length: cell_length,
    });
    Decomposition::plan(owner, bounds, ghost_margin(global), rank, at)
}

/// Edge lengths of the scene's periodic cell at t = 0 (zero without one).
pub fn initial_cell_length(loaded: &LoadedScene) -> [f64; 3] {
    PeriodicCell::of_scene(&loaded.scene).map_or([0.0; 3], |c| c.length0)
}

/// Message tags of the two reductions that run through a stage (beside the halo's).
const WALL_SUM_TAG: i32 = 111;
const REBUILD_MAX_TAG: i32 = 113;

/// The MPI side of a step: ghost exchange and reductions.
pub struct RankHooks<'d> {
    pub domain: &'d Domain,
    pub halo: Halo<'d>,
    /// The walls' sum begun by `start_sum`, and the rebuild inputs' maximum begun by
    /// `start_max`.
    wall_sum: Reducing<'d>,
    rebuild_max: Reducing<'d>,
}

/// A reduction over ranks in flight, or the buffers kept between two.
struct Reducing<'d> {
    combine: Combine,
    tag: i32,
    in_flight: Option<PendingReduction<'d>>,
    buffers: ReductionBuffers<'d>,
}

impl<'d> Reducing<'d> {
    fn new(combine: Combine, tag: i32) -> Self {
        Self {
            combine,
            tag,
            in_flight: None,
            buffers: ReductionBuffers::default(),
        }
    }

    /// Starts one on `domain`; one left unfinished (a solver replaced while it ran) is
    /// waited for and dropped first, as every rank does.
    fn start(&mut self, domain: &'d Domain, values: &[f64]) {
        let buffers = match self.in_flight.take() {
            Some(stale) => stale.discard(),
            None => std::mem::take(&mut self.buffers),
        };
        let pending = domain.start_reduction(values, self.combine, self.tag, buffers);
        self.in_flight = Some(pending);
    }

    fn finish(&mut self, values: &mut [f64]) {
        let pending = (self.in_flight.take()).expect("a reduction over ranks was started");
        self.buffers = pending.finish(values);
    }
}

impl<'d> RankHooks<'d> {
    pub fn new(domain: &'d Domain, halo: Halo<'d>) -> Self {
        Self {
            domain,
            halo,
            wall_sum: Reducing::new(Combine::Sum, WALL_SUM_TAG),
            rebuild_max: Reducing::new(Combine::Max, REBUILD_MAX_TAG),
        }
    }
}

impl StepHooks for RankHooks<'_> {
    fn ghosts_in(&mut self, x: &mut [[f64; 3]], v: &mut [[f64; 3]]) -> Result<(), MufeError> {
        self.halo.end(x, v)
    }
    fn ghosts_out(
        &mut self,
        x: &[[f64; 3]],
        v: &[[f64; 3]],
        cell: &CellKinematics,
    ) -> Result<(), MufeError> {
        self.halo.begin(x, v, cell)
    }
    fn sends_only_what_is_read(&self) -> bool {
        self.halo.plan.trims
    }
    fn ghosts_read(&mut self, read: &[bool]) -> Result<(), MufeError> {
        self.halo.send_only_what_is_read(read)
    }
    fn refresh_ghosts(
        &mut self,
        x: &mut [[f64; 3]],
        v: &mut [[f64; 3]],
        cell: &CellKinematics,
    ) -> Result<(), MufeError> {
        self.halo.refresh_zones(x, v, cell)
    }
    fn max(&mut self, values: &mut [f64]) {
        if self.domain.size() > 1 {
            self.domain.max_in_place(values);
        }
    }
    fn sum(&mut self, values: &mut [f64]) {
        if self.domain.size() > 1 {
            self.domain.sum_in_place(values);
        }
    }
    fn start_sum(&mut self, values: &[f64]) {
        self.wall_sum.start(self.domain, values);
    }
    fn finish_sum(&mut self, values: &mut [f64]) {
        self.wall_sum.finish(values);
    }
    /// The driver changes a solver between steps only by replacing it (migration) or
    /// through `Solver::restore`, both of which drop the measure.
    fn decides_rebuild_ahead(&self) -> bool {
        true
    }
    fn start_max(&mut self, values: &[f64]) {
        self.rebuild_max.start(self.domain, values);
    }
    fn finish_max(&mut self, values: &mut [f64]) {
        self.rebuild_max.finish(values);
    }
}
