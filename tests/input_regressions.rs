//! One named test per defect of issue 9 (bad input that got through the one-line error
//! contract): each must now end with exit code 2 and one line `error: FILE: FIELD: what`
//! within a few seconds, with nothing in an existing output directory touched.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

const MUFE: &str = env!("CARGO_BIN_EXE_mufe");

fn root(rel: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join(rel)
        .display()
        .to_string()
}

fn tmp(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("input_regressions")
        .join(name);
    if dir.exists() {
        std::fs::remove_dir_all(&dir).unwrap();
    }
    std::fs::create_dir_all(dir.parent().unwrap()).unwrap();
    dir
}

fn mufe_env(args: &[&str], env: &[(&str, &str)]) -> (Output, Duration) {
    let t0 = Instant::now();
    let mut cmd = Command::new(MUFE);
    cmd.args(args)
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .env("OMPI_MCA_rmaps_base_oversubscribe", "1")
        .env("OMPI_MCA_hwloc_base_binding_policy", "none")
        .env_remove("MUFE_VALIDATION_SCENES")
        .env_remove("MUFE_MEMORY_LIMIT");
    for (k, v) in env {
        cmd.env(k, v);
    }
    let o = cmd.output().expect("cannot start mufe");
    (o, t0.elapsed())
}

fn mufe(args: &[&str]) -> (Output, Duration) {
    mufe_env(args, &[])
}

/// Exit 2, one stderr line `error: FILE: FIELD: message` containing every needle, within
/// `seconds`. Returns the line.
fn refused(o: &(Output, Duration), seconds: u64, needles: &[&str]) -> String {
    let (o, took) = o;
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(
        o.status.code(),
        Some(2),
        "exit {:?}; stderr:\n{err}",
        o.status
    );
    assert!(!err.contains("panicked"), "{err}");
    let lines: Vec<&str> = err.lines().collect();
    assert_eq!(lines.len(), 1, "expected one stderr line:\n{err}");
    let line = lines[0];
    let parts: Vec<&str> = line.splitn(4, ": ").collect();
    assert!(
        parts.len() == 4 && parts[0] == "error" && !parts[1].is_empty() && !parts[2].is_empty(),
        "not `error: FILE: FIELD: what`: {line}"
    );
    for n in needles {
        assert!(line.contains(n), "line lacks {n:?}: {line}");
    }
    assert!(
        *took < Duration::from_secs(seconds),
        "took {took:?} (bound {seconds} s): {line}"
    );
    line.to_string()
}

const HERTZ: &str = "jobs/validation/hertz.toml";
const SMALL: &str = "tests/fixtures/valid_small.toml";
const PUCK: &str = "jobs/tests/wall_friction.toml";
const HEAD_ON: &str = "jobs/tests/contact_head_on.toml";

fn check_set(scene: &str, set: &str) -> (Output, Duration) {
    mufe(&["check", &root(scene), "--set", set])
}

#[test]
fn growth_1e6_is_refused_not_a_panic() {
    refused(
        &check_set(HERTZ, "grains[0].shape.sphere.refine[0].growth=1e6"),
        5,
        &["grains[0].shape.sphere.refine[0].growth", "1e6"],
    );
}

#[test]
fn growth_zero_is_refused_at_once() {
    refused(
        &check_set(HERTZ, "grains[0].shape.sphere.refine[0].growth=0"),
        5,
        &["grains[0].shape.sphere.refine[0].growth", "[0.01, 1]"],
    );
}

#[test]
fn growth_1e_minus_300_is_refused_at_once() {
    let line = refused(
        &check_set(HERTZ, "grains[0].shape.sphere.refine[0].growth=1e-300"),
        5,
        &["grains[0].shape.sphere.refine[0].growth", "1e-300"],
    );
    assert!(!line.contains("0.0000000000"), "unreadable number: {line}");
}

