//! Checkpoints against faults and changes (issue 13, items 4, 6, 8), on the elastic–plastic
//! variant of `jobs/tests/assembly.toml` (27 spheres, contacts straddling the ranks, a
//! moving wall, plastic state at the contacts):
//! - a 2-rank checkpoint restarted on 1 and 3 ranks (grains re-partitioned) ends with the
//!   2-rank run's history to 1e-10;
//! - `--restart latest` skips a damaged newest checkpoint (named on stderr) and continues
//!   bitwise from the older one; with none valid it is one line and exit 2;
//! - `kill -9` of a running job (serial, and every process of a 2-rank job), then
//!   `--restart latest`, ends equal to the uninterrupted run with no row lost or repeated;
//! - SIGTERM (serial) and SIGUSR1 to `mpirun` (2 ranks) stop the run with a checkpoint and
//!   a readable `results.h5`, and the restart ends equal to the uninterrupted run;
//! - a changed scene is refused naming the first difference (output settings and the end
//!   time may change), and so is a `results.h5` of another format version; `--branch`
//!   starts a new run from the checkpoint with other physics, but not with other grains.

#[path = "common/mpi_launch.rs"]
mod mpi_launch;
#[path = "common/results.rs"]
mod results;

use mpi_launch::Job;
use results::history;
use std::path::{Path, PathBuf};
use std::process::Output;
use std::sync::OnceLock;
use std::time::{Duration, Instant};

const PLASTIC: [&str; 4] = [
    "--set",
    "materials.glass.yield_stress=1e8",
    "--set",
    "materials.glass.hardening_modulus=1e9",
];

fn scene() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("jobs/tests/assembly.toml")
        .to_string_lossy()
        .into_owned()
}

fn dir(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("checkpoint_faults")
        .join(name);
    let _ = std::fs::remove_dir_all(&d);
    d
}

/// `mufe run ASSEMBLY --out OUT ARGS PLASTIC` on `ranks` ranks (1: under mpirun too).
fn mufe(ranks: usize, out: &Path, args: &[&str]) -> Output {
    mufe_with_scene(ranks, &scene(), out, args)
}

/// `mufe run SCENE --out OUT ARGS PLASTIC` on `ranks` ranks.
fn mufe_with_scene(ranks: usize, s: &str, out: &Path, args: &[&str]) -> Output {
    let mut all = vec![
        "run",
        s,
        "--threads",
        "1",
        "--quiet",
        "--out",
        out.to_str().unwrap(),
    ];
    all.extend_from_slice(args);
    all.extend_from_slice(&PLASTIC);
    mpi_launch::run_mufe(ranks, &all, Duration::from_secs(240))
}

fn copy_dir(from: &Path, to: &Path) {
    let _ = std::fs::remove_dir_all(to);
    let ok = std::process::Command::new("cp")
        .args(["-a", from.to_str().unwrap(), to.to_str().unwrap()])
        .status()
        .unwrap()
        .success();
    assert!(ok, "copying {}", from.display());
}

fn checkpoint(out: &Path, step: u64) -> PathBuf {
    out.join(format!("checkpoints/step_{step:012}.h5"))
}

/// Every `/history` series of `b` equals `a`'s: bitwise (`tol` = 0) or to `tol` relative
/// to the series' largest value; same rows.
fn assert_same_history(a: &Path, b: &Path, tol: f64, what: &str) {
    let (x, y) = (history(a), history(b));
    assert_eq!(x.len(), y.len(), "{what}: columns");
    for ((name, p), (name_b, q)) in x.iter().zip(&y) {
        assert_eq!(name, name_b);
        assert_eq!(p.len(), q.len(), "{what}: /history/{name} rows");
        let scale = p.iter().map(|v| v.abs()).fold(0.0, f64::max);
        for (i, (u, v)) in p.iter().zip(q).enumerate() {
            let ok = if tol == 0.0 {
                u.to_bits() == v.to_bits()
            } else {
                (u - v).abs() <= tol * scale.max(1e-300)
            };
            assert!(ok, "{what}: /history/{name}[{i}] = {v:e}, expected {u:e}");
        }
    }
}

