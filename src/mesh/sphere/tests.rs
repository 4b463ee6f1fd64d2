//! Tests of the sphere mesher: closed surface and volume, local and graded refinement, node
//! patches, and the spec's errors and TOML defaults.

use super::*;
use crate::math::{add, cross, dot};
use crate::mesh::{
    extract_surface, facet_normals, quality, surface_node_geometry, tet_volume, SurfaceMesh,
};
use std::collections::HashMap;
use std::f64::consts::PI;

const R: f64 = 1.1e-3;

fn mesh_volume(m: &TetMesh) -> f64 {
    m.tets
        .iter()
        .map(|t| tet_volume(&t.map(|i| m.nodes[i as usize])))
        .sum()
}

/// Every directed edge exactly once, with its twin: closed, consistently oriented.
fn assert_closed(s: &SurfaceMesh) {
    let mut directed: HashMap<(u32, u32), u32> = HashMap::new();
    for f in &s.facets {
        for k in 0..3 {
            *directed.entry((f[k], f[(k + 1) % 3])).or_default() += 1;
        }
    }
    for (&(a, b), &n) in &directed {
        assert_eq!(n, 1, "edge ({a},{b}) used {n} times in one direction");
        assert_eq!(
            directed.get(&(b, a)),
            Some(&1),
            "edge ({a},{b}) not shared by exactly 2 facets"
        );
    }
    // Euler characteristic of a sphere.
    let (v, e, f) = (
        s.nodes.len() as i64,
        directed.len() as i64 / 2,
        s.facets.len() as i64,
    );
    assert_eq!(v - e + f, 2);
}

/// Surface edges as (midpoint, length).
fn surface_edges(m: &TetMesh, s: &SurfaceMesh) -> Vec<([f64; 3], f64)> {
    let mut out = Vec::new();
    for f in &s.facets {
        for k in 0..3 {
            let (a, b) = (f[k], f[(k + 1) % 3]);
            if a < b {
                let (p, q) = (m.nodes[a as usize], m.nodes[b as usize]);
                out.push((scale(add(p, q), 0.5), norm(sub(q, p))));
            }
        }
    }
    out
}

#[test]
fn uniform_sphere_is_closed_outward_and_has_the_right_volume() {
    let spec = SphereMeshSpec::from_meshing_ratio(R, 0.09);
    let m = mesh_sphere(&spec).unwrap();
    validate(&m).unwrap();
    for t in &m.tets {
        assert!(tet_volume(&t.map(|i| m.nodes[i as usize])) > 0.0);
    }
    let s = extract_surface(&m);
    assert_closed(&s);

    // Divergence theorem: Σ (area vector · centroid)/3 over the facets = enclosed volume,
    // positive only if the facets point outward.
    let v_tets = mesh_volume(&m);
    let v_surf: f64 = s
        .facets
        .iter()
        .map(|f| {
            let [a, b, c] = f.map(|i| m.nodes[i as usize]);
            let area = scale(cross(sub(b, a), sub(c, a)), 0.5);
            dot(area, scale(add(add(a, b), c), 1.0 / 3.0)) / 3.0
        })
        .sum();
    assert!(v_surf > 0.0);
    assert!(
        (v_surf / v_tets - 1.0).abs() < 1e-10,
        "{v_surf} vs {v_tets}"
    );

    // The convex polyhedron lies inside the sphere and contains the ball of radius
    // d_min = R − (largest chord sagitta) = min distance from the centre to a facet plane.
    let normals = facet_normals(&m, &s);
    let d_min = s
        .facets
        .iter()
        .zip(&normals)
        .map(|(f, n)| dot(*n, m.nodes[f[0] as usize]))
        .fold(f64::INFINITY, f64::min);
    let sagitta = R - d_min;
    assert!(sagitta > 0.0 && sagitta < 0.05 * R, "sagitta {sagitta}");
    let (v_in, v_out) = (4.0 / 3.0 * PI * d_min.powi(3), 4.0 / 3.0 * PI * R.powi(3));
    assert!(
        v_tets >= v_in * (1.0 - 1e-12) && v_tets <= v_out * (1.0 + 1e-12),
        "{v_in} ≤ {v_tets} ≤ {v_out}"
    );
    for &n in &s.nodes {
        assert!(norm(m.nodes[n as usize]) <= R * (1.0 + 1e-12));
    }

    // The surface is exactly the triangulated sphere (no TetGen Steiner points): mean
    // edge ≈ seeding, every surface node on the sphere.
    let q = quality(&m);
    assert!(
        (q.mean_surface_edge / spec.seeding - 1.0).abs() < 0.1,
        "{}",
        q.mean_surface_edge
    );
    for &n in &s.nodes {
        assert!((norm(m.nodes[n as usize]) / R - 1.0).abs() < 1e-12);
    }
    assert!(q.min_dihedral_deg > 5.0, "{q}");

    // Node geometry for contact: tributary areas add up to the surface area, normals are
    // unit and outward.
    let g = surface_node_geometry(&m, &s);
    let area: f64 = s
        .facets
        .iter()
        .map(|f| {
            let [a, b, c] = f.map(|i| m.nodes[i as usize]);
            0.5 * norm(cross(sub(b, a), sub(c, a)))
        })
        .sum();
    assert!((g.areas.iter().sum::<f64>() / area - 1.0).abs() < 1e-12);
    assert!(area < 4.0 * PI * R * R && area > 4.0 * PI * d_min * d_min);
    for (k, &n) in s.nodes.iter().enumerate() {
        let x = m.nodes[n as usize];
        assert!((norm(g.normals[k]) - 1.0).abs() < 1e-12);
        assert!(dot(g.normals[k], x) / norm(x) > 0.99);
    }
}

