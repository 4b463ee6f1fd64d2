//! Two-rank tests of the MPI layer (`mufe::domain`) and the collective results writer
//! (`mufe::io`), spawned under `mpirun -n 2` from `cargo test`.
//!
//! How to run: `cargo test --test mpi_io` (needs `mpirun` on PATH, or `MPIEXEC`). Each test
//! relaunches this executable under MPI filtered to itself; the `MUFE_MPI_CHILD` branch
//! runs on every rank, the parent checks the exit status and what the ranks wrote.

#[path = "common/mpi_launch.rs"]
mod mpi_launch;

use std::path::{Path, PathBuf};
use std::process::Command;

use hdf5::types::VarLenUnicode;
use mpi_launch::{assert_success, is_mpi_child, relaunch_test, DEFAULT_TIMEOUT};
use mufe::domain::{Domain, Exchange};
use mufe::io::{grain_row_blocks, FieldPart, HistoryColumn, MeshPart, Provenance, ResultsWriter};

const OUT_ENV: &str = "MUFE_TEST_OUT";

// The written data are functions of the global index, so every value can be checked.
const TOTAL_NODES: u64 = 11;
const TOTAL_TETS: u64 = 7;
const GRAIN_OWNERS: [u32; 3] = [0, 1, 1];
/// The frame's node rows in four "grains" owned alternately by the two ranks, so each rank
/// writes two blocks that are not contiguous in the file (as after a real partition).
const FRAME_GRAIN_NODES: [usize; 5] = [0, 3, 5, 9, TOTAL_NODES as usize];
const FRAME_GRAIN_OWNERS: [u32; 4] = [0, 1, 0, 1];
const HISTORY_ROWS: usize = 5;
const SCENE: &str = "# two-rank io test\n[run]\nend_time = 1.0\n";

fn node(i: u64) -> [f64; 3] {
    let x = i as f64;
    [0.5 * x, -x, 1e-3 * x + 7.0]
}

fn tet(e: u64) -> [u64; 4] {
    [e, e + 1, e + 2, (e + 3) % TOTAL_NODES]
}

fn grain(e: u64) -> u32 {
    (e % 3) as u32
}

fn velocity(i: u64) -> [f64; 3] {
    let x = i as f64;
    [x.sin(), x.cos(), -2.0 * x]
}

fn pressure(i: u64) -> f64 {
    1.0e5 + i as f64
}

/// Probe rows: all on rank 0, so rank 1 takes part with an empty selection.
const PROBE: [f64; 2] = [4.5, -4.5];

fn history_row(k: usize) -> [f64; 2] {
    let t = k as f64 * 0.1;
    [t, 3.0 * t * t]
}

/// Splits `total` rows unevenly: rank 0 gets the larger half.
fn block(total: u64, rank: usize, size: usize) -> (u64, u64) {
    let size = size as u64;
    let rank = rank as u64;
    let base = total / size;
    let extra = total % size;
    let rows = base + u64::from(rank < extra);
    let offset = rank * base + rank.min(extra);
    (offset, rows)
}

/// Both ranks printed `rank R <what>`.
fn assert_every_rank_said(out: &std::process::Output, what: &str) {
    let stdout = String::from_utf8_lossy(&out.stdout);
    for r in 0..2 {
        assert!(stdout.contains(&format!("rank {r} {what}")), "{stdout}");
    }
}

