//! `mufe run`: a run as named phases, top-down.
//!
//! load scene (done by the CLI, which validates before anything is written) →
//! [`GlobalMesh`] (every grain meshed, identical on all ranks) → partition (METIS,
//! [`rank`]) → build the rank's solver (owned grains + ghosts) → open the output
//! ([`output`]: `results.h5`, `/mesh`, history columns, frame 0) → loop { step, history,
//! frames, progress, rebalance ([`balance`]) } → finish (last rows and frame, energy
//! plot, summary).
//!
//! The driver sits above the solver: it owns everything about output, partitioning and
//! reporting; the solver advances one step at a time and keeps all evolving data in its
//! `State`. MPI is reached only through [`crate::domain::Domain`].

pub mod balance;
pub mod checkpoints;
pub mod contact_watch;
pub mod energy_plot;
pub mod frames;
pub mod grain_motion;
pub mod history;
pub mod migration;
pub mod output;
pub mod output_lock;
pub mod progress;
pub mod rank;
mod scene_counts;
pub mod stop_signal;
pub mod summary;
pub mod triaxial_plot;

use crate::domain::halo::Halo;
use crate::domain::Domain;
use crate::error::{MufeError, Result};
use crate::model::global::{ghost_margin, GlobalMesh};
use crate::scene::LoadedScene;
use crate::solver::{Solver, Stage};
use balance::{rebalance, BalanceCheck, Rebalanced};
use output::Output;
use progress::Progress;
use rank::{build_rank_solver, partition_grains, RankHooks};
use std::path::PathBuf;
use std::time::Instant;

/// Steps between the time loop's own all-reduces (the stop signal, the wall-time
/// checkpoint clock): each costs a network latency, which at cluster scale is a
/// noticeable part of a step, while a signal or a clock can wait a few steps.
pub const COLLECTIVE_CHECK_EVERY: u64 = 16;

/// Whether the time loop's own all-reduces run after `step`: every step on one rank (no
/// collective), every [`COLLECTIVE_CHECK_EVERY`] steps on several.
fn loop_collective_due(domain: &Domain, step: u64) -> bool {
    domain.size() == 1 || step.is_multiple_of(COLLECTIVE_CHECK_EVERY)
}

pub use history::{history_columns, history_row};
pub use summary::{print_model_summary, print_representative_summary};

/// Options of one run.
#[derive(Debug, Clone)]
pub struct RunOptions {
    /// Output directory (created if missing).
    pub out: PathBuf,
    /// Threads per rank (rayon pool size).
    pub threads: usize,
    /// Stop after this many steps from t = 0.
    pub max_steps: Option<u64>,
    /// No progress or summary printing.
    pub quiet: bool,
    /// Run even when the step count exceeds the scale guard's limit.
    pub force: bool,
    /// Write a checkpoint every this many steps (replaces `output.checkpoint_every`).
    pub checkpoint_every: Option<u64>,
    /// Continue from this checkpoint (`latest`: the newest valid one of `out`).
    pub restart: Option<PathBuf>,
    /// Start a new run from the checkpoint although the scene differs.
    pub branch: bool,
}

/// What a finished run reports.
#[derive(Debug, Clone)]
pub struct RunSummary {
    pub steps: u64,
    /// Steps taken by this run (fewer than `steps` after a restart).
    pub steps_run: u64,
    pub time: f64,
    pub dt: f64,
    pub wall_s: f64,
    /// Elements and nodes of the scene (every rank's owned ones; ghosts and periodic
    /// images are copies and not counted).
    pub elements: usize,
    pub nodes: usize,
    pub energy: crate::energy::EnergyLedger,
    pub timing_table: String,
    /// Seconds in each stage (in `Stage::ALL` order), one row per rank, in rank order (on
    /// rank 0; empty elsewhere).
    pub stage_seconds_by_rank: Vec<[f64; Stage::ALL.len()]>,
    pub results: PathBuf,
    /// Most contact points at one step (grain–grain per pass + wall nodes).
    pub max_contacts: usize,
    /// Largest grain–grain penetration over the run (m).
    pub max_penetration: f64,
    /// Share of step time spent in the contact stage (0..1).
    pub contact_share: f64,
    /// Broad-phase rebuilds (summed over ranks).
    pub rebuilds: u64,
    /// Contact points at the end (summed over ranks).
    pub contacts_now: usize,
    /// First gap opening between grains touching when the watched stage began (rank 0).
    pub first_opening: Option<contact_watch::GapOpening>,
    /// Largest ALLKE/ALLIE at the history rows of each stage.
    pub max_kinetic_ratio: Vec<f64>,
    /// Checkpoints this run wrote.
    pub checkpoints: checkpoints::CheckpointStats,
    /// Per rank: mean bytes the halo sent per step (full exchanges included), bytes per
    /// step at the end (the zone nodes contact reads), what whole contact zones and what
    /// whole ghost surfaces would send (empty on one rank).
    pub halo_bytes: Vec<[u64; 4]>,
    /// Farthest a ghost node outside the trimmed halo had moved when refreshed (m, max
    /// over ranks), and the limit of a quarter of the ghost margin.
    pub dormant_drift: (f64, f64),
}