#[test]
fn local_refinement_is_fine_at_the_point_and_coarse_elsewhere() {
    let s = R / 4.0;
    let fine = s / 4.0;
    let dir = [1.0, 1.0, 0.0];
    let spec = SphereMeshSpec::uniform(R, s).with_refinement(dir, fine, 0.1 * R);
    let m = mesh_sphere(&spec).unwrap();
    validate(&m).unwrap();
    let surf = extract_surface(&m);
    assert_closed(&surf);
    let point = scale(dir, R / norm(dir));
    let edges = surface_edges(&m, &surf);
    let near: Vec<f64> = edges
        .iter()
        .filter(|(c, _)| norm(sub(*c, point)) < 0.1 * R)
        .map(|e| e.1)
        .collect();
    let far: Vec<f64> = edges
        .iter()
        .filter(|(c, _)| norm(sub(*c, point)) > 1.5 * R)
        .map(|e| e.1)
        .collect();
    assert!(near.len() >= 6 && !far.is_empty());
    let near_max = near.iter().cloned().fold(0.0, f64::max);
    let far_mean = far.iter().sum::<f64>() / far.len() as f64;
    assert!(near_max <= 1.5 * fine, "near {near_max} vs {fine}");
    assert!(
        far_mean > 3.0 * fine && (far_mean / s - 1.0).abs() < 0.15,
        "far mean {far_mean}"
    );
    let q = quality(&m);
    assert!(q.min_dihedral_deg > 5.0, "{q}");
    // TetGen kept the surface exactly as triangulated (no Steiner points on it).
    assert_eq!(
        q.surface_facets,
        unit_surface(&spec).unwrap().triangles.len()
    );
    // Much cheaper than meshing the whole sphere at the fine seeding.
    let uniform_fine = mesh_sphere(&SphereMeshSpec::uniform(R, fine)).unwrap();
    assert!(
        5 * m.tets.len() < uniform_fine.tets.len(),
        "refined {} vs uniform fine {}",
        m.tets.len(),
        uniform_fine.tets.len()
    );
    // Two calls give bitwise identical meshes.
    assert_eq!(mesh_sphere(&spec).unwrap(), m);
}

