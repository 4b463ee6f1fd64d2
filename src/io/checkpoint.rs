//! Checkpoints: `DIR/checkpoints/step_NNNNNNNNNNNN.h5`, the whole evolving state of a run
//! (every rank's `solver::State`) at one step, written collectively into one HDF5 file.
//!
//! Layout (format [`CHECKPOINT_FORMAT`]):
//! - attributes of `/`: `format_version`, `step`, `time` (s), `ranks`;
//! - `/scene`: the scene text as run (a restart is refused if it differs);
//! - `/state` (u8): the ranks' states as serde JSON (exact f64 round trip), rank r's bytes
//!   at `[state_offsets[r], state_offsets[r+1])`, each rank writing its own hyperslab;
//! - `/state_offsets` (u64, ranks + 1) and `/state_checksums` (u64 FNV-1a per rank).
//!
//! A file is written as `.step_….h5.tmp` and renamed when complete (rename is atomic on
//! POSIX file systems), so a run killed while writing leaves the previous checkpoints
//! intact; the last K are kept. A checkpoint restarts on the rank count that wrote it.

use super::collective;
use super::results::{agree, fnv1a, io_error, put_u64_attr};
use crate::domain::Domain;
use crate::error::{InputError, MufeError};
use hdf5::File;
use std::path::{Path, PathBuf};

/// Version of the checkpoint layout; a file of another version is refused.
pub const CHECKPOINT_FORMAT: u64 = 1;
/// Subdirectory of the output directory.
pub const CHECKPOINT_DIR: &str = "checkpoints";

/// `DIR/checkpoints/step_<step, 12 digits>.h5`.
pub fn checkpoint_path(dir: &Path, step: u64) -> PathBuf {
    dir.join(CHECKPOINT_DIR).join(format!("step_{step:012}.h5"))
}

/// What a checkpoint says about itself.
#[derive(Debug, Clone, PartialEq)]
pub struct CheckpointInfo {
    pub step: u64,
    pub time: f64,
    pub ranks: u64,
    pub scene: String,
}

/// Writes this rank's `state` (serialised) into the checkpoint of `step` and keeps the
/// last `keep` checkpoints of the directory. All ranks must call.
pub fn write_checkpoint(
    domain: &Domain,
    dir: &Path,
    scene_text: &str,
    state: &[u8],
    step: u64,
    time: f64,
    keep: usize,
) -> Result<PathBuf, MufeError> {
    let final_path = checkpoint_path(dir, step);
    let folder = dir.join(CHECKPOINT_DIR);
    let tmp = folder.join(format!(".step_{step:012}.h5.tmp"));
    let made = if domain.is_root() {
        std::fs::create_dir_all(&folder).map_err(|e| e.to_string())
    } else {
        Ok(())
    };
    agree(domain, &folder, "creating the checkpoint directory", made)?;

    let lengths = domain.all_gather_u64(state.len() as u64);
    let mut offsets = vec![0u64];
    for l in &lengths {
        offsets.push(offsets.last().copied().unwrap_or(0) + l);
    }
    let total = *offsets.last().unwrap_or(&0);
    let rank = domain.rank();
    let created = File::with_options()
        .with_fapl(|p| p.mpio(domain.raw_comm(), None))
        .create(&tmp)
        .map_err(|e| e.to_string());
    agree(
        domain,
        &tmp,
        "creating checkpoint",
        created.as_ref().map(|_| ()).map_err(Clone::clone),
    )?;
    let file = created.map_err(|e| io_error(&tmp, "creating checkpoint", e))?;
    let written = (|| -> hdf5::Result<()> {
        put_u64_attr(&file, "format_version", CHECKPOINT_FORMAT)?;
        put_u64_attr(&file, "step", step)?;
        put_u64_attr(&file, "ranks", domain.size() as u64)?;
        file.new_attr::<f64>().create("time")?.write_scalar(&time)?;
        collective::create_text_dataset(&file, "scene", scene_text, domain.is_root())?;
        let ds = file
            .new_dataset::<u8>()
            .shape(total as usize)
            .create("state")?;
        collective::write_rows(&ds, state, 1, offsets[rank], total)?;
        let ds = (file.new_dataset::<u64>())
            .shape(offsets.len())
            .create("state_offsets")?;
        let root_rows: &[u64] = if domain.is_root() { &offsets } else { &[] };
        collective::write_1d_u64(&ds, root_rows, 0, offsets.len() as u64)?;
        let ds = (file.new_dataset::<u64>())
            .shape(lengths.len())
            .create("state_checksums")?;
        collective::write_1d_u64(&ds, &[fnv1a(state)], rank as u64, lengths.len() as u64)?;
        Ok(())
    })();
    agree(
        domain,
        &tmp,
        "writing checkpoint",
        written.map_err(|e| e.to_string()),
    )?;
    let closed = file.close().map_err(|e| e.to_string());
    agree(domain, &tmp, "closing checkpoint", closed)?;
    let renamed = if domain.is_root() {
        std::fs::rename(&tmp, &final_path)
            .map_err(|e| e.to_string())
            .and_then(|()| prune(&folder, keep).map_err(|e| e.to_string()))
    } else {
        Ok(())
    };
    agree(domain, &final_path, "renaming checkpoint", renamed)?;
    Ok(final_path)
}

