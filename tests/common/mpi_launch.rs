//! Running a test's MPI part under `mpirun` from `cargo test`.
//!
//! A multi-rank test relaunches its own test executable under `mpirun -n K`, filtered to
//! itself (`--exact NAME`), with `MUFE_MPI_CHILD=1` set: the child branch does the MPI work
//! on every rank, the parent (plain `cargo test`, no MPI) checks the exit status and the
//! files the child wrote. Every job runs in a session of its own: a timeout prints each
//! process's stacks (gdb) and kills the launcher and all its ranks, so a deadlock fails the
//! test and says where it waits instead of hanging CI; and no rank outlives its job, not
//! even one whose test failed while it ran.
//! Runs are serialised within a test binary (the machine has few cores).
//!
//! Use from a test file with `#[path = "common/mpi_launch.rs"] mod mpi_launch;`.
//!
//! Settings go through the environment so the code stays MPI-implementation neutral:
//! `MPIEXEC` overrides the launcher (default `mpirun`); the OpenMPI variables below allow
//! running as root, more ranks than cores, and unbound ranks (rayon threads).
#![allow(dead_code)]

use std::io::Read;
use std::os::unix::process::CommandExt;
use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::sync::Mutex;
use std::thread;
use std::time::{Duration, Instant};

/// Set in the children's environment; `is_mpi_child()` tells the two branches apart.
pub const CHILD_ENV: &str = "MUFE_MPI_CHILD";

/// Default time limit of an MPI test run.
pub const DEFAULT_TIMEOUT: Duration = Duration::from_secs(60);

/// Whether this process is a rank started by [`relaunch_test`] (then do the MPI work).
pub fn is_mpi_child() -> bool {
    std::env::var_os(CHILD_ENV).is_some_and(|v| v == "1")
}

/// Runs this package's `mufe` binary with `args` under `mpirun -n ranks` (see
/// [`run_under_mpirun`]).
pub fn run_mufe(ranks: usize, args: &[&str], timeout: Duration) -> Output {
    run_under_mpirun(
        ranks,
        Path::new(env!("CARGO_BIN_EXE_mufe")),
        args,
        &[],
        timeout,
    )
}

/// One MPI job at a time per test binary.
static SERIAL: Mutex<()> = Mutex::new(());

/// Environment every launch gets (harmless for MPICH, which ignores OMPI_*).
const LAUNCH_ENV: [(&str, &str); 4] = [
    ("OMPI_ALLOW_RUN_AS_ROOT", "1"),
    ("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1"),
    ("OMPI_MCA_rmaps_base_oversubscribe", "1"),
    ("OMPI_MCA_hwloc_base_binding_policy", "none"),
];

/// Runs `exe args...` under `$MPIEXEC` (or `mpirun`) with `ranks` ranks and the extra
/// `env`, and returns its output. Panics (failing the test) if the launcher cannot be
/// started or does not finish within `timeout`; then every process of the job is killed
/// and the output so far is shown, with each process's stacks.
pub fn run_under_mpirun(
    ranks: usize,
    exe: &Path,
    args: &[&str],
    env: &[(&str, &str)],
    timeout: Duration,
) -> Output {
    let _serial = SERIAL.lock().unwrap_or_else(|p| p.into_inner());
    let job = Job::start(Some(ranks), exe, args, env);
    job.wait(timeout)
}

/// A launched job (its own session) whose output is being collected. Dropped without
/// [`Job::wait`] (a test that failed while it ran), it kills every process of the job.
pub struct Job {
    child: std::process::Child,
    session: Session,
    label: String,
    stdout: thread::JoinHandle<Vec<u8>>,
    stderr: thread::JoinHandle<Vec<u8>>,
}

/// The session of a job, whose id is the launcher's pid. OpenMPI puts every rank in a
/// process group of its own, so only the session holds the launcher and all its ranks
/// together, even once a rank outlives the launcher and is re-parented. Ended on drop.
struct Session(i32);

impl Drop for Session {
    fn drop(&mut self) {
        end_session(self.0);
    }
}

