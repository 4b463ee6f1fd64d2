use super::*;
use crate::scene::parse_scene;

const R: f64 = 1.1e-3;

fn scene_text(cells: &str, faces: &str, gap: f64) -> String {
    format!(
        r#"
[simulation]
duration = 1e-6
[materials.glass]
youngs_modulus = 63e9
poisson_ratio = 0.22
density = 2500.0
[[packings]]
name = "fcc"
lattice = "fcc"
cells = {cells}
faces = "{faces}"
material = "glass"
gap = {gap}
sphere = {{ radius = {R}, seeding = 5e-4, contact_seeding = 2e-4, contact_radius = 1e-4, axis_patches = true }}
"#
    )
}

fn scene(cells: &str, faces: &str, gap: f64) -> Scene {
    parse_scene("t.toml", &scene_text(cells, faces, gap), &[])
        .unwrap()
        .scene
}

fn spec(cells: [i64; 3], faces: Faces) -> PackingSpec {
    let mut s = scene("[1, 1, 1]", "open", 0.0).packings.remove(0);
    s.cells = cells;
    s.faces = faces;
    s
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

#[test]
fn counts_match_the_closed_forms() {
    for cells in [[1, 1, 1], [2, 3, 4], [10, 10, 5], [3, 1, 2]] {
        let [n, m, k] = cells.map(|c| c as usize);
        let open = spec(cells, Faces::Open);
        assert_eq!(open.count(), Some(4 * n * m * k));
        assert_eq!(open.sites().len(), 4 * n * m * k);
        let closed = spec(cells, Faces::Closed);
        // even-parity points of a (2n+1)(2m+1)(2k+1) grid whose corner is even
        let grid = ((2 * n + 1) * (2 * m + 1) * (2 * k + 1)).div_ceil(2);
        assert_eq!(closed.count(), Some(grid));
        assert_eq!(closed.sites().len(), grid);
    }
    assert_eq!(spec([1, 1, 1], Faces::Closed).count(), Some(14));
    assert_eq!(spec([10, 10, 5], Faces::Open).count(), Some(2000));
}

#[test]
fn interior_spheres_have_twelve_neighbours_at_the_contact_distance() {
    let gap = 0.03;
    let s = scene("[2, 2, 2]", "closed", gap);
    let g = &s.grains;
    assert_eq!(g.len(), 63);
    let d = 2.0 * R * (1.0 + gap);
    let boundary: std::collections::BTreeSet<usize> = FACES
        .iter()
        .flatten()
        .flat_map(|f| s.grain_set(&format!("fcc.{f}")).unwrap())
        .collect();
    let interior: Vec<usize> = (0..g.len()).filter(|i| !boundary.contains(i)).collect();
    // (2n−1)³ odd-odd-odd-excluded interior sites of a 2×2×2 closed block: 63 − 50
    assert_eq!(interior.len(), 63 - boundary.len());
    assert!(!interior.is_empty());
    for &i in &interior {
        let near: Vec<f64> = (0..g.len())
            .filter(|&j| j != i)
            .map(|j| dist(g[i].centre, g[j].centre))
            .filter(|&r| r < d * (1.0 + 1e-9))
            .collect();
        assert_eq!(near.len(), 12, "sphere {i}");
        for r in near {
            assert!(
                (r - d).abs() < 1e-12 * d,
                "sphere {i}: neighbour at {r}, want {d}"
            );
        }
    }
}

#[test]
fn face_sets_hold_the_outer_lattice_planes() {
    let (n, m, k) = (3usize, 2usize, 4usize);
    for (faces, per_face) in [
        ("open", [2 * m * k, 2 * n * k, 2 * n * m]),
        (
            "closed",
            [
                2 * m * k + m + k + 1,
                2 * n * k + n + k + 1,
                2 * n * m + n + m + 1,
            ],
        ),
    ] {
        let s = scene("[3, 2, 4]", faces, 0.0);
        let geo = &s.packing_geometry()[0];
        for axis in 0..3 {
            for (side, want) in [(0, geo.span_min[axis]), (1, geo.span_max[axis])] {
                let set = s.grain_set(&format!("fcc.{}", FACES[axis][side])).unwrap();
                assert_eq!(set.len(), per_face[axis], "{faces} {}", FACES[axis][side]);
                for &gi in &set {
                    assert!((s.grains[gi].centre[axis] - want).abs() < 1e-15);
                }
                // and no other sphere lies on that plane
                let on_plane = s
                    .grains
                    .iter()
                    .filter(|g| (g.centre[axis] - want).abs() < 1e-9)
                    .count();
                assert_eq!(on_plane, set.len());
            }
        }
        assert_eq!(s.grain_set("fcc").unwrap().len(), s.grains.len());
        assert_eq!(s.grain_set("fcc_3"), Some(vec![3]));
        assert_eq!(s.grain_set("fcc.w_min"), None);
    }
}

#[test]
fn geometry_spans_the_centres_and_the_block() {
    let s = scene("[2, 1, 1]", "open", 0.0);
    let geo = &s.packing_geometry()[0];
    let a = 2.0 * std::f64::consts::SQRT_2 * R;
    assert_eq!(geo.grains, 0..8);
    assert!((geo.lattice_constant - a).abs() < 1e-18);
    assert!((geo.span_max[0] - 1.5 * a).abs() < 1e-15);
    assert!((geo.span_max[2] - 0.5 * a).abs() < 1e-15);
    assert!((geo.bounds_min[1] + R).abs() < 1e-18);
    assert!((geo.bounds_max[0] - 1.5 * a - R).abs() < 1e-15);
    // grain order: z outermost, x fastest
    assert_eq!(s.grains[1].name.as_deref(), Some("fcc_1"));
    assert!(s.grains[1].centre[0] > s.grains[0].centre[0] && s.grains[1].centre[2] == 0.0);
    assert!(s
        .grains
        .windows(2)
        .all(|w| w[0].centre[2] <= w[1].centre[2]));
}

#[test]
fn every_sphere_has_the_one_shape_with_contact_patches() {
    let s = scene("[2, 2, 1]", "closed", 0.0);
    let key = |g: &GrainSpec| serde_json::to_string(&g.shape).unwrap();
    let first = key(&s.grains[0]);
    assert!(s.grains.iter().all(|g| key(g) == first));
    let ShapeSpec::Sphere(sp) = &s.grains[0].shape else {
        panic!("not a sphere")
    };
    assert_eq!(sp.refine.len(), 18);
    // each ⟨110⟩ patch points at a neighbour of an interior sphere
    for r in &sp.refine[..12] {
        let n2: f64 = r.direction.iter().map(|x| x * x).sum();
        assert_eq!(n2, 2.0);
    }
}

#[test]
fn bad_fields_are_named() {
    let err = |text: String, set: &[&str]| {
        let set: Vec<String> = set.iter().map(|s| s.to_string()).collect();
        match parse_scene("t.toml", &text, &set) {
            Ok(_) => panic!("accepted {set:?}"),
            Err(e) => e.item,
        }
    };
    let t = || scene_text("[2, 2, 2]", "open", 0.0);
    // (overrides, the field the one-line error must name)
    let cases: [(&[&str], &str); 13] = [
        (&["packings[0].cells=[0, 2, 2]"], "packings[0].cells"),
        (&["packings[0].cells=[2, -1, 2]"], "packings[0].cells"),
        (&["packings[0].material=\"steel\""], "packings[0].material"),
        (&["packings[0].lattice=\"bcc\""], "packings[0].lattice"),
        (&["packings[0].faces=\"half\""], "packings[0].faces"),
        (&["packings[0].gap=0.6"], "packings[0].gap"),
        (&["packings[0].gap=-0.02"], "packings[0].gap"),
        // within the gap bounds but deeper than the faceting: the overlap check, renamed
        (
            &[
                "packings[0].gap=-0.009",
                "packings[0].sphere.seeding=1e-4",
                "packings[0].sphere.contact_seeding=5e-5",
            ],
            "packings[0].gap",
        ),
        (
            &["packings[0].sphere.radius=-1.0"],
            "packings[0].sphere.radius",
        ),
        (
            &["packings[0].sphere.seeding=2e-3"],
            "packings[0].sphere.seeding",
        ),
        (
            &["packings[0].sphere.contact_seeding=6e-4"],
            "packings[0].sphere.contact_seeding",
        ),
        (&["packings[0].cells=[100, 100, 100]"], "packings[0].cells"),
        (&["packings[0].name=\"a b\""], "packings[0].name"),
    ];
    for (set, field) in cases {
        assert_eq!(err(t(), set), *field, "{set:?}");
    }
    let dup = format!(
        "{}[[grains]]\nname = \"fcc_3\"\nmaterial = \"glass\"\ncentre = [1.0, 0.0, 0.0]\nshape = {{ sphere = {{ radius = 1e-3, seeding = 5e-4 }} }}\n",
        t()
    );
    assert_eq!(err(dup, &[]), "packings[0].name");
}

#[test]
fn touching_spheres_at_zero_gap_pass_the_overlap_check() {
    let s = scene("[1, 1, 1]", "closed", 0.0);
    assert_eq!(s.grains.len(), 14);
}

/// Smallest distance between the surface nodes of two copies of `mesh` centred at `a`
/// and `b`: an upper bound on the gap between the two convex meshes, 0 where they share
/// a contact point.
fn node_gap(mesh: &crate::mesh::TetMesh, surface: &[u32], a: [f64; 3], b: [f64; 3]) -> f64 {
    let at = |c: [f64; 3], n: u32| {
        let x = mesh.nodes[n as usize];
        [c[0] + x[0], c[1] + x[1], c[2] + x[2]]
    };
    let mut gap = f64::INFINITY;
    for &i in surface {
        for &j in surface {
            gap = gap.min(dist(at(a, i), at(b, j)));
        }
    }
    gap
}

#[test]
fn touching_spheres_start_in_contact_at_every_lattice_contact_and_wall() {
    let s = scene("[1, 1, 1]", "closed", 0.0);
    let ShapeSpec::Sphere(spec) = &s.grains[0].shape else {
        panic!("not a sphere")
    };
    assert!(spec.refine.iter().all(|r| r.node));
    let mesh = crate::mesh::mesh_sphere(spec).unwrap();
    let surface = crate::mesh::extract_surface(&mesh).nodes;
    let mut plain_spec = spec.clone();
    plain_spec.refine.iter_mut().for_each(|r| r.node = false);
    let plain = crate::mesh::mesh_sphere(&plain_spec).unwrap();
    let plain_surface = crate::mesh::extract_surface(&plain).nodes;

    // every neighbour pair of the cell, covering all 12 ⟨110⟩ directions
    let g = &s.grains;
    let mut directions = std::collections::BTreeSet::new();
    let mut largest_plain_gap: f64 = 0.0;
    for i in 0..g.len() {
        for j in 0..g.len() {
            let (a, b) = (g[i].centre, g[j].centre);
            if i == j || (dist(a, b) - 2.0 * R).abs() > 1e-12 * R {
                continue;
            }
            directions.insert([0, 1, 2].map(|k| ((b[k] - a[k]) / R).round() as i64));
            let gap = node_gap(&mesh, &surface, a, b);
            assert!(gap <= 1e-12 * R, "grains {i} and {j}: gap {gap} m");
            largest_plain_gap = largest_plain_gap.max(node_gap(&plain, &plain_surface, a, b));
        }
    }
    assert_eq!(directions.len(), 12, "{directions:?}");
    // without contact nodes the meshes start apart by up to their faceting sag
    assert!(largest_plain_gap > 1e-3 * R, "{largest_plain_gap}");

    // walls at the lattice span ± R touch the outer spheres' axis nodes
    let geo = &s.packing_geometry()[0];
    for axis in 0..3 {
        for (side, wall) in [(0, geo.bounds_min[axis]), (1, geo.bounds_max[axis])] {
            let set = s.grain_set(&format!("fcc.{}", FACES[axis][side])).unwrap();
            for gi in set {
                let reach = surface
                    .iter()
                    .map(|&n| (g[gi].centre[axis] + mesh.nodes[n as usize][axis] - wall).abs())
                    .fold(f64::INFINITY, f64::min);
                assert!(reach <= 1e-12 * R, "grain {gi}: {reach} m from its wall");
            }
        }
    }
}
