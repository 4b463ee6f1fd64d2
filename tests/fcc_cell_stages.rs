//! The walled triaxial test in miniature (issue 11, item 8): `jobs/tests/fcc_cell_stages.toml`,
//! one closed FCC cell of 14 spheres in six walls, isotropic compression to σ3 = 50 kPa
//! then axial strain at a constant inertial number with the lateral walls servo-held.
//! - both stages run and end as they should: stage 1 by holding the stress, stage 2 by
//!   failure (+ margin), with the peak stress ratio above the frictionless bound 2 and not
//!   above Thornton's 2(1+μ)/(1−μ);
//! - the servos hold σ3 within 1 % at the end of stage 1 and within 8 % while the cell
//!   fails (the stress ratio divides by the measured lateral stress, so this tolerance is
//!   on the loading path, not on the ratio);
//! - the cell's 36 lattice contacts all carry load after stage 1;
//! - Love–Weber: at the last frame the grains' volume-averaged stresses add up to the wall
//!   forces times the wall distances (Σ V σ̄ = −F L per axis) within 2 %;
//! - `/history` is the same on 2 ranks as on 1 (1e-10 of each series' scale);
//! - `/stages` holds both stages with the summary's lines, peak and residual, and the file
//!   matches docs/RESULTS.md.

#[path = "common/mpi_launch.rs"]
mod mpi_launch;
#[path = "common/results.rs"]
mod results;

use results::{
    assert_held_then_failed, assert_lateral_stress_held, assert_matches_documented_layout,
    assert_same_history, column, history, stage2_peak_ratio,
};
use std::path::{Path, PathBuf};

const SCENE: &str = "jobs/tests/fcc_cell_stages.toml";
const MU: f64 = 0.22;
const SIGMA3: f64 = 5.0e4;
const RADIUS: f64 = 1.1e-3;

fn run(ranks: usize, name: &str) -> (PathBuf, String) {
    mpi_launch::run_scene(SCENE, ranks, &format!("fcc_stages_{name}"))
}

#[test]
fn both_stages_run_hold_fail_and_agree_on_two_ranks() {
    let (serial_dir, stdout) = run(1, "r1");
    let serial = history(&serial_dir.join("results.h5"));
    assert_held_then_failed(&stdout);
    assert!(stdout.contains("first gap opening between initially touching grains"));

    let stage = column(&serial, "stage");
    let end1 = stage.iter().rposition(|&s| s == 1.0).unwrap();
    let lateral = ["x_min", "x_max", "y_min", "y_max"];
    for w in lateral.iter().chain(&["top"]) {
        let e = column(&serial, &format!("{w}_stress_error"))[end1];
        assert!(e.abs() <= 0.01, "{w}: {e:+.4} at the end of stage 1");
    }
    assert_eq!(column(&serial, "grain_pair_contacts")[end1], 36.0);
    assert_lateral_stress_held(&serial, SIGMA3, 0.08);
    let peak = stage2_peak_ratio(&serial);
    let thornton = 2.0 * (1.0 + MU) / (1.0 - MU);
    assert!(
        peak > 2.0 && peak <= thornton,
        "peak σ1/σ3 = {peak:.4} (Thornton {thornton:.4})"
    );

    love_weber_balances_the_walls(&serial_dir.join("results.h5"), &serial);
    stages_are_in_the_file_as_the_summary_says(&serial_dir.join("results.h5"), &stdout, peak);

    let (parallel_dir, _) = run(2, "r2");
    let parallel = history(&parallel_dir.join("results.h5"));
    let work = column(&serial, "external_work");
    let w_max = work.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert_same_history(&serial, &parallel, w_max, "2 ranks");
    for d in [serial_dir, parallel_dir] {
        let _ = std::fs::remove_dir_all(d);
    }
}