impl Job {
    /// Starts `exe args...` under the launcher with `ranks` ranks, or directly (a serial
    /// run without MPI launcher) for `None`, in a new session.
    pub fn start(ranks: Option<usize>, exe: &Path, args: &[&str], env: &[(&str, &str)]) -> Job {
        let launcher = std::env::var("MPIEXEC").unwrap_or_else(|_| "mpirun".to_string());
        let mut cmd = match ranks {
            Some(n) => {
                let mut c = Command::new(&launcher);
                c.arg("-n").arg(n.to_string()).arg(exe);
                c
            }
            None => Command::new(exe),
        };
        cmd.args(args);
        for (k, v) in LAUNCH_ENV.iter().chain(env) {
            cmd.env(k, v);
        }
        // SAFETY: setsid is async-signal-safe, as code between fork and exec must be; the
        // child is then the leader of a new session whose id is its pid, from before exec.
        unsafe {
            cmd.pre_exec(|| {
                if libc::setsid() < 0 {
                    return Err(std::io::Error::last_os_error());
                }
                Ok(())
            });
        }
        cmd.stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        let label = match ranks {
            Some(n) => format!("{launcher} -n {n} {}", exe.display()),
            None => exe.display().to_string(),
        };
        let mut child = cmd
            .spawn()
            .unwrap_or_else(|e| panic!("cannot start {label}: {e}"));
        let session = Session(child.id() as i32);
        let stdout = drain(child.stdout.take());
        let stderr = drain(child.stderr.take());
        Job {
            child,
            session,
            label,
            stdout,
            stderr,
        }
    }

    /// Whether the job is still running.
    pub fn running(&mut self) -> bool {
        matches!(self.child.try_wait(), Ok(None))
    }

    /// The pids and command names of the job's live processes: the launcher and every
    /// rank, wherever they have been re-parented.
    pub fn processes(&self) -> Vec<(i32, String)> {
        processes_of_session(self.session.0)
    }

    /// Sends `signal` (TERM, USR1 or KILL) to the launcher only, or with `whole_job` to the
    /// launcher and every rank.
    pub fn signal(&self, signal: &str, whole_job: bool) {
        if whole_job {
            signal_session(self.session.0, signal);
        } else {
            send(self.session.0, signal);
        }
    }

    /// Waits for the job to end (killing it after `timeout`, which fails the test) and
    /// returns its output.
    pub fn wait(mut self, timeout: Duration) -> Output {
        let start = Instant::now();
        let status = loop {
            match self.child.try_wait() {
                Ok(Some(status)) => break Some(status),
                Ok(None) if start.elapsed() < timeout => thread::sleep(Duration::from_millis(50)),
                Ok(None) => break None,
                Err(e) => panic!("waiting for {}: {e}", self.label),
            }
        };
        let Some(status) = status else {
            // Where each process waits says more about a deadlock than that it happened.
            let stacks = stacks_of_session(self.session.0);
            signal_session(self.session.0, "TERM");
            thread::sleep(Duration::from_secs(2));
            drop(self.session); // ends it
            let _ = self.child.kill();
            let _ = self.child.wait();
            let out = String::from_utf8_lossy(&join(self.stdout)).into_owned();
            let err = String::from_utf8_lossy(&join(self.stderr)).into_owned();
            panic!(
                "{} did not finish within {timeout:?} (deadlock?); killed.\n\
                 --- stdout ---\n{out}\n--- stderr ---\n{err}\n--- stacks ---\n{stacks}",
                self.label
            );
        };
        // A rank left behind by the launcher (after a kill of the launcher alone, say) would
        // go on writing the job's files under the next run, and hold the output pipes open:
        // the session ends here, before the pipes are read to their end.
        drop(self.session);
        Output {
            status,
            stdout: join(self.stdout),
            stderr: join(self.stderr),
        }
    }
}

/// Relaunches the current test executable under MPI, running only `test_name` in every
/// rank with `MUFE_MPI_CHILD=1` plus `env`.
pub fn relaunch_test(
    test_name: &str,
    ranks: usize,
    env: &[(&str, &str)],
    timeout: Duration,
) -> Output {
    let exe = std::env::current_exe().expect("path of the test executable");
    let mut all_env: Vec<(&str, &str)> = vec![(CHILD_ENV, "1")];
    all_env.extend_from_slice(env);
    run_under_mpirun(
        ranks,
        &exe,
        &["--exact", test_name, "--nocapture", "--test-threads=1"],
        &all_env,
        timeout,
    )
}

