//! `results.h5`: the run's results in one parallel HDF5 file. The layout (every group,
//! dataset and attribute with shape, type and units) is docs/RESULTS.md, checked against
//! real files by `scripts/check_results_layout.py` (tests/results_layout.rs); in short:
//!
//! ```text
//! /scene                          fixed-length UTF-8 string: the scene text as run
//! /provenance                     group; attributes version, ranks, threads, start_time,
//!                                 command_line, hostname, kernel
//! /history/<name>                 1-D f64 over output times, chunked and extended at each
//!                                 flush; attributes units, description, abaqus (if any)
//! /mesh/nodes                     (N, 3) f64, m
//! /mesh/tetrahedra                (E, 4) u64, global node ids (0-based)
//! /mesh/grain_of_element          (E,) u32
//! /mesh/owner_rank_of_grain       (G,) u32
//! /frames/NNNNNN/<field>          (rows,) or (rows, components) f64; group attribute time (s)
//! ```
//! Every dataset has a string attribute `units`; ids, counts and text have `units = ""`.
//!
//! The file is opened with the MPI-IO driver on the [`Domain`]'s communicator, on one rank
//! as on many. Each rank writes its own rows (blocks of rows in global order, see
//! [`blocks`]) with one collective transfer per dataset (see [`super::collective`]);
//! whole-job data (history, scene, the grain-owner table, per-contact records) is
//! written by rank 0 within the same collective calls. HDF5 metadata (groups, datasets,
//! attributes) must be identical on every rank, so the writer takes the scene text and
//! provenance from rank 0 and checks that the ranks agree on names and sizes before each
//! write: a disagreement is an error on every rank, never a deadlock or a corrupt file.
//!
//! After every history flush and frame the file is flushed (`H5Fflush`), so a run that
//! dies later leaves a file that h5py and h5dump can read up to the last output.

use std::fmt::Display;
use std::path::{Path, PathBuf};

use hdf5::types::VarLenUnicode;
use hdf5::{Dataset, File, Group, Location};
use serde::{Deserialize, Serialize};

use super::collective::{self, IoMode};
pub use super::provenance::Provenance;
use crate::domain::Domain;
use crate::error::MufeError;

/// File name of the results inside a run's output directory.
pub const RESULTS_FILE_NAME: &str = "results.h5";
/// Version of the `results.h5` layout (docs/RESULTS.md), the root attribute
/// `format_version`; a restart continues only a file of this version.
pub const RESULTS_FORMAT: u64 = 1;

/// Rows per chunk of the extendable history datasets (8 KiB of f64: small enough that a
/// short run wastes little, large enough that a long one has few chunks).
const HISTORY_CHUNK_ROWS: usize = 1024;

/// One time series of `/history`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct HistoryColumn {
    /// Dataset name under `/history` (`kinetic_energy`); no `/`.
    pub name: String,
    /// Units (`J`, `N`, `s`, `""` for dimensionless).
    pub units: String,
    /// Name of the Abaqus history output with the same meaning (`ALLKE`), if there is one.
    pub abaqus: Option<String>,
    /// One-line description for people reading the file.
    pub description: String,
}

impl HistoryColumn {
    /// Convenience constructor.
    pub fn new(name: &str, units: &str, abaqus: Option<&str>, description: &str) -> Self {
        HistoryColumn {
            name: name.to_string(),
            units: units.to_string(),
            abaqus: abaqus.map(str::to_string),
            description: description.to_string(),
        }
    }
}

/// This rank's part of the mesh, for [`ResultsWriter::write_mesh`]. Nodes and elements are
/// numbered globally; each rank holds some blocks of rows of each (see [`grain_row_blocks`]).
#[derive(Debug, Clone, Copy)]
pub struct MeshPart<'a> {
    /// Coordinates (m) of the nodes in `node_blocks`, packed in block order.
    pub nodes: &'a [[f64; 3]],
    /// `(first row, rows)` of this rank's nodes, ascending, non-overlapping.
    pub node_blocks: &'a [(u64, u64)],
    pub total_nodes: u64,
    /// Global node ids of the tetrahedra in `tet_blocks`, packed in block order.
    pub tets: &'a [[u64; 4]],
    /// `(first row, rows)` of this rank's tetrahedra, ascending, non-overlapping.
    pub tet_blocks: &'a [(u64, u64)],
    pub total_tets: u64,
    /// Grain id of each of this rank's tetrahedra (same length as `tets`).
    pub grain_of_tet: &'a [u32],
    /// Owning rank of every grain of the scene (global; identical on all ranks).
    pub grain_owner_rank: &'a [u32],
}

