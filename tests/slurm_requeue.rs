//! `jobs/cluster/slurm_run.sh` requeues itself (issue 13, item 7), exercised without Slurm:
//! the script runs as the batch shell would (SLURM_JOB_ID set, a stand-in `scontrol` on
//! PATH that records its arguments), gets Slurm's early-warning SIGUSR1 while mufe runs,
//! must make mufe write a checkpoint and stop, and call `scontrol requeue JOBID`; run again
//! (the requeued job) it continues from the latest checkpoint, and the pieces together give
//! the history of an uninterrupted run bitwise.

#[path = "common/mpi_launch.rs"]
mod mpi_launch;
#[path = "common/results.rs"]
mod results;

use mpi_launch::Job;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn dir(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("slurm_requeue")
        .join(name);
    let _ = std::fs::remove_dir_all(&d);
    d
}

const EXTRA: &str = "--quiet --max-steps 1200 --checkpoint-every 200";

#[test]
fn the_job_script_stops_mufe_requeues_and_resumes() {
    let scene = root().join("jobs/tests/assembly.toml");
    let scene = scene.to_str().unwrap();
    let script = root().join("jobs/cluster/slurm_run.sh");
    let fake = dir("bin");
    std::fs::create_dir_all(&fake).unwrap();
    let log = fake.join("scontrol.log");
    std::fs::write(
        fake.join("scontrol"),
        format!("#!/bin/sh\necho \"$@\" >> {}\n", log.display()),
    )
    .unwrap();
    std::process::Command::new("chmod")
        .args(["+x", fake.join("scontrol").to_str().unwrap()])
        .status()
        .unwrap();
    let path = format!(
        "{}:{}",
        fake.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let mufe = env!("CARGO_BIN_EXE_mufe");
    let env = [
        ("PATH", path.as_str()),
        ("SLURM_JOB_ID", "4242"),
        ("MUFE", mufe),
        ("MUFE_EXTRA_ARGS", EXTRA),
    ];
    let out = dir("run");
    let args = [script.to_str().unwrap(), scene, out.to_str().unwrap()];

    // first piece: the early warning arrives once the run has written a checkpoint
    let _one = mpi_launch::exclusive();
    let mut job = Job::start(None, Path::new("bash"), &args, &env);
    let first = out.join("checkpoints/step_000000000200.h5");
    let start = Instant::now();
    while !first.is_file() && job.running() {
        assert!(start.elapsed() < Duration::from_secs(120), "no checkpoint");
        std::thread::sleep(Duration::from_millis(20));
    }
    assert!(job.running(), "the job is still running at the warning");
    job.signal("USR1", false);
    let o = job.wait(Duration::from_secs(120));
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(o.status.success(), "the script ends cleanly: {text}");
    assert!(
        text.contains("stopped: SIGUSR1"),
        "mufe stopped on the signal: {text}"
    );
    let requeued = std::fs::read_to_string(&log).unwrap_or_default();
    assert_eq!(requeued.trim(), "requeue 4242", "{text}");

    // second piece: the requeued job continues and finishes
    let o = Job::start(None, Path::new("bash"), &args, &env).wait(Duration::from_secs(240));
    let text = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(
        o.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(
        text.contains("continuing from the latest checkpoint"),
        "{text}"
    );
    drop(_one);

    // the same run in one piece
    let whole = dir("whole");
    let mut whole_args = vec![
        "run",
        scene,
        "--out",
        whole.to_str().unwrap(),
        "--threads",
        "1",
        "--set",
        "output.checkpoint_interval=1800",
    ];
    whole_args.extend(EXTRA.split(' '));
    let o = mpi_launch::run_mufe(1, &whole_args, Duration::from_secs(240));
    mpi_launch::assert_success(&o);
    let (a, b) = (
        results::history(&whole.join("results.h5")),
        results::history(&out.join("results.h5")),
    );
    assert_eq!(a.len(), b.len());
    for ((name, x), (_, y)) in a.iter().zip(&b) {
        assert_eq!(x.len(), y.len(), "/history/{name}: rows");
        assert!(
            x.iter().zip(y).all(|(p, q)| p.to_bits() == q.to_bits()),
            "/history/{name} differs from the uninterrupted run"
        );
    }
}
