//! Tests of the broad phase: candidate lists, the Verlet skin and detection references.

use super::*;
use crate::contact::triangle::nearest_record;

/// Two passes over surfaces 0 and 1 whose entries had the gaps `gaps` at the rebuild.
fn lists(gaps: [&[f64]; 2]) -> CandidateLists {
    let mut lists = CandidateLists::default();
    for (p, g) in gaps.iter().enumerate() {
        let first = lists.gap_at_rebuild.len() as u32;
        lists.passes.push(Pass {
            slave: p as u32,
            master: 1 - p as u32,
        });
        lists.gap_at_rebuild.extend_from_slice(g);
        lists
            .pass_entries
            .push(first..lists.gap_at_rebuild.len() as u32);
    }
    lists
}

fn reach(lists: &CandidateLists, moved: f64, motion: &[SurfaceMotion]) -> Vec<u32> {
    let mut out = Vec::new();
    lists.within_reach(moved, motion, &mut out);
    out
}

/// The skin starts at the margin, doubles (to the margin at most) after a rebuild that
/// came early, stays after one that came late, and thins only at check steps, only
/// when a quarter of it or less lasts `SKIN_LASTS` steps at the pace so far, never
/// below the floor.
#[test]
fn the_skin_follows_the_pace_of_the_surfaces() {
    let cm = ContactModel {
        margin: 1e-5,
        ..Default::default()
    };
    let mut reference = DetectionReference::default();
    assert_eq!(next_skin(&cm, &reference, 7, 0.0, 0.0, false), Some(1e-5));
    // lists dropped by a migration keep the skin they had
    reference.skin = 3e-6;
    assert_eq!(next_skin(&cm, &reference, 7, 0.0, 0.0, false), Some(3e-6));
    reference.built = true;
    reference.built_at = 2048;
    reference.skin = 1e-6;
    let step = |since: u64| 2048 + since;
    // a rebuild voted early doubles the skin, late keeps it, and never past the margin
    assert_eq!(
        next_skin(&cm, &reference, step(100), 0.0, 0.0, true),
        Some(2e-6)
    );
    let late = step(GROW_BELOW);
    assert_eq!(next_skin(&cm, &reference, late, 0.0, 0.0, true), Some(1e-6));
    reference.skin = 8e-6;
    assert_eq!(
        next_skin(&cm, &reference, step(1), 0.0, 0.0, true),
        Some(1e-5)
    );
    // no vote: nothing between checks, however still the surfaces
    assert_eq!(
        next_skin(&cm, &reference, step(1000), 0.0, 0.0, false),
        None
    );
    let check = SKIN_CHECK_EVERY;
    // at a check: 2 × pace × SKIN_LASTS, when at most a quarter of the skin
    let moved = 1e-7;
    let wanted = 2.0 * moved / check as f64 * SKIN_LASTS as f64;
    assert!(wanted < 0.25 * 8e-6);
    assert_eq!(
        next_skin(&cm, &reference, step(check), moved, 0.0, false),
        Some(wanted)
    );
    // the walls' motion counts like the nodes'
    let both = next_skin(
        &cm,
        &reference,
        step(check),
        0.5 * moved,
        0.5 * moved,
        false,
    );
    assert_eq!(both, Some(wanted));
    // a pace at which a quarter of the skin does not last: kept
    let fast = 0.25 * 8e-6 / (2.0 * SKIN_LASTS as f64) * check as f64 * 1.01;
    assert_eq!(
        next_skin(&cm, &reference, step(check), fast, 0.0, false),
        None
    );
    // at rest: the floor
    let floor = next_skin(&cm, &reference, step(2 * check), 0.0, 0.0, false);
    assert_eq!(floor, Some(SKIN_FLOOR * 1e-5));
    reference.skin = SKIN_FLOOR * 1e-5;
    assert_eq!(
        next_skin(&cm, &reference, step(check), 0.0, 0.0, false),
        None
    );
    // a checkpoint from before the adaptive skin: the margin
    reference.skin = 0.0;
    assert_eq!(reference.skin(&cm), 1e-5);
}

#[test]
fn entries_in_reach_are_those_their_two_surfaces_can_have_closed() {
    let (um, moved) = (1e-6, 3e-6);
    let lists = lists([&[0.0, 0.2 * um, 0.5 * um, 5.0 * um, 7.0 * um], &[0.4 * um]]);
    // no surface motion known: every gap within 2 × the largest displacement
    assert_eq!(reach(&lists, moved, &[]), [0, 1, 2, 3, 5]);
    let unknown = [SurfaceMotion::UNKNOWN; 2];
    assert_eq!(reach(&lists, moved, &unknown), [0, 1, 2, 3, 5]);
    // both grains carried 3 µm the same way, each turned or strained by ≤ 0.1–0.2 µm:
    // together they closed at most 0.3 µm of any gap
    let together = [
        SurfaceMotion {
            shift: [moved, 0.0, 0.0],
            spread: 0.1 * um,
        },
        SurfaceMotion {
            shift: [moved, 0.0, 0.0],
            spread: 0.2 * um,
        },
    ];
    assert_eq!(reach(&lists, moved, &together), [0, 1]);
    // head-on, 2.5 µm each way: the relative bound (5.3 µm) is above 2 × moved, which
    // then bounds
    let head_on = [
        SurfaceMotion {
            shift: [2.5 * um, 0.0, 0.0],
            ..together[0]
        },
        SurfaceMotion {
            shift: [-2.5 * um, 0.0, 0.0],
            ..together[1]
        },
    ];
    assert_eq!(head_on[0].closing_with(&head_on[1]), 5.3 * um);
    assert_eq!(reach(&lists, moved, &head_on), [0, 1, 2, 3, 5]);
    assert_eq!(reach(&lists, 1.5 * um, &head_on), [0, 1, 2, 5]);
}

