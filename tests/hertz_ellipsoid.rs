//! `mufe validate hertz_ellipsoid`: an ellipsoid imported from STL between rigid plates
//! against elliptical Hertz theory, at the quick meshing ratio, for the shipped glass and
//! for a material and size nobody tuned for; the case's input checks; the shipped scene
//! and STL are the generator's output.

#[path = "common/quick_case.rs"]
mod quick_case;

use mufe::validate::hertz_ellipsoid::{write_shipped_files, NAME};
use mufe::validate::scenes::Params;
use std::process::Command;

fn axis_ratio_is_checked(o: &mufe::validate::runner::CaseOutcome) {
    let d = &o.details;
    let ratio = d["axis_ratio_theory"].as_f64().unwrap();
    // the shipped ellipsoid's contact is clearly not a circle
    assert!(ratio < 0.8, "b/a = {ratio}");
    assert!(d["error_axis_ratio"].as_f64().unwrap() <= o.target);
    assert!(d["error_force"].as_f64().unwrap() <= o.target);
    assert!(d["samples_in_window"].as_u64().unwrap() >= 20);
}

#[test]
fn shipped_glass_ellipsoid_quick() {
    for o in quick_case::run_quick(NAME, "shipped glass", &[]) {
        axis_ratio_is_checked(&o);
    }
}

/// Steel-like constants and a grain 2.5× larger: the drive, window, mesh and theory follow
/// the scene as run.
#[test]
fn another_material_and_size_quick() {
    let sets = [
        "materials.glass.youngs_modulus=2.1e11",
        "materials.glass.poisson_ratio=0.3",
        "materials.glass.density=7800",
        "grains[0].shape.surface.scale=2.5",
    ]
    .map(String::from);
    for o in quick_case::run_quick(NAME, "steel, 2.5× size", &sets) {
        axis_ratio_is_checked(&o);
        let radii = o.details["tip_radii_m"].as_array().unwrap();
        // R1 = A²/C of the shipped 1.0 × 0.8 × 0.75 mm ellipsoid, scaled
        let r1 = radii[0].as_f64().unwrap();
        assert!(
            (r1 / (2.5 * 1e-6 / 0.75e-3) - 1.0).abs() < 1e-9,
            "R1 = {r1}"
        );
    }
}

#[test]
fn the_shipped_scene_and_stl_are_the_generator_output() {
    let dir = std::env::temp_dir().join(format!("mufe-test-he-shipped-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    write_shipped_files(&dir, &[], &Params::default()).unwrap();
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("jobs/validation");
    for file in ["hertz_ellipsoid.toml", "hertz_ellipsoid.stl"] {
        let (a, b) = (
            std::fs::read(dir.join(file)).unwrap(),
            std::fs::read(root.join(file)).unwrap(),
        );
        assert!(
            a == b,
            "{file} differs from the generator: run `mufe validate hertz_ellipsoid --write-scenes jobs/validation`"
        );
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// A case scene whose grain is not an ellipsoid pressed along its shortest axis is refused
/// with exit 2 and one line naming the file and field.
#[test]
fn a_wrong_ellipsoid_is_an_input_error() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("jobs/validation");
    let scene = std::fs::read_to_string(root.join("hertz_ellipsoid.toml")).unwrap();
    let stl = std::fs::read(root.join("hertz_ellipsoid.stl")).unwrap();
    let run = |dir: &std::path::Path, sets: &[&str]| {
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_mufe"));
        cmd.env("MUFE_VALIDATION_SCENES", dir)
            .args(["validate", NAME, "--quick", "--out"])
            .arg(dir.join("out"));
        for s in sets {
            cmd.args(["--set", s]);
        }
        cmd.output().unwrap()
    };
    let base = std::env::temp_dir().join(format!("mufe-test-he-bad-{}", std::process::id()));
    // pressed along its longest axis: the STL turned so that z is the 1 mm axis
    let long = base.join("long");
    std::fs::create_dir_all(&long).unwrap();
    std::fs::write(long.join("hertz_ellipsoid.toml"), &scene).unwrap();
    let mut swapped = stl.clone();
    for t in 0..u32::from_le_bytes(stl[80..84].try_into().unwrap()) as usize {
        for v in 0..3 {
            let o = 84 + 50 * t + 12 + 12 * v;
            // (x, y, z) → (y, z, x): a rotation (a mirror would turn the facets inward)
            let old = stl[o..o + 12].to_vec();
            swapped[o..o + 8].copy_from_slice(&old[4..12]);
            swapped[o + 8..o + 12].copy_from_slice(&old[0..4]);
        }
    }
    std::fs::write(long.join("hertz_ellipsoid.stl"), &swapped).unwrap();
    let out = run(&long, &[]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("grains[0].shape.surface.file") && err.contains("shortest axis"),
        "{err}"
    );
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    // not an ellipsoid: the shipped one stretched along x by a rotation it must not have
    let out = run(&long, &["grains[0].shape.surface.rotation=[0.0, 0.3, 0.0]"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("rotation"), "{err}");
    // a box is no ellipsoid
    let cube = base.join("cube");
    std::fs::create_dir_all(&cube).unwrap();
    std::fs::write(cube.join("hertz_ellipsoid.toml"), &scene).unwrap();
    let mut text = String::from("solid cube\n");
    let v = |i: usize| {
        [(i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64].map(|c| (c - 0.5) * 1e-3)
    };
    for f in [
        [0, 2, 1],
        [1, 2, 3],
        [4, 5, 6],
        [5, 7, 6],
        [0, 1, 4],
        [1, 5, 4],
        [2, 6, 3],
        [3, 6, 7],
        [0, 4, 2],
        [2, 4, 6],
        [1, 3, 5],
        [3, 7, 5],
    ] {
        text += "facet normal 0 0 0\nouter loop\n";
        for i in f {
            let p = v(i);
            text += &format!("vertex {:e} {:e} {:e}\n", p[0], p[1], p[2]);
        }
        text += "endloop\nendfacet\n";
    }
    text += "endsolid cube\n";
    std::fs::write(cube.join("hertz_ellipsoid.stl"), text).unwrap();
    let out = run(&cube, &[]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("is not an ellipsoid"), "{err}");
    std::fs::remove_dir_all(&base).ok();
}
