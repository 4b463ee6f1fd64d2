//! Bad input on the command line (docs/INPUT.md): every case must end with exit code 2 and
//! exactly one line on stderr that names the file (or `<command line>`) and the field or
//! item, with no panic — and a failed `mufe run` must leave an existing output directory
//! exactly as it was. Also: `mufe check` on a valid scene reports the model, and a run with
//! more threads than its CPUs warns (exit 0).
//!
//! Scenes are in `tests/fixtures/` (`valid_small.toml`; `bad/*.toml`, each wrong in one
//! place). Outputs go under `CARGO_TARGET_TMPDIR`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::OnceLock;

const MUFE: &str = env!("CARGO_BIN_EXE_mufe");

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name)
}

fn tmp(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("cli_errors")
        .join(name);
    if dir.exists() {
        std::fs::remove_dir_all(&dir).unwrap();
    }
    std::fs::create_dir_all(dir.parent().unwrap()).unwrap();
    dir
}

fn mufe(args: &[&str]) -> Output {
    Command::new(MUFE)
        .args(args)
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .env("OMPI_MCA_hwloc_base_binding_policy", "none")
        .output()
        .expect("cannot start mufe")
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// Every file under `dir` with its bytes.
fn snapshot(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap() {
            let p = entry.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.insert(p.clone(), std::fs::read(&p).unwrap());
            }
        }
    }
    out
}

/// A real `results.h5` from a successful run of the valid fixture (made once per test
/// binary), to put in output directories that failed runs must not touch.
fn baseline_results() -> &'static [u8] {
    static BASELINE: OnceLock<Vec<u8>> = OnceLock::new();
    BASELINE.get_or_init(|| {
        let out = tmp("baseline");
        let scene = fixture("valid_small.toml");
        let o = mufe(&[
            "run",
            scene.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--threads",
            "1",
            "--quiet",
        ]);
        assert!(
            o.status.success(),
            "baseline run failed: {}{}",
            text(&o.stdout),
            text(&o.stderr)
        );
        let bytes = std::fs::read(out.join("results.h5")).expect("baseline results.h5");
        assert!(!bytes.is_empty());
        bytes
    })
}

/// Asserts the docs/INPUT.md contract for a failed command: exit code 2, one stderr line
/// containing every `needles` entry, no panic text. Returns the line.
fn assert_one_line_error(o: &Output, needles: &[&str]) -> String {
    let err = text(&o.stderr);
    assert_eq!(
        o.status.code(),
        Some(2),
        "expected exit code 2, got {:?}; stderr:\n{err}",
        o.status
    );
    assert!(!err.contains("panicked"), "panic on bad input:\n{err}");
    assert!(
        !err.contains("RUST_BACKTRACE"),
        "panic on bad input:\n{err}"
    );
    let lines: Vec<&str> = err.lines().collect();
    assert_eq!(
        lines.len(),
        1,
        "expected exactly one stderr line, got:\n{err}"
    );
    assert!(
        err.ends_with('\n'),
        "error line must end with a newline: {err:?}"
    );
    let line = lines[0];
    for n in needles {
        assert!(line.contains(n), "error line lacks {n:?}: {line}");
    }
    line.to_string()
}