/// This rank's rows of one field of a frame, for [`ResultsWriter::write_frame`].
#[derive(Debug, Clone, Copy)]
pub struct FieldPart<'a> {
    /// Dataset name in the frame group (`displacement`); no `/`.
    pub name: &'a str,
    /// Units of the values (`m`, `Pa`).
    pub units: &'a str,
    /// Values per row: 1 (scalar, stored 1-D), 3 (vector), 6 (symmetric tensor), ...
    pub components: usize,
    /// `rows × components` values, row-major: the rows of `blocks`, packed in block order.
    pub data: &'a [f64],
    /// `(first row, rows)` of this rank's rows, ascending, non-overlapping (empty: none).
    pub blocks: &'a [(u64, u64)],
    /// Rows of the whole field (all ranks).
    pub total: u64,
}

/// How a set of bulk writes was actually performed, as HDF5 reports it
/// (`H5Pget_mpio_actual_io_mode`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct IoCount {
    /// Writes HDF5 performed collectively.
    pub collective: u64,
    /// Writes HDF5 performed (wholly or partly) independently.
    pub not_collective: u64,
}

impl IoCount {
    fn add(&mut self, mode: IoMode) {
        if mode.is_collective() {
            self.collective += 1;
        } else {
            self.not_collective += 1;
        }
    }
}

/// The writer's bulk writes on this rank, by kind: one per dataset written (so a frame of
/// 17 fields counts 17), and the number of frames written.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct IoStats {
    pub mesh: IoCount,
    pub history: IoCount,
    pub frames: IoCount,
    pub frames_written: u64,
}

impl IoStats {
    /// All bulk writes together.
    pub fn total(&self) -> IoCount {
        IoCount {
            collective: self.mesh.collective + self.history.collective + self.frames.collective,
            not_collective: self.mesh.not_collective
                + self.history.not_collective
                + self.frames.not_collective,
        }
    }
}

/// What [`ResultsWriter::count`] adds to.
#[derive(Debug, Clone, Copy)]
enum WriteKind {
    Mesh,
    History,
    Frame,
}

/// Extendable `/history` time series, buffered between flushes.
struct History {
    columns: Vec<HistoryColumn>,
    datasets: Vec<Dataset>,
    /// Rows pushed since the last flush, row-major (`columns.len()` values per row).
    pending: Vec<f64>,
    /// Rows already in the file.
    rows_written: u64,
}

/// Writer of `results.h5` (see the module docs for the layout). Borrows the [`Domain`] so it
/// cannot outlive MPI; methods documented "all ranks must call" are collective.
///
/// On error every rank gets an error (the ranks agree on success after each operation), so
/// all ranks can stop together.
pub struct ResultsWriter<'d> {
    domain: &'d Domain,
    path: PathBuf,
    // Before `file`: open datasets must close before the file does (MPI-IO closes "semi").
    history: Option<History>,
    io: IoStats,
    /// Every rank's hash of the row layouts of the last frame, once verified to tile the
    /// datasets (see `blocks::check_frame_tiling`); empty before.
    verified_layouts: Vec<u64>,
    file: File,
}