const STEPS: &str = "300";

/// The 2-rank reference: 300 steps, checkpoints at 150 and 300.
fn two_rank_reference() -> &'static PathBuf {
    static REFERENCE: OnceLock<PathBuf> = OnceLock::new();
    REFERENCE.get_or_init(|| {
        let d = dir("reference2");
        let o = mufe(2, &d, &["--max-steps", STEPS, "--checkpoint-every", "150"]);
        mpi_launch::assert_success(&o);
        assert!(checkpoint(&d, 150).is_file() && checkpoint(&d, 300).is_file());
        d
    })
}

#[test]
fn a_two_rank_checkpoint_restarts_on_one_and_three_ranks() {
    let reference = two_rank_reference();
    for ranks in [1, 3] {
        let d = dir(&format!("to{ranks}"));
        copy_dir(reference, &d);
        let from = checkpoint(&d, 150);
        let o = mufe(
            ranks,
            &d,
            &["--max-steps", STEPS, "--restart", from.to_str().unwrap()],
        );
        mpi_launch::assert_success(&o);
        assert_same_history(
            &reference.join("results.h5"),
            &d.join("results.h5"),
            1e-10,
            &format!("2 → {ranks} ranks"),
        );
        let f = hdf5::File::open(d.join("results.h5")).unwrap();
        let note: hdf5::types::VarLenUnicode = f
            .group("provenance")
            .unwrap()
            .attr("restart_0")
            .unwrap()
            .read_scalar()
            .unwrap();
        assert!(
            note.as_str().contains("written by 2 ranks")
                && note.contains(&format!("on {ranks} ranks")),
            "/provenance records the restart: {note}"
        );
        // the continued file still matches docs/RESULTS.md
        results::assert_matches_documented_layout(&d.join("results.h5"), "");
    }
}

