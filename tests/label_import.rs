//! `mufe import` of a labelled image (issue 15, item 3): three balls cut from one another
//! by their bisecting planes, so each pair touches over a flat face, become three
//! non-overlapping grains whose volumes are within 3 % of their voxels', whose contact faces
//! coincide, and whose scene `mufe check` accepts and `mufe run` starts stress-free.

use std::path::Path;
use std::process::Command;

use mufe::image::nrrd::write_nrrd;
use mufe::image::scene::{import_labels, ImportOptions};
use mufe::image::LabelImage;

#[path = "../src/testing.rs"]
mod testing;
use testing::TestDir;

const VOXEL: f64 = 1.0e-5; // m
const RADIUS: f64 = 9.0; // voxels
const CENTRES: [[f64; 3]; 3] = [[0.0, 0.0, 0.0], [15.0, 0.0, 0.0], [7.5, 13.0, 0.0]]; // voxels

/// Voxel centres within RADIUS of a centre take the label of the nearest one.
fn three_touching_balls() -> LabelImage {
    let n = 44usize;
    let shift = [14.0, 12.0, 22.0];
    let mut labels = vec![0u32; n * n * n];
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let p = [
                    i as f64 - shift[0],
                    j as f64 - shift[1],
                    k as f64 - shift[2],
                ];
                let d: Vec<f64> = CENTRES
                    .iter()
                    .map(|c| (0..3).map(|a| (p[a] - c[a]).powi(2)).sum::<f64>().sqrt())
                    .collect();
                let (best, dist) =
                    d.iter().enumerate().fold(
                        (0, f64::INFINITY),
                        |b, (g, &x)| if x < b.1 { (g, x) } else { b },
                    );
                if dist <= RADIUS {
                    labels[i + n * (j + n * k)] = best as u32 + 1;
                }
            }
        }
    }
    LabelImage {
        size: [n; 3],
        labels,
        spacing: None,
        origin: [0.0; 3],
    }
}

fn mufe(args: &[&str], dir: &Path) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_mufe"))
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap()
}

/// `mufe import LABELS --out SCENE` succeeds with `grains` grains and no overlapping pair;
/// returns its report.
fn import_without_overlap(labels: &str, scene: &str, grains: usize, dir: &Path) -> String {
    let out = mufe(&["import", labels, "--out", scene], dir);
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let summary = format!("{grains} grains; 0 pairs with vertices inside each other");
    assert!(text.contains(&summary), "{text}");
    text
}

#[test]
fn three_touching_labels_become_three_grains_that_meet_without_overlap() {
    let image = three_touching_balls();
    let imported = import_labels(&image, "balls.nrrd", &{
        ImportOptions {
            voxel_size: Some(VOXEL),
            ..ImportOptions::default()
        }
    })
    .unwrap();
    assert_eq!(imported.grains.len(), 3);
    for g in &imported.grains {
        let v = mufe::mesh::import::checks::signed_volume(&g.surface);
        let e = v / g.voxel_volume - 1.0;
        assert!(
            e.abs() < 0.03,
            "label {}: volume error {:.2} %",
            g.label,
            100.0 * e
        );
        assert!(
            g.shared > 10,
            "label {}: {} contact vertices",
            g.label,
            g.shared
        );
    }
    assert_eq!(imported.pairs.len(), 3);
    for p in &imported.pairs {
        let (a, b) = (p.first_in_second, p.second_in_first);
        assert!(a.touching > 10 && b.touching > 10, "{p:?}");
        assert_eq!(a.inside + b.inside, 0, "{p:?}");
    }
}

#[test]
fn the_imported_scene_checks_and_starts_stress_free() {
    let dir = TestDir::new("label_import_run");
    let image = three_touching_balls();
    write_nrrd(&dir.join("balls.nrrd"), &image, [VOXEL; 3]).unwrap();
    import_without_overlap("balls.nrrd", "balls.toml", 3, &dir);
    for l in 1..=3 {
        assert!(dir.join(format!("balls_grains/label_{l}.msh")).is_file());
    }
    let out = mufe(&["check", "balls.toml"], &dir);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("3 grains"));
    // 400 steps with no load (mass-scaled to 0.1 ns: TetGen's smallest elements sit at the
    // ends of the line where all three grains meet): coincident faces exert no force.
    let out = mufe(
        &[
            "run",
            "balls.toml",
            "--out",
            "run",
            "--set",
            "simulation.target_dt=1e-10",
            "--set",
            "simulation.duration=4e-8",
        ],
        &dir,
    );
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let energy = text.lines().find(|l| l.starts_with("energy:")).unwrap();
    let value = |name: &str| -> f64 {
        energy
            .split(&format!("{name} "))
            .nth(1)
            .and_then(|s| s.split_whitespace().next())
            .unwrap()
            .parse()
            .unwrap()
    };
    // The scale: the energy of a strain of 1e-7 over one voxel of the scene's material
    // (E = 70 GPa as written by the importer) — far below any load a run would apply.
    let youngs_modulus = 7.0e10;
    let bound = 0.5 * youngs_modulus * 1e-14 * VOXEL.powi(3);
    let (kinetic, strain) = (value("kinetic"), value("strain"));
    assert!(kinetic + strain < bound, "{energy} (bound {bound:e} J)");
}