impl<'d> ResultsWriter<'d> {
    /// Creates (truncating) the results file at `path` (normally `DIR/results.h5`) and writes
    /// `/scene` and `/provenance`. Rank 0's `scene_text` and `provenance` are used on all
    /// ranks.
    ///
    /// All ranks must call.
    pub fn create(
        domain: &'d Domain,
        path: &Path,
        scene_text: &str,
        provenance: &Provenance,
    ) -> Result<Self, MufeError> {
        // HDF5 metadata must be identical on all ranks (hostnames and clocks are not).
        let mut bytes = if domain.is_root() {
            serde_json::to_vec(&(scene_text, provenance)).unwrap_or_default()
        } else {
            Vec::new()
        };
        domain.broadcast_bytes(&mut bytes);
        let (scene, provenance): (String, Provenance) = serde_json::from_slice(&bytes)
            .map_err(|e| io_error(path, "sharing scene and provenance", e))?;

        let created = if path.is_dir() {
            Err(format!(
                "is a directory; expected a file path such as DIR/{RESULTS_FILE_NAME}"
            ))
        } else {
            File::with_options()
                .with_fapl(|p| p.mpio(domain.raw_comm(), None))
                .create(path)
                .map_err(|e| e.to_string())
        };
        let local = created.as_ref().map(|_| ()).map_err(Clone::clone);
        agree(domain, path, "creating results file", local)?;
        let file = created.map_err(|e| io_error(path, "creating results file", e))?;

        let writer = ResultsWriter {
            domain,
            path: path.to_path_buf(),
            history: None,
            io: IoStats::default(),
            verified_layouts: Vec::new(),
            file,
        };
        let local = writer.write_header(&scene, &provenance);
        writer.agree("writing /scene and /provenance", local)?;
        writer.flush_file()?;
        Ok(writer)
    }

    /// Path of the file being written.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// How this rank's bulk writes were performed so far.
    pub fn io_stats(&self) -> IoStats {
        self.io
    }

    fn write_header(&self, scene: &str, provenance: &Provenance) -> Result<(), String> {
        let is_root = self.domain.is_root();
        put_u64_attr(&self.file, "format_version", RESULTS_FORMAT)
            .map_err(|e| format!("/: {e}"))?;
        let ds = collective::create_text_dataset(&self.file, "scene", scene, is_root)
            .map_err(|e| format!("/scene: {e}"))?;
        put_str_attr(&ds, "units", "").map_err(|e| format!("/scene: {e}"))?;
        put_str_attr(&ds, "description", "the scene (TOML) as run")
            .map_err(|e| format!("/scene: {e}"))?;

        let group = self
            .file
            .create_group("provenance")
            .map_err(|e| format!("/provenance: {e}"))?;
        let write = || -> hdf5::Result<()> {
            put_str_attr(&group, "version", &provenance.version)?;
            put_u64_attr(&group, "ranks", provenance.ranks as u64)?;
            put_u64_attr(&group, "threads", provenance.threads as u64)?;
            put_str_attr(&group, "start_time", &provenance.start_time)?;
            put_str_attr(&group, "command_line", &provenance.command_line)?;
            put_str_attr(&group, "hostname", &provenance.hostname)?;
            put_str_attr(&group, "kernel", &provenance.kernel)?;
            Ok(())
        };
        write().map_err(|e| format!("/provenance: {e}"))
    }

    /// Defines the `/history` time series (once per file) and creates their empty,
    /// extendable datasets with attributes `units`, `description` and `abaqus` (where
    /// given). Column names must be unique, non-empty and free of `/`.
    ///
    /// All ranks must call, with the same columns.
    pub fn define_history(&mut self, columns: &[HistoryColumn]) -> Result<(), MufeError> {
        let mut local = if self.history.is_some() {
            Err("history is already defined".to_string())
        } else {
            check_names(columns.iter().map(|c| c.name.as_str()))
        };
        if local.is_ok() {
            let text = serde_json::to_string(columns).unwrap_or_default();
            local = self.same_on_all_ranks(fnv1a(text.as_bytes()), "history columns");
        }
        self.agree("defining /history", local)?;

        let created = (|| -> hdf5::Result<Vec<Dataset>> {
            let group = self.file.create_group("history")?;
            let mut datasets = Vec::with_capacity(columns.len());
            for c in columns {
                let ds = group
                    .new_dataset::<f64>()
                    .chunk(HISTORY_CHUNK_ROWS)
                    .shape(0..)
                    .create(c.name.as_str())?;
                put_str_attr(&ds, "units", &c.units)?;
                put_str_attr(&ds, "description", &c.description)?;
                if let Some(a) = &c.abaqus {
                    put_str_attr(&ds, "abaqus", a)?;
                }
                datasets.push(ds);
            }
            Ok(datasets)
        })();
        let local = created.as_ref().map(|_| ()).map_err(|e| e.to_string());
        self.agree("defining /history", local)?;
        let datasets = created.map_err(|e| self.error("defining /history", e))?;
        self.history = Some(History {
            columns: columns.to_vec(),
            datasets,
            pending: Vec::new(),
            rows_written: 0,
        });
        self.flush_file()
    }