#[test]
fn node_patches_put_a_surface_node_exactly_at_their_centres() {
    // The FCC cell's sphere: patches at the 12 ⟨110⟩ contacts and the 6 ⟨100⟩ wall points.
    let dirs = fcc_contact_directions(true);
    let (plain, pinned) = dirs.iter().fold(
        (
            SphereMeshSpec::uniform(R, 4.5e-4),
            SphereMeshSpec::uniform(R, 4.5e-4),
        ),
        |(a, b), &d| {
            (
                a.with_refinement(d, 2e-4, 0.0),
                b.with_node_refinement(d, 2e-4, 0.0),
            )
        },
    );
    let nearest_surface_node = |m: &TetMesh, s: &SurfaceMesh, x: [f64; 3]| {
        s.nodes
            .iter()
            .map(|&n| norm(sub(m.nodes[n as usize], x)))
            .fold(f64::INFINITY, f64::min)
    };
    let m = mesh_sphere(&pinned).unwrap();
    validate(&m).unwrap();
    let surf = extract_surface(&m);
    assert_closed(&surf);
    let m0 = mesh_sphere(&plain).unwrap();
    let surf0 = extract_surface(&m0);
    let mut missed_without = 0;
    for d in &dirs {
        let centre = scale(*d, R / norm(*d));
        let off = nearest_surface_node(&m, &surf, centre);
        assert!(off <= 1e-12 * R, "{d:?}: nearest node {off} m away");
        if nearest_surface_node(&m0, &surf0, centre) > 1e-3 * R {
            missed_without += 1;
        }
    }
    assert!(missed_without > 0, "the plain mesh already has every node");
    let q = quality(&m);
    assert!(q.min_dihedral_deg > 5.0, "{q}");
    // Acute surface: TetGen had no surface edge to split.
    assert_eq!(
        q.surface_facets,
        unit_surface(&pinned).unwrap().triangles.len()
    );
    assert_eq!(mesh_sphere(&pinned).unwrap(), m);
    // Plain patches serialise as before the option existed.
    assert!(!serde_json::to_string(&plain).unwrap().contains("node"));
    let text = "radius = 1.0\nseeding = 0.1\nrefine = [ { direction = [0, 0, 1], seeding = 0.05, radius = 0.0, node = true } ]";
    assert!(toml::from_str::<SphereMeshSpec>(text).unwrap().refine[0].node);
}

#[test]
fn two_node_patches_closer_than_an_edge_are_refused_naming_the_second() {
    let spec = SphereMeshSpec::uniform(R, 4.5e-4)
        .with_node_refinement([0.0, 0.0, 1.0], 2e-4, 0.0)
        .with_node_refinement([0.0, 0.02, 1.0], 2e-4, 0.0);
    match mesh_sphere(&spec) {
        Err(MeshError::InvalidSpec { field, .. }) => assert_eq!(field, "refine[1].node"),
        other => panic!("expected an InvalidSpec error, got {other:?}"),
    }
}

#[test]
fn graded_mesh_has_a_coarse_core_and_the_same_surface() {
    let s = 0.045 * 2.0 * R;
    let uniform = mesh_sphere(&SphereMeshSpec::uniform(R, s)).unwrap();
    let graded = mesh_sphere(&SphereMeshSpec::uniform(R, s).with_graded(3.0 * s, R / 4.0)).unwrap();
    validate(&graded).unwrap();
    assert!(
        (graded.tets.len() as f64) < 0.8 * uniform.tets.len() as f64,
        "graded {} vs uniform {}",
        graded.tets.len(),
        uniform.tets.len()
    );
    let (qg, qu) = (quality(&graded), quality(&uniform));
    assert!((qg.mean_surface_edge / s - 1.0).abs() < 0.1, "{qg}");
    assert_eq!(qg.surface_facets, qu.surface_facets);
    assert!(qg.min_dihedral_deg > 5.0, "{qg}");
    // Mean edge of the tets in the inner half of the radius: coarse in the graded mesh.
    let core_edge = |m: &TetMesh| {
        let (mut sum, mut n) = (0.0, 0);
        for t in &m.tets {
            let x = t.map(|i| m.nodes[i as usize]);
            let c = scale(add(add(x[0], x[1]), add(x[2], x[3])), 0.25);
            if norm(c) < 0.5 * R {
                for (i, j) in [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)] {
                    sum += norm(sub(x[i], x[j]));
                    n += 1;
                }
            }
        }
        sum / n as f64
    };
    assert!(
        core_edge(&graded) > 1.6 * s,
        "graded core edge {}",
        core_edge(&graded)
    );
    assert!(
        (core_edge(&uniform) / s - 1.0).abs() < 0.2,
        "uniform core edge {}",
        core_edge(&uniform)
    );
}

