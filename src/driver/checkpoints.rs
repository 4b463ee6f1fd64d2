//! When a run writes checkpoints (every N steps, every T seconds of wall time, and on
//! SIGTERM/SIGINT/SIGUSR1), and how a run restarts from one.
//!
//! A restart on the rank count that wrote the checkpoint gives every rank its own `State`
//! back and continues bitwise. On another rank count the grains are re-partitioned (METIS
//! on their bounds at the checkpoint) and every rank installs the grain packages of the
//! grains it holds; the run-level state comes from rank 0's, and the per-rank totals
//! (energies, the walls' work) are summed onto rank 0, so the sums over ranks are those of
//! the checkpoint up to round-off.
//!
//! `latest` takes the newest readable checkpoint of `OUT/checkpoints/`, naming on stderr
//! every newer one it skipped as damaged.

use super::migration::{pack_grain, pack_image_history, remote_images, unpack_grains};
use super::rank::{build_rank_solver, metis_owner};
use crate::domain::Domain;
use crate::error::{InputError, MufeError, Result};
use crate::io::checkpoint::{
    step_files_oldest_first, write_checkpoint, CheckpointFile, CheckpointInfo, GrainPackages,
    RankCheckpoint, Target, CHECKPOINT_DIR,
};
use crate::model::decomposition::{Decomposition, Partition};
use crate::model::global::{ghost_margin, GlobalMesh};
use crate::scene::LoadedScene;
use crate::solver::{RankTotals, Solver, State};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The value of `--restart` that picks the newest valid checkpoint of `OUT/checkpoints/`.
pub const LATEST: &str = "latest";

/// The checkpoint schedule of a run.
pub struct CheckpointSchedule {
    every_steps: Option<u64>,
    every_seconds: Option<f64>,
    keep: usize,
    last: Instant,
    /// Step of the last checkpoint written by this run.
    last_step: Option<u64>,
    /// What this run has written.
    pub stats: CheckpointStats,
}

/// Checkpoints written by a run: count, size and time of the last (for the summary and
/// docs/BENCHMARKS.md).
#[derive(Debug, Clone, Copy, Default)]
pub struct CheckpointStats {
    pub written: u64,
    /// Size of the last file (bytes).
    pub last_bytes: u64,
    /// Wall time of the last write, packing and serialisation included (s).
    pub last_seconds: f64,
    /// Wall time of all writes (s).
    pub total_seconds: f64,
    /// Elements of the whole model (all ranks).
    pub elements: usize,
}

impl CheckpointSchedule {
    /// From the scene's `[output]` and the command line's `--checkpoint-every` (which
    /// replaces the scene's step interval).
    pub fn new(loaded: &LoadedScene, every_steps: Option<u64>) -> Self {
        let o = &loaded.scene.output;
        Self {
            every_steps: every_steps.or(o.checkpoint_every),
            every_seconds: o.checkpoint_interval,
            keep: o.checkpoints_kept,
            last: Instant::now(),
            last_step: None,
            stats: CheckpointStats::default(),
        }
    }

    /// Whether a checkpoint is due after step `step` (`forced`: now, e.g. on a stop
    /// signal, unless this step's is written already). The wall-time decision is reduced
    /// over ranks (clocks differ), every [`super::COLLECTIVE_CHECK_EVERY`] steps; `forced`
    /// must be the same on all ranks. All ranks must call.
    pub fn due(&self, domain: &Domain, step: u64, forced: bool) -> bool {
        let by_steps = self.every_steps.is_some_and(|n| step.is_multiple_of(n));
        let clock_read = super::loop_collective_due(domain, step);
        let by_time = match self.every_seconds {
            Some(t) if clock_read => {
                let mut elapsed = [self.last.elapsed().as_secs_f64()];
                domain.max_in_place(&mut elapsed);
                elapsed[0] >= t
            }
            _ => false,
        };
        (by_steps || by_time || forced) && self.last_step != Some(step)
    }

