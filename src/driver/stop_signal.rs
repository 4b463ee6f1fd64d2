//! Stopping a run cleanly on a signal: SIGTERM (Slurm's time limit, `kill`), SIGINT
//! (Ctrl-C) and SIGUSR1 (what `mpirun` forwards to every rank, and what
//! `jobs/cluster/slurm_run.sh` sends before the time limit) set a flag; the run loop sees
//! it at the end of a step, all ranks agree on it, and the run writes a checkpoint, its
//! last history row and frame, closes `results.h5` and exits with 128 + the signal.

use std::sync::atomic::{AtomicI32, Ordering};

/// The signal received (0: none). An atomic store is async-signal-safe.
static RECEIVED: AtomicI32 = AtomicI32::new(0);

extern "C" fn remember(signal: libc::c_int) {
    RECEIVED.store(signal, Ordering::SeqCst);
}

/// Installs the handlers (once per process; later calls change nothing).
pub fn install() {
    for signal in [libc::SIGTERM, libc::SIGINT, libc::SIGUSR1] {
        // SAFETY: `remember` only stores into an atomic, which is async-signal-safe; the
        // handler is a plain `extern "C" fn(c_int)` as `signal` expects.
        unsafe {
            libc::signal(
                signal,
                remember as extern "C" fn(libc::c_int) as libc::sighandler_t,
            );
        }
    }
}

/// The signal received so far on this rank, if any.
pub fn received() -> Option<i32> {
    match RECEIVED.load(Ordering::SeqCst) {
        0 => None,
        s => Some(s),
    }
}

/// The name of a stop signal, for messages.
pub fn name(signal: i32) -> &'static str {
    match signal {
        libc::SIGTERM => "SIGTERM",
        libc::SIGINT => "SIGINT",
        libc::SIGUSR1 => "SIGUSR1",
        _ => "a signal",
    }
}
