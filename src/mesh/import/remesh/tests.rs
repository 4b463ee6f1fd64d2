use super::*;
use crate::math::point_triangle_distance;
use crate::mesh::import::checks::{check, signed_volume, tests::cube};
use crate::mesh::surface_refine::triangulate_sphere;

fn sphere(radius: f64, edge: f64) -> Surface {
    let t = triangulate_sphere(radius, edge, |_| edge, &[], "test").unwrap();
    Surface {
        points: t.points,
        facets: t.triangles,
    }
}

fn edges(s: &Surface) -> Vec<([f64; 3], f64)> {
    let mut out = Vec::new();
    for f in &s.facets {
        for k in 0..3 {
            let (a, b) = (f[k], f[(k + 1) % 3]);
            if a < b {
                let (p, q) = (s.points[a as usize], s.points[b as usize]);
                out.push((scale(add(p, q), 0.5), norm(sub(p, q))));
            }
        }
    }
    out
}

/// Mean length of the edges whose midpoint `pick` selects.
fn mean_edge(s: &Surface, pick: impl Fn([f64; 3]) -> bool) -> f64 {
    let l: Vec<f64> = edges(s).iter().filter(|e| pick(e.0)).map(|e| e.1).collect();
    l.iter().sum::<f64>() / l.len() as f64
}

fn distance_to(s: &Surface, x: [f64; 3]) -> f64 {
    s.facets
        .iter()
        .map(|f| {
            let p = f.map(|v| s.points[v as usize]);
            point_triangle_distance(x, p[0], p[1], p[2])
        })
        .fold(f64::INFINITY, f64::min)
}

/// Largest facet angle (degrees).
fn largest_angle(s: &Surface) -> f64 {
    let mut worst: f64 = 0.0;
    for f in &s.facets {
        let p = f.map(|v| s.points[v as usize]);
        for k in 0..3 {
            let (u, v) = (sub(p[(k + 1) % 3], p[k]), sub(p[(k + 2) % 3], p[k]));
            worst = worst.max((dot(u, v) / (norm(u) * norm(v))).acos().to_degrees());
        }
    }
    worst
}

fn stretched(mut s: Surface, axes: [f64; 3]) -> Surface {
    for p in &mut s.points {
        *p = [0, 1, 2].map(|k| p[k] * axes[k]);
    }
    s
}

#[test]
fn a_fine_sphere_coarsens_onto_itself_at_the_seeding() {
    let fine = sphere(1.0, 0.03);
    let h = 0.2;
    let field = SizeField {
        seeding: h,
        zones: &[],
    };
    let reference = Reference::new(&fine, field, None);
    let out = remesh(&fine, &reference);
    check(&out).unwrap();
    let mean = mean_edge(&out, |_| true);
    assert!((0.8 * h..1.15 * h).contains(&mean), "mean edge {mean}");
    let worst = edges(&out).iter().fold(0.0f64, |m, e| m.max(e.1));
    assert!(worst < 1.6 * h, "longest edge {worst}");
    for p in out.points.iter().step_by(7) {
        assert!(distance_to(&fine, *p) < 1e-9);
    }
    // vertices on the input, facets chords of it: the volume lost is the chord sag's, as
    // for the sphere mesher's own triangulation at that edge (within 1.5×)
    let loss = 1.0 - signed_volume(&out) / signed_volume(&fine);
    let geodesic = 1.0 - signed_volume(&sphere(1.0, h)) / signed_volume(&fine);
    assert!(
        loss > 0.0 && loss < 1.5 * geodesic,
        "volume lost {loss}, geodesic {geodesic}"
    );
    let expected = reference.expected_facets();
    let ratio = out.facets.len() as f64 / expected;
    assert!(
        (0.7..1.3).contains(&ratio),
        "{} facets, {expected} expected",
        out.facets.len()
    );
    // quality: no sliver facets
    let worst_q = out
        .facets
        .iter()
        .map(|f| {
            let p = f.map(|v| out.points[v as usize]);
            quality(p[0], p[1], p[2])
        })
        .fold(1.0f64, f64::min);
    assert!(worst_q > 0.3, "worst facet quality {worst_q}");
    // acute (TetGen would split the edge opposite any angle ≥ 90°)
    assert!(largest_angle(&out) < 90.0, "{}°", largest_angle(&out));
}

#[test]
fn a_cube_keeps_its_corners_edges_and_volume() {
    let c = cube();
    let h = 0.15;
    let field = SizeField {
        seeding: h,
        zones: &[],
    };
    let reference = Reference::new(&c, field, None);
    let out = remesh(&c, &reference);
    check(&out).unwrap();
    assert!((signed_volume(&out) - 1.0).abs() < 1e-12);
    for corner in 0..8 {
        let x = [corner & 1, (corner >> 1) & 1, (corner >> 2) & 1].map(|b| b as f64);
        assert!(out.points.contains(&x), "corner {x:?} lost");
    }
    for p in &out.points {
        let on_face = p
            .iter()
            .any(|&c| c.abs() < 1e-12 || (c - 1.0).abs() < 1e-12);
        let inside = p.iter().all(|&c| (-1e-12..=1.0 + 1e-12).contains(&c));
        assert!(on_face && inside, "{p:?} is off the cube");
    }
    let mean = mean_edge(&out, |_| true);
    assert!((0.75 * h..1.2 * h).contains(&mean), "mean edge {mean}");
}

#[test]
fn curvature_sizing_refines_the_tips_of_a_spheroid_by_their_radius() {
    // prolate spheroid a = b = 1, c = 3: smallest radius of curvature a²/c = 1/3 at the
    // tips, a = 1 at the equator
    let s = stretched(sphere(1.0, 0.02), [1.0, 1.0, 3.0]);
    let mr = 0.05;
    let curvature = CurvatureSizing {
        mr,
        min_seeding: 1e-3,
        growth: 0.3,
    };
    let field = SizeField {
        seeding: 0.5,
        zones: &[],
    };
    let reference = Reference::new(&s, field, Some(&curvature));
    let out = remesh(&s, &reference);
    check(&out).unwrap();
    assert!(largest_angle(&out) < 90.0, "{}°", largest_angle(&out));
    let tip = mean_edge(&out, |x| x[2].abs() > 2.97);
    let equator = mean_edge(&out, |x| x[2].abs() < 0.15);
    let (want_tip, want_equator) = (2.0 * mr / 3.0, 2.0 * mr);
    assert!(
        (tip / want_tip - 1.0).abs() < 0.3,
        "tip edge {tip} vs {want_tip}"
    );
    assert!(
        (equator / want_equator - 1.0).abs() < 0.3,
        "equator edge {equator} vs {want_equator}"
    );
}
