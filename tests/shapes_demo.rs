//! The shape demo `jobs/shapes/`: it is `mufe sand --box`'s output, and it starts under
//! `mpirun -n 2` with the grains partitioned by METIS on the weights of their real meshes,
//! writing frames ParaView opens (XDMF beside the HDF5 file).

#[path = "common/mpi_launch.rs"]
mod mpi_launch;

use mpi_launch::{assert_success, run_mufe, DEFAULT_TIMEOUT};
use std::path::Path;
use std::process::Command;

const GENERATOR: [&str; 9] = [
    "sand",
    "--box",
    "--grains",
    "27",
    "--seeding",
    "2.5e-4",
    "--level",
    "2",
    "--out",
];

#[test]
fn the_demo_is_the_generator_output() {
    let dir = std::env::temp_dir().join(format!("mufe-shapes-demo-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let out = Command::new(env!("CARGO_BIN_EXE_mufe"))
        .args(GENERATOR)
        .arg(&dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let shipped = Path::new(env!("CARGO_MANIFEST_DIR")).join("jobs/shapes");
    let mut files: Vec<_> = std::fs::read_dir(&shipped)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    files.sort();
    assert_eq!(files.len(), 28, "{files:?}");
    for f in files {
        assert!(
            std::fs::read(shipped.join(&f)).unwrap() == std::fs::read(dir.join(&f)).unwrap(),
            "jobs/shapes/{} differs from `mufe {} jobs/shapes`",
            f.to_string_lossy(),
            GENERATOR.join(" ")
        );
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn the_demo_starts_on_two_ranks_with_mesh_weighted_partition_and_frames() {
    let dir = std::env::temp_dir().join(format!("mufe-shapes-run-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("jobs/shapes/scene.toml");
    let out = run_mufe(
        2,
        &[
            "run",
            scene.to_str().unwrap(),
            "--out",
            dir.to_str().unwrap(),
            "--max-steps",
            "300",
        ],
        DEFAULT_TIMEOUT,
    );
    assert_success(&out);
    let stdout = String::from_utf8_lossy(&out.stdout);
    // METIS balances the ranks by the grains' element and surface-node counts
    let owns: Vec<usize> = stdout
        .lines()
        .filter_map(|l| l.split("owns ").nth(1))
        .filter_map(|r| r.split_whitespace().next()?.parse().ok())
        .collect();
    assert!(
        stdout.contains("ranks: 2 (METIS)") && !owns.is_empty(),
        "{stdout}"
    );
    assert!(dir.join("results.h5").exists() && dir.join("results.xdmf").exists());
    let xdmf = std::fs::read_to_string(dir.join("results.xdmf")).unwrap();
    assert!(
        xdmf.contains("results.h5") && xdmf.contains("Tetrahedron"),
        "{xdmf}"
    );
    std::fs::remove_dir_all(&dir).ok();
}
