//! `results.xdmf` describes `results.h5` for ParaView: every HDF5 path it names exists,
//! with the shape and number type it states, and there is one grid per frame at the
//! frame's time (the XDMF is parsed here by hand: it is plain XML of a fixed form).

use std::process::Command;

/// (dimensions, number type, precision, "file:/path") of every `Format="HDF"` item.
fn hdf_items(text: &str) -> Vec<(Vec<usize>, String, usize, String)> {
    let attr = |tag: &str, name: &str| -> Option<String> {
        let key = format!("{name}=\"");
        let start = tag.find(&key)? + key.len();
        Some(tag[start..start + tag[start..].find('"')?].to_string())
    };
    let mut items = Vec::new();
    for piece in text.split("<DataItem ").skip(1) {
        let (tag, rest) = piece.split_once('>').unwrap();
        if attr(tag, "Format").as_deref() != Some("HDF") {
            continue;
        }
        let body = rest.split("</DataItem>").next().unwrap().trim().to_string();
        let dims = attr(tag, "Dimensions")
            .unwrap()
            .split_whitespace()
            .map(|d| d.parse().unwrap())
            .collect();
        let precision = attr(tag, "Precision").unwrap().parse().unwrap();
        items.push((dims, attr(tag, "NumberType").unwrap(), precision, body));
    }
    items
}

#[test]
fn every_path_shape_and_type_resolves_in_results_h5() {
    let out = std::env::temp_dir().join(format!("mufe_xdmf_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let status = Command::new(env!("CARGO_BIN_EXE_mufe"))
        .args(["run", "jobs/demo/sphere_compression.toml", "--quiet"])
        .args(["--max-steps", "300", "--set", "output.frame_interval=2e-7"])
        .arg("--out")
        .arg(&out)
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .status()
        .unwrap();
    assert!(status.success());
    let text = std::fs::read_to_string(out.join("results.xdmf")).expect("results.xdmf written");
    let f = hdf5::File::open(out.join("results.h5")).unwrap();

    let frames = f.group("frames").unwrap().member_names().unwrap();
    assert!(frames.len() >= 3, "{} frames", frames.len());
    assert_eq!(text.matches("<Grid Name=\"frame_").count(), frames.len());
    for name in &frames {
        let t: f64 = f
            .group(&format!("frames/{name}"))
            .unwrap()
            .attr("time")
            .unwrap()
            .read_scalar()
            .unwrap();
        let grid = text
            .split(&format!("<Grid Name=\"frame_{name}\""))
            .nth(1)
            .unwrap_or_else(|| panic!("no grid for frame {name}"));
        let value: f64 = grid
            .split("<Time Value=\"")
            .nth(1)
            .unwrap()
            .split('"')
            .next()
            .unwrap()
            .parse()
            .unwrap();
        assert_eq!(value, t, "frame {name}: XDMF time vs /frames/{name}@time");
    }

    let items = hdf_items(&text);
    // topology, geometry, 3 node vectors (displacement, velocity, contact force), 6 stress
    // slabs, 3 element scalars, grain
    assert_eq!(items.len(), 15 * frames.len());
    for (dims, kind, precision, reference) in &items {
        let (file, path) = reference.split_once(':').unwrap();
        assert_eq!(file, "results.h5");
        let ds = f
            .dataset(path)
            .unwrap_or_else(|e| panic!("{path} named in results.xdmf: {e}"));
        assert_eq!(&ds.shape(), dims, "{path}: shape");
        let dtype = ds.dtype().unwrap();
        assert_eq!(dtype.size(), *precision, "{path}: precision");
        let td = dtype.to_descriptor().unwrap();
        let expected = match kind.as_str() {
            "Float" => matches!(td, hdf5::types::TypeDescriptor::Float(_)),
            "UInt" => matches!(td, hdf5::types::TypeDescriptor::Unsigned(_)),
            "Int" => matches!(td, hdf5::types::TypeDescriptor::Integer(_)),
            _ => false,
        };
        assert!(expected, "{path}: {kind} in XDMF, {td:?} in HDF5");
    }
    drop(f);
    let _ = std::fs::remove_dir_all(&out);
}
