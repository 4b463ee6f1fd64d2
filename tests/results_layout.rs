//! `results.h5` of a two-rank run with migration is exactly what docs/RESULTS.md says
//! (checked by `scripts/check_results_layout.py` with h5py: every object documented, every
//! documented object present, shapes, dtypes, units and attributes as stated), every frame
//! write was collective, the per-frame owners show the migration, and the frames hold the
//! same values as a one-rank run's.
//!
//! How to run: `cargo test --release --test results_layout` (needs `mpirun` and a python3
//! with h5py, found by `scripts/h5python`).

#[path = "common/mpi_launch.rs"]
mod mpi_launch;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

const MANIFEST: &str = env!("CARGO_MANIFEST_DIR");
/// Conditions of docs/RESULTS.md that hold for jobs/tests/assembly.toml.
const EXPECT: &str = "frames,walls,contact,grain-contact";

fn out_dir(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("results_layout")
        .join(name);
    let _ = std::fs::remove_dir_all(&d);
    d
}

/// 300 steps of the assembly with a frame every 2e-7 s (5–6 frames, by the step) and re-partitioning at
/// steps 100 and 200, so grains change ranks between frames.
fn run(ranks: usize, name: &str) -> (PathBuf, String) {
    let out = out_dir(name);
    let scene = Path::new(MANIFEST).join("jobs/tests/assembly.toml");
    let args = [
        "run",
        scene.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--max-steps",
        "300",
        "--set",
        "output.frame_interval=2e-7",
        "--set",
        "parallel.imbalance_threshold=0.0",
        "--set",
        "parallel.check_interval=100",
    ];
    let output = mpi_launch::run_mufe(ranks, &args, Duration::from_secs(240));
    mpi_launch::assert_success(&output);
    let stdout = String::from_utf8_lossy(&output.stdout).into_owned();
    (out.join("results.h5"), stdout)
}

/// Runs the layout checker; `Err(its output)` when it finds problems.
fn check_layout(h5: &Path, doc: &Path) -> Result<String, String> {
    let script = Path::new(MANIFEST).join("scripts/check_results_layout.py");
    let out = Command::new(Path::new(MANIFEST).join("scripts/h5python"))
        .arg(&script)
        .arg(h5)
        .arg("--doc")
        .arg(doc)
        .arg("--expect")
        .arg(EXPECT)
        .output()
        .expect("scripts/h5python runs");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        !text.contains("No module named 'h5py'"),
        "the layout check needs h5py: pip install h5py (or apt install python3-h5py)"
    );
    if out.status.success() {
        Ok(text)
    } else {
        Err(text)
    }
}

fn read(f: &hdf5::File, path: &str) -> Vec<f64> {
    f.dataset(path)
        .unwrap_or_else(|e| panic!("{path}: {e}"))
        .read_raw::<f64>()
        .unwrap()
}

fn last_frame(f: &hdf5::File) -> String {
    let mut frames = f.group("frames").unwrap().member_names().unwrap();
    frames.sort();
    frames.pop().unwrap()
}

