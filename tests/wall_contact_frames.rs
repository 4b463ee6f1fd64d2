//! The frames' nodal `contact_force` includes the walls: on two spheres pressed between two
//! walls (`jobs/tests/two_spheres_stages.toml`), the grain–grain forces cancel in the sum
//! over all nodes (action and reaction), so that sum is the walls' total force on the
//! grains, which `/history` records per wall. A history row stands for the step before
//! the one that wrote it, so the frame is compared with the row one step earlier, within
//! what the wall force changes in one step of this slow pressing (2 %); without the walls'
//! share the nodal sum would be zero.

#[path = "common/results.rs"]
mod results;

use std::path::Path;
use std::process::Command;

#[test]
fn nodal_contact_forces_add_up_to_the_wall_forces() {
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("jobs/tests/two_spheres_stages.toml");
    let out = Path::new(env!("CARGO_TARGET_TMPDIR")).join("wall_contact_frames");
    let _ = std::fs::remove_dir_all(&out);
    let o = Command::new(env!("CARGO_BIN_EXE_mufe"))
        .args(["run", scene.to_str().unwrap(), "--quiet", "--threads", "1"])
        .args(["--out", out.to_str().unwrap(), "--max-steps", "12000"])
        // a history row at every frame step, whatever the step
        .args(["--set", "output.frame_interval=1e-5"])
        .args(["--set", "output.history_interval=1e-5"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let path = out.join("results.h5");
    let h = results::history(&path);
    let time = results::column(&h, "time");
    let walls: Vec<[&[f64]; 3]> = ["bottom", "top"]
        .iter()
        .map(|w| ["x", "y", "z"].map(|c| results::column(&h, &format!("{w}_force_{c}"))))
        .collect();
    let f = hdf5::File::open(&path).unwrap();
    let frames = f.group("frames").unwrap();
    let mut checked = 0;
    for name in frames.member_names().unwrap() {
        let g = frames.group(&name).unwrap();
        let t: f64 = g.attr("time").unwrap().read_scalar().unwrap();
        let interval = time[1] - time[0];
        let Some(row) = time
            .iter()
            .position(|&s| t > 0.0 && (s - t).abs() <= 0.01 * interval)
        else {
            continue;
        };
        let nodal = g
            .dataset("contact_force")
            .unwrap()
            .read_raw::<f64>()
            .unwrap();
        let sum: Vec<f64> = (0..3)
            .map(|k| nodal.iter().skip(k).step_by(3).sum())
            .collect();
        let expected: Vec<f64> = (0..3)
            .map(|k| walls.iter().map(|w| w[k][row]).sum())
            .collect();
        let scale = walls.iter().map(|w| w[2][row].abs()).fold(0.0, f64::max);
        if scale == 0.0 {
            continue;
        }
        for k in 0..3 {
            assert!(
                (sum[k] - expected[k]).abs() <= 0.02 * scale,
                "frame {name}: Σ nodal contact force {sum:?} N, walls {expected:?} N"
            );
        }
        checked += 1;
    }
    assert!(
        checked >= 3,
        "frames at history rows with walls in contact: {checked}"
    );
}
