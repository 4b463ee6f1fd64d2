use super::*;
use crate::domain::with_test_domain;
use crate::io::provenance::{iso8601_utc, shell_quote};
use crate::testing::TestDir;
use std::time::UNIX_EPOCH;

fn str_attr(loc: &Location, name: &str) -> String {
    loc.attr(name)
        .unwrap()
        .read_scalar::<VarLenUnicode>()
        .unwrap()
        .as_str()
        .to_string()
}

fn provenance() -> Provenance {
    Provenance {
        version: "9.9.9".into(),
        ranks: 1,
        threads: 2,
        start_time: "2024-01-02T03:04:05Z".into(),
        command_line: "mufe run 'a b.toml'".into(),
        hostname: "node1".into(),
        kernel: "avx2".into(),
    }
}

#[test]
fn iso8601_matches_known_instants() {
    let at = |s: u64| iso8601_utc(UNIX_EPOCH + std::time::Duration::from_secs(s));
    assert_eq!(at(0), "1970-01-01T00:00:00Z");
    assert_eq!(at(951_782_400), "2000-02-29T00:00:00Z");
    assert_eq!(at(1_700_000_000), "2023-11-14T22:13:20Z");
    assert_eq!(at(4_107_542_399), "2100-02-28T23:59:59Z");
}

#[test]
fn shell_quoting() {
    assert_eq!(shell_quote("--set=a.b=1"), "--set=a.b=1");
    assert_eq!(shell_quote("a b"), "'a b'");
    assert_eq!(shell_quote("it's"), r"'it'\''s'");
    assert_eq!(shell_quote(""), "''");
}

