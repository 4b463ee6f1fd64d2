//! Grains from surface files (issue 15): format round trips give the same mesh, every
//! surface defect is a one-line exit-2 error naming the file and the facet, repair fixes
//! near-duplicate vertices and a flipped facet, an imported ellipsoid meshes to its
//! volume, the on-disk cache misses then hits (bitwise the same mesh) and misses again
//! when the file or the seeding changes, and a two-grain virtual sand runs.

#[path = "common/results.rs"]
mod results;
#[path = "../src/testing.rs"]
mod testing;

use mufe::mesh::import::formats::{
    write_msh, write_msh_volume, write_obj, write_stl_ascii, write_stl_binary,
};
use mufe::mesh::import::{mesh_surface_cached, Surface, SurfaceOrigin, SurfaceSpec};
use mufe::mesh::{tet_volume, TetMesh};
use mufe::sand::{grain_surface, icosphere, SandParams};
use results::{column, history};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

fn dir(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("surface_import")
        .join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn spec(file: &Path, units: &str, seeding: f64) -> SurfaceSpec {
    SurfaceSpec {
        file: file.display().to_string(),
        units: units.into(),
        seeding,
        scale: 1.0,
        rotation: [0.0; 3],
        repair: false,
        origin: SurfaceOrigin::Centroid,
        refine: Vec::new(),
        remesh: true,
        curvature: None,
        geometry: None,
    }
}

fn write(path: &Path, f: impl FnOnce(&mut Vec<u8>) -> std::io::Result<()>) {
    let mut bytes = Vec::new();
    f(&mut bytes).unwrap();
    std::fs::write(path, bytes).unwrap();
}

/// A virtual-sand grain in mm, coordinates exact in f32 (STL's precision).
fn sand_grain_mm(index: usize, level: u32) -> Surface {
    let p = SandParams {
        level,
        ..SandParams::default()
    };
    let mut s = grain_surface(&p, index);
    s.points
        .iter_mut()
        .for_each(|x| *x = x.map(|c| (c * 1e3) as f32 as f64));
    s
}

fn volume(m: &TetMesh) -> f64 {
    m.tets
        .iter()
        .map(|t| tet_volume(&t.map(|i| m.nodes[i as usize])))
        .sum()
}

#[test]
fn round_trips_stl_binary_ascii_obj_msh_give_the_same_mesh() {
    let d = dir("round_trip");
    let s = sand_grain_mm(0, 2);
    write(&d.join("g.stl"), |o| write_stl_binary(&s, o));
    write(&d.join("g_ascii.stl"), |o| write_stl_ascii(&s, o));
    write(&d.join("g.obj"), |o| write_obj(&s, o));
    write(&d.join("g.msh"), |o| write_msh(&s, o));
    let mesh = |f: &str| {
        mesh_surface_cached(&spec(&d.join(f), "mm", 2.5e-4), None)
            .unwrap()
            .0
    };
    let reference = mesh("g.stl");
    // at least half the tets of regular ones of edge = seeding filling the grain
    let regular = 2.5e-4f64.powi(3) / (6.0 * 2f64.sqrt());
    assert!(
        reference.tets.len() as f64 > 0.5 * volume(&reference) / regular,
        "{} tets",
        reference.tets.len()
    );
    for f in ["g_ascii.stl", "g.obj", "g.msh"] {
        assert!(mesh(f) == reference, "{f} meshes differently");
    }
    // A tetrahedral MSH is used as is.
    write(&d.join("v.msh"), |o| write_msh_volume(&reference, o));
    let mut v = spec(&d.join("v.msh"), "m", 1.0);
    v.origin = SurfaceOrigin::File;
    assert!(mesh_surface_cached(&v, None).unwrap().0 == reference);
    // A rotation turns the mesh about the origin: same volume, moved nodes.
    let mut r = spec(&d.join("g.obj"), "mm", 2.5e-4);
    r.rotation = [0.0, 0.0, std::f64::consts::FRAC_PI_2];
    let turned = mesh_surface_cached(&r, None).unwrap().0;
    assert!((volume(&turned) / volume(&reference) - 1.0).abs() < 1e-12);
    let (p, q) = (reference.nodes[0], turned.nodes[0]);
    assert!((q[0] + p[1]).abs() < 1e-15 && (q[1] - p[0]).abs() < 1e-15);
}

const SCENE: &str = r#"
[simulation]
duration = 1.0e-6
[materials.quartz]
youngs_modulus = 7.0e10
poisson_ratio = 0.17
density = 2650.0
[[grains]]
material = "quartz"
shape = { surface = { file = "FILE", units = "mm", seeding = 2.5e-4 REPAIR } }
"#;

fn check_scene(d: &Path, file: &str, repair: bool) -> (i32, String, String) {
    let text = SCENE
        .replace("FILE", file)
        .replace("REPAIR", if repair { ", repair = true" } else { "" });
    let scene = d.join(format!("{file}.toml"));
    std::fs::write(&scene, text).unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_mufe"))
        .arg("check")
        .arg(&scene)
        .env("MUFE_CACHE_DIR", "off")
        .output()
        .unwrap();
    (
        o.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

#[test]
fn every_surface_defect_is_one_exit_2_line_naming_file_and_facet() {
    let d = dir("defects");
    let good = sand_grain_mm(1, 2);
    let mut cases: Vec<(&str, Surface, &str)> = Vec::new();
    let mut open = good.clone();
    open.facets.remove(7);
    cases.push(("open", open, "not closed"));
    let mut non_manifold = good.clone();
    let extra = good.points.len() as u32;
    let f = good.facets[3];
    non_manifold.points.push([9.0, 9.0, 9.0]);
    non_manifold.facets.push([f[1], f[0], extra]);
    cases.push(("non_manifold", non_manifold, "non-manifold edge"));
    let mut flipped = good.clone();
    flipped.facets[10].swap(1, 2);
    cases.push(("flipped", flipped, "inconsistent orientation"));
    let mut inward = good.clone();
    inward.facets.iter_mut().for_each(|f| f.swap(1, 2));
    cases.push(("inward", inward, "inward orientation"));
    let mut degenerate = good.clone();
    degenerate.facets[5][2] = degenerate.facets[5][0];
    cases.push(("degenerate", degenerate, "degenerate facet"));
    let mut crossing = good.clone();
    // Push a vertex through the grain and out of the other side.
    let p = crossing.points[0];
    crossing.points[0] = p.map(|c| -1.5 * c);
    cases.push(("self_intersecting", crossing, "self-intersection"));
    for (name, s, what) in cases {
        // Soup formats merge by position: write these as OBJ, whose indices are kept.
        let file = format!("{name}.obj");
        write(&d.join(&file), |o| write_obj(&s, o));
        let (code, _, stderr) = check_scene(&d, &file, false);
        assert_eq!(code, 2, "{name}: {stderr}");
        let lines: Vec<&str> = stderr.lines().collect();
        assert_eq!(lines.len(), 1, "{name}: {stderr}");
        let line = lines[0];
        assert!(
            line.starts_with("error: ")
                && line.contains(&format!("{file}: facet "))
                && line.contains(what),
            "{name}: {line}"
        );
        println!("{line}");
    }
}

#[test]
fn repair_merges_duplicate_vertices_and_flips_a_facet_back() {
    let d = dir("repair");
    let mut s = sand_grain_mm(2, 2);
    // Facet 4 uses a copy of its first vertex 1e-9 of the grain's size away.
    let v = s.facets[4][0] as usize;
    let p = s.points[v];
    s.points.push([p[0] + 1e-9, p[1], p[2]]);
    s.facets[4][0] = (s.points.len() - 1) as u32;
    s.facets[9].swap(1, 2);
    write(&d.join("broken.obj"), |o| write_obj(&s, o));
    let (code, _, stderr) = check_scene(&d, "broken.obj", false);
    assert_eq!(code, 2, "{stderr}");
    let (code, stdout, stderr) = check_scene(&d, "broken.obj", true);
    assert_eq!(code, 0, "{stderr}");
    assert!(stdout.contains("ok: "), "{stdout}");
    assert!(
        stderr.contains("broken.obj: repaired: merged 1 duplicate vertices")
            && stderr.contains("flipped 1 facets"),
        "{stderr}"
    );
}

#[test]
fn imported_ellipsoid_meshes_to_its_volume_and_20k_facets_check_fast() {
    let d = dir("ellipsoid");
    let (a, b, c) = (1.0, 0.7, 0.5); // mm
    let mut s = icosphere(5);
    s.points
        .iter_mut()
        .for_each(|p| *p = [p[0] * a, p[1] * b, p[2] * c].map(|x| x as f32 as f64));
    assert_eq!(s.facets.len(), 20480);
    write(&d.join("ellipsoid.stl"), |o| write_stl_binary(&s, o));
    let sp = spec(&d.join("ellipsoid.stl"), "mm", 1e-4);
    let t0 = Instant::now();
    let g = mufe::mesh::import::inspect(&sp).unwrap();
    let checked = t0.elapsed().as_secs_f64();
    let t0 = Instant::now();
    let m = mesh_surface_cached(&sp, None).unwrap().0;
    let meshed = t0.elapsed().as_secs_f64();
    let exact = 4.0 / 3.0 * std::f64::consts::PI * a * b * c * 1e-9;
    let v = volume(&m);
    println!(
        "20480 facets: read + checked in {checked:.3} s; meshed at 0.1 mm in {meshed:.2} s: {} tets, volume {:.4e} vs {exact:.4e} m³ ({:+.3} %); descriptors {}",
        m.tets.len(),
        v,
        100.0 * (v / exact - 1.0),
        g.descriptors
    );
    assert!((v / exact - 1.0).abs() < 0.01);
    assert!(checked < 1.0, "checks took {checked} s");
    let axes = g.descriptors.axes;
    assert!(
        (axes[0] / 1e-3 - a).abs() < 0.01 && (axes[2] / 1e-3 - c).abs() < 0.01,
        "{axes:?}"
    );
}

/// `refine` zones make the elements below a surface point fine, not only the facets: at
/// depths of 1–4 zone seedings under the point the tets stay near the zone's size, while
/// without the zone they grow with the depth; a zone coarser than the shape is refused.
#[test]
fn a_refine_zone_makes_the_elements_below_the_point_fine() {
    use mufe::mesh::import::zones::SurfaceRefinement;
    let d = dir("zone");
    let mut s = icosphere(3);
    s.points
        .iter_mut()
        .for_each(|p| *p = [p[0], 0.8 * p[1], 0.7 * p[2]].map(|x| x as f32 as f64));
    write(&d.join("e.stl"), |o| write_stl_binary(&s, o));
    // a zone at the x tip of a 1 × 0.8 × 0.7 mm ellipsoid (file origin)
    let plain = spec(&d.join("e.stl"), "mm", 1.5e-4);
    let mut zoned = plain.clone();
    zoned.origin = SurfaceOrigin::File;
    zoned.refine = vec![SurfaceRefinement {
        point: [1e-3, 0.0, 0.0],
        seeding: 1e-5,
        radius: 2e-5,
        growth: 0.2,
    }];
    let mut plain = plain;
    plain.origin = SurfaceOrigin::File;
    // mean edge of the tets whose centroid is at depth 1–4 seedings below the x tip
    let below = |m: &TetMesh| {
        let (mut sum, mut n) = (0.0, 0);
        for t in &m.tets {
            let x = t.map(|i| m.nodes[i as usize]);
            let c = [0, 1, 2].map(|k| x.iter().map(|p| p[k]).sum::<f64>() / 4.0);
            let depth = 1e-3 - c[0];
            if (1e-5..4e-5).contains(&depth) && c[1].hypot(c[2]) < 2e-5 {
                let mut e = 0.0;
                for (i, j) in [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)] {
                    e += ((0..3).map(|k| (x[i][k] - x[j][k]).powi(2)).sum::<f64>()).sqrt();
                }
                sum += e / 6.0;
                n += 1;
            }
        }
        (if n > 0 { sum / n as f64 } else { f64::INFINITY }, n)
    };
    let (m_plain, m_zoned) = (
        mesh_surface_cached(&plain, None).unwrap().0,
        mesh_surface_cached(&zoned, None).unwrap().0,
    );
    let ((e_plain, n_plain), (e_zoned, n_zoned)) = (below(&m_plain), below(&m_zoned));
    println!("tets 1–4 zone seedings below the point: without the zone {n_plain} (mean edge {e_plain:.2e} m), with it {n_zoned} ({e_zoned:.2e} m); {} vs {} tets in all", m_plain.tets.len(), m_zoned.tets.len());
    assert!(
        n_zoned > 20 && e_zoned < 2.0e-5,
        "{n_zoned} tets, mean edge {e_zoned:e}"
    );
    assert!(e_plain > 3.0 * e_zoned, "{e_plain:e} vs {e_zoned:e}");
    // both remeshed onto the file's surface: the volume lost is the chord sag of edges h
    // at radius of curvature ρ, at most h²/(8ρ) × area / volume (ρ = c²/a = 0.49 mm at the
    // x tip, area/volume ≈ 3/∛(abc)); the zone's finer tip loses less
    let input = mufe::mesh::import::checks::signed_volume(&s) * 1e-9;
    let (loss_plain, loss_zoned) = (
        1.0 - volume(&m_plain) / input,
        1.0 - volume(&m_zoned) / input,
    );
    let sag_bound = 1.5e-4f64.powi(2) / (8.0 * 0.49e-3) * 3.0 / (0.56f64.cbrt() * 1e-3);
    println!("volume lost: {loss_plain:.4} without the zone, {loss_zoned:.4} with it, bound {sag_bound:.4}");
    assert!(
        loss_plain > 0.0 && loss_plain < sag_bound,
        "{loss_plain} vs {sag_bound}"
    );
    assert!(
        loss_zoned < loss_plain + 1e-3,
        "{loss_zoned} vs {loss_plain}"
    );
    let mut bad = zoned.clone();
    bad.refine[0].seeding = 2e-4;
    let e = mesh_surface_cached(&bad, None).unwrap_err().to_string();
    assert!(e.contains("refine[0].seeding"), "{e}");
}

#[test]
fn disk_cache_misses_then_hits_bitwise_and_misses_on_a_new_file_or_seeding() {
    let d = dir("cache");
    let cache = d.join("cache");
    let file = d.join("g.stl");
    write(&file, |o| write_stl_binary(&sand_grain_mm(3, 3), o));
    let sp = spec(&file, "mm", 1.5e-4);
    let t0 = Instant::now();
    let (first, hit) = mesh_surface_cached(&sp, Some(&cache)).unwrap();
    let miss_time = t0.elapsed().as_secs_f64();
    assert!(!hit);
    let t0 = Instant::now();
    let (second, hit) = mesh_surface_cached(&sp, Some(&cache)).unwrap();
    let hit_time = t0.elapsed().as_secs_f64();
    assert!(hit);
    println!(
        "miss {miss_time:.4} s, hit {hit_time:.4} s, {} tets",
        first.tets.len()
    );
    assert!(hit_time < miss_time);
    assert!(first.tets == second.tets);
    assert!(first
        .nodes
        .iter()
        .zip(&second.nodes)
        .all(|(p, q)| p.map(f64::to_bits) == q.map(f64::to_bits)));
    // Another seeding misses; the first entry stays.
    let finer = spec(&file, "mm", 1.2e-4);
    assert!(!mesh_surface_cached(&finer, Some(&cache)).unwrap().1);
    assert!(mesh_surface_cached(&finer, Some(&cache)).unwrap().1);
    assert!(mesh_surface_cached(&sp, Some(&cache)).unwrap().1);
    // A changed file misses.
    write(&file, |o| write_stl_binary(&sand_grain_mm(4, 3), o));
    assert!(!mesh_surface_cached(&sp, Some(&cache)).unwrap().1);
    // A corrupted entry is ignored and re-meshed to the same mesh.
    for e in std::fs::read_dir(&cache).unwrap() {
        let p = e.unwrap().path();
        let mut bytes = std::fs::read(&p).unwrap();
        let n = bytes.len() / 2;
        bytes[n] ^= 0xff;
        std::fs::write(&p, bytes).unwrap();
    }
    let (again, hit) = mesh_surface_cached(&sp, Some(&cache)).unwrap();
    assert!(!hit);
    assert!(mesh_surface_cached(&sp, Some(&cache)).unwrap().1);
    assert!(again.tets.len() > 100);
}

#[test]
fn two_grains_of_virtual_sand_run_with_the_energy_ledger_balanced() {
    let d = dir("sand_run");
    let mufe = |args: &[&str]| {
        let o = Command::new(env!("CARGO_BIN_EXE_mufe"))
            .args(args)
            .env("MUFE_CACHE_DIR", d.join("cache"))
            .output()
            .unwrap();
        assert!(
            o.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        String::from_utf8_lossy(&o.stdout).into_owned()
    };
    let sand = d.join("sand");
    mufe(&[
        "sand",
        "--out",
        sand.to_str().unwrap(),
        "--grains",
        "2",
        "--seed",
        "7",
        "--level",
        "2",
        "--seeding",
        "2.5e-4",
    ]);
    let scene = sand.join("scene.toml");
    let check = mufe(&["check", scene.to_str().unwrap()]);
    assert!(check.contains("totals: 2 grains"), "{check}");
    assert_eq!(check.matches("shape of grain").count(), 2, "{check}");
    let out = d.join("out");
    mufe(&[
        "run",
        scene.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--max-steps",
        "300",
        "--threads",
        "1",
        "--quiet",
        "--set",
        "grains[0].velocity=[0.0, 0.0, -0.5]",
        "--set",
        "grains[1].angular_velocity=[0.0, 300.0, 0.0]",
    ]);
    let h = history(&out.join("results.h5"));
    let largest = ["external_work", "kinetic_energy", "internal_energy"]
        .iter()
        .flat_map(|n| column(&h, n).iter().map(|v| v.abs()))
        .fold(0.0, f64::max);
    let total = column(&h, "energy_balance");
    let drift = total
        .iter()
        .map(|e| (e - total[0]).abs())
        .fold(0.0, f64::max);
    assert!(largest > 0.0 && total.iter().all(|v| v.is_finite()));
    assert!(
        drift <= 5e-3 * largest,
        "energy balance error {:.2e} of {largest:.3e} J",
        drift / largest
    );
}

/// Distinct shapes missing from the cache are meshed in `mufe mesh-worker` processes
/// (issue 15, item 2), giving the meshes the in-process mesher gives.
#[test]
fn distinct_shapes_mesh_in_worker_processes_into_the_cache_alike() {
    let dir = testing::TestDir::new("workers");
    let mufe = env!("CARGO_BIN_EXE_mufe");
    let run = |args: &[&str], envs: &[(&str, &str)]| {
        let mut c = std::process::Command::new(mufe);
        c.args(args).current_dir(&dir);
        for (k, v) in envs {
            c.env(k, v);
        }
        c.output().unwrap()
    };
    let out = run(&["sand", "--out", "s", "--grains", "4", "--seed", "3"], &[]);
    assert!(out.status.success());
    let totals = |o: &std::process::Output| {
        String::from_utf8_lossy(&o.stdout)
            .lines()
            .find(|l| l.starts_with("totals:"))
            .unwrap()
            .to_string()
    };
    let with_workers = run(&["check", "s/scene.toml"], &[("MUFE_CACHE_DIR", "cache_w")]);
    let note = String::from_utf8_lossy(&with_workers.stderr);
    assert!(with_workers.status.success(), "{note}");
    assert!(
        note.contains("meshed 4 distinct surface shapes in up to"),
        "{note}"
    );
    assert_eq!(std::fs::read_dir(dir.join("cache_w")).unwrap().count(), 4);
    // an MPI rank meshes in-process: same meshes
    let in_process = run(
        &["check", "s/scene.toml"],
        &[("MUFE_CACHE_DIR", "cache_p"), ("OMPI_COMM_WORLD_SIZE", "1")],
    );
    assert!(!String::from_utf8_lossy(&in_process.stderr).contains("worker"));
    assert_eq!(totals(&with_workers), totals(&in_process));
    for e in std::fs::read_dir(dir.join("cache_w")).unwrap() {
        let name = e.unwrap().file_name();
        assert_eq!(
            std::fs::read(dir.join("cache_w").join(&name)).unwrap(),
            std::fs::read(dir.join("cache_p").join(&name)).unwrap(),
            "{name:?}"
        );
    }
    // warm: nothing left for the workers
    let warm = run(&["check", "s/scene.toml"], &[("MUFE_CACHE_DIR", "cache_w")]);
    assert!(!String::from_utf8_lossy(&warm.stderr).contains("worker"));
    // a worker fed garbage fails with exit 2
    let mut c = std::process::Command::new(mufe)
        .arg("mesh-worker")
        .stdin(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    use std::io::Write as _;
    c.stdin.take().unwrap().write_all(b"{not json").unwrap();
    assert_eq!(c.wait_with_output().unwrap().status.code(), Some(2));
}

/// Remeshing: a fine STL is coarsened onto its own surface to the seeding, and curvature
/// sizing makes the facets at the tips of a prolate spheroid as fine as 2·mr·ρ there
/// (ρ = a²/c) and 2·mr·a at the equator; curvature sizing without remeshing is refused.
#[test]
fn remeshing_coarsens_a_fine_file_and_curvature_sizing_follows_the_radius() {
    let d = dir("curvature");
    let (a, c) = (0.5, 1.5); // mm
    let mut s = icosphere(5);
    s.points
        .iter_mut()
        .for_each(|p| *p = [a * p[0], a * p[1], c * p[2]].map(|x| x as f32 as f64));
    write(&d.join("spheroid.stl"), |o| write_stl_binary(&s, o));
    let mut coarse = spec(&d.join("spheroid.stl"), "mm", 2e-4);
    let boundary = |m: &TetMesh| {
        let b = mufe::mesh::extract_surface(m);
        let mut edges = Vec::new();
        for f in &b.facets {
            for k in 0..3 {
                let (p, q) = (m.nodes[f[k] as usize], m.nodes[f[(k + 1) % 3] as usize]);
                let mid = [0, 1, 2].map(|i| 0.5 * (p[i] + q[i]));
                let l = (0..3).map(|i| (p[i] - q[i]).powi(2)).sum::<f64>().sqrt();
                edges.push((mid, l));
            }
        }
        (b.facets.len(), edges)
    };
    let mean = |edges: &[([f64; 3], f64)], pick: &dyn Fn([f64; 3]) -> bool| {
        let l: Vec<f64> = edges.iter().filter(|e| pick(e.0)).map(|e| e.1).collect();
        l.iter().sum::<f64>() / l.len().max(1) as f64
    };
    let m = mesh_surface_cached(&coarse, None).unwrap().0;
    let (facets, edges) = boundary(&m);
    let all = mean(&edges, &|_| true);
    println!(
        "{} file facets → {facets} at seeding 0.2 mm (mean edge {all:.3e} m)",
        s.facets.len()
    );
    assert!(facets < s.facets.len() / 10, "{facets} facets");
    assert!((all / 2e-4 - 1.0).abs() < 0.2, "mean edge {all:e}");

    let mr = 0.1;
    coarse.curvature = Some(mufe::mesh::import::remesh::CurvatureSizing {
        mr,
        min_seeding: 1e-5,
        growth: 0.3,
    });
    let m = mesh_surface_cached(&coarse, None).unwrap().0;
    let (_, edges) = boundary(&m);
    let tip = mean(&edges, &|x| x[2].abs() > 0.98 * c * 1e-3);
    let equator = mean(&edges, &|x| x[2].abs() < 0.05e-3);
    let (want_tip, want_equator) = (2.0 * mr * a * a / c * 1e-3, 2.0 * mr * a * 1e-3);
    println!("curvature mr {mr}: tip edge {tip:.3e} m (2·mr·a²/c = {want_tip:.3e}), equator {equator:.3e} m (2·mr·a = {want_equator:.3e})");
    assert!(
        (tip / want_tip - 1.0).abs() < 0.3,
        "tip {tip:e} vs {want_tip:e}"
    );
    assert!(
        (equator / want_equator - 1.0).abs() < 0.3,
        "equator {equator:e} vs {want_equator:e}"
    );

    coarse.remesh = false;
    let e = mesh_surface_cached(&coarse, None).unwrap_err().to_string();
    assert!(e.contains("curvature") && e.contains("remesh"), "{e}");
}