/// Runs a scene to its duration (or `max_steps`) and writes the results: serially, or
/// under `mpirun` with the grains partitioned over the ranks (all ranks must call).
pub fn run(domain: &Domain, loaded: &LoadedScene, opts: &RunOptions) -> Result<RunSummary> {
    let wall0 = Instant::now();
    // before anything in `out` is read (a restart's checkpoints); held to the end of the run
    let mut only_job_in_out = output_lock::OutputLock::check(domain, &opts.out)?;
    let global = GlobalMesh::build(loaded)?;
    let restart = (opts.restart.as_deref())
        .map(|p| checkpoints::load_restart(domain, loaded, p, &opts.out, opts.branch))
        .transpose()?;
    let continued = restart.as_ref().map(|r| output::Continued {
        note: format!(
            "{}: {}",
            r.describe(domain.size(), opts.branch),
            crate::io::provenance::command_line()
        ),
        resume: !opts.branch,
    });
    let (solver, plan, halo_plan) = match restart {
        // a restart continues with the grains where the checkpoint had them (or
        // re-partitioned for another rank count)
        Some(r) => {
            if domain.is_root() && !opts.quiet {
                println!("{}", r.describe(domain.size(), opts.branch));
            }
            checkpoints::build_restarted_solver(domain, loaded, &global, r)?
        }
        None => {
            let owner = partition_grains(domain, loaded, &global)?;
            let cell = rank::initial_cell_length(loaded);
            build_rank_solver(domain, loaded, &global, &owner, &global.bounds, cell)?
        }
    };
    let restarted = continued.is_some();
    stop_signal::install();
    let mut run = Run {
        domain,
        loaded,
        global: &global,
        hooks: RankHooks::new(domain, Halo::new(domain, halo_plan, ghost_margin(&global))),
        solver,
        talk: domain.is_root() && !opts.quiet,
        out: opts.out.clone(),
        checkpoint_every: opts.checkpoint_every,
        first_step: 0,
        checkpoint_stats: Default::default(),
    };
    run.first_step = run.solver.state.step;
    let total_steps = step_count(loaded, &run.solver, opts)?;
    let last_step = opts.max_steps.map_or(total_steps, |m| m.min(total_steps));
    let halo_bytes = domain.all_gather_u64(run.hooks.halo.plan.bytes_per_step() as u64);
    let scene_counts = (domain.size() > 1)
        .then(|| summary::SceneCounts::owned_by(&run.solver.model).sum_over_ranks(domain));
    if run.talk {
        match &scene_counts {
            Some(scene) => summary::print_rank_summary(&run.solver, loaded, total_steps, scene),
            None => print_model_summary(&run.solver, loaded, total_steps),
        }
        if domain.size() > 1 {
            let per_rank: Vec<String> = halo_bytes.iter().map(u64::to_string).collect();
            println!(
                "ranks: {} (METIS), rank 0 owns {} grains and mirrors {} ghosts; halo bytes per step by rank with whole ghost surfaces: {}",
                domain.size(),
                plan.owned.len(),
                plan.ghosts.len(),
                per_rank.join(", ")
            );
        }
    }
    if restarted {
        // the ghosts' values in flight when the checkpoint was written, the contact zones
        // aimed where the grains are now (the plan's bounds are those of the last re-plan)
        if run.hooks.halo.plan.trims && domain.size() > 1 {
            let bounds = balance::current_bounds(domain, &run.solver, loaded.scene.grains.len());
            let owner = &run.solver.state.partition.owner;
            run.hooks
                .halo
                .retarget(owner, &bounds, ghost_margin(&global));
        }
        let s = &run.solver.state;
        let cell = s.cell_kinematics(&run.solver.model);
        run.hooks.halo.begin(&s.x, &s.v, &cell)?;
    }
    // the first write to `out`: a run refused for its input before this leaves it untouched
    only_job_in_out.hold(domain, &opts.out)?;
    let mut output = Output::open(
        domain,
        loaded,
        opts,
        &global,
        &run.solver,
        continued.as_ref(),
    )?;
    let end = run.advance_to(last_step, &mut output)?;
    let (failure, stop) = match end {
        LoopEnd::Done => (None, None),
        LoopEnd::Failed(e) => (Some(e), None),
        LoopEnd::Stopped(signal, checkpoint) => (None, Some((signal, checkpoint))),
    };
    let summary = run.finish(output, failure, stop.is_some(), opts, wall0)?;
    if run.talk {
        summary::print_run_summary(&summary, &run.solver);
    }
    if let Some((signal, checkpoint)) = stop {
        let s = &run.solver.state;
        return Err(MufeError::Stopped {
            signal,
            message: format!(
                "{} at step {} (t = {:.6e} s): checkpoint {} and {} written; continue with: mufe run SCENE --out {} --restart latest",
                stop_signal::name(signal),
                s.step,
                s.time,
                checkpoint.display(),
                summary.results.display(),
                opts.out.display()
            ),
        });
    }
    Ok(summary)
}