#[test]
fn latest_skips_a_damaged_newest_checkpoint() {
    let reference = two_rank_reference();
    let d = dir("damaged");
    copy_dir(reference, &d);
    // a checkpoint cut short (e.g. a full disk under a non-atomic copy)
    let newest = checkpoint(&d, 300);
    let len = std::fs::metadata(&newest).unwrap().len();
    let f = std::fs::OpenOptions::new()
        .write(true)
        .open(&newest)
        .unwrap();
    f.set_len(len / 2).unwrap();
    drop(f);
    let o = mufe(2, &d, &["--max-steps", STEPS, "--restart", "latest"]);
    mpi_launch::assert_success(&o);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("skipping damaged checkpoint") && err.contains("step_000000000300.h5"),
        "the damaged file is named: {err}"
    );
    assert_same_history(
        &reference.join("results.h5"),
        &d.join("results.h5"),
        0.0,
        "restart from the older checkpoint",
    );

    // every checkpoint damaged: one line, exit 2
    for step in [150, 300] {
        let p = checkpoint(&d, step);
        if p.is_file() {
            let len = std::fs::metadata(&p).unwrap().len();
            let f = std::fs::OpenOptions::new().write(true).open(&p).unwrap();
            f.set_len(len / 3).unwrap();
        }
    }
    let o = mufe(2, &d, &["--max-steps", STEPS, "--restart", "latest"]);
    assert_eq!(
        o.status.code(),
        Some(2),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let err = String::from_utf8_lossy(&o.stderr);
    let errors: Vec<&str> = err.lines().filter(|l| l.starts_with("error")).collect();
    assert!(
        !errors.is_empty() && errors.iter().all(|l| l.contains("step_000000000150.h5")),
        "one line naming the oldest file: {err}"
    );

    // no checkpoint at all
    let empty = dir("no_checkpoint");
    let o = mufe(1, &empty, &["--max-steps", STEPS, "--restart", "latest"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("no checkpoint"));
}

#[test]
fn a_changed_scene_is_refused_and_a_branch_starts_a_new_run() {
    let reference = two_rank_reference();
    let d = dir("branch_source");
    copy_dir(reference, &d);
    let from = checkpoint(&d, 150);
    let from = from.to_str().unwrap();
    // physics changed: refused, naming the first difference
    let o = mufe(2, &d, &["--restart", from, "--set", "contact.friction=0.5"]);
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("first difference: contact.friction = 0.3") && err.contains("--branch"),
        "{err}"
    );
    // a branch keeps the grains: a scene without the last one is refused, on the
    // checkpoint's rank count and on another, naming the grain counts
    let text = std::fs::read_to_string(scene()).unwrap();
    let last = text.rfind("[[grains]]").unwrap();
    let fewer = d.with_file_name("assembly_26_grains.toml");
    std::fs::write(&fewer, &text[..last]).unwrap();
    for ranks in [2, 1] {
        let out = dir(&format!("branch_fewer_grains_{ranks}"));
        let o = mufe_with_scene(
            ranks,
            fewer.to_str().unwrap(),
            &out,
            &["--restart", from, "--branch", "--max-steps", STEPS],
        );
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{ranks} ranks: {err}");
        assert!(
            err.contains("grains: the checkpoint holds 27 grains")
                && err.contains("has 26; a restart or branch needs the same grains"),
            "{ranks} ranks: {err}"
        );
    }
    // a results file of another layout version is not continued
    let other = dir("other_results_version");
    copy_dir(&d, &other);
    {
        let f = hdf5::File::open_rw(other.join("results.h5")).unwrap();
        f.attr("format_version")
            .unwrap()
            .write_scalar(&99u64)
            .unwrap();
    }
    let o = mufe(
        2,
        &other,
        &["--restart", checkpoint(&other, 150).to_str().unwrap()],
    );
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("results.h5: format_version: format 99"),
        "{err}"
    );
    // output settings and the end time may change
    let o = mufe(
        2,
        &d,
        &[
            "--restart",
            from,
            "--max-steps",
            STEPS,
            "--set",
            "simulation.duration=4e-5",
            "--set",
            "output.flush_interval=5",
        ],
    );
    mpi_launch::assert_success(&o);
    assert_same_history(
        &reference.join("results.h5"),
        &d.join("results.h5"),
        0.0,
        "restart with a later end time",
    );
    // a branch: new --out, other friction, recorded in /provenance
    let b = dir("branch");
    let o = mufe(
        2,
        &b,
        &[
            "--restart",
            from,
            "--branch",
            "--max-steps",
            STEPS,
            "--set",
            "contact.friction=0.5",
        ],
    );
    mpi_launch::assert_success(&o);
    let f = hdf5::File::open(b.join("results.h5")).unwrap();
    let note: hdf5::types::VarLenUnicode = f
        .group("provenance")
        .unwrap()
        .attr("branch_0")
        .unwrap()
        .read_scalar()
        .unwrap();
    assert!(note.as_str().contains("step_000000000150.h5"), "{note}");
    let h = history(&b.join("results.h5"));
    let steps = results::column(&h, "step");
    assert!(
        steps.first().is_some_and(|&s| s >= 149.0),
        "the branch starts at the checkpoint: {steps:?}"
    );
    let friction = results::column(&h, "friction_dissipation");
    let reference_h = history(&reference.join("results.h5"));
    let reference_friction = results::column(&reference_h, "friction_dissipation");
    assert_ne!(
        friction.last(),
        reference_friction.last(),
        "the branch runs with the other friction"
    );
}

/// `mufe run ASSEMBLY` for `steps` steps with a checkpoint every 200 into `out`, followed by
/// `more` arguments.
fn long_run_args<'a>(
    scene: &'a str,
    out: &'a Path,
    steps: &'a str,
    more: &[&'a str],
) -> Vec<&'a str> {
    let mut args = vec![
        "run",
        scene,
        "--threads",
        "1",
        "--quiet",
        "--out",
        out.to_str().unwrap(),
        "--max-steps",
        steps,
        "--checkpoint-every",
        "200",
    ];
    args.extend_from_slice(more);
    args.extend_from_slice(&PLASTIC);
    args
}