/// `mufe run SCENE` (a path relative to the crate) on `ranks` ranks with one thread each
/// into a fresh temporary directory named after `name`; panics unless it succeeds.
/// Returns the output directory and the job's stdout.
pub fn run_scene(scene: &str, ranks: usize, name: &str) -> (std::path::PathBuf, String) {
    let out = std::env::temp_dir().join(format!("mufe_{name}_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join(scene);
    let args = [
        "run",
        scene.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--threads",
        "1",
    ];
    let o = run_mufe(ranks, &args, Duration::from_secs(300));
    assert_success(&o);
    (out, String::from_utf8_lossy(&o.stdout).into_owned())
}

/// Panics with the job's output unless it exited successfully.
pub fn assert_success(out: &Output) {
    assert!(
        out.status.success(),
        "MPI job failed ({}).\n--- stdout ---\n{}\n--- stderr ---\n{}",
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

fn drain(pipe: Option<impl Read + Send + 'static>) -> thread::JoinHandle<Vec<u8>> {
    thread::spawn(move || {
        let mut buf = Vec::new();
        if let Some(mut p) = pipe {
            let _ = p.read_to_end(&mut buf);
        }
        buf
    })
}

fn join(handle: thread::JoinHandle<Vec<u8>>) -> Vec<u8> {
    handle.join().unwrap_or_default()
}

/// The live processes of `session` as (pid, command name), read from `/proc` (field 6 of
/// `stat` is the session; a zombie, dead but not yet reaped by whoever adopted it, writes
/// nothing and is left out).
fn processes_of_session(session: i32) -> Vec<(i32, String)> {
    let Ok(dir) = std::fs::read_dir("/proc") else {
        panic!("/proc is not readable: the MPI tests need Linux");
    };
    let mut found = Vec::new();
    for entry in dir.flatten() {
        let Some(pid) = entry
            .file_name()
            .to_str()
            .and_then(|n| n.parse::<i32>().ok())
        else {
            continue;
        };
        let Ok(stat) = std::fs::read_to_string(format!("/proc/{pid}/stat")) else {
            continue; // ended meanwhile
        };
        // "pid (comm) state ppid pgrp session ...": comm may hold spaces and parentheses
        let (Some(open), Some(close)) = (stat.find('('), stat.rfind(')')) else {
            continue;
        };
        let fields: Vec<&str> = stat[close + 1..].split_whitespace().collect();
        let state = fields.first().copied();
        let in_session = fields.get(3).and_then(|f| f.parse::<i32>().ok()) == Some(session);
        if in_session && !matches!(state, None | Some("Z")) {
            found.push((pid, stat[open + 1..close].to_string()));
        }
    }
    found
}

/// The thread stacks of every process in `session` (the launcher and its ranks), from
/// `gdb -batch`; where none come back (gdb missing, attaching not permitted) the reason
/// gdb gave. Each attach is bounded so that a stuck debugger cannot hang the test in turn.
fn stacks_of_session(session: i32) -> String {
    let mut report = String::new();
    for (pid, comm) in processes_of_session(session) {
        let bt = Command::new("timeout")
            .args([
                "-k",
                "5",
                "30",
                "gdb",
                "-p",
                &pid.to_string(),
                "-batch",
                "-nx",
            ])
            .args(["-ex", "thread apply all bt"])
            .stdin(Stdio::null())
            .output();
        let text = match bt {
            Ok(o) => {
                // Only the frames: gdb's banner and symbol-loading chatter are noise here.
                let frames: String = String::from_utf8_lossy(&o.stdout)
                    .lines()
                    .filter(|l| l.starts_with('#') || l.starts_with("Thread "))
                    .map(|l| format!("{l}\n"))
                    .collect();
                if frames.is_empty() {
                    let why = String::from_utf8_lossy(&o.stderr);
                    let last = why.lines().rev().find(|l| !l.trim().is_empty());
                    format!(
                        "(no stack: gdb {}: {})\n",
                        o.status,
                        last.unwrap_or("no message")
                    )
                } else {
                    frames
                }
            }
            Err(e) => format!("(no stack: gdb could not be run: {e})\n"),
        };
        report.push_str(&format!("pid {pid} ({comm}):\n{text}"));
    }
    report
}

/// Sends `signal` (TERM, USR1 or KILL) to process `pid`.
fn send(pid: i32, signal: &str) {
    let number = match signal {
        "TERM" => libc::SIGTERM,
        "USR1" => libc::SIGUSR1,
        "KILL" => libc::SIGKILL,
        other => panic!("no signal {other} in the test harness"),
    };
    // SAFETY: kill(2) has no memory effects; a pid that has ended meanwhile gives ESRCH.
    unsafe {
        libc::kill(pid, number);
    }
}

/// Signals every live process of the session we created for the launcher.
fn signal_session(session: i32, signal: &str) {
    for (pid, _) in processes_of_session(session) {
        send(pid, signal);
    }
}

/// Kills whatever is left of `session` and waits until it is gone, so the next run never
/// shares the output directory with a survivor of this one. Panics (unless already
/// unwinding) if a process outlives 30 s of SIGKILL, which only an unkillable process does.
fn end_session(session: i32) {
    let start = Instant::now();
    loop {
        let left = processes_of_session(session);
        if left.is_empty() {
            return;
        }
        if start.elapsed() > Duration::from_secs(30) {
            if !thread::panicking() {
                panic!("still running 30 s after SIGKILL: {left:?}");
            }
            return;
        }
        signal_session(session, "KILL");
        thread::sleep(Duration::from_millis(20));
    }
}

/// Holds this test binary's one-job-at-a-time lock (for tests that drive a [`Job`]).
pub fn exclusive() -> std::sync::MutexGuard<'static, ()> {
    SERIAL.lock().unwrap_or_else(|p| p.into_inner())
}