/// Runs `mufe run <args> --out DIR` where DIR already holds a results file and another
/// file, checks the one-line error, and that DIR is byte-for-byte unchanged. When the
/// scene is a file, `mufe check` must give the same error line.
fn bad_input(case: &str, scene: &Path, extra: &[&str], needles: &[&str]) {
    let out = tmp(case);
    std::fs::create_dir_all(out.join("checkpoints")).unwrap();
    std::fs::write(out.join("results.h5"), baseline_results()).unwrap();
    std::fs::write(out.join("checkpoints/notes.txt"), b"keep me\n").unwrap();
    let before = snapshot(&out);

    let scene_arg = scene.to_str().unwrap();
    let mut args = vec!["run", scene_arg, "--out", out.to_str().unwrap()];
    args.extend_from_slice(extra);
    let o = mufe(&args);
    let line = assert_one_line_error(&o, needles);
    assert!(
        line.starts_with("error: "),
        "error line should start with 'error: ': {line}"
    );
    assert_eq!(
        snapshot(&out),
        before,
        "{case}: the failed run changed {}",
        out.display()
    );

    // A failed run must not create a missing output directory either.
    let fresh = tmp(&format!("{case}_fresh"));
    let mut args = vec!["run", scene_arg, "--out", fresh.to_str().unwrap()];
    args.extend_from_slice(extra);
    let o = mufe(&args);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        !fresh.exists(),
        "{case}: failed run created {}",
        fresh.display()
    );

    if !extra.contains(&"--threads") {
        let mut args = vec!["check", scene_arg];
        args.extend(extra.iter().copied());
        let o = mufe(&args);
        let check_line = assert_one_line_error(&o, needles);
        assert_eq!(check_line, line, "check and run disagree");
    }
}

#[test]
fn unknown_field() {
    bad_input(
        "unknown_field",
        &fixture("bad/unknown_field.toml"),
        &[],
        &[
            "unknown_field.toml",
            "materials.glass.colour",
            "unknown field",
        ],
    );
}

#[test]
fn negative_radius() {
    bad_input(
        "negative_radius",
        &fixture("bad/negative_radius.toml"),
        &[],
        &[
            "negative_radius.toml",
            "grains[0].shape.sphere.radius",
            "-0.0011",
        ],
    );
}

#[test]
fn poisson_ratio_of_one_half() {
    bad_input(
        "poisson_half",
        &fixture("bad/poisson_half.toml"),
        &[],
        &["poisson_half.toml", "materials.glass.poisson_ratio", "0.5"],
    );
}

#[test]
fn poisson_ratio_above_one_half_via_set() {
    bad_input(
        "poisson_set",
        &fixture("valid_small.toml"),
        &["--set", "materials.glass.poisson_ratio=0.7"],
        &[
            "valid_small.toml",
            "materials.glass.poisson_ratio",
            "0.7",
            "--set",
        ],
    );
}

#[test]
fn missing_file() {
    bad_input(
        "missing_file",
        &fixture("bad/no_such_scene.toml"),
        &[],
        &["no_such_scene.toml", "cannot read"],
    );
}

#[test]
fn nan_value() {
    bad_input(
        "nan_value",
        &fixture("bad/nan_value.toml"),
        &[],
        &[
            "nan_value.toml",
            "materials.glass.youngs_modulus",
            "finite",
            "NaN",
        ],
    );
}

#[test]
fn nan_value_via_set() {
    bad_input(
        "nan_set",
        &fixture("valid_small.toml"),
        &["--set", "grains[0].centre=[0.0, nan, 0.0]"],
        &["valid_small.toml", "grains[0].centre[1]", "finite"],
    );
}

#[test]
fn bad_set_path_unknown_table() {
    bad_input(
        "set_path_table",
        &fixture("valid_small.toml"),
        &["--set", "simulatoin.duration=1e-6"],
        &[
            "<command line>",
            "--set simulatoin.duration=1e-6",
            "simulatoin",
        ],
    );
}

#[test]
fn bad_set_path_unknown_field() {
    bad_input(
        "set_path_field",
        &fixture("valid_small.toml"),
        &["--set", "grains[0].shape.sphere.radiuss=1e-3"],
        &[
            "valid_small.toml",
            "grains[0].shape.sphere.radiuss",
            "unknown field",
            "--set",
        ],
    );
}

#[test]
fn bad_set_path_index_out_of_range() {
    bad_input(
        "set_path_index",
        &fixture("valid_small.toml"),
        &["--set", "grains[4].centre=[0, 0, 0]"],
        &["<command line>", "--set grains[4].centre", "no index 4"],
    );
}

