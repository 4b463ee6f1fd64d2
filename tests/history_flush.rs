//! History as it happens: a run killed with SIGKILL keeps the history rows written up to
//! its last flush (`output.flush_interval`, wall-clock seconds), and its `results.h5`
//! stays readable. Without the periodic flush the rows of a run without frames stay in
//! memory until the end, and a killed run leaves `/history` empty.
//!
//! A kill that lands while HDF5 writes out a flush's metadata can leave the columns of
//! that last flush at different lengths (each column is its own dataset, and their new
//! extents reach the file one after another; docs/RESULTS.md): the rows up to the
//! shortest column are the complete ones, and that is what is checked.

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

#[test]
fn a_killed_run_keeps_its_history_up_to_the_last_flush() {
    let out = std::env::temp_dir().join(format!("mufe_history_flush_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let mut child = Command::new(env!("CARGO_BIN_EXE_mufe"))
        .args([
            "run",
            "jobs/bench/assembly_64.toml",
            "--quiet",
            "--threads",
            "1",
        ])
        .args([
            "--set",
            "output.frames=false",
            "--set",
            "output.flush_interval=0.25",
        ])
        .args(["--set", "output.history_interval=2e-9"])
        .arg("--out")
        .arg(&out)
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("mufe starts");
    let results = out.join("results.h5");
    let t0 = Instant::now();
    while !results.exists() && t0.elapsed() < Duration::from_secs(60) {
        std::thread::sleep(Duration::from_millis(100));
    }
    assert!(results.exists(), "no results.h5 after 60 s");
    // several flush intervals of stepping
    std::thread::sleep(Duration::from_secs(4));
    if let Some(status) = child.try_wait().unwrap() {
        let mut err = String::new();
        std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut err).unwrap();
        panic!("the run ended ({status}) before it could be killed: {err}");
    }
    child.kill().unwrap(); // SIGKILL: no chance to write anything more
    child.wait().unwrap();

    let f = hdf5::File::open(&results).expect("a killed run's results.h5 is readable");
    let history = f.group("history").unwrap();
    let columns = history.member_names().unwrap();
    assert!(columns.len() > 2, "history columns: {columns:?}");
    let lengths: Vec<usize> = (columns.iter())
        .map(|c| history.dataset(c).unwrap().shape()[0])
        .collect();
    let complete = *lengths.iter().min().unwrap();
    assert!(
        complete >= 2,
        "{complete} complete history rows survived the kill"
    );
    // at most the last flush is partial: its rows are far fewer than those before it
    let longest = *lengths.iter().max().unwrap();
    assert!(
        longest - complete < complete,
        "columns from {complete} to {longest} rows: more than the last flush is missing"
    );
    let time: Vec<f64> = f.dataset("history/time").unwrap().read_raw().unwrap();
    let time = &time[..complete];
    assert!(time.windows(2).all(|w| w[1] > w[0]), "rows out of order");
    let energy: Vec<f64> = f
        .dataset("history/energy_balance")
        .unwrap()
        .read_raw()
        .unwrap();
    assert!(energy[..complete].iter().all(|e| e.is_finite()));
    drop(f);
    let _ = std::fs::remove_dir_all(&out);
}