    /// Buffers one history row (one value per column, in the order of `define_history`).
    /// Local, not collective: every rank pushes the same rows (rank 0's are written).
    pub fn push_history(&mut self, values: &[f64]) -> Result<(), MufeError> {
        let path = self.path.clone();
        let Some(history) = self.history.as_mut() else {
            return Err(io_error(
                &path,
                "history row",
                "define_history was not called",
            ));
        };
        if values.len() != history.columns.len() {
            return Err(io_error(
                &path,
                "history row",
                format!(
                    "{} values for {} columns",
                    values.len(),
                    history.columns.len()
                ),
            ));
        }
        history.pending.extend_from_slice(values);
        Ok(())
    }

    /// Appends the buffered history rows to the `/history` datasets (extending them, a
    /// collective operation) and flushes the file. Rank 0's rows are written.
    ///
    /// All ranks must call.
    pub fn flush_history(&mut self) -> Result<(), MufeError> {
        let Some(history) = self.history.as_mut() else {
            return Ok(());
        };
        let ncol = history.columns.len();
        let local_rows = (history.pending.len() / ncol.max(1)) as u64;
        // The extent change must be identical on all ranks: use rank 0's row count.
        let rows = self.domain.all_gather_u64(local_rows)[0];
        if rows == 0 {
            history.pending.clear();
            return Ok(());
        }
        let start = history.rows_written;
        let end = start + rows;
        let is_root = self.domain.is_root();
        let mut column = Vec::with_capacity(if is_root { rows as usize } else { 0 });
        let mut modes = Vec::with_capacity(ncol);
        let mut result = Ok(());
        for (j, ds) in history.datasets.iter().enumerate() {
            column.clear();
            if is_root {
                column.extend(history.pending.chunks_exact(ncol).map(|row| row[j]));
            }
            let written = ds
                .resize(end as usize)
                .and_then(|()| collective::write_1d_f64(ds, &column, start, end));
            // Keep going after an error: the other ranks are in the same collective calls.
            match written {
                Ok(mode) => modes.push(mode),
                Err(e) if result.is_ok() => {
                    result = Err(format!("/history/{}: {e}", history.columns[j].name));
                }
                Err(_) => {}
            }
        }
        history.pending.clear();
        history.rows_written = end;
        self.count(WriteKind::History, &modes);
        self.agree("writing /history", result)?;
        self.flush_file()
    }

