//! `[[packings]]` end to end: the shipped FCC scenes expand to the expected grains with one
//! distinct shape, `mufe check` reports the 2000-sphere block in seconds, `--set` reaches
//! the packing, touching spheres (gap 0) pass the mesh-level overlap check and a real
//! overlap is refused naming `packings[0].gap`.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

const MUFE: &str = env!("CARGO_BIN_EXE_mufe");
const BLOCK: &str = "jobs/fcc/fcc_2000.toml";
const CELL: &str = "jobs/fcc/fcc_cell.toml";

fn root(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

fn mufe(args: &[&str]) -> (Output, Duration) {
    let t0 = Instant::now();
    let o = Command::new(MUFE)
        .args(args)
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .env("OMPI_MCA_hwloc_base_binding_policy", "none")
        .env_remove("MUFE_MEMORY_LIMIT")
        .output()
        .expect("cannot start mufe");
    (o, t0.elapsed())
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

#[test]
fn the_paper_block_is_2000_spheres_of_one_shape() {
    let loaded = mufe::scene::load_scene(&root(BLOCK), &[]).unwrap();
    let s = &loaded.scene;
    assert_eq!(s.grains.len(), 2000);
    let keys: std::collections::BTreeSet<String> = s
        .grains
        .iter()
        .map(|g| serde_json::to_string(&g.shape).unwrap())
        .collect();
    assert_eq!(keys.len(), 1, "the packing must be meshed once");
    let geo = &s.packing_geometry()[0];
    assert_eq!(geo.grains, 0..2000);
    // 10×10×5 open cells: the span is (n − ½)·a per axis
    let a = geo.lattice_constant;
    for (k, n) in [10.0, 10.0, 5.0].into_iter().enumerate() {
        assert!((geo.span_max[k] - geo.span_min[k] - (n - 0.5) * a).abs() < 1e-12);
    }
    assert_eq!(s.grain_set("fcc.z_min").unwrap().len(), 2 * 10 * 10);
}

#[test]
fn set_reaches_the_packing() {
    let set = ["packings[0].cells=[1,1,1]".to_string()];
    let loaded = mufe::scene::load_scene(&root(BLOCK), &set).unwrap();
    assert_eq!(loaded.scene.grains.len(), 4);
}

#[test]
fn check_reports_the_2000_sphere_block_in_seconds() {
    let (o, took) = mufe(&["check", root(BLOCK).to_str().unwrap()]);
    let out = text(&o.stdout);
    assert!(o.status.success(), "{}\n{}", out, text(&o.stderr));
    for needle in [
        "totals: 2000 grains",
        "elements",
        "nodes",
        "time step: stable",
        "memory estimate",
    ] {
        assert!(out.contains(needle), "lacks {needle:?}:\n{out}");
    }
    assert!(took < Duration::from_secs(30), "check took {took:?}");
}

#[test]
fn touching_spheres_pass_the_mesh_overlap_check_and_overlaps_are_refused() {
    let cell = root(CELL);
    let cell = cell.to_str().unwrap();
    let (o, _) = mufe(&["check", cell]);
    let out = text(&o.stdout);
    assert!(o.status.success(), "{}\n{}", out, text(&o.stderr));
    assert!(out.contains("totals: 14 grains"), "{out}");
    // deeper than the faceting of the contact patches: refused on the meshes
    let (o, _) = mufe(&["check", cell, "--set", "packings[0].gap=-0.005"]);
    let err = text(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("packings[0].gap") && err.contains("overlap"),
        "{err}"
    );
}

#[test]
fn the_cell_runs_at_rest() {
    let out = Path::new(env!("CARGO_TARGET_TMPDIR")).join("packings_cell");
    let _ = std::fs::remove_dir_all(&out);
    let (o, _) = mufe(&[
        "run",
        root(CELL).to_str().unwrap(),
        "--max-steps",
        "50",
        "--out",
        out.to_str().unwrap(),
    ]);
    let stdout = text(&o.stdout);
    assert!(o.status.success(), "{stdout}\n{}", text(&o.stderr));
    // nothing loads the cell: no contact force, energies at round-off
    assert!(stdout.contains("contact: 0 points now"), "{stdout}");
    let kinetic: f64 = stdout
        .split("energy: kinetic ")
        .nth(1)
        .and_then(|r| r.split(' ').next())
        .and_then(|v| v.parse().ok())
        .expect("no kinetic energy in the summary");
    assert!(kinetic < 1e-20, "kinetic energy {kinetic} J");
}

/// "added mass X kg" of `mufe check`'s mass-scaling line.
fn added_mass(out: &str) -> f64 {
    let line = out
        .lines()
        .find(|l| l.starts_with("mass scaling:"))
        .unwrap_or_else(|| panic!("no mass-scaling line:\n{out}"));
    let rest = line.split("added mass ").nth(1).expect(line);
    rest.split(' ').next().unwrap().parse().expect(line)
}

#[test]
fn check_counts_the_added_mass_of_every_copy_of_a_shape() {
    // The 2000-sphere block is checked with one mesh built for its single shape; its added
    // mass must be 500 times that of the 4-sphere block, whose grains are all built.
    let block = root(BLOCK);
    let block = block.to_str().unwrap();
    let step = "simulation.target_dt=3e-8";
    let (o, _) = mufe(&["check", block, "--set", step]);
    let all = text(&o.stdout);
    assert!(o.status.success(), "{all}\n{}", text(&o.stderr));
    assert!(all.contains("each meshed and built once"), "{all}");
    let cells = "packings[0].cells=[1,1,1]";
    let (o, _) = mufe(&["check", block, "--set", step, "--set", cells]);
    let four = text(&o.stdout);
    assert!(o.status.success(), "{four}\n{}", text(&o.stderr));
    let ratio = added_mass(&all) / added_mass(&four);
    assert!((ratio - 500.0).abs() < 500.0 * 1e-9, "ratio {ratio}");
}
