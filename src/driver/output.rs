//! The output of a run: `DIR/results.h5` (mesh, history rows, frames) and
//! `DIR/energy.png`, on the schedule the scene's `[output]` sets.

use super::contact_watch::ContactWatch;
use super::energy_plot::EnergyPlot;
use super::frames::write_frame;
use super::history::{history_columns, history_reductions, history_row, reduce_row, Reduce};
use super::triaxial_plot::TriaxialPlot;
use super::RunOptions;
use crate::domain::Domain;
use crate::error::{MufeError, Result};
use crate::io::results::{
    grain_row_blocks, MeshPart, Provenance, ResultsWriter, RESULTS_FILE_NAME,
};
use crate::io::xdmf::{write_xdmf, XdmfLayout, XDMF_FILE_NAME};
use crate::model::global::GlobalMesh;
use crate::scene::LoadedScene;
use crate::solver::Solver;
use std::path::Path;
use std::time::Instant;

/// Output state of a run in progress on one rank.
pub struct Output<'a, 'd> {
    domain: &'d Domain,
    global: &'a GlobalMesh,
    writer: ResultsWriter<'d>,
    reductions: Vec<Reduce>,
    /// Steps between history rows and between frames (none: first and last frame only).
    history_every: u64,
    frame_every: Option<u64>,
    frames: bool,
    frame_index: usize,
    /// (index, time) of the frames written, for `results.xdmf`.
    frame_times: Vec<(usize, f64)>,
    dir: std::path::PathBuf,
    energy_plot: EnergyPlot,
    row: Vec<f64>,
    /// Wall-clock time of the last history flush, and the scene's interval between them.
    last_flush: Instant,
    flush_interval: f64,
    /// Grain-pair contact counts and the failure watch (rank 0).
    contacts: ContactWatch,
    /// `DIR/stress_ratio.png` of a staged cell.
    triaxial_plot: Option<TriaxialPlot>,
    /// No report of the results writes at the end (`--quiet`).
    quiet: bool,
}

/// How a run continues a checkpoint.
pub struct Continued {
    /// What `/provenance` records: the checkpoint, its step, the ranks and the command.
    pub note: String,
    /// Continue `results.h5` (a restart) rather than start a new one (a branch).
    pub resume: bool,
}

impl<'a, 'd> Output<'a, 'd> {
    /// Creates the output directory and `results.h5` with `/scene`, `/provenance`,
    /// `/mesh`, the history columns and the first frame; after a restart (`continued`,
    /// the solver holding the checkpoint's state) an existing `results.h5` is reopened
    /// and continued instead, and the restart is recorded in `/provenance` (a branch
    /// starts a new file). All ranks must call.
    pub fn open(
        domain: &'d Domain,
        loaded: &LoadedScene,
        opts: &RunOptions,
        global: &'a GlobalMesh,
        solver: &Solver,
        continued: Option<&Continued>,
    ) -> Result<Self> {
        std::fs::create_dir_all(&opts.out).map_err(|e| {
            MufeError::Io(format!(
                "{}: cannot create output directory: {e}",
                opts.out.display()
            ))
        })?;
        let results = opts.out.join(RESULTS_FILE_NAME);
        let columns = history_columns(solver);
        let kernel = solver.scratch.elements.path.name();
        // what a restart or branch records: the checkpoint, the command, this run's loop
        let note_of = |c: &Continued| format!("{} (element kernel {kernel})", c.note);
        let resumed = match continued {
            Some(c) if c.resume && results.is_file() => {
                let s = &solver.state;
                let mut r = ResultsWriter::resume(domain, &results, &columns, s.step, s.time)?;
                match r.writer.provenance_text("kernel") {
                    Some(k) if k != kernel && domain.is_root() && !opts.quiet => println!(
                        "note: this restart runs the {kernel} element kernel, the run began on {k} (the two give bitwise identical forces)"
                    ),
                    _ => {}
                }
                r.writer.note_provenance("restart", &note_of(c))?;
                Some(r)
            }
            _ => None,
        };
        let (writer, kept_rows, kept_frames) = match resumed {
            Some(r) => (r.writer, r.rows, r.frames),
            None => {
                let provenance = Provenance::collect(domain, opts.threads, kernel);
                let mut writer =
                    ResultsWriter::create(domain, &results, &loaded.text, &provenance)?;
                write_mesh(
                    &mut writer,
                    domain,
                    loaded,
                    global,
                    &solver.state.partition.owner,
                )?;
                writer.define_history(&columns)?;
                if let Some(c) = continued {
                    writer.note_provenance(
                        if c.resume { "restart" } else { "branch" },
                        &note_of(c),
                    )?;
                }
                (writer, Vec::new(), Vec::new())
            }
        };

        let scene = &loaded.scene;
        let dt = solver.model.dt;
        let history_interval = scene
            .output
            .history_interval
            .unwrap_or(scene.simulation.duration / 1000.0);
        let mut output = Self {
            domain,
            global,
            writer,
            reductions: history_reductions(solver),
            history_every: ((history_interval / dt).round() as u64).max(1),
            frame_every: scene
                .output
                .frame_interval
                .map(|f| ((f / dt).round() as u64).max(1)),
            frames: scene.output.frames,
            frame_index: kept_frames.iter().map(|f| f.0 + 1).max().unwrap_or(0),
            frame_times: kept_frames,
            dir: opts.out.clone(),
            energy_plot: EnergyPlot::default(),
            row: Vec::new(),
            last_flush: Instant::now(),
            flush_interval: scene.output.flush_interval,
            contacts: ContactWatch::new(solver),
            triaxial_plot: TriaxialPlot::new(solver, &columns),
            quiet: opts.quiet,
        };
        // the plots cover the whole run: the rows before a restart come from the file
        let stage_column = columns.iter().position(|c| c.name == "stage");
        for row in &kept_rows {
            let stage = stage_column.map_or(0, |k| (row[k] as usize).saturating_sub(1));
            output.contacts.observe_reduced(stage, row);
            output.energy_plot.push(row);
            if let Some(p) = &mut output.triaxial_plot {
                p.push(row);
            }
        }
        if output.frames && output.frame_times.is_empty() {
            output.write_frame(solver)?;
        }
        Ok(output)
    }