#[test]
fn small_growth_is_refused_by_the_memory_estimate_before_meshing() {
    let o = mufe_env(
        &[
            "check",
            &root(HERTZ),
            "--set",
            "grains[0].shape.sphere.refine[0].growth=0.01",
        ],
        &[("MUFE_MEMORY_LIMIT", "1G")],
    );
    refused(
        &o,
        5,
        &["grains[0].shape.sphere.refine[0].growth", "elements", "GiB"],
    );
}

#[test]
fn seeding_5e_minus_6_is_refused_by_the_memory_estimate() {
    let o = mufe_env(
        &[
            "check",
            &root(SMALL),
            "--set",
            "grains[0].shape.sphere.seeding=5e-6",
        ],
        &[("MUFE_MEMORY_LIMIT", "64G")],
    );
    refused(
        &o,
        5,
        &["grains[0].shape.sphere.seeding", "elements", "memory"],
    );
}

#[test]
fn huge_block_divisions_are_refused_not_aborted() {
    let o = check_set(
        PUCK,
        "grains[0].shape.block.divisions=[100000, 100000, 100000]",
    );
    refused(
        &o,
        5,
        &["grains[0].shape.block.divisions", "6.000e15 elements"],
    );
    // a product that overflows 64 bits
    let o = check_set(
        PUCK,
        "grains[0].shape.block.divisions=[4000000000, 4000000000, 4000000000]",
    );
    refused(&o, 5, &["grains[0].shape", "counted"]);
}