#[test]
fn spec_errors_name_the_field() {
    let ok = SphereMeshSpec::uniform(R, 1e-4);
    ok.validate().unwrap();
    let field = |spec: SphereMeshSpec| match spec.validate() {
        Err(MeshError::InvalidSpec { field, .. }) => field,
        other => panic!("expected an InvalidSpec error, got {other:?}"),
    };
    assert_eq!(field(SphereMeshSpec::uniform(-1.0, 1e-4)), "radius");
    assert_eq!(field(SphereMeshSpec::uniform(f64::NAN, 1e-4)), "radius");
    assert_eq!(field(SphereMeshSpec::uniform(R, 0.0)), "seeding");
    assert_eq!(field(SphereMeshSpec::uniform(R, f64::INFINITY)), "seeding");
    assert_eq!(field(SphereMeshSpec::uniform(R, 2.0 * R)), "seeding");
    assert_eq!(field(ok.clone().with_graded(R, 2e-4)), "graded.band_depth");
    assert_eq!(
        field(ok.clone().with_graded(0.5e-4, 2e-4)),
        "graded.band_depth"
    );
    assert_eq!(
        field(ok.clone().with_graded(3e-4, 0.5e-4)),
        "graded.core_seeding"
    );
    assert_eq!(
        field(ok.clone().with_graded(3e-4, -1.0)),
        "graded.core_seeding"
    );
    assert_eq!(
        field(ok.clone().with_refinement([0.0; 3], 2e-5, 1e-4)),
        "refine[0].direction"
    );
    assert_eq!(
        field(ok.clone().with_refinement([1.0, 0.0, 0.0], 2e-4, 1e-4)),
        "refine[0].seeding"
    );
    let mut bad = ok
        .clone()
        .with_refinement([1.0, 0.0, 0.0], 2e-5, 1e-4)
        .with_refinement([0.0, 1.0, 0.0], 2e-5, -1.0);
    assert_eq!(field(bad.clone()), "refine[1].radius");
    bad.refine[1].radius = 1e-4;
    bad.refine[1].growth = f64::NAN;
    assert_eq!(field(bad.clone()), "refine[1].growth");
    let e = SphereMeshSpec::uniform(R, -1.0).validate().unwrap_err();
    assert_eq!(
        e.to_string(),
        "seeding: must be a positive finite length, got -1"
    );
    // mesh_sphere validates first.
    assert!(matches!(
        mesh_sphere(&SphereMeshSpec::uniform(R, 0.0)),
        Err(MeshError::InvalidSpec { .. })
    ));
}

#[test]
fn spec_reads_from_toml_with_default_growth() {
    let text = r#"
        radius = 1.1e-3
        seeding = 9.9e-5
        graded = { band_depth = 3.0e-4, core_seeding = 2.75e-4 }
        refine = [ { direction = [0, 0, 2], seeding = 2.5e-5, radius = 1e-4 } ]
    "#;
    let spec: SphereMeshSpec = toml::from_str(text).unwrap();
    assert_eq!(spec.refine[0].growth, 0.3);
    assert_eq!(
        spec.graded,
        Some(GradedBand {
            band_depth: 3.0e-4,
            core_seeding: 2.75e-4
        })
    );
    spec.validate().unwrap();
    assert!((spec.meshing_ratio() - 0.045).abs() < 1e-12);
    // Sizing formula: fine at the point, growing with chord distance beyond the zone.
    assert_eq!(spec.surface_size([0.0, 0.0, R]), 2.5e-5);
    let x = [R * 0.6f64.sin(), 0.0, R * 0.6f64.cos()];
    let d = norm(sub(x, [0.0, 0.0, R]));
    assert!((spec.surface_size(x) - (2.5e-5 + 0.3 * (d - 1e-4)).min(9.9e-5)).abs() < 1e-18);
    assert_eq!(spec.surface_size([0.0, 0.0, -R]), 9.9e-5);
    assert!(toml::from_str::<SphereMeshSpec>("radius = 1.0\nseeding = 0.1\nbogus = 1").is_err());
}
