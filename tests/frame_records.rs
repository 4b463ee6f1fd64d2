//! Per-grain and per-contact records in frames, and the grain-pair columns of `/history`,
//! on an oblique collision of two glass spheres: free flight is rigid translation, the
//! contact record joins the two grains along their line of centres, and the pair columns
//! of `/history` follow the contact points. (The grains' averaged stress is checked
//! against the wall forces in equilibrium by `tests/fcc_cell_stages.rs`.)

use std::process::Command;

const RADIUS: f64 = 1.0e-3;
const SPEED: [f64; 3] = [0.3, 0.0, 5.0];

fn scene() -> String {
    format!(
        r#"
[simulation]
duration = 1.0e-5   # s
[materials.glass]
youngs_modulus = 63e9
poisson_ratio = 0.22
density = 2500.0
[contact]
friction = 0.3
[[grains]]
name = "a"
material = "glass"
shape = {{ sphere = {{ radius = {RADIUS:e}, seeding = 4.0e-4 }} }}
centre = [0.0, 0.0, 0.0]
velocity = {SPEED:?}
[[grains]]
name = "b"
material = "glass"
shape = {{ sphere = {{ radius = {RADIUS:e}, seeding = 4.0e-4 }} }}
centre = [0.0, 0.0, 1.995e-3]
velocity = [0.0, 0.0, -5.0]
[output]
frame_interval = 1.25e-6
"#
    )
}

fn read(f: &hdf5::File, path: &str) -> Vec<f64> {
    f.dataset(path).unwrap().read_raw::<f64>().unwrap()
}

#[test]
fn frames_carry_grain_and_contact_records() {
    let dir = std::env::temp_dir().join(format!("mufe_records_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("collision.toml");
    std::fs::write(&path, scene()).unwrap();
    let status = Command::new(env!("CARGO_BIN_EXE_mufe"))
        .arg("run")
        .arg(&path)
        .args(["--quiet", "--out"])
        .arg(dir.join("out"))
        .status()
        .unwrap();
    assert!(status.success());
    let f = hdf5::File::open(dir.join("out/results.h5")).unwrap();
    let mut frames = f.group("frames").unwrap().member_names().unwrap();
    frames.sort();

    // frame 1, before contact: rigid translation at the initial speed, no rotation
    let t1: f64 = (f.group(&format!("frames/{}", frames[1])).unwrap())
        .attr("time")
        .unwrap()
        .read_scalar()
        .unwrap();
    let d = read(&f, &format!("frames/{}/grain_displacement", frames[1]));
    let rot = read(&f, &format!("frames/{}/grain_rotation", frames[1]));
    for k in 0..3 {
        assert!(
            (d[k] - SPEED[k] * t1).abs() <= 1e-9 * 5.0 * t1,
            "grain a: {d:?}"
        );
    }
    assert!(rot.iter().all(|r| r.abs() < 1e-12), "{rot:?}");

    // nodes of grain a (grain 0): those of its elements
    let tets = f
        .dataset("mesh/tetrahedra")
        .unwrap()
        .read_raw::<u64>()
        .unwrap();
    let grain_of = f
        .dataset("mesh/grain_of_element")
        .unwrap()
        .read_raw::<u32>()
        .unwrap();
    let mut of_a = std::collections::BTreeSet::new();
    for (t, g) in tets.chunks_exact(4).zip(&grain_of) {
        if *g == 0 {
            of_a.extend(t.iter().map(|&n| n as usize));
        }
    }
    let mut seen = 0;
    for name in &frames {
        let g = |what: &str| read(&f, &format!("frames/{name}/{what}"));
        let pairs = g("contact_grains");
        if pairs.is_empty() {
            continue;
        }
        seen += 1;
        assert_eq!(pairs, vec![0.0, 1.0]);
        let (n, fn_, ft) = (
            g("contact_normal"),
            g("contact_normal_force")[0],
            g("contact_tangential_force")[0],
        );
        let (point, disp) = (g("contact_point"), g("grain_displacement"));
        // normal along the line of centres (a → b), within the tilt of the oblique impact
        let centre_a = [disp[0], disp[1], disp[2]];
        let centre_b = [disp[3], disp[4], 1.995e-3 + disp[5]];
        let branch: Vec<f64> = (0..3).map(|k| centre_b[k] - centre_a[k]).collect();
        let len = branch.iter().map(|c| c * c).sum::<f64>().sqrt();
        let cos = (0..3).map(|k| n[k] * branch[k] / len).sum::<f64>();
        assert!(cos > 0.95, "normal {n:?} vs branch {branch:?}");
        assert!(
            fn_ > 0.0 && ft >= 0.0 && ft <= 0.3 * fn_ * 1.5,
            "Fn {fn_}, Ft {ft}"
        );
        assert!((point[2] - 0.5 * (centre_a[2] + centre_b[2])).abs() < 0.1 * RADIUS);
        // the nodal contact forces: they cancel over both grains (action and reaction),
        // and grain a's add up to the pair record's force on a, −Fn n + tangential
        let nodal = g("contact_force");
        let total: Vec<f64> = (0..3)
            .map(|k| nodal.iter().skip(k).step_by(3).sum())
            .collect();
        assert!(
            total.iter().all(|c| c.abs() < 1e-9 * fn_),
            "Σ f = {total:?}"
        );
        let on_a: Vec<f64> = (0..3)
            .map(|k| of_a.iter().map(|&node| nodal[3 * node + k]).sum())
            .collect();
        let along = (0..3).map(|k| on_a[k] * n[k]).sum::<f64>();
        assert!(
            (along + fn_).abs() < 1e-9 * fn_,
            "nodal {along} vs pair −{fn_}"
        );
        // mid-impact the stress is dynamic; compressive along the normal all the same
        let s = g("grain_stress");
        assert!(s[2] < 0.0, "σ̄_zz {} Pa", s[2]);
    }
    assert!(seen >= 1, "no frame caught the contact");

    // /history: one grain pair in contact exactly while there are contact points
    let points = read(&f, "history/contacts");
    let pairs = read(&f, "history/grain_pair_contacts");
    assert!(pairs.contains(&1.0));
    for (p, c) in pairs.iter().zip(&points) {
        assert_eq!(*p, if *c > 0.0 { 1.0 } else { 0.0 });
    }
    let rotation = read(&f, "history/mean_grain_rotation");
    assert!(
        rotation.last().unwrap() > &1e-5,
        "friction spins the grains"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