#[test]
fn force_skips_the_memory_guard() {
    // The guard refuses a modest scene under a tiny limit; --force meshes it anyway.
    let args = ["check", &root("jobs/examples/free_vibration.toml")];
    let o = mufe_env(&args, &[("MUFE_MEMORY_LIMIT", "1M")]);
    refused(
        &o,
        5,
        &[
            "grains[0].shape.sphere.seeding",
            "MUFE_MEMORY_LIMIT",
            "--force",
        ],
    );
    let mut forced = args.to_vec();
    forced.push("--force");
    let (o, _) = mufe_env(&forced, &[("MUFE_MEMORY_LIMIT", "1M")]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

#[test]
fn grains_at_the_same_centre_are_refused() {
    refused(
        &check_set(HEAD_ON, "grains[1].centre=[-1.0005e-3, 0.0, 0.0]"),
        5,
        &["grains[0] and grains[1]", "overlap"],
    );
}

#[test]
fn grains_at_nearly_the_same_centre_are_refused() {
    refused(
        &check_set(HEAD_ON, "grains[1].centre=[-1.0004e-3, 1e-9, 0.0]"),
        5,
        &["grains[0] and grains[1]", "overlap"],
    );
}

#[test]
fn block_inside_a_block_is_refused() {
    let text = std::fs::read_to_string(root(PUCK)).unwrap()
        + "\n[[grains]]\nname = \"twin\"\nmaterial = \"glass\"\nshape = { block = { size = [4.0e-4, 4.0e-4, 2.0e-4], divisions = [4, 4, 2] } }\ncentre = [1e-5, 0.0, 0.0]\n";
    let dir = tmp("block_twin");
    std::fs::create_dir_all(&dir).unwrap();
    let scene = dir.join("twin.toml");
    std::fs::write(&scene, text).unwrap();
    refused(
        &mufe(&["check", scene.to_str().unwrap()]),
        5,
        &["grains[0] and grains[1]", "overlap"],
    );
}

#[test]
fn youngs_modulus_1e300_is_refused() {
    refused(
        &check_set(SMALL, "materials.glass.youngs_modulus=1e300"),
        5,
        &["materials.glass.youngs_modulus", "1e13"],
    );
}

#[test]
fn density_1e300_is_refused() {
    refused(
        &check_set(SMALL, "materials.glass.density=1e300"),
        5,
        &["materials.glass.density", "1e300"],
    );
}

#[test]
fn wave_speed_beyond_any_solid_is_refused() {
    refused(
        &mufe(&[
            "check",
            &root(SMALL),
            "--set",
            "materials.glass.youngs_modulus=1e13",
            "--set",
            "materials.glass.density=0.1",
        ]),
        5,
        &["materials.glass", "wave speed"],
    );
}

#[test]
fn target_dt_1e_minus_300_is_refused() {
    refused(
        &check_set(HERTZ, "simulation.target_dt=1e-300"),
        5,
        &["simulation.target_dt", "2^53"],
    );
    // and never reaches the solver in a run either
    let out = tmp("tiny_target_dt");
    let o = mufe(&[
        "run",
        &root(HERTZ),
        "--set",
        "simulation.target_dt=1e-300",
        "--out",
        out.to_str().unwrap(),
        "--max-steps",
        "3",
    ]);
    refused(&o, 5, &["simulation.target_dt"]);
    assert!(!out.exists());
}

#[test]
fn duration_1e20_is_refused() {
    refused(
        &check_set(HERTZ, "simulation.duration=1e20"),
        5,
        &["simulation.duration", "steps"],
    );
}

#[test]
fn target_dt_1e300_is_refused() {
    refused(
        &check_set(HERTZ, "simulation.target_dt=1e300"),
        5,
        &["simulation.target_dt"],
    );
    // below the duration but far above the stable step: the added mass would be absurd
    refused(
        &check_set(HERTZ, "simulation.target_dt=1e-6"),
        5,
        &["simulation.target_dt", "mass scaling"],
    );
}

#[test]
fn step_limit_is_refused_and_force_proceeds() {
    let set = "simulation.duration=20.0";
    refused(
        &check_set(SMALL, set),
        5,
        &["simulation.duration", "steps", "--force"],
    );
    let (o, _) = mufe(&["check", &root(SMALL), "--set", set, "--force"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(!stdout.contains("18446744073709551615"), "{stdout}");
}

#[test]
fn duplicate_boundary_names_are_refused_before_the_run() {
    let out = tmp("dup_boundary");
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("keep.txt"), b"keep\n").unwrap();
    let o = mufe(&[
        "run",
        &root("jobs/demo/sphere_compression.toml"),
        "--set",
        "boundaries[1].name=bottom",
        "--out",
        out.to_str().unwrap(),
        "--max-steps",
        "3",
    ]);
    refused(
        &o,
        10,
        &["boundaries[1].name", "duplicate boundary name 'bottom'"],
    );
    let names: Vec<_> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names, vec![std::ffi::OsString::from("keep.txt")]);
    assert_eq!(std::fs::read(out.join("keep.txt")).unwrap(), b"keep\n");
}

#[test]
fn set_value_with_a_newline_is_refused() {
    refused(
        &check_set(SMALL, "simulation.duration=1e-8\ngarbage = 1"),
        5,
        &["<command line>", "--set simulation.duration", "line break"],
    );
    refused(
        &check_set(SMALL, "simulation.duration=1e-8\u{1}"),
        5,
        &["<command line>", "control character"],
    );
}

#[test]
fn a_huge_bad_value_is_echoed_cut() {
    // 10 MB in the file (a command-line argument cannot be that long) ...
    let big = "x".repeat(10_000_000);
    let text = std::fs::read_to_string(root(SMALL))
        .unwrap()
        .replace("material = \"glass\"", &format!("material = \"{big}\""));
    let dir = tmp("huge_value");
    std::fs::create_dir_all(&dir).unwrap();
    let scene = dir.join("huge.toml");
    std::fs::write(&scene, text).unwrap();
    let line = refused(
        &mufe(&["check", scene.to_str().unwrap()]),
        10,
        &["grains[0].material", "…"],
    );
    assert!(line.chars().count() < 700, "{} chars", line.chars().count());
    // ... and 100 kB on the command line
    let big = "y".repeat(100_000);
    let line = refused(
        &check_set(SMALL, &format!("grains[0].material=\"{big}\"")),
        10,
        &["grains[0].material", "…"],
    );
    assert!(line.chars().count() < 900, "{} chars", line.chars().count());
}

#[test]
fn out_naming_an_existing_file_exits_2() {
    let dir = tmp("out_file");
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("results_here");
    std::fs::write(&file, b"not a directory\n").unwrap();
    refused(
        &mufe(&["run", &root(SMALL), "--out", file.to_str().unwrap()]),
        5,
        &["<command line>", "--out", "not a directory"],
    );
    assert_eq!(std::fs::read(&file).unwrap(), b"not a directory\n");
}

#[test]
fn validation_scenes_naming_a_missing_folder_exits_2() {
    let o = mufe_env(
        &[
            "validate",
            "hertz",
            "--quick",
            "--out",
            tmp("val").to_str().unwrap(),
        ],
        &[("MUFE_VALIDATION_SCENES", "/no/such/folder")],
    );
    refused(&o, 5, &["MUFE_VALIDATION_SCENES", "/no/such/folder"]);
}

#[test]
fn argument_parser_errors_have_the_documented_form() {
    refused(
        &mufe(&["run", &root(SMALL), "--threads", "x"]),
        5,
        &["error: <command line>: --threads: invalid value 'x'"],
    );
    refused(
        &mufe(&["check", &root(SMALL), "--bogus"]),
        5,
        &["error: <command line>: --bogus: unexpected argument"],
    );
    refused(
        &mufe(&["run"]),
        5,
        &["error: <command line>: <SCENE>: required argument is missing"],
    );
    refused(
        &mufe(&["frobnicate"]),
        5,
        &["error: <command line>: command: unknown command 'frobnicate'"],
    );
}

#[test]
fn missing_simulation_names_the_field() {
    let dir = tmp("no_sim");
    std::fs::create_dir_all(&dir).unwrap();
    let scene = dir.join("no_sim.toml");
    std::fs::write(
        &scene,
        "[materials.glass]\nyoungs_modulus = 63e9\npoisson_ratio = 0.22\ndensity = 2500.0\n",
    )
    .unwrap();
    refused(
        &mufe(&["check", scene.to_str().unwrap()]),
        5,
        &["no_sim.toml: simulation: required field is missing"],
    );
}

/// The estimate before meshing against the built model, on every scene in `jobs/`:
/// elements within a factor 1.6, steps within a factor 2 (the numbers are in
/// docs/INPUT.md).
#[test]
fn estimator_tracks_the_jobs() {
    let mut scenes: Vec<PathBuf> = Vec::new();
    for dir in std::fs::read_dir(root("jobs")).unwrap() {
        let dir = dir.unwrap().path();
        if dir.is_dir() {
            for f in std::fs::read_dir(&dir).unwrap() {
                let f = f.unwrap().path();
                if f.extension().is_some_and(|e| e == "toml") {
                    scenes.push(f);
                }
            }
        }
    }
    scenes.sort();
    assert!(scenes.len() >= 10);
    let number_before = |s: &str, key: &str| -> f64 {
        let i = s.find(key).unwrap_or_else(|| panic!("no {key:?} in {s}"));
        s[..i]
            .split_whitespace()
            .last()
            .unwrap()
            .trim_matches(',')
            .parse()
            .unwrap()
    };
    for scene in scenes {
        let (o, took) = mufe(&["check", scene.to_str().unwrap()]);
        let out = String::from_utf8_lossy(&o.stdout);
        assert!(
            o.status.success(),
            "{}: {}",
            scene.display(),
            String::from_utf8_lossy(&o.stderr)
        );
        assert!(took < Duration::from_secs(60));
        let totals = out.lines().find(|l| l.starts_with("totals:")).unwrap();
        let steps_line = out.lines().find(|l| l.starts_with("time step:")).unwrap();
        let est = out
            .lines()
            .find(|l| l.starts_with("estimate before meshing:"))
            .unwrap();
        let (e_real, e_est) = (
            number_before(totals, " elements"),
            number_before(est, " elements"),
        );
        let (s_real, s_est) = (
            number_before(steps_line, " steps"),
            number_before(est, " steps"),
        );
        let re = e_est / e_real;
        let rs = s_est / s_real;
        assert!(
            (1.0 / 1.6..1.6).contains(&re),
            "{}: elements {e_est} vs {e_real}",
            scene.display()
        );
        assert!(
            (0.5..2.0).contains(&rs),
            "{}: steps {s_est} vs {s_real}",
            scene.display()
        );
    }
}

// J2 parameters (issue 10): each bad value is one line naming its field.

fn check_sets(scene: &str, sets: &[&str]) -> (Output, Duration) {
    let mut args = vec!["check".to_string(), root(scene)];
    for s in sets {
        args.push("--set".into());
        args.push(s.to_string());
    }
    let args: Vec<&str> = args.iter().map(|s| s.as_str()).collect();
    mufe(&args)
}

#[test]
fn hardening_without_yield_stress_is_refused() {
    refused(
        &check_set(SMALL, "materials.glass.hardening_modulus=1e9"),
        5,
        &["materials.glass.hardening_modulus", "yield_stress"],
    );
}

#[test]
fn yield_stress_above_youngs_modulus_is_refused() {
    refused(
        &check_set(SMALL, "materials.glass.yield_stress=1e12"),
        5,
        &["materials.glass.yield_stress", "youngs_modulus"],
    );
}

#[test]
fn negative_or_nan_plastic_parameters_are_refused() {
    refused(
        &check_set(SMALL, "materials.glass.yield_stress=-1e8"),
        5,
        &["materials.glass.yield_stress"],
    );
    refused(
        &check_set(SMALL, "materials.glass.yield_stress=nan"),
        5,
        &["materials.glass.yield_stress"],
    );
    refused(
        &check_sets(
            SMALL,
            &[
                "materials.glass.yield_stress=1e8",
                "materials.glass.hardening_modulus=-5.0",
            ],
        ),
        5,
        &["materials.glass.hardening_modulus", "[0, youngs_modulus"],
    );
}

#[test]
fn plasticity_on_another_elastic_law_is_refused() {
    refused(
        &check_sets(
            SMALL,
            &[
                "materials.glass.yield_stress=1e8",
                "materials.glass.law=\"st_venant_kirchhoff\"",
            ],
        ),
        5,
        &["materials.glass.law", "biot"],
    );
}

const FCC_CELL: &str = "jobs/fcc/fcc_cell.toml";

#[test]
fn bad_packing_fields_are_named() {
    for (set, field, needle) in [
        ("packings[0].cells=[0, 1, 1]", "packings[0].cells", "≥ 1"),
        ("packings[0].cells=[1, -2, 1]", "packings[0].cells", "-2"),
        ("packings[0].lattice=\"bcc\"", "packings[0].lattice", "fcc"),
        ("packings[0].faces=\"half\"", "packings[0].faces", "closed"),
        (
            "packings[0].material=\"steel\"",
            "packings[0].material",
            "steel",
        ),
        ("packings[0].gap=0.5", "packings[0].gap", "0.5"),
        ("packings[0].gap=-0.01", "packings[0].gap", "-0.01"),
        (
            "packings[0].sphere.radius=0.0",
            "packings[0].sphere.radius",
            "positive",
        ),
        (
            "packings[0].sphere.seeding=-1e-4",
            "packings[0].sphere.seeding",
            "positive",
        ),
        (
            "packings[0].sphere.seeding=2e-3",
            "packings[0].sphere.seeding",
            "radius",
        ),
        (
            "packings[0].sphere.contact_seeding=5e-4",
            "packings[0].sphere.contact_seeding",
            "coarser",
        ),
        (
            "packings[0].sphere.contact_growth=2.0",
            "packings[0].sphere.contact_growth",
            "[0.01, 1]",
        ),
        (
            "packings[0].cells=[100, 100, 100]",
            "packings[0].cells",
            "100000 grains",
        ),
        ("packings[0].name=\"a.b\"", "packings[0].name", "identifier"),
        ("packings[0].shape=1", "packings[0]", "shape"),
    ] {
        refused(&check_set(FCC_CELL, set), 5, &[field, needle]);
    }
}

#[test]
fn packing_names_must_not_clash_with_grains() {
    let set = r#"grains=[{ name = "cell_3", material = "glass", centre = [0.1, 0.0, 0.0], shape = { sphere = { radius = 1e-3, seeding = 5e-4 } } }]"#;
    refused(
        &check_set(FCC_CELL, set),
        5,
        &["packings[0].name", "cell_3"],
    );
}

#[test]
fn a_packing_too_big_for_memory_names_its_cells() {
    // one distinct sphere, so check itself fits; `run` must refuse the whole block
    let o = mufe_env(
        &[
            "run",
            &root(FCC_CELL),
            "--set",
            "packings[0].cells=[20, 20, 20]",
            "--out",
            tmp("packing_memory").to_str().unwrap(),
        ],
        &[("MUFE_MEMORY_LIMIT", "1G")],
    );
    refused(&o, 5, &["packings[0].cells", "memory"]);
}

const SERVO_SPHERE: &str = "jobs/tests/servo_sphere.toml";
const FCC_SERVO: &str = "jobs/fcc/fcc_cell_servo.toml";

/// Bad servo-wall input (issue 11, item 2) is one line naming the field, before meshing.
#[test]
fn bad_servo_walls_are_refused() {
    for (scene, set, field, needle) in [
        (
            SERVO_SPHERE,
            "walls[1].servo.stress=0.0",
            "walls[1].servo.stress",
            "> 0",
        ),
        (
            SERVO_SPHERE,
            "walls[1].servo.stress=-5e4",
            "walls[1].servo.stress",
            "> 0",
        ),
        (
            FCC_SERVO,
            "walls[1].servo.area_of=\"box\"",
            "walls[1].servo.area_of",
            "no packing named 'box'",
        ),
        (
            FCC_SERVO,
            "walls[1].normal=[0.0, 0.6, -0.8]",
            "walls[1].servo.area_of",
            "coordinate axis",
        ),
        (
            SERVO_SPHERE,
            "walls[1].velocity={ times = [0.0], values = [[0.0, 0.0, -1.0]] }",
            "walls[1].servo",
            "at most one of velocity, displacement and servo",
        ),
        (
            SERVO_SPHERE,
            "walls[1].servo={ stress = 5e4 }",
            "walls[1].servo",
            "area",
        ),
        (
            FCC_SERVO,
            "walls[1].servo={ stress = 5e4, area = 1e-5, area_of = \"cell\" }",
            "walls[1].servo.area",
            "not both",
        ),
        (
            SERVO_SPHERE,
            "walls[1].servo.time_constant=0.0",
            "walls[1].servo.time_constant",
            "> 0",
        ),
        (
            SERVO_SPHERE,
            "walls[1].servo.periods=0.0",
            "walls[1].servo.periods",
            "> 0",
        ),
        (
            FCC_SERVO,
            "walls[1].servo={ stress = 5e4, area_of = \"cell\", periods = 0.5, time_constant = 1e-4 }",
            "walls[1].servo.periods",
            "not both",
        ),
        (
            SERVO_SPHERE,
            "walls[1].servo.max_speed=-1.0",
            "walls[1].servo.max_speed",
            "> 0",
        ),
        (
            SERVO_SPHERE,
            "walls[1].servo.gain=1.0",
            "walls[1].servo",
            "gain",
        ),
    ] {
        refused(&check_set(scene, set), 5, &[field, needle]);
    }
}

#[test]
fn an_unknown_or_unavailable_element_kernel_is_refused() {
    let args = ["check", &root("jobs/examples/free_vibration.toml")];
    let o = mufe_env(&args, &[("MUFE_KERNEL", "avx513")]);
    let line = refused(&o, 5, &["<environment>", "MUFE_KERNEL", "'avx513'"]);
    assert!(line.contains("portable, avx2 or avx512"), "{line}");
    // a narrower path the CPU has runs
    let (o, _) = mufe_env(&args, &[("MUFE_KERNEL", "portable")]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // and a path the CPU lacks is named as such
    if !mufe::solver::forces::KernelPath::Avx512.is_supported() {
        let o = mufe_env(&args, &[("MUFE_KERNEL", "avx512")]);
        refused(&o, 5, &["MUFE_KERNEL", "cannot run the avx512 kernel"]);
    }
}