    /// After step n: a history row every `history_every` steps and at the last step, a
    /// frame every `frame_every` steps (the last frame is written by [`Self::close`]).
    /// All ranks must call.
    pub fn after_step(&mut self, solver: &Solver, last: bool) -> Result<()> {
        let n = solver.state.step;
        if n.is_multiple_of(self.history_every) || last {
            self.push_history_row(solver)?;
            self.flush_history_when_due()?;
        }
        if let Some(fe) = self.frame_every {
            if n.is_multiple_of(fe) && !last && self.frames {
                self.write_frame(solver)?;
                self.writer.flush_history()?;
            }
        }
        Ok(())
    }

    /// Writes the buffered history rows now (before a checkpoint, so that a job killed
    /// after it keeps every row the restart will not write again). All ranks must call.
    pub fn flush_history(&mut self) -> Result<()> {
        self.writer.flush_history()?;
        self.last_flush = Instant::now();
        Ok(())
    }

    /// Writes what a finished (or failed) run leaves: a last history row when the loop
    /// wrote none for this state, the last frame, then closes the file and draws
    /// `DIR/energy.png`. A run `stopped` by a signal writes no extra row or frame: its
    /// restart continues the file as the uninterrupted run would have written it. All
    /// ranks must call.
    /// Returns what the contact watch saw (gap opening on rank 0; kinetic ratios).
    pub fn close(
        mut self,
        solver: &Solver,
        failed: bool,
        stopped: bool,
        dir: &Path,
    ) -> Result<ContactWatch> {
        // Keep what was computed up to a failure: history and a last frame help diagnose it.
        if failed || solver.state.step == 0 {
            self.push_history_row(solver)?;
        }
        if self.frames && !stopped {
            self.write_frame(solver)?;
        }
        if solver.model.stages.is_some() {
            let done = &solver.state.stages.done;
            self.writer
                .write_stages(&super::summary::stage_attributes(done))?;
        }
        // the last history rows too, so that the report counts every write
        self.writer.flush_history()?;
        self.report_io();
        self.writer.close()?;
        if self.domain.is_root() {
            self.energy_plot.draw(&dir.join("energy.png"))?;
            if let Some(p) = &self.triaxial_plot {
                p.draw(&dir.join("stress_ratio.png"))?;
            }
        }
        Ok(self.contacts)
    }

    /// Says how the bulk writes of `results.h5` were performed, summed over the ranks:
    /// collective MPI-IO is what makes the output scale, and HDF5 can fall back to
    /// independent I/O silently, so a fallback is a warning even with `--quiet`.
    /// All ranks must call.
    fn report_io(&self) {
        let io = self.writer.io_stats();
        let total = io.total();
        let mut counts = [
            io.frames.collective as f64,
            io.frames.not_collective as f64,
            total.collective as f64,
            total.not_collective as f64,
        ];
        self.domain.sum_in_place(&mut counts);
        if !self.domain.is_root() {
            return;
        }
        let [frames_ok, frames_bad, all_ok, all_bad] = counts.map(|c| c as u64);
        if !self.quiet {
            println!(
                "results.h5: {} frames written by {} rank(s); collective MPI-IO writes: \
                 frames {frames_ok}/{}, all {all_ok}/{}",
                io.frames_written,
                self.domain.size(),
                frames_ok + frames_bad,
                all_ok + all_bad,
            );
        }
        if all_bad > 0 {
            crate::error::report_line(format_args!(
                "warning: {}: {all_bad} of {} dataset writes fell back to independent MPI-IO",
                self.writer.path().display(),
                all_ok + all_bad
            ));
        }
    }