/// `/stages` holds each finished stage with the run summary's line and its figures, and
/// the file still matches docs/RESULTS.md with the staged objects expected.
fn stages_are_in_the_file_as_the_summary_says(path: &Path, stdout: &str, sampled_peak: f64) {
    let f = hdf5::File::open(path).unwrap();
    let stage = |name: &str| f.group(&format!("stages/{name}")).unwrap();
    let text = |g: &hdf5::Group, a: &str| -> String {
        let v: hdf5::types::VarLenUnicode = g.attr(a).unwrap().read_scalar().unwrap();
        v.as_str().to_string()
    };
    let number = |g: &hdf5::Group, a: &str| -> f64 {
        g.attr(a)
            .unwrap_or_else(|e| panic!("{a}: {e}"))
            .read_scalar()
            .unwrap()
    };
    let (iso, shear) = (stage("1_isotropic"), stage("2_shear"));
    assert_eq!(text(&iso, "ended_by"), "stress held");
    assert_eq!(text(&shear, "ended_by"), "failure + margin");
    for g in [&iso, &shear] {
        let line = text(g, "summary");
        assert!(stdout.contains(&line), "'{line}' is not in the summary");
    }
    assert_eq!(number(&shear, "start_time"), number(&iso, "end_time"));
    // the per-step peak, the residual after failure and the ratio at failure detection
    let peak = number(&shear, "peak_stress_ratio");
    assert!(peak >= sampled_peak, "{peak} < history's {sampled_peak}");
    let summary = text(&shear, "summary");
    assert!(
        summary.contains(&format!("peak σ1/σ3 = {peak:.4}")),
        "{summary}"
    );
    let residual = number(&shear, "residual_stress_ratio");
    assert!(
        summary.contains(&format!("(residual) = {residual:.4}")),
        "{summary}"
    );
    assert!(residual > 0.0 && residual <= peak);
    assert!(number(&shear, "failure_time") > number(&shear, "peak_time"));
    drop(f);
    assert_matches_documented_layout(path, "frames,walls,contact,grain-contact,servo,staged,cell");
}

/// Σ_g V_g σ̄_g (the frame's grain stresses over the grains' current volumes) against
/// −F_k L_k per axis (mean force of the axis' walls times their distance).
fn love_weber_balances_the_walls(path: &Path, h: &[(String, Vec<f64>)]) {
    let f = hdf5::File::open(path).unwrap();
    let mut frames = f.group("frames").unwrap().member_names().unwrap();
    frames.sort();
    let last = f
        .group(&format!("frames/{}", frames.last().unwrap()))
        .unwrap();
    let time: f64 = last.attr("time").unwrap().read_scalar().unwrap();
    let read = |g: &hdf5::Group, n: &str| g.dataset(n).unwrap().read_raw::<f64>().unwrap();
    let x0 = f.dataset("mesh/nodes").unwrap().read_raw::<f64>().unwrap();
    let u = read(&last, "displacement");
    let tets = f
        .dataset("mesh/tetrahedra")
        .unwrap()
        .read_raw::<u64>()
        .unwrap();
    let grain = f
        .dataset("mesh/grain_of_element")
        .unwrap()
        .read_raw::<u32>()
        .unwrap();
    let stress = read(&last, "grain_stress");
    let mut volume = vec![0.0; stress.len() / 6];
    for (e, t) in tets.chunks_exact(4).enumerate() {
        let p = |i: usize| {
            let n = t[i] as usize;
            [0, 1, 2].map(|k| x0[3 * n + k] + u[3 * n + k])
        };
        let (a, b, c, d) = (p(0), p(1), p(2), p(3));
        let (e1, e2, e3) = (
            [0, 1, 2].map(|k| b[k] - a[k]),
            [0, 1, 2].map(|k| c[k] - a[k]),
            [0, 1, 2].map(|k| d[k] - a[k]),
        );
        volume[grain[e] as usize] += (e1[0] * (e2[1] * e3[2] - e2[2] * e3[1])
            - e1[1] * (e2[0] * e3[2] - e2[2] * e3[0])
            + e1[2] * (e2[0] * e3[1] - e2[1] * e3[0]))
            / 6.0;
    }
    let times = column(h, "time");
    let row = (0..times.len())
        .min_by(|&i, &j| (times[i] - time).abs().total_cmp(&(times[j] - time).abs()))
        .unwrap();
    let lattice = 2.0 * std::f64::consts::SQRT_2 * RADIUS;
    for (k, axis, lo, hi) in [
        (0, "x", "x_min", "x_max"),
        (1, "y", "y_min", "y_max"),
        (2, "z", "bottom", "top"),
    ] {
        let sum: f64 = volume
            .iter()
            .enumerate()
            .map(|(g, v)| v * stress[6 * g + k])
            .sum();
        let force = 0.5
            * (column(h, &format!("{lo}_force_{axis}"))[row]
                - column(h, &format!("{hi}_force_{axis}"))[row]);
        let distance =
            lattice + 2.0 * RADIUS + column(h, &format!("{hi}_displacement_{axis}"))[row]
                - column(h, &format!("{lo}_displacement_{axis}"))[row];
        let walls = -force * distance;
        assert!(
            (sum / walls - 1.0).abs() < 0.02,
            "axis {axis}: Σ V σ̄ = {sum:.5e} N·m, walls −F L = {walls:.5e} N·m"
        );
    }
}
