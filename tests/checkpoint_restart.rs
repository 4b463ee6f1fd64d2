//! Checkpoint and restart (issue 13, item 3) on `jobs/tests/two_spheres_stages.toml`:
//! - a run stopped after a checkpoint and restarted from it continues `results.h5`
//!   bitwise as the uninterrupted run wrote it (history, frames), serially and on 2 ranks
//!   (each rank its own hyperslab of the checkpoint), and so does the same checkpoint
//!   rewritten as format 2 wrote it (vectors as JSON numbers, byte-by-byte checksums);
//! - only the newest `output.checkpoints_kept` files remain, no temporary file is left,
//!   and the file states its format, step, time and rank count;
//! - a checkpoint of another format version or another scene, or one whose checksum
//!   fails, is refused with exit 2 and one line naming the file and what is wrong (other
//!   rank counts, `latest`, faults and branches: `tests/checkpoint_faults.rs`).

#[path = "common/mpi_launch.rs"]
mod mpi_launch;
#[path = "common/results.rs"]
mod results;

use mufe::io::checkpoint::CHECKPOINT_FORMAT;
use mufe::io::results::fnv1a;
use results::history;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::Duration;

const SCENE: &str = "jobs/tests/two_spheres_stages.toml";

fn scene() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join(SCENE)
        .to_string_lossy()
        .into_owned()
}

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("mufe_ckpt_{name}_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

fn mufe(ranks: usize, args: &[&str]) -> Output {
    let mut all = vec!["run", "--threads", "1", "--quiet"];
    all.extend_from_slice(args);
    mpi_launch::run_mufe(ranks, &all, Duration::from_secs(120))
}

fn frames(path: &Path) -> Vec<(String, Vec<f64>)> {
    let f = hdf5::File::open(path).unwrap();
    let g = f.group("frames").unwrap();
    let mut names = g.member_names().unwrap();
    names.sort();
    let mut out = Vec::new();
    for n in names {
        for field in ["displacement", "velocity", "stress", "grain_rotation"] {
            let v = g
                .dataset(&format!("{n}/{field}"))
                .unwrap()
                .read_raw::<f64>()
                .unwrap();
            out.push((format!("{n}/{field}"), v));
        }
    }
    out
}

fn restart_continues_bitwise(ranks: usize) {
    let s = scene();
    let whole = dir(&format!("whole{ranks}"));
    let o = mufe(ranks, &[&s, "--out", whole.to_str().unwrap()]);
    mpi_launch::assert_success(&o);

    // stopped at step 11000 with checkpoints every 4000 steps: 4000, 8000 written, the
    // newest 2 kept; restarted from 8000 (in stage 2) it must rewrite steps 8001…11000
    // exactly as before and go on as the whole run did
    let part = dir(&format!("part{ranks}"));
    let out = part.to_str().unwrap();
    let o = mufe(
        ranks,
        &[
            &s,
            "--out",
            out,
            "--checkpoint-every",
            "4000",
            "--max-steps",
            "11000",
        ],
    );
    mpi_launch::assert_success(&o);
    let ckpt = part.join("checkpoints");
    let mut files: Vec<String> = std::fs::read_dir(&ckpt)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    files.sort();
    // the end of stage 1 is kept outside the rotation
    let stage_file = ckpt.join("stage_1_press.h5");
    assert_eq!(
        files,
        [
            "stage_1_press.h5",
            "step_000000004000.h5",
            "step_000000008000.h5"
        ],
        "kept files"
    );
    files.remove(0);
    let f = hdf5::File::open(ckpt.join(&files[1])).unwrap();
    let attr = |n: &str| f.attr(n).unwrap().read_scalar::<u64>().unwrap();
    assert_eq!(
        (attr("format_version"), attr("step"), attr("ranks")),
        (CHECKPOINT_FORMAT, 8000, ranks as u64)
    );
    drop(f);

    let from = ckpt.join(&files[1]);
    let o = mufe(
        ranks,
        &[&s, "--out", out, "--restart", from.to_str().unwrap()],
    );
    mpi_launch::assert_success(&o);

    assert_same_as_whole(&whole, &part);

    // a restart from the end of stage 1 also continues exactly as the whole run went on
    let f = hdf5::File::open(&stage_file).unwrap();
    let stage_step = f.attr("step").unwrap().read_scalar::<u64>().unwrap();
    assert!(
        stage_step > 0 && stage_step < 11000,
        "stage 1 ended at step {stage_step}"
    );
    drop(f);
    let o = mufe(
        ranks,
        &[&s, "--out", out, "--restart", stage_file.to_str().unwrap()],
    );
    mpi_launch::assert_success(&o);
    assert_same_as_whole(&whole, &part);

    // a checkpoint of format 2 (the state's vectors as JSON numbers, checksums byte by
    // byte), as mufe wrote them before format 3, also continues exactly
    let old = part.join("format_2.h5");
    rewrite_as_format_2(&from, &old);
    let o = mufe(
        ranks,
        &[&s, "--out", out, "--restart", old.to_str().unwrap()],
    );
    mpi_launch::assert_success(&o);
    assert_same_as_whole(&whole, &part);
    let _ = std::fs::remove_dir_all(whole);
    let _ = std::fs::remove_dir_all(part);
}

/// Copies the checkpoint `from` (format 3) to `to` as format 2 wrote it: every rank's
/// state with its positions, velocities and detection reference as JSON arrays of
/// numbers, and every checksum FNV-1a over the block's bytes.
fn rewrite_as_format_2(from: &Path, to: &Path) {
    std::fs::copy(from, to).unwrap();
    let f = hdf5::File::open_rw(to).unwrap();
    let u64s = |name: &str| f.dataset(name).unwrap().read_raw::<u64>().unwrap();
    let offsets = u64s("state_offsets");
    let state = f.dataset("state").unwrap().read_raw::<u8>().unwrap();
    let (mut bytes, mut new_offsets, mut sums) = (Vec::new(), vec![0u64], Vec::new());
    for w in offsets.windows(2) {
        let block = &state[w[0] as usize..w[1] as usize];
        let mut json: serde_json::Value = serde_json::from_slice(block).unwrap();
        let unpack = |v: &mut serde_json::Value| {
            let packed = v.as_str().expect("format 3 packs the vectors");
            let vectors = mufe::packed_vectors::decode(packed).unwrap();
            *v = serde_json::to_value(vectors).unwrap();
        };
        unpack(&mut json["x"]);
        unpack(&mut json["v"]);
        unpack(&mut json["contact"]["detection"]["x_ref"]);
        let text = serde_json::to_vec(&json).unwrap();
        sums.push(fnv1a(&text));
        bytes.extend(text);
        new_offsets.push(bytes.len() as u64);
    }
    f.unlink("state").unwrap();
    let ds = f
        .new_dataset::<u8>()
        .shape(bytes.len())
        .create("state")
        .unwrap();
    ds.write(&bytes).unwrap();
    f.dataset("state_offsets")
        .unwrap()
        .write(&new_offsets)
        .unwrap();
    f.dataset("state_checksums").unwrap().write(&sums).unwrap();
    let totals = f.dataset("totals").unwrap().read_raw::<u8>().unwrap();
    let sums: Vec<u64> = (u64s("totals_offsets").windows(2))
        .map(|w| fnv1a(&totals[w[0] as usize..w[1] as usize]))
        .collect();
    f.dataset("totals_checksums").unwrap().write(&sums).unwrap();
    let packages = f.dataset("grains").unwrap().read_raw::<f64>().unwrap();
    let (ids, lengths) = (u64s("grain_ids"), u64s("grain_package_lengths"));
    let (id_rows, value_rows) = (u64s("grain_ids_offsets"), u64s("grains_offsets"));
    let mut sums = Vec::new();
    for (rows, values) in id_rows.windows(2).zip(value_rows.windows(2)) {
        let (rows, values) = (
            rows[0] as usize..rows[1] as usize,
            values[0] as usize..values[1] as usize,
        );
        let mut block = Vec::new();
        block.extend(ids[rows.clone()].iter().flat_map(|v| v.to_le_bytes()));
        block.extend(lengths[rows].iter().flat_map(|v| v.to_le_bytes()));
        block.extend(packages[values].iter().flat_map(|v| v.to_le_bytes()));
        sums.push(fnv1a(&block));
    }
    f.dataset("grains_checksums").unwrap().write(&sums).unwrap();
    f.attr("format_version")
        .unwrap()
        .write_scalar(&2u64)
        .unwrap();
}

/// `part/results.h5` holds bitwise the history and frames of `whole/results.h5`.
fn assert_same_as_whole(whole: &Path, part: &Path) {
    let (a, b) = (
        history(&whole.join("results.h5")),
        history(&part.join("results.h5")),
    );
    assert_eq!(a.len(), b.len());
    for ((name, x), (_, y)) in a.iter().zip(&b) {
        assert_eq!(x.len(), y.len(), "/history/{name}: rows");
        for (i, (p, q)) in x.iter().zip(y).enumerate() {
            assert!(
                p.to_bits() == q.to_bits(),
                "/history/{name}[{i}]: restarted {q:e}, whole {p:e}"
            );
        }
    }
    let (fa, fb) = (
        frames(&whole.join("results.h5")),
        frames(&part.join("results.h5")),
    );
    assert_eq!(fa.len(), fb.len(), "frames");
    for ((name, x), (_, y)) in fa.iter().zip(&fb) {
        assert!(x == y, "/frames/{name} differs after the restart");
    }
}

#[test]
fn a_restarted_serial_run_continues_bitwise() {
    restart_continues_bitwise(1);
}

#[test]
fn a_restarted_two_rank_run_continues_bitwise() {
    restart_continues_bitwise(2);
}

#[test]
fn foreign_checkpoints_are_refused_with_one_line() {
    let s = scene();
    let d = dir("refuse");
    let out = d.to_str().unwrap();
    let o = mufe(
        1,
        &[
            &s,
            "--out",
            out,
            "--checkpoint-every",
            "3000",
            "--max-steps",
            "3000",
        ],
    );
    mpi_launch::assert_success(&o);
    let ckpt = d.join("checkpoints/step_000000003000.h5");
    let refused = |o: &Output, what: &str| {
        let err = String::from_utf8_lossy(&o.stderr);
        let line = err
            .lines()
            .find(|l| l.contains("error"))
            .unwrap_or_default();
        assert!(
            !o.status.success() && line.contains(ckpt.to_str().unwrap()) && line.contains(what),
            "expected a refusal naming {what}:\n{err}"
        );
        assert_eq!(o.status.code(), Some(2), "{err}");
    };
    let restart_serially = |extra: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_mufe"))
            .args([
                "run",
                &s,
                "--quiet",
                "--out",
                out,
                "--restart",
                ckpt.to_str().unwrap(),
            ])
            .args(extra)
            .output()
            .unwrap()
    };
    // another scene (a --set value changes the scene as run)
    let o = restart_serially(&["--set", "contact.friction=0.5"]);
    refused(&o, "scene");
    // a damaged state (one byte changed)
    {
        let f = hdf5::File::open_rw(&ckpt).unwrap();
        let ds = f.dataset("state").unwrap();
        let byte = ds.read_slice_1d::<u8, _>(100..101).unwrap()[0];
        ds.write_slice(&[byte ^ 0x01], 100..101).unwrap();
    }
    let o = restart_serially(&[]);
    refused(&o, "damaged");
    // another format version
    {
        let f = hdf5::File::open_rw(&ckpt).unwrap();
        f.attr("format_version")
            .unwrap()
            .write_scalar(&99u64)
            .unwrap();
    }
    let o = restart_serially(&[]);
    refused(&o, "format");
    let _ = std::fs::remove_dir_all(d);
}

#[test]
fn a_wall_time_interval_writes_checkpoints_and_keeps_the_newest() {
    // an interval far below a step's wall time: a checkpoint after every step
    let s = scene();
    let d = dir("interval");
    let o = mufe(
        1,
        &[
            &s,
            "--out",
            d.to_str().unwrap(),
            "--max-steps",
            "5",
            "--set",
            "output.checkpoint_interval=1e-9",
            "--set",
            "output.checkpoints_kept=3",
        ],
    );
    mpi_launch::assert_success(&o);
    let mut files: Vec<String> = std::fs::read_dir(d.join("checkpoints"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    files.sort();
    assert_eq!(
        files,
        [
            "step_000000000003.h5",
            "step_000000000004.h5",
            "step_000000000005.h5"
        ]
    );
    let _ = std::fs::remove_dir_all(d);
}