    /// Flushes the buffered history rows once `flush_interval` seconds of wall time have
    /// passed on any rank. The decision is reduced over the ranks (the flush is
    /// collective; clocks differ), once per history row, beside the row's own reduction.
    fn flush_history_when_due(&mut self) -> Result<()> {
        let mut elapsed = [self.last_flush.elapsed().as_secs_f64()];
        self.domain.max_in_place(&mut elapsed);
        if elapsed[0] >= self.flush_interval {
            self.writer.flush_history()?;
            self.last_flush = Instant::now();
        }
        Ok(())
    }

    fn push_history_row(&mut self, solver: &Solver) -> Result<()> {
        history_row(solver, &mut self.row);
        self.contacts.fill_row(self.domain, solver, &mut self.row);
        reduce_row(self.domain, &self.reductions, &mut self.row);
        self.contacts
            .observe_reduced(solver.state.stages.index, &self.row);
        if let Some(p) = &mut self.triaxial_plot {
            p.push(&self.row);
        }
        self.writer.push_history(&self.row)?;
        self.energy_plot.push(&self.row);
        Ok(())
    }

    fn write_frame(&mut self, solver: &Solver) -> Result<()> {
        write_frame(
            &mut self.writer,
            self.domain,
            solver,
            self.global,
            self.frame_index,
        )?;
        self.frame_times.push((self.frame_index, solver.state.time));
        self.frame_index += 1;
        // rank 0 alone: a failure is reported, not returned, so that the ranks stay in
        // step (the description is auxiliary; results.h5 holds the data)
        if self.domain.is_root() {
            let path = self.dir.join(XDMF_FILE_NAME);
            let written = write_xdmf(
                &path,
                &XdmfLayout {
                    h5_name: RESULTS_FILE_NAME,
                    nodes: self.global.total_nodes() as u64,
                    elements: self.global.total_elements() as u64,
                    frames: &self.frame_times,
                },
            );
            if let Err(e) = written {
                crate::error::report_line(format_args!("warning: {}: {e}", path.display()));
            }
        }
        Ok(())
    }
}

/// `/mesh` from the global layout (identical on all ranks): each rank writes the nodes,
/// tetrahedra and grain ids of the grains `owner` gives it, in global grain order; rank 0
/// writes `owner` itself (the initial owners: the frames' `owner_rank_of_grain` follows
/// migration). All ranks must call.
fn write_mesh(
    writer: &mut ResultsWriter,
    domain: &Domain,
    loaded: &LoadedScene,
    global: &GlobalMesh,
    owner: &[u32],
) -> Result<()> {
    let rank = domain.rank();
    let owned = || (0..owner.len()).filter(|&g| owner[g] as usize == rank);
    let node_blocks = grain_row_blocks(owned(), &global.node_offset);
    let tet_blocks = grain_row_blocks(owned(), &global.element_offset);
    let rows = |blocks: &[(u64, u64)]| blocks.iter().map(|b| b.1 as usize).sum();
    let mut nodes = Vec::with_capacity(rows(&node_blocks));
    let mut tets = Vec::with_capacity(rows(&tet_blocks));
    let mut grain_of_tet = Vec::with_capacity(rows(&tet_blocks));
    for g in owned() {
        let mesh = &global.meshes[g];
        let base = global.node_offset[g] as u64;
        let c = loaded.scene.grains[g].centre;
        nodes.extend(
            mesh.nodes
                .iter()
                .map(|p| [p[0] + c[0], p[1] + c[1], p[2] + c[2]]),
        );
        tets.extend(mesh.tets.iter().map(|t| t.map(|n| n as u64 + base)));
        grain_of_tet.extend(std::iter::repeat_n(g as u32, mesh.tets.len()));
    }
    writer.write_mesh(&MeshPart {
        nodes: &nodes,
        node_blocks: &node_blocks,
        total_nodes: global.total_nodes() as u64,
        tets: &tets,
        tet_blocks: &tet_blocks,
        total_tets: global.total_elements() as u64,
        grain_of_tet: &grain_of_tet,
        grain_owner_rank: owner,
    })
}