fn out_dir(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn two_ranks_write_results_collectively() {
    if is_mpi_child() {
        child_write_results();
        return;
    }
    let path = out_dir("mpi_io").join("results.h5");
    let _ = std::fs::remove_file(&path);
    let out = relaunch_test(
        "two_ranks_write_results_collectively",
        2,
        &[(OUT_ENV, path.to_str().unwrap())],
        DEFAULT_TIMEOUT,
    );
    assert_success(&out);
    assert_every_rank_said(&out, "wrote results");
    check_results_file(&path);

    // h5dump must be able to read the file too (when installed).
    if Command::new("h5dump").arg("--version").output().is_ok() {
        let dump = Command::new("h5dump")
            .arg("-H")
            .arg(&path)
            .output()
            .unwrap();
        assert!(
            dump.status.success(),
            "h5dump -H failed: {}",
            String::from_utf8_lossy(&dump.stderr)
        );
        let header = String::from_utf8_lossy(&dump.stdout);
        assert!(
            header.contains("frames") && header.contains("owner_rank_of_grain"),
            "{header}"
        );
    }
}

fn child_write_results() {
    let domain = Domain::init();
    let (rank, size) = (domain.rank(), domain.size());
    assert_eq!(size, 2);
    let path = PathBuf::from(std::env::var(OUT_ENV).expect("output path"));
    // Provenance differs per rank (hostname, clock); the writer must store rank 0's.
    let mut provenance = Provenance::collect(&domain, 1, "portable");
    provenance.hostname = format!("host-of-rank-{rank}");
    let mut w = ResultsWriter::create(&domain, &path, SCENE, &provenance).unwrap();

    w.define_history(&[
        HistoryColumn::new("time", "s", None, "output time"),
        HistoryColumn::new("kinetic_energy", "J", Some("ALLKE"), "kinetic energy"),
    ])
    .unwrap();
    // Two flushes: the second extends the datasets.
    for k in 0..3 {
        w.push_history(&history_row(k)).unwrap();
    }
    w.flush_history().unwrap();
    for k in 3..HISTORY_ROWS {
        w.push_history(&history_row(k)).unwrap();
    }

    let (node_offset, n_nodes) = block(TOTAL_NODES, rank, size);
    let (tet_offset, n_tets) = block(TOTAL_TETS, rank, size);
    let nodes: Vec<[f64; 3]> = (node_offset..node_offset + n_nodes).map(node).collect();
    let tets: Vec<[u64; 4]> = (tet_offset..tet_offset + n_tets).map(tet).collect();
    let grains: Vec<u32> = (tet_offset..tet_offset + n_tets).map(grain).collect();
    w.write_mesh(&MeshPart {
        nodes: &nodes,
        node_blocks: &[(node_offset, n_nodes)],
        total_nodes: TOTAL_NODES,
        tets: &tets,
        tet_blocks: &[(tet_offset, n_tets)],
        total_tets: TOTAL_TETS,
        grain_of_tet: &grains,
        grain_owner_rank: &GRAIN_OWNERS,
    })
    .unwrap();

    // This rank's frame rows: the interleaved blocks of its grains, packed in order.
    let mine = (0..FRAME_GRAIN_OWNERS.len()).filter(|&g| FRAME_GRAIN_OWNERS[g] as usize == rank);
    let blocks = grain_row_blocks(mine, &FRAME_GRAIN_NODES);
    assert_eq!(
        blocks.len(),
        2,
        "rank {rank}: two separate blocks {blocks:?}"
    );
    let rows = || blocks.iter().flat_map(|&(o, n)| o..o + n);
    let v: Vec<f64> = rows().flat_map(velocity).collect();
    let p: Vec<f64> = rows().map(pressure).collect();
    let probe: &[f64] = if rank == 0 { &PROBE } else { &[] };
    let probe_blocks: &[(u64, u64)] = if rank == 0 { &[(0, 2)] } else { &[] };
    w.write_frame(
        7,
        0.125,
        &[
            FieldPart {
                name: "velocity",
                units: "m/s",
                components: 3,
                data: &v,
                blocks: &blocks,
                total: TOTAL_NODES,
            },
            FieldPart {
                name: "pressure",
                units: "Pa",
                components: 1,
                data: &p,
                blocks: &blocks,
                total: TOTAL_NODES,
            },
            FieldPart {
                name: "probe",
                units: "N",
                components: 1,
                data: probe,
                blocks: probe_blocks,
                total: PROBE.len() as u64,
            },
        ],
    )
    .unwrap();

    // A frame whose blocks overlap is refused on both ranks alike (no deadlock).
    let bad = FieldPart {
        name: "u",
        units: "m",
        components: 1,
        data: &[0.0; 2],
        blocks: &[(0, 2)],
        total: 4,
    };
    let e = w.write_frame(8, 0.25, &[bad]).unwrap_err();
    assert!(e.to_string().contains(path.to_str().unwrap()), "{e}");
    assert!(e.to_string().contains("overlap"), "{e}");
    // So is one whose blocks leave rows to nobody (each rank's blocks valid on their own).
    let gap_blocks: &[(u64, u64)] = if rank == 0 { &[(0, 1)] } else { &[(2, 1)] };
    let gap = FieldPart {
        name: "u",
        units: "m",
        components: 1,
        data: &[0.0; 1],
        blocks: gap_blocks,
        total: 3,
    };
    let e = w.write_frame(8, 0.25, &[gap]).unwrap_err();
    assert!(
        e.to_string().contains("[1, 2) are written by no rank"),
        "{e}"
    );

    let stats = w.io_stats();
    // Every bulk write (mesh, frame, history) must really have been collective, the
    // frame's interleaved multi-block writes included.
    assert_eq!(stats.total().not_collective, 0, "rank {rank}: {stats:?}");
    assert_eq!(stats.mesh.collective, 4, "rank {rank}: {stats:?}");
    assert_eq!(stats.history.collective, 2, "rank {rank}: {stats:?}");
    assert_eq!(stats.frames.collective, 3, "rank {rank}: {stats:?}");
    assert_eq!(stats.frames_written, 1, "rank {rank}: {stats:?}");
    w.close().unwrap();
    println!("rank {rank} wrote results ({stats:?})");
}

fn str_attr(loc: &hdf5::Location, name: &str) -> String {
    loc.attr(name)
        .unwrap_or_else(|e| panic!("attribute {name}: {e}"))
        .read_scalar::<VarLenUnicode>()
        .unwrap()
        .as_str()
        .to_string()
}

fn check_results_file(path: &Path) {
    let f = hdf5::File::open(path).unwrap();
    let scene = mufe::io::collective::read_text_dataset(&f.dataset("scene").unwrap()).unwrap();
    assert_eq!(scene, SCENE);
    let prov = f.group("provenance").unwrap();
    assert_eq!(str_attr(&prov, "hostname"), "host-of-rank-0");
    assert_eq!(str_attr(&prov, "version"), env!("CARGO_PKG_VERSION"));
    assert_eq!(prov.attr("ranks").unwrap().read_scalar::<u64>().unwrap(), 2);

    let time = f.dataset("history/time").unwrap();
    let ke = f.dataset("history/kinetic_energy").unwrap();
    let (tv, kv) = (
        time.read_raw::<f64>().unwrap(),
        ke.read_raw::<f64>().unwrap(),
    );
    assert_eq!(tv.len(), HISTORY_ROWS);
    for k in 0..HISTORY_ROWS {
        assert_eq!([tv[k], kv[k]], history_row(k), "history row {k}");
    }
    assert_eq!(str_attr(&time, "units"), "s");
    assert!(time.attr("abaqus").is_err());
    assert_eq!(str_attr(&ke, "units"), "J");
    assert_eq!(str_attr(&ke, "abaqus"), "ALLKE");

    let nodes = f.dataset("mesh/nodes").unwrap();
    assert_eq!(nodes.shape(), vec![TOTAL_NODES as usize, 3]);
    assert_eq!(str_attr(&nodes, "units"), "m");
    let xyz = nodes.read_raw::<f64>().unwrap();
    for i in 0..TOTAL_NODES {
        let i_ = i as usize;
        assert_eq!(xyz[3 * i_..3 * i_ + 3], node(i), "node {i}");
    }
    let tets = f.dataset("mesh/tetrahedra").unwrap();
    assert_eq!(tets.shape(), vec![TOTAL_TETS as usize, 4]);
    let conn = tets.read_raw::<u64>().unwrap();
    for e in 0..TOTAL_TETS {
        let e_ = e as usize;
        assert_eq!(conn[4 * e_..4 * e_ + 4], tet(e), "element {e}");
    }
    let g = f
        .dataset("mesh/grain_of_element")
        .unwrap()
        .read_raw::<u32>()
        .unwrap();
    assert_eq!(g, (0..TOTAL_TETS).map(grain).collect::<Vec<_>>());
    let owners = f.dataset("mesh/owner_rank_of_grain").unwrap();
    assert_eq!(owners.read_raw::<u32>().unwrap(), GRAIN_OWNERS);
    for name in ["tetrahedra", "grain_of_element", "owner_rank_of_grain"] {
        assert_eq!(
            str_attr(&f.dataset(&format!("mesh/{name}")).unwrap(), "units"),
            ""
        );
    }

    let frame = f.group("frames/000007").unwrap();
    assert_eq!(
        frame.attr("time").unwrap().read_scalar::<f64>().unwrap(),
        0.125
    );
    let v = frame.dataset("velocity").unwrap();
    assert_eq!(v.shape(), vec![TOTAL_NODES as usize, 3]);
    assert_eq!(str_attr(&v, "units"), "m/s");
    let vv = v.read_raw::<f64>().unwrap();
    for i in 0..TOTAL_NODES {
        let i_ = i as usize;
        assert_eq!(vv[3 * i_..3 * i_ + 3], velocity(i), "velocity {i}");
    }
    let p = frame.dataset("pressure").unwrap();
    assert_eq!(p.shape(), vec![TOTAL_NODES as usize]);
    assert_eq!(str_attr(&p, "units"), "Pa");
    assert_eq!(
        p.read_raw::<f64>().unwrap(),
        (0..TOTAL_NODES).map(pressure).collect::<Vec<_>>()
    );
    let probe = frame.dataset("probe").unwrap();
    assert_eq!(probe.read_raw::<f64>().unwrap(), PROBE);
    assert!(
        !f.link_exists("frames/000008"),
        "refused frame must not be written"
    );
}

#[test]
fn two_rank_collectives_and_exchange() {
    if is_mpi_child() {
        child_collectives();
        return;
    }
    let out = relaunch_test("two_rank_collectives_and_exchange", 2, &[], DEFAULT_TIMEOUT);
    assert_success(&out);
    assert_every_rank_said(&out, "collectives ok");
}

fn child_collectives() {
    let d = Domain::init();
    let (rank, size) = (d.rank(), d.size());
    assert_eq!(size, 2);
    assert_eq!(d.is_root(), rank == 0);
    let r = rank as f64;

    // Small (stack) and large (heap) reductions; expected values from the per-rank inputs.
    let mut v = [r + 1.0, 2.0 * r, -r];
    d.sum_in_place(&mut v);
    assert_eq!(v, [1.0 + 2.0, 2.0, -1.0]);
    let mut big: Vec<f64> = (0..100).map(|i| i as f64 * (r + 1.0)).collect();
    d.sum_in_place(&mut big);
    assert!(big.iter().enumerate().all(|(i, &x)| x == 3.0 * i as f64));
    let mut m = [r, -r, 10.0 - r];
    d.max_in_place(&mut m);
    assert_eq!(m, [1.0, 0.0, 10.0]);

    // A sum and a maximum started, the caller's values changed meanwhile, then finished:
    // rank 1 starts late, so rank 0 waits in `finish` for it; the buffers come back for the
    // next round (96 kB: a rendezvous message, as the per-grain wall forces; the maximum
    // as the rebuild inputs, with −∞ where a rank has nothing to say).
    use mufe::domain::{Combine, ReductionBuffers};
    let (mut sum_buffers, mut max_buffers) = (ReductionBuffers::default(), Default::default());
    for round in 0..2 {
        let mut walls: Vec<f64> = (0..12_000).map(|i| (i % 7) as f64 * (r + 1.0)).collect();
        let mut motion = [r, -r, if rank == 0 { f64::NEG_INFINITY } else { 2.5 }];
        if rank == 1 {
            std::thread::sleep(std::time::Duration::from_millis(50));
        }
        let max = d.start_reduction(&motion, Combine::Max, 13, max_buffers);
        let sum = d.start_reduction(&walls, Combine::Sum, 11, sum_buffers);
        walls.iter_mut().for_each(|w| *w = -1.0);
        motion = [0.0; 3];
        sum_buffers = sum.finish(&mut walls);
        max_buffers = max.finish(&mut motion);
        let expected = |i: usize| 3.0 * (i % 7) as f64;
        assert!(
            walls.iter().enumerate().all(|(i, &w)| w == expected(i)),
            "round {round}"
        );
        assert_eq!(motion, [1.0, 0.0, 2.5], "round {round}");
    }
    drop((sum_buffers, max_buffers));
    let mut m = [r, -r, 10.0 - r];
    d.min_in_place(&mut m);
    assert_eq!(m, [0.0, -1.0, 9.0]);

    assert_eq!(d.sum_u64(rank as u64 + 5), 5 + 6);
    let local = 10 * (rank as u64 + 1);
    let (offset, total) = d.exclusive_scan_u64(local);
    assert_eq!((offset, total), (if rank == 0 { 0 } else { 10 }, 30));
    assert_eq!(d.all_gather_u64(rank as u64 * 7), vec![0, 7]);

    let mut bytes = if rank == 0 {
        b"from root".to_vec()
    } else {
        vec![1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12]
    };
    d.broadcast_bytes(&mut bytes);
    assert_eq!(bytes, b"from root");

    // Variable counts: rank r contributes r + 1 values r*10 + j.
    let mine: Vec<f64> = (0..=rank).map(|j| (rank * 10 + j) as f64).collect();
    match d.gather_f64_to_root(&mine) {
        Some(all) => {
            assert_eq!(rank, 0);
            assert_eq!(all, vec![0.0, 10.0, 11.0]);
        }
        None => assert_eq!(rank, 1),
    }

    // Exchange: each rank sends 3 + rank values to the other and one value to itself;
    // two exchanges with different tags in flight at once, begun in opposite orders.
    let other = 1 - rank;
    let to_other: Vec<f64> = (0..3 + rank).map(|j| (100 * rank + j) as f64).collect();
    let forward = Exchange::new(1);
    let reverse = Exchange::new(2);
    let sends = vec![(other, to_other), (rank, vec![-(r + 1.0)])];
    let recvs = [(other, 3 + other), (rank, 1)];
    let (pf, pr) = if rank == 0 {
        let pf = forward.begin(&d, &sends, &recvs).unwrap();
        let pr = reverse
            .begin(&d, &[(other, vec![r; 2])], &[(other, 2)])
            .unwrap();
        (pf, pr)
    } else {
        let pr = reverse
            .begin(&d, &[(other, vec![r; 2])], &[(other, 2)])
            .unwrap();
        let pf = forward.begin(&d, &sends, &recvs).unwrap();
        (pf, pr)
    };
    // (Work would overlap here.)
    let got_r = reverse.end(pr).unwrap();
    let got_f = forward.end(pf).unwrap();
    let expect_other: Vec<f64> = (0..3 + other).map(|j| (100 * other + j) as f64).collect();
    assert_eq!(got_f, vec![(other, expect_other), (rank, vec![-(r + 1.0)])]);
    assert_eq!(got_r, vec![(other, vec![other as f64; 2])]);

    d.barrier();
    println!("rank {rank} collectives ok");
}

#[test]
fn panic_on_one_rank_ends_the_job() {
    if is_mpi_child() {
        let d = Domain::init();
        d.barrier();
        if d.rank() == 1 {
            panic!("deliberate test panic");
        }
        // Rank 0 would wait here forever without the abort hook.
        d.barrier();
        println!("rank 0 passed the barrier: the abort hook did not work");
        return;
    }
    // run_under_mpirun panics (failing the test) if the job is still running at the timeout.
    let out = relaunch_test("panic_on_one_rank_ends_the_job", 2, &[], DEFAULT_TIMEOUT);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "job must fail: {stderr}");
    assert!(stderr.contains("rank 1: panicked"), "{stderr}");
    assert!(stderr.contains("deliberate test panic"), "{stderr}");
    assert!(!String::from_utf8_lossy(&out.stdout).contains("passed the barrier"));
}