#[test]
fn a_header_without_spacing_or_unit_is_refused_naming_the_field() {
    let dir = TestDir::new("label_import_errors");
    let mut image = three_touching_balls();
    image.labels.truncate(8);
    image.size = [2, 2, 2];
    std::fs::write(
        dir.join("plain.nrrd"),
        "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2 2 1\nspacings: 0.01 0.01 0.01\nencoding: ascii\n\n1 1\n0 0\n",
    )
    .unwrap();
    let out = mufe(&["import", "plain.nrrd", "--out", "s.toml"], &dir);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("plain.nrrd: space units:"), "{err}");
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(!dir.join("s.toml").exists());
    let out = mufe(
        &["import", "plain.nrrd", "--out", "s.toml", "--voxel-size=-1"],
        &dir,
    );
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--voxel-size"));
}

#[test]
fn a_virtual_sand_image_imports_as_its_grains_touching_without_overlap() {
    let dir = TestDir::new("label_import_sand");
    let out = mufe(
        &[
            "sand",
            "--out",
            "sand",
            "--grains",
            "4",
            "--size",
            "1e-3",
            "--image-voxel",
            "8e-5",
        ],
        &dir,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = import_without_overlap("sand/labels.nrrd", "sand/imported.toml", 4, &dir);
    // every grain within 3 % of its voxels' volume, and some pairs in contact
    for line in text.lines().filter(|l| l.starts_with("label ")) {
        let pct: f64 = line
            .split(" % from the voxels' volume")
            .next()
            .and_then(|s| s.rsplit(' ').next())
            .unwrap()
            .parse()
            .unwrap();
        assert!(pct.abs() < 3.0, "{line}");
    }
    assert!(text.lines().any(|l| l.starts_with("pair ")), "{text}");
    // the TIFF stack of the same image gives the same grains (voxels per label, no overlap)
    let tiff = import_without_overlap("sand/labels.tif", "sand/from_tiff.toml", 4, &dir);
    let voxels = |t: &str| -> Vec<String> {
        t.lines()
            .filter(|l| l.starts_with("label "))
            .map(|l| l.split(" voxels").next().unwrap().to_string())
            .collect()
    };
    assert_eq!(voxels(&text), voxels(&tiff), "{tiff}");
    let out = mufe(&["check", "sand/imported.toml"], &dir);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("4 grains"));
}

#[test]
fn a_stated_gap_separates_the_grains_and_bad_gaps_are_refused() {
    let image = three_touching_balls();
    let gap = 0.2 * VOXEL;
    let opts = ImportOptions {
        voxel_size: Some(VOXEL),
        gap,
        ..ImportOptions::default()
    };
    let imported = import_labels(&image, "balls.nrrd", &opts).unwrap();
    assert!(imported.grains.iter().all(|g| g.mesh.is_none()));
    for p in &imported.pairs {
        let (a, b) = (p.first_in_second, p.second_in_first);
        assert_eq!(a.touching + b.touching + a.inside + b.inside, 0, "{p:?}");
    }
    // the faces moved apart by the gap: across the contact face the vertices of one grain
    // are G from the other; at the rim, where vertex normals tilt, no less than G/2
    let (s1, s2) = (&imported.grains[0].surface, &imported.grains[1].surface);
    let near: Vec<f64> = s1
        .points
        .iter()
        .map(|p| mufe::image::overlap::distance_to_surface(*p, s2))
        .filter(|&d| d < 2.0 * gap)
        .collect();
    let closest = near.iter().copied().fold(f64::INFINITY, f64::min);
    let at_gap = near
        .iter()
        .filter(|&&d| (d / gap - 1.0).abs() < 0.05)
        .count();
    assert!(closest > 0.5 * gap, "closest {closest:e} vs gap {gap:e}");
    assert!(
        at_gap as f64 > 0.7 * near.len() as f64,
        "{at_gap} of {} near vertices at the gap",
        near.len()
    );
    for bad in [0.05 * VOXEL, 0.5 * VOXEL, -VOXEL] {
        let e = import_labels(
            &image,
            "balls.nrrd",
            &ImportOptions {
                gap: bad,
                ..opts.clone()
            },
        )
        .unwrap_err();
        assert_eq!(e.item, "--gap", "{e}");
    }
}