    /// Writes `/mesh` (nodes, tetrahedra, grain of each element, owner rank of each grain)
    /// collectively, each rank its own blocks; rank 0 writes the grain-owner table (the
    /// owners when the mesh is written, i.e. at the start of the run). Once per file.
    ///
    /// All ranks must call.
    pub fn write_mesh(&mut self, part: &MeshPart) -> Result<(), MufeError> {
        let mut local = self.check_mesh_part(part);
        if local.is_ok() {
            let mut key = Vec::new();
            key.extend_from_slice(&part.total_nodes.to_le_bytes());
            key.extend_from_slice(&part.total_tets.to_le_bytes());
            for r in part.grain_owner_rank {
                key.extend_from_slice(&r.to_le_bytes());
            }
            local = self.same_on_all_ranks(fnv1a(&key), "mesh sizes and grain owners");
        }
        self.agree("writing /mesh", local)?;
        self.check_blocks(
            &["/mesh/nodes", "/mesh/tetrahedra"],
            &[
                (part.node_blocks, part.total_nodes),
                (part.tet_blocks, part.total_tets),
            ],
        )?;

        let is_root = self.domain.is_root();
        let owners: &[u32] = if is_root { part.grain_owner_rank } else { &[] };
        let grains = part.grain_owner_rank.len() as u64;
        let mut modes = Vec::with_capacity(4);
        let result = (|| -> hdf5::Result<()> {
            let group = self.file.create_group("mesh")?;
            let ds = new_fixed::<f64>(&group, "nodes", part.total_nodes, 3)?;
            put_str_attr(&ds, "units", "m")?;
            put_str_attr(
                &ds,
                "description",
                "node coordinates in the reference configuration",
            )?;
            modes.push(collective::write_row_blocks(
                &ds,
                part.nodes.as_flattened(),
                3,
                part.node_blocks,
                part.total_nodes,
            )?);

            let ds = new_fixed::<u64>(&group, "tetrahedra", part.total_tets, 4)?;
            put_str_attr(&ds, "units", "")?;
            put_str_attr(
                &ds,
                "description",
                "global node ids (0-based) of each linear tetrahedron",
            )?;
            modes.push(collective::write_row_blocks(
                &ds,
                part.tets.as_flattened(),
                4,
                part.tet_blocks,
                part.total_tets,
            )?);

            let ds = new_fixed::<u32>(&group, "grain_of_element", part.total_tets, 1)?;
            put_str_attr(&ds, "units", "")?;
            put_str_attr(&ds, "description", "grain id of each tetrahedron")?;
            modes.push(collective::write_row_blocks(
                &ds,
                part.grain_of_tet,
                1,
                part.tet_blocks,
                part.total_tets,
            )?);

            let ds = new_fixed::<u32>(&group, "owner_rank_of_grain", grains, 1)?;
            put_str_attr(&ds, "units", "")?;
            put_str_attr(
                &ds,
                "description",
                "MPI rank that owns each grain at the start of the run (frames/NNNNNN/owner_rank_of_grain follows migration)",
            )?;
            modes.push(collective::write_1d_u32(&ds, owners, 0, grains)?);
            Ok(())
        })();
        self.count(WriteKind::Mesh, &modes);
        self.agree("writing /mesh", result.map_err(|e| e.to_string()))?;
        self.flush_file()
    }

    /// Writes frame `index` (`/frames/NNNNNN`, six digits) with group attribute `time` (s)
    /// and one dataset per field, each rank its own rows, collectively. Scalar fields
    /// (`components == 1`) are 1-D, others `(total, components)`.
    ///
    /// All ranks must call, with the same index, time and fields (names, units,
    /// components, totals) in the same order.
    pub fn write_frame(
        &mut self,
        index: usize,
        time: f64,
        fields: &[FieldPart],
    ) -> Result<(), MufeError> {
        let group_name = format!("{index:06}");
        let what = format!("writing /frames/{group_name}");
        let mut local = check_names(fields.iter().map(|f| f.name)).and_then(|()| {
            for f in fields {
                if f.components == 0 {
                    return Err(format!("field {}: 0 components", f.name));
                }
                if f.data.len() % f.components != 0 {
                    return Err(format!(
                        "field {}: {} values are not whole rows of {} components",
                        f.name,
                        f.data.len(),
                        f.components
                    ));
                }
                let rows = (f.data.len() / f.components) as u64;
                blocks::check_local(f.blocks, rows)
                    .map_err(|e| format!("field {}: {e}", f.name))?;
            }
            Ok(())
        });
        if local.is_ok() && self.file.link_exists(&format!("frames/{group_name}")) {
            local = Err("frame already written".to_string());
        }
        if local.is_ok() {
            let mut key = format!("{index}|{}|", time.to_bits());
            for f in fields {
                key.push_str(&format!(
                    "{}|{}|{}|{}|",
                    f.name, f.units, f.components, f.total
                ));
            }
            local = self.same_on_all_ranks(fnv1a(key.as_bytes()), "frame index, time and fields");
        }
        self.agree(&what, local)?;
        let layouts: Vec<_> = fields.iter().map(|f| (f.blocks, f.total)).collect();
        blocks::check_frame_tiling(self.domain, &layouts, &mut self.verified_layouts)
            .map_err(|(i, e)| self.error(&format!("/frames/{group_name}/{}", fields[i].name), e))?;

        let mut modes = Vec::with_capacity(fields.len());
        let result = (|| -> hdf5::Result<()> {
            let frames = if self.file.link_exists("frames") {
                self.file.group("frames")?
            } else {
                self.file.create_group("frames")?
            };
            let group = frames.create_group(&group_name)?;
            group
                .new_attr::<f64>()
                .create("time")?
                .write_scalar(&time)?;
            for f in fields {
                let ds = new_fixed::<f64>(&group, f.name, f.total, f.components)?;
                put_str_attr(&ds, "units", f.units)?;
                modes.push(collective::write_row_blocks(
                    &ds,
                    f.data,
                    f.components,
                    f.blocks,
                    f.total,
                )?);
            }
            Ok(())
        })();
        self.count(WriteKind::Frame, &modes);
        self.agree(&what, result.map_err(|e| e.to_string()))?;
        self.io.frames_written += 1;
        self.flush_file()
    }