/// Values per message of the test below: 1 MiB, far above the shared-memory transport's
/// eager limit (4 KiB in Open MPI), so that a send completes only when its receiver takes it.
const LARGE_MESSAGE: usize = 1 << 17;

/// The file by which rank 0 tells rank 1 that its receives are in.
const RECEIVED_WORD: &str = "rank0_received";

/// How long rank 1 stays out of MPI waiting for rank 0's word (s).
const OUT_OF_MPI_LIMIT: u64 = 30;

/// `Exchange::end_receives` returns once this rank's receives are in, without waiting for
/// its own sends, which complete only when the receiver enters MPI to take them: rank 1
/// posts its exchange and then stays out of MPI until rank 0 says, through a file, that
/// its receives are in. Waiting for the sends as well (what the halo did until session
/// 63), rank 0 would block until rank 1 entered MPI, and rank 1 gives up after
/// [`OUT_OF_MPI_LIMIT`] s and fails the test. Relies on a transport that can take a
/// large message without the sender's help (Open MPI's shared-memory single copy, the
/// default on Linux).
#[test]
fn an_exchange_s_receives_end_while_the_receiver_of_its_sends_stays_out_of_mpi() {
    let name = "an_exchange_s_receives_end_while_the_receiver_of_its_sends_stays_out_of_mpi";
    if is_mpi_child() {
        child_receives_before_sends(Path::new(&std::env::var(OUT_ENV).unwrap()));
        return;
    }
    let dir = out_dir("receives_first");
    let _ = std::fs::remove_file(dir.join(RECEIVED_WORD));
    let env = [(OUT_ENV, dir.to_str().unwrap())];
    let out = relaunch_test(name, 2, &env, DEFAULT_TIMEOUT);
    assert_success(&out);
    assert_every_rank_said(&out, "exchange ok");
}

