//! `mufe partition SCENE --parts N [--out FILE] [--margin M] [--exact]` on a small
//! multi-grain scene (`tests/fixtures/grains19.toml`: 18 spheres on a lattice + 1 block).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const MUFE: &str = env!("CARGO_BIN_EXE_mufe");

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name)
}

fn tmp(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("cli_partition");
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join(name);
    let _ = std::fs::remove_file(&p);
    p
}

fn mufe(args: &[&str]) -> Output {
    Command::new(MUFE)
        .args(args)
        .output()
        .expect("cannot start mufe")
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

fn scene() -> String {
    fixture("grains19.toml").to_str().unwrap().to_string()
}

fn n_grains() -> usize {
    let loaded = mufe::scene::load_scene(&fixture("grains19.toml"), &[]).unwrap();
    loaded.scene.grains.len()
}

fn assert_one_line_error(o: &Output, needles: &[&str]) {
    let err = text(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "stderr:\n{err}");
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(err.lines().count(), 1, "expected one stderr line:\n{err}");
    for n in needles {
        assert!(err.contains(n), "error lacks {n:?}: {err}");
    }
}

#[test]
fn partitions_and_writes_the_file() {
    let n = n_grains();
    let parts = 3;
    let out = tmp("grains19.part");
    let o = mufe(&[
        "partition",
        &scene(),
        "--parts",
        &parts.to_string(),
        "--out",
        out.to_str().unwrap(),
    ]);
    let stdout = text(&o.stdout);
    assert!(o.status.success(), "{stdout}{}", text(&o.stderr));
    assert!(stdout.contains("imbalance"), "{stdout}");
    assert!(stdout.contains("edge cut"), "{stdout}");
    assert!(
        stdout.contains(&format!("{n} grains into {parts} parts")),
        "{stdout}"
    );

    let part = partition::read_partition(&out, n).expect("partition file reads back");
    assert_eq!(part.len(), n);
    for p in 0..parts as u32 {
        assert!(part.contains(&p), "part {p} is empty: {part:?}");
    }
    assert!(part.iter().all(|&p| (p as usize) < parts));
    assert!(!out.with_extension("part.tmp").exists());

    // Deterministic: the same command gives the same partition.
    let o2 = mufe(&[
        "partition",
        &scene(),
        "--parts",
        &parts.to_string(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o2.status.success());
    assert_eq!(partition::read_partition(&out, n).unwrap(), part);
    assert_eq!(text(&o2.stdout), stdout);
}

#[test]
fn exact_counts_match_the_meshes() {
    let loaded = mufe::scene::load_scene(&fixture("grains19.toml"), &[]).unwrap();
    let mut elements = 0;
    let mut surface = 0;
    for g in &loaded.scene.grains {
        let m = mufe::model::mesh_shape(&g.shape).unwrap();
        elements += m.tets.len();
        surface += mufe::mesh::extract_surface(&m).nodes.len();
    }
    let o = mufe(&["partition", &scene(), "--parts", "2", "--exact"]);
    let stdout = text(&o.stdout);
    assert!(o.status.success(), "{stdout}{}", text(&o.stderr));
    let expect = format!("elements {elements}, surface nodes {surface}");
    assert!(stdout.contains(&expect), "lacks {expect:?}:\n{stdout}");
    assert!(stdout.contains("imbalance"));
}

#[test]
fn one_part_and_margin() {
    let o = mufe(&["partition", &scene(), "--parts", "1", "--margin", "0"]);
    let stdout = text(&o.stdout);
    assert!(o.status.success(), "{stdout}{}", text(&o.stderr));
    assert!(stdout.contains("imbalance"));
    assert!(stdout.contains("margin 0.0000e0 m"), "{stdout}");
}

#[test]
fn zero_parts_is_one_line_error() {
    let o = mufe(&["partition", &scene(), "--parts", "0"]);
    assert_one_line_error(&o, &["--parts", "≥ 1"]);
}

#[test]
fn more_parts_than_grains_is_one_line_error_and_keeps_the_file() {
    let n = n_grains();
    let out = tmp("too_many.part");
    std::fs::write(&out, b"# an earlier partition\n").unwrap();
    let too_many = (n + 1).to_string();
    let o = mufe(&[
        "partition",
        &scene(),
        "--parts",
        &too_many,
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_one_line_error(
        &o,
        &[
            "grains19.toml",
            "--parts",
            &format!("{n} grains into {too_many} parts"),
        ],
    );
    assert_eq!(std::fs::read(&out).unwrap(), b"# an earlier partition\n");
}

#[test]
fn negative_margin_is_one_line_error() {
    let o = mufe(&["partition", &scene(), "--parts", "2", "--margin", "-1e-4"]);
    assert_one_line_error(&o, &["--margin"]);
}

#[test]
fn bad_scene_is_one_line_error() {
    let bad = fixture("bad/negative_radius.toml");
    let o = mufe(&["partition", bad.to_str().unwrap(), "--parts", "1"]);
    assert_one_line_error(
        &o,
        &["negative_radius.toml", "grains[0].shape.sphere.radius"],
    );
}

#[test]
fn exact_partition_prints_the_contact_zone_halo_of_the_run() {
    // 8 uniformly fine spheres meeting across the cut: the zones are a fraction of the
    // ghosts' surfaces (`mufe run` sent 35 % on 2 ranks, tests/mpi_assembly.rs)
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("jobs/tests/assembly_fine.toml");
    let o = mufe(&[
        "partition",
        scene.to_str().unwrap(),
        "--parts",
        "2",
        "--exact",
    ]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let out = text(&o.stdout);
    let line = out
        .lines()
        .find(|l| l.starts_with("forward halo of mufe run"))
        .unwrap_or_else(|| panic!("no halo line in {out}"));
    let share: f64 = line
        .rsplit_once(", ")
        .and_then(|(_, tail)| tail.split_whitespace().next())
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("no share in {line}"));
    assert!(share > 10.0 && share < 60.0, "{line}");
}