#[test]
fn single_rank_file_reads_back() {
    let dir = TestDir::new("io_single");
    let path = dir.join("single.h5");
    let scene = "[scene]\nname = \"drop\" # ünïcode\n";
    let (stats, n_nodes) = with_test_domain(|d| {
        let mut w = ResultsWriter::create(d, &path, scene, &provenance()).unwrap();
        w.define_history(&[
            HistoryColumn::new("time", "s", None, "output time"),
            HistoryColumn::new("kinetic_energy", "J", Some("ALLKE"), "kinetic energy"),
        ])
        .unwrap();
        // More rows than one chunk, over two flushes, to exercise extension.
        for i in 0..1500 {
            let t = i as f64 * 1e-3;
            w.push_history(&[t, 0.5 * t * t]).unwrap();
            if i == 700 {
                w.flush_history().unwrap();
            }
        }
        let nodes: Vec<[f64; 3]> = (0..5)
            .map(|i| [i as f64, 2.0 * i as f64, -(i as f64)])
            .collect();
        let tets = [[0u64, 1, 2, 3], [1, 2, 3, 4]];
        w.write_mesh(&MeshPart {
            nodes: &nodes,
            node_blocks: &[(0, 5)],
            total_nodes: 5,
            tets: &tets,
            tet_blocks: &[(0, 2)],
            total_tets: 2,
            grain_of_tet: &[0, 1],
            grain_owner_rank: &[0, 0],
        })
        .unwrap();
        let u: Vec<f64> = (0..15).map(|i| i as f64 * 0.1).collect();
        let p = [1.0, 2.0, 3.0, 4.0, 5.0];
        w.write_frame(
            3,
            0.25,
            &[
                FieldPart {
                    name: "displacement",
                    units: "m",
                    components: 3,
                    data: &u,
                    blocks: &[(0, 5)],
                    total: 5,
                },
                FieldPart {
                    name: "pressure",
                    units: "Pa",
                    components: 1,
                    data: &p,
                    blocks: &[(0, 5)],
                    total: 5,
                },
            ],
        )
        .unwrap();
        let stats = w.io_stats();
        w.close().unwrap();
        (stats, nodes.len())
    });
    assert_eq!(stats.total().not_collective, 0, "{stats:?}");
    assert_eq!(stats.mesh.collective, 4, "{stats:?}");
    assert_eq!(
        stats.history.collective, 2,
        "one flush of two columns: {stats:?}"
    );
    assert_eq!(stats.frames.collective, 2, "{stats:?}");
    assert_eq!(stats.frames_written, 1, "{stats:?}");

    let f = File::open(&path).unwrap();
    assert_eq!(
        collective::read_text_dataset(&f.dataset("scene").unwrap()).unwrap(),
        scene
    );
    assert_eq!(str_attr(&f.dataset("scene").unwrap(), "units"), "");
    let prov = f.group("provenance").unwrap();
    assert_eq!(str_attr(&prov, "version"), "9.9.9");
    assert_eq!(str_attr(&prov, "command_line"), "mufe run 'a b.toml'");
    assert_eq!(str_attr(&prov, "hostname"), "node1");
    assert_eq!(str_attr(&prov, "kernel"), "avx2");
    assert_eq!(str_attr(&prov, "start_time"), "2024-01-02T03:04:05Z");
    assert_eq!(prov.attr("ranks").unwrap().read_scalar::<u64>().unwrap(), 1);
    assert_eq!(
        prov.attr("threads").unwrap().read_scalar::<u64>().unwrap(),
        2
    );

    let time = f.dataset("history/time").unwrap();
    let ke = f.dataset("history/kinetic_energy").unwrap();
    let tv = time.read_raw::<f64>().unwrap();
    let kv = ke.read_raw::<f64>().unwrap();
    assert_eq!(tv.len(), 1500);
    for (i, (&t, &k)) in tv.iter().zip(&kv).enumerate() {
        assert_eq!(t, i as f64 * 1e-3);
        assert_eq!(k, 0.5 * t * t);
    }
    assert_eq!(str_attr(&time, "units"), "s");
    assert!(time.attr("abaqus").is_err());
    assert_eq!(str_attr(&ke, "units"), "J");
    assert_eq!(str_attr(&ke, "abaqus"), "ALLKE");
    assert_eq!(str_attr(&ke, "description"), "kinetic energy");

    let nodes = f.dataset("mesh/nodes").unwrap();
    assert_eq!(nodes.shape(), vec![n_nodes, 3]);
    assert_eq!(str_attr(&nodes, "units"), "m");
    let xyz = nodes.read_raw::<f64>().unwrap();
    for i in 0..n_nodes {
        assert_eq!(
            &xyz[3 * i..3 * i + 3],
            &[i as f64, 2.0 * i as f64, -(i as f64)]
        );
    }
    let tets = f.dataset("mesh/tetrahedra").unwrap();
    assert_eq!(tets.shape(), vec![2, 4]);
    assert_eq!(
        tets.read_raw::<u64>().unwrap(),
        vec![0, 1, 2, 3, 1, 2, 3, 4]
    );
    assert_eq!(str_attr(&tets, "units"), "");
    assert_eq!(
        f.dataset("mesh/grain_of_element")
            .unwrap()
            .read_raw::<u32>()
            .unwrap(),
        vec![0, 1]
    );
    assert_eq!(
        f.dataset("mesh/owner_rank_of_grain")
            .unwrap()
            .read_raw::<u32>()
            .unwrap(),
        vec![0, 0]
    );

    let frame = f.group("frames/000003").unwrap();
    assert_eq!(
        frame.attr("time").unwrap().read_scalar::<f64>().unwrap(),
        0.25
    );
    let u = frame.dataset("displacement").unwrap();
    assert_eq!(u.shape(), vec![5, 3]);
    assert_eq!(str_attr(&u, "units"), "m");
    let uv = u.read_raw::<f64>().unwrap();
    assert!(uv.iter().enumerate().all(|(i, &v)| v == i as f64 * 0.1));
    let p = frame.dataset("pressure").unwrap();
    assert_eq!(p.shape(), vec![5]);
    assert_eq!(str_attr(&p, "units"), "Pa");
    assert_eq!(p.read_raw::<f64>().unwrap(), vec![1.0, 2.0, 3.0, 4.0, 5.0]);
    std::fs::remove_file(&path).ok();
}