#[test]
fn bad_set_without_equals() {
    bad_input(
        "set_no_equals",
        &fixture("valid_small.toml"),
        &["--set", "simulation.duration"],
        &["<command line>", "--set simulation.duration", "PATH=VALUE"],
    );
}

#[test]
fn bad_set_value_type() {
    bad_input(
        "set_value_type",
        &fixture("valid_small.toml"),
        &["--set", "simulation.duration=fast"],
        &[
            "valid_small.toml",
            "simulation.duration",
            "invalid type",
            "--set simulation.duration=fast",
        ],
    );
}

#[test]
fn bad_set_value_shape() {
    bad_input(
        "set_value_shape",
        &fixture("valid_small.toml"),
        &["--set", "grains[0].centre=[0, 0]"],
        &["valid_small.toml", "grains[0].centre", "length", "--set"],
    );
}

#[test]
fn zero_threads() {
    bad_input(
        "zero_threads",
        &fixture("valid_small.toml"),
        &["--threads", "0"],
        &["<command line>", "--threads", "≥ 1"],
    );
}

#[test]
fn unknown_material() {
    bad_input(
        "unknown_material",
        &fixture("bad/unknown_material.toml"),
        &[],
        &["unknown_material.toml", "grains[0].material", "steel"],
    );
}

#[test]
fn non_increasing_history_times() {
    bad_input(
        "history_times",
        &fixture("bad/history_not_increasing.toml"),
        &[],
        &[
            "history_not_increasing.toml",
            "boundaries[0].velocity.times[1]",
            "increase",
        ],
    );
}

#[test]
fn toml_syntax_error_names_the_line() {
    bad_input(
        "toml_syntax",
        &fixture("bad/toml_syntax.toml"),
        &[],
        &["toml_syntax.toml", "line ", "invalid TOML"],
    );
}

#[test]
fn check_valid_scene_reports_the_model() {
    let scene = fixture("valid_small.toml");
    let o = mufe(&["check", scene.to_str().unwrap()]);
    let stdout = text(&o.stdout);
    assert!(
        o.status.success(),
        "check failed: {stdout}{}",
        text(&o.stderr)
    );
    assert!(o.stderr.is_empty(), "stderr: {}", text(&o.stderr));

    // Expected figures from the library, not hard-coded.
    let loaded = mufe::scene::load_scene(&scene, &[]).unwrap();
    let solver = mufe::solver::build_solver(&loaded).unwrap();
    let m = &solver.model;
    assert!(m.num_elements() > 0 && m.num_nodes() > 0);
    for needle in [
        format!("{} elements", m.num_elements()),
        format!("{} nodes", m.num_nodes()),
        format!("stable {:.4e} s", m.dt_stable),
        "memory estimate".to_string(),
        "is valid".to_string(),
    ] {
        assert!(
            stdout.contains(&needle),
            "check output lacks {needle:?}:\n{stdout}"
        );
    }
}

#[test]
fn failed_run_after_success_keeps_results() {
    // The baseline is a real results file: a bad re-run into the same directory keeps it.
    let bytes = baseline_results();
    assert!(bytes.starts_with(b"\x89HDF\r\n\x1a\n"), "not an HDF5 file");
}