    /// Flushes the history and closes the file.
    ///
    /// All ranks must call.
    pub fn close(mut self) -> Result<(), MufeError> {
        self.flush_history()?;
        let ResultsWriter {
            domain,
            path,
            history,
            file,
            ..
        } = self;
        // Datasets first: with MPI-IO the file only closes when nothing in it is open.
        drop(history);
        let local = file.close().map_err(|e| e.to_string());
        agree(domain, &path, "closing results file", local)
    }

    fn check_mesh_part(&self, part: &MeshPart) -> Result<(), String> {
        blocks::check_local(part.node_blocks, part.nodes.len() as u64)
            .map_err(|e| format!("nodes: {e}"))?;
        blocks::check_local(part.tet_blocks, part.tets.len() as u64)
            .map_err(|e| format!("tetrahedra: {e}"))?;
        if part.grain_of_tet.len() != part.tets.len() {
            return Err(format!(
                "{} grain ids for {} tetrahedra",
                part.grain_of_tet.len(),
                part.tets.len()
            ));
        }
        if let Some((i, t)) = part
            .tets
            .iter()
            .enumerate()
            .find(|(_, t)| t.iter().any(|&n| n >= part.total_nodes))
        {
            return Err(format!(
                "element {}: node id out of range in {t:?} ({} nodes)",
                global_row(part.tet_blocks, i as u64),
                part.total_nodes
            ));
        }
        let grains = part.grain_owner_rank.len();
        if let Some((i, g)) = part
            .grain_of_tet
            .iter()
            .enumerate()
            .find(|(_, &g)| g as usize >= grains)
        {
            return Err(format!(
                "element {}: grain {g} out of range ({grains} grains)",
                global_row(part.tet_blocks, i as u64)
            ));
        }
        let size = self.domain.size();
        if let Some((g, r)) = part
            .grain_owner_rank
            .iter()
            .enumerate()
            .find(|(_, &r)| r as usize >= size)
        {
            return Err(format!(
                "grain {g}: owner rank {r} out of range ({size} ranks)"
            ));
        }
        Ok(())
    }

    /// Checks (on every rank, from gathered data, so every rank reaches the same verdict)
    /// that for each layout the ranks' blocks tile `[0, total)` exactly (no overlap, no
    /// gap) and that all ranks name the same total; `names[k]` names layout k in the
    /// error. All ranks must call, with the same number of layouts.
    fn check_blocks<S: AsRef<str>>(
        &self,
        names: &[S],
        layouts: &[(&[(u64, u64)], u64)],
    ) -> Result<(), MufeError> {
        blocks::check_tiling(self.domain, layouts).map_err(|(k, e)| {
            let name = names.get(k).map_or("", |n| n.as_ref());
            self.error(name, e)
        })
    }

    /// `Ok` if every rank passes the same `key`, else a local error naming `what`.
    /// All ranks must call.
    fn same_on_all_ranks(&self, key: u64, what: &str) -> Result<(), String> {
        let keys = self.domain.all_gather_u64(key);
        match keys.iter().position(|&k| k != keys[0]) {
            Some(r) => Err(format!("{what} differ between rank 0 and rank {r}")),
            None => Ok(()),
        }
    }

    fn agree(&self, what: &str, local: Result<(), String>) -> Result<(), MufeError> {
        agree(self.domain, &self.path, what, local)
    }

