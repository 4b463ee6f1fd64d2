//! Checkpoints: `DIR/checkpoints/step_NNNNNNNNNNNN.h5`, the whole evolving state of a run
//! at one step, written collectively into one HDF5 file, readable by the same rank count
//! (each rank takes its own `State` back, bitwise) and by any other (grains re-partitioned,
//! each rank taking the packages of the grains it will hold).
//!
//! Layout (format [`CHECKPOINT_FORMAT`]); "blocks" are one per rank, in rank order, each
//! rank writing its own hyperslab, with `NAME_offsets` (ranks + 1) and `NAME_checksums`
//! ([`BlockChecksum`] of each rank's bytes):
//! - attributes of `/`: `format_version`, `step`, `time` (s), `ranks`, `grains`;
//! - `/scene`: the scene text as run;
//! - `/state` (u8 blocks): each rank's `solver::State` as serde JSON (exact f64 round trip;
//!   its positions, velocities and detection reference as base64 of their bytes,
//!   [`crate::packed_vectors`]);
//! - `/totals` (u8 blocks): each rank's `solver::RankTotals` as JSON (energies and wall
//!   work summed over what it owns);
//! - `/grains` (f64 blocks): the owned grains' packages (`driver::migration::pack_grain`),
//!   with `/grain_ids` and `/grain_package_lengths` (u64, one row per grain, in the same
//!   rank-block order; `/grain_offsets` gives each rank's first row). The checksum of a
//!   rank's `/grains` block covers its ids, lengths and packages.
//!
//! A file is written as `.step_….h5.tmp` and renamed when complete (rename is atomic on
//! POSIX file systems), so a run killed while writing leaves the previous checkpoints
//! intact; the last K are kept.

use super::collective;
use super::results::{agree, fnv1a, io_error, put_u64_attr, FNV_OFFSET, FNV_PRIME};
use crate::domain::Domain;
use crate::error::{InputError, MufeError};
use hdf5::File;
use std::path::{Path, PathBuf};

/// Version of the checkpoint layout written. Format 2 (the state's vectors as JSON numbers,
/// FNV-1a checksums byte by byte) is read as well; any other version is refused.
pub const CHECKPOINT_FORMAT: u64 = 3;
/// The earliest format read.
const OLDEST_FORMAT_READ: u64 = 2;
/// Subdirectory of the output directory.
pub const CHECKPOINT_DIR: &str = "checkpoints";

/// `DIR/checkpoints/step_<step, 12 digits>.h5`.
pub fn checkpoint_path(dir: &Path, step: u64) -> PathBuf {
    dir.join(CHECKPOINT_DIR).join(format!("step_{step:012}.h5"))
}

/// `DIR/checkpoints/stage_<k>_<name>.h5`: the state at the end of stage `k` (1-based),
/// outside the rotation of `step_*.h5` (never pruned, not taken by `--restart latest`).
pub fn stage_checkpoint_path(dir: &Path, k: usize, name: &str) -> PathBuf {
    let safe: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect();
    dir.join(CHECKPOINT_DIR)
        .join(format!("stage_{k}_{safe}.h5"))
}

/// Where a checkpoint goes.
pub enum Target {
    /// `step_<step>.h5`, then all but the newest `keep` such files are removed.
    Rotation { keep: usize },
    /// This path (a stage's end), outside the rotation.
    Kept(PathBuf),
}

/// Keeps the checkpoint `from` also as `to` (a hard link, or a copy where the file system
/// has none). Root only; the caller agrees the result over ranks.
pub fn keep_checkpoint_as(from: &Path, to: &Path) -> std::io::Result<()> {
    if to.exists() {
        std::fs::remove_file(to)?;
    }
    std::fs::hard_link(from, to).or_else(|_| std::fs::copy(from, to).map(|_| ()))
}

/// What a checkpoint says about itself.
#[derive(Debug, Clone, PartialEq)]
pub struct CheckpointInfo {
    pub step: u64,
    pub time: f64,
    pub ranks: u64,
    /// Grains of the run (all ranks'), which a restart's scene must have too.
    pub grains: u64,
    pub scene: String,
}

/// What one rank puts into a checkpoint.
pub struct RankCheckpoint<'a> {
    /// The rank's `State`, serde JSON.
    pub state: &'a [u8],
    /// The rank's `RankTotals`, serde JSON.
    pub totals: &'a [u8],
    /// Global ids of the grains the rank owns (ascending).
    pub grain_ids: &'a [u64],
    /// Length (values) of each owned grain's package.
    pub package_lengths: &'a [u64],
    /// The owned grains' packages, concatenated in `grain_ids` order.
    pub packages: &'a [f64],
}

