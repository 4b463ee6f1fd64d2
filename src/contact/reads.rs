//! The nodes the narrow phase can read until the next rebuild of the contact lists. A
//! listed entry reads its slave node (x, v) and, on the master, the corners of its
//! candidate facets and of their neighbours across an edge (edge pseudo-normals; the
//! second patch solve across a clamped edge, whose corners then give v at the contact
//! point), each with its ring of neighbours (its vertex normal and vertex pseudo-normal):
//! `narrow::locate_on_record`, `narrow::evaluate_entry_on`. Nothing else is read between
//! rebuilds, so a ghost's other nodes need not be fresh then (`crate::domain::halo`, "What
//! contact reads").

use super::narrow::{CandidateFacet, Entry};
use super::vertex_normals::fan_around;
use super::{ContactModel, ContactScratch, NONE};
use crate::model::Model;

/// Per model node: whether the contact lists read it, and the facet corners whose rings
/// are added to it; kept between rebuilds so that marking allocates nothing once grown.
#[derive(Debug, Default)]
pub struct NodeReadMarks {
    read: Vec<bool>,
    corners: Vec<bool>,
}

impl NodeReadMarks {
    /// One flag per model node: read by the lists of the last marking.
    pub fn read(&self) -> &[bool] {
        &self.read
    }
}

/// Marks in `marks` (cleared first) every node the lists in `scratch` let the narrow
/// phase read (module docs). Runs when the lists are rebuilt or restored.
pub fn mark_nodes_the_lists_read(
    model: &Model,
    scratch: &ContactScratch,
    marks: &mut NodeReadMarks,
) {
    let lists = &scratch.lists;
    let cm = &model.contact;
    let (entries, facets) = (&lists.entries, &lists.candidate_facets);
    mark_nodes_read_by(cm, entries, facets, model.x0.len(), marks);
}

/// [`mark_nodes_the_lists_read`] for `entries` with their candidate `facets`, in a model
/// of `nodes` nodes.
fn mark_nodes_read_by(
    cm: &ContactModel,
    entries: &[Entry],
    facets: &[CandidateFacet],
    nodes: usize,
    marks: &mut NodeReadMarks,
) {
    let NodeReadMarks { read, corners } = marks;
    for flags in [&mut *read, &mut *corners] {
        flags.clear();
        flags.resize(nodes, false);
    }
    for e in entries {
        read[cm.node[e.slave as usize] as usize] = true;
        for r in &facets[e.start as usize..e.end as usize] {
            let across = r.neighbours.iter().filter(|o| o[0] != NONE);
            for g in std::iter::once(&r.corners).chain(across) {
                for &c in g {
                    corners[c as usize] = true;
                }
            }
        }
    }
    add_one_ring(cm, corners, read);
}

