//! One running job per output directory.
//!
//! Two jobs writing the same `--out` overwrite each other's `results.h5` and checkpoints,
//! and a restart can read a checkpoint another job is deleting. That happens by accident:
//! after `kill -9` of `mpirun`, OpenMPI's ranks (each in a process group of its own) can
//! run on for seconds, and a `--restart latest` typed at once would share the directory
//! with them. So rank 0 holds an advisory lock on `OUT/.mufe.lock` for the whole run; the
//! kernel drops it when the process ends, however it ends, so a stale lock cannot outlive
//! its job. A second job is refused with one line (exit 2) before it reads or writes
//! anything else there.

use crate::domain::Domain;
use crate::error::{InputError, MufeError, Result};
use std::fs::{File, TryLockError};
use std::path::Path;

/// The lock file inside the output directory.
pub const LOCK_FILE_NAME: &str = ".mufe.lock";

/// Held for the whole run (rank 0 holds the file; other ranks hold nothing).
pub struct OutputLock {
    _file: Option<File>,
}

/// How rank 0's attempt ended, as sent to the other ranks.
const TAKEN: u8 = 0;
const IN_USE: u8 = 1;
const IO_FAILED: u8 = 2;

impl OutputLock {
    /// Creates `out` if needed and locks it for this job, or fails on every rank: an input
    /// error (exit 2) if another job holds it, an I/O error if it cannot be created.
    /// All ranks must call.
    pub fn take(domain: &Domain, out: &Path) -> Result<Self> {
        let (file, mut verdict) = if domain.is_root() {
            match lock_on_root(out) {
                Ok(f) => (Some(f), vec![TAKEN]),
                Err((kind, message)) => (None, [vec![kind], message.into_bytes()].concat()),
            }
        } else {
            (None, Vec::new())
        };
        domain.broadcast_bytes(&mut verdict);
        let message = String::from_utf8_lossy(verdict.get(1..).unwrap_or_default()).into_owned();
        match verdict.first().copied() {
            Some(TAKEN) => Ok(Self { _file: file }),
            Some(IN_USE) => {
                Err(InputError::new(out.display().to_string(), "--out", message).into())
            }
            _ => Err(MufeError::Io(message)),
        }
    }
}

/// Rank 0's part: the directory, the file and a non-blocking exclusive lock on it.
fn lock_on_root(out: &Path) -> std::result::Result<File, (u8, String)> {
    let io = |what: &str, e: std::io::Error| (IO_FAILED, format!("{}: {what}: {e}", out.display()));
    std::fs::create_dir_all(out).map_err(|e| io("cannot create output directory", e))?;
    let path = out.join(LOCK_FILE_NAME);
    let file = File::options()
        .create(true)
        .truncate(false)
        .write(true)
        .open(&path)
        .map_err(|e| io("cannot open the lock file", e))?;
    match file.try_lock() {
        Ok(()) => Ok(file),
        Err(TryLockError::WouldBlock) => Err((
            IN_USE,
            format!(
                "in use by another running mufe job (it holds {LOCK_FILE_NAME}); wait for it to end or write to another directory"
            ),
        )),
        // A file system without locks (some network mounts) must not stop a run: it only
        // loses the guard, and says so.
        Err(TryLockError::Error(e)) => {
            eprintln!(
                "warning: {}: cannot lock {LOCK_FILE_NAME} ({e}); a second job into this directory would not be refused",
                out.display()
            );
            Ok(file)
        }
    }
}