    /// Writes the checkpoint of the solver's current step. All ranks must call.
    pub fn write(
        &mut self,
        domain: &Domain,
        dir: &Path,
        loaded: &LoadedScene,
        solver: &Solver,
    ) -> Result<PathBuf> {
        let t0 = Instant::now();
        let target = Target::Rotation { keep: self.keep };
        let path = write_solver_checkpoint(domain, dir, loaded, solver, target)?;
        let seconds = t0.elapsed().as_secs_f64();
        self.stats = CheckpointStats {
            written: self.stats.written + 1,
            last_bytes: std::fs::metadata(&path).map_or(0, |m| m.len()),
            last_seconds: seconds,
            total_seconds: self.stats.total_seconds + seconds,
            elements: self.stats.elements,
        };
        self.last = Instant::now();
        self.last_step = Some(solver.state.step);
        Ok(path)
    }
}

impl CheckpointSchedule {
    /// Keeps the state at the end of stage `k` (1-based) as
    /// `DIR/checkpoints/stage_<k>_<name>.h5`: a link to this step's checkpoint when the
    /// rotation has just written it, else its own file (the rotation is left as it is).
    /// All ranks must call.
    pub fn write_stage_end(
        &mut self,
        domain: &Domain,
        dir: &Path,
        loaded: &LoadedScene,
        solver: &Solver,
        (k, name): (usize, &str),
    ) -> Result<PathBuf> {
        let step = solver.state.step;
        let kept = crate::io::checkpoint::stage_checkpoint_path(dir, k, name);
        if self.last_step != Some(step) {
            return write_solver_checkpoint(domain, dir, loaded, solver, Target::Kept(kept));
        }
        let source = crate::io::checkpoint::checkpoint_path(dir, step);
        let linked = if domain.is_root() {
            crate::io::checkpoint::keep_checkpoint_as(&source, &kept).map_err(|e| e.to_string())
        } else {
            Ok(())
        };
        crate::io::results::agree(domain, &kept, "keeping the stage checkpoint", linked)?;
        Ok(kept)
    }
}

/// Writes the checkpoint of the solver's current step. All ranks must call.
fn write_solver_checkpoint(
    domain: &Domain,
    dir: &Path,
    loaded: &LoadedScene,
    solver: &Solver,
    target: Target,
) -> Result<PathBuf> {
    let json = |what: &str, r: serde_json::Result<Vec<u8>>| {
        r.map_err(|e| MufeError::Run(format!("serialising the {what} for a checkpoint: {e}")))
    };
    let state = json("state", serde_json::to_vec(&solver.state))?;
    let totals = json("totals", serde_json::to_vec(&solver.state.rank_totals()))?;
    let m = &solver.model;
    let (mut ids, mut lengths, mut packages) = (Vec::new(), Vec::new(), Vec::new());
    for (mg, g) in m.grains[..m.owned_grains].iter().enumerate() {
        let before = packages.len();
        pack_grain(solver, mg, &mut packages);
        ids.push(u64::from(g.global_id));
        lengths.push((packages.len() - before) as u64);
    }
    // the history of passes computed only here, for a restart on another rank count
    for mg in remote_images(solver) {
        let before = packages.len();
        pack_image_history(solver, mg, &mut packages);
        if packages.len() > before {
            ids.push(u64::from(m.grains[mg].global_id));
            lengths.push((packages.len() - before) as u64);
        }
    }
    let part = RankCheckpoint {
        state: &state,
        totals: &totals,
        grain_ids: &ids,
        package_lengths: &lengths,
        packages: &packages,
    };
    let s = &solver.state;
    write_checkpoint(domain, dir, &loaded.text, &part, s.step, s.time, target)
}

/// A checkpoint to continue from.
pub struct Restart {
    pub info: CheckpointInfo,
    pub path: PathBuf,
    pub source: RestartSource,
}

/// Where a rank's state comes from.
pub enum RestartSource {
    /// The rank count that wrote the checkpoint: this rank's own state.
    Own(Box<State>),
    /// Another rank count: rank 0's state for what is not per grain, the per-rank totals
    /// of all ranks, and every grain package.
    Repartition {
        run_level: Box<State>,
        totals: Vec<RankTotals>,
        grains: GrainPackages,
    },
}

impl Restart {
    /// "restart from FILE (step N, t = T s, written by R ranks) on Q ranks", naming a
    /// re-partition and a branch.
    pub fn describe(&self, ranks: usize, branch: bool) -> String {
        format!(
            "{} from {} (step {}, t = {:.9e} s, written by {} ranks) on {ranks} ranks{}",
            if branch { "branch" } else { "restart" },
            self.path.display(),
            self.info.step,
            self.info.time,
            self.info.ranks,
            if self.info.ranks == ranks as u64 {
                ""
            } else {
                ", grains re-partitioned"
            }
        )
    }

