//! History as it happens: a run killed with SIGKILL keeps the history rows written up to
//! its last flush (`output.flush_interval`, wall-clock seconds), and its `results.h5`
//! stays readable. Without the periodic flush the rows of a run without frames stay in
//! memory until the end, and a killed run leaves `/history` empty.

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
    let time: Vec<f64> = f.dataset("history/time").unwrap().read_raw().unwrap();
    assert!(
        time.len() >= 2,
        "{} history rows survived the kill",
        time.len()
    );
    assert!(time.windows(2).all(|w| w[1] > w[0]), "rows out of order");
    let energy: Vec<f64> = f
        .dataset("history/energy_balance")
        .unwrap()
        .read_raw()
        .unwrap();
    assert_eq!(energy.len(), time.len(), "columns of different lengths");
    drop(f);
    let _ = std::fs::remove_dir_all(&out);
}