/// The checksum of a checkpoint block (format 3): FNV-1a over its bytes eight at a time,
/// each little-endian u64 word (a last partial one zero-padded) xor-ed in and multiplied
/// by the FNV prime, closed by the byte count the same way. One multiply per eight bytes:
/// byte by byte (format 2) a dependent multiply per byte took ≈ 0.35 s of a 330 MB
/// checkpoint (docs/BENCHMARKS.md, session 75).
#[derive(Debug, Clone, Copy)]
pub struct BlockChecksum {
    hash: u64,
    bytes: u64,
}

impl Default for BlockChecksum {
    fn default() -> Self {
        Self {
            hash: FNV_OFFSET,
            bytes: 0,
        }
    }
}

impl BlockChecksum {
    #[inline]
    fn mix(&mut self, word: u64) {
        self.hash = (self.hash ^ word).wrapping_mul(FNV_PRIME);
    }

    /// Adds whole words (the little-endian bytes of each); only words may come before.
    pub fn words(&mut self, words: impl IntoIterator<Item = u64>) -> &mut Self {
        debug_assert!(self.bytes.is_multiple_of(8), "words after a partial word");
        for w in words {
            self.mix(w);
            self.bytes += 8;
        }
        self
    }

    /// Adds `bytes`; a partial last word ends what may be added.
    pub fn bytes(&mut self, bytes: &[u8]) -> &mut Self {
        let chunks = bytes.chunks_exact(8);
        let tail = chunks.remainder();
        self.words(chunks.map(|c| u64::from_le_bytes(c.try_into().expect("8 bytes"))));
        if !tail.is_empty() {
            let mut last = [0u8; 8];
            last[..tail.len()].copy_from_slice(tail);
            self.mix(u64::from_le_bytes(last));
            self.bytes += tail.len() as u64;
        }
        self
    }

    /// The checksum of what was added.
    pub fn value(&self) -> u64 {
        let mut closed = *self;
        closed.mix(self.bytes);
        closed.hash
    }
}

/// The checksum of a JSON block in a checkpoint of format `version`.
fn bytes_checksum(version: u64, bytes: &[u8]) -> u64 {
    if version == 2 {
        fnv1a(bytes)
    } else {
        BlockChecksum::default().bytes(bytes).value()
    }
}

/// The checksum of a grain block (its ids, lengths and packages, in that order) in a
/// checkpoint of format `version`.
fn grains_checksum(version: u64, ids: &[u64], lengths: &[u64], packages: &[f64]) -> u64 {
    if version == 2 {
        let mut bytes = Vec::with_capacity(8 * (ids.len() + lengths.len() + packages.len()));
        bytes.extend(ids.iter().flat_map(|v| v.to_le_bytes()));
        bytes.extend(lengths.iter().flat_map(|v| v.to_le_bytes()));
        bytes.extend(packages.iter().flat_map(|v| v.to_le_bytes()));
        return fnv1a(&bytes);
    }
    let mut sum = BlockChecksum::default();
    sum.words(ids.iter().copied())
        .words(lengths.iter().copied())
        .words(packages.iter().map(|p| p.to_bits()));
    sum.value()
}

/// Writes this rank's part of the checkpoint of `step` and keeps the last `keep`
/// checkpoints of the directory. All ranks must call.
pub fn write_checkpoint(
    domain: &Domain,
    dir: &Path,
    scene_text: &str,
    part: &RankCheckpoint,
    step: u64,
    time: f64,
    target: Target,
) -> Result<PathBuf, MufeError> {
    let final_path = match &target {
        Target::Rotation { .. } => checkpoint_path(dir, step),
        Target::Kept(path) => path.clone(),
    };
    let folder = dir.join(CHECKPOINT_DIR);
    let tmp = folder.join(format!(".step_{step:012}.h5.tmp"));
    let made = if domain.is_root() {
        std::fs::create_dir_all(&folder).map_err(|e| e.to_string())
    } else {
        Ok(())
    };
    agree(domain, &folder, "creating the checkpoint directory", made)?;

    let grains = domain.sum_u64(part.grain_ids.len() as u64);
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
        put_u64_attr(&file, "grains", grains)?;
        file.new_attr::<f64>().create("time")?.write_scalar(&time)?;
        collective::create_text_dataset(&file, "scene", scene_text, domain.is_root())?;
        let json_sum = |bytes| Some(bytes_checksum(CHECKPOINT_FORMAT, bytes));
        write_blocks(domain, &file, "state", part.state, json_sum(part.state))?;
        write_blocks(domain, &file, "totals", part.totals, json_sum(part.totals))?;
        let (ids, lengths) = (part.grain_ids, part.package_lengths);
        let grains_sum = grains_checksum(CHECKPOINT_FORMAT, ids, lengths, part.packages);
        write_blocks(domain, &file, "grains", part.packages, Some(grains_sum))?;
        write_blocks(domain, &file, "grain_ids", part.grain_ids, None)?;
        write_blocks(
            domain,
            &file,
            "grain_package_lengths",
            part.package_lengths,
            None,
        )?;
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
            .and_then(|()| match target {
                Target::Rotation { keep } => prune(&folder, keep).map_err(|e| e.to_string()),
                Target::Kept(_) => Ok(()),
            })
    } else {
        Ok(())
    };
    agree(domain, &final_path, "renaming checkpoint", renamed)?;
    Ok(final_path)
}