/// Starts the long run, sends `signal` once the checkpoint of step 200 exists, and
/// returns the job's output.
fn interrupted_run(ranks: Option<usize>, out: &Path, signal: &str, whole_job: bool) -> Output {
    let _one = mpi_launch::exclusive();
    let s = scene();
    let args = long_run_args(&s, out, LONG, &[]);
    let mut job = Job::start(ranks, Path::new(env!("CARGO_BIN_EXE_mufe")), &args, &[]);
    let start = Instant::now();
    while !checkpoint(out, 200).is_file() && job.running() {
        assert!(start.elapsed() < Duration::from_secs(120), "no checkpoint");
        std::thread::sleep(Duration::from_millis(20));
    }
    assert!(
        job.running(),
        "the run is still going when it is interrupted"
    );
    job.signal(signal, whole_job);
    job.wait(Duration::from_secs(120))
}

#[test]
fn a_second_job_in_a_running_jobs_directory_is_refused() {
    let _one = mpi_launch::exclusive();
    let d = dir("in_use");
    // a scene time far beyond what the test lets it run: the first job is still running
    // when the second has started and been refused, however slow the machine
    const LONGER: [&str; 2] = ["--set", "simulation.duration=1.0"];
    let s = scene();
    let exe = Path::new(env!("CARGO_BIN_EXE_mufe"));
    let first_args = long_run_args(&s, &d, "100000000", &LONGER);
    let mut first = Job::start(None, exe, &first_args, &[]);
    let start = Instant::now();
    while !checkpoint(&d, 200).is_file() {
        assert!(start.elapsed() < Duration::from_secs(120), "no checkpoint");
        assert!(first.running(), "the first job runs");
        std::thread::sleep(Duration::from_millis(20));
    }
    let restart = long_run_args(&s, &d, LONG, &["--restart", "latest", LONGER[0], LONGER[1]]);
    let second = Job::start(Some(2), exe, &restart, &[]).wait(Duration::from_secs(120));
    let err = String::from_utf8_lossy(&second.stderr);
    assert_eq!(second.status.code(), Some(2), "{err}");
    // mufe's lines (mpirun adds its own box about the exit code)
    let ours: Vec<&str> = err.lines().filter(|l| l.starts_with("error:")).collect();
    let expected = format!(
        "error: <command line>: --out: '{}' is in use by another running mufe job",
        d.display()
    );
    assert!(
        !ours.is_empty() && ours.iter().all(|l| l.starts_with(&expected)),
        "one line per rank naming the directory: {err}"
    );
    assert!(first.running(), "the first job goes on");
    // the kernel drops the lock of a killed job: its restart is accepted at once
    first.signal("KILL", true);
    let _ = first.wait(Duration::from_secs(60));
    let newest = std::fs::read_dir(d.join("checkpoints"))
        .unwrap()
        .filter_map(|e| {
            let name = e.ok()?.file_name().into_string().ok()?;
            name.strip_prefix("step_")?
                .strip_suffix(".h5")?
                .parse::<u64>()
                .ok()
        })
        .max()
        .expect("the killed job left a checkpoint");
    let end = (newest + 100).to_string();
    let restart = long_run_args(&s, &d, &end, &["--restart", "latest", LONGER[0], LONGER[1]]);
    let o = Job::start(Some(2), exe, &restart, &[]).wait(Duration::from_secs(240));
    mpi_launch::assert_success(&o);
}

const LONG: &str = "1200";

/// The uninterrupted long run on `ranks` ranks (same checkpoints, so the files compare),
/// in a directory of its own per test (`test`): tests run in parallel, and `dir` empties
/// the directory it names, so a shared one could vanish under another test's comparison.
fn whole_long_run(ranks: usize, test: &str) -> PathBuf {
    let d = dir(&format!("whole_long{ranks}_{test}"));
    let o = mufe(
        ranks,
        &d,
        &["--max-steps", LONG, "--checkpoint-every", "200"],
    );
    mpi_launch::assert_success(&o);
    d
}

fn resume_and_compare(ranks: usize, out: &Path, whole: &Path, what: &str) {
    let o = mufe(
        ranks,
        out,
        &[
            "--max-steps",
            LONG,
            "--checkpoint-every",
            "200",
            "--restart",
            "latest",
        ],
    );
    mpi_launch::assert_success(&o);
    assert_same_history(
        &whole.join("results.h5"),
        &out.join("results.h5"),
        0.0,
        what,
    );
}

