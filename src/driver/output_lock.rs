//! One running job per output directory.
//!
//! Two jobs writing the same `--out` overwrite each other's `results.h5` and checkpoints,
//! and a restart can read a checkpoint another job is deleting. That happens by accident:
//! after `kill -9` of `mpirun`, OpenMPI's ranks (each in a process group of its own) can
//! run on for seconds, and a `--restart latest` typed at once would share the directory
//! with them. So rank 0 holds an advisory lock on `OUT/.mufe.lock` for the whole run; the
//! kernel drops it when the process ends, however it ends, so a stale lock cannot outlive
//! its job. A second job is refused with one line (exit 2).
//!
//! The lock is taken in two steps so that a run refused for its input still leaves the
//! directory as it found it (docs/INPUT.md): [`OutputLock::check`] at the start locks the
//! file if it is already there (every job that got as far as writing made it) and creates
//! nothing; [`OutputLock::hold`], just before the first write, creates the directory and
//! the file and locks it if the first step found none (two new jobs racing for one new
//! directory).
//!
//! `flock` is per node on some parallel file systems (Lustre mounted with `localflock`,
//! BeeGFS without global locks): there a job whose rank 0 runs on another node is not seen.

use crate::domain::Domain;
use crate::error::{echo, report_line, InputError, MufeError, Result};
use std::fs::{File, TryLockError};
use std::path::Path;

/// The lock file inside the output directory.
pub const LOCK_FILE_NAME: &str = ".mufe.lock";

/// Held for the whole run (rank 0 holds the file; other ranks hold nothing).
pub struct OutputLock {
    file: Option<File>,
}

/// How rank 0's attempt ended, as sent to the other ranks.
const TAKEN: u8 = 0;
const IN_USE: u8 = 1;
const IO_FAILED: u8 = 2;

impl OutputLock {
    /// Locks `out/.mufe.lock` if it exists, creating nothing; fails on every rank with an
    /// input error (exit 2) if another job holds it. All ranks must call.
    pub fn check(domain: &Domain, out: &Path) -> Result<Self> {
        let mut lock = Self { file: None };
        let there = domain.is_root() && out.join(LOCK_FILE_NAME).is_file();
        lock.take(domain, out, there)?;
        Ok(lock)
    }

    /// Creates `out` and the lock file and locks it, unless [`Self::check`] already holds
    /// it; fails on every rank as `check` does, or with an I/O error if the directory or
    /// the file cannot be created. On a file system without locks the run goes on, with a
    /// warning that a second job would not be refused. All ranks must call.
    pub fn hold(&mut self, domain: &Domain, out: &Path) -> Result<()> {
        let held = self.file.is_some();
        self.take(domain, out, !held)
    }

    /// With `attempt` (read on rank 0), rank 0 opens or makes the directory and the file and
    /// locks it; the verdict goes to every rank (one broadcast, whatever rank 0 did).
    /// Without, rank 0 keeps what it holds.
    fn take(&mut self, domain: &Domain, out: &Path, attempt: bool) -> Result<()> {
        let mut verdict = Vec::new();
        if domain.is_root() {
            verdict = match attempt.then(|| lock_on_root(out)).transpose() {
                Ok(file) => {
                    if file.is_some() {
                        self.file = file;
                    }
                    vec![TAKEN]
                }
                Err((kind, message)) => [vec![kind], message.into_bytes()].concat(),
            };
        }
        domain.broadcast_bytes(&mut verdict);
        let message = String::from_utf8_lossy(verdict.get(1..).unwrap_or_default()).into_owned();
        match verdict.first().copied() {
            Some(TAKEN) => Ok(()),
            Some(IN_USE) => Err(InputError::new("<command line>", "--out", message).into()),
            _ => Err(MufeError::Io(message)),
        }
    }
}

/// Rank 0's part: the directory, the file and a non-blocking exclusive lock on it.
fn lock_on_root(out: &Path) -> std::result::Result<File, (u8, String)> {
    let path = out.join(LOCK_FILE_NAME);
    let io = |at: &Path, what: &str, e: std::io::Error| {
        (IO_FAILED, format!("{}: {what}: {e}", at.display()))
    };
    std::fs::create_dir_all(out).map_err(|e| io(out, "cannot create output directory", e))?;
    let file = File::options()
        .create(true)
        .truncate(false)
        .write(true)
        .open(&path)
        .map_err(|e| io(&path, "cannot open the output directory's lock file", e))?;
    match file.try_lock() {
        Ok(()) => Ok(file),
        Err(TryLockError::WouldBlock) => Err((
            IN_USE,
            format!(
                "'{}' is in use by another running mufe job (it holds {LOCK_FILE_NAME}); wait for it to end or write to another directory",
                echo(&out.display().to_string())
            ),
        )),
        // A file system without locks (some network mounts) must not stop a run: it only
        // loses the guard, and says so.
        Err(TryLockError::Error(e)) => {
            report_line(format_args!(
                "warning: {}: cannot lock ({e}); a second job into this directory would not be refused",
                path.display()
            ));
            Ok(file)
        }
    }
}