    /// Grain owners and bounds to build the ranks' solvers with: the checkpoint's on its
    /// own rank count, a METIS partition of the bounds at the checkpoint otherwise. All
    /// ranks must call.
    pub fn partition(&self, domain: &Domain, global: &GlobalMesh) -> Result<Partition> {
        let (state, own) = match &self.source {
            RestartSource::Own(s) => (s.as_ref(), true),
            RestartSource::Repartition { run_level, .. } => (run_level.as_ref(), false),
        };
        let p = &state.partition;
        let bounds = if p.planned_bounds.is_empty() {
            global.bounds.clone()
        } else {
            p.planned_bounds.clone()
        };
        if own {
            return Ok(Partition {
                owner: p.owner.clone(),
                planned_bounds: bounds,
                planned_cell: p.planned_cell,
            });
        }
        let infos: Vec<partition::GrainInfo> = (0..bounds.len())
            .map(|g| partition::GrainInfo {
                centre: bounds[g].centre,
                bounding_radius: bounds[g].radius,
                elements: global.element_offset[g + 1] - global.element_offset[g],
                surface_nodes: global.surface_nodes[g],
            })
            .collect();
        let owner = metis_owner(
            domain,
            &infos,
            ghost_margin(global),
            "re-partitioning a restart",
        )?;
        Ok(Partition {
            owner,
            planned_bounds: bounds,
            planned_cell: p.planned_cell,
        })
    }

    /// Puts the checkpoint's state into `solver` (built for [`Restart::partition`]).
    pub fn install(self, domain: &Domain, solver: &mut Solver) -> Result<()> {
        let partition = solver.state.partition.clone();
        match self.source {
            RestartSource::Own(state) => solver.restore(*state),
            RestartSource::Repartition {
                run_level,
                totals,
                grains,
            } => {
                solver.state.take_run_level_from(&run_level);
                solver.state.partition = partition;
                let sum = RankTotals::sum(&totals);
                let mine = if domain.is_root() {
                    sum
                } else {
                    sum.zero_like()
                };
                solver.state.set_rank_totals(&mine);
                solver.state.contact.history.clear();
                let installed = unpack_grains(solver, &grains.packages)?;
                // images and plain copies of one grain share its package
                let mut ids: Vec<u32> = solver.model.grains.iter().map(|g| g.global_id).collect();
                ids.sort_unstable();
                ids.dedup();
                let held = ids.len();
                if installed.len() != held {
                    return Err(MufeError::Run(format!(
                        "restart on rank {}: the checkpoint holds {} of the {held} grains this rank needs",
                        domain.rank(),
                        installed.len()
                    )));
                }
                Ok(())
            }
        }
    }
}

/// Reads the checkpoint named by `--restart` (a file, or [`LATEST`] in `out`) for the
/// scene `loaded`. An error on any rank is an error on all. All ranks must call.
pub fn load_restart(
    domain: &Domain,
    loaded: &LoadedScene,
    spec: &Path,
    out: &Path,
    branch: bool,
) -> Result<Restart> {
    let latest = spec.as_os_str() == LATEST;
    let candidates = if latest {
        let folder = out.join(CHECKPOINT_DIR);
        let found = newest_first(&folder);
        if found.is_empty() {
            return Err(InputError::new(
                folder.display().to_string(),
                "--restart latest",
                "no checkpoint (step_*.h5) to restart from",
            )
            .into());
        }
        found
    } else {
        vec![spec.to_path_buf()]
    };
    let last = candidates.len() - 1;
    for (k, path) in candidates.into_iter().enumerate() {
        let local = read_restart(domain, loaded, &path, branch);
        let failed = domain.all_gather_u64(u64::from(local.is_err()));
        let first_failed = failed.iter().position(|&f| f != 0);
        match (local, first_failed) {
            (Ok(r), None) => return Ok(r),
            // with `latest`, a damaged file gives way to the next older one
            (local, Some(r))
                if latest && k < last && local.as_ref().err().is_none_or(|e| e.damaged) =>
            {
                if domain.is_root() {
                    let why = match &local {
                        Err(e) => e.error.to_string(),
                        Ok(_) => format!("unreadable on rank {r}"),
                    };
                    crate::error::report_line(format_args!(
                        "warning: skipping damaged checkpoint {}: {why}",
                        path.display()
                    ));
                }
            }
            (Err(e), _) => return Err(e.error),
            (Ok(_), Some(r)) => {
                return Err(InputError::new(
                    path.display().to_string(),
                    "checkpoint",
                    format!("unreadable on rank {r} (see its error)"),
                )
                .into())
            }
        }
    }
    unreachable!("the last candidate returns")
}