/// `/NAME` holding every rank's `data` as one block in rank order, `/NAME_offsets` and,
/// with a checksum, `/NAME_checksums`. All ranks must call.
fn write_blocks<T: collective::Element + hdf5::H5Type>(
    domain: &Domain,
    file: &File,
    name: &str,
    data: &[T],
    checksum: Option<u64>,
) -> hdf5::Result<()> {
    let (offset, total) = domain.exclusive_scan_u64(data.len() as u64);
    let ds = file.new_dataset::<T>().shape(total as usize).create(name)?;
    collective::write_rows(&ds, data, 1, offset, total)?;
    let ends = domain.all_gather_u64(offset + data.len() as u64);
    let offsets: Vec<u64> = std::iter::once(0).chain(ends).collect();
    let ds = (file.new_dataset::<u64>())
        .shape(offsets.len())
        .create(format!("{name}_offsets").as_str())?;
    let root_rows: &[u64] = if domain.is_root() { &offsets } else { &[] };
    collective::write_1d_u64(&ds, root_rows, 0, offsets.len() as u64)?;
    if let Some(sum) = checksum {
        let ranks = domain.size() as u64;
        let ds = (file.new_dataset::<u64>())
            .shape(ranks as usize)
            .create(format!("{name}_checksums").as_str())?;
        collective::write_1d_u64(&ds, &[sum], domain.rank() as u64, ranks)?;
    }
    Ok(())
}

/// The `step_*.h5` files of `folder`, oldest step first (the names are zero-padded, so
/// name order is step order).
pub fn step_files_oldest_first(folder: &Path) -> std::io::Result<Vec<PathBuf>> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(folder)?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with("step_") && n.ends_with(".h5"))
        })
        .collect();
    files.sort();
    Ok(files)
}

/// Removes all but the newest `keep` (≥ 1) `step_*.h5` files of `folder`.
fn prune(folder: &Path, keep: usize) -> std::io::Result<()> {
    let files = step_files_oldest_first(folder)?;
    let excess = files.len().saturating_sub(keep.max(1));
    for f in &files[..excess] {
        std::fs::remove_file(f)?;
    }
    Ok(())
}

/// An open checkpoint whose header has been checked (a mufe checkpoint of this format).
pub struct CheckpointFile {
    file: File,
    name: String,
    /// The layout's version (how its checksums are computed).
    version: u64,
    pub info: CheckpointInfo,
}

/// Every rank's grain packages of a checkpoint, checksums verified.
pub struct GrainPackages {
    /// Global grain id of each package.
    pub ids: Vec<u64>,
    /// Each package's values.
    pub lengths: Vec<u64>,
    /// All packages, concatenated.
    pub packages: Vec<f64>,
}