/// The lists a rebuild makes hold every facet that can become a slave node's nearest,
/// and every node that can come into contact, before the next rebuild: two spheres
/// pressed 17 µm into each other, their lists built with a 20 µm skin, then every
/// surface node moved by just under half the skin (what the next rebuild allows), the
/// grains closing head-on or sliding past each other, every node straying its own way.
/// For every entry within a quarter edge of the master, the nearest of its candidates
/// is as near as the nearest facet of the whole master surface; every slave node then
/// inside its master has an entry; and the lists hold fewer facets than half-edge boxes
/// find. Entries kept only within half the skin, or candidates only within the nearest
/// distance (no skin term), fail it; random motion cannot tell the candidates' factor 2
/// from 1, which only a contrived motion needs.
#[test]
fn rebuilt_lists_hold_every_nearest_facet_and_contact_the_skin_allows() {
    let (radius, seeding, depth, skin) = (1.0e-3, 1.0e-4, 1.7e-5, 2.0e-5);
    let (solver, x) = super::super::tests::pressed_pair_with_lists(radius, seeding, depth, skin);
    let (cm, lists) = (&solver.model.contact, &solver.scratch.contact.lists);

    let distance = |y: &[[f64; 3]], p: [f64; 3], f: u32| facet_distance(cm, y, p, f as usize);
    // against half-edge boxes (at the contact itself both hold the ring of facets
    // around the master vertex nearest a slave node; the far entries shed the most)
    let (mut kept, mut half_edge_boxes) = (0, 0);
    for e in &lists.entries {
        let k = e.slave as usize;
        let mut found = Vec::new();
        let master = &lists.bvh[lists.passes[e.pass as usize].master as usize];
        let around = Aabb::around(x[cm.node[k] as usize], skin + 0.5 * cm.node_h[k]);
        master.query(&around, &mut found);
        kept += e.end - e.start;
        half_edge_boxes += found.len() as u32;
    }
    assert!(
        4 * kept < 3 * half_edge_boxes,
        "{kept} candidates kept of {half_edge_boxes}"
    );

    let (mut near, mut inside) = (0, 0);
    let b_nodes = solver.model.grains[1].nodes.clone();
    for trial in 0..16u64 {
        // the grains slide past each other (a one way, b the other) and every node
        // strays in its own direction: each by just under half the skin
        // (the first trial head-on: the grains close by most of the skin)
        let mut rng = crate::math::SplitMix64(trial);
        let slide = if trial == 0 {
            [1.0, 0.0, 0.0]
        } else {
            rng.direction()
        };
        let mut y = x.clone();
        for &n in &cm.node {
            let sign = if b_nodes.contains(&(n as usize)) {
                -1.0
            } else {
                1.0
            };
            let stray = rng.direction();
            let d: [f64; 3] = std::array::from_fn(|i| sign * slide[i] + 0.7 * stray[i]);
            let length = dot(d, d).sqrt();
            for i in 0..3 {
                y[n as usize][i] += 0.499 * skin * d[i] / length;
            }
        }
        for e in &lists.entries {
            let p = y[cm.node[e.slave as usize] as usize];
            let master = &cm.surfaces[lists.passes[e.pass as usize].master as usize];
            let everywhere = (master.facets.clone())
                .map(|f| distance(&y, p, f as u32))
                .fold(f64::INFINITY, f64::min);
            // within the half edge the narrow phase looks (less the skin's travel)
            if everywhere > 0.25 * cm.node_h[e.slave as usize] {
                continue;
            }
            near += 1;
            let kept = &lists.candidate_facets[e.start as usize..e.end as usize];
            let nearest = kept[nearest_record(&y, p, kept).expect("candidates")].facet;
            assert_eq!(distance(&y, p, nearest), everywhere, "entry {e:?}");
        }
        // every slave node inside its master after the motion has an entry there
        for (pi, pass) in lists.passes.iter().enumerate() {
            let master = &cm.surfaces[pass.master as usize];
            let facets: Vec<u32> = (master.facets.clone()).map(|f| f as u32).collect();
            let centre = if pass.master == 0 {
                0.0
            } else {
                2.0 * radius - depth
            };
            for k in cm.surfaces[pass.slave as usize].nodes.clone() {
                let p = y[cm.node[k] as usize];
                let off_centre = [p[0] - centre, p[1], p[2]];
                if dot(off_centre, off_centre).sqrt() > radius + 4.0 * skin {
                    continue;
                }
                let f = facets[nearest_candidate(cm, &y, p, &facets).expect("facets")];
                if locate_on_facet(cm, &y, p, f as usize).depth <= 0.0 {
                    continue;
                }
                inside += 1;
                let listed =
                    (lists.entries.iter()).any(|e| e.slave as usize == k && e.pass as usize == pi);
                assert!(listed, "node {k} inside its master has no entry");
            }
        }
    }
    assert!(inside > 20, "{inside} nodes inside their master");
    assert!(near > 100, "{near} entries near the master");
}