/// The step that reaches `simulation.duration` on the solver's clock (a branch with
/// another Δt counts from its checkpoint), refused (exit 2, before any output) when it
/// exceeds the scale guard's limit for what is actually run (`--max-steps` counts) and
/// `--force` is not given. The estimate before meshing uses an approximate Δt; this is
/// the exact count.
fn step_count(loaded: &LoadedScene, solver: &Solver, opts: &RunOptions) -> Result<u64> {
    let limit = crate::scene::estimate::MAX_STEPS;
    let dt = solver.model.dt;
    let duration = loaded.scene.simulation.duration;
    let state = &solver.state;
    let steps = state.step_origin as f64 + ((duration - state.time_origin) / dt).ceil();
    let run = opts.max_steps.map_or(steps, |m| steps.min(m as f64));
    if !opts.force && (run > limit as f64 || run.is_nan()) {
        return Err(crate::error::InputError::new(
            &loaded.path,
            "simulation.duration",
            format!(
                "{:.3e} s at the stable step {dt:.3e} s is {steps:.3e} steps, more than the limit of {limit:.0e}; shorten the duration, raise simulation.target_dt, or pass --force",
                loaded.scene.simulation.duration
            ),
        )
        .into());
    }
    Ok(steps.min(u64::MAX as f64) as u64)
}

/// How the time loop ended.
enum LoopEnd {
    Done,
    /// A step failed (serial run).
    Failed(MufeError),
    /// A stop signal; the checkpoint of the last step.
    Stopped(i32, PathBuf),
}

/// A run in progress on one rank.
struct Run<'a, 'd> {
    domain: &'d Domain,
    loaded: &'a LoadedScene,
    global: &'a GlobalMesh,
    hooks: RankHooks<'d>,
    solver: Solver,
    /// This rank prints progress and summaries.
    talk: bool,
    /// Output directory (checkpoints go into its `checkpoints/`).
    out: PathBuf,
    checkpoint_every: Option<u64>,
    /// The step the run started from (0, or the checkpoint's).
    first_step: u64,
    checkpoint_stats: checkpoints::CheckpointStats,
}

impl Run<'_, '_> {
    /// The time loop up to `last_step`. A step error on one rank of several aborts the
    /// job (the others cannot know); serially it is returned after the loop so that the
    /// output can still be finished. A stop signal ends the loop after a checkpoint.
    fn advance_to(&mut self, last_step: u64, output: &mut Output) -> Result<LoopEnd> {
        let mut checkpoints =
            checkpoints::CheckpointSchedule::new(self.loaded, self.checkpoint_every);
        let end = self.time_loop(last_step, output, &mut checkpoints);
        self.checkpoint_stats = checkpoints.stats;
        end
    }

