//! The periodic FCC cell (issue 12): `jobs/periodic/thornton_cell.toml`, one cubic cell
//! of 4 spheres repeated along x, y, z (no walls), isotropic compression on the cell's
//! homogenised stress, then axial shortening at a constant inertial number with σx = σy
//! servo-held, to failure.
//! - both stages end as they should (stress held; failure + margin) and the servo holds
//!   the lateral stress;
//! - the peak σ1/σ3 is within 2 % of Thornton's 2(1+μ)/(1−μ) for the scene's μ;
//! - the Love–Weber contact stress equals the volume average of the grains' Cauchy
//!   stress once the cell slides slowly (equilibrium), and the ledger balances with the
//!   cell's work in ALLWK;
//! - `/history` is the same on 2 and 3 ranks as on 1 (1e-10 of each series' scale): the
//!   images of grains on other ranks come through the halo, shifted by the cell.

#[path = "common/mpi_launch.rs"]
mod mpi_launch;
#[path = "common/results.rs"]
mod results;

use results::{
    assert_held_then_failed, assert_lateral_stress_held, assert_same_history, column, history,
    stage2_peak_ratio,
};
use std::path::{Path, PathBuf};

const SCENE: &str = "jobs/periodic/thornton_cell.toml";

fn scene_path(scene: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(scene)
}

/// Runs `scene` on `ranks` ranks (1 thread each); returns the output directory and stdout.
fn run(scene: &str, ranks: usize, name: &str) -> (PathBuf, String) {
    mpi_launch::run_scene(scene, ranks, &format!("periodic_{name}"))
}

#[test]
fn the_periodic_cell_fails_at_thornton_and_agrees_on_two_and_three_ranks() {
    let scene = mufe::scene::load_scene(&scene_path(SCENE), &[])
        .unwrap()
        .scene;
    let mu = scene.contact.friction;
    let sigma3 = 5.0e4;
    let (serial_dir, stdout) = run(SCENE, 1, "r1");
    let serial = history(&serial_dir.join("results.h5"));
    assert_held_then_failed(&stdout);
    let stage = column(&serial, "stage");
    let end1 = stage.iter().rposition(|&s| s == 1.0).unwrap();
    for a in ["sigma_x", "sigma_y", "sigma_z"] {
        let s = column(&serial, a)[end1];
        assert!((s / sigma3 - 1.0).abs() <= 0.01, "{a} = {s:.5e} Pa");
    }
    assert_lateral_stress_held(&serial, sigma3, 0.05);
    let peak = stage2_peak_ratio(&serial);
    let thornton = 2.0 * (1.0 + mu) / (1.0 - mu);
    assert!(
        (peak / thornton - 1.0).abs() <= 0.02,
        "peak σ1/σ3 = {peak:.4} against Thornton {thornton:.4} (μ = {mu})"
    );

    // sliding slowly at the end: Love–Weber = volume-averaged grain stress
    let last = stage.len() - 1;
    let scale = column(&serial, "cell_contact_stress_zz")[last];
    for c in ["xx", "yy", "zz", "yz", "xz", "xy"] {
        let lw = column(&serial, &format!("cell_contact_stress_{c}"))[last]
            + column(&serial, &format!("cell_kinetic_stress_{c}"))[last];
        let grains = column(&serial, &format!("cell_grain_stress_{c}"))[last];
        assert!(
            (lw - grains).abs() <= 0.005 * scale,
            "{c}: Love–Weber {lw:.5e} Pa, grains {grains:.5e} Pa"
        );
    }
    // the ledger closes with the cell's work as the only external work
    let work = column(&serial, "external_work");
    let cell = column(&serial, "cell_work");
    let balance = column(&serial, "energy_balance");
    let w_max = work.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    for i in 0..work.len() {
        assert_eq!(work[i], cell[i], "row {i}: ALLWK is the cell's work");
        assert!(
            balance[i].abs() <= 5e-4 * w_max,
            "row {i}: ETOTAL {:.3e} J of ALLWK {w_max:.3e} J",
            balance[i]
        );
    }

    // the cell's work is ∫ V σ : D dt (σ the Love–Weber stress, sampled at the rows)
    let length: Vec<&[f64]> = ["x", "y", "z"]
        .iter()
        .map(|a| column(&serial, &format!("cell_length_{a}")))
        .collect();
    let sigma: Vec<&[f64]> = ["xx", "yy", "zz"]
        .iter()
        .map(|c| column(&serial, &format!("cell_contact_stress_{c}")))
        .collect();
    let mut stress_power = 0.0;
    for i in 1..work.len() {
        let volume = |j: usize| length.iter().map(|l| l[j]).product::<f64>();
        for k in 0..3 {
            let (l0, l1) = (length[k][i - 1], length[k][i]);
            let mean = |v: &[f64]| 0.5 * (v[i - 1] + v[i]);
            stress_power -=
                0.5 * (volume(i - 1) + volume(i)) * mean(sigma[k]) * (l1 - l0) / (0.5 * (l0 + l1));
        }
    }
    let done = cell[cell.len() - 1] - cell[0];
    assert!(
        (stress_power / done - 1.0).abs() <= 0.005,
        "∫ V σ:D dt = {stress_power:.5e} J, cell work {done:.5e} J"
    );

    for ranks in [2, 3] {
        let (dir, _) = run(SCENE, ranks, &format!("r{ranks}"));
        let parallel = history(&dir.join("results.h5"));
        assert_same_history(&serial, &parallel, w_max, &format!("{ranks} ranks"));
        let _ = std::fs::remove_dir_all(dir);
    }
    let _ = std::fs::remove_dir_all(serial_dir);
}

#[test]
fn a_grain_leaving_the_cell_is_wrapped_and_its_displacement_stays_continuous() {
    const WRAP: &str = "jobs/tests/periodic_wrap.toml";
    let loaded = mufe::scene::load_scene(&scene_path(WRAP), &[])
        .unwrap()
        .scene;
    let speed = loaded.grains[0].velocity[0];
    let mut finals = Vec::new();
    for ranks in [1, 2] {
        let (out, stdout) = run(WRAP, ranks, &format!("wrap{ranks}"));
        assert!(
            stdout.contains("grains wrapped back into the periodic cell"),
            "no wrap on {ranks} ranks:\n{stdout}"
        );
        let f = hdf5::File::open(out.join("results.h5")).unwrap();
        let mut frames = f.group("frames").unwrap().member_names().unwrap();
        frames.sort();
        // the mover's reported displacement grows as v t through the wrap: no jump of 4R
        for name in &frames {
            let g = f.group(&format!("frames/{name}")).unwrap();
            let t: f64 = g.attr("time").unwrap().read_scalar().unwrap();
            let u = g
                .dataset("grain_displacement")
                .unwrap()
                .read_raw::<f64>()
                .unwrap();
            assert!(
                (u[0] - speed * t).abs() <= 1e-6 * speed * t.max(1e-4),
                "{ranks} ranks, t = {t:e} s: displacement {:e} m, v t = {:e} m",
                u[0],
                speed * t
            );
        }
        let h = history(&out.join("results.h5"));
        let balance = column(&h, "energy_balance");
        let kinetic = column(&h, "kinetic_energy")[0];
        // ETOTAL holds the initial kinetic energy; what matters is that it stays put
        assert!(balance
            .iter()
            .all(|b| (b - balance[0]).abs() <= 1e-9 * kinetic));
        finals.push(column(&h, "kinetic_energy").to_vec());
        let _ = std::fs::remove_dir_all(out);
    }
    assert_eq!(finals[0], finals[1], "1 and 2 ranks");
}