/// A run that fails numerically (a head-on impact at half the wave speed inverts elements
/// within a few steps) stops at once with exit 1 and one line naming time, step, element
/// and grain, and leaves a readable `results.h5` whose history holds finite values up to
/// the failure — never exit 0, never NaN in the file.
#[test]
fn numerical_failure_stops_with_exit_1_and_a_readable_file() {
    let out = tmp("blow_up");
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("jobs/tests/contact_head_on.toml");
    let o = mufe(&[
        "run",
        scene.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--quiet",
        "--set",
        "grains[0].velocity=[2500.0, 0, 0]",
        "--set",
        "grains[1].velocity=[-2500.0, 0, 0]",
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o.stderr));
    let err = text(&o.stderr);
    assert_eq!(err.lines().count(), 1, "{err}");
    for word in ["error: blow-up at t = ", "(step ", "element ", "of grain '"] {
        assert!(err.contains(word), "{word:?} in {err}");
    }
    let f = hdf5::File::open(out.join("results.h5")).expect("results.h5 readable");
    let steps: Vec<f64> = f.dataset("history/step").unwrap().read_raw().unwrap();
    assert!(!steps.is_empty(), "history rows up to the failure");
    for name in ["energy_balance", "kinetic_energy", "strain_energy"] {
        let v: Vec<f64> = f
            .dataset(&format!("history/{name}"))
            .unwrap()
            .read_raw()
            .unwrap();
        assert!(v.iter().all(|x| x.is_finite()), "{name}: {v:?}");
    }
}

/// A run refused inside the driver, after the output lock's first step (`--restart latest`
/// with no checkpoint), leaves an existing output directory as it was, an earlier run's
/// `.mufe.lock` included, and does not create a missing one: the lock file is made only
/// just before the first write.
#[test]
fn a_restart_without_checkpoints_touches_no_output_directory() {
    let scene = fixture("valid_small.toml");
    let scene = scene.to_str().unwrap();
    let out = tmp("restart_without_checkpoints");
    std::fs::create_dir_all(out.join("checkpoints")).unwrap();
    std::fs::write(out.join("results.h5"), baseline_results()).unwrap();
    std::fs::write(out.join(".mufe.lock"), b"").unwrap();
    std::fs::write(out.join("checkpoints/notes.txt"), b"keep me\n").unwrap();
    let before = snapshot(&out);
    let run = |dir: &Path| {
        mufe(&[
            "run",
            scene,
            "--out",
            dir.to_str().unwrap(),
            "--restart",
            "latest",
        ])
    };
    assert_one_line_error(&run(&out), &["checkpoint"]);
    assert_eq!(
        snapshot(&out),
        before,
        "the refused restart changed {}",
        out.display()
    );

    let fresh = tmp("restart_without_checkpoints_fresh");
    assert_one_line_error(&run(&fresh), &["checkpoint"]);
    assert!(
        !fresh.exists(),
        "the refused restart created {}",
        fresh.display()
    );
}

/// `--threads N` on a rank that may run on fewer CPUs (its affinity mask; Open MPI binds a
/// rank to one core by default for up to two ranks) says so in one warning line, and the
/// run still completes; as many threads as CPUs say nothing. The mask is set with
/// `taskset`, as a launcher would set it.
#[test]
fn more_threads_than_the_rank_s_cpus_are_warned_about() {
    let scene = fixture("valid_small.toml");
    let run = |threads: &str, name: &str| {
        let out = tmp(name);
        Command::new("taskset")
            .args(["--cpu-list", "0", MUFE, "run"])
            .arg(&scene)
            .args([
                "--out",
                out.to_str().unwrap(),
                "--quiet",
                "--max-steps",
                "3",
            ])
            .args(["--threads", threads])
            .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
            .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
            .output()
            .expect("cannot start taskset (util-linux)")
    };
    let warned = |o: &Output| {
        (text(&o.stderr).lines())
            .filter(|l| l.starts_with("warning: --threads"))
            .count()
    };
    let two = run("2", "two_threads_on_one_cpu");
    assert!(two.status.success(), "{}", text(&two.stderr));
    assert_eq!(warned(&two), 1, "{}", text(&two.stderr));
    let line = text(&two.stderr);
    assert!(line.contains("may run on 1 CPU only") && line.contains("--bind-to none"));
    let one = run("1", "one_thread_on_one_cpu");
    assert!(one.status.success(), "{}", text(&one.stderr));
    assert_eq!(warned(&one), 0, "{}", text(&one.stderr));
}