/// `step_*.h5` files of `folder`, newest step first (none when it cannot be read).
fn newest_first(folder: &Path) -> Vec<PathBuf> {
    let mut files = step_files_oldest_first(folder).unwrap_or_default();
    files.reverse();
    files
}

/// A failed read, and whether it is damage (a newer file that `latest` may skip) rather
/// than a mismatch the user must resolve.
struct ReadError {
    error: MufeError,
    damaged: bool,
}

fn read_restart(
    domain: &Domain,
    loaded: &LoadedScene,
    path: &Path,
    branch: bool,
) -> std::result::Result<Restart, ReadError> {
    let damaged = |error: MufeError| ReadError {
        error,
        damaged: true,
    };
    let file = CheckpointFile::open(path).map_err(|error| ReadError {
        damaged: !matches!(&error, MufeError::Input(e) if e.item == "format_version"),
        error,
    })?;
    let name = path.display().to_string();
    if !branch {
        if let Some(diff) = crate::scene::first_difference(&file.info.scene, &loaded.text) {
            return Err(ReadError {
                error: InputError::new(
                    &name,
                    "scene",
                    format!(
                        "written for another scene than {} (first difference: {diff}); restart with the scene it was written with, or pass --branch with a new --out to start a new run from it",
                        loaded.path
                    ),
                )
                .into(),
                damaged: false,
            });
        }
    }
    // a branch may change the physics, not which grains there are: the grain packages
    // are found by global id
    let scene_grains = loaded.scene.grains.len() as u64;
    if file.info.grains != scene_grains {
        return Err(ReadError {
            error: InputError::new(
                &name,
                "grains",
                format!(
                    "the checkpoint holds {} grains and the scene {} has {scene_grains}; a restart or branch needs the same grains",
                    file.info.grains, loaded.path
                ),
            )
            .into(),
            damaged: false,
        });
    }
    let parse_state = |bytes: Vec<u8>| -> std::result::Result<State, ReadError> {
        serde_json::from_slice(&bytes).map_err(|e| {
            damaged(InputError::new(&name, "state", format!("unreadable: {e}")).into())
        })
    };
    let source = if file.info.ranks == domain.size() as u64 {
        let bytes = file.json_block("state", domain.rank()).map_err(damaged)?;
        RestartSource::Own(Box::new(parse_state(bytes)?))
    } else {
        let bytes = file.json_block("state", 0).map_err(damaged)?;
        let run_level = Box::new(parse_state(bytes)?);
        let mut totals = Vec::with_capacity(file.info.ranks as usize);
        for r in 0..file.info.ranks as usize {
            let bytes = file.json_block("totals", r).map_err(damaged)?;
            totals.push(serde_json::from_slice(&bytes).map_err(|e| {
                damaged(InputError::new(&name, "totals", format!("unreadable: {e}")).into())
            })?);
        }
        let grains = file.grain_packages().map_err(damaged)?;
        RestartSource::Repartition {
            run_level,
            totals,
            grains,
        }
    };
    Ok(Restart {
        info: file.info.clone(),
        path: path.to_path_buf(),
        source,
    })
}

/// The solver, decomposition and owners of a restarted rank. All ranks must call.
pub fn build_restarted_solver(
    domain: &Domain,
    loaded: &LoadedScene,
    global: &GlobalMesh,
    restart: Restart,
) -> Result<(Solver, Decomposition, crate::domain::halo::HaloPlan)> {
    let p = restart.partition(domain, global)?;
    let (mut solver, plan, halo) = build_rank_solver(
        domain,
        loaded,
        global,
        &p.owner,
        &p.planned_bounds,
        p.planned_cell,
    )?;
    let installed = restart.install(domain, &mut solver);
    let failed = domain.all_gather_u64(u64::from(installed.is_err()));
    installed?;
    if let Some(r) = failed.iter().position(|&f| f != 0) {
        return Err(MufeError::Run(format!(
            "restoring the checkpoint failed on rank {r} (see its error)"
        )));
    }
    Ok((solver, plan, halo))
}