/// Marks in `into` every node marked in `from` and its surface neighbours.
fn add_one_ring(cm: &ContactModel, from: &[bool], into: &mut [bool]) {
    for (n, _) in from.iter().enumerate().filter(|(_, &on)| on) {
        into[n] = true;
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
    use crate::contact::broad::CandidateLists;
    use crate::contact::narrow::{evaluate_entry, EvalContext, PointResult};
    use crate::contact::tests::result_bits as bits;
    use crate::contact::triangle::nearest_record;

    /// Two spheres pressed together, lists built, then every node moved by just under half
    /// the skin (as far as it may go before a rebuild), and then grain b slid sideways by
    /// up to half an edge besides, so that nodes face the master's edges: the evaluation of
    /// every entry is the same to the bit when every node the lists do not read is replaced
    /// by garbage. Then entry by entry with each entry's candidates cut to its nearest
    /// facet, so that no other entry's marks cover for it and a patch point clamped to an
    /// edge is looked for on a neighbour facet that is no candidate.
    #[test]
    fn an_evaluation_reads_no_node_outside_the_marked_ones() {
        let (radius, seeding, depth, skin) = (1.0e-3, 1.0e-4, 1.7e-5, 2.0e-5);
        let (mut solver, x) =
            super::super::tests::pressed_pair_with_lists(radius, seeding, depth, skin);
        let model = &solver.model;
        let cm = &model.contact;
        let scratch = &mut solver.scratch.contact;
        let b = model.grains[1].nodes.clone();
        let mut marks = NodeReadMarks::default();
        mark_nodes_the_lists_read(model, scratch, &mut marks);
        let marked = marks.read().iter().filter(|&&r| r).count();
        assert!(
            2 * marked < cm.node.len(),
            "{marked} of {} surface nodes read",
            cm.node.len()
        );
        let lists = &scratch.lists;
        for slide in [0.0, 0.5 * seeding] {
            let motion = (skin, slide, b.clone());
            let active = evaluations_agree_without_the_unread_nodes(
                model,
                lists,
                &lists.entries,
                &x,
                marks.read(),
                motion,
            );
            assert!(active > 100, "{active} active evaluations");
        }

        let lists = &mut scratch.lists;
        for e in lists.entries.iter_mut() {
            let kept = &lists.candidate_facets[e.start as usize..e.end as usize];
            let p = x[cm.node[e.slave as usize] as usize];
            let i = e.start as usize + nearest_record(&x, p, kept).expect("candidates");
            lists.candidate_facets[e.start as usize] = lists.candidate_facets[i];
            e.end = e.start + 1;
        }
        let lists = &scratch.lists;
        let at_rest = vec![[0.0; 3]; x.len()];
        let in_contact = |e: &&Entry| {
            let ctx = EvalContext {
                cm,
                passes: &lists.passes,
                facets: &lists.candidate_facets,
                x: &x,
                v: &at_rest,
                mass: &model.mass,
                dt: model.dt,
                history: &[],
                friction: false,
            };
            evaluate_entry(&ctx, e).active
        };
        let mut active = 0;
        for e in lists.entries.iter().filter(in_contact) {
            let one = std::slice::from_ref(e);
            mark_nodes_read_by(cm, one, &lists.candidate_facets, x.len(), &mut marks);
            let motion = (skin, 0.5 * seeding, b.clone());
            let read = marks.read();
            active +=
                evaluations_agree_without_the_unread_nodes(model, lists, one, &x, read, motion);
        }
        assert!(active > 100, "{active} active evaluations");
    }

    /// Evaluates `entries` at 12 random displacements of the nodes from `x`, each by
    /// 0.499 `skin` and the nodes `slid` together by up to `slide` ⟂ x, with and without
    /// garbage in the nodes not marked in `read`; asserts the same bits and returns the
    /// number of active evaluations.
    fn evaluations_agree_without_the_unread_nodes(
        model: &Model,
        lists: &CandidateLists,
        entries: &[Entry],
        x: &[[f64; 3]],
        read: &[bool],
        (skin, slide, slid): (f64, f64, std::ops::Range<usize>),
    ) -> usize {
        let cm = &model.contact;
        let mut active = 0;
        for trial in 0..12u64 {
            let mut rng = crate::math::SplitMix64(trial);
            let (mut y, mut v) = (x.to_vec(), vec![[0.0; 3]; x.len()]);
            let (angle, amount) = (std::f64::consts::TAU * rng.unit(), slide * rng.unit());
            for n in slid.clone() {
                y[n][1] += amount * angle.cos();
                y[n][2] += amount * angle.sin();
            }
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
            let evaluate = |x: &'_ [[f64; 3]], v: &'_ [[f64; 3]]| -> Vec<PointResult> {
                let ctx = EvalContext {
                    cm,
                    passes: &lists.passes,
                    facets: &lists.candidate_facets,
                    x,
                    v,
                    mass: &model.mass,
                    dt: model.dt,
                    history: &[],
                    friction: true,
                };
                entries.iter().map(|e| evaluate_entry(&ctx, e)).collect()
            };
            let (good, bad) = (evaluate(&y, &v), evaluate(&y_bad, &v_bad));
            for (i, (g, b)) in good.iter().zip(&bad).enumerate() {
                assert_eq!(bits(g), bits(b), "trial {trial}, entry {i}");
                active += usize::from(g.active);
            }
        }
        active
    }
}