    fn count(&mut self, kind: WriteKind, modes: &[IoMode]) {
        let count = match kind {
            WriteKind::Mesh => &mut self.io.mesh,
            WriteKind::History => &mut self.io.history,
            WriteKind::Frame => &mut self.io.frames,
        };
        for &m in modes {
            count.add(m);
        }
    }

    /// `H5Fflush`: makes everything written so far readable even if the run dies later.
    /// All ranks must call.
    fn flush_file(&self) -> Result<(), MufeError> {
        let local = self.file.flush().map_err(|e| e.to_string());
        self.agree("flushing results file", local)
    }

    fn error(&self, what: &str, e: impl Display) -> MufeError {
        io_error(&self.path, what, e)
    }
}

pub(crate) fn io_error(path: &Path, what: &str, e: impl Display) -> MufeError {
    MufeError::Io(format!("{}: {what}: {e}", path.display()))
}

/// Turns rank-local outcomes into one outcome on every rank: `Err` everywhere if any rank
/// failed (a rank's own message where it failed, "failed on rank R" elsewhere), so that no
/// rank goes on into a collective the others have abandoned. All ranks must call.
pub(crate) fn agree(
    domain: &Domain,
    path: &Path,
    what: &str,
    local: Result<(), String>,
) -> Result<(), MufeError> {
    let failed = domain.all_gather_u64(u64::from(local.is_err()));
    match local {
        Err(m) => Err(io_error(path, what, m)),
        Ok(()) => match failed.iter().position(|&f| f != 0) {
            Some(r) => Err(io_error(
                path,
                what,
                format!("failed on rank {r} (see its error)"),
            )),
            None => Ok(()),
        },
    }
}

/// Names must be non-empty, free of `/` (they become HDF5 link names) and unique.
fn check_names<'a>(names: impl Iterator<Item = &'a str>) -> Result<(), String> {
    let mut seen = std::collections::HashSet::new();
    for name in names {
        if name.is_empty() || name.contains('/') || name == "." {
            return Err(format!(
                "invalid name {name:?} (must be non-empty, without '/')"
            ));
        }
        if !seen.insert(name) {
            return Err(format!("duplicate name {name:?}"));
        }
    }
    Ok(())
}

/// A fixed-size dataset of `rows` (× `columns` if > 1) elements. All ranks must call.
fn new_fixed<T: hdf5::H5Type>(
    group: &Group,
    name: &str,
    rows: u64,
    columns: usize,
) -> hdf5::Result<Dataset> {
    let rows = rows as usize;
    let builder = group.new_dataset::<T>();
    if columns == 1 {
        builder.shape(rows).create(name)
    } else {
        builder.shape([rows, columns]).create(name)
    }
}

/// A scalar variable-length UTF-8 string attribute (reads as `str` in h5py).
pub(crate) fn put_str_attr(loc: &Location, name: &str, value: &str) -> hdf5::Result<()> {
    // VarLenUnicode cannot hold NUL; replace it rather than fail on odd input.
    let value: VarLenUnicode = value
        .replace('\0', "\u{FFFD}")
        .parse()
        .map_err(|e| hdf5::Error::from(format!("attribute {name}: {e}")))?;
    loc.new_attr::<VarLenUnicode>()
        .create(name)?
        .write_scalar(&value)
}

pub(crate) fn put_u64_attr(loc: &Location, name: &str, value: u64) -> hdf5::Result<()> {
    loc.new_attr::<u64>().create(name)?.write_scalar(&value)
}

/// FNV-1a's 64-bit offset basis and prime.
pub(crate) const FNV_OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
pub(crate) const FNV_PRIME: u64 = 0x0100_0000_01b3;

/// FNV-1a: a stable (process- and platform-independent) hash for comparing metadata
/// across ranks, and the checksum of checkpoint blocks in format 2.
pub fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(FNV_OFFSET, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(FNV_PRIME)
    })
}

mod blocks;
mod resume;
mod stages;
use blocks::global_row;
pub use blocks::grain_row_blocks;
pub use resume::Resumed;
pub use stages::StageAttributes;

#[cfg(test)]
mod tests;
