//! The nodes the narrow phase can read until the next rebuild of the contact lists. A
//! listed entry reads its slave node (x, v) and, on the master, the corners of its
//! candidate facets and of their neighbours across an edge (edge pseudo-normals; the
//! second patch solve across a clamped edge, whose corners then give v at the contact
//! point), each with its ring of neighbours (its vertex normal and vertex pseudo-normal):
//! `narrow::locate_on_facet`, `narrow::evaluate_entry_on`. Nothing else is read between
//! rebuilds, so a ghost's other nodes need not be fresh then (`crate::domain::halo`, "What
//! contact reads").

use super::vertex_normals::fan_around;
use super::{ContactScratch, NONE};
use crate::model::Model;

/// Marks in `read` (one flag per model node, cleared first) every node the lists in
/// `scratch` let the narrow phase read (module docs). Runs at rebuilds only.
pub fn mark_nodes_the_lists_read(model: &Model, scratch: &ContactScratch, read: &mut Vec<bool>) {
    let cm = &model.contact;
    let lists = &scratch.lists;
    let nodes = model.x0.len();
    read.clear();
    read.resize(nodes, false);
    let mut corners = vec![false; nodes];
    for e in &lists.entries {
        read[cm.node[e.slave as usize] as usize] = true;
        for &f in &lists.candidates[e.start as usize..e.end as usize] {
            let f = f as usize;
            let across = cm.facet_adjacent[f].into_iter().filter(|&o| o != NONE);
            for g in std::iter::once(f).chain(across.map(|o| o as usize)) {
                for c in cm.facet[g] {
                    corners[c as usize] = true;
                }
            }
        }
    }
    add_one_ring(model, &corners, read);
    for (r, c) in read.iter_mut().zip(&corners) {
        *r |= *c;
    }
}

/// Marks in `into` the surface neighbours of every node marked in `from`.
fn add_one_ring(model: &Model, from: &[bool], into: &mut [bool]) {
    let cm = &model.contact;
    for (n, _) in from.iter().enumerate().filter(|(_, &on)| on) {
        for pair in fan_around(cm, n as u32) {
            for &m in pair {
                into[m as usize] = true;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contact::broad::DetectionReference;
    use crate::contact::narrow::{evaluate_entry, EvalContext, PointResult};

    /// What an evaluation depends on, to the bit.
    fn bits(r: &PointResult) -> Vec<u64> {
        let mut b = vec![u64::from(r.active), r.gap.to_bits(), r.separation.to_bits()];
        for v in [r.force, r.normal, r.traction, r.weights] {
            b.extend(v.map(f64::to_bits));
        }
        b.extend(r.masters.map(u64::from));
        b
    }

    /// Two spheres pressed together, lists built, then every node moved by just under half
    /// the skin (as far as it may go before a rebuild): the evaluation of every entry is the
    /// same to the bit when every node the lists do not read is replaced by garbage.
    #[test]
    fn an_evaluation_reads_no_node_outside_the_marked_ones() {
        let (radius, seeding, depth) = (1.0e-3, 1.0e-4, 1.7e-5);
        let sphere = format!("{{ sphere = {{ radius = {radius:e}, seeding = {seeding:e} }} }}");
        let scene = super::super::tests::pair_scene(
            ("a", &sphere, [0.0; 3]),
            ("b", &sphere, [2.0 * radius + depth, 0.0, 0.0]),
        );
        let mut solver = super::super::tests::solver(&scene);
        let model = &solver.model;
        let cm = &model.contact;
        let mut x = solver.state.x.clone();
        for n in model.grains[1].nodes.clone() {
            x[n][0] -= 2.0 * depth;
        }
        let skin = 2.0e-5;
        let scratch = &mut solver.scratch.contact;
        let (broad, lists) = (&mut scratch.broad, &mut scratch.lists);
        broad.rebuild(
            cm,
            &x,
            &[],
            lists,
            &mut DetectionReference::default(),
            skin,
            0,
        );
        let mut read = Vec::new();
        mark_nodes_the_lists_read(model, scratch, &mut read);
        let marked = read.iter().filter(|&&r| r).count();
        assert!(
            2 * marked < cm.node.len(),
            "{marked} of {} surface nodes read",
            cm.node.len()
        );

        let lists = &scratch.lists;
        let mut active = 0;
        for trial in 0..12u64 {
            let mut rng = crate::math::SplitMix64(trial);
            let (mut y, mut v) = (x.clone(), vec![[0.0; 3]; x.len()]);
            for &n in &cm.node {
                let (stray, speed) = (rng.direction(), rng.direction());
                for i in 0..3 {
                    y[n as usize][i] += 0.499 * skin * stray[i];
                    v[n as usize][i] = 0.1 * speed[i];
                }
            }
            let (mut y_bad, mut v_bad) = (y.clone(), v.clone());
            for (n, _) in read.iter().enumerate().filter(|(_, &r)| !r) {
                y_bad[n] = [rng.unit(), rng.unit(), rng.unit()];
                v_bad[n] = [1.0e3; 3];
            }
            let context = |x: &'_ [[f64; 3]], v: &'_ [[f64; 3]]| -> Vec<PointResult> {
                let ctx = EvalContext {
                    cm,
                    passes: &lists.passes,
                    candidates: &lists.candidates,
                    x,
                    v,
                    mass: &model.mass,
                    dt: model.dt,
                    history: &[],
                    friction: true,
                };
                lists
                    .entries
                    .iter()
                    .map(|e| evaluate_entry(&ctx, e))
                    .collect()
            };
            let (good, bad) = (context(&y, &v), context(&y_bad, &v_bad));
            for (i, (g, b)) in good.iter().zip(&bad).enumerate() {
                assert_eq!(bits(g), bits(b), "trial {trial}, entry {i}");
                active += usize::from(g.active);
            }
        }
        assert!(active > 100, "{active} active evaluations");
    }
}