    fn time_loop(
        &mut self,
        last_step: u64,
        output: &mut Output,
        checkpoints: &mut checkpoints::CheckpointSchedule,
    ) -> Result<LoopEnd> {
        let mut progress = Progress::new(self.talk, "run");
        let check_interval = self.loaded.scene.parallel.check_interval;
        let mut reported_stages = self.solver.state.stages.done.len();
        let mut stages_kept = reported_stages;
        let mut labelled_stage = None;
        while self.solver.state.step < last_step && !self.solver.state.stages.finished {
            if let Err(e) = self.solver.step_with(&mut self.hooks) {
                if self.domain.size() > 1 {
                    crate::error::report_line(format_args!(
                        "rank {}: error: {e}",
                        self.domain.rank()
                    ));
                    self.domain.abort(e.exit_code().max(1));
                }
                return Ok(LoopEnd::Failed(e));
            }
            let n = self.solver.state.step;
            let t_out = Instant::now();
            let stop = self.stop_signal(n);
            let last = n == last_step || self.solver.state.stages.finished;
            output.after_step(&self.solver, last)?;
            let mut written = None;
            if checkpoints.due(self.domain, n, stop.is_some()) {
                // rows up to this step reach the file first: a job killed after the
                // checkpoint keeps every row its restart will not write again
                output.flush_history()?;
                written =
                    Some(checkpoints.write(self.domain, &self.out, self.loaded, &self.solver)?);
            }
            self.keep_stage_ends(output, checkpoints, &mut stages_kept)?;
            self.solver.timers.add(Stage::Output, t_out.elapsed());
            if let Some(signal) = stop {
                progress.finish();
                let path =
                    written.unwrap_or_else(|| crate::io::checkpoint::checkpoint_path(&self.out, n));
                return Ok(LoopEnd::Stopped(signal, path));
            }
            match self.solver.model.stages.as_ref().filter(|p| p.staged) {
                Some(plan) => {
                    let s = &self.solver.state;
                    if self.talk && s.stages.done.len() > reported_stages {
                        progress.finish();
                        for r in &s.stages.done[reported_stages..] {
                            println!("{}", summary::describe_stage(r));
                        }
                        reported_stages = s.stages.done.len();
                    }
                    let i = s.stages.index.min(plan.stages.len() - 1);
                    if labelled_stage != Some(i) {
                        labelled_stage = Some(i);
                        progress.set_label(&format!(
                            "stage {}/{} {}",
                            i + 1,
                            plan.stages.len(),
                            plan.stages[i].name
                        ));
                    }
                    let fraction = plan.stage_fraction(&s.stages, s.time);
                    progress.update(fraction, n, s.time, || plan.waiting_on(&s.stages, s.time));
                }
                None => {
                    let fraction = n as f64 / last_step as f64;
                    progress.update(fraction, n, self.solver.state.time, || None)
                }
            }
            // a periodic cell re-plans its images (and wraps grains) on one rank too
            let replans = self.domain.size() > 1 || self.solver.model.periodic.is_some();
            if replans && n.is_multiple_of(check_interval) && n != last_step {
                self.rebalance(n)?;
            }
        }
        progress.finish();
        Ok(LoopEnd::Done)
    }

    /// Keeps a checkpoint at the end of every stage but the last (`output.stage_checkpoints`)
    /// once the stage count `kept` falls behind the stages done. All ranks must call.
    fn keep_stage_ends(
        &self,
        output: &mut Output,
        checkpoints: &mut checkpoints::CheckpointSchedule,
        kept: &mut usize,
    ) -> Result<()> {
        let s = &self.solver.state;
        let ended = s.stages.done.len();
        if ended == *kept {
            return Ok(());
        }
        *kept = ended;
        if s.stages.finished || !self.loaded.scene.output.stage_checkpoints {
            return Ok(());
        }
        let Some(plan) = self.solver.model.stages.as_ref() else {
            return Ok(());
        };
        output.flush_history()?;
        let name = &plan.stages[ended - 1].name;
        let path = checkpoints.write_stage_end(
            self.domain,
            &self.out,
            self.loaded,
            &self.solver,
            (ended, name),
        )?;
        if self.talk {
            println!(
                "stage '{name}' kept as {} (branch from it: --restart FILE --branch)",
                path.display()
            );
        }
        Ok(())
    }

    /// A stop signal received by any rank (the largest signal number if several), the
    /// same on all ranks. With several ranks it takes an all-reduce, so the ranks ask only
    /// every [`COLLECTIVE_CHECK_EVERY`] steps: a signal then stops the run within that many
    /// steps. All ranks must call.
    fn stop_signal(&self, step: u64) -> Option<i32> {
        let mut s = [f64::from(stop_signal::received().unwrap_or(0))];
        if !loop_collective_due(self.domain, step) {
            return None;
        }
        if self.domain.size() > 1 {
            self.domain.max_in_place(&mut s);
        }
        (s[0] > 0.0).then_some(s[0] as i32)
    }