#[test]
fn a_kill_of_the_whole_job_leaves_no_rank_running() {
    // OpenMPI gives each rank a process group of its own, so a kill of the launcher's group
    // alone left the ranks running on, writing checkpoints and `results.h5` under the
    // restart that followed.
    let _one = mpi_launch::exclusive();
    let mut job = Job::start(Some(2), Path::new("sleep"), &["60"], &[]);
    let start = Instant::now();
    let ranks = |job: &Job| job.processes().iter().filter(|p| p.1 == "sleep").count();
    while ranks(&job) < 2 {
        assert!(start.elapsed() < Duration::from_secs(30), "the ranks start");
        std::thread::sleep(Duration::from_millis(20));
    }
    job.signal("KILL", true);
    // the launcher's exit is reported once its last thread has gone, a moment after
    // its main thread shows as a zombie
    let start = Instant::now();
    while !job.processes().is_empty() || job.running() {
        assert!(
            start.elapsed() < Duration::from_secs(5),
            "still running after kill -9 of the job: {:?}",
            job.processes()
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn kill_9_then_latest_ends_equal_to_the_uninterrupted_run() {
    for ranks in [1, 2] {
        let whole = whole_long_run(ranks, "kill_9");
        let d = dir(&format!("killed{ranks}"));
        let launch = (ranks > 1).then_some(ranks);
        let o = interrupted_run(launch, &d, "KILL", true);
        assert!(!o.status.success(), "the job was killed");
        resume_and_compare(ranks, &d, &whole, &format!("kill -9, {ranks} rank(s)"));
    }
}

#[test]
fn a_stop_signal_writes_a_checkpoint_and_a_readable_file() {
    // serial: SIGTERM to the process
    let whole = whole_long_run(1, "stop_signal");
    let d = dir("sigterm");
    let o = interrupted_run(None, &d, "TERM", false);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(128 + 15), "{err}");
    assert!(err.contains("stopped: SIGTERM at step"), "{err}");
    // the file is closed and readable, and the stop's checkpoint is there
    let h = history(&d.join("results.h5"));
    assert!(!results::column(&h, "time").is_empty());
    let stop_step: u64 = err
        .split("at step ")
        .nth(1)
        .and_then(|r| r.split_whitespace().next())
        .and_then(|n| n.parse().ok())
        .expect("the step is named");
    assert!(checkpoint(&d, stop_step).is_file(), "{err}");
    resume_and_compare(1, &d, &whole, "SIGTERM");

    // 2 ranks: SIGUSR1 to mpirun, which forwards it to every rank
    let whole = whole_long_run(2, "stop_signal");
    let d = dir("sigusr1");
    let o = interrupted_run(Some(2), &d, "USR1", false);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("stopped: SIGUSR1"),
        "{err}"
    );
    resume_and_compare(2, &d, &whole, "SIGUSR1, 2 ranks");
}

/// Stage progress, walls and servo state travel with a re-partition: the staged two-sphere
/// scene with forced re-partitioning on 2 ranks gives the serial history.
#[test]
fn a_staged_run_keeps_its_stage_through_migration() {
    let s = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("jobs/tests/two_spheres_stages.toml")
        .to_string_lossy()
        .into_owned();
    let run = |ranks: usize, name: &str, extra: &[&str]| {
        let d = dir(name);
        let mut args = vec![
            "run",
            s.as_str(),
            "--threads",
            "1",
            "--quiet",
            "--out",
            d.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        let o = mpi_launch::run_mufe(ranks, &args, Duration::from_secs(240));
        mpi_launch::assert_success(&o);
        d
    };
    let serial = run(1, "staged1", &[]);
    let moved = run(
        2,
        "staged2_migrating",
        &[
            "--set",
            "parallel.imbalance_threshold=0.0",
            "--set",
            "parallel.check_interval=3000",
        ],
    );
    assert_same_history(
        &serial.join("results.h5"),
        &moved.join("results.h5"),
        1e-10,
        "staged run with re-partitioning",
    );
}