impl CheckpointFile {
    /// Opens `path` and checks its header: a file that is not a checkpoint or is of another
    /// format version is an input error naming it.
    pub fn open(path: &Path) -> Result<Self, MufeError> {
        let name = path.display().to_string();
        let bad =
            |item: &str, msg: String| -> MufeError { InputError::new(&name, item, msg).into() };
        let file =
            File::open(path).map_err(|e| bad("file", format!("cannot open as HDF5: {e}")))?;
        let u64_attr = |attr: &str| -> Result<u64, MufeError> {
            (file.attr(attr).and_then(|a| a.read_scalar::<u64>()))
                .map_err(|_| bad(attr, "missing: not a mufe checkpoint".into()))
        };
        let version = u64_attr("format_version")?;
        if !(OLDEST_FORMAT_READ..=CHECKPOINT_FORMAT).contains(&version) {
            return Err(bad(
                "format_version",
                format!(
                    "checkpoint format {version}; this mufe reads formats {OLDEST_FORMAT_READ} to {CHECKPOINT_FORMAT}"
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
            ranks: u64_attr("ranks")?,
            grains: u64_attr("grains")?,
            scene,
        };
        Ok(Self {
            file,
            name,
            version,
            info,
        })
    }

    fn bad(&self, item: &str, msg: String) -> MufeError {
        InputError::new(&self.name, item, msg).into()
    }

    fn read_u64(&self, dataset: &str) -> Result<Vec<u64>, MufeError> {
        (self.file.dataset(dataset).and_then(|d| d.read_raw::<u64>()))
            .map_err(|e| self.bad(dataset, e.to_string()))
    }

    /// Rank `rank`'s block of `/NAME` (of the ranks that wrote the file).
    fn block<T: hdf5::H5Type + Copy>(
        &self,
        dataset: &str,
        rank: usize,
    ) -> Result<Vec<T>, MufeError> {
        let offsets = self.read_u64(&format!("{dataset}_offsets"))?;
        if offsets.len() != self.info.ranks as usize + 1 || rank >= self.info.ranks as usize {
            return Err(self.bad(
                &format!("{dataset}_offsets"),
                "does not match the rank count".into(),
            ));
        }
        let (a, b) = (offsets[rank] as usize, offsets[rank + 1] as usize);
        Ok((self.file.dataset(dataset))
            .and_then(|d| d.read_slice_1d::<T, _>(a..b))
            .map_err(|e| self.bad(dataset, e.to_string()))?
            .to_vec())
    }

    /// Rank `rank`'s bytes of a JSON block (`state` or `totals`), checksum verified.
    pub fn json_block(&self, dataset: &str, rank: usize) -> Result<Vec<u8>, MufeError> {
        let bytes: Vec<u8> = self.block(dataset, rank)?;
        let sums = self.read_u64(&format!("{dataset}_checksums"))?;
        if sums.get(rank) != Some(&bytes_checksum(self.version, &bytes)) {
            return Err(self.bad(
                dataset,
                format!("checksum mismatch in rank {rank}'s block: the file is damaged"),
            ));
        }
        Ok(bytes)
    }

    /// Every grain package of the file, checksums verified.
    pub fn grain_packages(&self) -> Result<GrainPackages, MufeError> {
        let sums = self.read_u64("grains_checksums")?;
        let mut all = GrainPackages {
            ids: Vec::new(),
            lengths: Vec::new(),
            packages: Vec::new(),
        };
        for r in 0..self.info.ranks as usize {
            let ids: Vec<u64> = self.block("grain_ids", r)?;
            let lengths: Vec<u64> = self.block("grain_package_lengths", r)?;
            let packages: Vec<f64> = self.block("grains", r)?;
            let sum = grains_checksum(self.version, &ids, &lengths, &packages);
            if sums.get(r) != Some(&sum)
                || ids.len() != lengths.len()
                || lengths.iter().sum::<u64>() != packages.len() as u64
            {
                return Err(self.bad(
                    "grains",
                    format!("checksum mismatch in rank {r}'s block: the file is damaged"),
                ));
            }
            all.ids.extend(ids);
            all.lengths.extend(lengths);
            all.packages.extend(packages);
        }
        Ok(all)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A grain block's checksum, taken over its values as words, is the checksum of the
    /// block's little-endian bytes; every flipped bit, a zero byte added at the end and a
    /// byte removed change it; format 2 keeps its byte-by-byte FNV-1a.
    #[test]
    fn block_checksums_see_every_bit_and_the_length() {
        let ids = [3u64, 7, 11];
        let lengths = [2u64, 0, 3];
        let packages = [1.5, -0.0, 2.0e-9, f64::MAX, -7.25];
        let mut bytes = Vec::new();
        bytes.extend(ids.iter().flat_map(|v| v.to_le_bytes()));
        bytes.extend(lengths.iter().flat_map(|v| v.to_le_bytes()));
        bytes.extend(packages.iter().flat_map(|v| v.to_le_bytes()));
        let sum = grains_checksum(CHECKPOINT_FORMAT, &ids, &lengths, &packages);
        assert_eq!(sum, bytes_checksum(CHECKPOINT_FORMAT, &bytes));
        assert_eq!(grains_checksum(2, &ids, &lengths, &packages), fnv1a(&bytes));
        assert_eq!(bytes_checksum(2, &bytes), fnv1a(&bytes));
        assert_ne!(sum, fnv1a(&bytes));
        for len in [0, 1, 7, 8, 9, 13, bytes.len()] {
            let part = &bytes[..len];
            let base = bytes_checksum(CHECKPOINT_FORMAT, part);
            for bit in 0..8 * len {
                let mut flipped = part.to_vec();
                flipped[bit / 8] ^= 1 << (bit % 8);
                assert_ne!(
                    bytes_checksum(CHECKPOINT_FORMAT, &flipped),
                    base,
                    "{len} {bit}"
                );
            }
            let mut longer = part.to_vec();
            longer.push(0);
            assert_ne!(
                bytes_checksum(CHECKPOINT_FORMAT, &longer),
                base,
                "{len} + 0"
            );
            if let Some((_, shorter)) = part.split_last() {
                assert_ne!(
                    bytes_checksum(CHECKPOINT_FORMAT, shorter),
                    base,
                    "{len} − 1"
                );
            }
        }
    }
}