    /// Completes the halo in flight, then re-partitions or re-plans ghosts if needed.
    fn rebalance(&mut self, step: u64) -> Result<()> {
        let (domain, loaded) = (self.domain, self.loaded);
        let s = &mut self.solver.state;
        self.hooks.halo.end(&mut s.x, &mut s.v)?;
        if balance::wrap_into_cell(domain, &mut self.solver) && self.talk {
            println!("grains wrapped back into the periodic cell at step {step}");
        }
        match rebalance(domain, loaded, self.global, &self.solver)? {
            BalanceCheck::Unchanged(bounds) => {
                let owner = &self.solver.state.partition.owner;
                (self.hooks.halo).retarget(owner, &bounds, ghost_margin(self.global));
                let s = &self.solver.state;
                let cell = s.cell_kinematics(&self.solver.model);
                self.hooks.halo.begin(&s.x, &s.v, &cell)?;
            }
            BalanceCheck::Rebalanced(rebalanced) => {
                let Rebalanced {
                    solver,
                    halo,
                    migrated,
                } = *rebalanced;
                self.solver = solver;
                let old = std::mem::replace(
                    &mut self.hooks.halo,
                    Halo::new(domain, halo, ghost_margin(self.global)),
                );
                self.hooks.halo.carry_counters_from(&old);
                // the new ghosts (images too: a package fills one copy) from their owners
                let s = &self.solver.state;
                let cell = s.cell_kinematics(&self.solver.model);
                self.hooks.halo.begin(&s.x, &s.v, &cell)?;
                if self.talk {
                    println!(
                        "re-partitioned at step {step}: {migrated} grains migrated (imbalance above {})",
                        loaded.scene.parallel.imbalance_threshold
                    );
                }
            }
        }
        Ok(())
    }

    /// Last history row and frame, closes the file, draws the energy plot, and gathers
    /// the global figures of the summary. A step failure is returned after the output is
    /// complete, so what was computed up to it can be inspected.
    fn finish(
        &mut self,
        output: Output,
        failure: Option<MufeError>,
        stopped: bool,
        opts: &RunOptions,
        wall0: Instant,
    ) -> Result<RunSummary> {
        let solver = &self.solver;
        let watched = output.close(solver, failure.is_some(), stopped, &opts.out)?;
        let domain = self.domain;
        let energy = history::global_ledger(domain, &solver.state.energy);
        let stats = &solver.state.contact.stats;
        let mut maxima = [stats.max_penetration_run, stats.max_contacts_run as f64];
        domain.max_in_place(&mut maxima);
        let mut now = [
            solver.state.contact.contacts() as f64,
            stats.rebuilds as f64,
        ];
        domain.sum_in_place(&mut now[..1]);
        let halo = &self.hooks.halo;
        let mean = (halo.values_sent * 8)
            .checked_div(halo.exchanges)
            .unwrap_or(0);
        let means = domain.all_gather_u64(mean);
        let read = domain.all_gather_u64(halo.bytes_per_step() as u64);
        let zones = domain.all_gather_u64(halo.zone_bytes_per_step() as u64);
        let wholes = domain.all_gather_u64(halo.plan.bytes_per_step() as u64);
        let mut drift = [halo.dormant_drift];
        domain.max_in_place(&mut drift);
        if let Some(e) = failure {
            return Err(e);
        }
        // every rank's stage times: the stage table is this rank's alone, and a rank that
        // waits for a slower one shows the wait in its sync row
        let stage_seconds = Stage::ALL.map(|st| solver.timers.seconds(st));
        let stage_seconds_by_rank = (domain.gather_f64_to_root(&stage_seconds))
            .map(|all| {
                (all.chunks_exact(Stage::ALL.len()))
                    .map(|row| std::array::from_fn(|i| row[i]))
                    .collect()
            })
            .unwrap_or_default();
        Ok(RunSummary {
            stage_seconds_by_rank,
            steps: solver.state.step,
            steps_run: solver.state.step - self.first_step,
            time: solver.state.time,
            dt: solver.model.dt,
            wall_s: wall0.elapsed().as_secs_f64(),
            elements: self.global.total_elements(),
            nodes: self.global.total_nodes(),
            energy,
            timing_table: solver.timers.table(solver.state.step - self.first_step),
            results: opts.out.join(crate::io::results::RESULTS_FILE_NAME),
            max_contacts: maxima[1] as usize,
            max_penetration: maxima[0],
            contact_share: solver.timers.share(Stage::Contact),
            rebuilds: now[1] as u64,
            contacts_now: now[0] as usize,
            first_opening: watched.first_opening,
            max_kinetic_ratio: watched.max_kinetic_ratio,
            checkpoints: checkpoints::CheckpointStats {
                elements: self.global.total_elements(),
                ..self.checkpoint_stats
            },
            halo_bytes: if domain.size() > 1 {
                (0..domain.size())
                    .map(|r| [means[r], read[r], zones[r], wholes[r]])
                    .collect()
            } else {
                Vec::new()
            },
            dormant_drift: (drift[0], 0.25 * ghost_margin(self.global)),
        })
    }
}