/// Removes all but the newest `keep` (≥ 1) `step_*.h5` files of `folder`.
fn prune(folder: &Path, keep: usize) -> std::io::Result<()> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(folder)?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with("step_") && n.ends_with(".h5"))
        })
        .collect();
    files.sort();
    let excess = files.len().saturating_sub(keep.max(1));
    for f in &files[..excess] {
        std::fs::remove_file(f)?;
    }
    Ok(())
}

/// Reads a checkpoint: its header, checked (a file that is not a checkpoint, of another
/// format version, or written by another number of ranks is an input error naming it),
/// and this rank's state bytes, checksum verified.
pub fn read_checkpoint(
    domain: &Domain,
    path: &Path,
) -> Result<(CheckpointInfo, Vec<u8>), MufeError> {
    let file_name = path.display().to_string();
    let bad =
        |item: &str, msg: String| -> MufeError { InputError::new(&file_name, item, msg).into() };
    let file = File::open(path).map_err(|e| bad("file", format!("cannot open as HDF5: {e}")))?;
    let u64_attr = |name: &str| -> Result<u64, MufeError> {
        (file.attr(name).and_then(|a| a.read_scalar::<u64>()))
            .map_err(|_| bad(name, "missing: not a mufe checkpoint".into()))
    };
    let version = u64_attr("format_version")?;
    if version != CHECKPOINT_FORMAT {
        return Err(bad(
            "format_version",
            format!("checkpoint format {version}; this mufe reads format {CHECKPOINT_FORMAT} only"),
        ));
    }
    let ranks = u64_attr("ranks")?;
    if ranks != domain.size() as u64 {
        return Err(bad(
            "ranks",
            format!(
                "written by {ranks} ranks; restart it with mpirun -n {ranks} (this run has {})",
                domain.size()
            ),
        ));
    }
    let time = (file.attr("time").and_then(|a| a.read_scalar::<f64>()))
        .map_err(|_| bad("time", "missing: not a mufe checkpoint".into()))?;
    let scene = (file
        .dataset("scene")
        .and_then(|d| collective::read_text_dataset(&d)))
    .map_err(|e| bad("scene", format!("unreadable: {e}")))?;
    let info = CheckpointInfo {
        step: u64_attr("step")?,
        time,
        ranks,
        scene,
    };

    let r = domain.rank();
    let read_u64 = |name: &str| {
        (file.dataset(name).and_then(|d| d.read_raw::<u64>())).map_err(|e| bad(name, e.to_string()))
    };
    let (offsets, sums) = (read_u64("state_offsets")?, read_u64("state_checksums")?);
    if offsets.len() != domain.size() + 1 || sums.len() != domain.size() {
        return Err(bad("state_offsets", "does not match the rank count".into()));
    }
    let (a, b) = (offsets[r] as usize, offsets[r + 1] as usize);
    let bytes = (file
        .dataset("state")
        .and_then(|d| d.read_slice_1d::<u8, _>(a..b)))
    .map_err(|e| bad("state", e.to_string()))?
    .to_vec();
    if fnv1a(&bytes) != sums[r] {
        return Err(bad(
            "state",
            format!("checksum mismatch in rank {r}'s state: the file is damaged"),
        ));
    }
    Ok((info, bytes))
}