fn child_receives_before_sends(dir: &Path) {
    let d = Domain::init();
    let (rank, other) = (d.rank(), 1 - d.rank());
    let value = |from: usize, j: usize| (from * LARGE_MESSAGE + j) as f64;
    let word = dir.join(RECEIVED_WORD);
    let ex = Exchange::new(7);
    let sends = vec![(other, (0..LARGE_MESSAGE).map(|j| value(rank, j)).collect())];
    let mut pending = ex.begin(&d, &sends, &[(other, LARGE_MESSAGE)]).unwrap();
    if rank == 1 {
        let start = std::time::Instant::now();
        while !word.exists() {
            assert!(
                start.elapsed().as_secs() < OUT_OF_MPI_LIMIT,
                "rank 0's receives did not complete in {OUT_OF_MPI_LIMIT} s while rank 1 stayed out of MPI"
            );
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
    }
    ex.end_receives(&mut pending).unwrap();
    let (from, data) = pending.received().next().expect("one message");
    assert_eq!(from, other);
    assert!(data.iter().enumerate().all(|(j, &v)| v == value(other, j)));
    if rank == 0 {
        std::fs::write(&word, b"in").unwrap();
    }
    // the sends complete now that both ranks are in MPI; the buffers come back
    let buffers = ex.end_reusing(pending).unwrap();
    assert_eq!(buffers.send.len(), LARGE_MESSAGE);
    d.barrier();
    println!("rank {rank} exchange ok");
}