#[test]
fn bad_input_is_an_error_and_the_file_stays_usable() {
    let dir = TestDir::new("io_bad_input");
    let path = dir.join("bad.h5");
    with_test_domain(|d| {
        let mut w = ResultsWriter::create(d, &path, "", &provenance()).unwrap();
        assert!(w.push_history(&[1.0]).is_err(), "push before define");
        let dup = [
            HistoryColumn::new("a", "", None, ""),
            HistoryColumn::new("a", "", None, ""),
        ];
        assert!(w.define_history(&dup).is_err());
        assert!(w
            .define_history(&[HistoryColumn::new("a/b", "", None, "")])
            .is_err());
        w.define_history(&[HistoryColumn::new("time", "s", None, "t")])
            .unwrap();
        assert!(
            w.define_history(&[HistoryColumn::new("x", "", None, "")])
                .is_err(),
            "twice"
        );
        let e = w.push_history(&[1.0, 2.0]).unwrap_err();
        assert!(e.to_string().contains("bad.h5"), "{e}");

        // Rows that do not cover the field, wrong row width, node ids out of range.
        let short = FieldPart {
            name: "u",
            units: "m",
            components: 3,
            data: &[0.0; 6],
            blocks: &[(0, 2)],
            total: 3,
        };
        assert!(w.write_frame(0, 0.0, &[short]).is_err());
        let ragged = FieldPart {
            name: "u",
            units: "m",
            components: 3,
            data: &[0.0; 7],
            blocks: &[(0, 2)],
            total: 2,
        };
        assert!(w.write_frame(0, 0.0, &[ragged]).is_err());
        // Row blocks must be ascending and must not overlap (the data are packed in order).
        let descending = FieldPart {
            name: "u",
            units: "m",
            components: 1,
            data: &[0.0; 4],
            blocks: &[(2, 2), (0, 2)],
            total: 4,
        };
        let e = w.write_frame(0, 0.0, &[descending]).unwrap_err();
        assert!(e.to_string().contains("ascending"), "{e}");
        let bad_mesh = MeshPart {
            nodes: &[[0.0; 3]; 4],
            node_blocks: &[(0, 4)],
            total_nodes: 4,
            tets: &[[0, 1, 2, 9]],
            tet_blocks: &[(0, 1)],
            total_tets: 1,
            grain_of_tet: &[0],
            grain_owner_rank: &[0],
        };
        let e = w.write_mesh(&bad_mesh).unwrap_err();
        assert!(e.to_string().contains("element 0"), "{e}");

        // The writer is still usable after refused input.
        let ok = FieldPart {
            name: "u",
            units: "m",
            components: 3,
            data: &[1.0; 6],
            blocks: &[(0, 2)],
            total: 2,
        };
        w.write_frame(0, 0.5, &[ok]).unwrap();
        assert!(w.write_frame(0, 0.5, &[ok]).is_err(), "same frame twice");
        w.push_history(&[0.5]).unwrap();
        w.close().unwrap();
    });
    let f = File::open(&path).unwrap();
    assert_eq!(
        collective::read_text_dataset(&f.dataset("scene").unwrap()).unwrap(),
        ""
    );
    assert_eq!(
        f.dataset("history/time")
            .unwrap()
            .read_raw::<f64>()
            .unwrap(),
        vec![0.5]
    );
    assert_eq!(
        f.dataset("frames/000000/u")
            .unwrap()
            .read_raw::<f64>()
            .unwrap(),
        vec![1.0; 6]
    );
    std::fs::remove_file(&path).ok();
}

#[test]
fn directory_path_is_a_clear_error() {
    let scratch = TestDir::new("io_directory");
    let dir = scratch.join("a-directory");
    std::fs::create_dir_all(&dir).unwrap();
    with_test_domain(|d| {
        let e = ResultsWriter::create(d, &dir, "", &provenance())
            .err()
            .unwrap();
        assert!(
            matches!(e, MufeError::Io(ref m) if m.contains("is a directory")),
            "{e}"
        );
    });
}

#[test]
fn collect_fills_provenance() {
    with_test_domain(|d| {
        let p = Provenance::collect(d, 3, "portable");
        assert_eq!(p.version, env!("CARGO_PKG_VERSION"));
        assert_eq!((p.ranks, p.threads), (1, 3));
        assert!(
            p.start_time.ends_with('Z') && p.start_time.len() == 20,
            "{}",
            p.start_time
        );
        assert!(!p.command_line.is_empty());
    });
}