#[test]
fn two_rank_results_match_the_documented_layout_and_the_serial_frames() {
    let (path, stdout) = run(2, "r2");

    // every frame dataset was written with a collective MPI-IO transfer (as HDF5 reports
    // it), summed over both ranks: frames × 17 datasets × 2 ranks
    let f = hdf5::File::open(&path).unwrap();
    let in_file = f.group("frames").unwrap().member_names().unwrap().len() as u64;
    drop(f);
    assert!(in_file >= 2, "frames in the file: {in_file}");
    assert!(
        stdout.contains(&format!(
            "results.h5: {in_file} frames written by 2 rank(s)"
        )),
        "{stdout}"
    );
    let counts = stdout
        .split("collective MPI-IO writes: frames ")
        .nth(1)
        .and_then(|s| s.split(',').next())
        .unwrap_or_else(|| panic!("no write report: {stdout}"));
    let (ok, all) = counts.split_once('/').unwrap();
    assert_eq!(ok, all, "every frame write collective: {counts}");
    assert_eq!(
        all.trim().parse::<u64>().unwrap(),
        in_file * 17 * 2,
        "{counts}"
    );
    assert!(stdout.contains("re-partitioned at step 100"), "{stdout}");

    // a job's log gets plain progress lines, not a live bar, although Open MPI hands each
    // rank a pseudo-terminal even when the job's output goes to a pipe or file
    assert!(
        !stdout.contains('\r'),
        "live progress bar in a job log: {stdout}"
    );
    assert!(
        stdout
            .lines()
            .any(|l| l.contains("% t = ") && l.contains(" step ")),
        "no progress line: {stdout}"
    );

    // the file against docs/RESULTS.md
    let doc = Path::new(MANIFEST).join("docs/RESULTS.md");
    let report = check_layout(&path, &doc).unwrap_or_else(|e| panic!("{e}"));
    assert!(report.contains("objects match"), "{report}");

    // the checker is not vacuous: an undocumented dataset or a changed unit is caught
    let text = std::fs::read_to_string(&doc).unwrap();
    let dir = path.parent().unwrap();
    let without_velocity: String = text
        .lines()
        .filter(|l| !l.starts_with("| `/frames/NNNNNN/velocity`"))
        .map(|l| format!("{l}\n"))
        .collect();
    let doc_missing = dir.join("RESULTS_missing.md");
    std::fs::write(&doc_missing, without_velocity).unwrap();
    let e = check_layout(&path, &doc_missing).expect_err("an undocumented dataset fails");
    assert!(e.contains("velocity: not documented"), "{e}");
    let mm = text.replace(
        "| `/mesh/nodes` | dataset | `(N, 3)` | f64 | `m` |",
        "| `/mesh/nodes` | dataset | `(N, 3)` | f64 | `mm` |",
    );
    assert_ne!(mm, text, "the /mesh/nodes row is where the test expects it");
    let doc_units = dir.join("RESULTS_units.md");
    std::fs::write(&doc_units, mm).unwrap();
    let e = check_layout(&path, &doc_units).expect_err("a changed unit fails");
    assert!(e.contains("/mesh/nodes: units 'm', documented 'mm'"), "{e}");

    // migration shows in the per-frame owners: grains changed ranks after frame 0
    let f = hdf5::File::open(&path).unwrap();
    let initial: Vec<u32> = f
        .dataset("mesh/owner_rank_of_grain")
        .unwrap()
        .read_raw()
        .unwrap();
    let first: Vec<f64> = read(&f, "frames/000000/owner_rank_of_grain");
    assert!(
        initial.iter().zip(&first).all(|(&a, &b)| a as f64 == b),
        "frame 0 has the initial owners"
    );
    let last = last_frame(&f);
    let owners = read(&f, &format!("frames/{last}/owner_rank_of_grain"));
    assert_ne!(owners, first, "some grain migrated");
    // the per-element owner agrees with the per-grain owner of the element's grain
    let grain: Vec<u32> = f
        .dataset("mesh/grain_of_element")
        .unwrap()
        .read_raw()
        .unwrap();
    let element_owner = read(&f, &format!("frames/{last}/owner_rank"));
    assert!(grain
        .iter()
        .zip(&element_owner)
        .all(|(&g, &r)| owners[g as usize] == r));

    // the same frames on one rank: every field of every frame but the owners
    let (serial_path, _) = run(1, "r1");
    let s = hdf5::File::open(&serial_path).unwrap();
    let mut frames = f.group("frames").unwrap().member_names().unwrap();
    frames.sort();
    assert_eq!(
        frames,
        {
            let mut v = s.group("frames").unwrap().member_names().unwrap();
            v.sort();
            v
        },
        "same frames"
    );
    for frame in &frames {
        let group = f.group(&format!("frames/{frame}")).unwrap();
        for name in group.member_names().unwrap() {
            if name.starts_with("owner_rank") {
                continue;
            }
            let path = format!("frames/{frame}/{name}");
            let (a, b) = (read(&s, &path), read(&f, &path));
            assert_eq!(a.len(), b.len(), "{path}: rows");
            let scale = a.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            for (i, (x, y)) in a.iter().zip(&b).enumerate() {
                assert!(
                    (x - y).abs() <= 1e-12 * scale,
                    "{path}[{i}]: 2 ranks {y:e}, 1 rank {x:e}"
                );
            }
        }
    }
    for name in ["nodes", "tetrahedra", "grain_of_element"] {
        let path = format!("mesh/{name}");
        let (a, b) = (
            s.dataset(&path).unwrap().read_raw::<f64>().unwrap(),
            f.dataset(&path).unwrap().read_raw::<f64>().unwrap(),
        );
        assert_eq!(a, b, "{path}");
    }
}
